"""A study pointed at a real dask scheduler that has no worker stops after a stated wait.

The scheduler is a loopback :class:`distributed.LocalCluster` with ``n_workers=0`` (127.0.0.1, no
dashboard). The study stops with one line and exit 1 once the scheduler has had no worker for the
wait, keeps what it has, and the same command resumes once a worker has joined.
"""

import importlib.util
import json
import logging
import time

import pytest

# skipped without distributed, which is imported by the tests themselves (0.35 s, not at collection)
pytestmark = [pytest.mark.slow, pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="distributed is not installed")]

from adm_calib import study as st  # noqa: E402
from adm_calib.calib_commands import main  # noqa: E402
from adm_calib.study import execution  # noqa: E402
from adm_sim.errors import RunError  # noqa: E402

ARGS = ["--trains", "ICE-2", "--spans", "40", "--freq-index", "1", "--mass-functions", "mu1"]


@pytest.fixture
def empty_scheduler():
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=0, processes=True, threads_per_worker=1, host="127.0.0.1",
                           dashboard_address=None, silence_logs=logging.CRITICAL,
                           scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
    try:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        yield cluster
    finally:
        cluster.close(timeout=20)


def test_no_worker_stops_after_the_wait_and_resumes(tmp_path, empty_scheduler, capsys, monkeypatch):
    addr = empty_scheduler.scheduler_address
    monkeypatch.setattr(execution, "NO_WORKER_WAIT_S", 0.5)
    t0 = time.monotonic()
    code = main(["study", "--out", str(tmp_path), *ARGS, "--scheduler", addr])
    waited = time.monotonic() - t0
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert err == [f"error: study stopped by RunError: the scheduler {addr} has had no worker for 0.5 s; 0 of 1 "
                   f"submitted cases finished and are kept; start workers for it; rerun the same command to resume"]
    assert 0.5 <= waited < 30.0                       # the stated wait, plus connecting; never without end
    run = json.loads((tmp_path / "study.json").read_text())["runs"][-1]
    assert run["finished"] and run["completed"] == 0 and "no worker for 0.5 s" in run["stopped"]
    assert (tmp_path / "results.jsonl").read_bytes() == b""
    # a worker joins: the same call resumes and computes the case
    empty_scheduler.scale(1)
    empty_scheduler.wait_for_workers(1, timeout=120)
    cases = st.select_cases(["ICE-2"], ["mu1"], (40, 40), [1])
    done = st.run_study(tmp_path, cases, scheduler=addr, no_worker_wait_s=60.0)
    assert (done.submitted, done.completed, done.errors) == (1, 1, 0)
    recs = st.read_results(tmp_path / "results.jsonl").records
    assert [(r["bridge"], r["status"]) for r in recs] == [("L40-f1-mu1", "ok")]


def test_run_study_raises_run_error_without_workers(tmp_path, empty_scheduler):
    cases = st.select_cases(["ICE-2"], ["mu1"], (40, 40), [1])
    t0 = time.monotonic()
    with pytest.raises(RunError, match=r"has had no worker for 0.5 s; 0 of 1 submitted cases finished"):
        st.run_study(tmp_path, cases, scheduler=empty_scheduler.scheduler_address, no_worker_wait_s=0.5)
    assert time.monotonic() - t0 < 20.0
