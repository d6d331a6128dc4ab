"""Every sample arrives: the recorder's flow control under load, per-run sample counts, trials
never above WARN, the per-passage summary.

Two busy processes hog both cores while the main job (``launch_scripts/calibrate.py``, B1 x ICE-2,
on a narrower speed range than the default so that the suite stays short) and a ``crossing.py``
MLM sweep run back to back. Every sample of every run is counted in the MCAP and in the ``.rrd``
against the counts the bridge published (its ``done`` records), and every run's counts are in the
MCAP's metadata.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter

import numpy as np
import pytest
from mcap.reader import make_reader
from rrd_views import read_rrd

from adm_sim import protocol as P
from adm_sim.recording.mcap_log import read_messages
from ros_fixtures import ros_domain  # noqa: F401

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _runs(mcap):
    """Bridge ``done`` records (with ``samples``) and ``started`` records by run id."""
    done, started = {}, {}
    for _t, _ns, m in read_messages(mcap, topics=[P.TOPIC_STATUS]):
        st = json.loads(m.data)
        if st.get("node") == P.BRIDGE_NODE and st.get("state") == P.DONE:
            done[st["run_id"]] = st
        if P.is_bridge_start(st):
            started[st["run_id"]] = st
    return done, started


def check_every_sample(out):
    """Count every monitoring message of every run in ``out/run.mcap`` and ``out/run.rrd``."""
    mcap = out / "run.mcap"
    done, started = _runs(mcap)
    assert done and set(done) == set(started)
    totals = Counter()
    accel = {rid: [] for rid in done}
    for topic, t_ns, m in read_messages(mcap, topics=list(P.SAMPLE_TOPICS)):
        if topic == P.TOPIC_DIAGNOSTICS and not any(s.name in (P.DIAG_NAME, P.DIAG_TRIAL_NAME) for s in m.status):
            continue
        totals[topic] += 1
        if topic == P.TOPIC_ACCEL:
            t = t_ns * 1e-9
            rid = next(r for r, st in done.items() if st["t0_s"] - 1e-9 <= t < st["t1_s"] - 1e-9)
            accel[rid].append((t, m))
    for topic in P.SAMPLE_TOPICS:  # nothing lost, nothing twice, over the whole recording
        assert totals[topic] == sum(st["samples"][topic] for st in done.values()), topic
    with open(mcap, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    for rid, st in done.items():
        s0 = started[rid]
        n, every = st["n_steps"], s0["monitor_every_steps"]
        assert st["samples"][P.TOPIC_ACCEL] == len(accel[rid]) == -(-n // every), rid
        # the step of every sample from its stamp (the monitored lane's time, docs/ros.md)
        v = s0["monitor_speed_kmh"] / 3.6
        steps = [round((t - s0["t0_s"]) * v / s0["ds_m"]) for t, _m in accel[rid]]
        assert steps == list(range(0, n, every)), rid
        assert {m.header.frame_id for _t, m in accel[rid]} == {"B1/midspan"}
        md = meta[f"{P.run_tag(rid)}_samples"]
        assert md["whole"] == "True"
        for topic in P.SAMPLE_TOPICS:
            assert md[f"received {topic}"] == md[f"published {topic}"] == str(st["samples"][topic])
    ents = read_rrd(out / "run.rrd")
    for rid, st in done.items():
        e = ents[f"/{P.acceleration_path(rid)}"]  # the samples (the series style is one static row more)
        assert len(e["values"]) == len(e["times"][P.SIM_TIME]) == st["samples"][P.TOPIC_ACCEL], rid
    return done, started


#: The main job's parameters (ros_ws/params/b1_ice2.yaml) at 4 RK4 steps per period of the highest
#: mode (not 16), one fundamental period of free vibration (not 2) and a monitoring sample at every
#: step (not every second one): a quarter of the DIM round trips, half the monitoring messages per
#: run (the flow control and the counts, not the numbers' accuracy, are under test).
COARSE_PARAMS = """\
bridge:
  ros__parameters:
    bridge: B1
    steps_per_period: 4.0
    free_vibration_periods: 1.0
    monitor_every_steps: 1
train:
  ros__parameters:
    train: ICE-2
    model: dim
calibration:
  ros__parameters:
    dim_grid: window
"""


@pytest.mark.slow
def test_no_sample_lost_under_load(tmp_path, ros_domain):
    from ros_fixtures import ROOT

    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        cal, cross = tmp_path / "cal", tmp_path / "cross"
        common = ["--domain-id", str(ros_domain.domain_id)]
        params = tmp_path / "b1_ice2_coarse.yaml"
        params.write_text(COARSE_PARAMS)
        p = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "calibrate.py"), "--bridge", "B1",
                            "--train", "ICE-2", "--speeds", "240:290:2", "--params-file", str(params),
                            "--out", str(cal), "--quiet"] + common,
                           env=dict(ros_domain), capture_output=True, text=True, timeout=600, cwd=ROOT)
        assert p.returncode == 0, p.stderr
        q = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "crossing.py"), "--bridge", "B1",
                            "--train", "ICE-2", "--model", "mlm", "--speeds", "160:350:10", "--out", str(cross)]
                           + common, env=dict(ros_domain), capture_output=True, text=True, timeout=600, cwd=ROOT)
        assert q.returncode == 0, q.stderr
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    done, started = check_every_sample(cal)
    check_every_sample(cross)
    summary = json.loads((cal / "summary.json").read_text())
    assert summary["co_simulation"]["incomplete_runs"] == []

    # trials are marked where they are produced, and a B1 x ICE-2 calibration raises no ERROR
    phases = {rid: st["phase"] for rid, st in started.items()}
    assert {P.PHASE_BRACKETING, P.PHASE_ROOT_SEARCH, P.PHASE_DIM, P.PHASE_MLM_ZETA} <= set(phases.values())
    assert all(done[rid]["phase"] == ph for rid, ph in phases.items())
    levels = Counter()
    for _t, _ns, m in read_messages(cal / "run.mcap", topics=[P.TOPIC_DIAGNOSTICS]):
        for s in m.status:
            vals = dict((kv.key, kv.value) for kv in s.values)
            levels[int.from_bytes(s.level, "little") if isinstance(s.level, bytes) else s.level] += 1
            if s.name in (P.DIAG_NAME, P.DIAG_TRIAL_NAME):
                trial = vals["phase"] in P.TRIAL_PHASES
                assert s.name == (P.DIAG_TRIAL_NAME if trial else P.DIAG_NAME)
                assert vals["phase"] == phases[int(vals["run_id"])]
    assert levels[2] == 0, levels
    assert levels[1] > 0  # the trials that exceed the limit say so at WARN

    # one latched per-passage summary per run, after the run's data, with the exact peak
    results = [P_matrix(m) for _t, _ns, m in read_messages(cal / "run.mcap", topics=[P.TOPIC_RESULT])]
    summaries = [P.summary_from_values([(kv.key, kv.value) for kv in m.values])
                 for _t, _ns, m in read_messages(cal / "run.mcap", topics=[P.TOPIC_SUMMARY])]
    assert [s["run_id"] for s in summaries] == sorted(done)
    for s, res in zip(summaries, results):
        st = started[s["run_id"]]
        lane = st["monitor_lane"]
        assert s["peak_acc_m_s2"] == res[1][lane]  # exact (repr round trip)
        assert s["speed_kmh"] == res[0][lane] == st["monitor_speed_kmh"]
        assert s["phase"] == phases[s["run_id"]]
        assert s["samples"] == done[s["run_id"]]["samples"]
        assert st["t0_s"] <= s["t_peak_s"] <= done[s["run_id"]]["t1_s"]
        assert s["level"] == (0 if s["peak_acc_m_s2"] <= 0.8 * 3.5 else 1 if (
            s["peak_acc_m_s2"] <= 3.5 or s["phase"] in P.TRIAL_PHASES) else 2)
        assert abs(s["x_front_peak_m"] - s["step_peak"] * st["ds_m"]) < 1e-9


def P_matrix(msg):
    shape = tuple(d.size for d in msg.layout.dim)
    return np.asarray(msg.data[msg.layout.data_offset:], dtype=float).reshape(shape)


def test_step_messages_counts_what_a_step_publishes():
    """The bridge checks the flow-control window before a DIM step's monitoring (it publishes the
    rail state first): :meth:`MonitoringOutput.step_messages` must count exactly the messages
    :meth:`MonitoringOutput.step_done` then publishes, so the window is never passed. Checked on every
    step of a B1 x ICE-2 run's grid with the automatic decimation, no ROS context needed."""
    from adm_sim.inputs.bridges import resolve_bridge
    from adm_sim.integrate.lockstep_runs import BridgeHalf
    from adm_sim.nodes.bridge_node import BridgeRunState
    from adm_sim.nodes.bridge_outputs import MonitoringOutput, monitor_steps
    from adm_sim.nodes.flow_control import FlowControl
    from adm_sim.nodes.params import bridge_specs
    from adm_sim.integrate.rk4_sides import BridgeSide
    from adm_sim.integrate.step_grid import StepOptions, make_grid
    from adm_sim.inputs.train_files import load_train

    bridge, train = resolve_bridge("B1"), load_train("ICE-2")
    grid = make_grid(bridge, train.length_m, np.array([250.0, 263.0]) / 3.6, StepOptions())
    side = BridgeSide(bridge, grid, train.axle_offsets_m, None, 0.0)
    half = BridgeHalf("mlm", grid, side)
    every, beam_every = monitor_steps(bridge, grid, 1, 0, 0)
    run = BridgeRunState(
        id=1, model="mlm", phase=P.PHASE_MLM_ZETA, train="ICE-2", grid=grid, run=half, bridge=bridge,
        speeds_kmh=np.array([250.0, 263.0]), dz=np.zeros(2), flow=FlowControl(()))
    values = {s.name: s.default for s in bridge_specs(bridge)} | {"monitor_speed_kmh": 263.0, "beam_points": 11}
    out = MonitoringOutput(run, None, run.flow, values, t0_s=0.0)  # no node, no publishers
    assert (out.lane, out.every, out.beam_every, out.frame) == (1, every, beam_every, "B1/midspan")
    published = []
    out.publish = lambda topic, msg, pub=None: published.append(topic)
    assert every > 1 and beam_every > every
    acc = np.array([0.1, 0.2])
    for k in range(grid.n_steps):
        before = len(published)
        out.step_done(k, half.disp_m, acc)
        assert len(published) - before == out.step_messages(k), k
    assert len(published) > grid.n_steps // every
