"""Step-wise bridge and train models with an explicit exchange (paper Section 2.3).

Time integration
----------------
Classical fourth-order Runge-Kutta with a fixed step on the explicit first-order form of the
coupled system, Eq. (17). Why: (i) like the paper's ode113 it integrates the explicit form in
which the wheelset inertia sits in the modified mass matrix (Eqs. 13-15), so the algebraic loop
of Eq. (10) is gone; (ii) every RK stage needs from the partner subsystem only quantities at the
same stage, so a bridge and a train in separate processes exchange exactly what the in-process
solver passes between its two halves: no lag, no extrapolation; (iii) it is 4th order, so halving
the step changes the peaks by far less than 0.1 %; (iv) a fixed step vectorises over speeds.

Space grid
----------
All speed lanes share one grid of *train positions*: at step ``k`` the first axle stands at
``x = s_k = k ds`` on the bridge (``s = 0``: first axle on the left support). Lane ``l`` then has the time step ``dt_l = ds / v_l``. Axle positions, the set of axles
on the bridge, the MLM modal loads and the active vehicles are therefore the same for every lane
at every stage, which keeps a whole speed sweep cheap. ``ds`` is chosen so that the slowest lane
takes ``steps_per_period`` steps per period of the highest retained bridge mode; faster lanes get
finer time steps.

Exchange per RK stage (DIM)
---------------------------
1. bridge -> train: rail displacement ``w`` and velocity ``w_dot`` (Eq. 9, first time derivative
   including the convective term ``v phi_x q``) under every axle on the bridge, shape
   ``(n_lanes, n_on)``.
2. train -> bridge: interaction force ``G_i = F_i - F_k1,i - F_c1,i`` per axle on the bridge
   (the contact force of Eq. 7 without the wheelset inertia, which the bridge carries in its
   modified mass matrix, Eq. 13).
Both sides then form their stage derivative and advance their own RK4 state.

MLM: the loads do not depend on the bridge motion; with the shared space grid the modal load
vector at every stage point is one array for all lanes, and each lane-mode pair follows the
exact RK4 recurrence of a linear oscillator (:meth:`BridgeSide.step_mlm`).

Free vibration: the run continues after the last axle has left the bridge for at least
``free_vibration_periods`` (default 2) fundamental periods in every lane, because the largest
acceleration of a resonant crossing can occur up to one period after the train has left.

One stepper, a template as scipy's ``OdeSolver``
------------------------------------------------
:class:`SteppedRun` writes the public :meth:`~SteppedRun.step` (and
:meth:`~AdvancingRun.advance` for a run that needs no partner per step) once: only they set
status and message; an implementation provides ``_step_impl`` (or ``_advance_impl`` for a
block), which returns ``(success, message)``. The input a half receives from its partner is the
argument of ``step``; nothing else advances a run. Implementations: :class:`InProcessRun` (both
halves in one process, :func:`adm_sim.sweep.run_sweep`), :class:`BridgeHalf` (the bridge node:
``rail_state`` is sent, ``step(interaction_n)`` per DIM stage, ``step(p0, ph, p1)`` with the
stage-point modal loads per MLM step), :class:`TrainHalf` (the train node: ``step(idx_on, w, wd)``
per DIM stage leaves the forces in ``interaction_n``; ``advance(n)`` books an MLM axle block) and
:class:`adm_sim.compiled_batch.BatchRun` (the compiled kernels). Every numpy path calls the same
:class:`BridgeSide` / :class:`TrainSide` methods in the same order, so the co-simulated runs
equal the in-process ones bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from adm_sim._jit import RK4_C, RK4_W  # the RK4 tableau, shared with the numba kernels
from adm_sim.errors import InputError, check_range
from adm_sim.fields import FIELDS
from adm_sim.tables import active_units, axle_rows, bridge_tables, vehicle_tables  # shared with the kernels

SPEED_RANGE_KMH = FIELDS["speeds_kmh"].range


@dataclass(frozen=True)
class StepOptions:
    """Discretisation settings.

    Parameters
    ----------
    steps_per_period : float
        RK4 steps per period of the highest retained bridge mode, at the slowest lane.
    free_vibration_periods : float
        Fundamental periods simulated after the last axle has left (every lane).
    ds_m : float or None
        Train advance per step (m); overrides ``steps_per_period``.
    dense_maxima : bool
        Also take the maximum |midspan acceleration| *between* the steps, from the integrator's
        dense output (:func:`hermite_max_abs_acc`), not only at the step points. Off by default:
        the paper's numbers and the shipped study are the sampled maxima.
    """

    steps_per_period: float = 16.0
    free_vibration_periods: float = 2.0
    ds_m: float | None = None
    dense_maxima: bool = False

    def __post_init__(self):
        FIELDS["steps_per_period"].check(self.steps_per_period)
        FIELDS["free_vibration_periods"].check(self.free_vibration_periods)
        if self.ds_m is not None:
            FIELDS["ds_m"].check(self.ds_m)

    def halved(self):
        """The same settings with half the step (for convergence checks)."""
        ds = None if self.ds_m is None else 0.5 * self.ds_m
        return StepOptions(2.0 * self.steps_per_period, self.free_vibration_periods, ds, self.dense_maxima)


@dataclass(frozen=True)
class Grid:
    """The shared space grid of a run.

    Attributes
    ----------
    speeds_m_s : ndarray, shape (n_lanes,)
    ds_m : float
        Train advance per step (m).
    n_steps : int
        Number of RK4 steps.
    """

    speeds_m_s: np.ndarray
    ds_m: float
    n_steps: int

    @property
    def n_lanes(self):
        return len(self.speeds_m_s)

    @property
    def dt_s(self):
        """Time step per lane (s), shape (n_lanes,)."""
        return self.ds_m / self.speeds_m_s

    def front_m(self, k, stage=0):
        """Position of the first axle at step ``k``, RK stage ``stage`` (m from the left support)."""
        return (k + RK4_C[stage]) * self.ds_m

    def clock_time_s(self, k, stage=0):
        """One time for the whole run: the time of the slowest lane (for ``/clock``)."""
        return self.front_m(k, stage) / float(self.speeds_m_s.min())


def speeds_to_m_s(speeds_kmh):
    """Validate speeds (km/h) and convert to m/s, shape (n_lanes,)."""
    v = np.atleast_1d(np.asarray(speeds_kmh, dtype=float))
    if v.ndim != 1 or v.size == 0:
        raise InputError("speeds_kmh: need a non-empty list of speeds (km/h)")
    for x in v:
        check_range("speed_kmh", x, "km/h", *SPEED_RANGE_KMH)
    return v / 3.6


def make_grid(bridge, train_length_m, speeds_m_s, options=None):
    """Space grid covering the crossing of a train and the free vibration afterwards."""
    options = options or StepOptions()
    v = np.asarray(speeds_m_s, dtype=float)
    if options.ds_m is not None:
        ds = float(options.ds_m)
    else:
        t_top = 2.0 * math.pi / bridge.omega_rad_s[-1]
        ds = float(v.min()) * t_top / options.steps_per_period
    t1 = 1.0 / bridge.n0_hz
    travel = train_length_m + bridge.span_m + options.free_vibration_periods * t1 * float(v.max())
    return Grid(speeds_m_s=v, ds_m=ds, n_steps=int(math.ceil(travel / ds)))


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
    bridge : adm_sim.bridge.Bridge
    grid : Grid
    axle_offsets_m : ndarray, shape (n_axles,)
        Axle offsets behind the first axle (m).
    wheel_mass_kg : ndarray, shape (n_axles,) or None
        Wheelset masses for the DIM (Eq. 13); ``None`` for the MLM.
    delta_zeta : float or ndarray (n_lanes,)
        Additional damping (fraction) added to the structural damping.
    """

    def __init__(self, bridge, grid, axle_offsets_m, wheel_mass_kg=None, delta_zeta=0.0):
        self.bridge = bridge
        self.grid = grid
        self.offsets = np.asarray(axle_offsets_m, dtype=float)
        self.m_w = None if wheel_mass_kg is None else np.asarray(wheel_mass_kg, dtype=float)
        self.v = grid.speeds_m_s[:, None]
        tables = bridge_tables([bridge])  # the tables of adm_sim.kernels, one bridge
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

    #: Half-step rows of :func:`adm_sim.tables.axle_rows` tabulated at once (one table call per
    #: ~32 steps instead of one per stage: the per-call overhead of the table builder).
    TABLE_ROWS = 64

    def _shapes(self):
        """Axles on the bridge at (k, stage), their mode shapes and (DIM) ``M_mod^-1`` (Eq. 13).

        The row of :func:`adm_sim.tables.axle_rows` (the kernels' table, ``M_mod^-1`` included) for
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
    on a rigid track without irregularities a unit rests until its first axle enters, and once
    its last axle has left it no longer acts on the bridge.
    """

    def __init__(self, train, grid, span_m):
        self.train = train
        self.grid = grid
        self.span = float(span_m)
        self.offsets = train.axle_offsets_m
        self.vehicles = vehicle_tables(train)  # the tables of adm_sim.kernels
        self.n_dof = self.vehicles.minv_dof.size
        self.x = np.zeros((grid.n_lanes, self.n_dof))  # displacements (m, rad)
        self.xd = np.zeros((grid.n_lanes, self.n_dof))  # velocities
        self.rk = None  # RK4 state of the active DOFs during the current step
        self.k = 0
        self._active_cache = {}
        self._step_active = None
        self._units = (-self.TABLE_STEPS, None)  # (first step, ActiveUnits) of the table in use

    #: Steps of :func:`adm_sim.tables.active_units` tabulated at once.
    TABLE_STEPS = 64

    def _active(self):
        """Matrices of the units active during step k (:func:`adm_sim.tables.active_units`),
        taken from the train's :class:`~adm_sim.tables.VehicleTables` (cached by unit set)."""
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
            Interaction forces ``F_i - F_k1,i - F_c1,i`` (N) for the bridge.
        """
        dofs, axles, KsT, CsT, Lw, LwT, kp, cp, minv = self._active()
        u, ud = self.rk.stage_state()
        # rail state under every axle of the active units (rigid track off the bridge)
        pos = np.searchsorted(axles, idx_on)
        W = np.zeros((self.grid.n_lanes, len(axles)))
        Wd = np.zeros_like(W)
        W[:, pos] = w
        Wd[:, pos] = wd
        zb, zbd = u @ LwT, ud @ LwT
        f = kp * (W - zb) + cp * (Wd - zbd)  # primary stage force on the bogies (Eq. 7 terms)
        udd = (f @ Lw - u @ KsT - ud @ CsT) * minv
        G = self.train.axle_loads_n[idx_on] - f[:, pos]
        if self.rk.push(ud, udd):
            self.x[:, dofs] = self.rk.x
            self.xd[:, dofs] = self.rk.xd
            self._step_active = None
            self.k += 1
        return G


RUNNING, FINISHED, FAILED = "running", "finished", "failed"  # SteppedRun.status
MODELS = FIELDS["model"].choices


def check_model(model, train=None):
    """Refuse a model other than ``"mlm"``/``"dim"``, and the DIM for a load train (no vehicles)."""
    if model not in MODELS:
        raise InputError(f"model: {model!r} is not allowed; allowed 'mlm' or 'dim'")
    if model == "dim" and train is not None and not train.units:
        raise InputError(f"model: 'dim' needs a train with vehicles; {train.name!r} is a load train (MLM only)")


def _all_finite(a):
    """True when every value of ``a`` is finite.

    ``a @ a`` is NaN or inf for a non-finite entry: one cheap call per step; only when it is not
    finite (also for finite values beyond 1e154) the exact element-wise check decides.
    """
    return math.isfinite(a @ a) or bool(np.isfinite(a).all())


def hermite_max_abs_acc(d0, v0, a0, d1, v1, a1, h):
    """Largest |acceleration| strictly inside a step from its dense output; 0 where there is none.

    Over one step ``[t_k, t_k + h]`` the midspan deflection, velocity and acceleration are known
    at both ends from the state (``d = phi q``, ``v = phi q'``, ``a = phi q''``, the stage-0
    derivative of Eq. 15 or Eq. 12). The quintic Hermite interpolant of the deflection through
    these six values (error O(h^6), so O(h^4) in its second derivative, the order of RK4 itself)
    has as second derivative the cubic in ``s = (t - t_k) / h``

        a(s) = a0 + c1 s + c2 s^2 + c3 s^3,  with D = (d1 - d0) / h^2, V0 = v0 / h, V1 = v1 / h,
        c1 =   60 D - 36 V0 - 24 V1 -  9 a0 +  3 a1,
        c2 = -180 D + 96 V0 + 84 V1 + 18 a0 - 12 a1,
        c3 =  120 D - 60 V0 - 60 V1 - 10 a0 + 10 a1,

    (a(1) = a1). Its interior extrema are the roots of ``a'(s) = c1 + 2 c2 s + 3 c3 s^2`` in
    (0, 1), found in closed form (the cancellation-free quadratic formula). The numba kernels use
    the same arithmetic (:func:`adm_sim.kernels.hermite_max_abs_acc`).

    Parameters
    ----------
    d0, v0, a0, d1, v1, a1 : ndarray (n_lanes,)
        Deflection (m), velocity (m/s), acceleration (m/s^2) at the start and the end of the step.
    h : ndarray (n_lanes,)
        Time step (s).

    Returns
    -------
    ndarray (n_lanes,)
        ``max |a(s)|`` over the interior extrema, 0 where ``a`` is monotone on the step (the ends
        are sampled anyway).
    """
    D = (d1 - d0) / (h * h)
    V0 = v0 / h
    V1 = v1 / h
    c1 = 60.0 * D - 36.0 * V0 - 24.0 * V1 - 9.0 * a0 + 3.0 * a1
    c2 = -180.0 * D + 96.0 * V0 + 84.0 * V1 + 18.0 * a0 - 12.0 * a1
    c3 = 120.0 * D - 60.0 * V0 - 60.0 * V1 - 10.0 * a0 + 10.0 * a1
    A, B, C = 3.0 * c3, 2.0 * c2, c1
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = B * B - 4.0 * A * C
        sq = np.sqrt(np.where(disc >= 0.0, disc, 0.0))
        q = np.where(B >= 0.0, -0.5 * (B + sq), -0.5 * (B - sq))
        quad = (A != 0.0) & (disc >= 0.0) & (q != 0.0)
        lin = (A == 0.0) & (B != 0.0)
        s1 = np.where(quad, q / A, np.where(lin, -C / B, -1.0))
        s2 = np.where(quad, C / q, -1.0)
    best = np.zeros(np.shape(s1))
    for s in (s1, s2):
        inside = (s > 0.0) & (s < 1.0)
        val = np.abs(a0 + s * (c1 + s * (c2 + s * c3)))
        best = np.where(inside & (val > best), val, best)
    return best


class SteppedRun:
    """The contract every run of the project keeps, in-process, co-simulated or compiled.

    Modelled on :class:`scipy.integrate.OdeSolver`: the public :meth:`step` (and
    :meth:`AdvancingRun.advance`) are written once here and are the only methods that set
    :attr:`status` and :attr:`message`; they refuse to step a run that is not running. An
    implementation provides :meth:`_step_impl` (one step, or one exchange with the partner half)
    which moves its state and step count on and returns ``(success, message)``: ``success`` False
    with a one-line ``message`` saying what was not finite, where and for which lane (see
    :meth:`_not_finite`), else ``(True, None)``. A run is ``'running'`` until its last step is done
    (``'finished'``) or an implementation reports a failure (``'failed'``); stepping a run that is
    not running raises ``RuntimeError``.

    One call of :meth:`step` is one exchange with the partner, whose input is its argument: a
    whole step for :class:`InProcessRun` and :class:`adm_sim.compiled_batch.BatchRun` (no
    partner) and for the MLM halves (the modal loads of a step); one RK4 stage of step ``k`` for
    the DIM halves (the exchange is per stage), ``k`` then moves on with the fourth stage.

    Implementations: :class:`InProcessRun` (the numpy stepper, both halves in one process, driven
    by :func:`adm_sim.sweep.run_sweep`), :class:`BridgeHalf` and :class:`TrainHalf` (what the
    bridge node and the train node each step, exchanging per RK4 stage or per block) and
    :class:`adm_sim.compiled_batch.BatchRun` (the compiled kernels, block of steps by block of steps).

    Attributes
    ----------
    k : int
        Steps done, ``0 .. n_steps``.
    n_steps : int
    status : {"running", "finished", "failed"}
    message : str
        Empty, or one line saying what was not finite, where.
    """

    k: int = 0
    n_steps: int = 0
    status: str = RUNNING
    message: str = ""

    # ------------------------------------------------------------------ public contract
    def step(self, *exchange):
        """Advance one step, or one exchange (``exchange``: what the partner half sends for it).

        Returns
        -------
        message : str or None
            ``None`` on success, else :attr:`message` (the run is then ``'failed'``).
        """
        self._require("step")
        return self._settle(*self._step_impl(*exchange))

    # ------------------------------------------------------------------ for implementations
    def _step_impl(self, *exchange):  # pragma: no cover - abstract
        """Move the state on by one step or exchange; return ``(success, message)``."""
        raise NotImplementedError

    def _settle(self, success, message):
        """Status and message after an implementation's step (the only place that sets them)."""
        if not success:
            self.status = FAILED
            self.message = message
            return message
        if self.k >= self.n_steps:
            self.status = FINISHED
        return None

    def _start_contract(self, n_steps):
        self.n_steps = int(n_steps)
        self.k = 0
        self.status = RUNNING if self.n_steps > 0 else FINISHED
        self.message = ""

    def _require(self, what):
        """Refuse to step a run that is not running (``RuntimeError`` naming the call)."""
        if self.status != RUNNING:
            name = type(self).__name__
            why = f": {self.message}" if self.message else ""
            raise RuntimeError(f"{name}.{what}: the run is {self.status} at step {self.k} of "
                               f"{self.n_steps}{why}")

    @staticmethod
    def _not_finite(what, values, where, lane_speeds_m_s, ds_m, lane_names=None):
        """The finite-value check: ``None`` when every value is finite, else the failure message.

        ``values``: an array (n_lanes,), or a tuple of arrays (..., n_lanes) (a non-finite
        entry fails its lane). ``lane_names``: names per lane, or a callable building them
        (called only for a failure).
        """
        arrays = values if isinstance(values, tuple) else (values,)
        if all(_all_finite(a.ravel()) for a in arrays):
            return None
        finite = np.logical_and.reduce([np.isfinite(a.reshape(-1, a.shape[-1])).all(axis=0) for a in arrays])
        bad = np.flatnonzero(~finite)
        first = f"{float(lane_speeds_m_s[bad[0]]) * 3.6:.6g} km/h"
        if callable(lane_names):
            lane_names = lane_names()
        if lane_names is not None:
            first = f"{lane_names[bad[0]]} at {first}"
        return (f"solution is not finite {where}: {what} in {bad.size} of {finite.size} lanes "
                f"(first at {first}); the step ds = {ds_m:.4g} m is too large for this bridge/train "
                f"(raise steps_per_period or lower ds_m)")


class AdvancingRun(SteppedRun):
    """A run that needs nothing from a partner per step, so it can also :meth:`advance` by blocks."""

    #: steps of :meth:`advance` without an argument
    ADVANCE_STEPS = 1

    def advance(self, max_steps=None):
        """Advance up to ``max_steps`` steps (default :attr:`ADVANCE_STEPS`), never past ``n_steps``.

        Returns ``None`` on success, else :attr:`message` (the run is then ``'failed'``).
        """
        self._require("advance")
        n = self.ADVANCE_STEPS if max_steps is None else int(max_steps)
        if n < 1:
            raise ValueError(f"{type(self).__name__}.advance: max_steps = {max_steps} must be >= 1")
        return self._settle(*self._advance_impl(min(n, self.n_steps - self.k)))

    def _advance_impl(self, n):
        """``n >= 1`` steps, ``k + n <= n_steps``; by default :meth:`_step_impl` ``n`` times.

        Returns ``(success, message)`` as :meth:`_step_impl`.
        """
        for _ in range(n):
            success, message = self._step_impl()
            if not success:
                return success, message
        return True, None


class _Lockstep(SteppedRun):
    """Step ``k`` and RK4 stage of the numpy stepper (shared by the in-process run and the halves)."""

    def __init__(self, model, grid, *sides):
        check_model(model)
        for side in sides:
            if side.k != 0:
                raise ValueError(f"{type(self).__name__}: {type(side).__name__} is at step {side.k}, not at step 0")
        self.model = model
        self.grid = grid
        self._start_contract(grid.n_steps)
        self.stage = 0

    def _next_stage(self):
        if self.stage < 3:
            self.stage += 1
            return None
        return self._next_step()

    def _next_step(self):
        """Move on to step ``k + 1``; returns ``None`` or the failure message of the new step."""
        self.stage = 0
        self.k += 1
        return None

    def _exchange_args(self, exchange, n, what):
        """Refuse a :meth:`step` exchange of the wrong arity (``TypeError`` naming what it takes)."""
        if len(exchange) != n:
            raise TypeError(f"{type(self).__name__}.step: the {self.model.upper()} takes {what} "
                            f"({n} argument{'s' if n != 1 else ''}), got {len(exchange)}")
        return exchange


class _BridgeRun(_Lockstep):
    """A run that holds the bridge: running maxima and the finite check of the midspan response.

    Attributes
    ----------
    stage : int
        RK4 stage ``0 .. 3`` of step ``k`` that the next call works on.
    max_acc_m_s2 : ndarray (n_lanes,)
        Max |midspan acceleration| at stage 0 of every step done so far (DIM Eq. 15, MLM Eq. 12)
        and, with ``dense_maxima``, between them (:func:`hermite_max_abs_acc`).
    max_disp_m : ndarray (n_lanes,)
        Max |midspan deflection| at the start of every step ``0 .. min(k, n_steps - 1)``.
    disp_m : ndarray (n_lanes,)
        Midspan deflection at the start of step ``k``.
    acc_m_s2 : ndarray (n_lanes,) or None
        Midspan acceleration at stage 0 of the step in progress (or of the last step done).
    """

    def __init__(self, model, grid, bridge_side, dense_maxima=False, *more_sides):
        super().__init__(model, grid, bridge_side, *more_sides)
        self.bridge_side = bridge_side
        self.dense_maxima = bool(dense_maxima)
        self.acc_m_s2 = None
        self._vel_m_s = self._prev = None  # midspan velocity at step k; (d, v, a) at step k - 1
        self.max_acc_m_s2 = np.zeros(grid.n_lanes)
        self.max_disp_m = np.zeros(grid.n_lanes)
        failure = self._start_step()
        if failure is not None:
            raise ValueError(f"{type(self).__name__}: the bridge side does not start from a finite state: {failure}")

    def _check_lanes(self, what, values):
        return self._not_finite(what, values, f"at step {self.k} of {self.n_steps} (stage {self.stage})",
                                self.grid.speeds_m_s, self.grid.ds_m)

    def _start_step(self):
        """Deflection at the start of step ``k``: check, and fold into the maxima (k < n_steps).

        Returns ``None`` or the failure message.
        """
        d = self.bridge_side.midspan_displacement()
        self.disp_m = d
        if self.dense_maxima:
            self._vel_m_s = self.bridge_side.midspan_velocity()
        failure = self._check_lanes("midspan deflection", d)
        if failure is None and self.k < self.n_steps:
            np.maximum(self.max_disp_m, np.abs(d), out=self.max_disp_m)
        return failure

    def _take_acc(self):
        """Acceleration at stage 0 of step ``k``: check, and fold into the maxima.

        Returns ``None`` or the failure message.
        """
        a = self.bridge_side.last_acc
        self.acc_m_s2 = a
        failure = self._check_lanes("midspan acceleration", a)
        if failure is not None:
            return failure
        np.maximum(self.max_acc_m_s2, np.abs(a), out=self.max_acc_m_s2)
        if self.dense_maxima:  # between steps k - 1 and k, from the dense output
            if self._prev is not None:
                d0, v0, a0 = self._prev
                inner = hermite_max_abs_acc(d0, v0, a0, self.disp_m, self._vel_m_s, a, self.grid.dt_s)
                np.maximum(self.max_acc_m_s2, inner, out=self.max_acc_m_s2)
            self._prev = (self.disp_m, self._vel_m_s, a)
        return None

    def _next_step(self):
        super()._next_step()
        return self._start_step()

    def _forces(self, interaction_n):
        """DIM: advance stage (k, stage) of the bridge with the interaction forces (n_lanes, n_on).

        Returns ``(success, message)``.
        """
        self.bridge_side.take_forces(interaction_n)
        failure = self._take_acc() if self.stage == 0 else None
        if failure is None:
            failure = self._next_stage()
        return failure is None, failure

    def _mlm(self, p0, ph, p1):
        """MLM: one step with the modal loads at ``s_k``, ``s_k + ds/2``, ``s_k + ds`` (Eq. 12).

        Returns ``(success, message)``.
        """
        self.bridge_side.step_mlm(p0, ph, p1)
        failure = self._take_acc()
        if failure is None:
            failure = self._next_step()
        return failure is None, failure


class InProcessRun(_BridgeRun, AdvancingRun):
    """Both halves in one process (:func:`adm_sim.sweep.run_sweep`): :meth:`step` advances one
    whole step including the per-stage exchange.

    A DIM stage is :meth:`BridgeSide.rail_state` -> :meth:`TrainSide.take_rail_state` ->
    :meth:`BridgeSide.take_forces`, the calls :class:`BridgeHalf` and :class:`TrainHalf` make in
    two processes, so the co-simulated runs equal this one bit for bit.

    Parameters
    ----------
    model : {"mlm", "dim"}
    grid : Grid
    bridge_side : BridgeSide
        Fresh (at step 0).
    train_side : TrainSide or None
        Fresh (at step 0); the DIM needs it, the MLM has none (its loads need no state).
    modal_loads : ndarray (2 n_steps + 1, n_modes) or None
        MLM modal loads of Eq. (6) on the half-step grid (:func:`mlm_modal_load_table`).
    dense_maxima : bool
        Fold the maxima between the steps (dense output, :func:`hermite_max_abs_acc`) into
        :attr:`max_acc_m_s2`.

    Attributes: those of :class:`_BridgeRun`, and ``axles0``, ``interaction0_n``: the stage-0
    exchange of the step in progress (DIM).
    """

    def __init__(self, model, grid, bridge_side, train_side=None, modal_loads=None, dense_maxima=False):
        check_model(model)
        if model == "dim" and train_side is None:
            raise ValueError("InProcessRun: the DIM needs a train side")
        if model == "mlm" and (train_side is not None or modal_loads is None):
            raise ValueError("InProcessRun: the MLM has no train side (its loads need no state) and needs "
                             "the modal-load table")
        super().__init__(model, grid, bridge_side, dense_maxima, *(() if train_side is None else (train_side,)))
        self.train_side = train_side
        self.modal_loads = modal_loads
        self.axles0 = self.interaction0_n = None

    def _step_impl(self):
        if self.model == "mlm":
            P, k = self.modal_loads, self.k
            return self._mlm(P[2 * k], P[2 * k + 1], P[2 * k + 2])
        b, t = self.bridge_side, self.train_side
        for _ in range(4):
            idx, w, wd = b.rail_state()
            G = t.take_rail_state(idx, w, wd)
            if self.stage == 0:
                self.axles0, self.interaction0_n = idx, G
            success, message = self._forces(G)
            if not success:
                return success, message
        return True, None

    def contact_forces_n(self):
        """Wheel-rail contact forces (Eq. 7) at stage 0 of the step in progress or last done.

        ``F_i = G_i - m_w,i w''(x_i)`` with the rail acceleration under the axle (Eq. 9); DIM.
        Returns ``(idx, F)``: axle indices (n_on,) and forces (n_lanes, n_on) in N.
        """
        b = self.bridge_side
        idx = self.axles0
        return idx, self.interaction0_n - b.m_w[idx] * b.last_wheel_acc


class BridgeHalf(_BridgeRun):
    """The bridge half of a co-simulated run (the bridge node): a :class:`BridgeSide` alone.

    DIM, per RK4 stage: :meth:`rail_state` (the state sent to the train; it does not advance),
    then :meth:`step` ``(interaction_n)`` with the partner's interaction forces (n_lanes, n_on),
    which advances the stage. At stage 0 the midspan acceleration is checked and folded into the
    maxima; at the end of the step the deflection of the next one. MLM: :meth:`step`
    ``(p0, ph, p1)`` per step with the modal loads of the stage points. Keeps the maxima and the
    finite check as :class:`InProcessRun` does (attributes there). It has no ``advance``: every
    step needs the partner's exchange.
    """

    def __init__(self, model, grid, bridge_side, dense_maxima=False):
        super().__init__(model, grid, bridge_side, dense_maxima)

    def rail_state(self):
        """DIM: rail state under the axles at (k, stage); see :meth:`BridgeSide.rail_state`."""
        if self.model != "dim":
            raise RuntimeError(f"BridgeHalf.rail_state: needs the DIM (this run is {self.model.upper()})")
        self._require("rail_state")
        return self.bridge_side.rail_state()

    def _step_impl(self, *exchange):
        if self.model == "dim":
            (interaction_n,) = self._exchange_args(exchange, 1, "the interaction forces of one RK4 stage")
            return self._forces(interaction_n)
        p0, ph, p1 = self._exchange_args(exchange, 3, "the modal loads p0, ph, p1 of one step")
        return self._mlm(p0, ph, p1)


class TrainHalf(_Lockstep, AdvancingRun):
    """The train half of a co-simulated run (the train node).

    DIM: a :class:`TrainSide`; :meth:`step` ``(idx_on, w, wd)`` per RK4 stage takes the bridge's
    rail state (see :meth:`TrainSide.take_rail_state`), advances the stage and leaves the
    interaction forces to send back in :attr:`interaction_n` (n_lanes, n_on) in N. MLM: no
    state; :meth:`advance` ``(n)`` books the next block of steps (whose axle positions are being
    sent), ``k`` then names the next block's first step.
    """

    def __init__(self, model, grid, train_side=None):
        if model == "mlm" and train_side is not None:
            raise ValueError("TrainHalf: the MLM has no train side (its loads need no state)")
        if model == "dim" and train_side is None:
            raise ValueError("TrainHalf: the DIM needs a train side")
        super().__init__(model, grid, *(() if train_side is None else (train_side,)))
        self.train_side = train_side
        self.interaction_n = None

    def _step_impl(self, *exchange):
        if self.model == "mlm":
            self._exchange_args(exchange, 0, "nothing per step")
            self.k += 1
            return True, None
        idx_on, w, wd = self._exchange_args(exchange, 3, "the rail state idx_on, w, wd of one RK4 stage")
        self.interaction_n = self.train_side.take_rail_state(idx_on, w, wd)
        self._next_stage()
        return True, None

    def _advance_impl(self, n):
        if self.model != "mlm":
            raise RuntimeError("TrainHalf.advance: needs the MLM (a DIM step is four stages, each with the "
                               "bridge's rail state: step(idx_on, w, wd))")
        self.k += n
        return True, None


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


def half_step_positions(ds_m, axle_offsets_m, k0, n_steps):
    """Axle positions (m from the left support) at the RK4 stage points of steps ``k0..k0+n``.

    Row ``r`` is the first axle at ``s = r ds / 2``, ``r = 2 k0 .. 2 (k0 + n)``; shape
    ``(2 n + 1, n_axles)``. Rows ``2k`` are steps, rows ``2k + 1`` the RK midpoints.
    """
    s = 0.5 * ds_m * np.arange(2 * k0, 2 * (k0 + n_steps) + 1)
    return s[:, None] - np.asarray(axle_offsets_m, dtype=float)[None, :]


def modal_loads_at(bridge, x_m, loads_n):
    """Modal loads of Eq. (6) for axle positions ``x_m`` (rows, n_axles), shape (rows, n_modes).

    One pass per axle over the rows with that axle on the bridge (positions increase along the
    rows); the rectangle function Gamma is the closed span ``[0, L]``.
    """
    out = np.zeros((x_m.shape[0], bridge.n_modes))
    j = bridge.mode_numbers * math.pi / bridge.span_m
    for i in range(x_m.shape[1]):
        x = x_m[:, i]
        on = np.flatnonzero((x >= 0.0) & (x <= bridge.span_m))
        if on.size:
            lo, hi = on[0], on[-1] + 1
            out[lo:hi] += loads_n[i] * np.sin(np.outer(x[lo:hi], j))
    return out


def mlm_modal_load_table(bridge, grid, axle_offsets_m, axle_loads_n):
    """Modal loads of Eq. (6) on the half-step grid, shape (2 n_steps + 1, n_modes).

    Row ``2k`` is step k, row ``2k + 1`` the RK midpoint; shared by all lanes.
    """
    x = half_step_positions(grid.ds_m, axle_offsets_m, 0, grid.n_steps)
    return modal_loads_at(bridge, x, np.asarray(axle_loads_n, dtype=float))
