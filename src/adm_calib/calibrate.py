"""Calibration of the additional damping Δζ_VBI for one bridge and one train (paper Section 4).

Steps (Section 4, steps 1-3):

1. Maximum midspan acceleration against speed for the MLM (every speed of the range, default
   160..350 km/h at 1 km/h) and the DIM.
2. The MLM peak (highest interior local maximum) and the associated DIM peak, by the rules of
   :mod:`adm_calib.peaks`. No MLM peak, or no DIM value near it, is a reported outcome
   (``status``), never a silent number.
3. Δζ_VBI solves ``f(dz) = peak_MLM(zeta + dz) / peak_DIM - 1 = 0``. The MLM peak is re-located
   at every trial damping as the largest MLM value within ``relocation_window_kmh`` of the MLM
   peak speed (a max over a fixed window is continuous in ``dz``). The root is bracketed by one
   vectorised MLM run over a ladder of trial dampings (negative down to ``-0.95 zeta``, positive
   up to 20 %), then found by :func:`scipy.optimize.elementwise.find_root` (Chandrupatla,
   vectorised over the cases of a batch) to ``xtol`` (5e-7 = 0.00005 %, half a unit of the fourth
   decimal of Δζ in percent that a calibration prints; the study 1e-8), well inside the paper's
   acceptance of 0.1 % in the peak value, which is checked.
4. A given speed grid that cannot show the resonance (too coarse, or a range without one) is a
   status of its own (:func:`speed_grid_finding`), not "ok".
5. A DIM peak from a run in which a wheel would lift off the rail (a tensile contact force,
   :mod:`adm_sim.integrate.contact`) breaks the DIM's own assumption: status ``contact_lost``.

6. A matched Δζ_VBI whose MLM peak or DIM value lies at an end of the speed range, or whose DIM
   value is no local maximum, is computed but not determined (Section 4, Step 2):
   :func:`adm_calib.peaks.determination`, statuses ``range_end`` and ``not_associated``, with the
   advice to extend the speed range.

Statuses (:data:`adm_calib.peaks.STATUSES`): ``ok``, ``no_mlm_peak``, ``no_dim_peak``,
``not_bracketed``, ``no_match``, ``grid_too_coarse``, ``no_resonance_in_range``, ``range_end``,
``not_associated``, ``contact_lost``.

DIM speeds (``dim_grid="paper"``, Section 3.3): 5 km/h steps over the range plus the MLM step
(1 km/h) on ``[v_max - 20, v_max + 5]`` around the MLM peak, all in one run; if the associated DIM
value lies where only the coarse grid was run, the DIM is run again at the fine step on
``+-5 km/h`` around it (``dim_refined``). ``dim_grid="full"`` runs the DIM at every MLM speed.
``dim_grid="window"`` (the study's default) runs only the paper's speeds where the associated peak
can lie (:func:`~adm_calib.speed_grids.dim_speeds_window`), and the rest of the paper grid for a case
whose association that part cannot decide (:func:`adm_calib.peaks.association_decided`): the same
DIM values, peaks and Δζ as ``paper``, with about half the DIM lanes.

All runs of one calibration share one space step ``ds`` (the one the full MLM speed range needs),
so the MLM curves at different dampings and the DIM curve are discretised alike.

Refined mode (``speed_refinement_kmh``, e.g. 0.05 km/h; off by default, the paper's 1 km/h
rule): both peaks located between the grid neighbours of the sampled peak (:func:`refine_peaks`).

Written once (:func:`calibrate_cases`), vectorised over the cases of a batch, over a lane runner
(:mod:`adm_calib.lanes`: run these lanes -> their maxima): :func:`calibrate` is the batch of one
on the compiled backend (or the numpy stepper, or a sweep hook such as the ROS co-simulation),
:func:`adm_calib.calibrate.calibrate_batch` the study's batches.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from adm_sim.errors import InputError
from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s

from adm_calib import peaks as pk
from adm_calib.calibration_options import CalibrationOptions, check_speeds
from adm_calib.calibration_result import make_result
from adm_calib.damping_root import solve_delta_zetas
from adm_calib.lanes import CompiledLanes, HookLanes, ProgressLanes, Requests, SteppedLanes, contact_loss_at, contact_message
from adm_calib.speed_grids import (REFINE_COARSE_KMH, dim_refinement, dim_speeds_paper, dim_speeds_window, merge_curve,
                                   relocate_peaks, relocation_speeds, speed_grid_finding)


def calibration_step(bridge, train, speeds_kmh=None, options=None):
    """The core's step settings shared by every run of one calibration (fixed ``ds_m``)."""
    opt = options or CalibrationOptions()
    v = check_speeds(speeds_kmh)
    base = opt.step or StepOptions()
    return replace(base, ds_m=make_grid(bridge, train.length_m, speeds_to_m_s(v), base).ds_m)


def batch_step(bridges, train, speeds_kmh=None, options=None):
    """Shared step settings of a batch: the smallest ``ds`` of the bridges' own calibrations.

    The study batches the six mass functions of one (span, frequency) pair, whose own steps are
    equal (the step depends on the highest mode's frequency only), so every case runs on exactly
    the grid it would get alone.
    """
    opt = options or CalibrationOptions()
    v = check_speeds(speeds_kmh)
    ds = min(calibration_step(b, train, v, opt).ds_m for b in bridges)
    return replace(opt.step or StepOptions(), ds_m=ds)


def calibrate_cases(bridges, train, lanes, speeds_kmh=None, *, options=None, step=None, adapted_curve=False,
                    dim_curves=None, on_trial=None):
    """Section 4 (steps 1-3) for every case of a batch, each phase one request to ``lanes``.

    The one calibration of the project; :func:`calibrate` is the batch of one and
    :func:`adm_calib.calibrate.calibrate_batch` the study's batches.

    1. one MLM request: every case x every speed (phase ``"mlm"``); the MLM peak of each case by
       :func:`adm_calib.peaks.find_peak`;
    2. one DIM request over every case's Section 3.3 speeds (``"dim"``), the association of
       :func:`adm_calib.peaks.associate_peak`, then at most two refinement requests
       (``"dim_refine"``) where the associated value lies on the coarse grid;
    3. :func:`solve_delta_zetas` over the relocation windows (``"ladder"``, ``"root"``,
       ``"check"``);

    Refined mode (``options.speed_refinement_kmh``): after step 1 the MLM peak is located between
    its neighbours on the MLM grid by :func:`refine_peaks` (``"mlm_refine"``), after step 2 the
    associated DIM peak likewise (``"dim_peak_refine"``); the DIM grid and the association use
    the MLM peak as sampled on the grid (the paper's rules), the relocation window of step 3 is the
    grid's window plus the finest pass around the refined peak. The refinement lanes of each
    case form their own sweep (their step count follows their own fastest speed, as any sweep's).
    4. with ``adapted_curve``, the MLM at ``zeta + Δζ_VBI`` over every speed (``"adapted"``).

    Parameters
    ----------
    bridges : sequence of adm_sim.model.bridge.Bridge
    train : adm_sim.model.trains.Train
    lanes : lane runner
        A backend of :mod:`adm_calib.lanes` built on ``bridges``, ``train`` and ``step``.
    speeds_kmh : array_like, optional
        MLM speeds (km/h); default 160..350 at 1 km/h.
    options : CalibrationOptions, optional
    step : adm_sim.integrate.step_grid.StepOptions, optional
        The shared step (``ds_m`` set), for the results; default :func:`batch_step`.
    adapted_curve : bool
    dim_curves : sequence of (ndarray, ndarray) or None, optional
        Per case a target curve ``(speeds_kmh, max_acc_m_s2)`` used instead of running the DIM.
    on_trial : callable(case, delta_zeta, mlm_peak_m_s2, dim_peak_m_s2), optional

    Returns
    -------
    list of CalibrationResult
        One per case, in order. ``timings_s`` holds the batch's phase times divided by its size.
    """
    opt = options or CalibrationOptions()
    v = check_speeds(speeds_kmh)
    step = step or batch_step(bridges, train, v, opt)
    timings = {}
    t0 = time.perf_counter()
    mlm = _mlm_step(lanes, v, len(bridges), opt)
    timings["mlm_sweep"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    dim = _dim_step(lanes, v, mlm, opt=opt, dim_curves=dim_curves)
    timings["dim_sweep"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    solves, adapted = _solve_step(lanes, v, mlm, dim.peaks, zetas=[b.damping_ratio for b in bridges], opt=opt,
                                  adapted_curve=adapted_curve, on_trial=on_trial)
    timings["solve"] = time.perf_counter() - t0
    per_case = _per_case(timings, len(bridges))
    return [make_result(bridge=b, train=train, **_status(lanes, v, c, bridge=b, train=train, mlm=mlm, dim=dim, solve=solves[c]),
                        solve=solves[c],
                        mlm_peak=mlm.peaks[c], dim_peak=dim.peaks[c], mlm_curve=(mlm.speeds[c], mlm.acc[c]),
                        dim_curve=(dim.speeds[c], dim.acc[c]), adapted_curve=adapted[c],
                        dim_grid="given" if dim_curves is not None else opt.dim_grid, dim_refined=dim.refined[c],
                        ds_m=step.ds_m, timings_s=per_case)
            for c, b in enumerate(bridges)]


class _MlmCurves(NamedTuple):
    """Step 1 of every case: the MLM speeds and maxima, the MLM peak (refined in the refined mode) and the
    peak as sampled on the MLM grid (the DIM grid and the association use it)."""

    speeds: list
    acc: list
    peaks: list
    sampled: list


def _mlm_step(lanes, v, n, opt):
    """Step 1: one MLM request, every case x every speed (phase ``"mlm"``), the MLM peak of each case
    (:func:`adm_calib.peaks.find_peak`); in the refined mode each peak located between its grid
    neighbours (``"mlm_refine"``, :func:`~adm_calib.speed_grids.relocate_peaks`)."""
    req = Requests()
    for c in range(n):
        req.add(c, v)
    mlm = req.run(lanes, "mlm", "mlm")
    mlm_peaks = [pk.find_peak(v, mlm[c], opt.min_prominence_rel) for c in range(n)]
    sampled_peaks = list(mlm_peaks)  # on the MLM grid: the DIM grid and the association use these
    vm = [v] * n
    if opt.speed_refinement_kmh is not None:
        vm, mlm, mlm_peaks = relocate_peaks(lanes, "mlm", "mlm_refine", speeds=vm, curves=mlm, peaks=mlm_peaks,
                                             resolution_kmh=opt.speed_refinement_kmh)
    return _MlmCurves(vm, mlm, mlm_peaks, sampled_peaks)


class _DimCurves:
    """Step 2 of every case: the DIM speeds and maxima, the associated DIM peak, whether the curve was
    refined, and for the window grid the paper speeds not run yet (``missing``; None: the curve holds
    the whole paper grid). Built by :meth:`run` (or :meth:`given`), completed in place."""

    def __init__(self, speeds, acc, missing, sampled, opt):
        n = len(speeds)
        self.speeds, self.acc, self.missing, self.sampled, self.opt = speeds, acc, missing, sampled, opt
        self.peaks = [pk.Peak(found=False, reason="no MLM peak to associate with")] * n
        self.refined = [False] * n

    @classmethod
    def given(cls, dim_curves, sampled, opt):
        """Per case a target curve ``(speeds_kmh, max_acc_m_s2)`` instead of the DIM, sorted by speed."""
        vd, dim = [], []
        for curve in dim_curves:
            s, a = (np.asarray(x, dtype=float) for x in curve)
            order = np.argsort(s)
            vd.append(s[order])
            dim.append(a[order])
        return cls(vd, dim, [None] * len(vd), sampled, opt)

    @classmethod
    def run(cls, lanes, v, sampled, opt):
        """One DIM request (phase ``"dim"``) over every case's Section 3.3 speeds: the paper grid, all
        speeds (``full``), or the part of the paper grid where the associated peak can lie (``window``)."""
        n = len(sampled)
        vd = [v if opt.dim_grid == "full" else dim_speeds_paper(v, p.speed_kmh if p.found else None, opt)
              for p in sampled]
        run_v = list(vd)
        if opt.dim_grid == "window":  # the paper's speeds where the associated peak can lie
            for c, p in enumerate(sampled):
                vd[c], run_v[c] = dim_speeds_window(vd[c], p.speed_kmh, opt) if p.found else (vd[c][:0], vd[c][:0])
        req = Requests()
        for c in range(n):
            req.add(c, run_v[c])
        dim = [acc[:vd[c].size] for c, acc in enumerate(req.run(lanes, "dim", "dim"))]
        missing = [None] * n
        if opt.dim_grid == "window":
            missing = [np.setdiff1d(dim_speeds_paper(v, p.speed_kmh, opt), vd[c]) if p.found else None
                       for c, p in enumerate(sampled)]
        return cls(vd, dim, missing, sampled, opt)

    def associate(self, c):
        """The DIM peak of case ``c`` associated with its sampled MLM peak (:func:`adm_calib.peaks.associate_peak`)."""
        opt = self.opt
        self.peaks[c] = pk.associate_peak(self.speeds[c], self.acc[c], self.sampled[c].speed_kmh,
                                          opt.association_window_kmh, min_prominence_rel=opt.min_prominence_rel)

    def complete_undecided(self, lanes, cases):
        """Run the rest of the paper grid for the window-grid cases whose association is not certain."""
        opt = self.opt
        todo = [c for c in cases if self.missing[c] is not None and self.missing[c].size and not pk.association_decided(
            self.speeds[c], self.acc[c], self.sampled[c].speed_kmh, opt.association_window_kmh,
            min_prominence_rel=opt.min_prominence_rel)]
        req = Requests()
        for c in todo:
            req.add(c, self.missing[c])
        for c, acc in zip(todo, req.run(lanes, "dim", "dim_refine")):
            self.speeds[c], self.acc[c] = merge_curve(self.speeds[c], self.acc[c], self.missing[c], acc)
            self.missing[c] = None

    def refine(self, lanes, v, found):
        """At most two refinement requests (``"dim_refine"``) where the associated value lies on the coarse
        grid (:func:`~adm_calib.speed_grids.dim_refinement`); the second for the cases refined by the first."""
        for round_ in range(2):
            req, which = Requests(), []
            for c in range(len(found)):
                extra = dim_refinement(v, self.speeds[c], self.peaks[c]) if found[c] else None
                if extra is not None and (round_ == 0 or self.refined[c]):
                    req.add(c, extra)
                    which.append((c, extra))
            if not which:
                break
            for (c, extra), acc in zip(which, req.run(lanes, "dim", "dim_refine")):
                self.speeds[c], self.acc[c] = merge_curve(self.speeds[c], self.acc[c], extra, acc)
                self.refined[c] = True
            self.complete_undecided(lanes, [c for c, _ in which])
            for c, _ in which:
                self.associate(c)


def _dim_step(lanes, v, mlm, *, opt, dim_curves=None):
    """Step 2: the DIM curves (run, or ``dim_curves`` given), the association with the sampled MLM peak,
    the refinements, in the refined mode the DIM peak located between its grid neighbours
    (``"dim_peak_refine"``); a window grid's curve does not reach the ends of the range, so its peak's
    ``max_at_range_end`` is unknown (None)."""
    given = dim_curves is not None
    dim = _DimCurves.given(dim_curves, mlm.sampled, opt) if given else _DimCurves.run(lanes, v, mlm.sampled, opt)
    found = [p.found for p in mlm.peaks]
    dim.complete_undecided(lanes, [c for c in range(len(found)) if found[c]])
    for c in range(len(found)):
        if found[c]:
            dim.associate(c)
    if not (opt.dim_grid == "full" or given):
        dim.refine(lanes, v, found)
    if opt.speed_refinement_kmh is not None and not given:
        dim.speeds, dim.acc, dim.peaks = relocate_peaks(lanes, "dim", "dim_peak_refine", speeds=dim.speeds,
                                                        curves=dim.acc, peaks=dim.peaks,
                                                        resolution_kmh=opt.speed_refinement_kmh)
    for c in range(len(found)):
        if dim.missing[c] is not None and dim.peaks[c].found:
            dim.peaks[c] = replace(dim.peaks[c], max_at_range_end=None)
    return dim


def _relocation_windows(v, mlm, dim_peaks, opt):
    """The speeds re-evaluated at each trial damping, per case (None: nothing to solve); in the refined
    mode the MLM grid's window plus the finest pass around the refined peak."""
    windows = [relocation_speeds(mlm.speeds[c], p, opt) if p.found and dim_peaks[c].found else None
               for c, p in enumerate(mlm.peaks)]
    if opt.speed_refinement_kmh is not None:
        for c, w in enumerate(windows):
            if w is not None:
                keep = np.isin(np.round(w, 9), np.round(v, 9)) | (
                    np.abs(w - mlm.peaks[c].speed_kmh) <= REFINE_COARSE_KMH + 1e-9)
                windows[c] = w[keep]
    return windows


def _solve_step(lanes, v, mlm, dim_peaks, *, zetas, opt, adapted_curve=False, on_trial=None):
    """Step 3: the damping ladder (bracket), then every root together (:func:`solve_delta_zetas`: phases
    ``"ladder"``, ``"root"``, ``"check"``); with ``adapted_curve`` the MLM at ``zeta + Δζ_VBI`` over every
    speed (``"adapted"``). ``(solves, adapted curves)``, one each per case."""
    n = len(mlm.peaks)
    windows = _relocation_windows(v, mlm, dim_peaks, opt)

    def evaluate(requests, phase):
        r = Requests()
        for c, dz in requests:
            r.add(c, np.tile(windows[c], dz.size), np.repeat(dz, windows[c].size))
        return [acc.reshape(dz.size, windows[c].size) for (c, dz), acc in zip(requests, r.run(lanes, "mlm", phase))]

    solves = solve_delta_zetas(evaluate, windows, peak_speeds_kmh=[p.speed_kmh for p in mlm.peaks],
                               targets_m_s2=[p.acc_m_s2 for p in dim_peaks], zetas=zetas, options=opt,
                               on_trial=on_trial)
    adapted = [(np.zeros(0), np.zeros(0))] * n
    if adapted_curve:
        req, which = Requests(), [c for c in range(n) if solves[c] is not None and solves[c].delta_zeta is not None]
        for c in which:
            req.add(c, mlm.speeds[c], solves[c].delta_zeta)
        for c, acc in zip(which, req.run(lanes, "mlm", "adapted")):
            adapted[c] = (mlm.speeds[c], acc)
    return solves, adapted


def _status(lanes, v, c, *, bridge, train, mlm, dim, solve):
    """``{"status", "message"}`` of case ``c``: no MLM peak, no DIM peak, a wheel off the rail at the DIM
    peak, else the root finder's, then a grid that cannot show the resonance and Step 2's determination."""
    if not mlm.peaks[c].found:
        status, message = "no_mlm_peak", mlm.peaks[c].reason
    elif not dim.peaks[c].found:
        status, message = "no_dim_peak", dim.peaks[c].reason
    elif (loss := contact_loss_at(lanes, c, dim.peaks[c].speed_kmh)) is not None:
        status, message = "contact_lost", contact_message(loss)  # the DIM's own assumption broken at its peak
    else:
        status, message = solve.status, solve.message
        if status == "ok":
            status, message = speed_grid_finding(bridge, train, v) or (status, message)
        if status == "ok":  # Step 2: a matched Δζ_VBI at an end of the range or without a DIM peak
            status, message = (pk.determination(mlm.speeds[c], mlm.acc[c], mlm.peaks[c], dim.peaks[c])
                               or (status, message))
    return {"status": status, "message": message}


def _per_case(timings, n):
    """The batch's phase times divided by its size (and the size, for a batch of more than one)."""
    per_case = {k: t / n for k, t in timings.items()}
    if n > 1:
        per_case["batch_size"] = n
    return per_case


BACKENDS = ("compiled", "numpy")


def calibrate(bridge, train, speeds_kmh=None, *, options=None, progress=None, adapted_curve=True, dim_curve=None,
              sweep=None, on_trial=None, backend="compiled"):
    """Calibrate Δζ_VBI for a bridge and a train and evaluate the reference methods.

    The batch of one of :func:`calibrate_cases`.

    Parameters
    ----------
    bridge : adm_sim.model.bridge.Bridge
    train : adm_sim.model.trains.Train
    speeds_kmh : array_like (n_speeds,), optional
        MLM speeds (km/h); default 160..350 at 1 km/h.
    options : CalibrationOptions, optional
    progress : callable(done, total, note), optional
        Called after every lane request with the count so far, ``None`` (the number of requests is
        not known in advance) and the run phase; the command line hands in a progress bar
        (:func:`adm_sim.cliutil.progress_callback`), the library draws nothing.
    adapted_curve : bool
        Also run the MLM at ``zeta + Δζ_VBI`` over all speeds (for the plot, Fig. 15).
    dim_curve : (ndarray (m,), ndarray (m,)), optional
        Target curve ``(speeds_kmh, max_acc_m_s2)`` used instead of running the DIM (a cached DIM
        sweep, or an MLM at ``zeta + x`` for the round-trip check); it should be computed with
        :func:`calibration_step` so that it is discretised as the MLM runs.
    sweep : callable(model, speeds_kmh (n,), delta_zeta (n,) or float, step[, phase]) -> ndarray (n,), optional
        Runs one speed sweep and returns the maximum midspan accelerations (m/s^2): a hook for
        sweeps run elsewhere (co-simulation, a cluster), used through
        :class:`adm_calib.lanes.HookLanes`; ``step`` is the shared
        :class:`~adm_sim.integrate.step_grid.StepOptions`, ``phase`` (if the hook takes it) the phase.
    on_trial : callable(delta_zeta, mlm_peak_m_s2, dim_peak_m_s2), optional
        Called for every trial damping of the root finder (fraction, re-located MLM peak, target):
        progress displays and logs of the iterations.
    backend : {"compiled", "numpy"}
        Lane runner when no ``sweep`` hook is given: the compiled batch
        (:class:`adm_calib.lanes.CompiledLanes`, default) or the numpy stepper
        (:class:`adm_calib.lanes.SteppedLanes`); they agree to ~1e-13 relative.

    Returns
    -------
    CalibrationResult
    """
    if backend not in BACKENDS:
        raise InputError(f"backend: {backend!r} is not known; allowed {', '.join(BACKENDS)}")
    opt = options or CalibrationOptions()
    v = check_speeds(speeds_kmh)
    step = calibration_step(bridge, train, v, opt)
    if sweep is not None:
        lanes = HookLanes(sweep, step)
    elif backend == "compiled":
        lanes = CompiledLanes([bridge], train, step)
    else:
        lanes = SteppedLanes([bridge], train, step)
    if progress is not None:
        lanes = ProgressLanes(lanes, progress)
    trial = None if on_trial is None else (lambda c, dz, peak, target: on_trial(dz, peak, target))
    return calibrate_cases([bridge], train, lanes, v, options=opt, step=step, adapted_curve=adapted_curve,
                           dim_curves=None if dim_curve is None else [dim_curve], on_trial=trial)[0]


def calibrate_batch(bridges, train, speeds_kmh=None, options=None, step=None):
    """Calibrate Δζ_VBI for every bridge (one span) under ``train``, all in lockstep.

    Runs :func:`calibrate_cases` (the one calibration) over :class:`adm_calib.lanes.CompiledLanes`: every sweep of every bridge is a lane of one compiled
    run (:class:`adm_sim.integrate.compiled_batch.BatchRunner`):

    1. one MLM run: every bridge x every speed;
    2. one DIM run over every bridge's Section 3.3 speeds, then at most two refinement runs;
    3. one MLM run over every bridge's damping ladder (bracketing), then the roots of
       ``peak_MLM(zeta + dz) / peak_DIM - 1`` for all bracketed bridges together with
       :func:`scipy.optimize.elementwise.find_root` (Chandrupatla, vectorised): one batched MLM run
       per iteration, tolerance ``xtol`` on Δζ;
    4. one MLM run at every root (the check of the match).

    Space step: all lanes share one ``ds``; by default the smallest of the bridges' own calibration
    steps (:func:`batch_step`).

    Parameters
    ----------
    bridges : sequence of adm_sim.model.bridge.Bridge
        Same span, mode count and damping model.
    train : adm_sim.model.trains.Train
    speeds_kmh : array_like, optional
        MLM speeds (km/h); default 160..350 at 1 km/h.
    options : CalibrationOptions, optional
    step : adm_sim.integrate.step_grid.StepOptions, optional
        Shared step (``ds_m`` set); default :func:`batch_step`.

    Returns
    -------
    list of CalibrationResult
        One per bridge, in order; ``solve.method`` is ``"find_root"`` (``"exact"`` when a ladder
        point is the root). ``timings_s`` holds the batch's phase times divided by its size.
    """
    opt = options or CalibrationOptions()
    v = check_speeds(speeds_kmh)
    step = step or batch_step(bridges, train, v, opt)
    return calibrate_cases(bridges, train, CompiledLanes(bridges, train, step), v, options=opt, step=step)
