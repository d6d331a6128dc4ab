"""The rerun recording an engineer opens: default blueprint, one entity per trial, runs that overlay.

A synthetic session (no ROS: the messages the driver would receive) goes through
:class:`adm_sim.recording.rerun_log.RunLogger` into an ``.rrd``; everything is read back with
``rerun.chunk.RrdReader``. The same checks run on a real co-simulated sweep in
``test_ros_rerun_live.py`` (live) and on its replay from MCAP below.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rrd_views import check_recording, read_rrd, view_entities

from adm_sim import protocol as P
from adm_sim.recording import rerun_blueprint as bp
from adm_sim.recording import rerun_log as rl

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable

SPAN_M = 15.0
DS_M = 0.05
N_STEPS = 400
EVERY = 4


# ---------------------------------------------------------------- a synthetic session


def _status(run_id, model, n_lanes, t0, v_clock, v_mon):
    return {"node": "bridge", "run_id": run_id, "state": "started", "model": model, "n_steps": N_STEPS,
            "n_lanes": n_lanes, "ds_m": DS_M, "t0_s": t0, "monitor_lane": 0, "monitor_speed_kmh": v_mon,
            "clock_speed_kmh": v_clock, "monitor_every_steps": EVERY, "beam_every_steps": 4 * EVERY}


#: The phase each run of the session is handed (as the calibration node does) and the kind it is drawn as.
PHASES = {1: P.PHASE_MLM_ZETA, 2: P.PHASE_DIM, 3: P.PHASE_BRACKETING, 4: P.PHASE_ROOT_SEARCH, 5: P.PHASE_MLM_ZETA_DZ}
KINDS = {1: rl.MLM_ZETA, 2: rl.DIM, 3: rl.BRACKETING, 4: rl.ROOT_SEARCH, 5: rl.MLM_ZETA_DZ}


def _session(viz: rl.RunLogger):
    """Five runs of a calibration: MLM ζ, DIM, a 3-rung ladder, a root-search step, MLM ζ+Δζ."""
    viz.bridge_description({"bridge": {"span_m": SPAN_M, "n_modes": 3}, "n0_hz": 8.0,
                            "description": "B1: L=15 m, zeta=1.85 %"})
    viz.train_description({"name": "ICE-2"})
    speeds = np.arange(200.0, 211.0)
    window = np.array([204.0, 205.0, 206.0])
    ladder = np.array([-0.005, 0.0, 0.01])
    runs = [("mlm", speeds, np.zeros(11)), ("dim", speeds, np.zeros(11)),
            ("mlm", np.tile(window, 3), np.repeat(ladder, 3)), ("mlm", window, np.full(3, 0.0055)),
            ("mlm", speeds, np.full(11, 0.0055))]
    t0 = 0.0
    expected = {}
    x = np.linspace(0.0, SPAN_M, 11)
    for i, (model, v, dz) in enumerate(runs, start=1):
        v_clock, v_mon = float(v.min()), 205.0
        viz.run_started(_status(i, model, v.size, t0, v_clock, v_mon))
        ks = np.arange(0, N_STEPS, EVERY)
        t = t0 + ks * DS_M / (v_clock / 3.6)
        for k, tk in zip(ks, t):
            viz.accel(tk, np.sin(0.1 * k) + i)
            if k % (4 * EVERY) == 0:
                viz.beam(tk, x, 1e-3 * np.sin(np.pi * x / SPAN_M) * np.sin(0.05 * k), [1.0], [0.0])
        viz.flush()
        acc = 1.0 + 0.01 * i + 0.001 * v - 10 * dz
        t1 = t0 + N_STEPS * DS_M / (v_clock / 3.6)
        assert viz.run_done(np.vstack([v, acc, 1e-3 * np.ones_like(v), dz]), PHASES[i]) == KINDS[i]
        expected[i] = (v, acc, dz, t, ks * DS_M / (v_mon / 3.6))
        if i == 3:
            for j, d in enumerate(ladder, start=1):
                viz.iteration(j, 100 * d, 2.0 - 100 * d, 1.8, PHASES[i])
        if i == 4:
            viz.iteration(4, 0.55, 1.8, 1.8, PHASES[i])
        t0 = t1
    viz.calibration_result({"bridge_description": "B1", "train": "ICE-2", "status": "ok",
                            "zeta_pct": 1.8500000000000003, "delta_zeta_vbi_pct": 0.5532999999999999,
                            "mlm_peak": {"speed_kmh": 205.0, "acc_m_s2": 2.2465199999}})
    return expected


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    path = tmp_path_factory.mktemp("views") / "session.rrd"
    rl.init_rerun("adm_sim_test", save_path=path, recording_id="views")
    viz = rl.RunLogger()
    viz.send_blueprint()
    expected = _session(viz)
    rl.close_rerun()
    return path, expected


def test_fmt_pct():
    assert rl.fmt_pct(0.018500000000000003) == "+1.8500 %"


def test_recording_carries_the_blueprint_and_its_views_have_data(synthetic):
    path, _ = synthetic
    ents, blue = check_recording(path)
    for view in blue["views"]:
        shown = view_entities(view, ents)
        assert shown, f"view {view['display_name']!r} shows no entity of the recording"
    names = [v["display_name"] for v in blue["views"]]
    assert any("×500" in n for n in names)  # the beam's exaggeration is in its title


def test_every_trial_is_its_own_entity_with_its_values(synthetic):
    path, expected = synthetic
    ents = read_rrd(path)
    v, acc, dz, *_ = expected[3]
    for j, d in enumerate(np.unique(dz), start=1):
        e = ents[f"/sweep/trials/bracketing/{j:02d}"]
        lanes = dz == d
        np.testing.assert_array_equal(e["times"][bp.SPEED], np.rint(v[lanes]).astype(int))
        np.testing.assert_allclose(e["values"], acc[lanes], rtol=0, atol=0)
    v4, acc4, *_ = expected[4]
    np.testing.assert_allclose(ents["/sweep/trials/root_search/01"]["values"], acc4, rtol=0, atol=0)
    for name, run in (("DIM", 2), ("MLM_zeta", 1), ("MLM_zeta_dz", 5)):
        np.testing.assert_allclose(ents[f"/sweep/curves/{name}"]["values"], expected[run][1], rtol=0, atol=0)
    assert len(ents["/calibration/delta_zeta_pct/bracketing"]["values"]) == 3
    assert ents["/calibration/delta_zeta_pct/root_search"]["values"] == [0.55]


def test_run_time_is_the_monitored_lanes_time_from_train_entry(synthetic):
    path, expected = synthetic
    ents = read_rrd(path)
    for i, (_v, _a, _dz, t_sim, t_run) in expected.items():
        e = ents[f"/runs/acceleration/run_{i:02d}"]
        np.testing.assert_allclose(np.array(e["times"][bp.RUN_TIME]) * 1e-9, t_run, rtol=0, atol=1e-9)
        np.testing.assert_allclose(np.array(e["times"][bp.SIM_TIME]) * 1e-9, t_sim, rtol=0, atol=1e-9)
    assert min(ents["/runs/beam/run_02/deflection"]["times"][bp.RUN_TIME]) == 0


def test_numbers_are_printed_at_sensible_precision(synthetic):
    path, _ = synthetic
    ents = read_rrd(path)
    text = ents["/calibration/result"]["text"][-1]
    assert "| zeta_pct | 1.8500 % |" in text and "0.5533 %" in text and "2.2465 m/s² at 205 km/h" in text
    table = ents["/runs/info"]["text"][-1]
    assert "| 5 | MLM ζ+Δζ, Δζ +0.5500 % | 11 | 200–210 | 205 | 3.51 | 4.0 |" in table


def test_runs_table_has_every_run_with_its_kind_lanes_and_peak(synthetic):
    """The run table read back: one row per run with the values the session put in, by hand.

    acc = 1 + 0.01 i + 0.001 v - 10 dz is largest at the highest speed and the lowest dz:
    run 1: 1.01 + 0.210 = 1.220 at 210; run 2: 1.02 + 0.210 = 1.230 at 210; run 3 (dz -0.5 %):
    1.03 + 0.206 + 0.05 = 1.286 at 206; run 4: 1.04 + 0.206 - 0.055 = 1.191 at 206;
    run 5: 1.05 + 0.210 - 0.055 = 1.205 at 210.
    """
    path, _ = synthetic
    table = read_rrd(path)["/runs/info"]["text"][-1]
    rows = [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in table.splitlines() if re.match(r"\|\s*\d+\s*\|", line)]
    want = [("1", "MLM ζ", "11", "200–210", "1.220", "210"), ("2", "DIM", "11", "200–210", "1.230", "210"),
            ("3", "bracketing, 3 Δζ", "9", "204–206", "1.286", "206"),
            ("4", "root search, Δζ +0.5500 %", "3", "204–206", "1.191", "206"),
            ("5", "MLM ζ+Δζ, Δζ +0.5500 %", "11", "200–210", "1.205", "210")]
    assert [(r[0], r[1], r[2], r[3], r[-2], r[-1]) for r in rows] == want


# ---------------------------------------------------------------- a real co-simulated sweep, replayed


@pytest.fixture(scope="module")
def crossing_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("crossing") / "run"
    r = subprocess.run([PY, str(ROOT / "launch_scripts" / "crossing.py"), "--model", "mlm", "--bridge", "B1",
                        "--speeds", "250:270:5", "--out", str(out)],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    return out


@pytest.mark.slow
def test_crossing_recording_and_its_replay_open_in_the_default_layout(crossing_run, tmp_path):
    live, blue = check_recording(crossing_run / "run.rrd")
    replayed = tmp_path / "replay.rrd"
    r = subprocess.run([PY, str(ROOT / "launch_scripts" / "replay.py"), str(crossing_run / "run.mcap"),
                        "--rrd", str(replayed)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "warning:" not in r.stderr  # the driver recorded the run's phase
    again, _ = check_recording(replayed)
    for p in ("/runs/acceleration/run_01", "/runs/beam/run_01/deflection", "/sweep/curves/MLM_zeta"):
        assert sorted(again[p]["values"]) == sorted(live[p]["values"]), p  # chunk order may differ
        for tl, times in live[p]["times"].items():
            assert sorted(again[p]["times"][tl]) == sorted(times), (p, tl)
    acc = live["/runs/acceleration/run_01"]
    t = np.array(acc["times"][bp.RUN_TIME]) * 1e-9
    dt = np.diff(t)  # uniform in the monitored lane's time, >= 8 samples per period of mode 3
    np.testing.assert_allclose(dt, dt[0], rtol=1e-6)
    from adm_sim.inputs.bridges import resolve_bridge

    b1 = resolve_bridge("B1")
    assert dt[0] <= 2 * np.pi / b1.omega_rad_s[-1] / 8 * (1 + 1e-6)  # times are stored in ns
    assert "monitored [km/h]" in live["/runs/info"]["text"][-1]
    np.testing.assert_allclose(sorted(live["/sweep/curves/MLM_zeta"]["times"][bp.SPEED]), [250, 255, 260, 265, 270])


def _without_phases(src: Path, dst: Path) -> int:
    """Copy the MCAP ``src`` record by record (raw CDR, mcap's own reader and writer) leaving out the
    driver's ``requested`` status records: a recording as made before runs carried their phase.
    Returns the records left out."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    dropped = 0
    with open(src, "rb") as f, open(dst, "wb") as g:
        w = Writer(g)
        w.start(profile="ros2", library="test")
        schemas, channels = {}, {}
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(channel.topic, channel.message_encoding,
                                                          schemas[schema.id], channel.metadata)
            if channel.topic == P.TOPIC_STATUS and b'"state": "requested"' in message.data:
                dropped += 1
                continue
            w.add_message(channels[channel.id], message.log_time, message.data, message.publish_time,
                          message.sequence)
        w.finish()
    return dropped


@pytest.mark.slow
def test_replay_of_a_recording_without_phases_shows_phase_unknown(crossing_run, tmp_path):
    """A recording made before the phase travelled (no ``requested`` record) still replays: exit 0,
    one warning line, the sweep under ``sweep/curves/unknown`` with the live values of ``MLM_zeta``."""
    old = tmp_path / "old.mcap"
    assert _without_phases(crossing_run / "run.mcap", old) == 1  # one run, one phase record
    replayed = tmp_path / "old.rrd"
    r = subprocess.run([PY, str(ROOT / "launch_scripts" / "replay.py"), str(old), "--rrd", str(replayed)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    warnings = [line for line in r.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and "phase 'unknown'" in warnings[0] and "run 1" in warnings[0], r.stderr
    live, _ = check_recording(crossing_run / "run.rrd")
    again = read_rrd(replayed)
    assert "/sweep/curves/MLM_zeta" not in again
    assert sorted(again["/sweep/curves/unknown"]["values"]) == sorted(live["/sweep/curves/MLM_zeta"]["values"])
    assert sorted(again["/sweep/curves/unknown"]["times"][bp.SPEED]) == [250, 255, 260, 265, 270]
    np.testing.assert_array_equal(again["/runs/acceleration/run_01"]["values"],
                                  live["/runs/acceleration/run_01"]["values"])


@pytest.mark.slow
def test_calibration_recording_every_view_has_data_and_monitors_the_peak(calibration_launch, tmp_path):
    """A small co-simulated calibration (B3 x ICE-2, coarse steps; conftest's ``calibration_launch``,
    whose numbers test_ros_cosim.py checks): the recording as a user opens it."""
    import json

    from adm_sim.recording.mcap_log import read_messages

    out = calibration_launch
    summary = json.loads((out / "summary.json").read_text())
    ents, blue = check_recording(out / "run.rrd")
    for view in blue["views"]:  # every view of every tab shows data of this recording
        assert view_entities(view, ents), view["display_name"]
    # the first run monitors the first lane, every later one the MLM peak speed
    started = [json.loads(m.data) for _t, _ns, m in read_messages(out / "run.mcap", topics=["/adm/run/status"])]
    started = [s for s in started if s["node"] == "bridge" and s["state"] == "started"]
    assert len(started) == summary["co_simulation"]["runs"]
    assert started[0]["monitor_speed_kmh"] == 250.0  # the first lane of conftest's CALIBRATION_SPEEDS
    assert {s["monitor_speed_kmh"] for s in started[1:]} == {summary["mlm_peak"]["speed_kmh"]}
    # one entity per trial damping, as many as the calibration's iterations
    trials = [p for p in ents if re.fullmatch(r"/sweep/trials/(bracketing|root_search)/\d\d", p)]
    assert len(trials) == summary["co_simulation"]["delta_zeta_trials"]
    iters = [m.data for _t, _ns, m in read_messages(out / "run.mcap", topics=["/adm/calibration/iteration"])]
    dz_logged = (ents["/calibration/delta_zeta_pct/bracketing"]["values"]
                 + ents["/calibration/delta_zeta_pct/root_search"]["values"])
    assert dz_logged == [float(d[1]) for d in iters]
    # the root is one of the dampings the search ran (each damping is run once, none again at the root)
    assert min(abs(v - summary["delta_zeta_vbi_pct"]) for v in dz_logged) <= 1e-12
    # each run is drawn where protocol puts its recorded phase: one trial per Δζ of a bracketing or
    # root-search run (Δζ from the run's result), one curve per other phase
    status = [json.loads(m.data) for _t, _ns, m in read_messages(out / "run.mcap", topics=[P.TOPIC_STATUS])]
    phase_of = {s["run_id"]: s["phase"] for s in status if s["state"] == P.REQUESTED}
    results = [c_matrix(m) for _t, _ns, m in read_messages(out / "run.mcap", topics=[P.TOPIC_RESULT])]
    assert [s["run_id"] for s in started] == sorted(phase_of)
    want, n_trials = set(), {ph: 0 for ph in P.TRIAL_PHASES}
    for s, res in zip(started, results):
        phase = phase_of[s["run_id"]]
        if phase in P.TRIAL_PHASES:
            for _dz in np.unique(res[3]):
                n_trials[phase] += 1
                want.add("/" + P.sweep_trial_path(phase, n_trials[phase]))
        else:
            want.add("/" + P.sweep_curve_path(P.SWEEP_CURVE_NAMES[phase]))
    drawn = {p for p in ents if re.fullmatch(r"/sweep/(curves|trials)/[^/]+(/\d\d)?", p)}
    assert drawn == want | {"/" + P.sweep_curve_path(P.SWEEP_CURVE_NAMES[P.PHASE_DIM], trials=True),
                            "/" + P.sweep_curve_path(P.SWEEP_CURVE_NAMES[P.PHASE_MLM_ZETA_DZ], trials=True)}
    # the iterations follow the phase of their run: as many bracketing values as ladder rungs
    assert len(ents["/" + P.delta_zeta_path(P.PHASE_BRACKETING)]["values"]) == n_trials[P.PHASE_BRACKETING]
    # its replay draws every run at the same place, with no warning
    replayed = tmp_path / "replay.rrd"
    r = subprocess.run([PY, str(ROOT / "launch_scripts" / "replay.py"), str(out / "run.mcap"), "--rrd",
                        str(replayed)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "warning:" not in r.stderr, r.stderr
    again = read_rrd(replayed)
    for path in (p for p in ents if p.startswith(("/sweep/", "/calibration/"))):
        assert sorted(again[path]["values"]) == sorted(ents[path]["values"]), path


def c_matrix(msg):
    """A ``Float64MultiArray`` (rows x lanes) as decoded from MCAP."""
    shape = tuple(dim.size for dim in msg.layout.dim)
    return np.asarray(msg.data, dtype=np.float64)[msg.layout.data_offset:].reshape(shape)


def test_runs_view_draws_the_en1990_limit_and_the_dim_window_as_points(tmp_path):
    """The Runs view gets the track's EN 1990 A2.4.4.2.1 limit (+3.5 and -3.5 m/s² for ballasted
    track) over every run's run time; the DIM sweep, computed on a window of the speed grid
    (200-204 and 210 km/h here), is drawn as points (SeriesPoints), so no line crosses 205-209 km/h."""
    from rerun.chunk import RrdReader

    path = tmp_path / "limit.rrd"
    rl.init_rerun("adm_sim_test", save_path=path, recording_id="limit")
    viz = rl.RunLogger()
    viz.bridge_description({"bridge": {"span_m": SPAN_M, "n_modes": 3}, "n0_hz": 8.0, "description": "B1",
                            "acc_limit_m_s2": 3.5, "track_type": "ballasted"})
    v = np.array([200.0, 201.0, 202.0, 203.0, 204.0, 210.0])
    viz.run_started(_status(1, "dim", v.size, 0.0, 200.0, 205.0))
    viz.accel(0.0, 0.1)
    viz.flush()
    viz.run_done(np.vstack([v, 1.0 + 0.001 * v, 1e-3 * np.ones_like(v), np.zeros_like(v)]), P.PHASE_DIM)
    rl.close_rerun()
    ents = read_rrd(path)
    t_end = N_STEPS * DS_M / (205.0 / 3.6)  # the run's end in the monitored lane's time
    for part, sign in (("limit_upper", 1.0), ("limit_lower", -1.0)):
        e = ents[f"/runs/acceleration/{part}"]
        assert e["values"] == [sign * 3.5, sign * 3.5]
        np.testing.assert_allclose(np.array(e["times"][bp.RUN_TIME]) * 1e-9, [0.0, t_end], rtol=0, atol=1e-9)
    styles = {}
    for chunk in RrdReader(path).stream():
        if chunk.is_static:
            styles.setdefault(chunk.entity_path, set()).update(chunk.to_record_batch().schema.names)
    dim = styles["/" + P.sweep_curve_path(P.SWEEP_CURVE_NAMES[P.PHASE_DIM])]
    assert any("SeriesPoints" in n for n in dim) and not any("SeriesLines" in n for n in dim), dim
    np.testing.assert_array_equal(ents["/" + P.sweep_curve_path(P.SWEEP_CURVE_NAMES[P.PHASE_DIM])]["times"][bp.SPEED],
                                  v.astype(int))
