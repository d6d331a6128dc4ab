"""The parametric study of paper Section 3.3 and the lower-bound fit of Section 4.2.1.

Study
    Every (bridge, train) case of the 1110-bridge field (:func:`adm_sim.bridge.parametric_field`,
    185 (L, n0) pairs x 6 mass functions, Table 2 damping) times the four trains is calibrated with
    :func:`adm_calib.calibrate.calibrate` (Section 4, steps 1-3). Cases run as tasks on a
    ``dask.distributed`` cluster: a loopback-only :class:`~distributed.LocalCluster` by default, or
    an existing scheduler. The client process appends one JSON object per finished case to
    ``results.jsonl`` (write, flush, ``os.fsync``), so a crash loses at most the cases still
    running; a rerun skips the cases already in the file (key: bridge name and train) and drops a
    truncated last line. A case that raises is recorded with ``status: "error"``.

Lower-bound fit (Section 4.2.1, Eq. 20)
    Per train and mass function, the n0 axis is cut into intervals (0.5 Hz from 2 to 8 Hz, then
    boundaries at 9, 10, 11, 13, 16 and 21 Hz); the smallest Δζ_VBI of each interval, at the n0 of
    the case that has it, is a data point; a cubic ``dz = a n0^3 + b n0^2 + c n0 + d`` is fitted to
    the data points by linear least squares (:func:`numpy.polyfit`), with R² and the residuals
    ``data - fit`` about the data points. The function holds from 2.1 Hz to its first real root
    above 2.1 Hz (the "upper limit"), and is 0 beyond. Cases above 21 Hz are not used (paper:
    too few results there). Cases without Δζ_VBI (no reasonable peak, no match, errors) are left
    out and counted; optionally also the cases the paper settled by eye (largest MLM value at an
    end of the speed range, associated DIM value not a local maximum).

Imports: numpy and scipy; dask only inside :func:`run_study`, matplotlib only inside the
``plot_*`` functions.
"""

from __future__ import annotations

import contextlib
import csv
import datetime as _dt
import io
import json
import math
import os
import platform
import re
import signal
import sys
import time
from collections import Counter
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError, check_range

from adm_calib.reference import STUDY_TRAINS, canonical_train_name

#: Frequency indices of the field: 1 = LB power law ... 5 = UB power law (Section 3.1.1).
FREQ_INDICES = (1, 2, 3, 4, 5)
#: Spans of the field (m).
SPAN_RANGE_M = (4, 40)
#: Mass functions of Table 1.
MASS_FUNCTION_NAMES = ("mu1", "mu2", "mu3", "mu4", "mu5", "mu6")
#: Interval boundaries of Section 4.2.1 (Hz): 0.5 Hz from 2 to 8 Hz, then 9, 10, 11, 13, 16, 21.
INTERVAL_EDGES_HZ = tuple(float(x) for x in np.arange(2.0, 8.0 + 1e-9, 0.5)) + (9.0, 10.0, 11.0, 13.0, 16.0, 21.0)
#: Lower validity limit of the lower-bound functions (Hz), Section 4.2.2.
LOWER_LIMIT_HZ = 2.1
RESULTS_NAME = "results.jsonl"
META_NAME = "study.json"
LOCK_NAME = ".study.lock"
META_FORMAT = "adm-calib-study/1"
#: Environment of the worker processes: one BLAS/OpenMP thread each (one case per core).
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

_NAME_RE = re.compile(r"^L(?P<span>\d+(?:\.\d+)?)-f(?P<fi>\d)-(?P<mf>mu\d)$")


# ====================================================================== cases
@dataclass(frozen=True)
class StudyCase:
    """One (bridge, train) pair of the study; ``bridge`` is an :class:`adm_sim.bridge.Bridge`."""

    bridge: object
    train: str
    mass_function: str
    freq_index: int

    @property
    def key(self):
        return (self.bridge.name, self.train)

    def __repr__(self):
        return f"StudyCase({self.bridge.name} x {self.train}, n0={self.bridge.n0_hz:.3f} Hz)"


def parse_bridge_name(name):
    """``"L15-f3-mu2"`` -> ``(15.0, 3, "mu2")`` (span in m, frequency index, mass function)."""
    m = _NAME_RE.match(str(name))
    if not m:
        raise InputError(f"bridge: {name!r} is not a field bridge name like 'L15-f3-mu2'")
    return float(m["span"]), int(m["fi"]), m["mf"]


def canonical_trains(names, field="trains"):
    """Study train names for ``names`` (duplicates dropped, order kept); ``field`` names the input."""
    out = []
    for t in names:
        try:
            name = canonical_train_name(t)
        except InputError:
            raise InputError(f"{field}: {t!r} is not a study train; allowed {', '.join(STUDY_TRAINS)}") from None
        if name not in out:
            out.append(name)
    return out


def select_cases(trains=STUDY_TRAINS, mass_functions=MASS_FUNCTION_NAMES, spans_m=SPAN_RANGE_M,
                 freq_indices=FREQ_INDICES):
    """The study cases of the field filtered by the arguments, in a fixed order.

    Parameters
    ----------
    trains : sequence of str
        Study trains (ICE-2, Eurostar, Railjet, ICE-4; case and dashes ignored).
    mass_functions : sequence of str
        Subset of ``mu1``..``mu6`` (Table 1).
    spans_m : (float, float)
        Inclusive span range (m), within [4, 40].
    freq_indices : sequence of int
        Subset of 1..5 (LB, mid, fit, mid, UB power law of n0, Section 3.1.1).

    Returns
    -------
    list of StudyCase
        Field order (span, frequency index, mass function), the trains innermost.
    """
    tr = canonical_trains(trains)
    for m in mass_functions:
        if m not in MASS_FUNCTION_NAMES:
            raise InputError(f"mass_functions: {m!r} is unknown; allowed {', '.join(MASS_FUNCTION_NAMES)}")
    lo, hi = (check_range("spans", s, "m", *SPAN_RANGE_M) for s in spans_m)
    if lo > hi:
        raise InputError(f"spans: {lo:g}:{hi:g} m is empty; give lo:hi with lo <= hi in [4, 40] m")
    for fi in freq_indices:
        if fi not in FREQ_INDICES:
            raise InputError(f"freq_index: {fi!r} is out of range; allowed integer in [1, 5]")
    mfs, fis = set(mass_functions), set(freq_indices)
    cases = []
    for b in _field():
        L, fi, mf = parse_bridge_name(b.name)
        if mf in mfs and fi in fis and lo <= L <= hi:
            cases.extend(StudyCase(bridge=b, train=t, mass_function=mf, freq_index=fi) for t in tr)
    return cases


@lru_cache(maxsize=1)
def _field():
    from adm_sim.bridge import parametric_field

    return tuple(parametric_field())


@lru_cache(maxsize=8)
def _train(name):
    from adm_sim.trains import load_train

    return load_train(name)


# ====================================================================== settings and one case
@dataclass(frozen=True)
class StudySettings:
    """Calibration settings shared by every case of one study (all runs into one results file).

    ``speeds`` is the MLM speed grid ``start:stop:step`` in km/h (Section 3.3: 160:350:1),
    ``dim_grid`` and ``steps_per_period`` as for :class:`~adm_calib.calibrate.CalibrationOptions`
    (``None``: the core's default). The adapted MLM curve is never computed (not needed here).
    """

    speeds: str = "160:350:1"
    dim_grid: str = "paper"
    steps_per_period: float | None = None

    def speeds_kmh(self):
        from adm_sim.sweep import parse_speeds

        return parse_speeds(self.speeds)

    def calibration_options(self):
        from adm_sim.stepping import StepOptions

        from adm_calib.calibrate import CalibrationOptions

        step = None if self.steps_per_period is None else StepOptions(steps_per_period=self.steps_per_period)
        return CalibrationOptions(dim_grid=self.dim_grid, step=step)

    def to_dict(self):
        return asdict(self)


def case_identity(bridge, train, mass_function=None, freq_index=None):
    """The identity fields of a result line (SI except ``mu_t_m`` in t/m and ``zeta_pct`` in %)."""
    if mass_function is None or freq_index is None:
        _, freq_index, mass_function = parse_bridge_name(bridge.name)
    return {
        "bridge": bridge.name, "train": train, "span_m": float(bridge.span_m), "n0_hz": float(bridge.n0_hz),
        "mu_t_m": float(bridge.mass_per_length_kg_m) / 1000.0, "mass_function": mass_function,
        "freq_index": int(freq_index), "bridge_type": bridge.bridge_type,
        "zeta_pct": 100.0 * float(bridge.damping_ratio),
    }


_KEEP = ("status", "message", "delta_zeta_vbi_pct", "delta_zeta_adm_pct", "delta_zeta_eada_pct", "delta_zeta_lb_pct",
         "mlm_peak", "dim_peak", "adapted_mlm_peak", "mlm_max_at_range_end", "dim_is_local_max",
         "dim_max_at_range_end", "dim_speed_shift_kmh", "adapted_is_local_max", "association_rule", "solver",
         "dim_grid", "dim_refined", "ds_m", "timings_s")


def result_record(case, result, wall_s):
    """One result line from a :class:`~adm_calib.calibrate.CalibrationResult` (Δζ in %)."""
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


def run_case(case, settings=StudySettings()):
    """Calibrate one case; never raises for errors of the case itself (they become an error record).

    This is the task run on the workers: it needs only this package importable there.
    """
    from adm_calib.calibrate import calibrate

    t0 = time.perf_counter()
    try:
        res = calibrate(case.bridge, _train(case.train), speeds_kmh=settings.speeds_kmh(),
                        options=settings.calibration_options(), progress=False, adapted_curve=False)
        rec = result_record(case, res, time.perf_counter() - t0)
    except Exception as exc:  # recorded, not lost: the study goes on
        rec = error_record(case, exc, time.perf_counter() - t0)
    rec["host"] = platform.node()
    rec["pid"] = os.getpid()
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
    """Read a ``results.jsonl``; a last line without its newline (a write cut short) is ignored.

    Raises
    ------
    InputError
        A complete line that is not a JSON object with ``bridge`` and ``train``.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        return ResultsContent(records=[], valid_bytes=0)
    except OSError as exc:
        raise InputError(f"results {str(p)!r}: cannot read ({exc.strerror})") from None
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
    """Write ``data`` (bytes) to ``path`` through a temporary file and ``os.replace``."""
    p = Path(path)
    tmp = p.with_name(p.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, p)
    _fsync_dir(p.parent)


def _line(rec):
    return (json.dumps(rec, allow_nan=False, separators=(",", ":")) + "\n").encode()


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
        held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            self._f.write(_line(rec))
            self._f.flush()
            os.fsync(self._f.fileno())
            self.records[record_key(rec)] = rec
            self.appended += 1
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)

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
    import fcntl

    f = open(Path(out_dir) / LOCK_NAME, "a")
    try:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(f"out: {str(out_dir)!r} is in use by another running study") from None
        yield
    finally:
        f.close()


def _now():
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def versions():
    """Versions of the software that computes the study."""
    from importlib import metadata

    out = {"python": platform.python_version(), "platform": platform.platform()}
    for dist in ("adm-sim", "numpy", "scipy", "dask", "distributed"):
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
    if not isinstance(meta, dict) or meta.get("format") != META_FORMAT:
        raise InputError(f"study metadata {str(p)!r}: not a {META_FORMAT} file")
    return meta


def _write_meta(out_dir, meta):
    _atomic_write(Path(out_dir) / META_NAME, (json.dumps(meta, indent=2) + "\n").encode())


# ====================================================================== the study on dask
@dataclass(repr=False)
class StudyRun:
    """Outcome of one :func:`run_study` call (one run into a results file)."""

    out_dir: Path
    selected: int
    already_done: int
    submitted: int = 0
    completed: int = 0
    statuses: Counter = field(default_factory=Counter)
    interrupted: bool = False
    dropped_truncated_line: bool = False
    dropped_error_lines: int = 0
    wall_s: float = 0.0
    scheduler: str = ""
    workers: list = field(default_factory=list)

    @property
    def errors(self):
        return self.statuses.get("error", 0)

    def summary(self):
        st = ", ".join(f"{k} {v}" for k, v in sorted(self.statuses.items())) or "none"
        lines = [f"study: {self.completed} of {self.submitted} submitted cases finished in {self.wall_s:.1f} s "
                 f"({st}); {self.already_done} of {self.selected} selected were already done"]
        if self.dropped_truncated_line:
            lines.append("study: dropped a truncated last line of results.jsonl (that case ran again)")
        if self.dropped_error_lines:
            lines.append(f"study: dropped {self.dropped_error_lines} error lines to run those cases again")
        done = self.already_done + self.completed
        lines.append(f"study: {done} of {self.selected} selected cases in {self.out_dir / RESULTS_NAME}")
        if self.interrupted:
            lines.append("study: interrupted; rerun the same command to resume")
        return "\n".join(lines)

    def __repr__(self):
        return (f"StudyRun({self.completed}/{self.submitted} cases, {self.already_done} skipped, "
                f"interrupted={self.interrupted})")


def local_cluster(workers=2):
    """A loopback-only :class:`distributed.LocalCluster`: ``workers`` processes of one thread each.

    Scheduler, nannies and workers listen on 127.0.0.1 only (also their small HTTP servers for
    health and metrics, on free ports); no dashboard; one BLAS thread per worker (set in the
    environment before the worker process starts).
    """
    import logging

    import dask
    from distributed import LocalCluster

    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
    env.update(WORKER_ENV)
    with dask.config.set({"distributed.nanny.pre-spawn-environ": env}), _workers_ignore_sigint():
        return LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True, host="127.0.0.1",
                            dashboard_address=None, worker_dashboard_address=None, silence_logs=logging.CRITICAL,
                            env=dict(WORKER_ENV),
                            # the scheduler's health/metrics HTTP routes: loopback, any free port
                            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})


@contextlib.contextmanager
def _workers_ignore_sigint():
    """Spawn the worker processes with SIGINT ignored (the disposition survives ``exec``).

    Ctrl-C on a terminal reaches the whole process group; the client alone then stops the
    study and closes the cluster, instead of every worker printing a KeyboardInterrupt trace.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _worker_env():
    return {k: os.environ.get(k) for k in WORKER_ENV}


def run_study(out_dir, cases, settings=StudySettings(), workers=2, scheduler=None, limit=None, progress=None,
              retry_errors=False, options=None):
    """Run the study cases not yet in ``out_dir/results.jsonl`` on a dask cluster.

    Parameters
    ----------
    out_dir : path
        Study directory (created); holds ``results.jsonl`` and ``study.json``.
    cases : list of StudyCase
        Selected cases (:func:`select_cases`); those already in the results file are skipped.
    settings : StudySettings
        Must equal the settings of earlier runs into ``out_dir``.
    workers : int
        Worker processes of the local cluster (ignored with ``scheduler``).
    scheduler : str, optional
        Address of a running scheduler (``tcp://127.0.0.1:8786``) instead of a local cluster.
    limit : int, optional
        Run at most this many of the pending cases (the first ones in the order of ``cases``).
    progress : bool or None
        tqdm bar on stderr; ``None``: only on a terminal.
    retry_errors : bool
        Drop earlier ``status: "error"`` lines and run those cases again.
    options : dict, optional
        Command-line options recorded in ``study.json``.

    Returns
    -------
    StudyRun
        ``interrupted`` is True after Ctrl-C or SIGTERM (everything finished is kept).
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"out: {str(out)!r} is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    with _exclusive(out):
        meta = read_meta(out)
        if meta is not None and meta.get("settings") != settings.to_dict():
            old, new = meta.get("settings"), settings.to_dict()
            diff = ", ".join(f"{k} {old.get(k)!r} -> {new[k]!r}" for k in new if old.get(k) != new[k])
            raise InputError(f"settings: the study in {str(out)!r} was computed with other settings ({diff}); "
                             f"use another --out")
        if meta is None:
            meta = {"format": META_FORMAT, "created": _now(), "settings": settings.to_dict(), "runs": []}
        with ResultsWriter(out / RESULTS_NAME, drop_errors=retry_errors) as writer:
            pending = [c for c in cases if c.key not in writer.records]
            if limit is not None:
                pending = pending[:int(limit)]
            run = StudyRun(out_dir=out, selected=len(cases), already_done=len(cases) - len(
                [c for c in cases if c.key not in writer.records]), submitted=len(pending),
                dropped_truncated_line=writer.dropped_truncated, dropped_error_lines=writer.dropped_errors)
            entry = {"started": _now(), "finished": None, "options": dict(options or {}), "versions": versions(),
                     "selected": run.selected, "already_done": run.already_done, "submitted": run.submitted}
            meta["runs"].append(entry)
            _write_meta(out, meta)
            t0 = time.perf_counter()
            try:
                if pending:
                    _run_on_dask(pending, settings, writer, run, workers, scheduler, progress, entry)
            except KeyboardInterrupt:
                run.interrupted = True
            finally:
                run.wall_s = time.perf_counter() - t0
                run.completed = writer.appended  # the lines this run wrote, whatever interrupted it
                entry.update({"finished": _now(), "completed": run.completed, "statuses": dict(run.statuses),
                              "interrupted": run.interrupted, "wall_s": round(run.wall_s, 3),
                              "dropped_truncated_line": run.dropped_truncated_line,
                              "dropped_error_lines": run.dropped_error_lines})
                _write_meta(out, meta)
    return run


def _run_on_dask(pending, settings, writer, run, workers, scheduler, progress, entry):
    from distributed import Client, as_completed
    from tqdm import tqdm

    cluster = client = bar = None
    futures = []
    try:
        if scheduler is None:
            cluster = local_cluster(workers)
            client = Client(cluster, set_as_default=False)
        else:
            try:
                client = Client(scheduler, timeout="10s", set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise InputError(f"scheduler: cannot connect to {scheduler!r} ({exc})") from None
        info = client.scheduler_info()
        run.scheduler = info.get("address", "")
        run.workers = sorted(info.get("workers", {}))
        entry["cluster"] = {"scheduler": run.scheduler, "local": cluster is not None,
                            "workers": {a: {"nanny": w.get("nanny"), "nthreads": w.get("nthreads")}
                                        for a, w in info.get("workers", {}).items()},
                            "worker_env": client.run(_worker_env)}
        # longest cases first (cost grows with n0: the time step follows the highest mode)
        order = sorted(pending, key=lambda c: -c.bridge.n0_hz)
        by_future = {}
        for c in order:
            fut = client.submit(run_case, c, settings, pure=False, key=f"case-{c.bridge.name}-{c.train}-{os.getpid()}")
            by_future[fut] = c
            futures.append(fut)
        bar = tqdm(total=run.selected, initial=run.already_done, unit="case", desc="study", file=sys.stderr,
                   disable=not (sys.stderr.isatty() if progress is None else progress), dynamic_ncols=True)
        for fut in as_completed(futures, loop=client.loop):
            case = by_future.pop(fut)
            try:
                rec = fut.result()
            except Exception as exc:  # the task never returned (worker died, cancelled)
                rec = error_record(case, exc)
            writer.append(rec)
            run.completed += 1
            run.statuses[rec["status"]] += 1
            fut.release()
            bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        if client is not None:
            with contextlib.suppress(Exception):
                client.cancel([f for f in futures if not f.done()])
            with contextlib.suppress(Exception):
                client.close(timeout=10)
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=20)


# ====================================================================== lower-bound fit
@dataclass(frozen=True)
class IntervalMinimum:
    """Smallest Δζ (%) in one n0 interval ``[lo_hz, hi_hz)`` and the case that has it."""

    lo_hz: float
    hi_hz: float
    n_cases: int
    n0_hz: float
    delta_zeta_pct: float
    bridge: str = ""


def interval_minima(n0_hz, delta_zeta_pct, names=None, edges_hz=INTERVAL_EDGES_HZ):
    """Data points of Section 4.2.1: the minimum Δζ of each n0 interval.

    Intervals are ``[e_k, e_k+1)``, the last one closed; empty intervals give no point; n0
    outside ``[edges_hz[0], edges_hz[-1]]`` is not used. Ties go to the lowest n0.

    Parameters
    ----------
    n0_hz, delta_zeta_pct : array_like (n,)
    names : sequence of str (n,), optional
        Bridge names carried into the result.

    Returns
    -------
    list of IntervalMinimum
    """
    x = np.asarray(n0_hz, dtype=float)
    y = np.asarray(delta_zeta_pct, dtype=float)
    names = list(names) if names is not None else [""] * x.size
    out = []
    e = np.asarray(edges_hz, dtype=float)
    for k in range(e.size - 1):
        last = k == e.size - 2
        sel = np.flatnonzero((x >= e[k]) & ((x <= e[k + 1]) if last else (x < e[k + 1])))
        if sel.size == 0:
            continue
        sel = sel[np.lexsort((x[sel], y[sel]))]
        i = int(sel[0])
        out.append(IntervalMinimum(lo_hz=float(e[k]), hi_hz=float(e[k + 1]), n_cases=int(sel.size),
                                   n0_hz=float(x[i]), delta_zeta_pct=float(y[i]), bridge=str(names[i])))
    return out


def first_root_hz(coefficients, lower_limit_hz=LOWER_LIMIT_HZ):
    """First real root of the cubic Eq. (20) above ``lower_limit_hz`` (Hz); ``inf`` if none."""
    roots = np.roots(np.asarray(coefficients, dtype=float))
    real = sorted(r.real for r in roots if abs(r.imag) < 1e-9 * max(1.0, abs(r)) and r.real > lower_limit_hz)
    return float(real[0]) if real else math.inf


@dataclass(frozen=True, repr=False)
class CubicFit:
    """Least-squares cubic of Eq. (20) through the interval minima (Δζ in %, n0 in Hz).

    ``residuals_pct`` (n_points,) are ``data - fit``; ``upper_limit_hz`` is the first root above
    2.1 Hz.
    """

    coefficients: tuple
    r2: float
    n0_hz: np.ndarray
    delta_zeta_pct: np.ndarray
    residuals_pct: np.ndarray
    upper_limit_hz: float

    @property
    def max_res_pct(self):
        return float(self.residuals_pct.max())

    @property
    def min_res_pct(self):
        return float(self.residuals_pct.min())

    def value_pct(self, n0_hz):
        """The lower bound: Eq. (20) up to the upper limit, 0 beyond."""
        n0 = np.asarray(n0_hz, dtype=float)
        return np.where(n0 >= self.upper_limit_hz, 0.0, np.polyval(self.coefficients, n0))

    def __repr__(self):
        a, b, c, d = self.coefficients
        return (f"CubicFit(a={a:.4g}, b={b:.4g}, c={c:.4g}, d={d:.4g}, R2={self.r2:.4f}, "
                f"upper limit {self.upper_limit_hz:.2f} Hz)")


def fit_cubic(n0_hz, delta_zeta_pct, lower_limit_hz=LOWER_LIMIT_HZ):
    """Fit Eq. (20) to data points by linear least squares (:func:`numpy.polyfit`, degree 3).

    ``R² = 1 - SS_res / SS_tot`` about the data points. Needs at least 4 points.
    """
    x = np.asarray(n0_hz, dtype=float)
    y = np.asarray(delta_zeta_pct, dtype=float)
    if x.size < 4:
        raise InputError(f"fit: {x.size} data points; a cubic needs at least 4")
    coef = np.polyfit(x, y, 3)
    res = y - np.polyval(coef, x)
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum(res**2)) / ss_tot if ss_tot > 0 else float("nan")
    return CubicFit(coefficients=tuple(float(c) for c in coef), r2=r2, n0_hz=x, delta_zeta_pct=y,
                    residuals_pct=res, upper_limit_hz=first_root_hz(coef, lower_limit_hz))


@dataclass(frozen=True, repr=False)
class LowerBoundFit:
    """Fit of one train and mass function, next to the published function (Tables B1-B4)."""

    train: str
    mass_function: str
    n_cases: int
    minima: list
    fit: CubicFit | None
    published: object = None
    note: str = ""

    def __repr__(self):
        return f"LowerBoundFit({self.train} {self.mass_function}: {self.n_cases} cases, {self.fit!r})"


#: Exclusion reasons used by :func:`fit_study` (key -> text).
EXCLUSIONS = {
    "error": "status error (the case raised)",
    "no_dz": "no dz_VBI (no reasonable peak, not bracketed or no match)",
    "mlm_max_at_range_end": "largest MLM value at an end of the speed range (--exclude-flagged)",
    "dim_not_local_max": "associated DIM value not a local maximum (--exclude-flagged)",
    "above_21hz": "n0 above 21 Hz (not fitted, Section 4.2.1)",
    "other_train": "not a study train",
}


@dataclass(repr=False)
class StudyFit:
    """Lower-bound fits of a study, ``fits[(train, mass_function)]``, with the excluded cases counted."""

    fits: dict
    records_used: list
    n_records: int
    excluded: Counter
    exclude_flagged: bool
    duplicates: int = 0

    def to_text(self):
        head = (f"{'train':9}{'mass':5}{'':6}{'cases':>6}{'pts':>4}{'a':>11}{'b':>11}{'c':>11}{'d':>11}"
                f"{'upper Hz':>9}{'R2':>8}{'max res':>9}{'min res':>9}")
        lines = ["Lower-bound functions, Eq. (20): dz = a n0^3 + b n0^2 + c n0 + d (dz in %, n0 in Hz), "
                 "Section 4.2.1; 'paper' = Tables B1-B4", head, "-" * len(head)]

        def nums(a, b, c, d, up, r2, mx, mn):
            return f"{a:11.4g}{b:11.4g}{c:11.4g}{d:11.4g}{up:9.2f}{r2:8.4f}{mx:9.4f}{mn:9.4f}"

        for (t, m), f in self.fits.items():
            pre = f"{t:9}{m:5}{'fit':6}{f.n_cases:6d}{len(f.minima):4d}"
            if f.fit is None:
                lines.append(f"{pre}  {f.note}")
            else:
                c = f.fit
                lines.append(pre + nums(*c.coefficients, c.upper_limit_hz, c.r2, c.max_res_pct, c.min_res_pct))
            p = f.published
            if p is not None:
                lines.append(f"{'':14}{'paper':6}{'':10}" + nums(p.a, p.b, p.c, p.d, p.upper_limit_hz, p.r2,
                                                                   p.max_res_pct, p.min_res_pct))
        used = len(self.records_used)
        lines.append(f"cases: {self.n_records} read, {used} used"
                     + (f", {self.duplicates} duplicate lines (last kept)" if self.duplicates else ""))
        for k, n in self.excluded.items():
            lines.append(f"  excluded {n:5d}: {EXCLUSIONS.get(k, k)}")
        return "\n".join(lines)

    def to_csv(self):
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        cols = ["a", "b", "c", "d", "upper_limit_hz", "r2", "max_res_pct", "min_res_pct"]
        w.writerow(["train", "mass_function", "n_cases", "n_points"] + cols + [f"paper_{c}" for c in cols] + ["note"])
        for (t, m), f in self.fits.items():
            if f.fit is None:
                fit = [""] * len(cols)
            else:
                c = f.fit
                fit = [*(f"{v:.6g}" for v in c.coefficients), f"{c.upper_limit_hz:.4f}", f"{c.r2:.4f}",
                       f"{c.max_res_pct:.5f}", f"{c.min_res_pct:.5f}"]
            p = f.published
            pub = [""] * len(cols) if p is None else [f"{getattr(p, c):.6g}" for c in cols]
            w.writerow([t, m, f.n_cases, len(f.minima)] + fit + pub + [f.note])
        return buf.getvalue()

    def minima_csv(self):
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["train", "mass_function", "lo_hz", "hi_hz", "n_cases", "n0_hz", "delta_zeta_pct", "bridge",
                    "fit_pct", "residual_pct"])
        for (t, m), f in self.fits.items():
            for p in f.minima:
                fv = "" if f.fit is None else float(np.polyval(f.fit.coefficients, p.n0_hz))
                w.writerow([t, m, f"{p.lo_hz:g}", f"{p.hi_hz:g}", p.n_cases, f"{p.n0_hz:.4f}",
                            f"{p.delta_zeta_pct:.5f}", p.bridge, "" if fv == "" else f"{fv:.5f}",
                            "" if fv == "" else f"{p.delta_zeta_pct - fv:.5f}"])
        return buf.getvalue()


def _exclusion(rec, exclude_flagged):
    if rec.get("status") == "error":
        return "error"
    if rec.get("status") != "ok" or rec.get("delta_zeta_vbi_pct") is None:
        return "no_dz"
    if exclude_flagged and rec.get("mlm_max_at_range_end"):
        return "mlm_max_at_range_end"
    if exclude_flagged and rec.get("dim_is_local_max") is False:
        return "dim_not_local_max"
    return None


def fit_study(records, exclude_flagged=False, edges_hz=INTERVAL_EDGES_HZ):
    """Lower-bound functions per train and mass function from study records (Section 4.2.1).

    Parameters
    ----------
    records : iterable of dict
        Result lines (``train``, ``mass_function``, ``n0_hz``, ``status``, ``delta_zeta_vbi_pct``,
        flags); for a repeated (bridge, train) key the last line counts.
    exclude_flagged : bool
        Also leave out the cases the paper settled by eye.

    Returns
    -------
    StudyFit
    """
    from adm_calib.reference import lower_bound_table

    records = list(records)
    by_key = {record_key(r): r for r in records}
    dup = len(records) - len(by_key)
    excluded = Counter()
    used = []
    groups = {}
    for rec in by_key.values():
        why = _exclusion(rec, exclude_flagged)
        if why is None and rec["train"] not in STUDY_TRAINS:
            why = "other_train"
        if why is not None:
            excluded[why] += 1
            continue
        used.append(rec)
        groups.setdefault((rec["train"], rec["mass_function"]), []).append(rec)
    table = lower_bound_table()
    fits = {}
    order = {t: i for i, t in enumerate(STUDY_TRAINS)}
    for key in sorted(groups, key=lambda k: (order[k[0]], k[1])):
        t, m = key
        recs = groups[key]
        x = np.array([r["n0_hz"] for r in recs], dtype=float)
        y = np.array([r["delta_zeta_vbi_pct"] for r in recs], dtype=float)
        over = int(np.count_nonzero(x > edges_hz[-1]))
        if over:
            excluded["above_21hz"] += over
        minima = interval_minima(x, y, [r["bridge"] for r in recs], edges_hz)
        fit, note = None, ""
        if len(minima) >= 4:
            fit = fit_cubic([p.n0_hz for p in minima], [p.delta_zeta_pct for p in minima])
        else:
            note = f"only {len(minima)} interval minima; a cubic needs 4"
        fits[key] = LowerBoundFit(train=t, mass_function=m, n_cases=len(recs), minima=minima, fit=fit,
                                  published=table.get(t, {}).get(m), note=note)
    return StudyFit(fits=fits, records_used=used, n_records=len(by_key), excluded=excluded,
                    exclude_flagged=exclude_flagged, duplicates=dup)


# ====================================================================== figures (matplotlib, Agg)
_MF_COLOURS = {"mu1": "#4b0082", "mu2": "#8a2be2", "mu3": "#c39bd3",
               "mu4": "#b35900", "mu5": "#ff8c00", "mu6": "#ffc266"}


def _pyplot():
    from adm_calib.plots import _pyplot as pp

    return pp()


def plot_dz_vs_span(records, path):
    """Analogue of Fig. 16: Δζ_VBI against span per train with the Eurocode ADM curve."""
    from adm_calib.reference import adm_delta_zeta_pct

    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True, squeeze=False)
    L = np.linspace(4.0, 40.0, 361)
    adm = [adm_delta_zeta_pct(x) for x in L]
    for ax, t in zip(axes.flat, STUDY_TRAINS):
        for m in MASS_FUNCTION_NAMES:
            pts = [(r["span_m"], r["delta_zeta_vbi_pct"]) for r in records if r["train"] == t and r["mass_function"] == m]
            if pts:
                a = np.array(pts)
                ax.plot(a[:, 0], a[:, 1], ls="none", marker="o", ms=3, color=_MF_COLOURS[m], label=m)
        ax.plot(L, adm, color="grey", lw=2, label="ADM (EN 1991-2)")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_title(t)
        ax.set_ylabel("dz (%)")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("span L (m)")
    _legend(axes[0, 0], fontsize=7, ncol=2)
    fig.suptitle("Computed additional damping vs the Eurocode ADM (Fig. 16 analogue)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _legend(ax, **kw):
    if ax.get_legend_handles_labels()[0]:
        ax.legend(**kw)


def _lb_curve(coefficients, root, n0):
    return np.where(n0 >= root, 0.0, np.polyval(coefficients, n0))


def plot_lower_bounds_train(study_fit, train, path):
    """Analogue of Fig. 17 for one train: Δζ against n0 per mass function, the interval minima,
    the fitted and the published lower bound."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5), sharex=True, squeeze=False)
    n0 = np.linspace(LOWER_LIMIT_HZ, 21.0, 400)
    for ax, m in zip(axes.flat, MASS_FUNCTION_NAMES):
        recs = [r for r in study_fit.records_used if r["train"] == train and r["mass_function"] == m]
        if recs:
            ax.plot([r["n0_hz"] for r in recs], [r["delta_zeta_vbi_pct"] for r in recs], ls="none", marker=".",
                    color="grey", ms=4, label="dz_VBI")
        f = study_fit.fits.get((train, m))
        if f is not None and f.minima:
            ax.plot([p.n0_hz for p in f.minima], [p.delta_zeta_pct for p in f.minima], ls="none", marker="o",
                    mfc="gold", mec="k", ms=6, label="interval minima")
        if f is not None and f.fit is not None:
            ax.plot(n0, f.fit.value_pct(n0), color="tab:blue", lw=1.5,
                    label=f"fit (R2 {f.fit.r2:.3f}, root {f.fit.upper_limit_hz:.2f} Hz)")
        p = f.published if f is not None else None
        if p is None:
            from adm_calib.reference import lower_bound_table

            p = lower_bound_table().get(train, {}).get(m)
        if p is not None:
            ax.plot(n0, _lb_curve(p.coefficients, p.first_root_hz, n0), color="tab:red", lw=1.2, ls="--",
                    label=f"paper (root {p.upper_limit_hz:.2f} Hz)")
        for e in INTERVAL_EDGES_HZ:
            ax.axvline(e, color="k", lw=0.3, alpha=0.25)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_title(f"{train}, {m}")
        ax.grid(alpha=0.2)
        _legend(ax, fontsize=6)
    for ax in axes[-1]:
        ax.set_xlabel("n0 (Hz)")
    for ax in axes[:, 0]:
        ax.set_ylabel("dz (%)")
    fig.suptitle(f"Lower bound of the additional damping, {train} (Fig. 17 analogue)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_lower_bounds(study_fit, path):
    """Analogue of Fig. 18: fitted (solid) and published (dashed) lower bounds per train."""
    from adm_calib.reference import lower_bound_table

    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True, squeeze=False)
    n0 = np.linspace(LOWER_LIMIT_HZ, 21.0, 400)
    pub = lower_bound_table()
    for ax, t in zip(axes.flat, STUDY_TRAINS):
        for m in MASS_FUNCTION_NAMES:
            f = study_fit.fits.get((t, m))
            if f is not None and f.fit is not None:
                ax.plot(n0, f.fit.value_pct(n0), color=_MF_COLOURS[m], lw=1.6, label=f"{m} fit")
            p = pub.get(t, {}).get(m)
            if p is not None:
                ax.plot(n0, _lb_curve(p.coefficients, p.first_root_hz, n0), color=_MF_COLOURS[m], lw=1.0, ls="--")
        ax.set_title(f"{t} (dashed: paper)")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.grid(alpha=0.3)
        ax.set_ylabel("dz (%)")
    for ax in axes[-1]:
        ax.set_xlabel("n0 (Hz)")
    _legend(axes[0, 0], fontsize=7, ncol=2)
    fig.suptitle("Lower bounds of the additional damping for each train (Fig. 18 analogue)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


__all__ = [
    "FREQ_INDICES", "INTERVAL_EDGES_HZ", "StudyCase", "StudySettings", "select_cases", "run_case", "read_results",
    "ResultsWriter", "run_study", "StudyRun", "local_cluster", "interval_minima", "first_root_hz", "fit_cubic",
    "CubicFit", "fit_study", "StudyFit", "LowerBoundFit", "plot_dz_vs_span", "plot_lower_bounds_train",
    "plot_lower_bounds",
]
