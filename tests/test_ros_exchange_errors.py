"""The exchange refuses messages out of order: one line naming the node, exit 2."""

import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")
from ros_fixtures import node_procs, ros_domain  # noqa: E402,F401

from adm_sim import protocol as P  # noqa: E402
from adm_sim.nodes import common as c  # noqa: E402


def test_stray_exchange_message_ends_the_node(node_procs, ros_domain):
    """Interaction forces with no DIM run active: the bridge says so in one line and exits 2."""
    from std_msgs.msg import Float64MultiArray

    b = node_procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": "B3"})
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=ros_domain.domain_id)
    node = rclpy.create_node("stray", context=ctx)
    try:
        pub = node.create_publisher(Float64MultiArray, P.TOPIC_FORCES, c.QOS_EXCHANGE)
        t_end = time.monotonic() + 30
        while pub.get_subscription_count() == 0:
            assert time.monotonic() < t_end, node_procs.stderr("bridge")
            time.sleep(0.05)
        pub.publish(c.pack(7, 0, 0, np.zeros((1, 0)), ("lane", "axle_on")))
        b.wait(20)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    assert b.returncode == 1  # an exchange out of order is a RunError: exit 1, as at the CLIs
    err = node_procs.stderr("bridge")
    assert "Traceback" not in err and "FATAL" not in err, err
    assert node_procs.stderr("bridge").splitlines()[-1] == (
        "error: bridge: bridge: interaction forces received with no DIM run active")
