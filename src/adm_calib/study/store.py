"""The study's result store: ``results.jsonl`` (one fsynced line per case) and ``study.json``.

Lines are appended and fsynced one by one, so a crash loses at most the cases still running; a
rerun skips the cases already in the file (key: bridge name and train) and drops a truncated
last line. ``study.json`` holds the format, settings, versions and every run's options and times.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import fcntl
import gzip
import json
import os
import platform
import signal
import threading
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from adm_sim.errors import InputError
from adm_sim.files import refuse_special, write_atomic

from adm_calib.study.cases import case_identity

RESULTS_NAME = "results.jsonl"
META_NAME = "study.json"
LOCK_NAME = ".study.lock"
META_FORMAT = "adm-calib-study/2"
#: Earlier formats: unbatched, brentq per case; their results differ in the solver, so never mixed.
OLD_FORMATS = ("adm-calib-study/1",)

_KEEP = ("status", "message", "delta_zeta_vbi_pct", "delta_zeta_adm_pct", "delta_zeta_eada_pct", "delta_zeta_lb_pct",
         "mlm_peak", "dim_peak", "adapted_mlm_peak", "mlm_max_at_range_end", "dim_is_local_max",
         "dim_max_at_range_end", "dim_speed_shift_kmh", "adapted_is_local_max", "association_rule", "solver",
         "dim_grid", "dim_refined", "ds_m", "timings_s")


def result_record(case, result, wall_s):
    """One result line from a :class:`~adm_calib.calibration_result.CalibrationResult` (Δζ in %)."""
    d = result.to_dict(curves=False)
    rec = case_identity(case.bridge, case.train, case.mass_function, case.freq_index)
    rec.update({k: d[k] for k in _KEEP})
    rec["mlm_peak_acc_m_s2"] = None if d["mlm_peak"] is None else d["mlm_peak"]["acc_m_s2"]
    rec["dim_peak_acc_m_s2"] = None if d["dim_peak"] is None else d["dim_peak"]["acc_m_s2"]
    rec["wall_s"] = float(wall_s)
    return rec


def error_record(case, exc, wall_s=None):
    """A result line for a case that raised; the message is one line."""
    rec = case_identity(case.bridge, case.train, case.mass_function, case.freq_index)
    text = " ".join(str(exc).split()) or "(no message)"
    rec.update({"status": "error", "message": f"{type(exc).__name__}: {text}", "delta_zeta_vbi_pct": None,
                "wall_s": None if wall_s is None else float(wall_s)})
    return rec


# ====================================================================== results file
def record_key(rec):
    return (rec["bridge"], rec["train"])


@dataclass(frozen=True, repr=False)
class ResultsContent:
    """What :func:`read_results` found: records in file order and the state of the file's end."""

    records: list
    valid_bytes: int
    truncated_tail: bytes = b""
    duplicates: int = 0

    @property
    def by_key(self):
        """``{(bridge, train): record}``, the last line of a key winning."""
        return {record_key(r): r for r in self.records}

    def __repr__(self):
        tail = f", truncated tail of {len(self.truncated_tail)} bytes" if self.truncated_tail else ""
        return f"ResultsContent({len(self.records)} records{tail})"


def read_results(path):
    """Read a ``results.jsonl`` (or a gzip-compressed ``results.jsonl.gz``, as shipped in
    ``results/study``); a last line without its newline (a write cut short) is ignored.

    Raises
    ------
    InputError
        A complete line that is not a JSON object with ``bridge`` and ``train``.
    """
    p = Path(path)
    refuse_special(p, f"results {str(p)!r}")
    try:
        data = p.read_bytes()
        if p.suffix == ".gz":
            data = gzip.decompress(data)
    except FileNotFoundError:
        return ResultsContent(records=[], valid_bytes=0)
    except (OSError, EOFError) as exc:
        raise InputError(f"results {str(p)!r}: cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    end = data.rfind(b"\n") + 1
    body, tail = data[:end], data[end:]
    records, seen, dup = [], set(), 0
    for no, line in enumerate(body.split(b"\n")[:-1], start=1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except (ValueError, UnicodeDecodeError):
            raise InputError(f"results {str(p)!r}: line {no} is not valid JSON (only the last line may be "
                             f"truncated)") from None
        if not isinstance(rec, dict) or "bridge" not in rec or "train" not in rec:
            raise InputError(f"results {str(p)!r}: line {no} lacks 'bridge' and 'train'")
        if not isinstance(rec["bridge"], str) or not isinstance(rec["train"], str):
            raise InputError(f"results {str(p)!r}: line {no}: 'bridge' and 'train' must be names (text), "
                             f"got {rec['bridge']!r} and {rec['train']!r}")
        k = record_key(rec)
        dup += k in seen
        seen.add(k)
        records.append(rec)
    return ResultsContent(records=records, valid_bytes=end, truncated_tail=tail, duplicates=dup)


def _fsync_dir(path):
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _atomic_write(path, data):
    """Write ``data`` (bytes) to ``path`` through a temporary file and ``os.replace``
    (:func:`adm_sim.files.write_atomic`; the study's folder lock is held by the caller), fsynced."""
    def write(tmp):
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())

    p = Path(path)
    write_atomic(p, write, option="out")
    _fsync_dir(p.parent)


def _line(rec):
    return (json.dumps(rec, allow_nan=False, separators=(",", ":")) + "\n").encode()


@contextlib.contextmanager
def _signals_deferred():
    """Hold Ctrl-C and SIGTERM back for the block, then act on them.

    The Python handlers run in the main thread but the signal may arrive in any thread (dask's
    event loop runs in another one), so blocking the signal in this thread is not enough: the
    handlers themselves are replaced for the block, and a signal that came is re-delivered after.
    """
    if threading.current_thread() is not threading.main_thread():
        held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
        return
    came = []
    old = {sig: signal.signal(sig, lambda s, f: came.append(s)) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)
        for sig in came[:1]:
            signal.raise_signal(sig)


class ResultsWriter:
    """Append-only writer of ``results.jsonl``: one line per record, flushed and fsynced.

    Opening drops a truncated last line (the file is rewritten without it); with
    ``drop_errors=True`` it also drops the ``status: "error"`` lines so those cases run again.
    A context manager; :meth:`finish` is idempotent.
    """

    def __init__(self, path, drop_errors=False):
        self.path = Path(path)
        content = read_results(self.path)
        keep = content.records
        self.dropped_truncated = bool(content.truncated_tail)
        self.dropped_errors = 0
        if drop_errors:
            keep = [r for r in content.records if r.get("status") != "error"]
            self.dropped_errors = len(content.records) - len(keep)
        if self.dropped_truncated or self.dropped_errors:
            _atomic_write(self.path, b"".join(_line(r) for r in keep))
        self.records = {record_key(r): r for r in keep}
        self._f = open(self.path, "ab")
        self.appended = 0

    def append(self, rec):
        """Append one record and make it durable before returning.

        Ctrl-C and SIGTERM are held back while the line is written and counted, so an interrupt
        never leaves a written line uncounted (or a counted line unwritten).
        """
        with _signals_deferred():
            self._f.write(_line(rec))
            self._f.flush()
            os.fsync(self._f.fileno())
            self.records[record_key(rec)] = rec
            self.appended += 1

    def finish(self):
        if self._f is not None and not self._f.closed:
            self._f.close()
        self._f = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.finish()
        return False


@contextlib.contextmanager
def _exclusive(out_dir):
    """Hold an advisory lock on ``out_dir`` so two studies never append to one file."""
    f = open(Path(out_dir) / LOCK_NAME, "a+")
    try:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            pid = f.read().strip()
            who = f" (process {pid})" if pid.isdigit() else ""
            raise InputError(f"out: {str(out_dir)!r} is in use by another running study{who}") from None
        f.seek(0)
        f.truncate()
        f.write(f"{os.getpid()}\n")
        f.flush()
        yield
    finally:
        f.close()


def _now():
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def versions():
    """Versions of the software that computes the study."""
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for dist in ("adm-sim", "numpy", "scipy", "numba", "dask", "distributed"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def read_meta(out_dir):
    p = Path(out_dir) / META_NAME
    if not p.exists():
        return None
    try:
        meta = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"study metadata {str(p)!r}: unreadable ({exc})") from None
    if isinstance(meta, dict) and meta.get("format") in OLD_FORMATS:
        raise InputError(f"study {str(Path(out_dir))!r} was written by an older, unbatched version "
                         f"({meta['format']}: brentq per case); its results are not mixed with batched ones: "
                         f"use another --out, or delete it to recompute")
    if not isinstance(meta, dict) or meta.get("format") != META_FORMAT:
        raise InputError(f"study metadata {str(p)!r}: not a {META_FORMAT} file")
    return meta


def _write_meta(out_dir, meta):
    _atomic_write(Path(out_dir) / META_NAME, (json.dumps(meta, indent=2) + "\n").encode())
