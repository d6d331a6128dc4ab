"""The two subsystems of a crossing, each with its own RK4 state, advanced in lockstep (paper Section 2.3).

Time integration
----------------
Classical fourth-order Runge-Kutta with a fixed step on the explicit first-order form of the
coupled system, Eq. (17). Why: (i) like the paper's ode113 it integrates the explicit form in
which the wheelset inertia sits in the modified mass matrix (Eqs. 13-15), so the algebraic loop
of Eq. (10) is gone; (ii) every RK stage needs from the partner subsystem only quantities at the
same stage, so a bridge and a train in separate processes exchange exactly what the in-process
solver passes between its two halves: no lag, no extrapolation; (iii) it is 4th order, so halving
the step changes the peaks by far less than 0.1 %; (iv) a fixed step vectorises over speeds.

Exchange per RK stage (DIM)
---------------------------
1. bridge -> train: rail displacement ``w`` and velocity ``w_dot`` (Eq. 9, first time derivative
   including the convective term ``v phi_x q``) under every axle on the bridge, shape
   ``(n_lanes, n_on)`` (:meth:`BridgeSide.rail_state`).
2. train -> bridge: interaction force ``G_i = F_i - F_k1,i - F_c1,i`` per axle on the bridge
   (the contact force of Eq. 7 without the wheelset inertia, which the bridge carries in its
   modified mass matrix, Eq. 13) (:meth:`TrainSide.take_rail_state`).
Both sides then form their stage derivative and advance their own RK4 state
(:meth:`BridgeSide.take_forces`).

MLM: the loads do not depend on the bridge motion; with the shared space grid the modal load
vector at every stage point is one array for all lanes (:mod:`adm_sim.integrate.mlm_loads`), and each
lane-mode pair follows the exact RK4 recurrence of a linear oscillator
(:func:`mlm_rk4_coefficients`, :meth:`BridgeSide.step_mlm`).

The runs that drive these sides (step count, status, maxima) are in :mod:`adm_sim.integrate.lockstep_runs`.
"""

from __future__ import annotations

import numpy as np

from adm_sim.integrate._jit import RK4_C, RK4_W  # the RK4 tableau, shared with the numba kernels
from adm_sim.errors import InputError
from adm_sim.integrate.tables import active_units, axle_rows, bridge_tables, vehicle_tables  # shared with the kernels
from adm_sim.model.irregularity import check_step  # the profile's shortest feature against ds (scipy loads only when a profile is used)


class _Rk4State:
    """RK4 bookkeeping for one subsystem: state ``(x, xd)`` of shape (n_lanes, n) per lane."""

    def __init__(self, h, n_lanes, n):
        self.h = np.asarray(h, dtype=float)[:, None]
        self.x = np.zeros((n_lanes, n))
        self.xd = np.zeros((n_lanes, n))
        self.stage = 0
        self._acc_x = None
        self._acc_xd = None
        self._sx = self.x
        self._sxd = self.xd

    def reset(self, x, xd):
        """Start a step from the given state (taken over, not copied)."""
        self.x, self.xd = x, xd
        self._sx, self._sxd = self.x, self.xd
        self.stage = 0

    def stage_state(self):
        """``(x, xd)`` at the current stage."""
        return self._sx, self._sxd

    def push(self, dx, dxd):
        """Give the stage derivative; returns True when this completed a step."""
        st = self.stage
        w = RK4_W[st]
        if st == 0:
            self._acc_x = w * dx
            self._acc_xd = w * dxd
        else:
            self._acc_x = self._acc_x + w * dx
            self._acc_xd = self._acc_xd + w * dxd
        if st < 3:
            c = RK4_C[st + 1] * self.h
            self._sx = self.x + c * dx
            self._sxd = self.xd + c * dxd
            self.stage = st + 1
            return False
        self.x = self.x + self.h * self._acc_x
        self.xd = self.xd + self.h * self._acc_xd
        self._sx, self._sxd = self.x, self.xd
        self.stage = 0
        return True


class BridgeSide:
    """The modal beam of Eqs. (5), (10), (13)-(15), advanced in lockstep.

    Parameters
    ----------
    bridge : adm_sim.model.bridge.Bridge
    grid : Grid
    axle_offsets_m : ndarray, shape (n_axles,)
        Axle offsets behind the first axle (m).
    wheel_mass_kg : ndarray, shape (n_axles,) or None
        Wheelset masses for the DIM (Eq. 13); ``None`` for the MLM.
    delta_zeta : float or ndarray (n_lanes,)
        Additional damping (fraction) added to the structural damping.
    response_m : float or None
        Where the recorded deflection and acceleration are taken (m from the left abutment);
        None: midspan (:func:`adm_sim.integrate.tables.bridge_tables`).
    """

    def __init__(self, bridge, grid, axle_offsets_m, wheel_mass_kg=None, delta_zeta=0.0, response_m=None):
        self.bridge = bridge
        self.grid = grid
        self.offsets = np.asarray(axle_offsets_m, dtype=float)
        self.m_w = None if wheel_mass_kg is None else np.asarray(wheel_mass_kg, dtype=float)
        self.v = grid.speeds_m_s[:, None]
        tables = bridge_tables([bridge], response_m)  # the tables of adm_sim.integrate.kernels, one bridge
        self.M = tables.M[0]
        self.K = tables.K[0]
        self.phi_mid = tables.phi_mid
        self.rk = _Rk4State(grid.dt_s, grid.n_lanes, bridge.n_modes)
        self.k = 0
        self.set_delta_zeta(delta_zeta)
        self._rows = (-self.TABLE_ROWS, None)  # (first row, AxleRows) of the table in use
        self._stage_cache = {}
        self.last_acc = np.zeros(grid.n_lanes)  # midspan acceleration at the start of step k

    # ------------------------------------------------------------------ settings
    def set_delta_zeta(self, delta_zeta):
        """Set the additional damping (fraction, scalar or per lane); takes effect next step."""
        dz = np.broadcast_to(np.asarray(delta_zeta, dtype=float), (self.grid.n_lanes,)).copy()
        zt = self.bridge.damping_ratio + dz
        if np.any(zt < 0.0):
            raise InputError(f"delta_zeta: total damping zeta + delta_zeta = {zt.min() * 100:.4g} % "
                             f"is negative; allowed >= {-self.bridge.damping_ratio * 100:.4g} %")
        self.delta_zeta = dz
        self.Z = self.bridge.modal_damping_Ns_m(dz)  # (n_lanes, n_modes)
        self._mlm_coeffs = None

    # ------------------------------------------------------------------ geometry
    @property
    def q(self):
        return self.rk.x

    @property
    def qd(self):
        return self.rk.xd

    def axles_on(self, k=None, stage=None):
        """Indices and positions of the axles on the bridge at step ``k``, stage ``stage``."""
        k = self.k if k is None else k
        stage = self.rk.stage if stage is None else stage
        x = self.grid.front_m(k, stage) - self.offsets
        idx = np.flatnonzero((x >= 0.0) & (x <= self.bridge.span_m))
        return idx, x[idx]

    #: Half-step rows of :func:`adm_sim.integrate.tables.axle_rows` tabulated at once (one table call per
    #: ~32 steps instead of one per stage: the per-call overhead of the table builder).
    TABLE_ROWS = 64

    def _shapes(self):
        """Axles on the bridge at (k, stage), their mode shapes and (DIM) ``M_mod^-1`` (Eq. 13).

        The row of :func:`adm_sim.integrate.tables.axle_rows` (the kernels' table, ``M_mod^-1`` included) for
        this stage point.
        """
        key = 2 * self.k + int(2 * RK4_C[self.rk.stage])  # half-step index: end of k = start of k+1
        hit = self._stage_cache.get(key)
        if hit is not None:
            return hit
        r0, rows = self._rows
        if not r0 <= key < r0 + self.TABLE_ROWS:
            r0, rows = key, axle_rows([self.bridge], self.offsets, self.grid.ds_m, key, self.TABLE_ROWS,
                                      wheel_mass_kg=self.m_w)
            self._rows = (r0, rows)
        i = key - r0
        e0, e1 = rows.ptr[i], rows.ptr[i + 1]
        idx, phi = rows.axle[e0:e1], rows.phi[e0:e1]
        minv = None if self.m_w is None else rows.minv[0, i]
        hit = (idx, phi, rows.phx[e0:e1], rows.phxx[e0:e1], minv)
        if len(self._stage_cache) > 8:
            self._stage_cache.clear()
        self._stage_cache[key] = hit
        return hit

    # ------------------------------------------------------------------ DIM exchange
    def rail_state(self):
        """Rail displacement and velocity under the axles on the bridge (Eqs. 4, 9).

        Returns ``(idx, w_m, w_dot_m_s)``: axle indices (n_on,) and arrays (n_lanes, n_on).
        """
        idx, phi, phx, _, _ = self._shapes()
        q, qd = self.rk.stage_state()
        w = q @ phi.T
        wd = qd @ phi.T + self.v * (q @ phx.T)
        return idx, w, wd

    def take_forces(self, interaction_n):
        """Advance one RK stage given ``G_i = F_i - F_k1,i - F_c1,i`` (n_lanes, n_on).

        Returns True when the stage completed step k (the bridge is then at step k+1).
        """
        idx, phi, phx, phxx, minv = self._shapes()
        q, qd = self.rk.stage_state()
        load = np.asarray(interaction_n, dtype=float)
        conv = None
        if self.m_w is not None and len(idx):
            conv = 2.0 * self.v * (qd @ phx.T) + self.v**2 * (q @ phxx.T)  # Eq. (9)
            load = load - self.m_w[idx] * conv
        p = load @ phi  # Eq. (14)
        rhs = p - self.Z * qd - self.K * q
        if minv is None:
            qdd = rhs / self.M
        else:
            qdd = rhs @ minv  # Eq. (15); M_mod is symmetric
        if self.rk.stage == 0:
            self.last_acc = qdd @ self.phi_mid
            # wheel (rail) acceleration under the axles, Eq. (9), for contact forces (Eq. 7)
            self.last_wheel_acc = qdd @ phi.T + (0.0 if conv is None else conv)
            if self.m_w is not None:  # the contact forces F_i = G_i - m_w,i w''_i (Eq. 7), compression positive
                self.last_axles = idx
                self.last_contact_n = np.asarray(interaction_n, dtype=float) - self.m_w[idx] * self.last_wheel_acc
        done = self.rk.push(qd, qdd)
        if done:
            self.k += 1
        return done

    # ------------------------------------------------------------------ MLM
    def _coeffs(self):
        """Exact RK4 recurrence of each lane-mode oscillator (see :func:`mlm_rk4_coefficients`)."""
        if self._mlm_coeffs is None:
            self._mlm_coeffs = mlm_rk4_coefficients(self.rk.h, self.M, self.Z, self.K)
        return self._mlm_coeffs

    def step_mlm(self, p0, ph, p1):
        """One full RK4 step of the MLM (Eq. 12) given the modal loads at the stage points.

        ``p0, ph, p1`` : modal loads (n_modes,) or (n_lanes, n_modes) at ``s_k``,
        ``s_k + ds/2`` and ``s_k + ds``. Sets :attr:`last_acc` (midspan acceleration at step k).
        """
        (ax, axd), (bx, bxd), (c0, c0d), (ch, chd), (c1, c1d) = self._coeffs()
        q, qd = self.rk.x, self.rk.xd
        self.last_acc = ((p0 - self.Z * qd - self.K * q) / self.M) @ self.phi_mid
        self.rk.reset(ax * q + bx * qd + c0 * p0 + ch * ph + c1 * p1,
                      axd * q + bxd * qd + c0d * p0 + chd * ph + c1d * p1)
        self.k += 1

    # ------------------------------------------------------------------ outputs
    def midspan_displacement(self):
        """Midspan deflection (m) at the current step, shape (n_lanes,)."""
        return self.rk.x @ self.phi_mid

    def midspan_velocity(self):
        """Midspan velocity (m/s) at the current step, shape (n_lanes,)."""
        return self.rk.xd @ self.phi_mid


class TrainSide:
    """The vehicles of the DIM (Eq. 11) advanced in lockstep with a :class:`BridgeSide`.

    Only units (vehicles, Jacobs sets) with an axle on the bridge during a step are integrated:
    on a rigid track a unit rests until its first axle enters, and once its last axle has left
    it no longer acts on the bridge.

    ``irregularity`` (:class:`adm_sim.model.irregularity.Profile` or None): the track profile on the
    deck; every wheel on the bridge then follows rail plus profile (Eq. 9 gains ``r(x)`` and
    ``v r'(x)``, :meth:`take_rail_state`). The profile is zero off the deck, so the units still
    rest until they enter.
    """

    def __init__(self, train, grid, span_m, irregularity=None):
        self.train = train
        self.grid = grid
        self.span = float(span_m)
        self.irregularity = irregularity
        if irregularity is not None:  # its shortest feature against the space step
            check_step(irregularity, grid.ds_m)
        self.offsets = train.axle_offsets_m
        self.vehicles = vehicle_tables(train)  # the tables of adm_sim.integrate.kernels
        self.n_dof = self.vehicles.minv_dof.size
        self.x = np.zeros((grid.n_lanes, self.n_dof))  # displacements (m, rad)
        self.xd = np.zeros((grid.n_lanes, self.n_dof))  # velocities
        self.rk = None  # RK4 state of the active DOFs during the current step
        self.k = 0
        self._active_cache = {}
        self._step_active = None
        self._units = (-self.TABLE_STEPS, None)  # (first step, ActiveUnits) of the table in use

    #: Steps of :func:`adm_sim.integrate.tables.active_units` tabulated at once.
    TABLE_STEPS = 64

    def _active(self):
        """Matrices of the units active during step k (:func:`adm_sim.integrate.tables.active_units`),
        taken from the train's :class:`~adm_sim.integrate.tables.VehicleTables` (cached by unit set)."""
        if self._step_active is not None:
            return self._step_active
        k0, act = self._units
        if not k0 <= self.k < k0 + self.TABLE_STEPS:
            k0, act = self.k, active_units(self.vehicles, self.span, self.grid.ds_m, self.k, self.k + self.TABLE_STEPS)
            self._units = (k0, act)
        units = tuple(act.units[act.ptr[self.k - k0]:act.ptr[self.k - k0 + 1]].tolist())
        hit = self._active_cache.get(units)
        if hit is None:
            t = self.vehicles
            dofs = np.concatenate([np.arange(t.unit_dof0[i], t.unit_dof0[i] + t.unit_ndof[i]) for i in units]) \
                if units else np.zeros(0, int)
            axles = np.concatenate([np.arange(t.unit_ax0[i], t.unit_ax0[i] + t.unit_nax[i]) for i in units]) \
                if units else np.zeros(0, int)
            Ks, Cs, Lw = t.Ks[np.ix_(dofs, dofs)], t.Cs[np.ix_(dofs, dofs)], t.Lw[np.ix_(axles, dofs)]
            hit = (dofs, axles, Ks.T.copy(), Cs.T.copy(), Lw, Lw.T.copy(), t.kp[axles], t.cp[axles], t.minv_dof[dofs])
            self._active_cache[units] = hit
        self._step_active = hit
        self.rk = _Rk4State(self.grid.dt_s, self.grid.n_lanes, len(hit[0]))
        self.rk.reset(self.x[:, hit[0]], self.xd[:, hit[0]])
        return hit

    def take_rail_state(self, idx_on, w, wd):
        """Advance one RK stage given the rail state under the axles on the bridge.

        Parameters
        ----------
        idx_on : ndarray (n_on,)
            Axle indices on the bridge (as from :meth:`BridgeSide.rail_state`).
        w, wd : ndarray (n_lanes, n_on)
            Rail displacement (m) and velocity (m/s) under those axles.

        Returns
        -------
        G : ndarray (n_lanes, n_on)
            Interaction forces ``F_i - F_k1,i - F_c1,i`` (N) for the bridge; on a rough track less
            the wheelset's inertia on the profile ``m_w,i v^2 r''(x_i)`` (the bridge carries the
            wheelset's inertia of its own motion, Eq. 13).
        """
        dofs, axles, KsT, CsT, Lw, LwT, kp, cp, minv = self._active()
        u, ud = self.rk.stage_state()
        # rail state under every axle of the active units (rigid track off the bridge)
        pos = np.searchsorted(axles, idx_on)
        W = np.zeros((self.grid.n_lanes, len(axles)))
        Wd = np.zeros_like(W)
        curv = None
        if self.irregularity is None:
            W[:, pos] = w
            Wd[:, pos] = wd
        else:  # the profile under the wheels (Eq. 9 with r(x), v r'(x)); positions as tables.axle_rows
            x = self.grid.front_m(self.k, self.rk.stage) - np.asarray(self.offsets, dtype=float)[idx_on]
            r, s, curv = self.irregularity.evaluate(x, curvature=True)
            W[:, pos] = w + r
            Wd[:, pos] = wd + self.grid.speeds_m_s[:, None] * s
        zb, zbd = u @ LwT, ud @ LwT
        f = kp * (W - zb) + cp * (Wd - zbd)  # primary stage force on the bogies (Eq. 7 terms)
        udd = (f @ Lw - u @ KsT - ud @ CsT) * minv
        G = self.train.axle_loads_n[idx_on] - f[:, pos]
        if curv is not None:  # the wheelset's inertia on the profile, m_w v^2 r''(x), acts on the bridge
            v = self.grid.speeds_m_s[:, None]
            G = G - np.asarray(self.train.wheel_mass_kg, dtype=float)[idx_on] * (v * v) * curv
        if self.rk.push(ud, udd):
            self.x[:, dofs] = self.rk.x
            self.xd[:, dofs] = self.rk.xd
            self._step_active = None
            self.k += 1
        return G


def mlm_rk4_coefficients(h, m, c, kk):
    """Exact RK4 recurrence of linear oscillators ``m x'' + c x' + kk x = p`` over one step ``h``.

    One classical RK4 step (stage loads ``p0`` at the start, ``ph`` at the midpoint, ``p1`` at
    the end) is linear in the state and the loads: ``x+ = ax x + bx xd + c0 p0 + ch ph + c1 p1``
    and the same for ``xd+``. Returns ``((ax, axd), (bx, bxd), (c0, c0d), (ch, chd), (c1, c1d))``,
    each broadcast of ``h`` (n_lanes, 1) with ``m``, ``c``, ``kk`` (n_lanes or 1, n_modes).
    """

    def f(x, xd, p):
        return xd, (p - c * xd - kk * x) / m

    def rk4(x, xd, p0, ph, p1):
        k1 = f(x, xd, p0)
        k2 = f(x + 0.5 * h * k1[0], xd + 0.5 * h * k1[1], ph)
        k3 = f(x + 0.5 * h * k2[0], xd + 0.5 * h * k2[1], ph)
        k4 = f(x + h * k3[0], xd + h * k3[1], p1)
        return (x + h / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
                xd + h / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]))

    one = np.ones_like(c)
    zero = np.zeros_like(c)
    return (rk4(one, zero, 0, 0, 0), rk4(zero, one, 0, 0, 0),
            rk4(zero, zero, 1, 0, 0), rk4(zero, zero, 0, 1, 0),
            rk4(zero, zero, 0, 0, 1))
