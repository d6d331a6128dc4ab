"""The shipped Fast DDS profile (ros_ws/dds/fastdds_shm_only.xml) carries messages between two
processes over shared memory with no builtin (UDP) transport."""

import os
import subprocess
import sys
from pathlib import Path

from adm_sim.processes.dds_env import reserve_domain_id

PROFILE = Path(__file__).resolve().parents[1] / "ros_ws" / "dds" / "fastdds_shm_only.xml"

SUB = r"""
import sys, rclpy
from std_msgs.msg import Float64MultiArray
rclpy.init()
n = rclpy.create_node("probe_sub")
got = []
n.create_subscription(Float64MultiArray, "probe", lambda m: got.append(sum(m.data)), 10)
print("ready", flush=True)
import time
end = time.monotonic() + 20
while not got and time.monotonic() < end:
    rclpy.spin_once(n, timeout_sec=0.1)
print("sum", got[0] if got else None, flush=True)
rclpy.try_shutdown()
"""

PUB = r"""
import rclpy, time
from std_msgs.msg import Float64MultiArray
rclpy.init()
n = rclpy.create_node("probe_pub")
p = n.create_publisher(Float64MultiArray, "probe", 10)
end = time.monotonic() + 20
while p.get_subscription_count() == 0 and time.monotonic() < end:
    rclpy.spin_once(n, timeout_sec=0.05)
m = Float64MultiArray()
m.data = [float(i) for i in range(1000)]
for _ in range(50):
    p.publish(m)
    rclpy.spin_once(n, timeout_sec=0.05)
rclpy.try_shutdown()
"""


def test_shm_only_profile_delivers_between_processes():
    # the profile alone (ROS_AUTOMATIC_DISCOVERY_RANGE would make rmw add its own transports)
    drop = ("FASTDDS_BUILTIN_TRANSPORTS", "ROS_AUTOMATIC_DISCOVERY_RANGE")
    env = {k: v for k, v in os.environ.items() if k not in drop}
    lock = reserve_domain_id()  # a domain id no concurrent run uses
    env.update(FASTRTPS_DEFAULT_PROFILES_FILE=str(PROFILE), ROS_DOMAIN_ID=str(lock.domain_id))
    sub = subprocess.Popen([sys.executable, "-c", SUB], env=env, stdout=subprocess.PIPE, text=True)
    try:
        assert sub.stdout.readline().strip() == "ready"
        # no UDP socket at all in the subscriber (the builtin UDP transport is off)
        fds = Path(f"/proc/{sub.pid}/fd")
        inodes = {os.readlink(f).split("[")[1].rstrip("]") for f in fds.iterdir()
                  if os.readlink(f).startswith("socket:[")}
        udp_inodes = set()
        for table in ("/proc/net/udp", "/proc/net/udp6"):
            for line in Path(table).read_text().splitlines()[1:]:
                udp_inodes.add(line.split()[9])
        assert not inodes & udp_inodes
        pub = subprocess.run([sys.executable, "-c", PUB], env=env, timeout=60)
        assert pub.returncode == 0
        out = sub.communicate(timeout=30)[0]
    finally:
        if sub.poll() is None:
            sub.kill()
        lock.release()
    assert "sum 499500.0" in out
