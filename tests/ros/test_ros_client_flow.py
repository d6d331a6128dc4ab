"""A client that joins after a job's runs gets every run's per-passage summary, in order.

(The opted-in clients under load, live and in a replay at ``--rate 0``: tests/ros/test_ros_flow.py.)
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from ros_fixtures import node_procs, ros_domain  # noqa: F401

pytest.importorskip("rclpy")
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

SUMMARIES = r"""
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
rclpy.init()
n = rclpy.create_node("late_summaries")
got = []
qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
n.create_subscription(DiagnosticStatus, "/adm/run/summary", got.append, qos)
import time
end = time.monotonic() + 20
while len(got) < 3 and time.monotonic() < end:
    rclpy.spin_once(n, timeout_sec=0.1)
print([dict((kv.key, kv.value) for kv in s.values)["run_id"] for s in got], flush=True)
rclpy.try_shutdown()
"""


#: Coarse runs (4 steps per period, one period of free vibration) whose monitoring topics carry every
#: 16th step and the beam and clock every 64th: the summary is the bridge's own, of every step, however
#: few steps are published; at these steps the automatic decimation publishes every one, and the
#: in-process driver receives and deserialises it all.
SHORT_RUN = {"steps_per_period": 4.0, "free_vibration_periods": 1.0, "monitor_every_steps": 16, "beam_every_steps": 64}


@pytest.mark.slow
def test_a_late_client_reads_every_passage_summary(node_procs, ros_domain):
    """Three runs, then a client joins: the summary's history (TRANSIENT_LOCAL, KEEP_LAST 1000) gives it
    all three passages, in order (with the depth-1 latching of before it got the last one only)."""
    from ros_fixtures import driver_node

    node_procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": "B1", **SHORT_RUN})
    node_procs.start("train", "adm_sim.nodes.train_node", {"speeds_kmh": "250,260", "model": "mlm"})
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        ids = [d.request_run()["run_id"] for _ in range(3)]
        late = subprocess.run([sys.executable, "-c", SUMMARIES], env=dict(ros_domain), capture_output=True,
                              text=True, timeout=120)
    assert late.stdout.strip() == repr([str(i) for i in ids]), late.stdout + late.stderr
