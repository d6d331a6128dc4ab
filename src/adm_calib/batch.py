"""Batched calibration: Section 4's steps 1-3 for many bridges at once, in lockstep.

:func:`calibrate_batch` applies exactly the rules of :func:`adm_calib.calibrate.calibrate`
(interior peaks, the association window, the DIM refinement, the damping ladder, the 0.1 % match,
the statuses) to a list of bridges of one span under one train, but runs every sweep of every
bridge as lanes of one compiled run (:class:`adm_sim.batch.BatchRunner`):

1. one MLM run: every bridge x every speed;
2. one DIM run over every bridge's Section 3.3 speeds, then at most two refinement runs;
3. one MLM run over every bridge's damping ladder (bracketing), then the roots of
   ``peak_MLM(zeta + dz) / peak_DIM - 1`` for all bracketed bridges together with
   :func:`scipy.optimize.elementwise.find_root` (Chandrupatla, vectorised): one batched MLM run
   per iteration, tolerance ``xtol`` on Δζ as brentq's in the single-case path;
4. one MLM run at every root (the check of the match).

Space step: all lanes share one ``ds``; by default the smallest of the bridges' own calibration
steps. The study batches the six mass functions of one (span, frequency) pair, whose own steps
are equal (the step depends on the highest mode's frequency only), so every case runs on exactly
the grid it would get alone.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from scipy.optimize import elementwise

from adm_sim.batch import BatchRunner
from adm_sim.stepping import StepOptions

from adm_calib import peaks as pk
from adm_calib.calibrate import (CalibrationOptions, DampingSolve, _ladder, _speeds, calibration_step, dim_refinement,
                                 dim_speeds_paper, finish_solve, ladder_bracket, make_result, merge_curve,
                                 relocation_speeds)


def batch_step(bridges, train, speeds_kmh=None, options=None):
    """Shared step settings of a batch: the smallest ``ds`` of the bridges' own calibrations."""
    opt = options or CalibrationOptions()
    v = _speeds(speeds_kmh)
    ds = min(calibration_step(b, train, v, opt).ds_m for b in bridges)
    return replace(opt.step or StepOptions(), ds_m=ds)


class _Lanes:
    """Lanes of one batched run built case by case: (case, speeds, damping, sweep id)."""

    def __init__(self):
        self.parts = []

    def add(self, case, speeds, dz=0.0, sweep=0):
        speeds = np.asarray(speeds, dtype=float)
        self.parts.append((case, speeds, np.broadcast_to(np.asarray(dz, float), speeds.shape), sweep))
        return len(self.parts) - 1

    def run(self, runner, model):
        if not self.parts:
            return []
        case = np.concatenate([np.full(p[1].size, p[0]) for p in self.parts])
        v = np.concatenate([p[1] for p in self.parts])
        dz = np.concatenate([p[2] for p in self.parts])
        sw = np.concatenate([np.full(p[1].size, p[3]) for p in self.parts])
        acc = runner.run(model, case, v, dz, sweep=sw)[0]
        out, i = [], 0
        for p in self.parts:
            out.append(acc[i:i + p[1].size])
            i += p[1].size
        return out


def calibrate_batch(bridges, train, speeds_kmh=None, options=None, step=None):
    """Calibrate Δζ_VBI for every bridge (one span) under ``train``, all in lockstep.

    Parameters
    ----------
    bridges : sequence of adm_sim.bridge.Bridge
        Same span, mode count and damping model.
    train : adm_sim.trains.Train
    speeds_kmh : array_like, optional
        MLM speeds (km/h); default 160..350 at 1 km/h.
    options : CalibrationOptions, optional
    step : adm_sim.stepping.StepOptions, optional
        Shared step (``ds_m`` set); default :func:`batch_step`.

    Returns
    -------
    list of CalibrationResult
        One per bridge, in order; ``solve.method`` is ``"find_root"`` (``"exact"`` when a ladder
        point is the root). ``timings_s`` holds the batch's phase times divided by its size.
    """
    opt = options or CalibrationOptions()
    v = _speeds(speeds_kmh)
    step = step or batch_step(bridges, train, v, opt)
    runner = BatchRunner(bridges, train, step.ds_m, step.free_vibration_periods)
    n = len(bridges)
    timings = {}

    # step 1: MLM over every speed
    t0 = time.perf_counter()
    lanes = _Lanes()
    for c in range(n):
        lanes.add(c, v)
    mlm = lanes.run(runner, "mlm")
    mlm_peaks = [pk.find_peak(v, mlm[c], opt.min_prominence_rel) for c in range(n)]
    timings["mlm_sweep"] = time.perf_counter() - t0

    # step 1-2: DIM on the paper's grid, association, refinement where the DIM value lies on the coarse grid
    t0 = time.perf_counter()
    vd = [v if opt.dim_grid == "full" else dim_speeds_paper(v, p.speed_kmh if p.found else None, opt)
          for p in mlm_peaks]
    lanes = _Lanes()
    for c in range(n):
        lanes.add(c, vd[c])
    dim = lanes.run(runner, "dim")
    dim_peaks = [pk.Peak(found=False, reason="no MLM peak to associate with")] * n
    refined = [False] * n

    def associate(c):
        return pk.associate_peak(vd[c], dim[c], mlm_peaks[c].speed_kmh, opt.association_window_kmh,
                                 opt.min_prominence_rel)

    for c in range(n):
        if mlm_peaks[c].found:
            dim_peaks[c] = associate(c)
    for round_ in range(2):
        if opt.dim_grid == "full":
            break
        lanes, which = _Lanes(), []
        for c in range(n):
            extra = dim_refinement(v, vd[c], dim_peaks[c]) if mlm_peaks[c].found else None
            if extra is not None and (round_ == 0 or refined[c]):
                lanes.add(c, extra, sweep=round_ + 1)
                which.append((c, extra))
        if not which:
            break
        for (c, extra), acc in zip(which, lanes.run(runner, "dim")):
            vd[c], dim[c] = merge_curve(vd[c], dim[c], extra, acc)
            refined[c] = True
            dim_peaks[c] = associate(c)
    timings["dim_sweep"] = time.perf_counter() - t0

    # step 3: damping ladder (bracket), then all roots together
    t0 = time.perf_counter()
    solves = [None] * n
    todo = [c for c in range(n) if mlm_peaks[c].found and dim_peaks[c].found]
    windows = {c: relocation_speeds(v, mlm_peaks[c], opt) for c in todo}
    half = (opt.relocation_window_kmh, opt.relocation_window_kmh)

    def window_peak(c, acc):
        return pk.window_max(windows[c], acc, mlm_peaks[c].speed_kmh, half)[1]

    lanes, ladders = _Lanes(), {}
    for c in todo:
        ladders[c] = _ladder(bridges[c].damping_ratio)
        w = windows[c]
        lanes.add(c, np.tile(w, ladders[c].size), np.repeat(ladders[c], w.size))
    brackets = {}
    for c, acc in zip(todo, lanes.run(runner, "mlm")):
        w, lad = windows[c], ladders[c]
        rows = acc.reshape(lad.size, w.size)
        fl = np.array([window_peak(c, row) for row in rows]) / dim_peaks[c].acc_m_s2 - 1.0
        b = ladder_bracket(lad, fl)
        if isinstance(b, DampingSolve):  # not bracketed
            solves[c] = b
            continue
        i, lo, hi = b
        if fl[i] == 0.0 or fl[i + 1] == 0.0:
            brackets[c] = (lo, hi, lo if fl[i] == 0.0 else hi)
        else:
            brackets[c] = (lo, hi, None)
    roots, iters, calls = {}, {}, {}
    open_ = [c for c in brackets if brackets[c][2] is None]
    for c in brackets:
        if brackets[c][2] is not None:
            roots[c], iters[c], calls[c] = brackets[c][2], 0, 0
    if open_:
        ids = np.array(open_)

        def f(x, idx):
            x = np.atleast_1d(x)
            idx = np.broadcast_to(np.atleast_1d(idx), x.shape)
            lanes = _Lanes()
            for k, (c, dz) in enumerate(zip(idx.ravel(), x.ravel())):
                lanes.add(int(c), windows[int(c)], dz, sweep=k)
            out = np.array([window_peak(int(c), acc) / dim_peaks[int(c)].acc_m_s2 - 1.0
                            for c, acc in zip(idx.ravel(), lanes.run(runner, "mlm"))])
            return out.reshape(x.shape)

        res = elementwise.find_root(
            f, (np.array([brackets[c][0] for c in open_]), np.array([brackets[c][1] for c in open_])),
            args=(ids,), tolerances=dict(xatol=opt.xtol, xrtol=4 * np.finfo(float).eps, fatol=0.0, frtol=0.0))
        for k, c in enumerate(open_):
            roots[c], iters[c], calls[c] = float(res.x[k]), int(res.nit[k]), int(res.nfev[k])
    lanes, order = _Lanes(), sorted(roots)
    for c in order:
        lanes.add(c, windows[c], roots[c])
    for c, acc in zip(order, lanes.run(runner, "mlm")):
        lo, hi, exact = brackets[c]
        solves[c] = finish_solve(roots[c], windows[c], acc, mlm_peaks[c].speed_kmh, dim_peaks[c].acc_m_s2,
                                 (lo, hi), iters[c], calls[c], opt, method="exact" if exact is not None else "find_root")
    timings["solve"] = time.perf_counter() - t0

    per_case = {k: t / n for k, t in timings.items()}
    out = []
    for c in range(n):
        s = solves[c]
        if not mlm_peaks[c].found:
            status, message = "no_mlm_peak", mlm_peaks[c].reason
        elif not dim_peaks[c].found:
            status, message = "no_dim_peak", dim_peaks[c].reason
        else:
            status, message = s.status, s.message
        out.append(make_result(bridges[c], train, status, message, s, mlm_peaks[c], dim_peaks[c], v, mlm[c],
                               vd[c], dim[c], np.zeros(0), np.zeros(0), opt.dim_grid, refined[c], step.ds_m,
                               dict(per_case, batch_size=n)))
    return out
