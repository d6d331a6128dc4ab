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
