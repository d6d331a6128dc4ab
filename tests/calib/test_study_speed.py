"""What makes the study's batches cheaper gives the numbers it gave before.

* the MLM kernel (block-local copies, vectorised over lanes) equals the numpy stepper bit for bit:
  held by tests/calib/test_study_speed_margin.py::test_mlm_chunks_of_a_wide_block_equal_the_numpy_stepper_bit_for_bit
  (with and without dense maxima, one- and several-chunk blocks, two bridges, sweeps of their own
  steps, resumed advances; the kernel takes Δζ only through each lane's damping and its RK4
  coefficients, with no branch on its sign, so the negative Δζ lane this file once ran adds nothing);
* the DIM kernel advances the bridges of a batch that share a number of steps as one block of
  lanes, each lane with its own bridge's stiffness and Eq. (13) inverses: every lane's maxima equal
  those of its bridge run alone, bit for bit (dense maxima, added damping, in chunks of steps);
* the Eq. (13) inverses by the adjugate equal LAPACK's to round-off (7e-16 relative measured;
  asserted 1e-14 relative to the largest entry of each inverse);
* the axles on the bridge found by bisection are the rows and entries of a test of every row, bit
  for bit;
* the speeds' one-array validation words an error as the per-speed check does.
"""

import numpy as np
import pytest

from adm_calib.calibrate import CalibrationOptions, batch_step
from adm_calib.study import MASS_FUNCTION_NAMES, select_cases
from adm_sim.integrate.compiled_batch import BatchRunner
from adm_sim.errors import InputError
from adm_sim.integrate.step_grid import StepOptions, speeds_to_m_s
from adm_sim.integrate.tables import _axles_on, axle_rows, small_inverse
from adm_sim.inputs.train_files import load_train


def _bridges(train, span, fi, mfs=MASS_FUNCTION_NAMES):
    return [c.bridge for c in select_cases([train], list(mfs), (span, span), [fi])]


def test_dim_bridges_advancing_together_equal_each_bridge_alone_bit_for_bit():
    bridges = _bridges("ICE-2", 12, 4, ("mu1", "mu5", "mu6"))
    tr = load_train("ICE-2")
    ds = batch_step(bridges, tr, options=CalibrationOptions(step=StepOptions(steps_per_period=8.0))).ds_m
    # mu1 and mu5 share their speeds, so their steps (one block of lanes); mu6's fastest speed is
    # lower, so it takes fewer steps (its own block)
    speeds = [np.array([165.0, 240.0, 301.0, 350.0])] * 2 + [np.array([120.0, 240.0, 301.0, 330.0])]
    dz = np.array([0.0, 0.003, -0.002, 0.02])
    case = np.repeat([0, 1, 2], 4)

    def run(runner, case, v, dz):
        r = runner.start("dim", case, v, dz)
        while r.status == "running":
            r.advance(301)
        assert r.status == "finished"
        return r.max_acc_m_s2, r.max_disp_m, r.lane_steps

    together = run(BatchRunner(bridges, tr, ds, dense_maxima=True), case, np.concatenate(speeds), np.tile(dz, 3))
    steps = together[2]
    assert steps[0] == steps[4] > steps[8]  # mu1 and mu5 advance as one block, mu6 apart
    for c, b in enumerate(bridges):
        alone = run(BatchRunner([b], tr, ds, dense_maxima=True), np.zeros(4, int), speeds[c], dz)
        assert np.all(alone[0] > 0.0)
        assert np.array_equal(together[0][case == c], alone[0])
        assert np.array_equal(together[1][case == c], alone[1])


@pytest.mark.parametrize("m", [1, 2, 3, 4])
def test_small_inverse_equals_lapack(m):
    rng = np.random.default_rng(m)
    v = rng.normal(size=(2000, m, 3))
    A = np.eye(m)[None] * rng.uniform(1e4, 1e6, (2000, 1, 1)) + 1500.0 * np.einsum("nik,njk->nij", v, v)
    A[:, 0, -1] *= 1.0 + 4e-16  # not exactly symmetric, as the Eq. (13) sums of outer products
    ref = np.linalg.inv(A)
    scale = np.max(np.abs(ref), axis=(1, 2))[:, None, None]
    assert np.max(np.abs(small_inverse(A) - ref) / scale) < 1e-14


def test_eq13_inverses_of_a_batch_equal_lapack():
    bridges = _bridges("ICE-2", 4, 5)
    tr = load_train("ICE-2")
    rows = axle_rows(bridges, tr.axle_offsets_m, 0.02, 0, 4001, tr.wheel_mass_kg)
    empty = np.diff(rows.ptr) == 0
    assert 0.2 < empty.mean() < 0.8  # both kinds of row are exercised
    for c, b in enumerate(bridges):
        S = np.zeros((4001, b.n_modes, b.n_modes))
        mw = np.asarray(tr.wheel_mass_kg, float)[rows.axle]
        np.add.at(S, np.repeat(np.arange(4001), np.diff(rows.ptr)),
                  (rows.phi * mw[:, None])[:, :, None] * rows.phi[:, None, :])
        ref = np.linalg.inv(np.diag(b.modal_mass_kg)[None] + S)
        np.testing.assert_allclose(rows.minv[c], ref, rtol=1e-14, atol=1e-14 * np.abs(ref).max())
        # a row without an axle: diag(1 / M) to round-off, exact zeros off the diagonal
        inv_diag = np.broadcast_to(np.diag(1.0 / b.modal_mass_kg), ref[empty].shape)
        np.testing.assert_allclose(rows.minv[c][empty], inv_diag, rtol=1e-15, atol=0)


@pytest.mark.parametrize("train,span,ds,r0,n", [("ICE-2", 4, 0.0086, 0, 30001), ("Eurostar", 40, 0.0374, 17, 20001),
                                                ("Railjet", 7, 0.013, 500, 3000), ("ICE-4", 23, 0.05, 3, 9000)])
def test_axles_on_the_bridge_equal_a_test_of_every_row(train, span, ds, r0, n):
    tr = load_train(train)
    L = float(_bridges(train, span, 1, ("mu1",))[0].span_m)
    r = np.arange(r0, r0 + n)
    front = (r // 2 + 0.5 * (r % 2)) * ds
    off = np.asarray(tr.axle_offsets_m, float)
    x = front[:, None] - off[None, :]
    rows, axles = np.nonzero((x >= 0.0) & (x <= L))
    got = _axles_on(front, off, L)
    assert rows.size > 0
    assert np.array_equal(got[0], rows) and np.array_equal(got[1], axles) and np.array_equal(got[2], x[rows, axles])


@pytest.mark.parametrize("speeds,msg", [([200.0, 700.0], r"^speed_kmh: 700 km/h is out of range; allowed \[1, 600\] km/h"),
                                        ([0.5, 200.0], r"^speed_kmh: 0.5 km/h is out of range"),
                                        ([200.0, np.nan], r"^speed_kmh: .*nan.* km/h is not finite")])
def test_speed_errors_name_the_first_bad_speed(speeds, msg):
    with pytest.raises(InputError, match=msg):
        speeds_to_m_s(speeds)
    assert np.array_equal(speeds_to_m_s([1.0, 600.0, 250.0]), np.array([1.0, 600.0, 250.0]) / 3.6)
