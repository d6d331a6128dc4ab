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
"""

from __future__ import annotations

import numpy as np

from adm_sim import kernels
from adm_sim.errors import InputError, check_range
from adm_sim.stepping import (StepOptions, half_step_positions, make_grid, mlm_rk4_coefficients, modal_loads_at,
                              speeds_to_m_s)


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
    """

    def __init__(self, bridges, train, ds_m, free_vibration_periods=2.0):
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
                                   ds_m=check_range("ds_m", ds_m, "m", 1e-5, 10.0))
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

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None):
        """Max |midspan acceleration| (m/s^2) and |deflection| (m) of every lane.

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
        """
        case = np.asarray(case, dtype=np.int64)
        n_l = case.size
        v_kmh = np.broadcast_to(np.asarray(speeds_kmh, dtype=float), (n_l,)).copy()
        v = speeds_to_m_s(v_kmh)
        dz = np.broadcast_to(np.asarray(delta_zeta, dtype=float), (n_l,)).copy()
        sweep = np.zeros(n_l, dtype=np.int64) if sweep is None else np.asarray(sweep, dtype=np.int64)
        if case.min() < 0 or case.max() >= len(self.bridges):
            raise InputError(f"case: lane bridge index out of range [0, {len(self.bridges) - 1}]")
        Z = np.empty((n_l, self.n_modes))
        for c in np.unique(case):
            lanes = case == c
            b = self.bridges[c]
            for x in np.unique(dz[lanes]):
                check_range("delta_zeta_pct", 100 * x, "%", -100 * b.damping_ratio, 20.0)
            Z[lanes] = b.modal_damping_Ns_m(dz[lanes])
        n_steps = self._lane_steps(case, v_kmh, sweep)
        h = self.ds_m / v
        acc = np.empty(n_l)
        disp = np.empty(n_l)
        if model == "mlm":
            P = self._mlm_table(int(n_steps.max()))
            (ax, axd), (bx, bxd), (c0, c0d), (ch, chd), (c1, c1d) = mlm_rk4_coefficients(
                h[:, None], self.M[case], Z, self.K[case])
            order, block_ptr, bcase, bsteps = self._blocks(case, sweep, n_steps)
            T = [np.ascontiguousarray(a[order].T) for a in (Z, ax, axd, bx, bxd, c0, c0d, ch, chd, c1, c1d)]
            acc_o, disp_o = np.empty(n_l), np.empty(n_l)
            bad = kernels.mlm_blocks(block_ptr, bcase, bsteps, P, self.phi_mid, self.M, self.K, *T, acc_o, disp_o)
            acc[order], disp[order] = acc_o, disp_o
        elif model == "dim":
            if not self.train.units:
                raise InputError(f"model: 'dim' needs a train with vehicles; {self.train.name!r} is a load train")
            self._dim_tables(int(n_steps.max()))
            t, d = self._trains(), self._dim
            order, block_ptr, bcase, bsteps = self._blocks(case, sweep, n_steps)
            acc_o, disp_o = np.empty(n_l), np.empty(n_l)
            bad = kernels.dim_blocks(
                block_ptr, bcase, bsteps, v[order], h[order], self.K,
                np.ascontiguousarray(Z[order]), d["minv"], self.phi_mid,
                d["row_ptr"], d["ent_axle"], d["ent_phi"], d["ent_phx"], d["ent_phxx"],
                self.train.axle_loads_n, self.train.wheel_mass_kg,
                d["act_ptr"], d["act_units"], t["unit_dof0"], t["unit_ndof"], t["unit_ax0"], t["unit_nax"],
                t["ks_ptr"], t["ks_col"], t["ks_val"], t["cs_ptr"], t["cs_col"], t["cs_val"],
                t["lw_ptr"], t["lw_col"], t["lw_val"], t["lwt_ptr"], t["lwt_col"], t["lwt_val"],
                t["kp"], t["cp"], t["minv_dof"], acc_o, disp_o)
            acc[order], disp[order] = acc_o, disp_o
        else:
            raise InputError(f"model: {model!r} is not allowed; allowed 'mlm' or 'dim'")
        if bad:
            raise InputError("solution is not finite: the step is too large for this bridge/train "
                             "(raise steps_per_period)")
        return acc, disp
