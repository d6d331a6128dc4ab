"""``launch_scripts/monitor.py`` end to end: a real crossing's MCAP, synthetic recordings (a sensor
topic without run records, a free decay too short), live on a ROS 2 graph, and every bad input
(one line ``error: ...``, exit 2, nothing written). The real crossing's recording, the restarted
bridge's and the live tests run the command's own process; the synthetic recordings and the
refusals of bad options and files run its ``main`` in this process (:func:`monitor_here`)."""

from __future__ import annotations

import json
import math
import queue
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from ros_fixtures import _HELD, ROOT, NodeProcs, ros_domain  # noqa: F401  (fixture)

from adm_sim.processes.dds_env import local_ros_env

pytestmark = pytest.mark.slow  # every test here starts processes

SCRIPT = ROOT / "launch_scripts" / "monitor.py"
KEYS = {"peak_acc_m_s2", "t_peak_s", "level", "f1_hz", "zeta1_pct", "f1_std_hz", "zeta1_std_pct", "identified",
        "reason"}
#: B1 with ζ = 1 % and 20 periods of free vibration after ICE-2 leaves, MLM at 263 km/h (resonance):
#: 15.5 cycles of free decay, about 4500 acceleration samples, fewer than the depth (5000) of the
#: bridge's and the monitor's histories, so a reliable subscriber that matched before the run can
#: be sent every one of them however late it takes them.
BRIDGE = {"bridge": "B1", "zeta_pct": 1.0, "free_vibration_periods": 20.0}
TRAIN = {"train": "ICE-2", "model": "mlm", "speeds_kmh": "263"}


def monitor(*args, env=None, timeout=180):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT, env=env)


def monitor_here(launcher, *args):
    """``monitor.py``'s ``main`` in this process (conftest's ``launcher``: exit code, stdout and
    stderr read at the file descriptors), as :func:`monitor` gives them. For the refusals: they end
    in the argument and file checks, where a process of their own cost 0.17 s of CPU each (its
    start-up) for 0.01 s of checking; and for the synthetic recordings (the analysis under test, not
    the process; 1 s of start-up each, scipy's import the most of it). The real crossing's recording,
    the live tests and the restarted bridge's (whose stderr must stay empty: in this process a Python
    warning would be pytest's, not the stream's) run the command's process."""
    code, out, err = launcher(SCRIPT, [str(a) for a in args])
    return subprocess.CompletedProcess(["monitor.py", *map(str, args)], code, out, err)


def decay(t, amp=2.0, f_hz=8.26, zeta=0.01):
    w = 2 * math.pi * f_hz
    return amp * np.exp(-zeta * w * t) * np.cos(w * math.sqrt(1 - zeta ** 2) * t)


def write_mcap(path, samples=(), records=(), topic="/adm/midspan/accel"):
    """An MCAP with AccelStamped ``samples`` ``(t_s, a)`` on ``topic`` and String ``records``
    ``(t_s, topic, dict)``, as the recorder writes them."""
    from geometry_msgs.msg import AccelStamped
    from std_msgs.msg import String

    from adm_sim.recording.mcap_log import McapRecorder

    with McapRecorder(path) as rec:
        for t, topic_r, d in records:
            rec.write(topic_r, String(data=json.dumps(d)), int(round(t * 1e9)))
        for t, a in samples:
            m = AccelStamped()
            ns = int(round(t * 1e9))
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
            m.header.frame_id = "sensor"
            m.accel.linear.z = float(a)
            rec.write(topic, m, ns)
    return path


def _read_lines(stream, lines):
    for line in stream:
        lines.put(line)
    lines.put(None)


def _wait_line(lines, seen, words, timeout_s):
    """The first line holding ``words`` from the queue ``lines`` (kept in ``seen``), else None at EOF
    or after ``timeout_s``."""
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        try:
            line = lines.get(timeout=min(0.5, max(0.01, t_end - time.monotonic())))
        except queue.Empty:
            continue
        if line is None:
            return None
        seen.append(line)
        if words in line:
            return line
    return None


# session scope: with --dist worksteal a worker can come back to this module after others, and a
# module-scoped fixture is then run again (a crossing, 13 s); the tests only read the run folder
# and what the monitor did, and the processes have ended when it returns
@pytest.fixture(scope="session")
def crossing_run(tmp_path_factory):
    """One crossing on a domain of its own, monitored live: ``monitor.py --passages 1`` and the bridge
    and train node processes start, and once the monitor has subscribed and found the bridge's
    acceleration publisher the driver node process runs the crossing (it records ``run.mcap`` and
    writes ``summary.json``, as under ``crossing.py``). The run starts after the monitor matched,
    so the live monitor is owed every sample. Returns the run folder and what the monitor did;
    each test asserts on its part (the recording's tests do not depend on the live monitor)."""
    out = tmp_path_factory.mktemp("crossing")
    run = out / "run"
    run.mkdir()
    env = local_ros_env()
    _HELD.append(env)  # never reused by a later test of the session
    env["OPENBLAS_NUM_THREADS"] = "1"
    env["PYTHONUNBUFFERED"] = "1"
    procs = NodeProcs(env, out / "logs")
    live = {"json": out / "live.json", "lines": []}
    mon = subprocess.Popen([sys.executable, str(SCRIPT), "--domain-id", str(env.domain_id), "--passages", "1",
                            "--timeout", "120", "--json", str(live["json"])], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env)
    lines = queue.Queue()
    threading.Thread(target=_read_lines, args=(mon.stdout, lines), daemon=True).start()
    try:
        procs.start("bridge", "adm_sim.nodes.bridge_node", BRIDGE)  # no run before the driver starts
        procs.start("train", "adm_sim.nodes.train_node", TRAIN)
        live["subscribed"] = _wait_line(lines, live["lines"], "subscribed to /adm/midspan/accel", 120)
        live["found"] = _wait_line(lines, live["lines"], "publisher(s) found", 120)
        driver = procs.start("driver", "adm_sim.nodes.driver",
                             {"record_path": str(run / "run.mcap"), "summary_path": str(run / "summary.json")})
        driver.wait(300)
        assert driver.returncode == 0, procs.stderr("driver")
        try:
            mon.wait(120)
        except subprocess.TimeoutExpired:
            pass
    finally:
        if mon.poll() is None:
            mon.kill()
            mon.wait()
        procs.stop_all()
    live["returncode"] = mon.returncode
    live["stderr"] = mon.stderr.read()
    mon.stderr.close()
    _wait_line(lines, live["lines"], "\0", 10.0)  # the rest of its stdout, to its end
    return run, live


def test_mcap_of_a_real_crossing(crossing_run, tmp_path):
    """f1 within 0.5 % of n0 and ζ1 within 5 % of mode 1's 1 % (measured: 8.2630 Hz for n0 8.2621 Hz,
    ζ1 0.994 %; 0.999 % from 30 periods of free vibration), the peak the one of the recorded samples, its level against 3.5 m/s²."""
    from adm_sim.model.bridge import named_bridge

    run, _live = crossing_run
    out = tmp_path / "passages.json"
    res = monitor("--mcap", run / "run.mcap", "--json", out)
    assert res.returncode == 0, res.stderr
    doc = json.loads(out.read_text())
    (p,) = doc["passages"]
    assert KEYS <= set(p)
    assert p["identified"] is True and p["reason"] is None
    assert (p["run_id"], p["source"]) == (1, "run records")
    assert p["f1_hz"] == pytest.approx(named_bridge("B1").n0_hz, rel=0.005)
    assert p["zeta1_pct"] == pytest.approx(1.0, rel=0.05)
    assert 0 < p["zeta1_std_pct"] < 0.05 and 0 < p["f1_std_hz"] < 0.01
    summary = json.loads((run / "summary.json").read_text())
    exact = summary["max_acc_m_s2"][0]  # every step; the topic carries every 2nd
    assert 0.99 * exact <= p["peak_acc_m_s2"] <= exact
    assert p["level"] == ("above" if p["peak_acc_m_s2"] > 3.5 else "near" if p["peak_acc_m_s2"] > 2.8 else "within")
    assert p["free_decay"]["t_start_s"] >= p["t_train_left_s"]
    assert f"passage 1 (run 1, mlm_zeta): dynamic peak |a| {p['peak_acc_m_s2']:.4f} m/s^2" in res.stdout
    assert doc["dropped_samples"] == 0


def test_mcap_sensor_topic_without_run_records(tmp_path, launcher):
    """A foreign topic, no run records: two passages found by the signal, each identified."""
    fs = 400
    t = np.arange(0.0, 60.0, 1 / fs)
    a = 0.002 * np.random.default_rng(2).standard_normal(t.size)
    for t0, amp in ((5.0, 1.2), (30.0, 2.0)):
        on = t >= t0
        a[on] += decay(t[on] - t0, amp)
    path = write_mcap(tmp_path / "sensor.mcap", zip(t, a), topic="/sensor/accel")
    out = tmp_path / "p.json"
    res = monitor_here(launcher, "--mcap", path, "--topic", "/sensor/accel", "--json", out)
    assert res.returncode == 0, res.stderr
    ps = json.loads(out.read_text())["passages"]
    assert [p["source"] for p in ps] == ["signal", "signal"]
    for p in ps:
        assert p["identified"], p["reason"]
        assert p["f1_hz"] == pytest.approx(8.26, rel=1e-3)
        assert p["zeta1_pct"] == pytest.approx(1.0, rel=0.02)


def test_mcap_too_short_a_free_decay_is_said_per_passage(tmp_path, launcher):
    """A run whose record ends 2 periods after the train left: no number, the reason instead."""
    fs = 400
    t = np.arange(0.0, 2.0 / 8.26, 1 / fs)
    st = "/adm/run/status"
    records = [(0.0, st, {"node": "bridge", "run_id": 1, "state": "started", "t0_s": 0.0}),
               (0.0, st, {"node": "bridge", "run_id": 1, "state": "done", "t0_s": 0.0, "t1_s": float(t[-1]) + 1 / fs})]
    path = write_mcap(tmp_path / "short.mcap", zip(t, decay(t)), records)
    out = tmp_path / "p.json"
    res = monitor_here(launcher, "--mcap", path, "--json", out)
    assert res.returncode == 0, res.stderr
    (p,) = json.loads(out.read_text())["passages"]
    assert p["identified"] is False
    assert "cycles" in p["reason"]
    assert all(p[k] is None for k in ("f1_hz", "zeta1_pct", "f1_std_hz", "zeta1_std_pct"))
    assert "first mode not identified: " in res.stdout and "zeta1" not in res.stdout


# ---------------------------------------------------------------------- bad input
@pytest.fixture
def status_only(tmp_path):
    return write_mcap(tmp_path / "status_only.mcap", records=[
        (0.0, "/adm/run/status", {"node": "bridge", "run_id": 1, "state": "started", "t0_s": 0.0})])


@pytest.fixture
def with_accel(tmp_path):
    return write_mcap(tmp_path / "accel.mcap", [(0.0, 0.1), (0.01, 0.2)],
                      [(0.0, "/adm/run/status", {"node": "bridge", "run_id": 1, "state": "started", "t0_s": 0.0})])


def _refused(res, *words):
    assert res.returncode == 2, res.stdout + res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    for w in words:
        assert w in lines[0], lines[0]


@pytest.mark.parametrize("case, args, words", [
    ("no such topic", ["--topic", "/nope"], ["--topic: '/nope' is not in", "AccelStamped and Imu topics: /adm/midspan/accel"]),
    ("another type", ["--topic", "/adm/run/status"], ["has type std_msgs/msg/String, not geometry_msgs/msg/AccelStamped"]),
    ("relative topic", ["--topic", "adm/x"], ["--topic: 'adm/x' is not an absolute topic name"]),
    ("domain id with mcap", ["--domain-id", "5"], ["--domain-id: only used live"]),
    ("status topic", ["--status-topic", "/nope"], ["--status-topic: '/nope' is not a std_msgs/String topic"]),
    ("timeout", ["--timeout", "-1"], ["--timeout: -1 s is out of range"]),
    ("min cycles", ["--min-cycles", "1"], ["--min-cycles: 1 periods is out of range; allowed [2, 1000]"]),
])
def test_bad_input_mcap(case, args, words, with_accel, tmp_path, launcher):
    out = tmp_path / "p.json"
    before = sorted(tmp_path.iterdir())
    _refused(monitor_here(launcher, "--mcap", with_accel, *args, "--json", out), *words)
    assert sorted(tmp_path.iterdir()) == before


def test_mcap_without_the_topic(status_only, tmp_path, launcher):
    before = sorted(tmp_path.iterdir())
    _refused(monitor_here(launcher, "--mcap", status_only, "--json", tmp_path / "p.json"),
             "'/adm/midspan/accel' is not in", "it holds no AccelStamped or Imu topic")
    assert sorted(tmp_path.iterdir()) == before


def test_not_an_mcap(tmp_path, launcher):
    bad = tmp_path / "run.mcap"
    bad.write_text("hello\n")
    _refused(monitor_here(launcher, "--mcap", bad, "--json", tmp_path / "p.json"), "--mcap:", "is not an MCAP file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]


def test_json_is_not_overwritten(with_accel, tmp_path, launcher):
    out = tmp_path / "p.json"
    out.write_text("keep\n")
    _refused(monitor_here(launcher, "--mcap", with_accel, "--json", out), "--json:", "exists; use --overwrite")
    assert out.read_text() == "keep\n"


@pytest.mark.parametrize("value, words", [("300", "--domain-id: 300 is out of range"),
                                          ("x", "--domain-id: 'x' is not an integer")])
def test_bad_domain_id(value, words, tmp_path, launcher):
    _refused(monitor_here(launcher, "--domain-id", value, "--json", tmp_path / "p.json"), words)
    assert list(tmp_path.iterdir()) == []


def test_live_topic_that_does_not_appear(ros_domain, tmp_path):  # noqa: F811
    res = monitor("--domain-id", ros_domain.domain_id, "--timeout", "1", "--json", tmp_path / "p.json",
                  env=dict(ros_domain))
    _refused(res, "topic: '/adm/midspan/accel' did not appear within 1 s", f"ROS_DOMAIN_ID {ros_domain.domain_id}")
    assert list(tmp_path.iterdir()) == []


def test_live_topic_of_another_type(ros_domain, tmp_path):  # noqa: F811
    import rclpy
    from std_msgs.msg import String

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=int(ros_domain.domain_id))
    node = rclpy.create_node("not_an_accelerometer", context=ctx)
    node.create_publisher(String, "/adm/midspan/accel", 10)
    try:
        res = monitor("--domain-id", ros_domain.domain_id, "--timeout", "20", "--json", tmp_path / "p.json",
                      env=dict(ros_domain))
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    _refused(res, "topic: '/adm/midspan/accel' has type std_msgs/msg/String, not geometry_msgs/msg/AccelStamped")
    assert list(tmp_path.iterdir()) == []


def test_live_crossing(crossing_run):
    """The monitor subscribes before a crossing starts on its domain and reports the passage as it
    completes: the same f1 and ζ1 tolerances as from the recording, and every sample the bridge
    published (the monitor matched before the run started; the run's samples fit the histories).

    Until this test waited for the monitor's ``publisher(s) found`` line before starting the run,
    it started ``crossing.py`` right after the monitor subscribed: the run could begin before the
    monitor's subscription matched the bridge's publisher (discovery of a new participant, slower
    under load), and what was published before the match never reached the monitor (a volatile
    subscription): a passage of few samples, or none."""
    from adm_sim.model.bridge import named_bridge

    run, live = crossing_run
    assert live["subscribed"] and live["found"], live
    assert live["returncode"] == 0, live["stderr"]
    doc = json.loads(live["json"].read_text())
    (p,) = doc["passages"]
    assert p["identified"], p["reason"]
    assert p["run_id"] == 1 and p["source"] == "run records"
    assert p["f1_hz"] == pytest.approx(named_bridge("B1").n0_hz, rel=0.005)
    assert p["zeta1_pct"] == pytest.approx(1.0, rel=0.05)
    summary = json.loads((run / "summary.json").read_text())
    assert p["n_samples"] == summary["samples"]["/adm/midspan/accel"] < 5000
    assert p["samples_published"] == p["n_samples"] and p["samples_lost"] == 0
    assert doc["dropped_samples"] == 0
    assert any(ln.startswith("passage 1 (run 1") for ln in live["lines"]), live["lines"]
    # no rclpy "offering incompatible QoS ... No messages will be received" beside a monitor that receives
    assert "incompatible" not in live["stderr"].lower(), live["stderr"]
    assert p["bridge"] == "B1" and p["offset_m_s2"] == 0.0 and p["signal"] == "dynamic"


def test_mcap_of_a_bridge_started_again(tmp_path):
    """A recording across a bridge started again: its second run stamps from 0 s again, after the
    first's 6 s (each run's done at 5.5 s: the samples after it complete the run). The second
    bridge's started record starts the stamp order again: the recording is read, not refused (without
    it: exit 2, the second bridge's first sample going back 5.9975 s), and the first run identified.
    The second run's passage is not checked: the tracker places the first bridge's samples after its
    done in it, and cuts them out again with all that follows (its run records give no bridge
    identity; a matter of its own)."""
    from geometry_msgs.msg import AccelStamped
    from std_msgs.msg import String

    from adm_sim.recording.mcap_log import McapRecorder

    fs, st = 400, "/adm/run/status"
    t = np.arange(0.0, 6.0, 1 / fs)
    a = decay(t) + 0.002 * np.random.default_rng(4).standard_normal(t.size)
    path = tmp_path / "restart.mcap"
    with McapRecorder(path) as rec:
        for log0 in (0.0, 10.0):  # log time: the recorder's clock, on across the restart
            run = {"node": "bridge", "run_id": 1, "t0_s": 0.0}
            rec.write(st, String(data=json.dumps({**run, "state": "started"})), int(round(log0 * 1e9)))
            done = {**run, "state": "done", "t1_s": 5.5}  # the samples after it complete the run
            rec.write(st, String(data=json.dumps(done)), int(round((log0 + 5.5) * 1e9)))
            for ti, ai in zip(t, a):
                m = AccelStamped()
                m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(round(ti * 1e9)), 1_000_000_000)
                m.accel.linear.z = float(ai)
                rec.write("/adm/midspan/accel", m, int(round((log0 + ti) * 1e9)) + 1)
    out = tmp_path / "p.json"
    res = monitor("--mcap", path, "--json", out)
    assert res.returncode == 0, res.stderr
    ps = json.loads(out.read_text())["passages"]
    assert len(ps) == 2 and res.stderr == "", res.stdout + res.stderr
    assert ps[0]["identified"] and ps[0]["f1_hz"] == pytest.approx(8.26, rel=1e-3)
