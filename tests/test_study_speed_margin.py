"""Work the study's batches no longer do, and the numbers they give unchanged.

* the MLM's modal load table of the compiled batch is made without the table of every axle's
  position at every half-step row, and equals the numpy stepper's table bit for bit;
* a pace lane (a sweep's fastest speed, wanted only for the number of steps it gives the sweep) is
  not run by the compiled lanes: the other lanes keep their steps and their maxima bit for bit, the
  pace lane's maximum is NaN; a backend that does not skip pace lanes runs it as an ordinary lane
  and the calibration sees the same values;
* the window grid's DIM request gives every case the maxima of the paper grid's sweep.
"""

import numpy as np
import pytest

from adm_calib.calibrate import CalibrationOptions, batch_step, calibrate_cases
from adm_calib.lanes import CompiledLanes, Requests
from adm_calib.study import MASS_FUNCTION_NAMES, select_cases
from adm_sim.compiled_batch import BatchRunner, modal_load_table
from adm_sim.errors import InputError
from adm_sim.mlm_loads import half_step_positions, modal_loads_at
from adm_sim.step_grid import StepOptions
from adm_sim.trains import load_train


def _bridges(train, span, fi, mfs=MASS_FUNCTION_NAMES):
    return [c.bridge for c in select_cases([train], list(mfs), (span, span), [fi])]


@pytest.mark.parametrize(("train", "span", "fi"), [("ICE-2", 4, 5), ("Eurostar", 8, 2), ("Railjet", 30, 1),
                                                   ("ICE-4", 40, 3)])
def test_modal_load_table_equals_the_steppers_bit_for_bit(train, span, fi):
    tr = load_train(train)
    b = _bridges(train, span, fi, ("mu3",))[0]
    for ds in (batch_step([b], tr).ds_m, 0.0137, 0.25):
        n = int(1.3 * (span + tr.length_m) / ds)
        ref = modal_loads_at(b, half_step_positions(ds, tr.axle_offsets_m, 0, n), np.asarray(tr.axle_loads_n, float))
        got = modal_load_table(b, ds, tr.axle_offsets_m, tr.axle_loads_n, n)
        assert got.shape == ref.shape == (2 * n + 1, b.n_modes)
        assert np.count_nonzero(ref) > 0.3 * ref.size  # loads on the span over much of the run
        assert np.array_equal(got, ref)


def _setup():
    bridges = _bridges("ICE-2", 12, 4, ("mu1", "mu6"))
    tr = load_train("ICE-2")
    ds = batch_step(bridges, tr, options=CalibrationOptions(step=StepOptions(steps_per_period=8.0))).ds_m
    return bridges, tr, ds


def test_pace_lanes_set_the_steps_and_are_not_run():
    bridges, tr, ds = _setup()
    runner = BatchRunner(bridges, tr, ds)
    v = np.array([170.0, 200.0, 230.0, 350.0, 180.0, 210.0, 350.0])
    case = np.array([0, 0, 0, 0, 1, 1, 1])
    pace = np.array([False, False, False, True, False, False, True])
    full = runner.start("dim", case, v)
    acc_full, disp_full = runner.run("dim", case, v)
    acc, disp = runner.run("dim", case, v, pace=pace)
    assert np.all(np.isnan(acc[pace])) and np.all(np.isnan(disp[pace]))
    assert np.array_equal(acc[~pace], acc_full[~pace]) and np.array_equal(disp[~pace], disp_full[~pace])
    assert np.all(acc[~pace] > 0.1)
    run = runner.start("dim", case, v, pace=pace)
    assert np.array_equal(run.kept, ~pace)
    assert np.array_equal(run.lane_steps, full.lane_steps[~pace])
    # without the pace speed the sweep is shorter (its fastest speed sets the free vibration), so
    # the pace lane is what keeps every other lane on the paper grid's steps
    short = runner.start("dim", case[~pace], v[~pace])
    assert np.all(short.lane_steps < run.lane_steps)
    with pytest.raises(InputError, match="pace"):
        runner.start("dim", case[pace], v[pace], pace=np.ones(2, bool))


class _RunsEveryLane:
    """A backend without ``skips_pace``: the compiled lanes, asked to run every lane."""

    def __init__(self, lanes):
        self.lanes, self.seen = lanes, []

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase=""):
        self.seen.append(np.size(case))
        return self.lanes.run(model, case, speeds_kmh, delta_zeta, sweep, phase)


def test_requests_give_the_same_maxima_whether_the_backend_skips_pace_lanes_or_not():
    bridges, tr, ds = _setup()
    compiled = CompiledLanes(bridges, tr, StepOptions(ds_m=ds))
    plain = _RunsEveryLane(CompiledLanes(bridges, tr, StepOptions(ds_m=ds)))

    def request():
        req = Requests()
        req.add(0, [170.0, 200.0, 230.0], pace_kmh=350.0)
        req.add(1, [180.0, 210.0])  # the window reaches the fastest speed: no pace
        req.add(1, [190.0, 220.0], dz=0.004, pace_kmh=340.0)
        return req

    skipped = request().run(compiled, "dim", "dim")
    ran = request().run(plain, "dim", "dim")
    assert plain.seen == [9]
    assert [a.size for a in skipped] == [3, 2, 2]
    for a, b in zip(skipped, ran):
        assert np.all(np.isfinite(a)) and np.array_equal(a, b)


class _CountsPace(_RunsEveryLane):
    """The compiled lanes, skipping pace lanes; counts the pace lanes skipped."""

    skips_pace = True

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase="", pace=None):
        self.seen.append(0 if pace is None else int(np.sum(pace)))
        return self.lanes.run(model, case, speeds_kmh, delta_zeta, sweep, phase, pace=pace)


def test_a_window_grid_batch_equals_itself_with_every_pace_lane_run():
    """The calibration over lanes that skip pace lanes and over lanes that run them: every field."""
    bridges = _bridges("ICE-2", 15, 3, ("mu2", "mu5"))
    tr = load_train("ICE-2")
    opt = CalibrationOptions(step=StepOptions(steps_per_period=8.0), dim_grid="window")
    v = np.arange(150.0, 350.0 + 1e-9, 2.5)
    step = batch_step(bridges, tr, v, opt)
    skipping = _CountsPace(CompiledLanes(bridges, tr, step))
    plain = _RunsEveryLane(CompiledLanes(bridges, tr, step))
    a = calibrate_cases(bridges, tr, skipping, v, options=opt, step=step)
    b = calibrate_cases(bridges, tr, plain, v, options=opt, step=step)
    assert sum(skipping.seen) == 2  # one pace lane per case, in the DIM request
    for ra, rb in zip(a, b):
        assert ra.status == rb.status == "ok"
        assert ra.delta_zeta_vbi is not None and ra.delta_zeta_vbi == rb.delta_zeta_vbi
        assert np.array_equal(ra.dim_speeds_kmh, rb.dim_speeds_kmh)
        assert np.array_equal(ra.dim_acc_m_s2, rb.dim_acc_m_s2)
        assert ra.dim_speeds_kmh.max() < 340.0  # a window below the fastest paper speed, run as a pace lane only
