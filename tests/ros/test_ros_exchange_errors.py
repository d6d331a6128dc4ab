"""The exchange refuses messages out of order: one line naming the node, exit 2."""

import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")
from ros_fixtures import node_procs, ros_domain  # noqa: E402,F401

from adm_sim import protocol as P  # noqa: E402
from adm_sim.nodes import common as c  # noqa: E402


@pytest.mark.slow
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


def test_exchange_messages_carry_the_array_bytes_exactly():
    """pack/unpack and matrix_msg hand the float64 bytes over unchanged (the co-simulation's bit for bit
    rests on it), the message's data an ``array.array('d')`` filled from the bytes, not value by value."""
    import array

    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import Float64MultiArray

    rng = np.random.default_rng(7)
    a = rng.standard_normal((2, 191, 5)) * 10.0 ** rng.integers(-300, 300, (2, 191, 5))
    a[0, 0, 0], a[1, 2, 3] = -0.0, 5e-324
    msg = c.pack(3, 17, 2, a, ("field", "lane", "axle_on"), np.array([4, 5, 6, 7, 8]))
    assert isinstance(msg.data, array.array) and msg.data.typecode == "d"
    back = deserialize_message(serialize_message(msg), Float64MultiArray)
    run_id, k, stage, idx, payload = c.unpack(back)
    assert (run_id, k, stage, idx.tolist()) == (3, 17, 2, [4, 5, 6, 7, 8])
    assert payload.tobytes() == a.tobytes()
    assert [(d.label, d.size, d.stride) for d in back.layout.dim] == [("field", 2, 1910), ("lane", 191, 955),
                                                                       ("axle_on", 5, 5)]
    assert back.layout.data_offset == 4 + 5
    # the layout of a shape is kept between messages: a message's own list, the same dimensions
    again = c.pack(3, 18, 0, a, ("field", "lane", "axle_on"))
    again.layout.dim.pop()
    assert [d.size for d in c.pack(3, 19, 0, a, ("field", "lane", "axle_on")).layout.dim] == [2, 191, 5]
    assert c.unpack(deserialize_message(serialize_message(c.pack(3, 19, 0, a[0], ("lane", "axle_on"))),
                                        Float64MultiArray))[4].tobytes() == a[0].tobytes()
    m = c.matrix_msg(("lane", "quantity"), a[0], step=12)
    assert np.frombuffer(m.data).tobytes() == np.concatenate([[12.0], a[0].ravel()]).tobytes()


def test_exchange_writer_sends_the_bytes_of_pack():
    """The nodes' ExchangeWriter (one message refilled per stage, rows written straight into its
    buffer, published serialized) sends what pack makes: the same layout and the same data bytes,
    through shape changes and back (compared deserialized; padding bytes are not defined); unpack
    reads the serialized bytes (a raw subscription's) as it reads the message."""
    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import Float64MultiArray

    def content(msg):
        back = deserialize_message(msg if isinstance(msg, bytes) else serialize_message(msg), Float64MultiArray)
        return ([(d.label, d.size, d.stride) for d in back.layout.dim], back.layout.data_offset,
                np.frombuffer(back.data).tobytes())

    sent = []

    class Pub:
        def publish(self, msg):
            sent.append(content(msg))

    rng = np.random.default_rng(3)
    w = rng.standard_normal((191, 5)) * 1e-3
    wd = rng.standard_normal((191, 5))
    wd[0, 0] = -0.0
    dims = ("field", "lane", "axle_on")
    writer = c.ExchangeWriter(Pub())
    cases = [(3, 17, 2, (w, wd), dims, np.array([4, 5, 6, 7, 8])),
             (3, 17, 3, (w[:, :2], wd[:, :2]), dims, np.array([7, 8])),
             (3, 18, 0, (w[:, :0], wd[:, :0]), dims, np.zeros(0, int)),
             (3, 18, 1, (w, wd), dims, np.array([4, 5, 6, 7, 8]))]
    raw = []
    writer.publisher.publish = lambda b: (raw.append(b), sent.append(content(b)))
    for run_id, k, stage, rows, d, idx in cases:
        writer.publish(run_id, k, stage, rows, d, idx)
        assert isinstance(raw[-1], bytes)
        assert sent[-1] == content(c.pack(run_id, k, stage, np.stack(rows), d, idx))
        got = c.unpack(raw[-1])
        assert got[:3] == (run_id, k, stage) and got[3].tolist() == idx.tolist()
        assert got[4].shape == np.stack(rows).shape and got[4].tobytes() == np.stack(rows).tobytes()
    with pytest.raises(c.ExchangeError, match="not a Float64MultiArray"):
        c.unpack(raw[0][:40])
    writer = c.ExchangeWriter(Pub())
    writer.publish(1, 0, 0, w, ("lane", "axle_on"), np.arange(5))
    assert sent[-1] == content(c.pack(1, 0, 0, w, ("lane", "axle_on"), np.arange(5)))
    assert len(sent) == 5
