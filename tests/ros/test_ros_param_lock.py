"""Parameters are locked while a run is active, on every lockstep node: a set during a run is
refused with the node's reason and changes nothing (``LockstepNode.lock_reason``); on the
calibration node, the parameters its job reads once are locked while the job runs
(``RunDriver.lock_reason``).

The bridge and the train node run in this process on a reserved domain; the train node's
``~/start_run`` starts a real run, the bridge takes it up from ``/adm/run/setup``, and the test
sets a parameter on each while both hold the run.
"""

from __future__ import annotations

import re
import time

import pytest

rclpy = pytest.importorskip("rclpy")
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from adm_sim import protocol as P  # noqa: E402
from adm_sim.nodes.bridge_node import BridgeNode  # noqa: E402
from adm_sim.nodes.train_node import TrainNode  # noqa: E402
from ros_fixtures import ros_domain  # noqa: E402,F401  (fixture)


def _until(ex, cond, what, timeout_s=10.0):
    end = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < end, f"timed out waiting for {what}"
        ex.spin_once(timeout_sec=0.05)


@pytest.fixture
def running(ros_domain):  # noqa: F811
    """``(bridge, train)`` in this process, both holding run 1 (an MLM run at 200 km/h)."""
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=int(ros_domain["ROS_DOMAIN_ID"]))
    bridge = BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value="B1")])
    train = TrainNode(context=ctx, parameter_overrides=[Parameter("model", value="mlm"),
                                                        Parameter("speeds_kmh", value="200")])
    ex = SingleThreadedExecutor(context=ctx)
    for n in (bridge, train):
        ex.add_node(n)
    try:
        _until(ex, lambda: train.count_subscribers(P.relative(P.TOPIC_SETUP)) > 0
               and train.count_publishers(P.relative(P.TOPIC_RAIL)) > 0
               and train._bridge_desc is not None, "the bridge node's entities and its description")
        response = train._on_start(Trigger.Request(), Trigger.Response())
        assert response.success, response.message
        _until(ex, lambda: bridge.run is not None, "the bridge to take up the run")
        assert train.run is not None and train.run.id == bridge.run.id == 1
        yield bridge, train
    finally:
        ex.shutdown()
        for n in (bridge, train):
            n.destroy_node()
        rclpy.try_shutdown(context=ctx)


@pytest.mark.parametrize("node, name, value", [
    ("bridge", "span_m", 20.0),
    ("bridge", "delta_zeta", 0.01),
    ("train", "speeds_kmh", "250"),
    ("train", "train", "Eurostar"),
])
def test_a_set_during_a_run_is_refused_with_the_reason(running, node, name, value):
    bridge, train = running
    n = bridge if node == "bridge" else train
    old = n.get_parameter(name).value
    before = (bridge.bridge, train.train)
    (res,) = n.set_parameters([Parameter(name, value=value)])
    assert not res.successful
    assert res.reason.startswith(f"{n.get_name()}: parameters are locked while run 1 is in progress"), res.reason
    if node == "bridge":
        assert f"of {bridge.run.grid.n_steps})" in res.reason  # the bridge adds the step it is at
    assert n.get_parameter(name).value == old
    assert (bridge.bridge, train.train) == before  # nothing configured


@pytest.fixture
def calibrating(ros_domain):  # noqa: F811
    """``(calibration, bridge)`` in this process, the calibration node's job holding its first run."""
    from adm_calib.nodes.calibration_node import CalibrationNode

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=int(ros_domain["ROS_DOMAIN_ID"]))
    bridge = BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value="B1")])
    train = TrainNode(context=ctx, parameter_overrides=[Parameter("model", value="mlm")])
    cal = CalibrationNode(context=ctx, parameter_overrides=[Parameter("speeds_kmh", value="200:300:10")])
    ex = SingleThreadedExecutor(context=ctx)
    for n in (bridge, train, cal):
        ex.add_node(n)
    try:
        cal.begin()  # the job, in its worker thread: the graph, the descriptions, then the first MLM run
        _until(ex, lambda: (bridge.run is not None and cal._current is not None) or cal.finished,
               "the calibration's first run", timeout_s=60.0)
        assert bridge.run is not None, cal.error
        yield cal, bridge
    finally:
        ex.shutdown()
        for n in (bridge, train, cal):
            n.destroy_node()
        rclpy.try_shutdown(context=ctx)


@pytest.mark.slow
@pytest.mark.parametrize("name, value", [("speeds_kmh", "250:300:5"), ("dim_grid", "full")])
def test_a_set_on_the_calibration_node_during_its_job_is_refused(calibrating, name, value):
    """The calibration node reads ``speeds_kmh`` and ``dim_grid`` once, when its job starts: a set
    while the job runs would change nothing, so it is refused with the reason, the value kept."""
    cal, _bridge = calibrating
    old = cal.get_parameter(name).value
    (res,) = cal.set_parameters([Parameter(name, value=value)])
    assert not res.successful
    # the run the job waits for (``run 1 of``) is named when the set comes during one
    assert re.match(r"calibration: parameters are locked while (run \d+ of )?its job is in progress "
                    r"\(speeds_kmh, dim_grid: read once, when it started\)$", res.reason), res.reason
    assert cal.get_parameter(name).value == old


def test_the_monitor_node_has_no_run_locked_parameters():
    """The monitor node reads every parameter once, at start-up, and follows no run of its own: it
    has nothing to lock (no post-set callback), so the lock test above covers bridge, train and
    calibration, the nodes whose parameters a run reads."""
    from adm_sim.nodes.monitor_node import MonitorNode

    assert not hasattr(MonitorNode, "lock_reason") and not hasattr(MonitorNode, "job_parameters")
