"""The contract every run keeps, shaped like scipy's ``OdeSolver``: step, status, message.

:class:`SteppedRun` writes the public :meth:`~SteppedRun.step` (and
:meth:`~AdvancingRun.advance` for a run that needs no partner per step) once: only they set
status and message; an implementation provides ``_step_impl`` (or ``_advance_impl`` for a
block), which returns ``(success, message)``. The input a half receives from its partner is the
argument of ``step``; nothing else advances a run. Implementations: the numpy runs of
:mod:`adm_sim.integrate.lockstep_runs` and :class:`adm_sim.integrate.compiled_batch.BatchRun` (the compiled kernels).
"""

from __future__ import annotations

import math

import numpy as np

from adm_sim.errors import InputError
from adm_sim.fields import FIELDS

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
    whole step for :class:`~adm_sim.integrate.lockstep_runs.InProcessRun` and
    :class:`adm_sim.integrate.compiled_batch.BatchRun` (no partner) and for the MLM halves (the modal loads
    of a step); one RK4 stage of step ``k`` for the DIM halves (the exchange is per stage), ``k``
    then moves on with the fourth stage.

    Implementations: :class:`~adm_sim.integrate.lockstep_runs.InProcessRun` (the numpy stepper, both halves
    in one process, driven by :func:`adm_sim.integrate.sweep.run_sweep`),
    :class:`~adm_sim.integrate.lockstep_runs.BridgeHalf` and :class:`~adm_sim.integrate.lockstep_runs.TrainHalf` (what
    the bridge node and the train node each step, exchanging per RK4 stage or per block) and
    :class:`adm_sim.integrate.compiled_batch.BatchRun` (the compiled kernels, block of steps by block of
    steps).

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
