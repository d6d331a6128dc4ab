"""Batched runs: many bridges of one span and all their speeds as lanes of one compiled run.

A :class:`BatchRunner` holds a train and several bridges that share the span, the number of
modes and the damping model, and one space step ``ds``. Then the axle positions, the axles on
the bridge and their mode shapes (Eq. 6), the MLM modal loads and the active vehicles are the same
for every lane at every stage (as in :mod:`adm_sim.integrate.step_grid`); what differs per lane is only the
bridge's modal stiffness, damping and mass (the wheelset-modified mass matrix of Eq. 13 is
tabulated per bridge), the speed, the additional damping and the number of steps.

Each lane reproduces what :func:`adm_sim.integrate.sweep.run_sweep` gives for its bridge, speed and damping
with the same ``ds`` (to ~1e-13 relative: the same operations in the same order, only the
summation order of a few small dot products differs), including its number of steps, which
``run_sweep`` derives from the fastest speed of the sweep: :meth:`BatchRunner.run` takes the
``sweep`` id of every lane and gives all lanes of one (bridge, sweep) the steps that sweep needs.

A run is a :class:`BatchRun`: the contract of :class:`adm_sim.integrate.run_contract.SteppedRun` (step, status,
message, running maxima, finite-value check) over the compiled kernels, advanced block of steps
by block of steps.
"""

from __future__ import annotations


import numpy as np

from adm_sim.integrate import kernels
from adm_sim.integrate.contact import ContactCheck
from adm_sim.errors import InputError, RunError
from adm_sim.fields import FIELDS
from adm_sim.integrate.rk4_sides import mlm_rk4_coefficients
from adm_sim.integrate.run_contract import FAILED, RUNNING, AdvancingRun, check_model
from adm_sim.limits import check_memory
from adm_sim.integrate.mlm_loads import axles_on_deck, span_load_table
from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s
from adm_sim.integrate.tables import active_units, axle_rows, bridge_tables, vehicle_tables
from adm_sim.model.irregularity import check_step  # the profile's shortest feature against ds (scipy loads only when a profile is used)


def modal_load_table(bridge, ds_m, axle_offsets_m, axle_loads_n, n_steps):
    """Modal loads of Eq. (6) on the half-step grid of steps ``0..n_steps``, shape (2 n + 1, n_modes).

    Bit for bit :func:`adm_sim.integrate.mlm_loads.modal_loads_at` of
    :func:`adm_sim.integrate.mlm_loads.half_step_positions` (the same positions ``s - offset``, the same rows
    on the span, the same sums in the same axle order) without the table of every axle's position at
    every row ((2 n + 1) x n_axles: 47 MB for ICE-2 on a 4 m span), whose making and reading per
    column cost more than the loads: each axle's position is computed only on the rows where it can
    be on the span.
    """
    s = 0.5 * ds_m * np.arange(0, 2 * n_steps + 1)
    if bridge.is_continuous:
        return _deck_load_table(bridge, s, axle_offsets_m, axle_loads_n)
    return span_load_table(bridge, s, axle_offsets_m, axle_loads_n)


def _deck_load_table(bridge, s, axle_offsets_m, axle_loads_n):
    """:func:`modal_load_table` of a continuous deck: each axle's rows on the deck
    (:func:`adm_sim.integrate.mlm_loads.axles_on_deck`) added in axle order by the compiled
    :func:`adm_sim.integrate.kernels.add_deck_loads` (the deck's exact mode shapes, entry by entry:
    no (rows x axles) temporaries)."""
    out = np.zeros((s.size, bridge.n_modes))
    shapes = kernels.deck_shapes(bridge.deck)
    for load, r0, x in axles_on_deck(s, bridge.span_m, axle_offsets_m, axle_loads_n):
        kernels.add_deck_loads(out, int(r0), np.ascontiguousarray(x), float(load), shapes)
    return out


class BatchRunner:
    """Lanes of several bridges (same span) under one train, on one space grid.

    Parameters
    ----------
    bridges : sequence of adm_sim.model.bridge.Bridge
        Same ``span_m``, ``n_modes`` and ``damping_model``.
    train : adm_sim.model.trains.Train
    ds_m : float
        Train advance per step (m), shared by every lane.
    free_vibration_periods : float
        As :class:`~adm_sim.integrate.step_grid.StepOptions`.
    dense_maxima : bool
        As :class:`~adm_sim.integrate.step_grid.StepOptions`: also the maxima between the steps.
    irregularity : adm_sim.model.irregularity.Profile or None
        Track irregularity on the deck under every DIM wheel (Eq. 9 with the profile's terms);
        ``None``: smooth track. The MLM is unaffected.
    response_m : float or None
        Where the maxima are taken (m from the left abutment); None: midspan.
    """

    def __init__(self, bridges, train, ds_m, free_vibration_periods=2.0, dense_maxima=False, irregularity=None,
                 response_m=None):
        self.bridges = list(bridges)
        if not self.bridges:
            raise InputError("bridges: need at least one bridge for a batch")
        b0 = self.bridges[0]
        for b in self.bridges[1:]:
            deck = (b.spans_m, b.span_EJ_Nm2, b.span_mu_kg_m)  # a continuous deck's shapes are its own
            if (b.span_m, b.n_modes, b.damping_model) + deck != (b0.span_m, b0.n_modes, b0.damping_model,
                                                                 b0.spans_m, b0.span_EJ_Nm2, b0.span_mu_kg_m):
                raise InputError(f"bridges: a batch needs one span (one deck), mode count and damping model; "
                                 f"{b.name or b.describe()} differs from {b0.name or b0.describe()}")
        self.train = train
        self.options = StepOptions(free_vibration_periods=free_vibration_periods,
                                   ds_m=FIELDS["ds_m"].check(ds_m), dense_maxima=bool(dense_maxima))
        self.dense_maxima = bool(dense_maxima)
        self.irregularity = irregularity
        self.ds_m = float(ds_m)
        if irregularity is not None:  # its shortest feature against the space step
            check_step(irregularity, self.ds_m)
        self.span_m = float(b0.span_m)
        self.n_modes = b0.n_modes
        self.tables = bridge_tables(self.bridges, response_m)
        self.phi_mid, self.M, self.K = self.tables.phi_mid, self.tables.M, self.tables.K
        self._rows = 0
        self._mlm_rows = 0
        self._vehicles = None

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
    def table_bytes(self, model, n_steps):
        """Memory (bytes) of the tables a run of ``n_steps`` steps builds: the MLM modal loads
        ``(2 n + 1) x n_modes``; the DIM axle rows (every axle's mode shapes and slopes and curvatures
        on its ``2 L / ds + 1`` rows on the bridge, the profile under it) and the Eq. (13) inverses
        ``n_bridges x (2 n + 1) x n_modes^2``.

        Built whole, not per block of steps: a runner builds them once, for its longest run, and every
        later run of the runner reads the same rows again (a calibration's MLM and DIM runs, each Δζ
        of its root search, every phase of a study batch), so tables made per block would be made
        again for every run; the MLM table itself is built axle by axle
        (:func:`adm_sim.integrate.mlm_loads.span_load_table`, no rows x axles temporary)."""
        rows, nm = 2.0 * n_steps + 1.0, self.n_modes
        if model == "mlm":
            return 8.0 * rows * nm
        n_ax = self.train.n_axles
        entries = min(rows * n_ax, n_ax * (2.0 * self.span_m / self.ds_m + 1.0))
        return 8.0 * (entries * (3 * nm + 5) + len(self.bridges) * rows * nm * nm + rows * 2)

    def check_tables(self, model, n_steps):
        """Refuse (one-line InputError) tables beyond this machine's memory before building them."""
        check_memory(self.table_bytes(model, n_steps), f"the {model.upper()} tables of {n_steps} steps",
                     f"large because {n_steps} steps of ds = {self.ds_m * 1e3:.3g} mm x {self.n_modes} modes"
                     f"{'' if model == 'mlm' else f' x {len(self.bridges)} bridges (Eq. 13 inverses)'}; "
                     f"fewer modes or fewer steps per period make it smaller")

    def _mlm_table(self, n_steps):
        if n_steps > self._mlm_rows:  # mlm_modal_load_table on a grid of n_steps steps, bit for bit
            self.check_tables("mlm", n_steps)
            self._P = modal_load_table(self.bridges[0], self.ds_m, self.train.axle_offsets_m,
                                       self.train.axle_loads_n, int(n_steps))
            self._mlm_rows = int(n_steps)
        return self._P

    def _dim_tables(self, n_steps):
        """The axles on the bridge per half-step row and the active units per step, steps 0..n."""
        if n_steps <= self._rows:
            return
        self.check_tables("dim", n_steps)
        tr = self.train
        self._axle_rows = axle_rows(self.bridges, tr.axle_offsets_m, self.ds_m, 0, 2 * n_steps + 1,
                                    tr.wheel_mass_kg)
        self._units = active_units(self.vehicles(), self.span_m, self.ds_m, 0, n_steps)
        self._track = self._track_table(self._axle_rows, 2 * n_steps + 1)
        self._rows = int(n_steps)

    def _track_table(self, rows, n_rows):
        """:class:`adm_sim.integrate.kernels.Track` of every entry of ``rows``: the profile's elevation, slope
        and curvature at the axle, at the position :func:`adm_sim.integrate.tables.axle_rows` puts it (bit for bit
        the position ``TrainSide`` evaluates the profile at)."""
        n = rows.axle.size
        if self.irregularity is None:
            return kernels.Track(np.zeros(n), np.zeros(n), np.zeros(n))
        r = np.repeat(np.arange(n_rows), np.diff(rows.ptr))
        front = (r // 2 + 0.5 * (r % 2)) * self.ds_m
        x = front - np.asarray(self.train.axle_offsets_m, dtype=float)[rows.axle]
        elev, slope, curv = self.irregularity.evaluate(x, curvature=True)
        return kernels.Track(np.ascontiguousarray(elev), np.ascontiguousarray(slope), np.ascontiguousarray(curv))

    def vehicles(self):
        """The train's :class:`adm_sim.integrate.tables.VehicleTables` (built on first use)."""
        if self._vehicles is None:
            self._vehicles = vehicle_tables(self.train)
        return self._vehicles

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
            ``delta_zeta`` (fractions) as checked where the sweep was built
            (:func:`adm_sim.integrate.sweep.lane_damping`); not checked again here.
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


class BatchRun(AdvancingRun):
    """A compiled batched run with the contract of :class:`~adm_sim.integrate.run_contract.SteppedRun`.

    Owns step ``k``, status, message, the state of every lane, the running maxima and the
    finite-value check; :meth:`advance` moves every lane on by a block of steps through one call of
    the compiled kernel (:func:`adm_sim.integrate.kernels.mlm_blocks` / :func:`~adm_sim.integrate.kernels.dim_blocks`),
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
            self._lanes = kernels.MlmLanes(self._ho, *(np.ascontiguousarray(a[order].T)
                                                       for a in (Z, *(x for pair in coef for x in pair))))
            self._u = self._ud = np.zeros((0, n_l))
        else:
            runner._dim_tables(n_max)
            n_dof = runner.vehicles().minv_dof.size
            self._u, self._ud = np.zeros((n_dof, n_l)), np.zeros((n_dof, n_l))
            self._lanes = kernels.DimLanes(v[order], self._ho, np.ascontiguousarray(Z[order]))
        # the DIM's contact check (block order): smallest contact force, first tension
        self._contact = kernels.Contact(np.full(n_l, np.inf), np.full(n_l, -1, dtype=np.int64),
                                        np.full(n_l, -1, dtype=np.int64), np.zeros(n_l))
        self._blocks_t = kernels.Blocks(self._block_ptr, self._bcase, self._bsteps)
        self._state = kernels.LaneState(self._q, self._qd, self._u, self._ud, self._amax, self._dmax, self._prev)
        self._start_contract(n_max)

    def _step_impl(self):
        return self._advance_impl(1)

    def _advance_impl(self, n):
        """Every lane by ``n`` steps in one kernel call; ``(success, message)`` of the finite check."""
        k0, k1 = self.k, self.k + n
        r = self.runner
        if self.model == "mlm":
            kernels.mlm_blocks(self._blocks_t, k0, k1, self._lanes, r.tables, self._P, self._state, r.dense_maxima)
            state = (self._q, self._qd)
        else:
            kernels.dim_blocks(self._blocks_t, k0, k1, self._lanes, r.tables, r._axle_rows, r._units, r.vehicles(),
                               self._state, r.dense_maxima, r._track, self._contact)
            state = (self._q, self._qd, self._u, self._ud)
        self.k = k1
        def names():
            return [r.bridges[c].name or r.bridges[c].describe() for c in self._case[self._order]]

        with np.errstate(over="ignore", invalid="ignore"):  # a blown-up state is what we look for
            failure = self._not_finite(f"{self.model.upper()} state", state, f"in steps {k0}..{k1} of {self.n_steps}",
                                       self._v[self._order], r.ds_m, names)
        return failure is None, failure

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

    @property
    def contact(self):
        """The DIM's contact check in the caller's lane order (:class:`adm_sim.integrate.contact.ContactCheck`);
        ``None`` for the MLM."""
        if self.model != "dim":
            return None
        c = self._contact
        return ContactCheck(min_n=self._in_lane_order(c.min_n), first_k=self._in_lane_order(c.first_k),
                            first_axle=self._in_lane_order(c.first_axle), first_n=self._in_lane_order(c.first_n),
                            speeds_m_s=self._v.copy(), dt_s=self.runner.ds_m / self._v)
