"""A run's result drawn with its phase whatever the order its phase record and its result arrive in.

The driver learns a run's id from the bridge's answer to its start request and publishes the
``requested`` record (the run's phase) then; on a loaded machine a short run's result can reach the
recorder first (two publishers, no order between them). Before the feed waited for the record, such
a result was drawn as ``unknown`` (``test_ros_rerun_views.py`` failed once with a KeyError on
``/sweep/curves/MLM_zeta``). Here the messages are fed by hand to a logger that notes its calls.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from adm_sim import protocol as P
from adm_sim.recording.viewer_feed import ViewerFeed


class _Notes:
    """A stand-in for :class:`~adm_sim.recording.rerun_log.RunLogger` that notes what it is asked to draw."""

    def __init__(self):
        self.runs, self.calls = [], []

    def run_started(self, st):
        self.calls.append(("status", st["state"], st["run_id"]))

    def run_done(self, result, phase, run_id=None):
        self.calls.append(("result", run_id, phase, float(result[1].max())))

    def iteration(self, i, dz_pct, mlm_peak, dim_peak, phase):
        self.calls.append(("iteration", i, phase))

    def flush(self):
        pass


def _status(run_id, state, node=P.BRIDGE_NODE, **extra):
    return SimpleNamespace(data=P.encode(P.status_record(node, run_id, state, **extra)))


def _matrix(rows):
    a = np.asarray(rows, dtype=float)
    return SimpleNamespace(data=a.ravel().tolist(), layout=SimpleNamespace(
        data_offset=0, dim=[SimpleNamespace(size=a.shape[0]), SimpleNamespace(size=a.shape[1])]))


def _result(peak):
    return _matrix([[250.0, 260.0], [peak / 2, peak], [1e-3, 1e-3], [0.0, 0.0]])


def _request(run_id, phase):
    return _status(run_id, P.REQUESTED, node="driver", model="mlm", phase=phase, label="MLM")


@pytest.mark.parametrize("request_first", [True, False])
def test_result_is_drawn_with_the_phase_of_its_run_in_either_order(request_first, capsys):
    viz = _Notes()
    feed = ViewerFeed(viz)
    feed(P.TOPIC_STATUS, _status(1, P.STARTED), 0)
    if request_first:
        feed(P.TOPIC_STATUS, _request(1, P.PHASE_MLM_ZETA), 0)
    feed(P.TOPIC_RESULT, _result(1.25), 10)
    feed(P.TOPIC_CAL_ITERATION, _matrix([[1.0, 0.5, 1.25, 1.2]]), 10)
    if not request_first:
        assert [c for c in viz.calls if c[0] != "status"] == []  # waits for the run's phase record
        feed(P.TOPIC_STATUS, _request(1, P.PHASE_MLM_ZETA), 10)
    feed.finish()
    drawn = [c for c in viz.calls if c[0] != "status"]
    assert drawn == [("result", 1, P.PHASE_MLM_ZETA, 1.25), ("iteration", 1, P.PHASE_MLM_ZETA)]
    assert "warning:" not in capsys.readouterr().err


def test_a_run_without_phase_record_is_drawn_unknown_when_the_next_run_starts(capsys):
    """A recording made before runs carried their phase: each result is drawn as ``unknown`` before
    the next run's ``started`` is drawn, and at the end for the last run; one warning line."""
    viz = _Notes()
    feed = ViewerFeed(viz)
    feed(P.TOPIC_STATUS, _status(1, P.STARTED), 0)
    feed(P.TOPIC_RESULT, _result(1.5), 10)
    feed(P.TOPIC_STATUS, _status(2, P.STARTED), 20)
    feed(P.TOPIC_RESULT, _result(2.5), 30)
    assert viz.calls[-1] == ("status", P.STARTED, 2)
    feed.finish()
    assert viz.calls == [("status", P.STARTED, 1), ("result", 1, P.PHASE_UNKNOWN, 1.5),
                         ("status", P.STARTED, 2), ("result", 2, P.PHASE_UNKNOWN, 2.5)]
    err = capsys.readouterr().err.splitlines()
    assert len([line for line in err if line.startswith("warning:")]) == 1
