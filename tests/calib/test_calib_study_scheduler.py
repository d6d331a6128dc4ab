"""The study on an existing scheduler (``adm-calib study --scheduler``), with a worker lost mid-run.

A ``dask scheduler`` and two ``dask worker`` processes (one thread each) are started from the
venv's ``dask`` executable, all bound to 127.0.0.1, without dashboards and without nannies (one
process each); the study runs through the command line in a subprocess. Once at least one result
line is written, the worker that holds a batch is killed (SIGKILL to its whole process group, like
a machine lost: no nanny is left to start it again). The study must still end with exactly the
cases of an uninterrupted run, with the same numbers: the reference is the workers' own task
(``run_batch``) called in this process, which tests/calib/test_calib_study.py shows equal to a study on
a local cluster. Cheap cases only: L = 38-39 m at the two lowest frequencies (4 batches of 6 cases:
when the first batch is written, three are left to the two workers, so the kill still lands mid-run
on a worker that holds a batch, as it did with 6 batches; the statuses are ok and range_end, L38-f2).
"""

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import psutil
import pytest

from adm_calib import peaks as pk
from adm_calib import study as st

DASK = Path(sys.executable).with_name("dask")
pytestmark = [pytest.mark.slow, pytest.mark.skipif(not DASK.exists(), reason=f"dask CLI not found next to {sys.executable}")]

SPANS, FREQS, TRAIN = (38, 39), (1, 2), "ICE-2"
STUDY_ARGS = ["--trains", TRAIN, "--spans", f"{SPANS[0]}:{SPANS[1]}", "--freq-index", ",".join(map(str, FREQS))]
N_CASES = 2 * 2 * 6          # 2 spans x 2 frequency indices x 6 mass functions: 4 batches


def _free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env():
    env = dict(os.environ)
    env.update(st.WORKER_ENV)
    env.pop("DASK_DISTRIBUTED__SCHEDULER_ADDRESS", None)
    return env


def _spawn(cmd, log):
    """A process in its own session (so its whole group can be signalled), output to ``log``."""
    with open(log, "wb") as f:
        return subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=_env(),
                                start_new_session=True)


def _signal_group(proc, sig):
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, sig)


def _stop_all(procs, timeout=10.0):
    """Terminate every process group started here, last started first, then kill what is left.

    Each is waited for before the one started before it is signalled: the workers end while their
    scheduler still answers (a worker terminated after its scheduler waited out its connection
    timeouts, up to the whole ``timeout``, in about one run in two).
    """
    t_end = time.monotonic() + timeout
    for p in reversed(procs):
        _signal_group(p, signal.SIGTERM)
        with contextlib.suppress(subprocess.TimeoutExpired):
            p.wait(timeout=max(0.1, t_end - time.monotonic()))
    for p in procs:
        _signal_group(p, signal.SIGKILL)       # also children left in the group after the leader ended
        with contextlib.suppress(subprocess.TimeoutExpired):
            p.wait(timeout=5)


def _complete_lines(path):
    if not path.exists():
        return []
    data = path.read_bytes()
    return data[: data.rfind(b"\n") + 1].splitlines()


def _listening_addresses(pids):
    return {c.laddr.ip for c in psutil.net_connections(kind="inet")
            if c.status == psutil.CONN_LISTEN and c.pid in pids}


def _tree_pids(procs):
    pids = set()
    for p in procs:
        with contextlib.suppress(psutil.NoSuchProcess):
            q = psutil.Process(p.pid)
            pids |= {q.pid} | {c.pid for c in q.children(recursive=True)}
    return pids


def _logs(tmp_path):
    return "\n".join(f"--- {f.name}\n{f.read_text(errors='replace')[-3000:]}" for f in sorted(tmp_path.glob("*.log")))


def test_study_on_scheduler_survives_a_killed_worker(tmp_path):
    from distributed import Client

    t_start = time.monotonic()
    cases = st.select_cases([TRAIN], spans_m=SPANS, freq_indices=FREQS)
    assert len(cases) == N_CASES and len(st.make_batches(cases)) == 4

    # reference: the same cases, uninterrupted, batch by batch in this process (the workers' task)
    ref_recs = {st.record_key(r): r for b in st.make_batches(cases) for r in st.run_batch(b)}
    assert len(ref_recs) == N_CASES

    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    out = tmp_path / "sched"
    res = out / st.RESULTS_NAME
    procs, workers = [], {}
    mon = None
    try:
        procs.append(_spawn([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                             "--no-dashboard", "--dashboard-address", "127.0.0.1:0", "--no-jupyter"],
                            tmp_path / "scheduler.log"))
        for name in ("w0", "w1"):
            w = _spawn([str(DASK), "worker", addr, "--nthreads", "1", "--nworkers", "1", "--no-nanny", "--host", "127.0.0.1",
                        "--no-dashboard", "--dashboard-address", "127.0.0.1:0", "--name", name,
                        "--death-timeout", "60", "--local-directory", str(tmp_path / f"scratch-{name}")],
                       tmp_path / f"{name}.log")
            procs.append(w)
            workers[name] = w
        mon = Client(addr, timeout="30s", set_as_default=False)
        mon.wait_for_workers(2, timeout=45)
        info = mon.scheduler_info(n_workers=-1)["workers"]
        by_name = {w["name"]: a for a, w in info.items()}
        assert set(by_name) == {"w0", "w1"}, info
        worker_pid = mon.run(os.getpid)                          # {worker address: pid of the worker process}
        # nothing started here listens on anything but the loopback interface
        assert _listening_addresses(_tree_pids(procs)) <= {"127.0.0.1"}

        study = _spawn([sys.executable, "-m", "adm_calib.calib_commands", "study", "--out", str(out), *STUDY_ARGS,
                        "--scheduler", addr], tmp_path / "study.log")
        procs.append(study)

        # wait for the first result line, then kill the worker that holds a batch
        t_end = time.monotonic() + 60
        while not _complete_lines(res):
            assert study.poll() is None, _logs(tmp_path)
            assert time.monotonic() < t_end, "no result line in time\n" + _logs(tmp_path)
            time.sleep(0.01)
        processing = mon.processing()
        victim_addr = max(processing, key=lambda a: len(processing[a]))
        lost_keys = set(processing[victim_addr])
        victim = next(n for n, a in by_name.items() if a == victim_addr)
        _signal_group(workers[victim], signal.SIGKILL)
        rows_at_kill = len(_complete_lines(res))
        study_alive_at_kill = study.poll() is None
        workers[victim].wait(timeout=10)

        # the kill came mid-run: some rows written, not all, the study still running, a batch lost
        assert 0 < rows_at_kill < N_CASES, rows_at_kill
        assert study_alive_at_kill and lost_keys, (rows_at_kill, lost_keys)

        try:
            rc = study.wait(timeout=90)
        except subprocess.TimeoutExpired:
            pytest.fail("study did not finish after the worker was killed\n" + _logs(tmp_path))
        assert rc == 0, _logs(tmp_path)
        survivor_addr = by_name[next(n for n in by_name if n != victim)]
        assert list(mon.scheduler_info(n_workers=-1)["workers"]) == [survivor_addr]
    finally:
        if mon is not None:
            with contextlib.suppress(Exception):
                mon.close(timeout=5)
        _stop_all(procs)

    # exactly the rows of the uninterrupted run: same keys, no duplicates, no errors, same numbers
    content = st.read_results(res)
    assert content.duplicates == 0 and not content.truncated_tail
    assert len(content.records) == N_CASES
    recs = content.by_key
    assert set(recs) == set(ref_recs) == {c.key for c in cases}
    for k, r in recs.items():
        assert r["status"] == ref_recs[k]["status"] and pk.has_delta_zeta(r["status"]), (k, r.get("message"))
        assert r["delta_zeta_vbi_pct"] == pytest.approx(ref_recs[k]["delta_zeta_vbi_pct"], abs=1e-9, rel=0), k
    # the lost batches were computed again by the surviving worker
    redone = {(r["span_m"], r["freq_index"]) for r in recs.values() if r["pid"] == worker_pid[survivor_addr]}
    lost = set()
    for key in lost_keys:                                       # batch-ICE-2-L38-f1-<client pid>
        parts = str(key).split("-")
        lost.add((float(parts[-3][1:]), int(parts[-2][1:])))
    assert lost & redone, (lost, redone)
    # the run is recorded as one on the external scheduler, with both workers at its start
    meta = json.loads((out / st.META_NAME).read_text())
    run = meta["runs"][-1]
    assert run["cluster"]["scheduler"] == addr and run["cluster"]["local"] is False
    assert set(run["cluster"]["workers"]) == set(by_name.values())
    assert run["completed"] == N_CASES and run["interrupted"] is False and sum(run["statuses"].values()) == N_CASES
    assert run["statuses"] == dict(Counter(r["status"] for r in recs.values()))  # ok and range_end (L38-f2)
    assert time.monotonic() - t_start < 120
