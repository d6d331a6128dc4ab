"""The job of a design check: its identification (project, structure, element, author, checker,
revision, date) from options or a TOML job file, and the sources of its inputs.

A job file holds a ``[job]`` table with every identification field, and may hold the bridge and the
trains (top-level keys, so before the table)::

    bridge = "L=15,n0=8.26,mu=19042,zeta_pct=1.85"   # or "B1", a file, or a [bridge] table of bridge keys
    trains = ["hslm", "ICE-2", "my_train.toml"]      # or one comma list; files relative to the job file

    [job]
    project = "High-speed line A-B"
    structure = "Bridge km 12.4"
    element = "Main span"
    author = "A. Engineer"
    checker = "B. Checker"
    revision = "B"
    date = 2026-12-06

Unknown keys, a missing identification field, a field that is not text (a TOML date is text) are
refused with one line naming the file and the key. :func:`input_sources` names where every input
comes from: ζ (the paper's Table 3, EN 1991-2 Table 6.6 / paper Table 2 by type, or the user's
value), each train (the paper's Table A1, EN 1991-2 Annex E, a shipped file or a user file with its
SHA-256), and the bridge file's SHA-256.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from adm_sim.errors import InputError
from adm_sim.files import input_file, read_toml
from adm_sim.model.bridge import DECK_DAMPING_LENGTH_RULE

#: The identification fields, in the order the report prints them.
JOB_FIELDS = ("project", "structure", "element", "author", "checker", "revision", "date")
#: Top-level keys of a job file.
JOB_FILE_KEYS = ("job", "bridge", "trains")
#: Longest identification text (characters).
MAX_FIELD_CHARS = 200
#: The paper's four trains (Table A1) as the check names them.
PAPER_TRAINS = ("ICE-2", "Eurostar", "Railjet", "ICE-4")
_DATA = Path(__file__).resolve().parents[1] / "data"


@dataclass(frozen=True)
class Job:
    """Identification (``fields``: name -> text, only the given ones) and, from a job file, its
    bridge (text or mapping), trains (text), folder and path."""

    fields: dict = field(default_factory=dict)
    bridge: object = None
    trains: str | None = None
    path: Path | None = None

    def rows(self):
        """``[(field, text)]`` of every identification field, ``"not given"`` where missing."""
        return [(k, self.fields.get(k, "not given")) for k in JOB_FIELDS]

    def to_dict(self):
        return {k: self.fields.get(k) for k in JOB_FIELDS}

    def lines(self):
        given = [f"{k} {v}" for k, v in self.rows() if k in self.fields]
        return ["job: " + "; ".join(given)] if given else []


def _text(value, where):
    if isinstance(value, (_dt.date, _dt.datetime)):
        value = value.isoformat()
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"{where}: {value!r} is not text; give a non-empty string (a date as 2026-12-06)")
    if len(value) > MAX_FIELD_CHARS or "\n" in value:
        raise InputError(f"{where}: {value[:40]!r}... is too long or holds a line break; allowed one line of at most "
                         f"{MAX_FIELD_CHARS} characters")
    return value.strip()


def job_from_options(values):
    """:class:`Job` from ``{field: text or None}`` (the check's options ``--project`` ...)."""
    return Job(fields={k: _text(v, f"--{k}") for k, v in values.items() if v is not None})


def read_job_file(text, option="--job"):
    """:class:`Job` from a TOML job file (module docstring); one-line refusals naming the file and key."""
    path = input_file(text, option, "job file")
    data = read_toml(path, "job file")
    where = f"{option}: {str(path)!r}"
    unknown = sorted(set(data) - set(JOB_FILE_KEYS))
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r}; allowed {', '.join(JOB_FILE_KEYS)}")
    job = data.get("job")
    if not isinstance(job, dict):
        raise InputError(f"{where}: no [job] table; give one with {', '.join(JOB_FIELDS)}")
    unknown = sorted(set(job) - set(JOB_FIELDS))
    if unknown:
        raise InputError(f"{where}: [job] unknown key {unknown[0]!r}; allowed {', '.join(JOB_FIELDS)}")
    missing = [k for k in JOB_FIELDS if k not in job]
    if missing:
        raise InputError(f"{where}: [job] misses {', '.join(missing)}; a signed report names every one of "
                         f"{', '.join(JOB_FIELDS)}")
    fields = {k: _text(job[k], f"{where}: [job] {k}") for k in JOB_FIELDS}
    bridge = data.get("bridge")
    if bridge is not None and not isinstance(bridge, (str, dict)):
        raise InputError(f"{where}: bridge: {bridge!r} is neither text (B1, a spec, a file) nor a [bridge] table")
    if isinstance(bridge, str) and bridge.strip().lower().endswith(".toml"):
        bridge = str((path.parent / bridge.strip()).resolve()) if not Path(bridge.strip()).is_absolute() else bridge
    trains = data.get("trains")
    if trains is not None:
        items = trains if isinstance(trains, list) else [trains] if isinstance(trains, str) else None
        if items is None or not items or not all(isinstance(t, str) and t.strip() for t in items):
            raise InputError(f"{where}: trains: {trains!r} is not a list of train names or files")
        parts = [p.strip() for t in items for p in t.split(",") if p.strip()]
        trains = ",".join(str((path.parent / p).resolve()) if p.lower().endswith(".toml") and not Path(p).is_absolute()
                          else p for p in parts)
    return Job(fields=fields, bridge=bridge, trains=trains, path=path)


def sha256(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _is_shipped(p):
    try:
        Path(p).resolve().relative_to(_DATA)
        return True
    except ValueError:
        return False


def zeta_source(bridge_spec):
    """Where the bridge's ζ comes from: the paper's Table 3 (B1-B4), the user's value, or EN 1991-2
    Table 6.6 (paper Table 2) by type and span."""
    if isinstance(bridge_spec, dict):
        keys = {k.lower() for k in bridge_spec}
        how = "the job file's [bridge] table"
    else:
        text = str(bridge_spec).strip()
        if text.upper() in ("B1", "B2", "B3", "B4"):
            return f"the paper's Table 3 ({text.upper()})"
        if text.lower().endswith(".toml") and Path(text).is_file():
            try:
                keys = {k.lower() for k in read_toml(Path(text), "bridge file")}
            except InputError:
                keys = set()
            how = f"bridge file {text}"
        else:
            keys = {p.partition("=")[0].strip().lower() for p in text.split(",")}
            how = "the bridge spec"
    if keys & {"zeta", "zeta_pct", "damping_ratio"}:
        return f"user ({how})"
    if "spans" in keys:
        return (f"EN 1991-2 Table 6.6 lower limit by type (paper Table 2) with {DECK_DAMPING_LENGTH_RULE}, "
                f"default")
    return "EN 1991-2 Table 6.6 lower limit by type and span (paper Table 2), default"


def input_sources(bridge_spec, trains_spec, trains, zeta_note=None):
    """``[(input, value, source)]``: the bridge (its file's SHA-256), ζ and every train.

    ``zeta_note`` overrides the ζ source (a measured ζ handed in by another reader)."""
    rows = []
    if isinstance(bridge_spec, dict):
        rows.append(("bridge", ", ".join(f"{k}={v}" for k, v in bridge_spec.items()), "the job file's [bridge] table"))
    else:
        text = str(bridge_spec).strip()
        if text.lower().endswith(".toml") and Path(text).is_file():
            kind = "shipped file" if _is_shipped(text) else "user file"
            rows.append(("bridge", text, f"{kind}, SHA-256 {sha256(text)}"))
        elif text.upper() in ("B1", "B2", "B3", "B4"):
            rows.append(("bridge", text.upper(), "the paper's Table 3"))
        else:
            rows.append(("bridge", text, "user (bridge spec)"))
    rows.append(("zeta", "", zeta_note or zeta_source(bridge_spec)))
    items = [p.strip() for p in str(trains_spec).split(",") if p.strip()]
    for item in items:
        low = item.lower()
        if low.endswith(".toml"):
            kind = "shipped file" if _is_shipped(item) else "user file"
            rows.append(("train", item, f"{kind}, SHA-256 {sha256(item)}"))
        elif low == "hslm" or low.startswith("hslm-a"):
            rows.append(("train", item, "EN 1991-2 Annex E, HSLM-A (Table E.4)"))
        elif low.startswith("hslm-b"):
            rows.append(("train", item, "EN 1991-2 Annex E, HSLM-B (N and d given by the user)"))
        else:
            name = next((t for t in PAPER_TRAINS if t.lower() == low), None)
            src = "the paper's Table A1 (shipped with the program)" if name else "shipped train data"
            rows.append(("train", item, src))
    return rows
