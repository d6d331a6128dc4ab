"""Compiled whole-run kernels: every lane of a batch integrated over all its steps in one call.

These are the per-stage computations of :class:`adm_sim.integrate.rk4_sides.BridgeSide` and
:class:`adm_sim.integrate.rk4_sides.TrainSide` (same equations, same RK4 bookkeeping, same operation order),
written as loops over lanes and steps so that numba compiles them: the Python overhead of ~40
small numpy calls per RK stage (~100 us) disappears, and a lane costs only its arithmetic.
Each lane carries its own bridge (modal stiffness, damping, the wheelset-modified mass matrix of
Eq. 13) and its own number of steps; the span, the space step ``ds`` and the train are shared,
so the axles on the bridge and the mode shapes under them are tabulated once per batch.

Arguments are named structures (``typing.NamedTuple`` of arrays): the tables of
:mod:`adm_sim.integrate.tables` (``BridgeTables``, ``AxleRows``, ``ActiveUnits``, ``VehicleTables``, built
by the same functions the numpy stepper uses) and, here, :class:`Blocks`, :class:`DimLanes`,
:class:`MlmLanes`, :class:`LaneState`. A DIM stage calls one helper per numpy step:
:func:`rail_state` (``BridgeSide.rail_state``), :func:`vehicle_accelerations`
(``TrainSide.take_rail_state``), :func:`bridge_accelerations` (``BridgeSide.take_forces``),
:func:`midspan_acceleration`, :func:`contact_forces`, and :func:`rk4_push` (``_Rk4State.push``) for
each subsystem; a step starts with :func:`start_step`, :func:`start_units` and ends with the maxima
(:func:`sampled_maxima`, :func:`dense_maxima`), which both kernels share; a run's set-up is
:func:`same_steps_run`, :func:`lane_tables`, :func:`scratch` and its end :func:`put_lanes`. An MLM
step is :func:`mlm_step` (``BridgeSide.step_mlm``) then the maxima. Every helper is
``inline="always"``: numba splices it into the kernel before compiling, so a helper costs no call,
and the work arrays stay the kernel's own, which keeps the loops over lanes vectorised (against
the DIM kernel written in one piece, ``bench/bench_kernels.py --baseline``: no slow-down beyond the
noise of the bench, the maxima bit for bit equal; the CHANGELOG has the figures).

One source: without numba the same functions run as plain Python (slow, for debugging;
``tests/integrate/test_kernels_uncompiled.py``). The numpy stepper stays the reference (the ROS nodes use
it); ``tests/integrate/test_batch.py`` holds the two together to 1e-12 relative.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# numba compiles these loops; the plain-Python path is the same source (adm_sim.integrate._jit.njit)
from adm_sim.integrate._jit import RK4_C_ARRAY as RK4_C
from adm_sim.integrate._jit import RK4_W_ARRAY as RK4_W
from adm_sim.integrate._jit import STAGE_ROW, njit


@njit(cache=True, inline="always")
def hermite_max_abs_acc(d0, v0, a0, d1, v1, a1, h):
    """Largest |acceleration| strictly inside one step from the dense output, 0 if none.

    One lane, scalar arithmetic of :func:`adm_sim.integrate.dense_output.hermite_max_abs_acc` operation for
    operation (the cubic second derivative of the quintic Hermite interpolant of the deflection).
    """
    D = (d1 - d0) / (h * h)
    V0 = v0 / h
    V1 = v1 / h
    c1 = 60.0 * D - 36.0 * V0 - 24.0 * V1 - 9.0 * a0 + 3.0 * a1
    c2 = -180.0 * D + 96.0 * V0 + 84.0 * V1 + 18.0 * a0 - 12.0 * a1
    c3 = 120.0 * D - 60.0 * V0 - 60.0 * V1 - 10.0 * a0 + 10.0 * a1
    A = 3.0 * c3
    B = 2.0 * c2
    C = c1
    s1 = -1.0
    s2 = -1.0
    disc = B * B - 4.0 * A * C
    if A != 0.0:
        if disc >= 0.0:
            sq = np.sqrt(disc)
            q = -0.5 * (B + sq) if B >= 0.0 else -0.5 * (B - sq)
            if q != 0.0:
                s1 = q / A
                s2 = C / q
    elif B != 0.0:
        s1 = -C / B
    best = 0.0
    if s1 > 0.0 and s1 < 1.0:
        val = abs(a0 + s1 * (c1 + s1 * (c2 + s1 * c3)))
        if val > best:
            best = val
    if s2 > 0.0 and s2 < 1.0:
        val = abs(a0 + s2 * (c1 + s2 * (c2 + s2 * c3)))
        if val > best:
            best = val
    return best


class Blocks(NamedTuple):
    """Lanes in block order: block ``i`` is lanes ``ptr[i]:ptr[i+1]`` (n_blocks + 1,), all on bridge
    ``case[i]`` with ``steps[i]`` steps (n_blocks,); they advance together, innermost."""

    ptr: np.ndarray
    case: np.ndarray
    steps: np.ndarray


class DimLanes(NamedTuple):
    """Per lane (block order): speed ``v`` (m/s), time step ``h`` (s) (n_lanes,), modal damping
    ``Z`` (n_lanes, n_modes) (Ns/m)."""

    v: np.ndarray
    h: np.ndarray
    Z: np.ndarray


class MlmLanes(NamedTuple):
    """Per lane (block order): time step ``h`` (s) (n_lanes,); modal damping ``Z`` and the exact
    RK4 recurrence of :func:`adm_sim.integrate.rk4_sides.mlm_rk4_coefficients`, each (n_modes, n_lanes)."""

    h: np.ndarray
    Z: np.ndarray
    ax: np.ndarray
    axd: np.ndarray
    bx: np.ndarray
    bxd: np.ndarray
    c0: np.ndarray
    c0d: np.ndarray
    ch: np.ndarray
    chd: np.ndarray
    c1: np.ndarray
    c1d: np.ndarray


class LaneState(NamedTuple):
    """State of every lane (block order), updated in place: modal ``q``, ``qd`` (n_modes, n_lanes),
    vehicle ``u``, ``ud`` (n_dof, n_lanes; n_dof = 0 for the MLM), the running maxima of |midspan
    acceleration| ``max_acc`` and |deflection| ``max_disp`` (n_lanes,), and ``prev`` (3, n_lanes)
    the midspan deflection, velocity and acceleration of the last step done (dense maxima)."""

    q: np.ndarray
    qd: np.ndarray
    u: np.ndarray
    ud: np.ndarray
    max_acc: np.ndarray
    max_disp: np.ndarray
    prev: np.ndarray


class Contact(NamedTuple):
    """The DIM's contact check of every lane (block order), updated in place: the smallest
    wheel-rail contact force of any axle on the bridge at stage 0 of the steps done ``min_n``
    (N, compression positive; ``inf`` before the first axle enters) and the first tension (the
    wheel would lift off, which the model excludes): step ``first_k`` (-1: none), axle
    ``first_axle`` and force ``first_n`` (N) (n_lanes,) each (:func:`contact_forces`)."""

    min_n: np.ndarray
    first_k: np.ndarray
    first_axle: np.ndarray
    first_n: np.ndarray


# ---------------------------------------------------------------------- the steps, one helper each
@njit(cache=True, inline="always")
def start_step(q, qd, phi_mid, d, vel, sq, sqd):
    """Start of a step: midspan deflection ``d`` and velocity ``vel`` (n_lanes,) of the modal state
    (``BridgeSide.midspan_displacement`` / ``midspan_velocity``); the stage state ``sq``, ``sqd``
    is the step's state (``_Rk4State.reset``)."""
    nm, nb = q.shape
    for b in range(nb):
        d[b] = 0.0
        vel[b] = 0.0
    for j in range(nm):
        pm = phi_mid[j]
        for b in range(nb):
            d[b] += q[j, b] * pm
            vel[b] += qd[j, b] * pm
            sq[j, b] = q[j, b]
            sqd[j, b] = qd[j, b]


@njit(cache=True, inline="always")
def start_units(vehicles, units, a0, a1, u, ud, su, sud):
    """Start of a step for the active units ``units[a0:a1]``: stage state = step state
    (``TrainSide._active`` / ``_Rk4State.reset``)."""
    dof0 = vehicles.unit_dof0
    ndof = vehicles.unit_ndof
    nb = u.shape[1]
    for ia in range(a0, a1):
        un = units[ia]
        for dd in range(dof0[un], dof0[un] + ndof[un]):
            for b in range(nb):
                su[dd, b] = u[dd, b]
                sud[dd, b] = ud[dd, b]


class Track(NamedTuple):
    """Track irregularity under the axles of :class:`adm_sim.integrate.tables.AxleRows`, entry by entry:
    elevation ``r`` (m), slope ``s`` (-) and curvature ``c`` (1/m) of the profile at the axle
    (n_entries,); zeros for a smooth track (:mod:`adm_sim.model.irregularity`)."""

    r: np.ndarray
    s: np.ndarray
    c: np.ndarray


@njit(cache=True, inline="always")
def rail_state(rows, r, sq, sqd, v, W, Wd, t1, t2, t3, track):
    """Bridge -> train (``BridgeSide.rail_state`` and the profile terms of
    ``TrainSide.take_rail_state``): rail displacement plus irregularity ``W = phi q + r(x)`` and
    velocity ``Wd = phi qd + v phi' q + v r'(x)`` (n_axles, n_lanes) under every axle on the bridge
    at half-step row ``r`` (Eqs. 4, 9 with the profile ``track``, :class:`Track`)."""
    ptr = rows.ptr
    axle = rows.axle
    phi = rows.phi
    phx = rows.phx
    tr = track.r
    ts = track.s
    nm, nb = sq.shape
    for e in range(ptr[r], ptr[r + 1]):
        a = axle[e]
        for b in range(nb):
            t1[b] = 0.0
            t2[b] = 0.0
            t3[b] = 0.0
        for j in range(nm):
            pj = phi[e, j]
            xj = phx[e, j]
            for b in range(nb):
                t1[b] += sq[j, b] * pj
                t2[b] += sqd[j, b] * pj
                t3[b] += sq[j, b] * xj
        re_ = tr[e]
        se = ts[e]
        for b in range(nb):
            W[a, b] = t1[b] + re_
            Wd[a, b] = (t2[b] + v[b] * t3[b]) + v[b] * se


@njit(cache=True, inline="always")
def vehicle_accelerations(vehicles, units, a0, a1, su, sud, W, Wd, f, udd, t1, t2, t3):
    """Train (``TrainSide.take_rail_state``): primary stage forces ``f = k_p (W - Lw u) + c_p (Wd -
    Lw ud)`` (n_axles, n_lanes) and vehicle accelerations ``udd = (Lw^T f - K_s u - C_s ud) / M``
    (Eq. 11) of the active units ``units[a0:a1]``."""
    dof0 = vehicles.unit_dof0
    ndof = vehicles.unit_ndof
    ax0 = vehicles.unit_ax0
    nax = vehicles.unit_nax
    lw_ptr = vehicles.lw_ptr
    lw_col = vehicles.lw_col
    lw_val = vehicles.lw_val
    lwt_ptr = vehicles.lwt_ptr
    lwt_col = vehicles.lwt_col
    lwt_val = vehicles.lwt_val
    ks_ptr = vehicles.ks_ptr
    ks_col = vehicles.ks_col
    ks_val = vehicles.ks_val
    cs_ptr = vehicles.cs_ptr
    cs_col = vehicles.cs_col
    cs_val = vehicles.cs_val
    kp = vehicles.kp
    cp = vehicles.cp
    minv_dof = vehicles.minv_dof
    nb = su.shape[1]
    for ia in range(a0, a1):
        un = units[ia]
        for ax_ in range(ax0[un], ax0[un] + nax[un]):
            for b in range(nb):
                t1[b] = 0.0
                t2[b] = 0.0
            for t in range(lw_ptr[ax_], lw_ptr[ax_ + 1]):
                col = lw_col[t]
                val = lw_val[t]
                for b in range(nb):
                    t1[b] += su[col, b] * val
                    t2[b] += sud[col, b] * val
            kpa = kp[ax_]
            cpa = cp[ax_]
            for b in range(nb):
                f[ax_, b] = kpa * (W[ax_, b] - t1[b]) + cpa * (Wd[ax_, b] - t2[b])
        for dd in range(dof0[un], dof0[un] + ndof[un]):
            for b in range(nb):
                t1[b] = 0.0
                t2[b] = 0.0
                t3[b] = 0.0
            for t in range(lwt_ptr[dd], lwt_ptr[dd + 1]):
                col = lwt_col[t]
                val = lwt_val[t]
                for b in range(nb):
                    t1[b] += f[col, b] * val
            for t in range(ks_ptr[dd], ks_ptr[dd + 1]):
                col = ks_col[t]
                val = ks_val[t]
                for b in range(nb):
                    t2[b] += su[col, b] * val
            for t in range(cs_ptr[dd], cs_ptr[dd + 1]):
                col = cs_col[t]
                val = cs_val[t]
                for b in range(nb):
                    t3[b] += sud[col, b] * val
            md = minv_dof[dd]
            for b in range(nb):
                udd[dd, b] = (t1[b] - t2[b] - t3[b]) * md


@njit(cache=True, inline="always")
def bridge_accelerations(rows, r, cl, Kl, vehicles, sq, sqd, v, Z, f, W, Wd, p, rhs, qdd, t1, t2, t3, track, g):
    """Train -> bridge (``BridgeSide.take_forces``): interaction ``G = F - F_k1 - F_c1`` (Eq. 7)
    less the wheelset inertia on the profile ``m_w v^2 r''(x)`` (``TrainSide.take_rail_state``;
    ``track``, :class:`Track`) and of the convective terms (Eq. 9), modal load ``p`` (Eq. 14) and
    ``qdd = M_mod^-1 (p - Z qd - K q)`` (Eq. 15) at half-step row ``r``, lane ``b`` on bridge ``cl[b]``
    with modal stiffness ``Kl[:, b]``; the rail state ``W``, ``Wd`` of the axles on the bridge is cleared (rigid track off the bridge).
    ``g`` (n_axles, n_lanes) keeps each axle's load on the bridge less the wheel's inertia but that of
    the modal accelerations (:func:`contact_forces` completes it)."""
    ptr = rows.ptr
    axle = rows.axle
    phi = rows.phi
    phx = rows.phx
    phxx = rows.phxx
    minv = rows.minv
    axle_load = vehicles.axle_load_n
    wheel_mass = vehicles.wheel_mass_kg
    tc = track.c
    nm, nb = sq.shape
    for j in range(nm):
        for b in range(nb):
            p[j, b] = 0.0
    for e in range(ptr[r], ptr[r + 1]):
        a = axle[e]
        for b in range(nb):
            t1[b] = 0.0
            t2[b] = 0.0
        for j in range(nm):
            xj = phx[e, j]
            xxj = phxx[e, j]
            for b in range(nb):
                t1[b] += sqd[j, b] * xj
                t2[b] += sq[j, b] * xxj
        fa = axle_load[a]
        mwa = wheel_mass[a]
        ce = tc[e]
        for b in range(nb):
            t3[b] = ((fa - f[a, b]) - mwa * (v[b] * v[b]) * ce) - mwa * (2.0 * v[b] * t1[b] + v[b] * v[b] * t2[b])
            g[a, b] = t3[b]
        for j in range(nm):
            pj = phi[e, j]
            for b in range(nb):
                p[j, b] += t3[b] * pj
        for b in range(nb):
            W[a, b] = 0.0
            Wd[a, b] = 0.0
    for j in range(nm):
        for b in range(nb):
            rhs[j, b] = p[j, b] - Z[j, b] * sqd[j, b] - Kl[j, b] * sq[j, b]
    for i in range(nm):
        for b in range(nb):
            qdd[i, b] = 0.0
        for j in range(nm):
            for b in range(nb):
                qdd[i, b] += rhs[j, b] * minv[cl[b], r, j, i]


@njit(cache=True, inline="always")
def contact_forces(rows, r, k, l0, vehicles, qdd, g, cmin, t1, contact):
    """Wheel-rail contact force of every axle on the bridge at half-step row ``r`` (stage 0 of step
    ``k``), ``F_i = G_i - m_w,i w''_i`` (Eq. 7 with the wheel acceleration of Eq. 9: ``g`` from
    :func:`bridge_accelerations` less ``m_w,i sum_j phi_j(x_i) qdd_j``), compression positive
    (``InProcessRun.contact_forces_n``). The smallest per lane is folded into ``cmin`` (n_lanes of
    the block); the first tension of lane ``l0 + b`` is recorded in ``contact`` (:class:`Contact`)."""
    ptr = rows.ptr
    axle = rows.axle
    phi = rows.phi
    wheel_mass = vehicles.wheel_mass_kg
    nm, nb = qdd.shape
    e0 = ptr[r]
    e1 = ptr[r + 1]
    for e in range(e0, e1):
        a = axle[e]
        for b in range(nb):
            t1[b] = 0.0
        for j in range(nm):
            pj = phi[e, j]
            for b in range(nb):
                t1[b] += qdd[j, b] * pj
        mwa = wheel_mass[a]
        lost = False
        for b in range(nb):
            fc = g[a, b] - mwa * t1[b]
            t1[b] = fc
            if fc < 0.0:
                lost = True
            cmin[b] = min(cmin[b], fc)
        if lost:  # rare: the first tension of each lane, at this step and axle
            for b in range(nb):
                if t1[b] < 0.0 and contact.first_k[l0 + b] < 0:
                    contact.first_k[l0 + b] = k
                    contact.first_axle[l0 + b] = a
                    contact.first_n[l0 + b] = t1[b]


@njit(cache=True, inline="always")
def midspan_acceleration(qdd, phi_mid, acc):
    """Midspan acceleration ``acc = phi_mid qdd`` (n_lanes,) (``BridgeSide.last_acc``)."""
    nm, nb = qdd.shape
    for b in range(nb):
        acc[b] = 0.0
    for j in range(nm):
        pm = phi_mid[j]
        for b in range(nb):
            acc[b] += qdd[j, b] * pm


@njit(cache=True, inline="always")
def dense_maxima(k, l0, acc, d, vel, h, amax, prev):
    """Dense maxima of a block (lanes ``l0 ..``) at step ``k`` (``_BridgeRun._take_acc``): the
    largest |acceleration| between steps ``k - 1`` and ``k`` from the dense output
    (:func:`hermite_max_abs_acc`) folded into ``amax``; ``prev`` (3, n_lanes) then carries the
    midspan deflection ``d``, velocity ``vel`` and acceleration ``acc`` to the next step."""
    nb = acc.shape[0]
    for b in range(nb):
        lb = l0 + b
        if k > 0:
            inner = hermite_max_abs_acc(prev[0, lb], prev[1, lb], prev[2, lb], d[b], vel[b], acc[b], h[b])
            if inner > amax[b]:
                amax[b] = inner
        prev[0, lb] = d[b]
        prev[1, lb] = vel[b]
        prev[2, lb] = acc[b]


# ---------------------------------------------------------------------- the whole-run kernels
#: Lanes of one chunk of :func:`mlm_blocks` at most: a sweep's 191 lanes run as 3 chunks of <= 64,
#: whose arrays stay in the first-level cache (0.74-0.90x the CPU of one block of 191).
MLM_CHUNK_LANES = 64


@njit(cache=True, inline="always")
def sampled_maxima(acc, d, amax, dmax):
    """Fold |acceleration| ``acc`` and |deflection| ``d`` (nb,) of stage 0 into the running maxima
    (``_BridgeRun``: the sampled maxima of every step)."""
    for b in range(acc.shape[0]):
        if abs(acc[b]) > amax[b]:
            amax[b] = abs(acc[b])
        if abs(d[b]) > dmax[b]:
            dmax[b] = abs(d[b])


@njit(cache=True, inline="always")
def same_steps_run(blocks, bi):
    """End ``be`` of the run of blocks ``bi .. be - 1`` that have block ``bi``'s number of steps (the
    bridges of one span in a batch, as a rule): :func:`dim_blocks` advances them as one."""
    n_blocks = blocks.ptr.shape[0] - 1
    be = bi + 1
    while be < n_blocks and blocks.steps[be] == blocks.steps[bi]:
        be += 1
    return be


@njit(cache=True, inline="always")
def lane_tables(blocks, bi, be, lanes, bridge):
    """Per lane of the blocks ``bi .. be - 1`` (n_lanes of the run, from lane ``blocks.ptr[bi]``): the
    bridge ``cl``, its modal stiffness ``Kl`` (n_modes, n_lanes), speed ``vl``, time step ``hl`` and
    modal damping ``Zl`` (n_modes, n_lanes), copies laid out lane-innermost."""
    l0 = blocks.ptr[bi]
    nb = blocks.ptr[be] - l0
    nm = bridge.K.shape[1]
    cl = np.empty(nb, np.int64)
    for g in range(bi, be):
        for b in range(blocks.ptr[g] - l0, blocks.ptr[g + 1] - l0):
            cl[b] = blocks.case[g]
    Kl = np.empty((nm, nb))
    Zl = np.empty((nm, nb))
    for j in range(nm):
        for b in range(nb):
            Kl[j, b] = bridge.K[cl[b], j]
            Zl[j, b] = lanes.Z[l0 + b, j]
    return cl, Kl, lanes.v[l0:l0 + nb].copy(), lanes.h[l0:l0 + nb].copy(), Zl


@njit(cache=True, inline="always")
def scratch(n, nb):
    """Five zeroed work arrays (n, nb) of one subsystem: its stage state ``sx``, ``sxd``, the RK4
    sums ``ax``, ``axd`` and the stage derivative ``sxdd``."""
    return np.zeros((n, nb)), np.zeros((n, nb)), np.zeros((n, nb)), np.zeros((n, nb)), np.zeros((n, nb))


@njit(cache=True, inline="always")
def rk4_push(st, i0, i1, h, x, xd, sx, sxd, sxdd, ax, axd):
    """RK4 bookkeeping of rows ``i0 .. i1 - 1`` of one subsystem at stage ``st`` (``_Rk4State.push``):
    the weighted sums ``ax``, ``axd`` take the stage derivative ``(sxd, sxdd)``; then the next
    stage's state ``sx``, ``sxd`` or, after stage 3, the step's new state ``x``, ``xd`` (n, n_lanes)."""
    nb = h.shape[0]
    wgt = RK4_W[st]
    cst = RK4_C[st + 1] if st < 3 else 0.0
    for i in range(i0, i1):
        for b in range(nb):
            if st == 0:
                ax[i, b] = wgt * sxd[i, b]
                axd[i, b] = wgt * sxdd[i, b]
            else:
                ax[i, b] = ax[i, b] + wgt * sxd[i, b]
                axd[i, b] = axd[i, b] + wgt * sxdd[i, b]
        if st < 3:
            for b in range(nb):
                cc = cst * h[b]
                x_new = x[i, b] + cc * sxd[i, b]
                sxd[i, b] = xd[i, b] + cc * sxdd[i, b]
                sx[i, b] = x_new
        else:
            for b in range(nb):
                x[i, b] = x[i, b] + h[b] * ax[i, b]
                xd[i, b] = xd[i, b] + h[b] * axd[i, b]


@njit(cache=True, inline="always")
def rk4_push_units(st, vehicles, units, a0, a1, h, u, ud, su, sud, udd, au, aud):
    """:func:`rk4_push` of the degrees of freedom of the active units ``units[a0:a1]``."""
    dof0 = vehicles.unit_dof0
    ndof = vehicles.unit_ndof
    for ia in range(a0, a1):
        un = units[ia]
        rk4_push(st, dof0[un], dof0[un] + ndof[un], h, u, ud, su, sud, udd, au, aud)


@njit(cache=True, inline="always")
def _put_columns(dst, src, l0):
    """``dst[:, l0:l0 + n] = src`` (n = ``src.shape[1]``), element by element."""
    for i in range(src.shape[0]):
        for b in range(src.shape[1]):
            dst[i, l0 + b] = src[i, b]


@njit(cache=True, inline="always")
def put_lanes(state, contact, l0, q, qd, u, ud, amax, dmax, cmin):
    """Write a run's state, maxima and smallest contact force back at lanes ``l0 ..``. Element by element:
    a slice assignment would compile numba's shape-mismatch error (its string formatting, about 5 s of
    the first compile) for copies whose shapes match by construction."""
    nb = amax.shape[0]
    _put_columns(state.q, q, l0)
    _put_columns(state.qd, qd, l0)
    _put_columns(state.u, u, l0)
    _put_columns(state.ud, ud, l0)
    for b in range(nb):
        state.max_acc[l0 + b] = amax[b]
        state.max_disp[l0 + b] = dmax[b]
        contact.min_n[l0 + b] = cmin[b]


@njit(cache=True, nogil=True)
def dim_blocks(blocks, k0, k1, lanes, bridge, rows, units, vehicles, state, dense, track, contact):
    """DIM (Eqs. 7-17) with one exchange per RK stage, every lane over all its steps.

    ``blocks`` (:class:`Blocks`); ``lanes`` (:class:`DimLanes`); ``bridge``
    (:class:`adm_sim.integrate.tables.BridgeTables`); ``rows`` (:class:`adm_sim.integrate.tables.AxleRows` of
    every half-step row from 0, with ``minv``); ``units`` (:class:`adm_sim.integrate.tables.ActiveUnits` of
    every step from 0); ``vehicles`` (:class:`adm_sim.integrate.tables.VehicleTables`); ``track``
    (:class:`Track`, zeros: smooth); ``contact`` (:class:`Contact`), updated in place. Consecutive
    blocks with the same step count (:func:`same_steps_run`) advance together, innermost, each lane
    with its own bridge's stiffness and Eq. (13) inverses (:func:`lane_tables`): every inner loop
    runs over one long run of contiguous lanes (SIMD; per lane the same operations in the same order
    as block by block, ~2.4x faster for 6 bridges x 8 speeds, ``bench/bench_kernels.py``). A stage is
    the numpy stepper's, helper by helper: :func:`rail_state`, :func:`vehicle_accelerations`,
    :func:`bridge_accelerations`, (stage 0) :func:`midspan_acceleration` and :func:`contact_forces`,
    then :func:`rk4_push` of both subsystems; a step starts with :func:`start_step` and ends with the
    maxima (:func:`sampled_maxima`, :func:`dense_maxima` with ``dense``).

    Resumable: advances every lane from step ``k0`` to ``min(k1, its block's steps)``; ``state``
    (:class:`LaneState`) is updated in place, so chunks give bit for bit what one call gives.
    """
    nm = bridge.K.shape[1]
    n_dof = vehicles.minv_dof.shape[0]
    n_axles = vehicles.axle_load_n.shape[0]
    act_ptr = units.ptr
    act_units = units.units
    n_blocks = blocks.ptr.shape[0] - 1
    be = 0
    while be < n_blocks:
        bi = be
        be = same_steps_run(blocks, bi)
        l0 = blocks.ptr[bi]
        nb = blocks.ptr[be] - l0
        k_end = min(k1, blocks.steps[bi])
        if k0 >= k_end:
            continue
        cl, Kl, vl, hl, Zl = lane_tables(blocks, bi, be, lanes, bridge)
        q = state.q[:, l0:l0 + nb].copy()
        qd = state.qd[:, l0:l0 + nb].copy()
        u = state.u[:, l0:l0 + nb].copy()
        ud = state.ud[:, l0:l0 + nb].copy()
        amax = state.max_acc[l0:l0 + nb].copy()
        dmax = state.max_disp[l0:l0 + nb].copy()
        cmin = contact.min_n[l0:l0 + nb].copy()
        sq, sqd, aq, aqd, qdd = scratch(nm, nb)
        su, sud, au, aud, udd = scratch(n_dof, nb)
        W, Wd, f, g = np.zeros((n_axles, nb)), np.zeros((n_axles, nb)), np.zeros((n_axles, nb)), np.zeros((n_axles, nb))
        p, rhs = np.zeros((nm, nb)), np.zeros((nm, nb))
        t1, t2, t3, acc0, d, vel = np.zeros(nb), np.zeros(nb), np.zeros(nb), np.zeros(nb), np.zeros(nb), np.zeros(nb)
        for k in range(k0, k_end):
            a0 = act_ptr[k]
            a1 = act_ptr[k + 1]
            start_step(q, qd, bridge.phi_mid, d, vel, sq, sqd)
            start_units(vehicles, act_units, a0, a1, u, ud, su, sud)
            for st in range(4):
                r = 2 * k + STAGE_ROW[st]
                rail_state(rows, r, sq, sqd, vl, W, Wd, t1, t2, t3, track)
                vehicle_accelerations(vehicles, act_units, a0, a1, su, sud, W, Wd, f, udd, t1, t2, t3)
                bridge_accelerations(rows, r, cl, Kl, vehicles, sq, sqd, vl, Zl, f, W, Wd, p, rhs, qdd,
                                     t1, t2, t3, track, g)
                if st == 0:
                    midspan_acceleration(qdd, bridge.phi_mid, acc0)
                    contact_forces(rows, r, k, l0, vehicles, qdd, g, cmin, t1, contact)
                rk4_push(st, 0, nm, hl, q, qd, sq, sqd, qdd, aq, aqd)
                rk4_push_units(st, vehicles, act_units, a0, a1, hl, u, ud, su, sud, udd, au, aud)
            sampled_maxima(acc0, d, amax, dmax)
            if dense:
                dense_maxima(k, l0, acc0, d, vel, hl, amax, state.prev)
        put_lanes(state, contact, l0, q, qd, u, ud, amax, dmax, cmin)


@njit(cache=True, inline="always")
def mlm_chunk_width(n_lanes):
    """Lanes per chunk of a block of ``n_lanes``: balanced chunks of at most :data:`MLM_CHUNK_LANES`,
    rounded up to a multiple of 8."""
    n_chunks = (n_lanes + MLM_CHUNK_LANES - 1) // MLM_CHUNK_LANES
    width = (n_lanes + n_chunks - 1) // n_chunks
    return min((width + 7) // 8 * 8, MLM_CHUNK_LANES)


@njit(cache=True, inline="always")
def mlm_coefficients(lanes, l0, nb, nm):
    """The chunk's copy ``cf`` (11, n_modes, nb) of ``Z`` and the RK4 recurrence ``ax, axd, bx, bxd,
    c0, c0d, ch, chd, c1, c1d`` of lanes ``l0 .. l0 + nb - 1`` (:class:`MlmLanes`)."""
    cf = np.empty((11, nm, nb))
    for i, arr in enumerate((lanes.Z, lanes.ax, lanes.axd, lanes.bx, lanes.bxd, lanes.c0, lanes.c0d, lanes.ch,
                             lanes.chd, lanes.c1, lanes.c1d)):
        for j in range(nm):
            for b in range(nb):
                cf[i, j, b] = arr[j, l0 + b]
    return cf


@njit(cache=True, inline="always")
def mlm_take(state, l0, nb, nm):
    """The chunk's copies: ``s`` (2, n_modes, nb) of ``q``, ``qd``; ``o`` (5, nb): midspan deflection,
    velocity, acceleration (zeros) and the running maxima of |acceleration|, |deflection|."""
    s = np.empty((2, nm, nb))
    for j in range(nm):
        for b in range(nb):
            s[0, j, b] = state.q[j, l0 + b]
            s[1, j, b] = state.qd[j, l0 + b]
    o = np.zeros((5, nb))
    for b in range(nb):
        o[3, b] = state.max_acc[l0 + b]
        o[4, b] = state.max_disp[l0 + b]
    return s, o


@njit(cache=True, inline="always")
def mlm_put(s, o, state, l0):
    """Write the chunk's state and maxima (:func:`mlm_take`) back at lanes ``l0 ..``."""
    nm, nb = s.shape[1], s.shape[2]
    for j in range(nm):
        for b in range(nb):
            state.q[j, l0 + b] = s[0, j, b]
            state.qd[j, l0 + b] = s[1, j, b]
    for b in range(nb):
        state.max_acc[l0 + b] = o[3, b]
        state.max_disp[l0 + b] = o[4, b]


@njit(cache=True, inline="always")
def mlm_step(k, c, P, bridge, cf, s, o):
    """``BridgeSide.step_mlm`` (Eq. 12) of a chunk on bridge ``c``: midspan deflection, velocity and
    acceleration at step ``k`` into ``o[0:3]``, then the exact RK4 recurrence with the modal loads of
    rows 2k, 2k + 1, 2k + 2 of ``P``."""
    K = bridge.K
    M = bridge.M
    phi_mid = bridge.phi_mid
    nm, nb = s.shape[1], s.shape[2]
    for b in range(nb):
        o[0, b] = 0.0
        o[1, b] = 0.0
        o[2, b] = 0.0
    for j in range(nm):
        p0, ph, p1 = P[2 * k, j], P[2 * k + 1, j], P[2 * k + 2, j]
        kj, mj, pm = K[c, j], M[c, j], phi_mid[j]
        for b in range(nb):
            x = s[0, j, b]
            xd = s[1, j, b]
            o[0, b] += x * pm
            o[1, b] += xd * pm
            o[2, b] += ((p0 - cf[0, j, b] * xd - kj * x) / mj) * pm
            s[0, j, b] = cf[1, j, b] * x + cf[3, j, b] * xd + cf[5, j, b] * p0 + cf[7, j, b] * ph + cf[9, j, b] * p1
            s[1, j, b] = (cf[2, j, b] * x + cf[4, j, b] * xd + cf[6, j, b] * p0 + cf[8, j, b] * ph
                          + cf[10, j, b] * p1)


@njit(cache=True, nogil=True)
def mlm_blocks(blocks, k0, k1, lanes, bridge, P, state, dense):
    """MLM (Eq. 12) by the exact RK4 recurrence of every lane-mode oscillator.

    ``P`` (2 n + 1, n_modes) modal loads on the half-step grid (shared); ``bridge``
    (:class:`adm_sim.integrate.tables.BridgeTables`); ``lanes`` (:class:`MlmLanes`), ``blocks`` and
    ``state`` as in :func:`dim_blocks` (``state.u``, ``state.ud`` unused). A step is
    :func:`mlm_step` then the maxima (:func:`sampled_maxima`, :func:`dense_maxima` with ``dense``);
    resumable as :func:`dim_blocks`.

    Each block advances in chunks of at most :data:`MLM_CHUNK_LANES` lanes (:func:`mlm_chunk_width`),
    each on copies made inside the kernel (:func:`mlm_coefficients`, :func:`mlm_take`): arrays the
    compiler knows to be distinct, so the loop over the chunk's lanes is vectorised (SIMD) with the
    same operations per lane in the same order (bit for bit the loop over the lanes' own arrays, ~6x
    faster; ``bench/bench_kernels.py``), and a chunk's arrays stay in the first-level cache (a
    sweep's 191 lanes as 3 chunks of <= 64: 0.74-0.90x the CPU of one block, docs/benchmarks.md).
    """
    nm = P.shape[1]
    block_ptr = blocks.ptr
    for bi in range(block_ptr.shape[0] - 1):
        c = blocks.case[bi]
        k_end = min(k1, blocks.steps[bi])
        if k0 >= k_end:
            continue
        width = mlm_chunk_width(block_ptr[bi + 1] - block_ptr[bi])
        for l0 in range(block_ptr[bi], block_ptr[bi + 1], width):
            l1 = min(l0 + width, block_ptr[bi + 1])
            nb = l1 - l0
            cf = mlm_coefficients(lanes, l0, nb, nm)
            s, o = mlm_take(state, l0, nb, nm)
            hl = lanes.h[l0:l1].copy()
            for k in range(k0, k_end):
                mlm_step(k, c, P, bridge, cf, s, o)
                sampled_maxima(o[2], o[0], o[3], o[4])
                if dense:
                    dense_maxima(k, l0, o[2], o[0], o[1], hl, o[3], state.prev)
            mlm_put(s, o, state, l0)


# ---------------------------------------------------------------------- the MLM loads of a continuous deck
class DeckShapes(NamedTuple):
    """The mode shapes of a continuous deck as :class:`adm_sim.model.spans.DeckModes` holds them:
    support abscissae ``supports`` (n_spans + 1,) (m), wave numbers ``beta`` (n_modes, n_spans)
    (1/m), coefficients ``coef`` (n_modes, n_spans, 4) of ``sin, cos, exp(-beta xi),
    exp(-beta (L - xi))``, and ``exp_bl = exp(-beta L)`` (n_modes, n_spans) per span."""

    supports: np.ndarray
    beta: np.ndarray
    coef: np.ndarray
    exp_bl: np.ndarray


def deck_shapes(modes):
    """:class:`DeckShapes` of a :class:`adm_sim.model.spans.DeckModes`."""
    beta = np.ascontiguousarray(modes.beta_1_m, dtype=float)
    return DeckShapes(np.ascontiguousarray(modes.supports_m, dtype=float), beta,
                      np.ascontiguousarray(modes.coef, dtype=float), np.exp(-beta * modes.spans_m[None, :]))


@njit(cache=True, nogil=True)
def add_deck_loads(out, r0, x, load, shapes):
    """Add one axle's modal loads (Eq. 6) ``load * phi_j(x[e])`` to rows ``r0 + e`` of ``out``
    (n_rows, n_modes), ``x`` (n,) its positions on the deck (m from the left abutment, increasing).

    ``phi_j`` is :meth:`adm_sim.model.spans.DeckModes.phi` entry by entry, the same expression in the
    same order (``c0 sin(b xi) + c1 cos(b xi) + c2 e^(-b xi) + c3 e^(-b L) / e^(-b xi)``), compiled:
    no gathered (n, n_modes, 4) temporaries, ``e^(-b L)`` once per span (``shapes.exp_bl``); agrees
    with it to a few units of round-off (``tests/integrate/test_deck_loads.py``)."""
    sup = shapes.supports
    beta = shapes.beta
    coef = shapes.coef
    ebl = shapes.exp_bl
    nm, n_spans = beta.shape
    i = 0
    for e in range(x.size):
        xe = x[e]
        while i < n_spans - 1 and xe >= sup[i + 1]:  # the span (searchsorted right, clipped)
            i += 1
        xi = xe - sup[i]
        for j in range(nm):
            bx = beta[j, i] * xi
            e0 = np.exp(-bx)
            ph = (coef[j, i, 0] * np.sin(bx) + coef[j, i, 1] * np.cos(bx) + coef[j, i, 2] * e0
                  + coef[j, i, 3] * (ebl[j, i] / e0))
            out[r0 + e, j] += ph * load
