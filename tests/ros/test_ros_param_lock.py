"""Parameters are locked while a run is active, on every lockstep node: a set during a run is
refused with the node's reason and changes nothing (``LockstepNode.lock_reason``).

The bridge and the train node run in this process on a reserved domain; the train node's
``~/start_run`` starts a real run, the bridge takes it up from ``/adm/run/setup``, and the test
sets a parameter on each while both hold the run.
"""

from __future__ import annotations

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
               and train.count_publishers(P.relative(P.TOPIC_RAIL)) > 0, "the bridge node's entities")
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
