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

try:  # numba compiles these loops; the plain-Python path is the same source
    from numba import njit
except ImportError:  # pragma: no cover - numba is in requirements.txt
    def njit(*args, **kwargs):
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

RK4_C = np.array([0.0, 0.5, 0.5, 1.0])
RK4_W = np.array([1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0])
#: Half-step row offset of each RK stage: stage points s_k, s_k + ds/2 (twice), s_k + ds.
STAGE_ROW = np.array([0, 1, 1, 2])


@njit(cache=True, nogil=True)
def mlm_lanes(P, phi_mid, M, K, Z, case, n_steps, ax, axd, bx, bxd, c0, c0d, ch, chd, c1, c1d,
              max_acc, max_disp):
    """MLM (Eq. 12) by the exact RK4 recurrence of every lane-mode oscillator.

    ``P`` (2 n + 1, n_modes) modal loads on the half-step grid (shared); ``M``, ``K``
    (n_cases, n_modes); ``Z`` and the recurrence coefficients (n_lanes, n_modes); ``case`` and
    ``n_steps`` (n_lanes,). Writes the maxima of |midspan acceleration| and |deflection| over
    steps ``0..n_steps[l]-1`` (as :meth:`BridgeSide.step_mlm` and ``run_sweep``). Returns the
    number of lanes with a non-finite value.
    """
    n_lanes = case.shape[0]
    nm = P.shape[1]
    bad = 0
    q = np.zeros(nm)
    qd = np.zeros(nm)
    for l in range(n_lanes):
        c = case[l]
        q[:] = 0.0
        qd[:] = 0.0
        amax = 0.0
        dmax = 0.0
        finite = True
        for k in range(n_steps[l]):
            d = 0.0
            a = 0.0
            for j in range(nm):
                d += q[j] * phi_mid[j]
                a += ((P[2 * k, j] - Z[l, j] * qd[j] - K[c, j] * q[j]) / M[c, j]) * phi_mid[j]
            for j in range(nm):
                p0, ph, p1 = P[2 * k, j], P[2 * k + 1, j], P[2 * k + 2, j]
                qn = ax[l, j] * q[j] + bx[l, j] * qd[j] + c0[l, j] * p0 + ch[l, j] * ph + c1[l, j] * p1
                qdn = axd[l, j] * q[j] + bxd[l, j] * qd[j] + c0d[l, j] * p0 + chd[l, j] * ph + c1d[l, j] * p1
                q[j] = qn
                qd[j] = qdn
            if not (abs(a) < np.inf and abs(d) < np.inf):
                finite = False
                break
            if abs(a) > amax:
                amax = abs(a)
            if abs(d) > dmax:
                dmax = abs(d)
        max_acc[l] = amax if finite else np.nan
        max_disp[l] = dmax if finite else np.nan
        if not finite:
            bad += 1
    return bad


@njit(cache=True, nogil=True)
def dim_lanes(v, h, case, n_steps, K, Z, minv, phi_mid,
              row_ptr, ent_axle, ent_phi, ent_phx, ent_phxx,
              axle_load, wheel_mass,
              act_ptr, act_units, unit_dof0, unit_ndof, unit_ax0, unit_nax,
              ks_ptr, ks_col, ks_val, cs_ptr, cs_col, cs_val,
              lw_ptr, lw_col, lw_val, lwt_ptr, lwt_col, lwt_val, kp, cp, minv_dof,
              max_acc, max_disp):
    """DIM (Eqs. 7-17) with one exchange per RK stage, every lane over all its steps.

    Bridge: ``K`` (n_cases, n_modes), ``Z`` (n_lanes, n_modes), ``minv`` (n_cases, n_rows,
    n_modes, n_modes) the inverse modified mass matrix (Eq. 13) per half-step row; the axles on
    the bridge per row as CSR (``row_ptr``, ``ent_axle``) with their mode shapes ``ent_phi``,
    ``ent_phx``, ``ent_phxx`` (n_ent, n_modes). Train: units active per step as CSR
    (``act_ptr``, ``act_units``), unit DOF/axle ranges, the secondary stage ``K_s``, ``C_s``,
    the DOF-to-bogie-point map ``Lw`` and its transpose as CSR, primary ``kp``, ``cp`` per axle,
    ``minv_dof`` the inverse diagonal vehicle masses. Returns the number of non-finite lanes.
    """
    n_lanes = case.shape[0]
    nm = K.shape[1]
    n_dof = minv_dof.shape[0]
    n_axles = axle_load.shape[0]
    q = np.zeros(nm)
    qd = np.zeros(nm)
    sq = np.zeros(nm)
    sqd = np.zeros(nm)
    aq = np.zeros(nm)
    aqd = np.zeros(nm)
    qdd = np.zeros(nm)
    p = np.zeros(nm)
    rhs = np.zeros(nm)
    u = np.zeros(n_dof)
    ud = np.zeros(n_dof)
    su = np.zeros(n_dof)
    sud = np.zeros(n_dof)
    au = np.zeros(n_dof)
    aud = np.zeros(n_dof)
    udd = np.zeros(n_dof)
    W = np.zeros(n_axles)
    Wd = np.zeros(n_axles)
    f = np.zeros(n_axles)
    max_ent = 0
    for r in range(row_ptr.shape[0] - 1):
        if row_ptr[r + 1] - row_ptr[r] > max_ent:
            max_ent = row_ptr[r + 1] - row_ptr[r]
    G = np.zeros(max_ent)
    bad = 0
    for l in range(n_lanes):
        c = case[l]
        vl = v[l]
        hl = h[l]
        q[:] = 0.0
        qd[:] = 0.0
        u[:] = 0.0
        ud[:] = 0.0
        amax = 0.0
        dmax = 0.0
        finite = True
        for k in range(n_steps[l]):
            d = 0.0
            for j in range(nm):
                d += q[j] * phi_mid[j]
            for j in range(nm):
                sq[j] = q[j]
                sqd[j] = qd[j]
            a0 = act_ptr[k]
            a1 = act_ptr[k + 1]
            for ia in range(a0, a1):
                un = act_units[ia]
                for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                    su[dd] = u[dd]
                    sud[dd] = ud[dd]
            acc0 = 0.0
            for st in range(4):
                r = 2 * k + STAGE_ROW[st]
                e0 = row_ptr[r]
                e1 = row_ptr[r + 1]
                # 1. bridge -> train: rail displacement and velocity under the axles (Eqs. 4, 9)
                for e in range(e0, e1):
                    w = 0.0
                    wq = 0.0
                    wx = 0.0
                    for j in range(nm):
                        w += sq[j] * ent_phi[e, j]
                        wq += sqd[j] * ent_phi[e, j]
                        wx += sq[j] * ent_phx[e, j]
                    W[ent_axle[e]] = w
                    Wd[ent_axle[e]] = wq + vl * wx
                # 2. train: primary stage forces and vehicle accelerations (Eq. 11)
                for ia in range(a0, a1):
                    un = act_units[ia]
                    for ax_ in range(unit_ax0[un], unit_ax0[un] + unit_nax[un]):
                        zb = 0.0
                        zbd = 0.0
                        for t in range(lw_ptr[ax_], lw_ptr[ax_ + 1]):
                            zb += su[lw_col[t]] * lw_val[t]
                            zbd += sud[lw_col[t]] * lw_val[t]
                        f[ax_] = kp[ax_] * (W[ax_] - zb) + cp[ax_] * (Wd[ax_] - zbd)
                    for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                        fl = 0.0
                        for t in range(lwt_ptr[dd], lwt_ptr[dd + 1]):
                            fl += f[lwt_col[t]] * lwt_val[t]
                        ks = 0.0
                        for t in range(ks_ptr[dd], ks_ptr[dd + 1]):
                            ks += su[ks_col[t]] * ks_val[t]
                        cs = 0.0
                        for t in range(cs_ptr[dd], cs_ptr[dd + 1]):
                            cs += sud[cs_col[t]] * cs_val[t]
                        udd[dd] = (fl - ks - cs) * minv_dof[dd]
                # 3. train -> bridge: G = F - F_k1 - F_c1 (Eq. 7), modified load (Eq. 14)
                for j in range(nm):
                    p[j] = 0.0
                for e in range(e0, e1):
                    ax_ = ent_axle[e]
                    G[e - e0] = axle_load[ax_] - f[ax_]
                    cx = 0.0
                    cxx = 0.0
                    for j in range(nm):
                        cx += sqd[j] * ent_phx[e, j]
                        cxx += sq[j] * ent_phxx[e, j]
                    load = G[e - e0] - wheel_mass[ax_] * (2.0 * vl * cx + vl * vl * cxx)
                    for j in range(nm):
                        p[j] += load * ent_phi[e, j]
                    W[ax_] = 0.0
                    Wd[ax_] = 0.0
                for j in range(nm):
                    rhs[j] = p[j] - Z[l, j] * sqd[j] - K[c, j] * sq[j]
                for i in range(nm):
                    s = 0.0
                    for j in range(nm):
                        s += rhs[j] * minv[c, r, j, i]
                    qdd[i] = s
                if st == 0:
                    for j in range(nm):
                        acc0 += qdd[j] * phi_mid[j]
                # 4. RK4 bookkeeping of both subsystems (as stepping._Rk4State.push)
                wgt = RK4_W[st]
                if st == 0:
                    for j in range(nm):
                        aq[j] = wgt * sqd[j]
                        aqd[j] = wgt * qdd[j]
                else:
                    for j in range(nm):
                        aq[j] = aq[j] + wgt * sqd[j]
                        aqd[j] = aqd[j] + wgt * qdd[j]
                for ia in range(a0, a1):
                    un = act_units[ia]
                    for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                        if st == 0:
                            au[dd] = wgt * sud[dd]
                            aud[dd] = wgt * udd[dd]
                        else:
                            au[dd] = au[dd] + wgt * sud[dd]
                            aud[dd] = aud[dd] + wgt * udd[dd]
                if st < 3:
                    cc = RK4_C[st + 1] * hl
                    for j in range(nm):
                        x_new = q[j] + cc * sqd[j]
                        sqd[j] = qd[j] + cc * qdd[j]
                        sq[j] = x_new
                    for ia in range(a0, a1):
                        un = act_units[ia]
                        for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                            x_new = u[dd] + cc * sud[dd]
                            sud[dd] = ud[dd] + cc * udd[dd]
                            su[dd] = x_new
                else:
                    for j in range(nm):
                        q[j] = q[j] + hl * aq[j]
                        qd[j] = qd[j] + hl * aqd[j]
                    for ia in range(a0, a1):
                        un = act_units[ia]
                        for dd in range(unit_dof0[un], unit_dof0[un] + unit_ndof[un]):
                            u[dd] = u[dd] + hl * au[dd]
                            ud[dd] = ud[dd] + hl * aud[dd]
            if not (abs(acc0) < np.inf and abs(d) < np.inf):
                finite = False
                break
            if abs(acc0) > amax:
                amax = abs(acc0)
            if abs(d) > dmax:
                dmax = abs(d)
        max_acc[l] = amax if finite else np.nan
        max_disp[l] = dmax if finite else np.nan
        if not finite:
            bad += 1
    return bad
