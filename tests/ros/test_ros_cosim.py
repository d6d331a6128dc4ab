"""A co-simulated run (bridge and train nodes in separate processes) reproduces the core.

The exchange carries float64 exactly and both nodes call the core's BridgeSide/TrainSide methods
in the order of :func:`adm_sim.integrate.sweep.run_sweep`, so the peaks agree to 1e-9 relative (in practice
bitwise). Small case for speed: B3 x ICE-2, 5 speeds from 290 km/h (the slowest speed sets the
step: a DIM run is 1400 steps, 2030 from 200 km/h), 4 steps per period of mode 3, one
fundamental period of free vibration. The in-process references of a model and damping are
computed once per module (:func:`reference`): the two graphs below, two processes and one, are
held to the same runs. The bridge nodes here publish the monitoring topics every 16th step and
the beam and clock every 64th (:data:`SPARSE`: the in-process driver receives and deserialises
each message, 1.4 s of CPU a DIM run at every step, 0.35 s thinned); the results are of every
step whatever is published. The calibration launch below is thinned too (every 4th step, conftest's
``CALIBRATION_PARAMS``); the same exactness with every step published, DIM included, is the deck
calibration launch's in test_ros_decks.py (automatic decimation: every step at 4 steps per period;
its status, Δζ and both peaks equal the numpy reference's bit for bit).
"""

import functools

import numpy as np
import pytest

pytest.importorskip("rclpy")
from ros_fixtures import driver_node, node_procs, ros_domain  # noqa: E402,F401

from adm_sim.inputs.bridges import resolve_bridge  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402

pytestmark = pytest.mark.slow  # every test here starts processes

SPEEDS = "290,305,320,335,350"
SPEEDS_KMH = [290.0, 305.0, 320.0, 335.0, 350.0]
STEP = {"steps_per_period": 4.0, "free_vibration_periods": 1.0}
#: The bridge's monitoring and beam/clock topics thinned (outputs only; a run's result is unchanged).
SPARSE = {"monitor_every_steps": 16, "beam_every_steps": 64}


@functools.cache
def reference(model, dz):
    """``run_sweep`` of B3 x ICE-2 on :data:`SPEEDS` with the numpy stepper (what the nodes split)."""
    return run_sweep(resolve_bridge("B3"), load_train("ICE-2"), model, SPEEDS_KMH, delta_zeta=dz,
                     options=StepOptions(**STEP))


def test_cosim_reproduces_run_sweep(node_procs, ros_domain):
    node_procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": "B3", **STEP, **SPARSE})
    node_procs.start("train", "adm_sim.nodes.train_node", {"speeds_kmh": SPEEDS})
    bridge, train = resolve_bridge("B3"), load_train("ICE-2")
    opts = StepOptions(**STEP)
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        for model, dz in (("mlm", 0.0), ("dim", 0.0), ("mlm", 0.004)):
            r = d.request_run(model=model, delta_zeta=dz)
            ref = reference(model, dz)
            np.testing.assert_array_equal(r["speeds_kmh"], SPEEDS_KMH)
            rel = np.max(np.abs(r["max_acc_m_s2"] / ref.max_acc_m_s2 - 1.0))
            assert rel <= 1e-9, (model, rel)
            np.testing.assert_allclose(r["max_disp_m"], ref.max_disp_m, rtol=1e-9, atol=0)
            np.testing.assert_array_equal(r["delta_zeta"], dz)
        # per-lane damping (the calibration's vectorised ladder) = one run_sweep with a dz array
        lanes = np.array([0.0, 0.001, 0.002, 0.004, 0.01])
        r = d.request_run(model="mlm", delta_zeta_lanes=lanes)
        ref = run_sweep(bridge, train, "mlm", r["speeds_kmh"], delta_zeta=lanes, options=opts)
        assert np.max(np.abs(r["max_acc_m_s2"] / ref.max_acc_m_s2 - 1.0)) <= 1e-9
        last = d.request_run(delta_zeta_lanes=[])  # back to the bridge's delta_zeta (0.004 since run 3)
        # runs outside a calibration are named by their request, published with their run id
        from adm_sim import protocol as P

        with d._lock:
            requested = {rid: st for (node, rid), st in d._status.items() if node == P.DRIVER_NODE}
        assert [requested[rid]["phase"] for rid in sorted(requested)] == [
            P.PHASE_MLM_ZETA, P.PHASE_DIM, P.PHASE_MLM_ZETA_DZ, P.PHASE_BRACKETING, P.PHASE_MLM_ZETA_DZ]
        assert max(requested) == last["run_id"] and last["phase"] == P.PHASE_MLM_ZETA_DZ
        check_wrong_lane_count_is_reported(d, model="mlm", dz=0.004)
    assert all(p.poll() is None for p in node_procs.procs.values())


def check_wrong_lane_count_is_reported(d, model, dz):
    """A bad run request fails with the bridge's reason and both nodes stay up; the run after the
    refused one is the core's run, bit for bit (as in test_ros_colcon.py). Checked on the graph of
    :func:`test_cosim_reproduces_run_sweep` (its last settings: ``model``, the bridge's ``dz``), whose
    nodes are then seen alive: a graph of its own cost a test two more node processes."""
    from adm_sim.nodes.driver import RunError

    with pytest.raises(RunError, match=f"delta_zeta_lanes: 3 values for {len(SPEEDS_KMH)} speed lanes"):
        d.request_run(delta_zeta_lanes=[0.0, 0.01, 0.02])
    r = d.request_run(delta_zeta_lanes=[])
    ref = reference(model, dz)
    np.testing.assert_array_equal(r["speeds_kmh"], SPEEDS_KMH)
    np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2)
    np.testing.assert_array_equal(r["max_disp_m"], ref.max_disp_m)


def test_calibrate_launch_matches_in_process_calibration(calibration_launch):
    """launch_scripts/calibrate.py (the bridge and train nodes in one process, the calibration node in
    another) gives the Δζ of adm_calib.calibrate.

    The launch is conftest's ``calibration_launch`` (B3 x ICE-2, 250..290 km/h every 2 km/h, 4 steps
    per period, one period of free vibration, monitoring every 4th step), run once for this test and
    the recording test of test_ros_rerun_views.py; the fixture asserts that its stdout printed the
    iterations and the result."""
    import json

    from adm_calib.calibrate import CalibrationOptions, calibrate

    out = calibration_launch
    got = json.loads((out / "summary.json").read_text())
    # the co-simulation is the numpy stepper split in two processes: the same numbers bit for bit
    # the reference runs every sweep on the numpy stepper through a hook that notes the phase the
    # calibration sends with it (HookLanes, as the calibration node gets them)
    sent, ref_runs = [], []

    def numpy_sweep(model, speeds, dz, step, phase):
        sent.append(phase)
        r = run_sweep(resolve_bridge("B3"), load_train("ICE-2"), model, speeds, delta_zeta=dz, options=step)
        ref_runs.append((model, np.array(speeds, dtype=float), np.broadcast_to(dz, np.shape(speeds)).copy(),
                         step, r))
        return r.max_acc_m_s2

    # the calibration node's default DIM grid is the window grid: the reference runs the same grid
    ref = calibrate(resolve_bridge("B3"), load_train("ICE-2"), np.arange(250.0, 291.0, 2.0),
                    options=CalibrationOptions(dim_grid="window", step=StepOptions(**STEP)), sweep=numpy_sweep).to_dict()
    assert got["status"] == ref["status"]
    for key in ("delta_zeta_vbi_pct", "delta_zeta_adm_pct", "delta_zeta_eada_pct", "delta_zeta_lb_pct"):
        assert got[key] == pytest.approx(ref[key], rel=1e-9, abs=0) if ref[key] is not None else got[key] is None
    assert got["mlm_peak"] == ref["mlm_peak"] and got["dim_peak"] == ref["dim_peak"]
    # the same runs give the same root bit for bit, and the compiled in-process calibration
    # (adm-calib calibrate) prints the same Δζ (four decimals in percent, the root tolerance's digits)
    assert got["delta_zeta_vbi_pct"] == ref["delta_zeta_vbi_pct"]
    b3 = resolve_bridge("B3")
    compiled = calibrate(b3, load_train("ICE-2"), np.arange(250.0, 291.0, 2.0),
                         options=CalibrationOptions(step=StepOptions(**STEP)))
    assert f"{got['delta_zeta_vbi_pct']:.4f}" == f"{100 * compiled.delta_zeta_vbi:.4f}"
    assert got["dim_grid"] == "window" and compiled.to_dict()["dim_grid"] == "paper"
    # every co-simulated run recorded in the MCAP is the core's run_sweep with the calibration's
    # step, bit for bit (as in test_ros_colcon.py): MLM zeta, DIM, ladder, root search, MLM zeta + dz
    from adm_calib.calibrate import calibration_step
    from adm_sim.recording.mcap_log import read_messages

    ice2 = load_train("ICE-2")
    step = calibration_step(b3, ice2, np.arange(250.0, 291.0, 2.0), CalibrationOptions(step=StepOptions(**STEP)))
    started, results = [], []
    for topic, _ns, msg in read_messages(out / "run.mcap", topics=["/adm/run/status", "/adm/run/result"]):
        if topic == "/adm/run/result":   # Float64MultiArray, rows speed_kmh, max_acc_m_s2, max_disp_m, delta_zeta
            shape = tuple(dim.size for dim in msg.layout.dim)
            results.append(np.asarray(msg.data, dtype=np.float64)[msg.layout.data_offset:].reshape(shape))
        elif (s := json.loads(msg.data))["node"] == "bridge" and s["state"] == "started":
            started.append(s)
    assert len(results) == len(started) == got["co_simulation"]["runs"] >= 5
    # the phase travelled with every run: the driver's requested records, in order, one per run
    # (its run id) are exactly the phases the calibration sent, mapped by the protocol
    from adm_sim import protocol as P

    requested = [json.loads(m.data) for _t, _ns, m in read_messages(out / "run.mcap", topics=[P.TOPIC_STATUS])]
    requested = [s for s in requested if s["state"] == P.REQUESTED]
    assert [s["phase"] for s in requested] == [P.CALIBRATION_PHASES[ph] for ph in sent]
    assert [s["run_id"] for s in requested] == [s["run_id"] for s in started]
    assert {s["node"] for s in requested} == {P.CALIBRATION_NODE}
    assert [s["model"] for s in requested] == [s["model"] for s in started]
    # the calibration node's own verdict on /diagnostics, recorded once as it was published (its own
    # /diagnostics subscription, which records the bridge's statuses, hands it back and is not written)
    from adm_calib.nodes.calibration_node import DIAG_VERDICT

    verdicts = [st for _t, _ns, m in read_messages(out / "run.mcap", topics=[P.TOPIC_DIAGNOSTICS])
                for st in m.status if st.name == DIAG_VERDICT]
    assert [st.hardware_id for st in verdicts] == ["B3"]
    models = [s["model"] for s in started]
    assert models[:2] == ["mlm", "dim"] and set(models[2:]) == {"mlm"}
    # run k of the launch is run k of the in-process reference (the same phases in the same order,
    # above): each is the reference's run_sweep (same model, speeds, damping and step), bit for bit
    assert len(ref_runs) == len(started)
    for s, (v, acc, disp, dz), (model, v_ref, dz_ref, step_ref, ref_run) in zip(started, results, ref_runs):
        assert s["ds_m"] == step.ds_m == step_ref.ds_m and s["model"] == model
        np.testing.assert_array_equal(v, v_ref)
        np.testing.assert_array_equal(dz, dz_ref)
        np.testing.assert_array_equal(acc, ref_run.max_acc_m_s2, err_msg=f"run {s['run_id']} {s['model']}")
        np.testing.assert_array_equal(disp, ref_run.max_disp_m, err_msg=f"run {s['run_id']} {s['model']}")
    np.testing.assert_array_equal(results[0][0], np.arange(250.0, 291.0, 2.0))
    assert (out / "run.rrd").read_bytes()[:4] == b"RRF2"


def test_non_finite_run_fails_with_the_message_and_nodes_stay_up(node_procs, ros_domain):
    """ds = 5 m makes the DIM blow up: the run fails at that step with the core's message (as
    run_sweep raises it), no result is taken, and the next run of the same nodes works."""
    from adm_sim import errors
    from adm_sim.nodes.driver import RunError

    node_procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": "B1", "ds_m": 5.0, **SPARSE})
    node_procs.start("train", "adm_sim.nodes.train_node", {"speeds_kmh": "160,250,350"})
    bridge, train = resolve_bridge("B1"), load_train("ICE-2")
    with np.errstate(all="ignore"), pytest.raises(errors.RunError) as ref:
        run_sweep(bridge, train, "dim", [160.0, 250.0, 350.0], options=StepOptions(ds_m=5.0))
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        with pytest.raises(RunError, match="failed on node 'bridge'") as exc:
            d.request_run(model="dim")
        assert str(ref.value) in str(exc.value) and "solution is not finite at step" in str(exc.value)
        d.set_params("bridge", ds_m=0.0, **STEP)
        r = d.request_run(model="mlm")
        ref_ok = run_sweep(bridge, train, "mlm", r["speeds_kmh"], options=StepOptions(**STEP))
        np.testing.assert_array_equal(r["max_acc_m_s2"], ref_ok.max_acc_m_s2)
    assert all(p.poll() is None for p in node_procs.procs.values())


def test_composed_nodes_reproduce_run_sweep(node_procs, ros_domain):
    """The bridge and train nodes in one process (adm_sim.nodes.composed, as the launch scripts run them)
    give the core's runs bit for bit; each ``-p node:name:=value`` reaches its own node only."""
    node_procs.start("bridge_train", "adm_sim.nodes.composed",
                     {"bridge:bridge": "B3", **{f"bridge:{k}": v for k, v in {**STEP, **SPARSE}.items()},
                      "train:speeds_kmh": SPEEDS})
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        for model, dz in (("dim", 0.0), ("mlm", 0.004), ("dim", 0.0)):
            r = d.request_run(model=model, delta_zeta=dz)
            ref = reference(model, dz)
            np.testing.assert_array_equal(r["speeds_kmh"], SPEEDS_KMH)
            np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2)
            np.testing.assert_array_equal(r["max_disp_m"], ref.max_disp_m)
    assert node_procs.procs["bridge_train"].poll() is None
    log = (node_procs.log_dir / "bridge_train.log").read_text()
    assert "[bridge]: run 3 done" in log and "error" not in log.lower()


def test_composed_nodes_refuse_a_parameter_of_the_other_node(tmp_path, ros_domain):
    """``-p train:span_m:=20.0``: the train node has no span: one line naming it, exit 2."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "adm_sim.nodes.composed", "--ros-args", "-p", "train:span_m:=20.0"],
                       env=dict(ros_domain), capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith(
        "error: bridge+train: span_m: unknown parameter of node 'train'; allowed ")
