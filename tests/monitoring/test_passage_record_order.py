"""The monitor's passages when a run's records and samples arrive out of order.

A replay at ``--rate 0`` (or a loaded graph) publishes the samples and the run records from different
publishers, with no order between them: the next run's samples can arrive before this run's
``done`` (which carries its end ``t1_s``), and before or after the next run's ``started``. Every
sample must still land in its own run: each passage counts exactly the samples the run published
and loses none, whatever the interleaving.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from adm_sim.monitoring.modal_id import PassageTracker

N = 3000          # samples per run, 1 kHz
RUNS = ((1, 0.0), (2, 5.0))  # (run id, t0_s): run 2 starts 2 s after run 1 ends


def _samples(t0):
    t = t0 + np.arange(N) * 1e-3
    return t, np.exp(-0.5 * (t - t0)) * np.sin(2 * np.pi * 5.0 * (t - t0))


def _records(run_id, t0):
    started = {"node": "bridge", "state": "started", "run_id": run_id, "t0_s": t0, "time_lane": 0}
    done = {"node": "bridge", "state": "done", "run_id": run_id, "t0_s": t0, "t1_s": t0 + N * 1e-3,
            "samples": {"/adm/bridge/midspan/accel": N}}
    return started, done


# where run 1's done and run 2's started fall among run 2's samples (index into them)
def _passages(done1_at, started2_at):
    """Both runs fed with run 1's done and run 2's started at these indices of run 2's samples."""
    tr = PassageTracker()
    s1, d1 = _records(*RUNS[0])
    s2, d2 = _records(*RUNS[1])
    t1, a1 = _samples(RUNS[0][1])
    t2, a2 = _samples(RUNS[1][1])
    tr.status(s1)
    for t, a in zip(t1, a1):
        tr.sample(t, a)
    for i, (t, a) in enumerate(zip(t2, a2)):
        if i == done1_at:
            tr.status(d1)
        if i == started2_at:
            tr.status(s2)
        tr.sample(t, a)
    if done1_at == N:
        tr.status(d1)
    if started2_at == N:
        tr.status(s2)
    tr.status(d2)
    tr.flush()
    return tr, {p.run_id: p for p in tr.passages}


@pytest.mark.parametrize("done1_at, started2_at", list(itertools.product((0, 1, 1500, N), (0, 700, N))))
def test_each_run_keeps_its_samples_whatever_the_order(done1_at, started2_at):
    tr, by_run = _passages(done1_at, started2_at)
    assert sorted(by_run) == [1, 2]
    for rid in (1, 2):
        assert by_run[rid].info["samples_published"] == N
        assert by_run[rid].info["samples_lost"] == 0, (rid, done1_at, started2_at)
    assert tr.dropped == 0
    # the passages are those of the records in order (run 1 done, run 2 started, then its samples)
    _, in_order = _passages(0, 0)
    for rid in (1, 2):
        assert by_run[rid].peak_acc_m_s2 == in_order[rid].peak_acc_m_s2
    assert in_order[2].peak_acc_m_s2 == pytest.approx(0.9, abs=0.1)  # the 5 Hz decay's first crest
