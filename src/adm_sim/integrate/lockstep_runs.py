"""The numpy runs on the :class:`~adm_sim.integrate.run_contract.SteppedRun` contract: in one process or as two halves.

:class:`InProcessRun` holds both subsystems (:func:`adm_sim.integrate.sweep.run_sweep`); :class:`BridgeHalf`
(the bridge node: ``rail_state`` is sent, ``step(interaction_n)`` per DIM stage,
``step(p0, ph, p1)`` with the stage-point modal loads per MLM step) and :class:`TrainHalf` (the
train node: ``step(idx_on, w, wd)`` per DIM stage leaves the forces in ``interaction_n``;
``advance(n)`` books an MLM axle block) each hold one. Every path calls the same
:class:`~adm_sim.integrate.rk4_sides.BridgeSide` / :class:`~adm_sim.integrate.rk4_sides.TrainSide` methods in the same
order, so the co-simulated runs equal the in-process ones bit for bit. The runs holding the bridge
keep the running maxima of the midspan response and its finite check.
"""

from __future__ import annotations

import numpy as np

from adm_sim.integrate.contact import ContactTracker
from adm_sim.integrate.dense_output import hermite_max_abs_acc
from adm_sim.integrate.run_contract import AdvancingRun, SteppedRun, check_model


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
        self._contact = ContactTracker(grid) if model == "dim" else None  # the DIM's contact check
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

    @property
    def contact(self):
        """The DIM's contact check over the steps done (:class:`adm_sim.integrate.contact.ContactCheck`):
        smallest contact force and first tension per lane; ``None`` for the MLM."""
        return None if self._contact is None else self._contact.check()

    def _forces(self, interaction_n):
        """DIM: advance stage (k, stage) of the bridge with the interaction forces (n_lanes, n_on).

        Returns ``(success, message)``.
        """
        self.bridge_side.take_forces(interaction_n)
        failure = None
        if self.stage == 0:
            b = self.bridge_side
            self._contact.take(self.k, b.last_axles, b.last_contact_n)
            failure = self._take_acc()
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
    """Both halves in one process (:func:`adm_sim.integrate.sweep.run_sweep`): :meth:`step` advances one
    whole step including the per-stage exchange.

    A DIM stage is :meth:`~adm_sim.integrate.rk4_sides.BridgeSide.rail_state` -> :meth:`~adm_sim.integrate.rk4_sides.TrainSide.take_rail_state` ->
    :meth:`~adm_sim.integrate.rk4_sides.BridgeSide.take_forces`, the calls :class:`BridgeHalf` and :class:`TrainHalf` make in
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
        MLM modal loads of Eq. (6) on the half-step grid (:func:`adm_sim.integrate.mlm_loads.mlm_modal_load_table`).
    dense_maxima : bool
        Fold the maxima between the steps (dense output, :func:`hermite_max_abs_acc`) into
        :attr:`max_acc_m_s2`.

    Attributes: those of :class:`_BridgeRun`, and ``axles0``, ``interaction0_n``: the stage-0
    exchange of the step in progress (DIM).
    """

    def __init__(self, model, grid, bridge_side, *, train_side=None, modal_loads=None, dense_maxima=False):
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
        return self.axles0, self.bridge_side.last_contact_n


class BridgeHalf(_BridgeRun):
    """The bridge half of a co-simulated run (the bridge node): a :class:`~adm_sim.integrate.rk4_sides.BridgeSide` alone.

    DIM, per RK4 stage: :meth:`rail_state` (the state sent to the train; it does not advance),
    then :meth:`step` ``(interaction_n)`` with the partner's interaction forces (n_lanes, n_on),
    which advances the stage. At stage 0 the midspan acceleration is checked and folded into the
    maxima; at the end of the step the deflection of the next one. MLM: :meth:`step`
    ``(p0, ph, p1)`` per step with the modal loads of the stage points. Keeps the maxima and the
    finite check as :class:`InProcessRun` does (attributes there). It has no ``advance``: every
    step needs the partner's exchange.
    """

    def __init__(self, model, grid, bridge_side, *, dense_maxima=False):
        super().__init__(model, grid, bridge_side, dense_maxima)

    def rail_state(self):
        """DIM: rail state under the axles at (k, stage); see :meth:`~adm_sim.integrate.rk4_sides.BridgeSide.rail_state`."""
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

    DIM: a :class:`~adm_sim.integrate.rk4_sides.TrainSide`; :meth:`step` ``(idx_on, w, wd)`` per RK4 stage takes the bridge's
    rail state (see :meth:`~adm_sim.integrate.rk4_sides.TrainSide.take_rail_state`), advances the stage and leaves the
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
