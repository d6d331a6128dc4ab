"""The vehicle and bridge tables of a run, built once for the numpy stepper and the numba kernels.

Named structures (``typing.NamedTuple`` of numpy arrays: numba takes them as kernel arguments and
reads their fields by name) built by one function each:

* :func:`vehicle_tables` -> :class:`VehicleTables`: the DIM vehicles of a train (Eq. 11): every
  unit's DOF and axle range, the secondary stage ``K_s``, ``C_s`` and the DOF-to-bogie-point map
  ``Lw`` (dense, and row-compressed for the kernels), the primary stage ``k_p``, ``c_p`` and the
  inverse diagonal masses per DOF, the axle loads and wheelset masses.
* :func:`active_units` -> :class:`ActiveUnits`: the units with an axle on the bridge during each
  step (a unit rests before its first axle enters and no longer acts once its last has left).
* :func:`bridge_tables` -> :class:`BridgeTables`: modal mass and stiffness (Eq. 5) per bridge
  and the mode shapes at midspan.
* :func:`axle_rows` -> :class:`AxleRows`: per half-step row of the shared space grid (the RK4
  stage points, :mod:`adm_sim.integrate.step_grid`), the axles on the bridge with their mode shapes and
  derivatives (Eqs. 4, 6, 9) and, for the DIM, the inverse of the wheelset-modified mass matrix
  ``M + sum_i m_w,i phi(x_i) phi(x_i)^T`` (Eq. 13) per bridge, used by the kernels and the numpy
  stepper alike.

:class:`adm_sim.integrate.rk4_sides.TrainSide` / :class:`~adm_sim.integrate.rk4_sides.BridgeSide` take the rows and units
of the step they are at; :class:`adm_sim.integrate.compiled_batch.BatchRunner` tabulates every step at once
for :mod:`adm_sim.integrate.kernels`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from adm_sim.errors import InputError


def _row_ptr(rows, n_rows):
    """CSR row pointers (n_rows + 1,) of sorted row indices: entries of row r are ptr[r]:ptr[r+1]."""
    return np.searchsorted(rows, np.arange(n_rows + 1)).astype(np.int64)


def _csr(dense):
    """Row-compressed nonzeros of a dense matrix: ``(ptr, col, val)``."""
    rows, cols = np.nonzero(dense)
    return _row_ptr(rows, dense.shape[0]), cols.astype(np.int64), dense[rows, cols].astype(float)


class VehicleTables(NamedTuple):
    """The vehicles of a train for the DIM (Eq. 11), DOFs of all units stacked in unit order.

    ``unit_dof0``, ``unit_ndof``, ``unit_ax0``, ``unit_nax`` (n_units,): first DOF, DOF count,
    first axle, axle count of every unit; ``first_m``, ``last_m`` (n_units,): offsets of its
    first and last axle behind the first axle of the train (m). Secondary stage ``K_s``, ``C_s``
    (n_dof, n_dof) and ``Lw`` (n_axles, n_dof) (block diagonal over the units), as CSR for the
    kernels (``*_ptr``, ``*_col``, ``*_val``; ``lwt`` is ``Lw^T``). ``kp``, ``cp`` (n_axles,)
    primary stiffness (N/m) and damping (Ns/m); ``minv_dof`` (n_dof,) inverse masses (1/kg,
    1/(kg m^2)); ``axle_load_n``, ``wheel_mass_kg`` (n_axles,).
    """

    unit_dof0: np.ndarray
    unit_ndof: np.ndarray
    unit_ax0: np.ndarray
    unit_nax: np.ndarray
    first_m: np.ndarray
    last_m: np.ndarray
    ks_ptr: np.ndarray
    ks_col: np.ndarray
    ks_val: np.ndarray
    cs_ptr: np.ndarray
    cs_col: np.ndarray
    cs_val: np.ndarray
    lw_ptr: np.ndarray
    lw_col: np.ndarray
    lw_val: np.ndarray
    lwt_ptr: np.ndarray
    lwt_col: np.ndarray
    lwt_val: np.ndarray
    kp: np.ndarray
    cp: np.ndarray
    minv_dof: np.ndarray
    axle_load_n: np.ndarray
    wheel_mass_kg: np.ndarray
    Ks: np.ndarray
    Cs: np.ndarray
    Lw: np.ndarray


def vehicle_tables(train):
    """:class:`VehicleTables` of a train with vehicles (its units' matrices, Eq. 11)."""
    mats = [train.unit_matrices(i) for i in range(len(train.units))]
    n = sum(len(m.M) for m in mats)
    Ks, Cs, Lw = np.zeros((n, n)), np.zeros((n, n)), np.zeros((train.n_axles, n))
    minv = np.zeros(n)
    kp, cp = np.zeros(train.n_axles), np.zeros(train.n_axles)
    dof0, ndof, ax0, nax, first, last = [], [], [], [], [], []
    d = 0
    for i, m in enumerate(mats):
        axles = train.unit_axles(i)
        if not np.all(np.diff(axles) == 1):
            raise InputError(f"train: unit {i} of {train.name!r} has axles out of order")
        nn = len(m.M)
        Ks[d:d + nn, d:d + nn] = m.K_s
        Cs[d:d + nn, d:d + nn] = m.C_s
        Lw[axles[0]:axles[-1] + 1, d:d + nn] = m.Lw
        kp[axles], cp[axles] = m.k_p, m.c_p
        minv[d:d + nn] = 1.0 / m.M
        dof0.append(d)
        ndof.append(nn)
        ax0.append(axles[0])
        nax.append(len(axles))
        first.append(train.axle_offsets_m[axles].min())
        last.append(train.axle_offsets_m[axles].max())
        d += nn
    ks, cs, lw, lwt = _csr(Ks), _csr(Cs), _csr(Lw), _csr(Lw.T.copy())
    i64 = lambda a: np.asarray(a, dtype=np.int64)  # noqa: E731
    return VehicleTables(
        unit_dof0=i64(dof0), unit_ndof=i64(ndof), unit_ax0=i64(ax0), unit_nax=i64(nax),
        first_m=np.array(first, dtype=float), last_m=np.array(last, dtype=float),
        ks_ptr=ks[0], ks_col=ks[1], ks_val=ks[2], cs_ptr=cs[0], cs_col=cs[1], cs_val=cs[2],
        lw_ptr=lw[0], lw_col=lw[1], lw_val=lw[2], lwt_ptr=lwt[0], lwt_col=lwt[1], lwt_val=lwt[2],
        kp=kp, cp=cp, minv_dof=minv, axle_load_n=np.asarray(train.axle_loads_n, dtype=float),
        wheel_mass_kg=np.asarray(train.wheel_mass_kg, dtype=float), Ks=Ks, Cs=Cs, Lw=Lw)


class ActiveUnits(NamedTuple):
    """Units active during steps ``k0 .. k1 - 1`` as CSR: step ``k0 + i`` has ``units[ptr[i]:ptr[i+1]]``."""

    ptr: np.ndarray
    units: np.ndarray


def active_units(vehicles, span_m, ds_m, k0, k1):
    """:class:`ActiveUnits` of steps ``k0 .. k1 - 1``: a unit acts during step ``k`` while
    ``s_k+1 - first >= 0`` and ``s_k - last <= L`` (first axle front ``s_k = k ds``)."""
    k = np.arange(k0, k1)
    lo, hi = (k + 0.0) * ds_m, (k + 1.0) * ds_m  # == Grid.front_m(k), front_m(k, 3) bit for bit
    act = (hi[:, None] - vehicles.first_m[None, :] >= 0.0) & (lo[:, None] - vehicles.last_m[None, :] <= span_m)
    krow, units = np.nonzero(act)
    return ActiveUnits(ptr=_row_ptr(krow, k.size), units=units.astype(np.int64))


class BridgeTables(NamedTuple):
    """Modal mass ``M`` (kg) and stiffness ``K`` (N/m) (n_bridges, n_modes) (Eq. 5) and the mode
    shapes at the response point ``phi_mid`` (n_modes,) of bridges of one span and mode count
    (midspan, or the point a run asks for)."""

    M: np.ndarray
    K: np.ndarray
    phi_mid: np.ndarray


def bridge_tables(bridges, response_m=None):
    """:class:`BridgeTables` of bridges sharing span and mode count (and, for continuous decks, spans).

    ``response_m``: the response point (m from the left abutment); None: midspan (one span:
    ``sin(j pi / 2)``; a continuous deck: its mode shapes at ``bridge.midspan_m``).
    """
    b0 = bridges[0]
    if response_m is None and not b0.is_continuous:
        phi = np.sin(b0.mode_numbers * math.pi / 2.0)
    else:
        x = b0.midspan_m if response_m is None else float(response_m)
        phi = np.ascontiguousarray(b0.shapes(np.array([x]))[0][0])
    return BridgeTables(M=np.array([b.modal_mass_kg for b in bridges]),
                        K=np.array([b.modal_stiffness_N_m for b in bridges]),
                        phi_mid=phi)


class AxleRows(NamedTuple):
    """Axles on the bridge per half-step row ``r0 .. r0 + n_rows - 1`` (row ``r``: first axle at
    ``s = r ds / 2``), as CSR: row ``r0 + i`` has entries ``ptr[i]:ptr[i+1]``, axle ``axle[e]``
    with mode shapes ``phi[e]``, ``phx[e]``, ``phxx[e]`` (n_ent, n_modes) (Eqs. 4, 6, 9); ``minv``
    (n_bridges, n_rows, n_modes, n_modes) the inverse modified mass matrix (Eq. 13) per row (DIM;
    shape (n_bridges, 0, 0, 0) for the MLM)."""

    ptr: np.ndarray
    axle: np.ndarray
    phi: np.ndarray
    phx: np.ndarray
    phxx: np.ndarray
    minv: np.ndarray


def small_inverse(A):
    """Inverse of a stack of square matrices ``A`` (n, m, m): the adjugate over the determinant for
    m <= 3 (whole-array arithmetic, ~20x faster than one LAPACK call per matrix; equal to
    :func:`numpy.linalg.inv` to a few units of round-off for the well-conditioned Eq. (13)
    matrices), :func:`numpy.linalg.inv` for larger m."""
    m = A.shape[-1]
    if m == 1:
        return 1.0 / A
    if m == 2:
        a, b, c, d = A[:, 0, 0], A[:, 0, 1], A[:, 1, 0], A[:, 1, 1]
        det = a * d - b * c
        return np.stack([np.stack([d, -b], -1), np.stack([-c, a], -1)], -2) / det[:, None, None]
    if m == 3:
        a, b, c, d, e, f, g, h, i = (A[:, r, k] for r in range(3) for k in range(3))
        c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g  # cofactors of the first row
        det = a * c00 + b * c01 + c * c02
        adj = np.stack([np.stack([c00, c * h - b * i, b * f - c * e], -1),
                        np.stack([c01, a * i - c * g, c * d - a * f], -1),
                        np.stack([c02, b * g - a * h, a * e - b * d], -1)], -2)
        return adj / det[:, None, None]
    return np.linalg.inv(A)


def _axles_on(front, offsets, span_m):
    """Every (row, axle) with the axle on the bridge, ``0 <= front - offset <= span``, in row-major
    order (row, then axle), and its position ``front - offset`` (m). ``front`` is non-decreasing,
    so each axle is on the bridge over one run of rows: found by bisection (widened by one row each
    side), then tested with the same subtraction and comparisons as a test of every row."""
    n = front.size
    lo = np.clip(np.searchsorted(front, offsets, side="left") - 1, 0, n)
    hi = np.clip(np.searchsorted(front, offsets + span_m, side="right") + 1, 0, n)
    count = np.maximum(hi - lo, 0)
    axle = np.repeat(np.arange(offsets.size), count)
    start = np.cumsum(count) - count
    row = np.arange(axle.size) - np.repeat(start - lo, count)
    x = front[row] - offsets[axle]
    keep = (x >= 0.0) & (x <= span_m)
    row, axle, x = row[keep], axle[keep], x[keep]
    order = np.lexsort((axle, row))
    return row[order], axle[order], x[order]


def axle_rows(bridges, axle_offsets_m, ds_m, r0, n_rows, wheel_mass_kg=None):
    """:class:`AxleRows` of half-step rows ``r0 .. r0 + n_rows - 1`` for bridges of one span.

    With ``wheel_mass_kg`` (n_axles,) also the inverse of ``M_mod = diag(M) + sum_i m_w,i
    phi(x_i) phi(x_i)^T`` (Eq. 13) per bridge and row.
    """
    b0 = bridges[0]
    r = np.arange(r0, r0 + n_rows)
    front = (r // 2 + 0.5 * (r % 2)) * ds_m  # == Grid.front_m(k, stage) bit for bit
    rows, axles, x = _axles_on(front, np.asarray(axle_offsets_m, dtype=float), b0.span_m)
    phi, phx, phxx = b0.shapes(x)
    nm = b0.n_modes
    if wheel_mass_kg is None:
        minv = np.zeros((len(bridges), 0, 0, 0))
    else:
        mw = np.asarray(wheel_mass_kg, dtype=float)[axles]
        outer = (phi * mw[:, None])[:, :, None] * phi[:, None, :]  # Eq. (13) terms per axle
        S = np.zeros((n_rows, nm, nm))
        np.add.at(S, rows, outer)
        minv = np.empty((len(bridges), n_rows, nm, nm))
        # a row without an axle on the bridge has M_mod = diag(M): inverted once per bridge (short
        # spans have ~half their rows empty)
        loaded = np.zeros(n_rows, dtype=bool)
        loaded[rows] = True
        for c, b in enumerate(bridges):
            D = np.diag(b.modal_mass_kg)[None]
            minv[c, loaded] = small_inverse(D + S[loaded])
            minv[c, ~loaded] = small_inverse(D + np.zeros((1, nm, nm)))[0]
    return AxleRows(ptr=_row_ptr(rows, n_rows), axle=axles.astype(np.int64), phi=np.ascontiguousarray(phi),
                    phx=np.ascontiguousarray(phx), phxx=np.ascontiguousarray(phxx), minv=minv)
