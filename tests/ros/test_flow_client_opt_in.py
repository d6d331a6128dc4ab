"""A client opts into the flow control only once it can receive: ``FlowClient`` creates its
``/adm/run/ack`` publisher (what the bridge and ``--wait-clients`` look for) when every subscription of
the node to the counted topics (here the acceleration) is matched with a publisher.

Before, it opted in at once: on a loaded machine the bridge could take a client whose acceleration
subscription discovery had not matched yet, publish the run's first samples to nobody and lose them
for that client (632 of 1682 samples of run 1 in one fresh-clone suite beside two busy processes).
"""

import time

import pytest

from adm_sim import protocol as P
from ros_fixtures import ros_domain  # noqa: F401

rclpy = pytest.importorskip("rclpy")
from geometry_msgs.msg import AccelStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from adm_sim.nodes.common import QOS_MONITOR, FlowClient  # noqa: E402


def _ack_publishers(node):
    return sorted(i.node_name for i in node.get_publishers_info_by_topic(P.TOPIC_ACK))


def _spin_until(ex, cond, timeout_s):
    t_end = time.monotonic() + timeout_s
    while not cond() and time.monotonic() < t_end:
        ex.spin_once(timeout_sec=0.05)
    return cond()


@pytest.mark.slow
def test_client_opts_in_once_its_subscriptions_are_matched(ros_domain):
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=int(ros_domain["ROS_DOMAIN_ID"]))
    try:
        ex = SingleThreadedExecutor(context=ctx)
        client = rclpy.create_node("opt_in_client", context=ctx)
        client.create_subscription(AccelStamped, P.relative(P.TOPIC_ACCEL), lambda m: None, QOS_MONITOR)
        flow = FlowClient(client)
        source = rclpy.create_node("opt_in_source", context=ctx)
        ex.add_node(client)
        ex.add_node(source)
        # no publisher of the acceleration: 1.5 s of spinning, and the client has not opted in
        assert not _spin_until(ex, lambda: flow.opted_in, 1.5)
        assert _ack_publishers(source) == []
        source.create_publisher(AccelStamped, P.relative(P.TOPIC_ACCEL), QOS_MONITOR)
        assert _spin_until(ex, lambda: flow.opted_in, 10.0)
        assert _spin_until(ex, lambda: _ack_publishers(source) == ["opt_in_client"], 10.0), _ack_publishers(source)
        accel = [s for s in client.subscriptions if s.topic_name == P.TOPIC_ACCEL]
        assert [s.get_publisher_count() for s in accel] == [1]
    finally:
        rclpy.try_shutdown(context=ctx)


@pytest.mark.slow
def test_monitor_node_opts_in_only_once_it_subscribes_to_the_acceleration(ros_domain):
    """The monitor node makes its acceleration subscription only once it has seen the topic's publishers
    (their type and reliability), after its ``FlowClient``. The client then had no subscription to the
    acceleration, took "every subscription matched" as true and opted in at once, so a run that started
    before the monitor subscribed lost all its samples for the monitor (run 1, 521 of 521, in one
    fresh-clone suite beside two busy processes). Now it opts in only once the node subscribes and the
    subscription is matched."""
    from rclpy.parameter import Parameter

    from adm_sim.nodes.monitor_node import MonitorNode

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=int(ros_domain["ROS_DOMAIN_ID"]))
    try:
        ex = SingleThreadedExecutor(context=ctx)
        mon = MonitorNode(context=ctx, parameter_overrides=[Parameter("topic", value=P.TOPIC_ACCEL)])
        source = rclpy.create_node("opt_in_source", context=ctx)
        ex.add_node(mon)
        ex.add_node(source)
        # no publisher of the acceleration: the monitor has not subscribed, so it has not opted in
        assert not _spin_until(ex, lambda: mon.flow.opted_in, 1.0)
        assert mon.sub is None and _ack_publishers(source) == []
        source.create_publisher(AccelStamped, P.TOPIC_ACCEL, QOS_MONITOR)
        assert _spin_until(ex, lambda: mon.flow.opted_in, 10.0)
        assert mon.sub is not None and mon.sub.get_publisher_count() == 1
        assert _spin_until(ex, lambda: _ack_publishers(source) == ["monitor"], 10.0), _ack_publishers(source)
    finally:
        rclpy.try_shutdown(context=ctx)
