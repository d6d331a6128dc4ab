"""The shipped Fast DDS profile (ros_ws/dds/fastdds_local.xml) lets a client given only the profile
and the domain id join a graph started as the launchers start theirs (the environment of
``local_ros_env``: ``FASTDDS_BUILTIN_TRANSPORTS=SHM ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``), and
opens no UDP socket on another address than 127.0.0.1."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from adm_sim.processes.dds_env import CLIENT_VARIABLES, local_ros_env

PROFILE = Path(__file__).resolve().parents[2] / "ros_ws" / "dds" / "fastdds_local.xml"

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


def _udp_addresses(pid):
    """Local addresses (hex ``IP:port`` of /proc/net/udp) of the UDP sockets process ``pid`` holds."""
    fds = Path(f"/proc/{pid}/fd")
    inodes = {os.readlink(f).split("[")[1].rstrip("]") for f in fds.iterdir()
              if os.readlink(f).startswith("socket:[")}
    found = []
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            cols = line.split()
            if cols[9] in inodes:
                found.append(cols[1])
    return found


@pytest.mark.slow
def test_profile_alone_joins_a_launcher_graph_over_loopback_only():
    graph = local_ros_env()  # what a launcher starts its nodes with (a reserved domain id)
    # the client: the profile and the domain id, none of the launcher's discovery variables
    client = {k: v for k, v in os.environ.items() if k not in CLIENT_VARIABLES}
    client.update(FASTRTPS_DEFAULT_PROFILES_FILE=str(PROFILE), ROS_DOMAIN_ID=str(graph.domain_id))
    sub = subprocess.Popen([sys.executable, "-c", SUB], env=client, stdout=subprocess.PIPE, text=True)
    try:
        assert sub.stdout.readline().strip() == "ready"
        # every UDP socket of the client is bound to 127.0.0.1 (0100007F in /proc/net/udp)
        addresses = _udp_addresses(sub.pid)
        assert addresses and all(a.startswith("0100007F:") for a in addresses), addresses
        pub = subprocess.run([sys.executable, "-c", PUB], env=graph, timeout=60)
        assert pub.returncode == 0
        out = sub.communicate(timeout=30)[0]
    finally:
        if sub.poll() is None:
            sub.kill()
        graph.release()
    assert "sum 499500.0" in out  # 0 + 1 + ... + 999: the message itself


# ---------------------------------------------------------------- domain ids


def test_exported_domain_id_is_honoured_and_checked_per_transport():
    from adm_sim.errors import InputError
    from adm_sim.processes.dds_env import local_ros_env

    import pytest

    env = local_ros_env(base={"ROS_DOMAIN_ID": "150"})  # exported: kept, not replaced by a free id
    assert (env.domain_id, env["ROS_DOMAIN_ID"], env["FASTDDS_BUILTIN_TRANSPORTS"], env.lock) == (150, "150", "SHM", None)
    assert local_ros_env(232, base={"ROS_DOMAIN_ID": "150"}).domain_id == 232  # an explicit id wins
    assert local_ros_env(101, base={"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}).domain_id == 101
    with local_ros_env(base={"ROS_DOMAIN_ID": ""}) as free:  # empty: a free, locked id
        assert 1 <= free.domain_id <= 101 and free.lock.held
    cases = [
        (dict(domain_id=233, base={}), "ROS_DOMAIN_ID: 233 is out of range; allowed [0, 232]"),
        (dict(base={"ROS_DOMAIN_ID": "233"}), "ROS_DOMAIN_ID (exported): 233 is out of range; allowed [0, 232]"),
        (dict(base={"ROS_DOMAIN_ID": "b3"}), "ROS_DOMAIN_ID (exported): 'b3' is not an integer; allowed [0, 232]"),
        (dict(domain_id=102, base={"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}),
         "ROS_DOMAIN_ID: 102 is out of range; allowed [0, 101] with FASTDDS_BUILTIN_TRANSPORTS=UDPv4 "
         "(up to 232 with FASTDDS_BUILTIN_TRANSPORTS=SHM)"),
    ]
    for kw, message in cases:
        with pytest.raises(InputError) as exc:
            local_ros_env(**kw)
        assert str(exc.value) == message


@pytest.mark.slow
def test_launchers_refuse_an_exported_domain_id_out_of_range(tmp_path):
    """The launchers read an exported ROS_DOMAIN_ID (they no longer replace it): out of range,
    one line, exit 2, no output folder."""
    root = Path(__file__).resolve().parents[2]
    for script, extra in (("crossing.py", []), ("replay.py", ["--republish"])):
        argv = [sys.executable, str(root / "launch_scripts" / script)]
        argv += ([str(root / "tests" / "data" / "missing.mcap")] if script == "replay.py" else ["--out", str(tmp_path / "o")])
        env = dict(os.environ, ROS_DOMAIN_ID="240", FASTDDS_BUILTIN_TRANSPORTS="SHM")
        if script == "replay.py":
            mcap = tmp_path / "in.mcap"
            mcap.write_bytes(b"\x89MCAP0\r\n")
            argv[2] = str(mcap)
        out = subprocess.run(argv + extra, capture_output=True, text=True, timeout=120, env=env)
        assert out.returncode == 2, (script, out.stderr)
        assert out.stderr.splitlines() == ["error: ROS_DOMAIN_ID (exported): 240 is out of range; allowed [0, 232]"]
        assert out.stdout == "" and not (tmp_path / "o").exists()
    env = dict(os.environ, ROS_DOMAIN_ID="150", FASTDDS_BUILTIN_TRANSPORTS="UDPv4")
    out = subprocess.run([sys.executable, str(root / "launch_scripts" / "crossing.py"), "--out", str(tmp_path / "o")],
                         capture_output=True, text=True, timeout=120, env=env)
    assert out.returncode == 2
    assert out.stderr.splitlines() == ["error: ROS_DOMAIN_ID (exported): 150 is out of range; allowed [0, 101] with "
                                       "FASTDDS_BUILTIN_TRANSPORTS=UDPv4 (up to 232 with FASTDDS_BUILTIN_TRANSPORTS=SHM)"]
