"""The monitor node in-process (isolated rclpy context): run records and samples published on
one domain become one passage per run; a best-effort sensor topic is matched; bad parameters are
refused with the core's one-line reason."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from ros_fixtures import ros_domain  # noqa: F401  (fixture)

from adm_sim.errors import InputError


def decay(t, amp=1.5, f_hz=8.26, zeta=0.01):
    w = 2 * math.pi * f_hz
    return amp * np.exp(-zeta * w * t) * np.cos(w * math.sqrt(1 - zeta ** 2) * t)


@pytest.fixture
def ctx(ros_domain):  # noqa: F811
    import rclpy

    c = rclpy.context.Context()
    rclpy.init(context=c, domain_id=int(ros_domain.domain_id))
    yield c
    rclpy.try_shutdown(context=c)


def make_monitor(ctx, **params):
    from rclpy.parameter import Parameter

    from adm_sim.nodes.monitor_node import MonitorNode

    return MonitorNode(context=ctx, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])


def spin_until(ctx, nodes, done, timeout_s=30.0):
    from rclpy.executors import SingleThreadedExecutor

    ex = SingleThreadedExecutor(context=ctx)
    for n in nodes:
        ex.add_node(n)
    t_end = time.monotonic() + timeout_s
    while not done() and time.monotonic() < t_end:
        ex.spin_once(timeout_sec=0.05)
    ex.shutdown()


def accel_msg(t, a, frame="b1/midspan"):
    from geometry_msgs.msg import AccelStamped

    m = AccelStamped()
    ns = int(round(t * 1e9))
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    m.header.frame_id = frame
    m.accel.linear.z = float(a)
    return m


@pytest.mark.slow  # in-process nodes, records of several runs: 2.5 s of CPU
def test_passage_per_run_from_records(ctx, tmp_path):
    from std_msgs.msg import String

    from adm_sim.nodes import common as c
    from adm_sim.nodes.monitor_node import QOS_SAMPLES

    out = tmp_path / "p.json"
    mon = make_monitor(ctx, json_path=str(out), settle_s=0.5)
    src = __import__("rclpy").create_node("fake_bridge", context=ctx)
    pub_a = src.create_publisher(type(accel_msg(0, 0)), "/adm/midspan/accel", QOS_SAMPLES)
    pub_s = src.create_publisher(String, "/adm/run/status", c.QOS_CONTROL)
    spin_until(ctx, [mon, src], lambda: pub_a.get_subscription_count() and pub_s.get_subscription_count(), 10)
    t = np.arange(0.0, 6.0, 1 / 400)
    a = -decay(t)  # z up or down: |a| counts
    pub_s.publish(String(data=json.dumps({"node": "bridge", "run_id": 7, "state": "started", "t0_s": 0.0})))
    for ti, ai in zip(t, a):
        pub_a.publish(accel_msg(ti, ai))
    pub_s.publish(String(data=json.dumps({"node": "bridge", "run_id": 7, "state": "done", "t0_s": 0.0,
                                          "t1_s": 6.0})))
    spin_until(ctx, [mon, src], lambda: len(mon.tracker.passages) == 1)
    (p,) = mon.tracker.passages
    assert p.run_id == 7 and p.n_samples == t.size
    assert p.peak_acc_m_s2 == np.abs(a).max()
    assert p.identified and p.fit.zeta1 == pytest.approx(0.01, rel=0.01)
    doc = json.loads(out.read_text())
    assert doc["passages"][0]["run_id"] == 7 and doc["passages"][0]["identified"] is True
    src.destroy_node()
    mon.destroy_node()
    from adm_sim.files import release_all

    release_all()


def test_best_effort_sensor_is_matched(ctx):
    from rclpy.qos import qos_profile_sensor_data

    mon = make_monitor(ctx, topic="/sensor/accel", quiet_s=1.0)
    src = __import__("rclpy").create_node("sensor", context=ctx)
    pub = src.create_publisher(type(accel_msg(0, 0)), "/sensor/accel", qos_profile_sensor_data)
    spin_until(ctx, [mon, src], lambda: mon.best_effort, 10)
    assert mon.best_effort
    spin_until(ctx, [mon, src], lambda: pub.get_subscription_count() > 0, 10)
    time.sleep(0.3)
    t = np.arange(0.0, 12.0, 1 / 400)
    a = 0.002 * np.random.default_rng(1).standard_normal(t.size)
    a[t >= 2.0] += decay(t[t >= 2.0] - 2.0)
    for i, (ti, ai) in enumerate(zip(t, a)):
        pub.publish(accel_msg(ti, ai, "sensor"))
        if i % 200 == 0:  # best effort: let the subscriber keep up
            spin_until(ctx, [mon, src], lambda: False, 0.01)
    spin_until(ctx, [mon, src], lambda: mon.samples >= t.size, 10)
    mon.finish()
    (p,) = mon.tracker.passages
    assert p.source == "signal"
    assert p.peak_acc_m_s2 == pytest.approx(1.5, rel=0.02)
    src.destroy_node()
    mon.destroy_node()


@pytest.mark.parametrize("params, match", [
    ({"track_type": "gravel"}, "track_type: 'gravel' is not allowed; allowed ballasted or direct_fastening"),
    ({"topic_timeout_s": 0.0}, r"topic_timeout_s: 0 s is out of range; allowed \[0.1, 3600\] s"),
    ({"min_cycles": 1.0}, r"min_cycles: 1 periods is out of range"),
    ({"topic": ""}, "topic: '' is empty"),
])
def test_bad_parameters(ctx, params, match):
    with pytest.raises(InputError, match=match):
        make_monitor(ctx, **params)


def test_existing_json_is_refused(ctx, tmp_path):
    out = tmp_path / "p.json"
    out.write_text("keep")
    with pytest.raises(InputError, match="json_path: .* exists; set -p overwrite:=true to replace it"):
        make_monitor(ctx, json_path=str(out))
    assert out.read_text() == "keep"


@pytest.mark.slow
@pytest.mark.parametrize("args, message", [
    (["-p", "track_type:=gravel"], "error: monitor: track_type: 'gravel' is not allowed"),
    (["-p", "topic_timeout_s:=0.5"], "error: monitor: topic: '/adm/midspan/accel' did not appear within 0.5 s"),
])
def test_node_process_bad_input(ros_domain, args, message):  # noqa: F811
    """``python -m adm_sim.nodes.monitor_node``: one ``error: monitor: ...`` line, exit 2."""
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-m", "adm_sim.nodes.monitor_node", "--ros-args", *args],
                         capture_output=True, text=True, timeout=120, env=dict(ros_domain))
    assert res.returncode == 2
    errors = [line for line in res.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and errors[0].startswith(message), res.stderr
    assert res.stderr.strip().splitlines() == errors, res.stderr  # no [INFO] line before it (issue 38)


def imu_msg(t, a):
    from sensor_msgs.msg import Imu

    m = Imu()
    ns = int(round(t * 1e9))
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    m.header.frame_id = "sensor"
    m.linear_acceleration.z = float(a)
    return m


@pytest.mark.slow  # in-process nodes, a 200 Hz Imu stream: 4.4 s of CPU
def test_live_imu_sensor(ctx):
    """A z-up Imu at 200 Hz with gravity, drift, noise, dropouts in the forced part and in the free
    decay, live: each passage's dynamic peak within 1 %, f1 within 0.5 %, ζ1 within 5 %."""
    from sensor_signals import check_passages, sensor_record

    from adm_sim.nodes.monitor_node import QOS_SAMPLES

    rec = sensor_record(200.0, passages=(5.0, 45.0), duration_s=80.0, dropouts=((6.3, 0.05), (50.1, 0.05)))
    mon = make_monitor(ctx, topic="/sensor/imu")
    src = __import__("rclpy").create_node("imu_driver", context=ctx)
    pub = src.create_publisher(type(imu_msg(0, 0)), "/sensor/imu", QOS_SAMPLES)
    spin_until(ctx, [mon, src], lambda: pub.get_subscription_count() > 0, 10)
    assert mon.kind == "sensor_msgs/msg/Imu" and not mon.best_effort
    for i, (ti, ai) in enumerate(zip(rec.t_s, rec.a_m_s2)):
        pub.publish(imu_msg(ti, ai))
        if i % 200 == 0:  # keep within the history depth (5000): a live sensor's pace, not a burst
            spin_until(ctx, [mon, src], lambda i=i: mon.samples >= i - 1000, 10)
    spin_until(ctx, [mon, src], lambda: mon.samples >= rec.t_s.size, 30)
    assert mon.samples == rec.t_s.size
    mon.finish()
    check_passages(mon.tracker.passages, rec)
    assert mon.tracker.passages[1].fit.method == "least squares on the samples present"
    src.destroy_node()
    mon.destroy_node()


@pytest.mark.slow  # starts the node process
def test_node_process_best_effort_sensor_without_qos_warning(ros_domain, monkeypatch):  # noqa: F811
    """A best-effort sensor: the node subscribes best effort from the start, so rclpy never says
    'offering incompatible QoS. No messages will be received' (issue 35); the passage is reported
    (after ``quiet_s`` of wall time without samples: the test reads the node's stderr until the
    passage's line is there, at most 60 s, then stops the node)."""
    import signal
    import subprocess
    import sys
    import threading

    import rclpy
    from rclpy.qos import qos_profile_sensor_data

    proc = subprocess.Popen([sys.executable, "-m", "adm_sim.nodes.monitor_node", "--ros-args", "-p",
                             "topic:=/sensor/accel", "-p", "quiet_s:=1.0", "-p", "topic_timeout_s:=60.0"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, env=dict(ros_domain))
    lines, reported = [], threading.Event()

    def read_stderr():
        for line in proc.stderr:
            lines.append(line)
            if "passage 1:" in line:
                reported.set()

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    for key in ("FASTDDS_BUILTIN_TRANSPORTS", "ROS_AUTOMATIC_DISCOVERY_RANGE"):  # this process joins its graph
        monkeypatch.setenv(key, ros_domain[key])
    c = rclpy.context.Context()
    rclpy.init(context=c, domain_id=int(ros_domain.domain_id))
    try:
        src = rclpy.create_node("sensor", context=c)
        pub = src.create_publisher(type(accel_msg(0, 0)), "/sensor/accel", qos_profile_sensor_data)
        spin_until(c, [src], lambda: pub.get_subscription_count() > 0, 60)
        assert pub.get_subscription_count() > 0
        time.sleep(0.5)
        t = np.arange(0.0, 8.0, 1 / 400)
        a = 0.002 * np.random.default_rng(1).standard_normal(t.size)
        a[t >= 2.0] += decay(t[t >= 2.0] - 2.0)
        for i, (ti, ai) in enumerate(zip(t, a)):
            pub.publish(accel_msg(ti, ai, "sensor"))
            if i % 20 == 0:
                time.sleep(0.005)  # best effort: let the subscriber keep up (on a loaded machine too)
        reported.wait(60.0)  # quiet_s of wall time without samples: the passage is reported
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=60)
        reader.join(10)
        rclpy.try_shutdown(context=c)
    err = "".join(lines)
    assert "incompatible" not in err.lower(), err
    assert "best effort" in err and "passage 1: dynamic peak |a| 1.4" in err and "f1 8.26" in err, err


def test_imu_without_linear_acceleration_is_refused(ctx):
    """An Imu whose ``linear_acceleration_covariance[0]`` is -1 (REP 145: no linear acceleration):
    the first message ends the monitor with one line naming the topic (exit 2 in ``main``)."""
    from adm_sim.nodes.monitor_node import QOS_SAMPLES

    mon = make_monitor(ctx, topic="/sensor/imu")
    src = __import__("rclpy").create_node("imu_driver", context=ctx)
    pub = src.create_publisher(type(imu_msg(0, 0)), "/sensor/imu", QOS_SAMPLES)
    spin_until(ctx, [mon, src], lambda: pub.get_subscription_count() > 0, 10)
    m = imu_msg(0.0, 9.81)
    m.linear_acceleration_covariance[0] = -1.0
    pub.publish(m)
    with pytest.raises(InputError, match=r"topic: '/sensor/imu': the Imu messages carry no linear acceleration "
                                         r"\(linear_acceleration_covariance\[0\] = -1, REP 145\)"):
        spin_until(ctx, [mon, src], lambda: False, 10)
    assert mon.tracker.passages == [] and mon.samples == 0
    src.destroy_node()
    mon.destroy_node()


def test_samples_whose_stamps_do_not_increase_are_refused(ctx):
    """Live, a duplicate stamp and a clock stepping back 0.1 s (10 samples) are refused, one warning
    naming the topic and the sample where each stretch starts and one where it ends; the monitor goes
    on and the passage has the numbers of the clean stream, exactly."""
    from rclpy.parameter import Parameter

    from adm_sim.nodes.monitor_node import MonitorNode

    t = np.arange(0.0, 8.0, 1 / 400)
    a = 0.002 * np.random.default_rng(1).standard_normal(t.size)
    a[t >= 2.0] += decay(t[t >= 2.0] - 2.0)
    bad = [(ti, ai) for ti, ai in zip(t[:301], a[:301])] + [(t[300], a[300] + 5.0)]  # sample 302: a duplicate
    bad += [(ti, ai) for ti, ai in zip(t[301:500], a[301:500])] + [(ti - 0.1, 9.0) for ti in t[500:510]]
    bad += [(ti, ai) for ti, ai in zip(t[500:], a[500:])]
    warnings = []
    mons = [MonitorNode(context=ctx, parameter_overrides=[Parameter("topic", value="/sensor/accel")], **kw)
            for kw in ({"on_warning": warnings.append}, {})]
    for mon, stream in zip(mons, (bad, list(zip(t, a)))):
        mon.kind, mon.imu_checked = "geometry_msgs/msg/AccelStamped", True
        for ti, ai in stream:
            mon._on_accel(accel_msg(ti, ai, "sensor"))
        mon.finish()
    assert mons[0].refused_samples == 11 and mons[1].refused_samples == 0
    assert warnings == [
        "/sensor/accel: sample 302 stamped 0.750000000 s repeats the stamp of sample 301 (0.750000000 s): refused, "
        "with every sample until the stamps pass 0.750000000 s (stamps must strictly increase)",
        "/sensor/accel: samples 302 to 302 refused (stamps not after 0.750000000 s); taken again from sample 303",
        "/sensor/accel: sample 502 stamped 1.150000000 s goes back 0.0975 s from sample 501 (1.247500000 s): "
        "refused, with every sample until the stamps pass 1.247500000 s (stamps must strictly increase)",
        "/sensor/accel: samples 502 to 511 refused (stamps not after 1.247500000 s); taken again from sample 512"]
    got, ref = (m.tracker.passages for m in mons)
    assert len(got) == len(ref) == 1 and ref[0].identified
    assert got[0].fit == ref[0].fit and got[0].peak_acc_m_s2 == ref[0].peak_acc_m_s2
    for mon in mons:
        mon.destroy_node()


def test_a_new_bridge_starts_the_stamp_order_again(ctx):
    """A bridge started again stamps from 0 s: its ``started`` run record (t0_s 0 below the last
    stamp taken) starts the order again, so its samples are taken, not refused."""
    from std_msgs.msg import String

    from adm_sim import protocol as P

    mon = make_monitor(ctx, topic="/sensor/accel")
    mon.kind, mon.imu_checked = "geometry_msgs/msg/AccelStamped", True
    t = np.arange(0.0, 2.0, 1 / 400)
    for ti in t:
        mon._on_accel(accel_msg(ti, 0.0, "sensor"))
    mon._on_status(String(data=P.encode(P.status_record("bridge", 1, "started", t0_s=0.0))))
    for ti in t[:100]:
        mon._on_accel(accel_msg(ti, 0.0, "sensor"))
    assert mon.refused_samples == 0 and mon.last_stamp[1] == t.size + 100
    assert mon.last_stamp[0] == pytest.approx(t[99], abs=1e-9)
    mon.destroy_node()
