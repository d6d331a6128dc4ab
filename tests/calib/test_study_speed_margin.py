"""Work the study's batches no longer do, and the numbers they give unchanged.

* the MLM's modal load table of the compiled batch is made without the table of every axle's
  position at every half-step row, and equals the numpy stepper's table bit for bit;
* the MLM kernel advances a block in chunks of at most ``MLM_CHUNK_LANES`` lanes: a block wider
  than a chunk (uneven chunks, several bridges, lanes of different steps, with and without dense
  maxima) gives every lane the maxima of the numpy stepper, bit for bit.
"""

import numpy as np
import pytest

from adm_calib.calibrate import CalibrationOptions, batch_step
from adm_calib.study import MASS_FUNCTION_NAMES, select_cases
from adm_sim.integrate import kernels
from adm_sim.integrate.compiled_batch import BatchRunner, modal_load_table
from adm_sim.integrate.mlm_loads import half_step_positions, modal_loads_at
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep
from adm_sim.inputs.train_files import load_train


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


@pytest.mark.parametrize("dense", [False, True])
def test_mlm_chunks_of_a_wide_block_equal_the_numpy_stepper_bit_for_bit(dense):
    assert kernels.MLM_CHUNK_LANES == 64
    bridges = _bridges("ICE-2", 30, 3, ("mu1", "mu4"))
    tr = load_train("ICE-2")
    ds = batch_step(bridges, tr, options=CalibrationOptions(step=StepOptions(steps_per_period=6.0))).ds_m
    # bridge 0: 150 lanes of one sweep (3 chunks: 56, 56, 38); bridge 1: two sweeps of 70 and 9 lanes
    # (two blocks with their own steps; 70 lanes: 2 chunks of 40 and 30)
    v0 = np.linspace(160.0, 350.0, 150)
    v1a, v1b = np.linspace(170.0, 340.0, 70), np.linspace(165.0, 230.0, 9)
    dz0, dz1a = np.linspace(0.0, 0.02, 150), np.linspace(0.01, 0.0, 70)
    case = np.r_[np.zeros(150, int), np.ones(79, int)]
    sweep = np.r_[np.zeros(150, int), np.zeros(70, int), np.ones(9, int)]
    run = BatchRunner(bridges, tr, ds, dense_maxima=dense).start("mlm", case, np.r_[v0, v1a, v1b],
                                                                np.r_[dz0, dz1a, np.zeros(9)], sweep)
    while run.status == "running":
        run.advance(997)
    assert run.status == "finished"
    assert run.lane_steps[150] > run.lane_steps[-1]  # the two sweeps of bridge 1 have their own steps
    opt = StepOptions(ds_m=ds, dense_maxima=dense)
    for sel, b, v, dz in ((slice(0, 150), bridges[0], v0, dz0), (slice(150, 220), bridges[1], v1a, dz1a),
                          (slice(220, 229), bridges[1], v1b, np.zeros(9))):
        ref = run_sweep(b, tr, "mlm", v, delta_zeta=dz, options=opt)
        assert np.all(ref.max_acc_m_s2 > 0.0)
        assert np.array_equal(run.max_acc_m_s2[sel], ref.max_acc_m_s2)
        assert np.array_equal(run.max_disp_m[sel], ref.max_disp_m)
