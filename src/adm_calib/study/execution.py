"""Running the study: cases grouped in batches, the batches as tasks on a dask.distributed cluster.

A loopback-only :class:`~distributed.LocalCluster` by default, or an existing scheduler
(``--scheduler``). The client appends every finished case to the result store at once.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import os
import platform
import re
import signal
import socket
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from adm_sim.errors import InputError, RunError

from adm_calib.calibrate import calibrate_batch
from adm_calib.study.cases import WORKER_ENV, StudySettings, _train
from adm_calib.study.store import (META_FORMAT, RESULTS_NAME, ResultsWriter, _exclusive, _now, _write_meta,
                                   error_record, read_meta, read_results, result_record, versions)

def run_case(case, settings=StudySettings()):
    """Calibrate one case alone (a batch of one); never raises for errors of the case itself."""
    return run_batch([case], settings)[0]


def make_batches(cases):
    """The cases grouped by :attr:`StudyCase.batch_key` (up to the six mass functions), in first-seen order."""
    groups = {}
    for c in cases:
        groups.setdefault(c.batch_key, []).append(c)
    return list(groups.values())


def run_batch(cases, settings=StudySettings(), train=None):
    """Calibrate cases of one batch key in lockstep (:func:`adm_calib.calibrate.calibrate_batch`).

    The task run on the workers. ``train``: the :class:`~adm_sim.model.trains.Train` of a train read
    from a file (:mod:`adm_calib.study.own_train`); None: the built-in train the cases name. Never raises for errors of the cases themselves: if the batch
    fails, every case is tried alone so that only the failing ones become error records.
    """
    t0 = time.perf_counter()
    try:
        train = _train(cases[0].train) if train is None else train
        res = calibrate_batch([c.bridge for c in cases], train, speeds_kmh=settings.speeds_kmh(),
                              options=settings.calibration_options(cases[0].bridge.span_m))  # the deck's length
        wall = (time.perf_counter() - t0) / len(cases)
        recs = [result_record(c, r, wall) for c, r in zip(cases, res)]
        for rec in recs:
            rec["batch_size"] = len(cases)
    except Exception as exc:
        if len(cases) == 1:
            recs = [error_record(cases[0], exc, time.perf_counter() - t0)]
        else:
            recs = [run_batch([c], settings, train)[0] for c in cases]
    for rec in recs:
        rec["host"] = platform.node()
        rec["pid"] = os.getpid()
    return recs


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
    #: One line per line the store dropped or repaired on opening (line number, byte offset, reason).
    store_notes: list = field(default_factory=list)
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
        lines += [f"study: {n}" for n in self.store_notes]
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


#: dask settings of the local cluster, for a cluster that runs long compute tasks and shows no
#: dashboard. dask's defaults would cost the study ~10 % of its CPU (``bench/bench_study_cluster.py``,
#: docs/benchmarks.md): the workers' statistical profiler samples the running task every 10 ms (its
#: only reader is the dashboard); the event-loop health tick (20 ms), the system monitor (0.5 s)
#: and the worker memory check (0.1 s) run in every process, scheduler and nannies included.
CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.worker.memory.monitor-interval": "1s",
}
#: glibc malloc settings that dask's nanny sets in its workers' environment and a local cluster
#: leaves unset: ``MALLOC_TRIM_THRESHOLD_=65536`` returns freed memory to the system at once and
#: fixes the mmap threshold at 128 kB, so every large table of a batch (the DIM's Eq. (13) inverses,
#: up to ~40 MB for a short span) comes from fresh pages again: ~20000 page faults per batch, 8 % of
#: the study's CPU as system time. A value exported in the environment is still passed on.
UNSET_WORKER_ENV = ("MALLOC_TRIM_THRESHOLD_",)


def local_cluster(workers=2):
    """A loopback-only :class:`distributed.LocalCluster`: ``workers`` processes of one thread each.

    Scheduler, nannies and workers listen on 127.0.0.1 only (also their small HTTP servers for
    health and metrics, on free ports); no dashboard; one BLAS thread per worker (set in the
    environment before the worker process starts); :data:`CLUSTER_CONFIG` (no task profiler,
    rarer housekeeping) and glibc's own malloc settings (:data:`UNSET_WORKER_ENV`).
    """
    import dask  # noqa: PLC0415  dask and distributed: only a study on a local cluster needs them
    from distributed import LocalCluster  # noqa: PLC0415  as dask

    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
    for k in UNSET_WORKER_ENV:
        env[k] = None  # dask: None leaves the variable unset (an exported value still wins)
    env.update(WORKER_ENV)
    with dask.config.set({"distributed.nanny.pre-spawn-environ": env, **CLUSTER_CONFIG}), _workers_ignore_sigint():
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


def _worker_settings():
    """What a worker runs with of :data:`CLUSTER_CONFIG` and :data:`UNSET_WORKER_ENV` (``None``: unset)."""
    import dask  # noqa: PLC0415  runs in a worker, which has dask

    return {**{k: dask.config.get(k, None) for k in CLUSTER_CONFIG}, **{k: os.environ.get(k) for k in UNSET_WORKER_ENV}}


#: The first message a dask scheduler sends on a new TCP connection is its comm handshake, a
#: msgpack map with these keys (``distributed.comm.core``); anything else is not dask.
_HANDSHAKE_KEYS = (b"compression", b"python", b"pickle-protocol")


def check_scheduler(address, timeout_s=5.0):
    """Check that ``address`` (``tcp://host:port``) answers as a dask scheduler, before anything
    is written. A malformed address is bad input (:class:`InputError`, exit 2); an address that does
    not answer as a dask scheduler is a server that does not answer (:class:`RunError`, exit 1, as
    a viewer that does not answer).

    A plain socket with a timeout reads the scheduler's handshake frame: an 8-byte little-endian
    length, at most 1 MiB, then a message holding the handshake keys. A closed port, a silent
    server or one answering another protocol is refused here, instead of a connection attempt
    without end or a frame length read from foreign bytes (``MemoryError: Unable to allocate
    3.07 EiB`` in ``distributed``).
    """
    m = re.fullmatch(r"tcp://(\[[^\]]+\]|[A-Za-z0-9_.\-]+):(\d{1,5})", address or "")
    if m is None:
        raise InputError(f"scheduler: {address!r} is not an address like tcp://127.0.0.1:8786", field="scheduler")
    host, port = m.group(1).strip("[]"), int(m.group(2))
    if not 0 < port < 65536:
        raise InputError(f"scheduler: port {port} is out of range; allowed [1, 65535]", field="scheduler")
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except TimeoutError:
        raise RunError(f"scheduler: {address!r} did not accept a connection within {timeout_s:g} s", field="scheduler") from None
    except OSError as exc:
        raise RunError(f"scheduler: cannot connect to {address!r} ({exc.strerror or exc}); "
                         f"is a dask scheduler running there?", field="scheduler") from None
    not_dask = f"scheduler: {address!r} is not a dask scheduler"
    with sock:
        sock.settimeout(timeout_s)

        def recv(n):
            data = b""
            while len(data) < n:
                chunk = sock.recv(n - len(data))
                if not chunk:
                    raise RunError(f"{not_dask} (it closed the connection without the dask handshake)", field="scheduler")
                data += chunk
            return data

        try:
            head = recv(8)
            n = int.from_bytes(head, "little")
            if not 0 < n <= 1 << 20:
                raise RunError(f"{not_dask} (its first bytes {head!r} are not a dask message)", field="scheduler")
            body = recv(n)
        except TimeoutError:
            raise RunError(f"{not_dask} (no dask handshake within {timeout_s:g} s)", field="scheduler") from None
        except OSError as exc:
            raise RunError(f"{not_dask} ({exc.strerror or exc})", field="scheduler") from None
    if not all(k in body for k in _HANDSHAKE_KEYS):
        raise RunError(f"{not_dask} (its first message is not the dask handshake)", field="scheduler")
    return address


def run_study(out_dir, cases, *, settings=StudySettings(), workers=2, scheduler=None, limit=None, progress=None,
              retry_errors=False, options=None, no_worker_wait_s=None, train_files=None):
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
    progress : callable(done, total), optional
        Called after every finished case with the number of selected cases done so far (those of
        earlier runs included) and their total; the command line hands in a progress bar
        (:func:`adm_sim.cliutil.progress_callback`), the study draws nothing.
    retry_errors : bool
        Drop earlier ``status: "error"`` lines and run those cases again.
    options : dict, optional
        Command-line options recorded in ``study.json``.
    no_worker_wait_s : float, optional
        While cases are pending and the scheduler has had no worker for this long (default
        :data:`NO_WORKER_WAIT_S`, 30 s), the study stops (everything finished is kept).
    train_files : dict, optional
        ``{name: TrainFile}`` of the trains read from files (:func:`adm_calib.study.own_train.study_trains`):
        ``study.json`` keeps each file's path, content and SHA-256 (``train_files``); a resume with
        another file under a recorded name, or with a built-in train where the study ran a file
        (and the reverse), is refused before anything is written.

    Returns
    -------
    StudyRun
        ``interrupted`` is True after Ctrl-C or SIGTERM (everything finished is kept).

    Raises
    ------
    RunError
        The scheduler had no worker for ``no_worker_wait_s`` seconds while cases were pending;
        the finished cases are kept and the same call resumes.
    """
    if importlib.util.find_spec("distributed") is None:  # an optional dependency: the [study] extra
        raise RunError("study: dask.distributed is not installed; install it with pip install 'adm-sim[study]'")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"out: {str(out)!r} is not a directory")
    if scheduler is not None:
        check_scheduler(scheduler)  # before the folder exists
    out.mkdir(parents=True, exist_ok=True)
    with _exclusive(out):
        files = dict(train_files or {})
        meta = _study_meta(out, settings, cases, files)
        with ResultsWriter(out / RESULTS_NAME, drop_errors=retry_errors) as writer:
            run, pending = _pending(out, cases, writer, limit)
            entry = {"started": _now(), "finished": None, "options": dict(options or {}), "versions": versions(),
                     "selected": run.selected, "already_done": run.already_done, "submitted": run.submitted}
            meta["runs"].append(entry)
            _write_meta(out, meta)
            t0 = time.perf_counter()
            try:
                if pending:
                    wait_s = NO_WORKER_WAIT_S if no_worker_wait_s is None else no_worker_wait_s
                    _run_on_dask(pending, settings, writer, run=run, workers=workers, scheduler=scheduler, progress=progress,
                                 entry=entry, no_worker_wait_s=wait_s, trains={n: f.train for n, f in files.items()})
            except KeyboardInterrupt:
                run.interrupted = True
            except RunError as exc:
                entry["stopped"] = str(exc)
                raise
            finally:
                run.wall_s = time.perf_counter() - t0
                run.completed = writer.appended  # the lines this run wrote, whatever interrupted it
                entry.update(_finished(run))
                _write_meta(out, meta)
    return run


def _pending(out, cases, writer, limit):
    """``(StudyRun, pending cases)``: the cases not in the results ``writer`` holds, the first ``limit``."""
    pending = [c for c in cases if c.key not in writer.records]
    if limit is not None:
        pending = pending[:int(limit)]
    run = StudyRun(out_dir=out, selected=len(cases), already_done=len(cases) - len(
        [c for c in cases if c.key not in writer.records]), submitted=len(pending),
        dropped_truncated_line=writer.dropped_truncated, dropped_error_lines=writer.dropped_errors,
        store_notes=list(writer.notes))
    return run, pending


def _finished(run):
    """The fields of a run's ``study.json`` entry once it ends, whatever ended it."""
    return {"finished": _now(), "completed": run.completed, "statuses": dict(run.statuses),
            "interrupted": run.interrupted, "wall_s": round(run.wall_s, 3),
            "dropped_truncated_line": run.dropped_truncated_line, "store_notes": run.store_notes,
            "dropped_error_lines": run.dropped_error_lines}


def _study_meta(out, settings, cases, files):
    """``study.json`` of ``out`` for this run (held under the study's lock): the one found, checked
    against ``settings`` and, for studies of train files, against ``files`` (:func:`check_resume`), or
    a new one; the train files recorded. Refusals are one line before anything is written."""
    meta = read_meta(out)
    old = None if meta is None else {**StudySettings().to_dict(), **(meta.get("settings") or {})}
    if meta is not None and old != settings.to_dict():
        new = settings.to_dict()
        diff = ", ".join(f"{k} {old.get(k)!r} -> {new[k]!r}" for k in new if old.get(k) != new[k])
        raise InputError(f"settings: the study in {str(out)!r} was computed with other settings ({diff}); "
                         f"use another --out")
    if files or (meta or {}).get("train_files"):
        from adm_calib.study.own_train import check_resume  # noqa: PLC0415  cycle: own_train imports the study package

        done = {r["train"] for r in read_results(out / RESULTS_NAME, skip_damaged=True).records}
        check_resume(meta, done, names=sorted({c.train for c in cases}), files=files, out=out)
    if meta is None:
        meta = {"format": META_FORMAT, "created": _now(), "settings": settings.to_dict(), "runs": []}
    if files:
        meta.setdefault("train_files", {}).update({n: f.record() for n, f in files.items()})
    return meta


#: How long a study waits while its scheduler has no worker before it stops (exit 1, resumable).
NO_WORKER_WAIT_S = 30.0
_POLL_S = 0.1


class _WorkerWatch:
    """Stops a study whose scheduler has had no worker for ``wait_s`` seconds in a row.

    Polled while no task is ready; asks the scheduler for its workers at most once a second.
    """

    def __init__(self, client, address, wait_s, submitted):
        self.client, self.address, self.wait_s, self.submitted = client, address, float(wait_s), submitted
        self.since = self.asked = None

    def check(self, completed):
        now = time.monotonic()
        if self.asked is not None and now - self.asked < min(1.0, self.wait_s / 4):
            return
        self.asked = now
        if self.client.scheduler_info().get("workers"):
            self.since = None
            return
        self.since = now if self.since is None else self.since
        if now - self.since >= self.wait_s:
            raise RunError(f"the scheduler {self.address} has had no worker for {self.wait_s:g} s; {completed} of "
                           f"{self.submitted} submitted cases finished and are kept; start workers for it")


def _run_on_dask(pending, settings, writer, *, run, workers, scheduler, progress, entry,
                 no_worker_wait_s=NO_WORKER_WAIT_S, trains=None):
    from distributed import Client, as_completed  # noqa: PLC0415  as dask

    cluster = client = None
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
        if scheduler is not None and info.get("type") != "Scheduler":
            raise InputError(f"scheduler: {scheduler!r} is not a dask scheduler (identity {info.get('type')!r})", field="scheduler")
        run.scheduler = info.get("address", "")
        run.workers = sorted(info.get("workers", {}))
        entry["cluster"] = {"scheduler": run.scheduler, "local": cluster is not None,
                            "workers": {a: {"nanny": w.get("nanny"), "nthreads": w.get("nthreads")}
                                        for a, w in info.get("workers", {}).items()},
                            "worker_env": client.run(_worker_env),
                            "worker_settings": client.run(_worker_settings)}
        # longest batches first (cost grows with n0: the time step follows the highest mode)
        batches = sorted(make_batches(pending), key=lambda b: -b[0].bridge.n0_hz)
        by_future = {}
        for b in batches:
            L, fi = b[0].span_m, b[0].freq_index
            mf = f"-{b[0].mass_function}" if b[0].bridge.is_continuous else ""  # a deck: a batch of one case
            fut = client.submit(run_batch, b, settings, (trains or {}).get(b[0].train), pure=False,
                                key=f"batch-{re.sub(r'[^A-Za-z0-9_.-]', '_', b[0].train)}-L{L:g}-f{fi}{mf}-{os.getpid()}")
            by_future[fut] = b
            futures.append(fut)
        if progress is not None:
            progress(run.already_done, run.selected)
        ac = as_completed(futures, loop=client.loop)
        watch = _WorkerWatch(client, run.scheduler, no_worker_wait_s, len(pending))
        while not ac.is_empty():
            if not ac.has_ready():
                watch.check(run.completed)
                time.sleep(_POLL_S)
                continue
            for fut in ac.next_batch(block=False):
                batch = by_future.pop(fut)
                try:
                    recs = fut.result()
                except Exception as exc:  # the task never returned (worker died, cancelled)
                    recs = [error_record(case, exc) for case in batch]
                for rec in recs:
                    writer.append(rec)
                    run.completed += 1
                    run.statuses[rec["status"]] += 1
                    if progress is not None:
                        progress(run.already_done + run.completed, run.selected)
                fut.release()
    finally:
        if client is not None:
            with contextlib.suppress(Exception):
                client.cancel([f for f in futures if not f.done()])
            with contextlib.suppress(Exception):
                client.close(timeout=10)
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=20)
