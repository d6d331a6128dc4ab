"""Compiled whole-run kernels: every lane of a batch integrated over all its steps in one call.

These are the per-stage computations of :class:`adm_sim.stepping.BridgeSide` and
:class:`adm_sim.stepping.TrainSide` (same equations, same RK4 bookkeeping, same operation order),
written as loops over lanes and steps so that numba compiles them: the Python overhead of ~40
small numpy calls per RK stage (~100 us) disappears, and a lane costs only its arithmetic.
Each lane carries its own bridge (modal stiffness, damping, the wheelset-modified mass matrix of
Eq. 13) and its own number of steps; the span, the space step ``ds`` and the train are shared,
so the axles on the bridge and the mode shapes under them are tabulated once per batch.

One source: without numba the same functions run as plain Python (slow, for debugging).
The numpy stepper stays the reference (the ROS nodes use it); ``tests/test_batch.py`` holds the
two together to 1e-12 relative.
"""

from __future__ import annotations

import numpy as np

# numba compiles these loops; the plain-Python path is the same source (adm_sim._jit.njit)
from adm_sim._jit import RK4_C_ARRAY as RK4_C
from adm_sim._jit import RK4_W_ARRAY as RK4_W
from adm_sim._jit import STAGE_ROW, njit


@njit(cache=True, inline="always")
def hermite_max_abs_acc(d0, v0, a0, d1, v1, a1, h):
    """Largest |acceleration| strictly inside one step from the dense output, 0 if none.

    One lane, scalar arithmetic of :func:`adm_sim.stepping.hermite_max_abs_acc` operation for
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


@njit(cache=True, nogil=True)
def dim_blocks(block_ptr, block_case, block_steps, k0, k1, v, h, K, Z, minv, phi_mid,
               row_ptr, ent_axle, ent_phi, ent_phx, ent_phxx,
               axle_load, wheel_mass,
               act_ptr, act_units, unit_dof0, unit_ndof, unit_ax0, unit_nax,
               ks_ptr, ks_col, ks_val, cs_ptr, cs_col, cs_val,
               lw_ptr, lw_col, lw_val, lwt_ptr, lwt_col, lwt_val, kp, cp, minv_dof,
               q_s, qd_s, u_s, ud_s, max_acc, max_disp, dense, prev_s):
    """DIM (Eqs. 7-17) with one exchange per RK stage, every lane over all its steps.

    Lanes ``block_ptr[i]..block_ptr[i+1]`` (same bridge ``block_case[i]``, same number of steps
    ``block_steps[i]``) advance together, innermost, so every inner loop runs over contiguous lanes
    and compiles to SIMD instructions; each lane's arithmetic is that of ``BridgeSide``/``TrainSide``
    in the same order. Bridge: ``K`` (n_cases, n_modes), ``Z`` (n_lanes, n_modes), ``minv``
    (n_cases, n_rows, n_modes, n_modes) the inverse modified mass matrix (Eq. 13) per half-step
    row; the axles on the bridge per row as CSR (``row_ptr``, ``ent_axle``) with their mode shapes
    ``ent_phi``, ``ent_phx``, ``ent_phxx`` (n_ent, n_modes). Train: units active per step as CSR
    (``act_ptr``, ``act_units``), unit DOF/axle ranges, the secondary stage ``K_s``, ``C_s``, the
    DOF-to-bogie-point map ``Lw`` and its transpose as CSR, primary ``kp``, ``cp`` per axle,
    ``minv_dof`` the inverse diagonal vehicle masses.

    Resumable: advances every lane from step ``k0`` to ``min(k1, its block's steps)``. The state
    lives in the caller's arrays, lanes in block order: modal ``q_s``, ``qd_s`` (n_modes,
    n_lanes), vehicle ``u_s``, ``ud_s`` (n_dof, n_lanes), and the running maxima of |midspan
    acceleration| (stage 0 of every step) ``max_acc`` and |deflection| (start of every step)
    ``max_disp`` (n_lanes,), updated in place. With ``dense``, the maxima between the steps from
    the dense output (:func:`hermite_max_abs_acc`) are folded in too; ``prev_s`` (3, n_lanes)
    carries the midspan deflection, velocity and acceleration of the last step done (as
    ``InProcessRun._prev``). Chunks give bit for bit what one call gives.
    """
    nm = K.shape[1]
    n_dof = minv_dof.shape[0]
    n_axles = axle_load.shape[0]
    for bi in range(block_ptr.shape[0] - 1):
        l0 = block_ptr[bi]
        nb = block_ptr[bi + 1] - l0
        c = block_case[bi]
        vl = v[l0:l0 + nb].copy()
        hl = h[l0:l0 + nb].copy()
        Zb = np.empty((nm, nb))
        for j in range(nm):
            for b in range(nb):
                Zb[j, b] = Z[l0 + b, j]
        k_end = min(k1, block_steps[bi])
        if k0 >= k_end:
            continue
        q = q_s[:, l0:l0 + nb].copy()
        qd = qd_s[:, l0:l0 + nb].copy()
        sq = np.zeros((nm, nb))
        sqd = np.zeros((nm, nb))
        aq = np.zeros((nm, nb))
        aqd = np.zeros((nm, nb))
        qdd = np.zeros((nm, nb))
        p = np.zeros((nm, nb))
        rhs = np.zeros((nm, nb))
        u = u_s[:, l0:l0 + nb].copy()
        ud = ud_s[:, l0:l0 + nb].copy()
        su = np.zeros((n_dof, nb))
        sud = np.zeros((n_dof, nb))
        au = np.zeros((n_dof, nb))
        aud = np.zeros((n_dof, nb))
        udd = np.zeros((n_dof, nb))
        W = np.zeros((n_axles, nb))
        Wd = np.zeros((n_axles, nb))
        f = np.zeros((n_axles, nb))
        t1 = np.zeros(nb)
        t2 = np.zeros(nb)
        t3 = np.zeros(nb)
        acc0 = np.zeros(nb)
        d = np.zeros(nb)
        amax = max_acc[l0:l0 + nb].copy()
        dmax = max_disp[l0:l0 + nb].copy()
        vel = np.zeros(nb)
        for k in range(k0, k_end):
            d[:] = 0.0
            vel[:] = 0.0
            for j in range(nm):
                for b in range(nb):
                    d[b] += q[j, b] * phi_mid[j]
                    vel[b] += qd[j, b] * phi_mid[j]
                    sq[j, b] = q[j, b]
                    sqd[j, b] = qd[j, b]
            a0 = act_ptr[k]
            a1 = act_ptr[k + 1]
            for ia in range(a0, a1):
                un = act_units[ia]
                for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                    for b in range(nb):
                        su[dd, b] = u[dd, b]
                        sud[dd, b] = ud[dd, b]
            acc0[:] = 0.0
            for st in range(4):
                r = 2 * k + STAGE_ROW[st]
                e0 = row_ptr[r]
                e1 = row_ptr[r + 1]
                # 1. bridge -> train: rail displacement and velocity under the axles (Eqs. 4, 9)
                for e in range(e0, e1):
                    a = ent_axle[e]
                    t1[:] = 0.0
                    t2[:] = 0.0
                    t3[:] = 0.0
                    for j in range(nm):
                        pj = ent_phi[e, j]
                        xj = ent_phx[e, j]
                        for b in range(nb):
                            t1[b] += sq[j, b] * pj
                            t2[b] += sqd[j, b] * pj
                            t3[b] += sq[j, b] * xj
                    for b in range(nb):
                        W[a, b] = t1[b]
                        Wd[a, b] = t2[b] + vl[b] * t3[b]
                # 2. train: primary stage forces and vehicle accelerations (Eq. 11)
                for ia in range(a0, a1):
                    un = act_units[ia]
                    for ax_ in range(unit_ax0[un], unit_ax0[un] + unit_nax[un]):
                        t1[:] = 0.0
                        t2[:] = 0.0
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
                    for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                        t1[:] = 0.0
                        t2[:] = 0.0
                        t3[:] = 0.0
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
                # 3. train -> bridge: G = F - F_k1 - F_c1 (Eq. 7), modified load (Eq. 14)
                p[:, :] = 0.0
                for e in range(e0, e1):
                    a = ent_axle[e]
                    t1[:] = 0.0
                    t2[:] = 0.0
                    for j in range(nm):
                        xj = ent_phx[e, j]
                        xxj = ent_phxx[e, j]
                        for b in range(nb):
                            t1[b] += sqd[j, b] * xj
                            t2[b] += sq[j, b] * xxj
                    fa = axle_load[a]
                    mwa = wheel_mass[a]
                    for b in range(nb):
                        t3[b] = (fa - f[a, b]) - mwa * (2.0 * vl[b] * t1[b] + vl[b] * vl[b] * t2[b])
                    for j in range(nm):
                        pj = ent_phi[e, j]
                        for b in range(nb):
                            p[j, b] += t3[b] * pj
                    for b in range(nb):
                        W[a, b] = 0.0
                        Wd[a, b] = 0.0
                for j in range(nm):
                    kj = K[c, j]
                    for b in range(nb):
                        rhs[j, b] = p[j, b] - Zb[j, b] * sqd[j, b] - kj * sq[j, b]
                for i in range(nm):
                    for b in range(nb):
                        qdd[i, b] = 0.0
                    for j in range(nm):
                        mji = minv[c, r, j, i]
                        for b in range(nb):
                            qdd[i, b] += rhs[j, b] * mji
                if st == 0:
                    for j in range(nm):
                        pm = phi_mid[j]
                        for b in range(nb):
                            acc0[b] += qdd[j, b] * pm
                # 4. RK4 bookkeeping of both subsystems (as stepping._Rk4State.push)
                wgt = RK4_W[st]
                for j in range(nm):
                    for b in range(nb):
                        if st == 0:
                            aq[j, b] = wgt * sqd[j, b]
                            aqd[j, b] = wgt * qdd[j, b]
                        else:
                            aq[j, b] = aq[j, b] + wgt * sqd[j, b]
                            aqd[j, b] = aqd[j, b] + wgt * qdd[j, b]
                for ia in range(a0, a1):
                    un = act_units[ia]
                    for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                        for b in range(nb):
                            if st == 0:
                                au[dd, b] = wgt * sud[dd, b]
                                aud[dd, b] = wgt * udd[dd, b]
                            else:
                                au[dd, b] = au[dd, b] + wgt * sud[dd, b]
                                aud[dd, b] = aud[dd, b] + wgt * udd[dd, b]
                if st < 3:
                    cst = RK4_C[st + 1]
                    for j in range(nm):
                        for b in range(nb):
                            cc = cst * hl[b]
                            x_new = q[j, b] + cc * sqd[j, b]
                            sqd[j, b] = qd[j, b] + cc * qdd[j, b]
                            sq[j, b] = x_new
                    for ia in range(a0, a1):
                        un = act_units[ia]
                        for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                            for b in range(nb):
                                cc = cst * hl[b]
                                x_new = u[dd, b] + cc * sud[dd, b]
                                sud[dd, b] = ud[dd, b] + cc * udd[dd, b]
                                su[dd, b] = x_new
                else:
                    for j in range(nm):
                        for b in range(nb):
                            q[j, b] = q[j, b] + hl[b] * aq[j, b]
                            qd[j, b] = qd[j, b] + hl[b] * aqd[j, b]
                    for ia in range(a0, a1):
                        un = act_units[ia]
                        for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                            for b in range(nb):
                                u[dd, b] = u[dd, b] + hl[b] * au[dd, b]
                                ud[dd, b] = ud[dd, b] + hl[b] * aud[dd, b]
            for b in range(nb):
                if abs(acc0[b]) > amax[b]:
                    amax[b] = abs(acc0[b])
                if abs(d[b]) > dmax[b]:
                    dmax[b] = abs(d[b])
            if dense:
                for b in range(nb):
                    lb = l0 + b
                    if k > 0:
                        inner = hermite_max_abs_acc(prev_s[0, lb], prev_s[1, lb], prev_s[2, lb],
                                                    d[b], vel[b], acc0[b], hl[b])
                        if inner > amax[b]:
                            amax[b] = inner
                    prev_s[0, lb] = d[b]
                    prev_s[1, lb] = vel[b]
                    prev_s[2, lb] = acc0[b]
        q_s[:, l0:l0 + nb] = q
        qd_s[:, l0:l0 + nb] = qd
        u_s[:, l0:l0 + nb] = u
        ud_s[:, l0:l0 + nb] = ud
        max_acc[l0:l0 + nb] = amax
        max_disp[l0:l0 + nb] = dmax


@njit(cache=True, nogil=True)
def mlm_blocks(block_ptr, block_case, block_steps, k0, k1, P, phi_mid, M, K, Z, ax, axd, bx, bxd, c0, c0d,
               ch, chd, c1, c1d, q_s, qd_s, max_acc, max_disp, dense, h, prev_s):
    """MLM (Eq. 12) by the exact RK4 recurrence of every lane-mode oscillator.

    ``P`` (2 n + 1, n_modes) modal loads on the half-step grid (shared); ``M``, ``K`` (n_cases,
    n_modes); ``Z`` and the recurrence coefficients of
    :func:`adm_sim.stepping.mlm_rk4_coefficients` per lane, transposed to (n_modes, n_lanes) so
    that the inner loops over the lanes of a block (one bridge, one step count) are contiguous.
    Same arithmetic as :meth:`BridgeSide.step_mlm`, operation for operation. Resumable as
    :func:`dim_blocks`: steps ``k0 .. min(k1, block steps) - 1``, state ``q_s``, ``qd_s``
    (n_modes, n_lanes) and the running maxima ``max_acc``, ``max_disp`` updated in place;
    ``dense``, ``h`` (time step per lane, lane order) and ``prev_s`` as in :func:`dim_blocks`.
    """
    nm = P.shape[1]
    for bi in range(block_ptr.shape[0] - 1):
        l0 = block_ptr[bi]
        l1 = block_ptr[bi + 1]
        nb = l1 - l0
        c = block_case[bi]
        k_end = min(k1, block_steps[bi])
        if k0 >= k_end:
            continue
        q = q_s[:, l0:l1].copy()
        qd = qd_s[:, l0:l1].copy()
        d = np.zeros(nb)
        a = np.zeros(nb)
        vel = np.zeros(nb)
        amax = max_acc[l0:l1].copy()
        dmax = max_disp[l0:l1].copy()
        for k in range(k0, k_end):
            d[:] = 0.0
            a[:] = 0.0
            vel[:] = 0.0
            for j in range(nm):
                p0, ph, p1 = P[2 * k, j], P[2 * k + 1, j], P[2 * k + 2, j]
                kj, mj, pm = K[c, j], M[c, j], phi_mid[j]
                for b in range(nb):
                    lb = l0 + b
                    x = q[j, b]
                    xd = qd[j, b]
                    d[b] += x * pm
                    vel[b] += xd * pm
                    a[b] += ((p0 - Z[j, lb] * xd - kj * x) / mj) * pm
                    q[j, b] = ax[j, lb] * x + bx[j, lb] * xd + c0[j, lb] * p0 + ch[j, lb] * ph + c1[j, lb] * p1
                    qd[j, b] = axd[j, lb] * x + bxd[j, lb] * xd + c0d[j, lb] * p0 + chd[j, lb] * ph + c1d[j, lb] * p1
            for b in range(nb):
                if abs(a[b]) > amax[b]:
                    amax[b] = abs(a[b])
                if abs(d[b]) > dmax[b]:
                    dmax[b] = abs(d[b])
            if dense:
                for b in range(nb):
                    lb = l0 + b
                    if k > 0:
                        inner = hermite_max_abs_acc(prev_s[0, lb], prev_s[1, lb], prev_s[2, lb],
                                                    d[b], vel[b], a[b], h[lb])
                        if inner > amax[b]:
                            amax[b] = inner
                    prev_s[0, lb] = d[b]
                    prev_s[1, lb] = vel[b]
                    prev_s[2, lb] = a[b]
        q_s[:, l0:l1] = q
        qd_s[:, l0:l1] = qd
        max_acc[l0:l1] = amax
        max_disp[l0:l1] = dmax
