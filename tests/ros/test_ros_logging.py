"""Logging layer of the ROS graph: MCAP recording, salvage, rerun, replay, local-only environment.

Every file written here is read back by an independent reader (mcap-ros2-support, rosbags,
rerun's CLI or RrdReader). DDS stays on shared memory with a locked ROS_DOMAIN_ID; every child
process is killed and reaped by the test that started it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from adm_sim.errors import InputError
from adm_sim.processes import dds_env as ros_env
from adm_sim.recording.mcap_log import McapRecorder, message_definition, read_messages, salvage

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
BIN = Path(sys.executable).parent
REPLAY = ROOT / "launch_scripts" / "replay.py"

N_STEPS = 50  # time steps of the reference recording
DT_NS = 2_000_000  # 2 ms


def _messages(k: int):
    """The five message types of one time step ``k`` (values chosen to be exact in binary)."""
    from builtin_interfaces.msg import Time
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import AccelStamped
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    t_ns = k * DT_NS
    stamp = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
    js = JointState()
    js.header.stamp = stamp
    js.name = ["lane_100", "lane_200"]
    js.position = [0.25 * k, -0.5 * k]
    js.effort = [1.0 + k, 2.0 + k]
    arr = Float64MultiArray()
    arr.data = np.arange(8, dtype=np.float64) + 0.125 * k
    acc = AccelStamped()
    acc.header.stamp = stamp
    acc.header.frame_id = "300 km/h"
    acc.accel.linear.z = 0.0625 * k - 1.0
    diag = DiagnosticArray()
    diag.header.stamp = stamp
    diag.status = [DiagnosticStatus(level=DiagnosticStatus.WARN if k % 10 == 0 else
                                    DiagnosticStatus.OK, name="adm/bridge",
                                    message=f"step {k}",
                                    values=[KeyValue(key="max_acc_m_s2", value=f"{0.5 * k}")])]
    clock = Clock(clock=stamp)
    return t_ns, {"/clock": clock, "/adm/lanes/state": js, "/adm/lanes/accel": arr,
                  "/adm/midspan/accel": acc, "/diagnostics": diag}


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("mcap") / "run.mcap"
    with McapRecorder(path) as rec:
        rec.write_metadata("run", {"bridge": "B1", "model": "MLM", "speeds_kmh": "100,200"})
        for k in range(N_STEPS):
            t_ns, msgs = _messages(k)
            for topic, msg in msgs.items():
                rec.write(topic, msg, t_ns)
    return path


# ---------------------------------------------------------------- schemas, writing


def test_schema_text_is_rosbag2_style():
    from geometry_msgs.msg import AccelStamped

    name, text = message_definition(AccelStamped)
    assert name == "geometry_msgs/msg/AccelStamped"
    headers = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert headers == ["MSG: std_msgs/Header", "MSG: builtin_interfaces/Time",
                       "MSG: geometry_msgs/Accel", "MSG: geometry_msgs/Vector3"]
    assert text.count("=" * 80 + "\nMSG: ") == 4
    assert "/msg/" not in "".join(headers)


@pytest.mark.slow
def test_read_back_with_mcap_ros2(recording):
    got = list(read_messages(recording))
    assert len(got) == 5 * N_STEPS
    by_topic = {}
    for topic, t_ns, msg in got:
        by_topic.setdefault(topic, []).append((t_ns, msg))
    assert sorted(by_topic) == sorted(_messages(0)[1])
    k = 37
    t_ns, msg = by_topic["/adm/midspan/accel"][k]
    assert t_ns == k * DT_NS
    assert msg.accel.linear.z == 0.0625 * k - 1.0
    assert msg.header.frame_id == "300 km/h"
    assert list(by_topic["/adm/lanes/accel"][k][1].data) == list(np.arange(8) + 0.125 * k)
    js = by_topic["/adm/lanes/state"][k][1]
    assert list(js.name) == ["lane_100", "lane_200"] and list(js.effort) == [1.0 + k, 2.0 + k]
    diag = by_topic["/diagnostics"][10][1]
    assert diag.status[0].message == "step 10" and diag.status[0].values[0].value == "5.0"
    assert by_topic["/clock"][k][1].clock.nanosec == k * DT_NS


@pytest.mark.slow
def test_read_back_with_rosbags_equal_values(recording):
    from rosbags.highlevel import AnyReader

    ref = {(topic, t): msg for topic, t, msg in read_messages(recording)}
    n = 0
    with AnyReader([recording]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {"/clock": "rosgraph_msgs/msg/Clock",
                         "/adm/lanes/state": "sensor_msgs/msg/JointState",
                         "/adm/lanes/accel": "std_msgs/msg/Float64MultiArray",
                         "/adm/midspan/accel": "geometry_msgs/msg/AccelStamped",
                         "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray"}
        for conn, t_ns, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            other = ref[(conn.topic, t_ns)]
            if conn.topic == "/adm/midspan/accel":
                assert msg.accel.linear.z == other.accel.linear.z
                assert msg.header.stamp.nanosec == other.header.stamp.nanosec
            elif conn.topic == "/adm/lanes/accel":
                np.testing.assert_array_equal(msg.data, np.asarray(other.data))
            elif conn.topic == "/adm/lanes/state":
                np.testing.assert_array_equal(msg.position, np.asarray(other.position))
                assert msg.name == list(other.name)
            elif conn.topic == "/diagnostics":
                assert msg.status[0].message == other.status[0].message
                level = other.status[0].level
                assert msg.status[0].level == (ord(level) if isinstance(level, bytes) else level)
            n += 1
    assert n == 5 * N_STEPS


@pytest.mark.slow
def test_metadata_written(recording):
    from mcap.reader import make_reader

    with open(recording, "rb") as f:
        meta = list(make_reader(f).iter_metadata())
    assert len(meta) == 1 and meta[0].name == "run"
    assert meta[0].metadata == {"bridge": "B1", "model": "MLM", "speeds_kmh": "100,200"}


def test_overwrite_refused_and_allowed(tmp_path):
    from std_msgs.msg import Float64

    path = tmp_path / "x.mcap"
    with McapRecorder(path) as rec:
        rec.write("/a", Float64(data=1.0), 0)
    with pytest.raises(InputError, match=r"x\.mcap' already exists; refusing to overwrite"):
        McapRecorder(path)
    with McapRecorder(path, overwrite=True) as rec:
        rec.write("/a", Float64(data=2.0), 5)
        rec.write("/a", Float64(data=3.0), 6)
        rec.finish()
        rec.finish()  # idempotent
    assert [m.data for _, _, m in read_messages(path)] == [2.0, 3.0]
    with pytest.raises(InputError, match="is finished"):
        rec.write("/a", Float64(data=4.0), 7)


def test_serialized_messages_written_as_they_came(tmp_path):
    """The recorder's path for messages taken serialised (the driver's subscriptions): the CDR bytes
    go into the file unchanged, and both independent readers decode the message that was sent."""
    from geometry_msgs.msg import AccelStamped
    from rclpy.serialization import serialize_message
    from rosbags.highlevel import AnyReader
    from std_msgs.msg import Float64MultiArray

    from adm_sim.nodes.common import matrix_msg

    acc = AccelStamped()
    acc.header.stamp.sec, acc.header.stamp.nanosec = 3, 250_000_000
    acc.header.frame_id = "B1/midspan"
    acc.accel.linear.z = -0.123456789
    arr = matrix_msg(("lane", "quantity:disp_m,acc_m_s2"), np.arange(10.0).reshape(5, 2) / 7.0, step=12)
    raw = [serialize_message(acc), serialize_message(arr)]
    path = tmp_path / "s.mcap"
    with McapRecorder(path) as rec:
        rec.write_serialized("/adm/midspan/accel", AccelStamped, raw[0], 3_250_000_000)
        rec.write_serialized("/adm/midspan/state", Float64MultiArray, raw[1], 3_250_000_000)
        rec.write("/adm/midspan/accel", acc, 3_300_000_000)  # the same channel, the message path
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        stored = [m.data for _, _, m in make_reader(f).iter_messages(log_time_order=False)]
    assert stored[:2] == raw
    got = list(read_messages(path))
    assert [t for t, _, _ in got] == ["/adm/midspan/accel", "/adm/midspan/state", "/adm/midspan/accel"]
    for _, _, m in (got[0], got[2]):
        assert (m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id) == (3, 250_000_000, "B1/midspan")
        assert m.accel.linear.z == -0.123456789
    np.testing.assert_array_equal(np.asarray(got[1][2].data), [12.0, *(np.arange(10.0) / 7.0)])
    with AnyReader([path]) as reader:
        msgs = [reader.deserialize(raw_, c.msgtype) for c, _, raw_ in reader.messages()]
    assert msgs[0].accel.linear.z == -0.123456789 and msgs[1].layout.data_offset == 1
    np.testing.assert_array_equal(msgs[1].data, [12.0, *(np.arange(10.0) / 7.0)])


def test_bad_inputs_are_named(tmp_path):
    from std_msgs.msg import Float64, String

    with McapRecorder(tmp_path / "y.mcap") as rec:
        rec.write("/a", Float64(data=1.0), 0)
        with pytest.raises(InputError, match="'/a' is registered as std_msgs/Float64"):
            rec.write("/a", String(data="x"), 1)
        with pytest.raises(InputError, match=r"log_time_ns: -1 ns is out of range"):
            rec.write("/a", Float64(data=1.0), -1)
        with pytest.raises(InputError, match="not an absolute ROS topic name"):
            rec.register("a", Float64)
    with pytest.raises(InputError, match=r"chunk_size: 10 B is out of range; allowed >= 1024"):
        McapRecorder(tmp_path / "z.mcap", chunk_size=10)


# ---------------------------------------------------------------- kill and salvage

_KILLED_WRITER = """
import sys
from std_msgs.msg import Float64MultiArray
from adm_sim.recording.mcap_log import McapRecorder
rec = McapRecorder(sys.argv[1], chunk_size=8 * 1024)
rec.write_metadata("run", {"model": "DIM"})
msg = Float64MultiArray()
i = 0
while True:
    msg.data = [float(i)] * 32
    rec.write("/adm/lanes/accel", msg, i * 1000)
    i += 1
    if i % 50 == 0:
        print(i, flush=True)
"""


@pytest.mark.slow
def test_sigkill_mid_run_is_salvaged(tmp_path):
    from rosbags.highlevel import AnyReader

    src, dst = tmp_path / "killed.mcap", tmp_path / "clean.mcap"
    proc = subprocess.Popen([PY, "-c", _KILLED_WRITER, str(src)], stdout=subprocess.PIPE,
                            text=True)
    try:
        written = 0
        for line in proc.stdout:
            written = int(line)
            if written >= 2000:
                break
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        proc.stdout.close()
    assert proc.returncode == -signal.SIGKILL
    with pytest.raises(InputError, match="salvage"):
        list(read_messages(src))
    n = salvage(src, dst)
    # one message is 32 doubles + header, ~300 B: an 8 KiB chunk holds ~28 messages, so at
    # most one chunk (< 40 messages) of the 2000 printed ones may be lost
    assert n >= written - 40, (n, written)
    vals = [m.data[0] for _, _, m in read_messages(dst)]
    assert vals == [float(i) for i in range(n)]  # complete, in order, no gap
    with AnyReader([dst]) as reader:
        assert sum(1 for _ in reader.messages()) == n
    from mcap.reader import make_reader

    with open(dst, "rb") as f:
        assert [m.metadata for m in make_reader(f).iter_metadata()] == [{"model": "DIM"}]


@pytest.mark.slow
def test_salvage_errors_and_cli(tmp_path, recording, capsys):
    with pytest.raises(InputError, match=r"src: MCAP file '.*missing\.mcap' does not exist"):
        salvage(tmp_path / "missing.mcap", tmp_path / "o.mcap")
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 5)
    with pytest.raises(InputError, match="holds no complete message"):
        salvage(junk, tmp_path / "o.mcap")
    assert not (tmp_path / "o.mcap").exists() and not list(tmp_path.glob("o.mcap.part*"))
    # the one salvage command: adm-sim salvage
    from adm_sim.cli.sim_commands import main as adm_sim

    assert adm_sim(["salvage", str(recording), str(tmp_path / "copy.mcap")]) == 0
    assert capsys.readouterr().out.strip() == f"recovered {5 * N_STEPS} messages into {tmp_path / 'copy.mcap'}"
    assert adm_sim(["salvage", str(recording), str(tmp_path / "copy.mcap")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "copy.mcap" in err
    out = subprocess.run([PY, "-c", "import sys; from adm_sim.cli.sim_commands import main; sys.exit(main())", "salvage",
                          str(tmp_path / "no.mcap"), str(tmp_path / "p.mcap")], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 2
    assert out.stderr.splitlines() == [f"error: salvage SRC: '{tmp_path / 'no.mcap'}' is not a file"]


# ---------------------------------------------------------------- rerun


def _rerun_env():
    from adm_sim.recording.viewer_process import ensure_analytics_disabled, rerun_cli_env

    ensure_analytics_disabled()
    return rerun_cli_env()


@pytest.mark.slow
def test_rerun_mcap_convert_and_verify(recording, tmp_path):
    out = tmp_path / "conv.rrd"
    env = _rerun_env()
    conv = subprocess.run([str(BIN / "rerun"), "mcap", "convert", str(recording), "-o", str(out),
                           "--application-id", "adm_sim_test"],
                          capture_output=True, text=True, env=env, timeout=120)
    assert conv.returncode == 0, conv.stderr
    assert "Processed" in conv.stderr
    ver = subprocess.run([str(BIN / "rerun"), "rrd", "verify", str(out)], capture_output=True,
                         text=True, env=env, timeout=120)
    assert ver.returncode == 0, ver.stderr
    assert "1 file verified without error" in ver.stdout + ver.stderr


def test_analytics_disabled_in_config():
    import json

    from adm_sim.recording.viewer_process import analytics_config_path, ensure_analytics_disabled

    path = ensure_analytics_disabled()
    assert path == analytics_config_path()
    assert json.loads(path.read_text())["analytics_enabled"] is False


def _entity_rows(rrd: Path) -> dict[str, int]:
    from rerun.chunk import RrdReader

    rows: dict[str, int] = {}
    for chunk in RrdReader(rrd).stream():
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    return rows


@pytest.mark.slow
def test_run_logger_writes_a_verified_rrd(tmp_path):
    from adm_sim.recording import rerun_log as rl

    out = tmp_path / "views.rrd"
    rl.init_rerun("adm_sim_test", save_path=out, recording_id="views")
    viz = rl.RunLogger()
    viz.bridge_description({"bridge": {"span_m": 20.0, "n_modes": 3}, "n0_hz": 5.0, "description": "B"})
    viz.run_started({"node": "bridge", "run_id": 1, "state": "started", "model": "mlm", "n_steps": 500,
                     "n_lanes": 2, "ds_m": 0.02, "t0_s": 0.0, "monitor_speed_kmh": 300.0, "clock_speed_kmh": 100.0,
                     "monitor_every_steps": 1, "beam_every_steps": 50})
    t = np.arange(500) * 0.02 / (100 / 3.6)
    x = np.linspace(0.0, 20.0, 41)
    for k, tk in enumerate(t):
        viz.accel(tk, np.cos(tk))
        if k % 50 == 0:
            viz.beam(tk, x, 1e-3 * np.sin(np.pi * x / 20), [2.0 + k / 50], [1e-3])
    assert viz.run_done(np.array([[100.0, 300.0], [1.0, 5.0], [1e-3, 2e-3], [0.0, 0.0]]), "mlm_zeta") == rl.MLM_ZETA
    viz.iteration(1, 0.25, 5.0, 3.5, "root_search")
    rl.close_rerun()
    with pytest.raises(InputError, match="refusing to overwrite"):
        rl.init_rerun("adm_sim_test", save_path=out)
    rows = _entity_rows(out)
    assert rows["/runs/acceleration/run_01"] == 500 + 1  # + the static series style
    assert rows["/runs/beam/run_01/deflection"] == 10 + 1  # + the clear at the run end
    assert rows["/sweep/curves/MLM_zeta"] == 2 + 1
    assert rows["/calibration/delta_zeta_pct/root_search"] == 1 + 1
    ver = subprocess.run([str(BIN / "rerun"), "rrd", "verify", str(out)], capture_output=True,
                         text=True, env=_rerun_env(), timeout=120)
    assert ver.returncode == 0, ver.stderr


def test_rerun_refuses_remote_viewer():
    from adm_sim.recording.rerun_log import init_rerun

    with pytest.raises(InputError, match="is not on this machine"):
        init_rerun("adm_sim_test", connect_url="rerun+http://192.0.2.1:9876/proxy")


def test_run_logger_gives_a_sample_that_comes_before_its_runs_start_to_that_run(tmp_path):
    """Runs follow each other on the session clock (run 2 starts at run 1's t1). The first sample
    of run 2 can arrive, and be flushed, before run 2's ``started`` record (two topics, no order
    between them): it is kept for run 2, not logged as a 501st sample of run 1 (the flow test saw
    1680 samples of a run that published 1679 beside two busy processes)."""
    from adm_sim.recording import rerun_log as rl

    out = tmp_path / "two_runs.rrd"
    rl.init_rerun("adm_sim_test", save_path=out, recording_id="two_runs")
    viz = rl.RunLogger()
    n, ds, v_kmh = 500, 0.02, 100.0
    dt = ds / (v_kmh / 3.6)
    t1 = n * dt

    def started(rid, t0):
        viz.run_started({"node": "bridge", "run_id": rid, "state": "started", "model": "mlm", "n_steps": n,
                         "n_lanes": 1, "ds_m": ds, "t0_s": t0, "monitor_speed_kmh": v_kmh,
                         "clock_speed_kmh": v_kmh, "monitor_every_steps": 1, "beam_every_steps": 0})

    started(1, 0.0)
    for k in range(n):
        viz.accel(k * dt, 1.0)
    viz.accel(t1, 2.0)  # run 2's step 0, before run 2 is announced
    viz.flush()
    started(2, t1)
    for k in range(1, n):
        viz.accel(t1 + k * dt, 2.0)
    viz.flush()
    rl.close_rerun()
    rows = _entity_rows(out)
    assert rows["/runs/acceleration/run_01"] == n
    assert rows["/runs/acceleration/run_02"] == n


# ---------------------------------------------------------------- replay


@pytest.mark.slow
def test_replay_writes_rrd(recording, tmp_path):
    out = tmp_path / "replay.rrd"
    proc = subprocess.run([PY, str(REPLAY), str(recording), "--rrd", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert f"logged {5 * N_STEPS} messages on 5 topics" in proc.stdout
    rows = _entity_rows(out)
    assert rows["/topics/midspan_acceleration_m_s2/300\\ km\\/h"] == N_STEPS  # outside any run
    assert rows["/topics/adm/lanes/accel/0"] == N_STEPS
    assert rows["/diagnostics/adm\\/bridge"] == N_STEPS
    again = subprocess.run([PY, str(REPLAY), str(recording), "--rrd", str(out)],
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 2 and again.stderr.startswith("error: ")


@pytest.mark.slow
def test_replay_republishes_in_sim_time(recording):
    import rclpy
    from geometry_msgs.msg import AccelStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    with ros_env.local_ros_env() as env:
        saved = {k: os.environ.get(k) for k in ("ROS_DOMAIN_ID", "FASTDDS_BUILTIN_TRANSPORTS",
                                                "ROS_AUTOMATIC_DISCOVERY_RANGE")}
        os.environ.update({k: env[k] for k in saved})
        ctx = rclpy.context.Context()
        rclpy.init(context=ctx)
        node = rclpy.create_node("monitor", context=ctx)
        got, clocks = [], []
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(AccelStamped, "/adm/midspan/accel", got.append, qos)
        node.create_subscription(Clock, "/clock", clocks.append, 100)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        proc = subprocess.Popen(
            [PY, str(REPLAY), str(recording), "--republish", "--domain-id", str(env.domain_id),
             "--rate", "0", "--topics", "/adm/midspan/accel", "--wait-subscribers", "10"],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and (proc.poll() is None or len(got) < N_STEPS):
                ex.spin_once(timeout_sec=0.05)
                if proc.poll() is not None and len(got) >= N_STEPS:
                    break
            out, err = proc.communicate(timeout=20)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            ex.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
    assert proc.returncode == 0, err
    assert out.splitlines()[0] == f"ROS_DOMAIN_ID={env.domain_id}"
    assert len(got) == N_STEPS
    assert [m.accel.linear.z for m in got] == [0.0625 * k - 1.0 for k in range(N_STEPS)]
    assert len(clocks) >= N_STEPS - 1  # /clock may be best effort for late joiners
    assert clocks[-1].clock.nanosec == (N_STEPS - 1) * DT_NS


# ---------------------------------------------------------------- environment


@pytest.mark.slow
def test_local_env_locks_distinct_domain_ids():
    with ros_env.local_ros_env() as a, ros_env.local_ros_env() as b:
        assert a["FASTDDS_BUILTIN_TRANSPORTS"] == os.environ.get("FASTDDS_BUILTIN_TRANSPORTS",
                                                                 "SHM")
        assert a["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
        assert a.domain_id != b.domain_id
        assert 1 <= a.domain_id <= 101 and a["ROS_DOMAIN_ID"] == str(a.domain_id)
        # another process cannot take a held id
        probe = subprocess.run(
            [PY, "-c", "from adm_sim.processes.dds_env import _try_lock; import sys; "
                       f"sys.exit(0 if _try_lock({a.domain_id}) is None else 1)"], timeout=60)
        assert probe.returncode == 0
        held = a.lock
    assert not held.held
    assert ros_env.local_ros_env(7).domain_id == 7
    with pytest.raises(InputError, match=r"ROS_DOMAIN_ID: 233 is out of range; allowed \[0, 232\]"):
        ros_env.local_ros_env(233, base={"FASTDDS_BUILTIN_TRANSPORTS": "SHM"})


_SHM_NODE = """
import rclpy, sys, time
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node("shm_probe")
pub = node.create_publisher(Float64, "/probe", 10)
sub = node.create_subscription(Float64, "/probe", lambda m: None, 10)
for _ in range(20):
    pub.publish(Float64(data=1.0))
    rclpy.spin_once(node, timeout_sec=0.02)
print("ready", flush=True)
time.sleep(60)
"""


def _data_segments_locked_by(pid: int) -> set[str]:
    """Fast DDS data segments whose ``_el`` lock ``pid`` holds (its own, per /proc/locks)."""
    inodes = set()
    with open("/proc/locks") as f:
        for line in f:
            parts = line.split()
            if "->" not in parts and len(parts) > 5 and parts[4] == str(pid):
                inodes.add(int(parts[5].rsplit(":", 1)[1]))
    return {e.name[:-3] for e in os.scandir("/dev/shm")
            if e.name.endswith("_el") and "port" not in e.name and e.inode() in inodes}


@pytest.mark.slow
def test_cleanup_shm_removes_only_dead_process_files():
    """``fastdds shm clean`` (through cleanup_shm) removes the segment a SIGKILLed participant
    left and keeps the live one's."""
    procs = []
    with ros_env.local_ros_env() as env:
        try:
            for _ in range(2):
                procs.append(subprocess.Popen([PY, "-c", _SHM_NODE], env=env,
                                              stdout=subprocess.PIPE, text=True))
            for p in procs:
                assert p.stdout.readline().strip() == "ready"
            victim, survivor = procs
            mine = _data_segments_locked_by(victim.pid)
            theirs = _data_segments_locked_by(survivor.pid)
            assert len(mine) == 1 and len(theirs) == 1
            (seg,), (other,) = mine, theirs
            ros_env.cleanup_shm()  # both alive: both kept
            assert os.path.exists(f"/dev/shm/{seg}") and os.path.exists(f"/dev/shm/{other}")
            victim.send_signal(signal.SIGKILL)
            victim.wait(timeout=10)
            assert os.path.exists(f"/dev/shm/{seg}")  # SIGKILL leaves the segment behind
            report = ros_env.cleanup_shm()
            assert report.startswith("shm.clean:") and "zombie segments cleaned" in report
            assert not os.path.exists(f"/dev/shm/{seg}") and not os.path.exists(f"/dev/shm/{seg}_el")
            assert os.path.exists(f"/dev/shm/{other}") and os.path.exists(f"/dev/shm/{other}_el")
            assert _data_segments_locked_by(survivor.pid) == theirs  # still locked by its live owner
        finally:
            for p in procs:
                if p.poll() is None:
                    p.kill()
                p.wait(timeout=10)
                p.stdout.close()
            ros_env.cleanup_shm()


def test_domain_ids_are_not_reused_straight_away():
    # A freed id goes to the back of the queue: DDS may still see a killed run on it.
    from adm_sim.processes.dds_env import reserve_domain_id

    first = reserve_domain_id()
    used = first.domain_id
    first.release()
    again = [reserve_domain_id() for _ in range(5)]
    try:
        assert used not in [lock.domain_id for lock in again]
        assert len({lock.domain_id for lock in again}) == 5
    finally:
        for lock in again:
            lock.release()


# ---------------------------------------------------------------- damaged files
def _chunks(data):
    """``[(body_start, body_end, n_messages)]`` of every Chunk record, parsed by hand from the MCAP
    specification (record: opcode u8, length u64, body; Chunk body: start u64, end u64,
    uncompressed size u64, crc u32, compression str, records u64 + bytes; records inside likewise)."""
    import struct

    from mcap.stream_reader import zstandard  # the codec mcap itself uses

    out, pos = [], 8
    while pos + 9 <= len(data):
        opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        body = pos + 9
        if opcode == 0x06:
            n_comp = struct.unpack_from("<I", data, body + 28)[0]
            comp = data[body + 32:body + 32 + n_comp].decode()
            size_at = body + 32 + n_comp
            n_rec = struct.unpack_from("<Q", data, size_at)[0]
            raw = data[size_at + 8:size_at + 8 + n_rec]
            if comp == "zstd":
                raw = zstandard.ZstdDecompressor().decompress(raw, max_output_size=struct.unpack_from("<Q", data, body + 16)[0])
            n_msg, q = 0, 0
            while q < len(raw):
                n_msg += raw[q] == 0x05
                q += 9 + struct.unpack_from("<Q", raw, q + 1)[0]
            out.append((size_at + 8, size_at + 8 + n_rec, n_msg))
        pos = body + length
    return out


@pytest.mark.slow
def test_damaged_chunk_is_skipped_and_counted(tmp_path):
    """One chunk's compressed bytes flipped: salvage recovers every other chunk (the count is the
    file's messages minus those of that chunk, counted by a parser written from the spec), reports
    the loss, and every reader refuses the damaged file with one line instead of a zstd traceback."""
    recording = tmp_path / "run.mcap"
    with McapRecorder(recording, chunk_size=1024) as rec:  # many small chunks
        for k in range(N_STEPS):
            t_ns, msgs = _messages(k)
            for topic, msg in msgs.items():
                rec.write(topic, msg, t_ns)
    data = recording.read_bytes()
    chunks = _chunks(data)
    total = sum(n for *_, n in chunks)
    assert total == 5 * N_STEPS and len(chunks) >= 3
    start, end, lost = chunks[len(chunks) // 2]
    bad = bytearray(data)
    for i in range((start + end) // 2, min(end, (start + end) // 2 + 32)):
        bad[i] ^= 0x5A
    src = tmp_path / "bad.mcap"
    src.write_bytes(bytes(bad))
    report = {}
    n = salvage(src, tmp_path / "out.mcap", report=report)
    damage = report.pop("damage")
    assert report == {"chunks": len(chunks), "lost_chunks": 1, "orphan_messages": 0, "truncated": False}
    assert n == total - lost
    assert len(damage) == 2 and damage[0].startswith("chunk ") and f": {lost} messages lost (" in damage[0]
    assert damage[1].startswith(f"in all {lost} of {total} recorded messages lost (")
    from rosbags.highlevel import AnyReader

    with AnyReader([tmp_path / "out.mcap"]) as reader:
        assert sum(1 for _ in reader.messages()) == n
    with pytest.raises(InputError, match=r"is damaged \(.*\); recover its readable chunks with: adm-sim salvage"):
        list(read_messages(src))
    r = subprocess.run([PY, str(ROOT / "launch_scripts" / "replay.py"), str(src), "--rrd", str(tmp_path / "o.rrd")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.splitlines() == [f"error: RUN.mcap: '{src}' is damaged (1 of {len(chunks)} chunks do not "
                                     f"decompress or fail their CRC; {damage[0]}); replay its intact chunks with "
                                     f"--skip-damaged or recover them with: adm-sim salvage {src} OUT.mcap"]
    assert not (tmp_path / "o.rrd").exists()
    r = subprocess.run([PY, "-m", "adm_sim.cli.sim_commands", "salvage", str(src), str(tmp_path / "cli.mcap")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0
    assert r.stdout.splitlines() == [f"recovered {n} messages into {tmp_path / 'cli.mcap'}",
                                     f"lost: 1 of {len(chunks)} chunks were damaged and skipped"] + [
                                     f"dropped: {line}" for line in damage]


@pytest.mark.slow
def test_replay_of_a_file_without_messages_is_an_error(tmp_path):
    from mcap.writer import Writer

    empty = tmp_path / "empty.mcap"
    with open(empty, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        w.finish()
    for extra in ([], ["--via-convert"]):
        r = subprocess.run([PY, str(ROOT / "launch_scripts" / "replay.py"), str(empty), "--rrd",
                            str(tmp_path / "o.rrd")] + extra, capture_output=True, text=True, timeout=120)
        assert r.returncode == 2
        assert r.stderr.splitlines() == [f"error: RUN.mcap: '{empty}' holds no message; nothing to replay"]
        assert not (tmp_path / "o.rrd").exists()
