"""A run's MCAP says its real date (metadata ``recording``) while its log times stay sim time."""

import time

import pytest

pytest.importorskip("rclpy")
from ros_fixtures import ros_domain  # noqa: E402,F401


def test_recorder_writes_the_wall_clock_start(tmp_path, ros_domain):
    import rclpy
    from mcap.reader import make_reader
    from rclpy.node import Node

    from adm_sim.nodes.recorder import RunRecorder

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=ros_domain.domain_id)
    node = Node("rec_date", context=ctx)
    try:
        before = time.time_ns()
        rec = RunRecorder(node, {"record_path": tmp_path / "run.mcap"})
        after = time.time_ns()
        rec.finish(keep=True)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    with open(tmp_path / "run.mcap", "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    got = meta["recording"]
    assert before <= int(got["started_unix_ns"]) <= after
    # the UTC text is the same instant to the second
    assert got["started_utc"] == time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(int(got["started_unix_ns"]) // 10**9))
    assert got["log_time"].startswith("sim time")
