"""The study's result store: ``results.jsonl`` (one fsynced line per case) and ``study.json``.

Lines are appended and fsynced one by one, so a crash loses at most the cases still running; a
rerun skips the cases already in the file (key: bridge name and train). Every line carries the
CRC-32 of its JSON; a reader refuses a damaged line (and a damaged ``.gz`` file) naming its line
number and byte offset, and a resumed study drops damaged lines and a truncated last line, says
so in one line each and computes those cases again. ``study.json`` holds the format, settings,
versions and every run's options and times.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import fcntl
import json
import os
import platform
import re
import signal
import threading
import zlib
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from adm_sim.errors import InputError
from adm_sim.files import refuse_special, write_atomic

from adm_calib.study.cases import case_identity
from adm_sim.model.plausibility import response_warnings

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
    peaks = [(k, rec[f"{k}_peak_acc_m_s2"]) for k in ("dim", "mlm") if rec[f"{k}_peak_acc_m_s2"] is not None]
    rec["warnings"] = [w for k, a in peaks  # implausible peaks, as adm-sim sweep warns them
                       for w in response_warnings(case.bridge.span_m, a, label=f"{k.upper()} peak")]
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


#: Every line written ends in ``,"crc32":"<8 hex digits>"}``: the CRC-32 of the line's JSON
#: without that member (the bytes before it, closed by ``}``). A file written before line
#: checksums existed carries none; it is read as it is and given checksums when a study resumes it.
CHECK_KEY = "crc32"
_CHECK_RE = re.compile(rb',"crc32":"([0-9a-f]{8})"\}$')


@dataclass(frozen=True)
class DamagedLine:
    """A complete line of ``results.jsonl`` that failed its check: line number (from 1), byte
    offset of its start (in the decompressed data of a ``.gz``), length with the newline, reason."""

    line_no: int
    offset: int
    length: int
    reason: str

    def describe(self):
        return f"line {self.line_no} (byte {self.offset}, {self.length} bytes): {self.reason}"


@dataclass(frozen=True, repr=False)
class ResultsContent:
    """What :func:`read_results` found: records in file order and the state of the file's end."""

    records: list
    valid_bytes: int
    truncated_tail: bytes = b""
    duplicates: int = 0
    #: :class:`DamagedLine` s (only with ``skip_damaged``; otherwise the first one raises).
    damaged: tuple = ()
    #: False for a file written before line checksums existed.
    checksummed: bool = True
    #: Number of complete lines (damaged ones included) before the truncated tail.
    lines: int = 0

    @property
    def by_key(self):
        """``{(bridge, train): record}``, the last line of a key winning."""
        return {record_key(r): r for r in self.records}

    def describe_tail(self):
        """The truncated last line: its number, byte offset and length."""
        return f"line {self.lines + 1} (byte {self.valid_bytes}, {len(self.truncated_tail)} bytes, no newline)"

    def __repr__(self):
        tail = f", truncated tail of {len(self.truncated_tail)} bytes" if self.truncated_tail else ""
        bad = f", {len(self.damaged)} damaged lines" if self.damaged else ""
        return f"ResultsContent({len(self.records)} records{tail}{bad})"


def _gunzip(data, label):
    """Decompress every gzip member of ``data``, each checked against its CRC-32 and length.

    Nothing of a damaged file is used: what was decompressed before a failed check is unverified.
    """
    if not data:
        raise InputError(f"{label}: empty, not gzip data (a file cut short?); nothing was read from it")
    out, pos, step = [], 0, 1 << 16
    while pos < len(data):
        if not data[pos:].strip(b"\0"):
            break  # zero padding after the last member, as gzip(1) allows
        d = zlib.decompressobj(wbits=31)
        member, at = [], pos
        try:
            while at < len(data) and not d.eof:
                member.append(d.decompress(data[at:at + step]))
                at += step
        except zlib.error as exc:
            raise InputError(f"{label}: damaged gzip data in compressed bytes {at}..{min(at + step, len(data))} of "
                             f"{len(data)} (member at byte {pos}: {exc}); nothing was read from it") from None
        if not d.eof:
            raise InputError(f"{label}: the gzip data is cut short (the member at byte {pos} ends at byte "
                             f"{len(data)} without its end and checksum); nothing was read from it")
        out.append(b"".join(member))
        pos = len(data) - len(d.unused_data)
    return b"".join(out)


def _check_line(line):
    """``(record, None)`` for a line whose checksum holds, else ``(None, reason)``."""
    m = _CHECK_RE.search(line)
    if m is None:
        return None, "no line checksum"
    body = line[:m.start()] + b"}"
    if f"{zlib.crc32(body):08x}".encode() != m.group(1):
        return None, "checksum mismatch"
    try:
        return json.loads(body), None
    except (ValueError, UnicodeDecodeError):
        return None, "not valid JSON"


def read_results(path, skip_damaged=False):
    """Read a ``results.jsonl`` (or a gzip-compressed ``results.jsonl.gz``, as shipped in
    ``results/study``), every line checked against its checksum.

    A last line without its newline (a write cut short) is not a record: it is returned as
    ``truncated_tail``, for the caller to name (:meth:`ResultsContent.describe_tail`).

    Parameters
    ----------
    skip_damaged : bool
        Return damaged lines in ``damaged`` (the study drops them and runs those cases again)
        instead of raising.

    Raises
    ------
    InputError
        A damaged line (checksum mismatch, no checksum in a checksummed file, not JSON, no
        ``bridge`` and ``train``), unless ``skip_damaged``; a damaged or cut-short gzip file always.
    """
    p = Path(path)
    label = f"results {str(p)!r}"
    refuse_special(p, label)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        return ResultsContent(records=[], valid_bytes=0)
    except OSError as exc:
        raise InputError(f"{label}: cannot read ({exc.strerror or exc})") from None
    if p.suffix == ".gz":
        data = _gunzip(data, label)
    end = data.rfind(b"\n") + 1
    body, tail = data[:end], data[end:]
    lines = body.split(b"\n")[:-1]
    checksummed = any(_CHECK_RE.search(line) for line in lines)
    records, seen, dup, damaged, offset = [], set(), 0, [], 0
    for no, line in enumerate(lines, start=1):
        at, offset = offset, offset + len(line) + 1
        if not line.strip():
            continue
        if checksummed:
            rec, why = _check_line(line)
        else:
            try:
                rec, why = json.loads(line), None
            except (ValueError, UnicodeDecodeError):
                rec, why = None, "not valid JSON"
        if why is None:
            if not isinstance(rec, dict) or "bridge" not in rec or "train" not in rec:
                why = "lacks 'bridge' and 'train'"
            elif not isinstance(rec["bridge"], str) or not isinstance(rec["train"], str):
                why = f"'bridge' and 'train' must be names (text), got {rec['bridge']!r} and {rec['train']!r}"
            elif not checksummed and CHECK_KEY in rec:
                why = "its checksum is damaged"
        if why is not None:
            bad = DamagedLine(no, at, len(line) + 1, why)
            if not skip_damaged:
                raise InputError(f"{label}: damaged {bad.describe()}; a study resumed with the same --out drops "
                                 f"damaged lines and computes those cases again")
            damaged.append(bad)
            continue
        rec.pop(CHECK_KEY, None)
        k = record_key(rec)
        dup += k in seen
        seen.add(k)
        records.append(rec)
    return ResultsContent(records=records, valid_bytes=end, truncated_tail=tail, duplicates=dup,
                          damaged=tuple(damaged), checksummed=checksummed or not lines, lines=len(lines))


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
    """One result line: the record's JSON with its CRC-32 as the last member, and a newline."""
    body = json.dumps({k: v for k, v in rec.items() if k != CHECK_KEY}, allow_nan=False,
                      separators=(",", ":")).encode()
    return body[:-1] + b',"%s":"%08x"}\n' % (CHECK_KEY.encode(), zlib.crc32(body))


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
    """Append-only writer of ``results.jsonl``: one checksummed line per record, flushed and fsynced.

    Opening drops a truncated last line and every damaged line (the file is rewritten without
    them, so those cases run again) and gives a file written without line checksums its checksums;
    ``notes`` names each drop in one line (line number, byte offset, reason). With
    ``drop_errors=True`` it also drops the ``status: "error"`` lines so those cases run again.
    A context manager; :meth:`finish` is idempotent.
    """

    def __init__(self, path, drop_errors=False):
        self.path = Path(path)
        content = read_results(self.path, skip_damaged=True)
        keep = content.records
        name = self.path.name
        self.dropped_truncated = bool(content.truncated_tail)
        self.dropped_damaged = len(content.damaged)
        self.notes = [f"dropped {name} {d.describe()}; that case runs again" for d in content.damaged]
        if content.truncated_tail:
            self.notes.append(f"dropped a truncated last {content.describe_tail()} of {name}; that case runs again")
        upgrade = bool(keep) and not content.checksummed
        if upgrade:
            self.notes.append(f"added line checksums to the {len(keep)} lines of {name} written without them")
        self.dropped_errors = 0
        if drop_errors:
            keep = [r for r in content.records if r.get("status") != "error"]
            self.dropped_errors = len(content.records) - len(keep)
        if self.dropped_truncated or self.dropped_damaged or self.dropped_errors or upgrade:
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
