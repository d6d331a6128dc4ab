"""Batched runs and batched calibration against the single-case paths.

* :class:`adm_sim.integrate.compiled_batch.BatchRunner` lanes equal :func:`adm_sim.integrate.sweep.run_sweep` (numpy stepper)
  with the same ``ds`` to 1e-12 relative, MLM and DIM, conventional and Jacobs trains;
* :func:`adm_calib.calibrate.calibrate_batch` reproduces :func:`adm_calib.calibrate.calibrate` to
  1e-9 relative on its peaks and 1e-5 % on Δζ_VBI (spans 4, 20 and 40 m; ICE-2, ICE-4, Eurostar;
  41-71 km/h speed ranges around each resonance);
* the batch's shared step equals every case's own step within one (span, frequency) pair.
"""

from __future__ import annotations

import numpy as np
import pytest

from adm_calib.calibrate import batch_step, calibrate_batch
from adm_calib.calibrate import CalibrationOptions, calibrate, calibration_step
from adm_calib.study import select_cases
from adm_sim.integrate.compiled_batch import BatchRunner
from adm_sim.errors import RunError
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep
from adm_sim.inputs.train_files import load_train
from train_files import short_ice2_file


def _group(span, fi, mfs=("mu1", "mu2", "mu3", "mu4", "mu5", "mu6"), train="ICE-2"):
    return [c.bridge for c in select_cases([train], list(mfs), (span, span), [fi])]


@pytest.mark.slow
@pytest.mark.parametrize("train,span,fi", [("ICE-2-short", 10, 5), ("Eurostar", 25, 2)])
def test_batch_lanes_equal_run_sweep(train, span, fi, tmp_path):
    """A conventional and a Jacobs train. The conventional one is the ICE-2 with 2 of its 12
    passenger cars (both vehicle types, 16 axles): a lane equals the numpy stepper step by step and
    axle by axle, so the ten cars left out would only repeat the same arithmetic."""
    bridges = _group(span, fi, ("mu1", "mu4", "mu6"))
    tr = load_train(str(short_ice2_file(tmp_path)) if train == "ICE-2-short" else train)
    # 4 steps per period of the highest mode (the core's default is 16; RK4 is stable up to h omega =
    # 2.8, here pi / 2) on both paths: the numpy stepper's cost is its number of steps, and lane and run_sweep are
    # compared on one ds, which need not be accurate for the two to agree
    ds = batch_step(bridges, tr, options=CalibrationOptions(step=StepOptions(steps_per_period=4.0))).ds_m
    runner = BatchRunner(bridges, tr, ds)
    # two speeds per bridge, the ends of the study's range (each a full numpy-stepper run below);
    # every lane has its own additional damping, zero and negative among them
    speeds = np.array([170.0, 345.0])
    case = np.repeat(np.arange(3), speeds.size)
    dz = np.array([0.0, 0.002, -0.001, 0.01, 0.004, -0.0005])
    for model in ("mlm", "dim"):
        acc, disp = runner.run(model, case, np.tile(speeds, 3), dz)
        for c, b in enumerate(bridges):
            ref = run_sweep(b, tr, model, speeds, delta_zeta=dz[case == c], options=StepOptions(ds_m=ds))
            np.testing.assert_allclose(acc[case == c], ref.max_acc_m_s2, rtol=1e-12, atol=0)
            np.testing.assert_allclose(disp[case == c], ref.max_disp_m, rtol=1e-12, atol=0)


def test_group_shares_the_step_of_every_case():
    """Within one (span, frequency) pair the cases' own calibration steps agree to rounding, so
    a batch runs every case on its own grid (the rule: the smallest step of the batch)."""
    for span, fi in [(4, 5), (17, 3), (40, 1)]:
        bridges = _group(span, fi)
        tr = load_train("Railjet")
        own = np.array([calibration_step(b, tr).ds_m for b in bridges])
        assert batch_step(bridges, tr).ds_m == own.min()
        assert np.ptp(own) <= 4e-16 * own.min()


# Each case's MLM resonance (1 km/h) lies inside its range (the shipped study's MLM peaks: 321, 240,
# 211-212 km/h), so every phase runs as on the default 160..350 km/h range (MLM curve, the paper's
# coarse and fine DIM grid, ladder, root, check); 4 steps per period of the highest mode (the core's
# default is 16) on both paths: the numpy stepper's cost is its number of steps per sweep, and the
# comparison holds at any step.
@pytest.mark.slow
@pytest.mark.parametrize("train,span,fi,mfs,speeds", [
    ("ICE-2", 40, 1, ("mu1", "mu3", "mu6"), (280, 350)),
    ("ICE-4", 4, 1, ("mu2", "mu5"), (220, 260)),  # the costliest (4 m span: the smallest step)
    ("Eurostar", 20, 3, ("mu1", "mu4"), (170, 240)),
])
def test_calibrate_batch_reproduces_calibrate(train, span, fi, mfs, speeds):
    bridges = _group(span, fi, mfs, train)
    tr = load_train(train)
    v = np.arange(speeds[0], speeds[1] + 0.5, 1.0)
    opt = CalibrationOptions(step=StepOptions(steps_per_period=4.0))
    step = batch_step(bridges, tr, v, opt)
    batch = calibrate_batch(bridges, tr, v, options=opt, step=step)
    assert all(r.status == "ok" and r.mlm_peak.found for r in batch)  # the resonance is inside the range
    for b, r in zip(bridges, batch):
        # the same calibration on the other backend: the numpy stepper, one run_sweep per sweep
        ref = calibrate(b, tr, v, options=CalibrationOptions(step=step), adapted_curve=False, backend="numpy")
        assert r.status == ref.status
        for p, q in ((r.mlm_peak, ref.mlm_peak), (r.dim_peak, ref.dim_peak)):
            assert p.found == q.found
            if p.found:
                assert p.speed_kmh == q.speed_kmh
                assert p.acc_m_s2 == pytest.approx(q.acc_m_s2, rel=1e-9)
        np.testing.assert_allclose(r.mlm_acc_m_s2, ref.mlm_acc_m_s2, rtol=1e-9)
        np.testing.assert_array_equal(r.dim_speeds_kmh, ref.dim_speeds_kmh)
        np.testing.assert_allclose(r.dim_acc_m_s2, ref.dim_acc_m_s2, rtol=1e-9)
        if ref.delta_zeta_vbi_pct is None:
            assert r.delta_zeta_vbi_pct is None
        else:
            assert abs(r.delta_zeta_vbi_pct - ref.delta_zeta_vbi_pct) <= 1e-5
            assert abs(r.solve.residual_rel) <= 1e-3 and r.solve.method in ("find_root", "exact")


# ---------------------------------------------------------------------- the BatchRun contract
def _small_batch(train="Eurostar"):
    bridges = _group(25, 2, ("mu1", "mu6"), train)
    tr = load_train(train)
    # 4 steps per period (a quarter of the core's default, the step of the calibrations above):
    # advancing one step at a time is a Python call per step, and the blocks must equal one call at
    # any step
    runner = BatchRunner(bridges, tr, batch_step(bridges, tr, options=CalibrationOptions(
        step=StepOptions(steps_per_period=4.0))).ds_m)
    case = np.repeat([0, 1], 3)
    speeds = np.tile([180.0, 250.0, 320.0], 2)
    sweep = np.array([0, 0, 1, 0, 1, 1])  # two sweeps per bridge: lanes of different step counts
    return runner, case, speeds, sweep


@pytest.mark.slow
@pytest.mark.parametrize("model", ["mlm", "dim"])
def test_batch_run_in_blocks_equals_one_call_bit_for_bit(model):
    """Advancing 1, 7 and 1000 steps at a time gives exactly what one call over all steps gives;
    the run keeps the SteppedRun contract (k, status, maxima in the caller's lane order)."""
    runner, case, speeds, sweep = _small_batch()
    whole = runner.start(model, case, speeds, 0.003, sweep)
    assert whole.status == "running" and whole.k == 0 and whole.n_steps == whole.lane_steps.max()
    assert whole.advance(10 ** 9) is None
    assert whole.status == "finished" and whole.k == whole.n_steps
    for block in (1, 7, 1000):
        run = runner.start(model, case, speeds, 0.003, sweep)
        while run.status == "running":
            k0 = run.k
            run.advance(block)
            assert run.k == min(k0 + block, run.n_steps)
        np.testing.assert_array_equal(run.max_acc_m_s2, whole.max_acc_m_s2)
        np.testing.assert_array_equal(run.max_disp_m, whole.max_disp_m)
    # the lane order is the caller's: each lane equals its own run_sweep (1e-12, see above)
    for lane in (0, 4):
        ref = run_sweep(runner.bridges[case[lane]], runner.train, model, [speeds[lane]], delta_zeta=0.003,
                        options=StepOptions(ds_m=runner.ds_m))
        assert whole.max_acc_m_s2[lane] == pytest.approx(ref.max_acc_m_s2[0], rel=1e-12)
    with pytest.raises(RuntimeError, match=r"^BatchRun.advance: the run is finished at step \d+ of \d+$"):
        whole.advance()


def test_batch_run_fails_on_a_non_finite_lane_with_one_line():
    """A step far beyond RK4's stability limit: the run fails in the first block where the state is
    not finite, naming the steps, the bridge and the speed of the first bad lane."""
    bridges = _group(4, 5, ("mu1",))
    tr = load_train("ICE-2")
    runner = BatchRunner(bridges, tr, 2.0)  # ds = 2 m: h = ds / v >> 2.8 / omega of every mode
    run = runner.start("mlm", [0, 0], [200.0, 300.0])
    while run.status == "running":
        run.advance(64)
    assert run.status == "failed" and run.k < run.n_steps
    assert run.message.startswith(f"solution is not finite in steps {run.k - 64}..{run.k} of {run.n_steps}: "
                                  f"MLM state in 2 of 2 lanes (first at {bridges[0].name or bridges[0].describe()} "
                                  f"at 200 km/h); the step ds = 2 m is too large")
    with pytest.raises(RunError, match=r"^solution is not finite in steps \d+\.\.\d+ of \d+: MLM state"):
        runner.run("mlm", [0, 0], [200.0, 300.0])
