"""Batched runs: many bridges of one span and all their speeds as lanes of one compiled run.

A :class:`BatchRunner` holds a train and several bridges that share the span, the number of
modes and the damping model, and one space step ``ds``. Then the axle positions, the axles on
the bridge and their mode shapes (Eq. 6), the MLM modal loads and the active vehicles are the same
for every lane at every stage (as in :mod:`adm_sim.stepping`); what differs per lane is only the
bridge's modal stiffness, damping and mass (the wheelset-modified mass matrix of Eq. 13 is
tabulated per bridge), the speed, the additional damping and the number of steps.

Each lane reproduces what :func:`adm_sim.sweep.run_sweep` gives for its bridge, speed and damping
with the same ``ds`` (to ~1e-13 relative: the same operations in the same order, only the
summation order of a few small dot products differs), including its number of steps, which
``run_sweep`` derives from the fastest speed of the sweep: :meth:`BatchRunner.run` takes the
``sweep`` id of every lane and gives all lanes of one (bridge, sweep) the steps that sweep needs.

A run is a :class:`BatchRun`: the contract of :class:`adm_sim.stepping.SteppedRun` (step, status,
message, running maxima, finite-value check) over the compiled kernels, advanced block of steps
by block of steps.
"""

from __future__ import annotations

import numpy as np

from adm_sim import kernels
from adm_sim.fields import FIELDS
from adm_sim.errors import InputError, RunError
from adm_sim.limits import check_delta_zeta_pct
from adm_sim.stepping import (FAILED, RUNNING, StepOptions, SteppedRun, check_model, half_step_positions,
                              make_grid, mlm_rk4_coefficients, modal_loads_at, speeds_to_m_s)


def _row_ptr(rows, n_rows):
    """CSR row pointers (n_rows + 1,) of sorted row indices: entries of row r are ptr[r]:ptr[r+1]."""
    return np.searchsorted(rows, np.arange(n_rows + 1)).astype(np.int64)


def _csr(dense):
    """Row-compressed nonzeros of a dense matrix: ``(ptr, col, val)``."""
    rows, cols = np.nonzero(dense)
    return _row_ptr(rows, dense.shape[0]), cols.astype(np.int64), dense[rows, cols].astype(float)


class BatchRunner:
    """Lanes of several bridges (same span) under one train, on one space grid.

    Parameters
    ----------
    bridges : sequence of adm_sim.bridge.Bridge
        Same ``span_m``, ``n_modes`` and ``damping_model``.
    train : adm_sim.trains.Train
    ds_m : float
        Train advance per step (m), shared by every lane.
    free_vibration_periods : float
        As :class:`~adm_sim.stepping.StepOptions`.
    dense_maxima : bool
        As :class:`~adm_sim.stepping.StepOptions`: also the maxima between the steps.
    """

    def __init__(self, bridges, train, ds_m, free_vibration_periods=2.0, dense_maxima=False):
        self.bridges = list(bridges)
        if not self.bridges:
            raise InputError("bridges: need at least one bridge for a batch")
        b0 = self.bridges[0]
        for b in self.bridges[1:]:
            if (b.span_m, b.n_modes, b.damping_model) != (b0.span_m, b0.n_modes, b0.damping_model):
                raise InputError(f"bridges: a batch needs one span, mode count and damping model; "
                                 f"{b.name or b.describe()} differs from {b0.name or b0.describe()}")
        self.train = train
        self.options = StepOptions(free_vibration_periods=free_vibration_periods,
                                   ds_m=FIELDS["ds_m"].check(ds_m), dense_maxima=bool(dense_maxima))
        self.dense_maxima = bool(dense_maxima)
        self.ds_m = float(ds_m)
        self.span_m = float(b0.span_m)
        self.n_modes = b0.n_modes
        self.phi_mid = np.sin(b0.mode_numbers * np.pi / 2.0)
        self.M = np.array([b.modal_mass_kg for b in self.bridges])
        self.K = np.array([b.modal_stiffness_N_m for b in self.bridges])
        self._rows = 0
        self._mlm_rows = 0
        self._train_tables = None

    # ------------------------------------------------------------------ steps
    def n_steps(self, case, speeds_kmh):
        """Steps ``run_sweep`` takes for bridge ``case`` on a sweep over ``speeds_kmh``."""
        grid = make_grid(self.bridges[case], self.train.length_m, speeds_to_m_s(speeds_kmh), self.options)
        return grid.n_steps

    def _lane_steps(self, case, v_kmh, sweep):
        n = np.empty(case.size, dtype=np.int64)
        keys = np.stack([case, sweep], axis=1)
        for key in np.unique(keys, axis=0):
            lanes = (case == key[0]) & (sweep == key[1])
            n[lanes] = self.n_steps(int(key[0]), v_kmh[lanes])
        return n

    # ------------------------------------------------------------------ tables
    def _mlm_table(self, n_steps):
        if n_steps > self._mlm_rows:  # as mlm_modal_load_table on a grid of n_steps steps
            x = half_step_positions(self.ds_m, self.train.axle_offsets_m, 0, int(n_steps))
            self._P = modal_loads_at(self.bridges[0], x, np.asarray(self.train.axle_loads_n, dtype=float))
            self._mlm_rows = int(n_steps)
        return self._P

    def _dim_tables(self, n_steps):
        if n_steps <= self._rows:
            return
        b0, tr, ds = self.bridges[0], self.train, self.ds_m
        r = np.arange(2 * n_steps + 1)
        front = (r // 2 + 0.5 * (r % 2)) * ds  # == grid.front_m(k, stage) bit for bit
        x = front[:, None] - tr.axle_offsets_m[None, :]
        on = (x >= 0.0) & (x <= self.span_m)
        rows, axles = np.nonzero(on)
        ptr = _row_ptr(rows, r.size)
        phi, phx, phxx = b0.shapes(x[rows, axles])
        mw = tr.wheel_mass_kg[axles]
        outer = (phi * mw[:, None])[:, :, None] * phi[:, None, :]  # Eq. (13) terms per axle
        S = np.zeros((r.size, self.n_modes, self.n_modes))
        np.add.at(S, rows, outer)
        minv = np.empty((len(self.bridges), r.size, self.n_modes, self.n_modes))
        for c, M in enumerate(self.M):
            minv[c] = np.linalg.inv(np.diag(M)[None] + S)
        self._dim = dict(row_ptr=ptr, ent_axle=axles.astype(np.int64), ent_phi=np.ascontiguousarray(phi),
                         ent_phx=np.ascontiguousarray(phx), ent_phxx=np.ascontiguousarray(phxx), minv=minv)
        # vehicles active during step k (as TrainSide._active)
        t = self._trains()
        k = np.arange(n_steps)
        lo, hi = (k + 0.0) * ds, (k + 1.0) * ds
        act = (hi[:, None] - t["first"][None, :] >= 0.0) & (lo[:, None] - t["last"][None, :] <= self.span_m)
        krow, units = np.nonzero(act)
        self._dim.update(act_ptr=_row_ptr(krow, n_steps), act_units=units.astype(np.int64))
        self._rows = int(n_steps)

    def _trains(self):
        if self._train_tables is None:
            tr = self.train
            mats = [tr.unit_matrices(i) for i in range(len(tr.units))]
            n = sum(len(m.M) for m in mats)
            Ks, Cs, Lw = np.zeros((n, n)), np.zeros((n, n)), np.zeros((tr.n_axles, n))
            minv = np.zeros(n)
            kp, cp = np.zeros(tr.n_axles), np.zeros(tr.n_axles)
            dof0, ndof, ax0, nax, first, last = [], [], [], [], [], []
            d = 0
            for i, m in enumerate(mats):
                axles = tr.unit_axles(i)
                if not np.all(np.diff(axles) == 1):
                    raise InputError(f"train: unit {i} of {tr.name!r} has axles out of order")
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
                first.append(tr.axle_offsets_m[axles].min())
                last.append(tr.axle_offsets_m[axles].max())
                d += nn
            ks, cs, lw, lwt = _csr(Ks), _csr(Cs), _csr(Lw), _csr(Lw.T.copy())
            i64 = lambda a: np.asarray(a, dtype=np.int64)  # noqa: E731
            self._train_tables = dict(
                unit_dof0=i64(dof0), unit_ndof=i64(ndof), unit_ax0=i64(ax0), unit_nax=i64(nax),
                ks_ptr=ks[0], ks_col=ks[1], ks_val=ks[2], cs_ptr=cs[0], cs_col=cs[1], cs_val=cs[2],
                lw_ptr=lw[0], lw_col=lw[1], lw_val=lw[2], lwt_ptr=lwt[0], lwt_col=lwt[1], lwt_val=lwt[2],
                kp=kp, cp=cp, minv_dof=minv, first=np.array(first), last=np.array(last))
        return self._train_tables

    # ------------------------------------------------------------------ run
    @staticmethod
    def _blocks(case, sweep, n_steps):
        """Lane order and blocks of one bridge and one step count (they advance together, SIMD)."""
        order = np.lexsort((sweep, case))
        key = np.stack([case[order], n_steps[order]], axis=1)
        starts = np.flatnonzero(np.r_[True, np.any(key[1:] != key[:-1], axis=1)])
        block_ptr = np.r_[starts, order.size].astype(np.int64)
        return order, block_ptr, key[starts, 0].copy(), key[starts, 1].copy()

    def start(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None):
        """A :class:`BatchRun` of these lanes at step 0 (see :meth:`run` for the arguments)."""
        return BatchRun(self, model, case, speeds_kmh, delta_zeta, sweep)

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None):
        """Max |midspan acceleration| (m/s^2) and |deflection| (m) of every lane.

        Starts a :class:`BatchRun` and advances it to its end.

        Parameters
        ----------
        model : {"mlm", "dim"}
        case : array_like of int (n_lanes,)
            Index into ``bridges`` of each lane.
        speeds_kmh, delta_zeta : array_like (n_lanes,) or scalar
        sweep : array_like of int (n_lanes,), optional
            Lanes of one bridge with equal ``sweep`` form one sweep (the fastest of them sets its
            number of steps, as in ``run_sweep``); default: all lanes of a bridge form one sweep.

        Returns
        -------
        (max_acc_m_s2, max_disp_m) : ndarray (n_lanes,) each

        Raises
        ------
        RunError
            The solution of a lane is not finite (the run's one-line message).
        """
        run = self.start(model, case, speeds_kmh, delta_zeta, sweep)
        while run.status == RUNNING:
            run.advance()
        if run.status == FAILED:
            raise RunError(run.message)
        return run.max_acc_m_s2, run.max_disp_m


class BatchRun(SteppedRun):
    """A compiled batched run with the contract of :class:`~adm_sim.stepping.SteppedRun`.

    Owns step ``k``, status, message, the state of every lane, the running maxima and the
    finite-value check; :meth:`advance` moves every lane on by a block of steps through one call of
    the compiled kernel (:func:`adm_sim.kernels.mlm_blocks` / :func:`~adm_sim.kernels.dim_blocks`),
    then checks the state of every lane. A lane whose solution is not finite fails the run with a
    one-line message naming the step block, the bridge and the speed. Lanes of shorter sweeps stop
    at their own number of steps; ``n_steps`` is the longest. Advancing block by block gives bit
    for bit what one call over all steps gives.

    Attributes
    ----------
    max_acc_m_s2, max_disp_m : ndarray (n_lanes,)
        Running maxima of |midspan acceleration| (stage 0 of every step) and |deflection| (start
        of every step) over the steps done, in the caller's lane order.
    lane_steps : ndarray of int (n_lanes,)
        Number of steps of every lane.
    """

    #: Steps per :meth:`advance` by default: the finite check runs this often; one kernel call
    #: costs a few microseconds against ~1 ms of arithmetic for a block of this size.
    BLOCK_STEPS = 4096
    ADVANCE_STEPS = BLOCK_STEPS

    def __init__(self, runner, model, case, speeds_kmh, delta_zeta=0.0, sweep=None):
        check_model(model, runner.train)
        self.runner = runner
        self.model = model
        case = np.asarray(case, dtype=np.int64)
        n_l = case.size
        v_kmh = np.broadcast_to(np.asarray(speeds_kmh, dtype=float), (n_l,)).copy()
        v = speeds_to_m_s(v_kmh)
        dz = np.broadcast_to(np.asarray(delta_zeta, dtype=float), (n_l,)).copy()
        sweep = np.zeros(n_l, dtype=np.int64) if sweep is None else np.asarray(sweep, dtype=np.int64)
        if case.min() < 0 or case.max() >= len(runner.bridges):
            raise InputError(f"case: lane bridge index out of range [0, {len(runner.bridges) - 1}]")
        Z = np.empty((n_l, runner.n_modes))
        for c in np.unique(case):
            lanes = case == c
            b = runner.bridges[c]
            for x in np.unique(dz[lanes]):
                check_delta_zeta_pct("delta_zeta_pct", 100 * x, b.damping_ratio)
            Z[lanes] = b.modal_damping_Ns_m(dz[lanes])
        self.lane_steps = runner._lane_steps(case, v_kmh, sweep)
        self._case, self._v = case, v
        order, self._block_ptr, self._bcase, self._bsteps = runner._blocks(case, sweep, self.lane_steps)
        self._order = order
        h = runner.ds_m / v
        nm = runner.n_modes
        self._q, self._qd = np.zeros((nm, n_l)), np.zeros((nm, n_l))
        self._amax, self._dmax = np.zeros(n_l), np.zeros(n_l)
        self._prev = np.zeros((3, n_l))  # dense output: deflection, velocity, acceleration of the last step
        self._ho = h[order]
        n_max = int(self.lane_steps.max())
        if model == "mlm":
            self._P = runner._mlm_table(n_max)
            coef = mlm_rk4_coefficients(h[:, None], runner.M[case], Z, runner.K[case])
            self._T = [np.ascontiguousarray(a[order].T) for a in (Z, *(x for pair in coef for x in pair))]
        else:
            runner._dim_tables(n_max)
            n_dof = runner._trains()["minv_dof"].size
            self._u, self._ud = np.zeros((n_dof, n_l)), np.zeros((n_dof, n_l))
            self._vo, self._Zo = v[order], np.ascontiguousarray(Z[order])
        self._start_contract(n_max)

    def _step_impl(self):
        self._advance_impl(1)

    def _advance_impl(self, n):
        """Every lane by ``n`` steps in one kernel call (:meth:`SteppedRun.advance` owns the status)."""
        k0, k1 = self.k, self.k + n
        r = self.runner
        head = (self._block_ptr, self._bcase, self._bsteps, k0, k1)
        if self.model == "mlm":
            kernels.mlm_blocks(*head, self._P, r.phi_mid, r.M, r.K, *self._T,
                               self._q, self._qd, self._amax, self._dmax, r.dense_maxima, self._ho, self._prev)
            state = (self._q, self._qd)
        else:
            t, d = r._trains(), r._dim
            kernels.dim_blocks(
                *head, self._vo, self._ho, r.K, self._Zo, d["minv"], r.phi_mid,
                d["row_ptr"], d["ent_axle"], d["ent_phi"], d["ent_phx"], d["ent_phxx"],
                r.train.axle_loads_n, r.train.wheel_mass_kg,
                d["act_ptr"], d["act_units"], t["unit_dof0"], t["unit_ndof"], t["unit_ax0"], t["unit_nax"],
                t["ks_ptr"], t["ks_col"], t["ks_val"], t["cs_ptr"], t["cs_col"], t["cs_val"],
                t["lw_ptr"], t["lw_col"], t["lw_val"], t["lwt_ptr"], t["lwt_col"], t["lwt_val"],
                t["kp"], t["cp"], t["minv_dof"], self._q, self._qd, self._u, self._ud, self._amax, self._dmax,
                r.dense_maxima, self._prev)
            state = (self._q, self._qd, self._u, self._ud)
        self.k = k1
        def names():
            return [r.bridges[c].name or r.bridges[c].describe() for c in self._case[self._order]]

        with np.errstate(over="ignore", invalid="ignore"):  # a blown-up state is what we look for
            self._check_finite(f"{self.model.upper()} state", state, f"in steps {k0}..{k1} of {self.n_steps}",
                               self._v[self._order], r.ds_m, names)

    def _in_lane_order(self, a):
        out = np.empty_like(a)
        out[self._order] = a
        return out

    @property
    def max_acc_m_s2(self):
        return self._in_lane_order(self._amax)

    @property
    def max_disp_m(self):
        return self._in_lane_order(self._dmax)
