"""``launch_scripts/monitor.py`` on a real sensor's data: a data logger's CSV (``--csv``) and an MCAP
of ``sensor_msgs/Imu`` mounted z down (``--axis -z``), each a record of tests/sensor_signals.py
(gravity, drift, noise, dropouts in the forced part and in the free decay, non-finite cells);
and the bad input of both (one line, exit 2, nothing written).

Tolerances (issue 35): dynamic peak within 1 %, f1 within 0.5 %, ζ1 within 5 % of the set values.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from sensor_signals import G, sensor_record
from ros_fixtures import ROOT

SCRIPT = ROOT / "launch_scripts" / "monitor.py"
DROPOUTS = ((6.3, 0.05), (50.1, 0.05), (91.0, 0.04))


def monitor(*args, timeout=300):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT)


def monitor_here(launcher, *args):
    """``monitor.py``'s ``main`` in this process (conftest's ``launcher``: exit code, stdout and
    stderr read at the file descriptors), as :func:`monitor` gives them. For the refusals: they end
    in the argument and file checks, where a process of their own cost about 0.2 s of CPU each (its
    start-up); and for the Imu record's second reading (its first runs the command's process, as
    the CSV record does)."""
    code, out, err = launcher(SCRIPT, [str(a) for a in args])
    return subprocess.CompletedProcess(["monitor.py", *map(str, args)], code, out, err)


def check_doc(doc, rec):
    ps = doc["passages"]
    assert len(ps) == len(rec.passages)
    for p, true in zip(ps, rec.passages):
        assert p["signal"] == "dynamic" and p["offset_m_s2"] == pytest.approx(G, abs=0.05)
        assert p["peak_acc_m_s2"] == pytest.approx(true["peak_m_s2"], rel=0.01)
        assert p["raw_peak_acc_m_s2"] > G and p["level"] == "within"
        assert p["identified"], p["reason"]
        assert p["f1_hz"] == pytest.approx(rec.f1_hz, rel=0.005)
        assert p["zeta1_pct"] == pytest.approx(100 * rec.zeta, rel=0.05)
    assert ps[1]["free_decay"]["method"] == "least squares on the samples present"
    assert ps[1]["free_decay"]["gaps"][0]["t_s"] == pytest.approx(50.1, abs=0.01)


@pytest.mark.slow
@pytest.mark.parametrize("fs", [500.0])
def test_csv_of_a_data_logger(fs, tmp_path):
    """Semicolon separated, other column names, an extra column, empty cells (lost samples).

    500 Hz only: the command's CSV path (read the file, feed the passage tracker sample by sample)
    does not depend on the rate; the analysis at 200 and 500 Hz is held by
    tests/monitoring/test_monitor_sensor.py (the tracker fed sample by sample included), and a
    200 Hz record goes through the command's process in test_mcap_of_an_imu_mounted_z_down."""
    rec = sensor_record(fs, dropouts=DROPOUTS)
    a = rec.a_m_s2.astype(object)
    empty = (rec.t_s > 30.0) & (rec.t_s < 30.01)  # quiet signal between passages
    nan_in = (rec.t_s > 11.0) & (rec.t_s < 11.01)  # free decay of passage 1
    a[empty] = ""
    a[nan_in] = "NaN"
    rows = "\n".join(f"{t!r};{x};{i}" for i, (t, x) in enumerate(zip(rec.t_s.tolist(), a.tolist())))
    csv = tmp_path / "logger.csv"
    csv.write_text("time_s;az;row\n" + rows + "\n")
    out = tmp_path / "p.json"
    res = monitor("--csv", csv, "--time-column", "time_s", "--accel-column", "az", "--json", out)
    assert res.returncode == 0, res.stderr
    doc = json.loads(out.read_text())
    check_doc(doc, rec)
    assert doc["passages"][0]["nonfinite_samples"] == int(nan_in.sum()) > 0
    assert f"warning: passage 1: {int(nan_in.sum())} non-finite samples" in res.stderr
    assert doc["source"] == str(csv) and doc["columns"] == {"time": "time_s", "accel": "az"}
    # the empty cells in the quiet signal belong to no passage: counted and said, not lost silently
    n_bad = int(empty.sum() + nan_in.sum())
    assert doc["nonfinite_samples"] == n_bad
    assert f"warning: {int(empty.sum())} non-finite samples (NaN or inf) outside every passage" in res.stderr
    assert f"3 passages, 3 with the first mode identified, {n_bad} non-finite samples excluded" in res.stdout


def write_imu_mcap(path, t_s, a_m_s2, topic="/sensor/imu", covariance=None, log_s=None):
    """Imu messages, the sensor mounted z down (``linear_acceleration.z`` = -a), x and y noise; logged
    at their stamps, or at ``log_s`` (a recorder's receive times)."""
    from sensor_msgs.msg import Imu

    from adm_sim.recording.mcap_log import McapRecorder

    with McapRecorder(path) as rec:
        for i, (t, a) in enumerate(zip(t_s, a_m_s2)):
            m = Imu()
            ns = int(round(t * 1e9))
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
            m.header.frame_id = "sensor"
            m.linear_acceleration.z = -float(a)
            m.linear_acceleration.x = 0.01
            if covariance is not None:
                m.linear_acceleration_covariance = covariance
            rec.write(topic, m, ns if log_s is None else int(round(log_s[i] * 1e9)))
    return path


@pytest.mark.slow
def test_mcap_of_an_imu_mounted_z_down(tmp_path, launcher):
    rec = sensor_record(200.0, dropouts=DROPOUTS)
    mcap = write_imu_mcap(tmp_path / "imu.mcap", rec.t_s, rec.a_m_s2)
    out = tmp_path / "p.json"
    res = monitor("--mcap", mcap, "--topic", "/sensor/imu", "--axis", "-z", "--json", out)
    assert res.returncode == 0, res.stderr
    doc = json.loads(out.read_text())
    check_doc(doc, rec)
    assert doc["axis"] == "-z" and res.stderr == ""
    # the same file read z up: the offset is -g, the dynamic numbers the same (|a|); the command's
    # main in this process (the file's process is the run above)
    res = monitor_here(launcher, "--mcap", mcap, "--topic", "/sensor/imu", "--json", tmp_path / "up.json")
    assert res.returncode == 0, res.stderr
    up = json.loads((tmp_path / "up.json").read_text())["passages"]
    assert [p["offset_m_s2"] for p in up] == pytest.approx([-p["offset_m_s2"] for p in doc["passages"]])
    assert [p["peak_acc_m_s2"] for p in up] == pytest.approx([p["peak_acc_m_s2"] for p in doc["passages"]])


def _refused(res, *words):
    assert res.returncode == 2, res.stdout + res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    for w in words:
        assert w in lines[0], lines[0]


@pytest.mark.slow
@pytest.mark.parametrize("text, args, words", [
    ("t,b\n0,1\n1,2\n", [], ["has no column 'a' (--accel-column); its columns: 't', 'b'"]),
    ("t,a\n0,1\n1,2\n", ["--time-column", "time"], ["has no column 'time' (--time-column)"]),
    ("t,a\n0,1\n0.5,2\n0.5,3\n", [], ["line 4: time 0.5 s repeats the time 0.5 s", "must strictly increase"]),
    ("t,a\n0,1\n0.5,2\n0.4,3\n", [], ["line 4: time 0.4 s goes back from 0.5 s"]),
    ("t,a\n0,1\nx,2\n", [], ["line 3: time 'x' in column 't' is not a finite number of seconds"]),
    ("t,a\n0,1\n1,1.2.3\n", [], ["line 3: acceleration '1.2.3' in column 'a' is not a number"]),
    ("", [], ["has no header line"]),
    ("t,a\n0,1\n", [], ["has 1 data row(s); at least 2"]),
    ("t,a\n0,1\n1,2\n", ["--axis", "up"], ["--axis: 'up' is not an axis; allowed z, -z, x, -x, y, -y"]),
    ("t,a\n0,1\n1,2\n", ["--status-topic", "/s"], ["--status-topic: not used with --csv"]),
])
def test_bad_csv(text, args, words, tmp_path, launcher):
    csv = tmp_path / "in.csv"
    csv.write_text(text)
    _refused(monitor_here(launcher, "--csv", csv, *args, "--json", tmp_path / "p.json"), "error: --", *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv"]


@pytest.mark.slow
def test_column_option_without_csv(tmp_path, launcher):
    _refused(monitor_here(launcher, "--mcap", tmp_path / "x.mcap", "--accel-column", "a"), "--accel-column: only used with --csv")


@pytest.mark.slow
@pytest.mark.parametrize("cov, words", [
    ([-1.0] + [0.0] * 8, ["carry no linear acceleration (linear_acceleration_covariance[0] = -1, REP 145)"]),
    ([0.1, 0, 0, 0, 0.1, 0, 0, 0, -1.0], ["mark axis z as absent (linear_acceleration_covariance[8] = -1)",
                                          "--axis"]),
])
def test_imu_without_the_axis(cov, words, tmp_path, launcher):
    t = np.arange(0.0, 1.0, 0.01)
    mcap = write_imu_mcap(tmp_path / "imu.mcap", t, np.zeros(t.size), covariance=cov)
    _refused(monitor_here(launcher, "--mcap", mcap, "--topic", "/sensor/imu", "--json", tmp_path / "p.json"), *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["imu.mcap"]


@pytest.mark.slow
@pytest.mark.parametrize("stamp_6, words", [
    (0.04, "sample 6 stamped 0.040000000 s repeats the stamp of sample 5 (0.040000000 s)"),
    (0.035, "sample 6 stamped 0.035000000 s goes back 0.005 s from sample 5 (0.040000000 s)"),
])
def test_mcap_stamps_that_do_not_increase(stamp_6, words, tmp_path, launcher):
    """An MCAP whose sixth sample repeats the fifth's stamp or goes back is refused as a CSV is: one
    line naming the topic, the file and the sample, exit 2, nothing written (logged in the order
    received, 10 ms apart)."""
    log = np.arange(0.0, 1.0, 0.01)
    t = log.copy()
    t[5] = stamp_6
    mcap = write_imu_mcap(tmp_path / "imu.mcap", t, np.zeros(t.size), log_s=log)
    _refused(monitor_here(launcher, "--mcap", mcap, "--topic", "/sensor/imu", "--json", tmp_path / "p.json"),
             f"error: --topic: '/sensor/imu' in '{mcap}': {words} (samples counted from 1 in log time order); "
             f"stamps must strictly increase")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["imu.mcap"]
