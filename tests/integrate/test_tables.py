"""The tables shared by the numpy stepper and the kernels (:mod:`adm_sim.integrate.tables`) against brute force.

* :func:`vehicle_tables`: the stacked matrices are the units' own (Eq. 11) block by block, zero
  between units, and every CSR table expands back to its dense matrix exactly;
* :func:`axle_rows`: the axles on the bridge per half-step row equal a loop over the axles at
  ``x = r ds / 2 - offset``; the mode shapes equal ``sin(j pi x / L)`` and its derivatives written
  out (1e-12, only rounding of the sine's argument differs); ``minv`` inverts the modified mass
  matrix of Eq. (13) summed axle by axle (``M_mod minv = I`` to 1e-12: a 3x3 inverse of a matrix
  with condition number < 10 loses a few ulp).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from adm_sim.model.bridge import named_bridge
from adm_sim.integrate.tables import axle_rows, bridge_tables, vehicle_tables
from adm_sim.inputs.train_files import load_train


def _dense(ptr, col, val, shape):
    out = np.zeros(shape)
    for r in range(shape[0]):
        for e in range(ptr[r], ptr[r + 1]):
            out[r, col[e]] += val[e]
    return out


@pytest.mark.parametrize("name", ["ICE-2", "Eurostar"])
def test_vehicle_tables_are_the_units_matrices(name):
    train = load_train(name)
    t = vehicle_tables(train)
    n = t.minv_dof.size
    seen = np.zeros((n, n), dtype=bool)
    for i in range(len(train.units)):
        m = train.unit_matrices(i)
        d0, nd, a0, na = t.unit_dof0[i], t.unit_ndof[i], t.unit_ax0[i], t.unit_nax[i]
        np.testing.assert_array_equal(np.arange(a0, a0 + na), train.unit_axles(i))
        np.testing.assert_array_equal(t.Ks[d0:d0 + nd, d0:d0 + nd], m.K_s)
        np.testing.assert_array_equal(t.Cs[d0:d0 + nd, d0:d0 + nd], m.C_s)
        np.testing.assert_array_equal(t.Lw[a0:a0 + na, d0:d0 + nd], m.Lw)
        np.testing.assert_array_equal(t.kp[a0:a0 + na], m.k_p)
        np.testing.assert_allclose(t.minv_dof[d0:d0 + nd] * m.M, 1.0, rtol=2.3e-16)  # 1 ulp
        seen[d0:d0 + nd, d0:d0 + nd] = True
    assert np.all(t.Ks[~seen] == 0.0) and np.all(t.Cs[~seen] == 0.0)  # nothing couples two units
    np.testing.assert_array_equal(_dense(t.ks_ptr, t.ks_col, t.ks_val, t.Ks.shape), t.Ks)
    np.testing.assert_array_equal(_dense(t.cs_ptr, t.cs_col, t.cs_val, t.Cs.shape), t.Cs)
    np.testing.assert_array_equal(_dense(t.lw_ptr, t.lw_col, t.lw_val, t.Lw.shape), t.Lw)
    np.testing.assert_array_equal(_dense(t.lwt_ptr, t.lwt_col, t.lwt_val, t.Lw.T.shape), t.Lw.T)


def test_axle_rows_against_a_loop_over_the_axles():
    bridge, train, ds = named_bridge("B1"), load_train("ICE-2"), 0.37
    L, nm = bridge.span_m, bridge.n_modes
    r0, n_rows = 3, 400
    rows = axle_rows([bridge], train.axle_offsets_m, ds, r0, n_rows, train.wheel_mass_kg)
    M = bridge_tables([bridge]).M[0]
    j = np.arange(1, nm + 1) * math.pi / L
    n_on_total = 0
    for i in range(n_rows):
        s = (r0 + i) * ds / 2.0
        e0, e1 = rows.ptr[i], rows.ptr[i + 1]
        on = [a for a, o in enumerate(train.axle_offsets_m) if 0.0 <= s - o <= L]
        assert rows.axle[e0:e1].tolist() == on
        mmod = np.diag(M)
        for e, a in zip(range(e0, e1), on):
            x = s - train.axle_offsets_m[a]
            phi = np.array([math.sin(jj * x) for jj in j])
            np.testing.assert_allclose(rows.phi[e], phi, rtol=0, atol=1e-12)
            np.testing.assert_allclose(rows.phx[e], j * np.cos(j * x), rtol=1e-12, atol=1e-12 * j.max())
            np.testing.assert_allclose(rows.phxx[e], -j**2 * phi, rtol=0, atol=1e-12 * j.max()**2)
            mmod = mmod + train.wheel_mass_kg[a] * np.outer(phi, phi)  # Eq. (13), axle by axle
        np.testing.assert_allclose(mmod @ rows.minv[0, i], np.eye(nm), rtol=0, atol=1e-12)
        n_on_total += len(on)
    assert n_on_total > n_rows  # the rows cover crossings with several axles on the bridge
    empty = axle_rows([bridge], train.axle_offsets_m, ds, r0, 5)  # the MLM needs no mass matrices
    assert empty.minv.shape == (1, 0, 0, 0)
