"""The lane runner: the one thing a calibration asks of a backend.

A calibration (paper Section 4, :mod:`adm_calib.calibrate`) needs nothing from a solver but the
largest midspan acceleration of many independent runs, each a **lane**: a case (a bridge of the
batch), a speed, an additional damping Δζ and a sweep id. Lanes of one case with one sweep id form
one speed sweep: the fastest of them sets its number of steps, exactly as
:func:`adm_sim.integrate.sweep.run_sweep` does, so every backend discretises a lane alike. Every request
also names its **phase** (what the calibration is doing: ``"mlm"``, ``"dim"``, ``"dim_refine"``,
``"ladder"``, ``"root"``, ``"check"``, ``"adapted"``, ``"mlm_refine"``, ``"dim_peak_refine"``) so
that a backend that records or shows its runs (the ROS co-simulation) need not guess it.

Every backend that sees the DIM's contact forces (the compiled and the numpy lanes) keeps a
``contact_log``: per case, the speeds (km/h) of the DIM lanes in which a wheel would lift off, each
with its first loss (:meth:`adm_sim.integrate.contact.ContactCheck.first`); a calibration whose DIM peak
comes from such a lane is not ``ok`` (:func:`contact_loss_at`).

**The governing point** (:func:`response_points_m`): a lane's maximum is taken at midspan of a
simply supported span (paper Section 4); on a continuous deck (:mod:`adm_sim.model.spans`) it is the
largest of the maxima at the middle of every span, the same points for the MLM and the DIM, so a
calibration matches the deck's largest midspan peak whichever span carries it. The compiled and
the numpy lanes run a deck once per span's midspan (the DIM's contact check is the same run's,
kept once); a sweep hook answers for the point its own runs use.

Backends (all give the same numbers: the compiled lanes equal the numpy stepper to ~1e-13
relative, the co-simulation equals it bit for bit):

* :class:`CompiledLanes`: every lane of a request as lanes of one compiled run
  (:class:`adm_sim.integrate.compiled_batch.BatchRunner`); the default of ``calibrate`` and the study.
* :class:`SteppedLanes`: the numpy stepper, one :func:`adm_sim.integrate.sweep.run_sweep` per sweep.
* :class:`HookLanes`: any ``sweep(model, speeds_kmh, delta_zeta, step[, phase=...])`` callable
  of one case, one call per sweep: the ROS calibration node (co-simulated runs), a cluster.
"""

from __future__ import annotations

import inspect

import numpy as np

from adm_sim.errors import RunError
from adm_sim.integrate.run_contract import FAILED, RUNNING
from adm_sim.protocol import CALIBRATION_PHASES
from adm_sim.integrate.sweep import run_sweep

#: Phases of a calibration, in the order they run (named once, with their run phases, in the protocol).
PHASES = tuple(CALIBRATION_PHASES)


def _groups(case, sweep):
    """Lane indices of every (case, sweep) pair, in first-seen order."""
    keys = {}
    for i, key in enumerate(zip(case.tolist(), sweep.tolist())):
        keys.setdefault(key, []).append(i)
    return [(k[0], np.array(ix)) for k, ix in keys.items()]


def _log_contact(log, case, speeds_kmh, check):
    """Fold the lanes of ``check`` (:class:`adm_sim.integrate.contact.ContactCheck`, or its JSON form from
    a co-simulated run) that lost contact into ``log``: case -> {speed rounded to 1e-9 km/h: first
    loss}; the first loss of a speed stays."""
    if check is None:
        return
    losses = check["losses"] if isinstance(check, dict) else check.losses()
    for loss in losses:
        i = loss["lane"]
        speed = round(float(speeds_kmh[i]), 9)
        log.setdefault(int(case[i]), {}).setdefault(speed, {
            "speed_kmh": speed, "time_s": loss["time_s"], "axle": loss["axle"], "force_n": loss["force_n"]})


def contact_loss_at(lanes, case, speed_kmh):
    """The first loss of contact of a DIM lane of ``case`` at ``speed_kmh`` that ``lanes`` ran (its
    ``contact_log``), or ``None`` (also for a backend that keeps no log)."""
    log = getattr(lanes, "contact_log", None) or {}
    return log.get(int(case), {}).get(round(float(speed_kmh), 9))


def contact_message(loss):
    """One line for a calibration whose DIM peak comes from a lane that lost contact."""
    return (f"the DIM peak at {loss['speed_kmh']:g} km/h comes from a run in which the wheel of axle {loss['axle']} "
            f"would lift off the rail (t = {loss['time_s']:.4g} s, contact force {loss['force_n'] / 1e3:.4g} kN < 0); "
            f"the DIM assumes every wheel stays on the rail")


def response_points_m(bridge):
    """The governing points of a calibration (m from the left abutment): ``(None,)`` for a simply
    supported span (midspan, the kernels' ``sin(j pi / 2)``), the middle of every span of a continuous
    deck, left to right, shape (n_spans,)."""
    if not bridge.is_continuous:
        return (None,)
    return tuple(float(a + 0.5 * L) for a, L in zip(bridge.supports_m[:-1], bridge.spans_m))


def _lane_arrays(case, speeds_kmh, delta_zeta, sweep):
    case = np.asarray(case, dtype=np.int64)
    v = np.broadcast_to(np.asarray(speeds_kmh, dtype=float), case.shape).copy()
    dz = np.broadcast_to(np.asarray(delta_zeta, dtype=float), case.shape).copy()
    sw = np.zeros(case.shape, np.int64) if sweep is None else np.asarray(sweep, dtype=np.int64)
    return case, v, dz, sw


class CompiledLanes:
    """Lanes as one compiled batched run (:class:`adm_sim.integrate.compiled_batch.BatchRunner`).

    Parameters
    ----------
    bridges : sequence of adm_sim.model.bridge.Bridge
        The cases (one span, mode count and damping model).
    train : adm_sim.model.trains.Train
    step : adm_sim.integrate.step_grid.StepOptions
        With ``ds_m`` set: the space step shared by every lane.
    """

    name = "compiled"

    def __init__(self, bridges, train, step):
        from adm_sim.integrate.compiled_batch import BatchRunner  # noqa: PLC0415  numba kernels: the stepped backends run without

        self.runners = [BatchRunner(bridges, train, step.ds_m, step.free_vibration_periods, step.dense_maxima,
                                    irregularity=step.irregularity, response_m=x)
                        for x in response_points_m(bridges[0])]
        self.runner = self.runners[0]
        self.contact_log = {}

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase=""):
        """Max |acceleration| (m/s^2) at the governing point of every lane, shape (n_lanes,)."""
        case, v, dz, sw = _lane_arrays(case, speeds_kmh, delta_zeta, sweep)
        if case.size == 0:
            return np.zeros(0)
        out = None
        for runner in self.runners:
            run = runner.start(model, case, v, dz, sweep=sw)  # BatchRunner.run, keeping the contact check
            while run.status == RUNNING:
                run.advance()
            if run.status == FAILED:
                raise RunError(run.message)
            if out is None:  # the contact forces do not depend on the response point: one log
                _log_contact(self.contact_log, case, v, run.contact)
                out = run.max_acc_m_s2
            else:
                out = np.maximum(out, run.max_acc_m_s2)
        return out


class SteppedLanes:
    """Lanes on the numpy stepper: one :func:`adm_sim.integrate.sweep.run_sweep` per (case, sweep)."""

    name = "numpy"

    def __init__(self, bridges, train, step):
        self.bridges, self.train, self.step = list(bridges), train, step
        self.contact_log = {}

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase=""):
        case, v, dz, sw = _lane_arrays(case, speeds_kmh, delta_zeta, sweep)
        out = np.empty(case.size)
        for c, ix in _groups(case, sw):
            for k, x in enumerate(response_points_m(self.bridges[c])):
                res = run_sweep(self.bridges[c], self.train, model, v[ix], delta_zeta=dz[ix], options=self.step,
                                where="midspan" if x is None else x)
                if k == 0:  # the contact forces do not depend on the response point: one log
                    out[ix] = res.max_acc_m_s2
                    _log_contact(self.contact_log, case[ix], v[ix], res.contact)
                else:
                    out[ix] = np.maximum(out[ix], res.max_acc_m_s2)
        return out


class HookLanes:
    """Lanes of one case through a sweep callable, one call per sweep.

    ``sweep(model, speeds_kmh (n,), delta_zeta (n,) or float, step)`` returns the maximum midspan
    accelerations (m/s^2), or a dict of them (``max_acc_m_s2``) and the run's DIM contact check
    (``contact``, :meth:`adm_sim.integrate.contact.ContactCheck.to_dict`: the ROS calibration node),
    which goes into :attr:`contact_log`; if it takes a ``phase`` keyword, it gets the phase of the
    request. A sweep whose lanes share one damping passes it as a float.
    """

    name = "hook"

    def __init__(self, sweep, step):
        self.sweep, self.step = sweep, step
        self.contact_log = {}
        try:
            self._phase = "phase" in inspect.signature(sweep).parameters
        except (TypeError, ValueError):  # builtins without a signature
            self._phase = False

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase=""):
        case, v, dz, sw = _lane_arrays(case, speeds_kmh, delta_zeta, sweep)
        if np.any(case != 0):
            raise ValueError("HookLanes: a sweep hook runs one case (case 0) only")
        out = np.empty(case.size)
        for _, ix in _groups(case, sw):
            d = dz[ix]
            d = float(d[0]) if np.all(d == d[0]) else d
            kw = {"phase": phase} if self._phase else {}
            res = self.sweep(model, v[ix], d, self.step, **kw)
            if isinstance(res, dict):
                _log_contact(self.contact_log, case[ix], v[ix], res.get("contact"))
                res = res["max_acc_m_s2"]
            out[ix] = np.asarray(res, dtype=float)
        return out


# ---------------------------------------------------------------------- requests
class Requests:
    """Sweeps of one lane-runner request built case by case: (case, speeds, damping) per sweep."""

    def __init__(self):
        self.parts = []

    def add(self, case, speeds, dz=0.0):
        speeds = np.asarray(speeds, dtype=float)
        self.parts.append((case, speeds, np.broadcast_to(np.asarray(dz, float), speeds.shape)))

    def run(self, lanes, model, phase):
        """Run every sweep as lanes of one request (sweep id = its index); the maxima per sweep."""
        if not self.parts:
            return []
        case = np.concatenate([np.full(p[1].size, p[0]) for p in self.parts])
        v = np.concatenate([p[1] for p in self.parts])
        dz = np.concatenate([p[2] for p in self.parts])
        sw = np.concatenate([np.full(p[1].size, k) for k, p in enumerate(self.parts)])
        acc = np.asarray(lanes.run(model, case, v, dz, sweep=sw, phase=phase), dtype=float)
        out, i = [], 0
        for p in self.parts:
            out.append(acc[i:i + p[1].size])
            i += p[1].size
        return out


class ProgressLanes:
    """A lane runner that reports every finished request: ``progress(n_done, None, phase)``."""

    def __init__(self, lanes, progress):
        self.lanes, self.progress, self.done = lanes, progress, 0

    @property
    def contact_log(self):
        return getattr(self.lanes, "contact_log", None)

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase=""):
        out = self.lanes.run(model, case, speeds_kmh, delta_zeta, sweep, phase)
        self.done += 1
        self.progress(self.done, None, phase)
        return out
