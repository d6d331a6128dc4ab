"""Speed grids of a calibration (paper Section 3.3): the DIM's coarse and fine speeds, its
refinement where the associated value lies on the coarse grid, the MLM relocation window, the
refined mode's peak location by extra lanes, and whether a given grid can show the resonance."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from adm_sim.integrate.sweep import run_sweep_compiled, sweep_exact

from adm_calib.calibration_options import DEFAULT_SPEEDS_KMH, CalibrationOptions
from adm_calib.lanes import Requests, response_points_m

#: A given speed grid is too coarse when its MLM maximum lies more than this fraction below the
#: maximum over its own range on the 1 km/h grid (exact MLM envelopes of both).
GRID_RTOL = 0.01
#: A given speed range holds no resonance when its MLM maximum is below this fraction of the
#: maximum over the paper's range and the given one together (exact MLM envelope, 1 km/h).
NO_RESONANCE_FRACTION = 0.5


def _fine_step(speeds):
    d = np.diff(speeds)
    return float(np.median(d)) if d.size else 1.0


def _grid_between(lo, hi, step, *, vmin, vmax):
    lo, hi = max(lo, vmin), min(hi, vmax)
    if hi < lo:
        return np.zeros(0)
    n = int(math.floor((hi - lo) / step + 1e-9)) + 1
    return lo + step * np.arange(n)


def _merge(*arrays):
    return np.unique(np.round(np.concatenate([np.asarray(a, float) for a in arrays]), 9))


def dim_speeds_paper(speeds_kmh, mlm_peak_kmh, options=None):
    """DIM speeds of Section 3.3 (km/h): coarse over the range plus fine around the MLM peak."""
    opt = options or CalibrationOptions()
    v = np.asarray(speeds_kmh, dtype=float)
    vmin, vmax, fine = float(v.min()), float(v.max()), _fine_step(v)
    coarse = _grid_between(vmin, vmax, max(opt.dim_coarse_step_kmh, fine), vmin=vmin, vmax=vmax)
    parts = [coarse, [vmax]]
    if mlm_peak_kmh is not None:
        parts.append(_grid_between(mlm_peak_kmh - opt.dim_refine_kmh[0], mlm_peak_kmh + opt.dim_refine_kmh[1],
                                   fine, vmin=vmin, vmax=vmax))
    return _merge(*parts)


#: Margin (km/h) of the window grid beyond the association window on each side: the half width of
#: :func:`dim_refinement`'s extra speeds, so every refinement lies inside the window grid.
WINDOW_MARGIN_KMH = 5.0


def dim_speeds_window(paper_kmh, mlm_peak_kmh, options=None):
    """The ``window`` DIM grid: the paper's DIM speeds only where the associated DIM peak can lie.

    Rule: by the association rule (:func:`adm_calib.peaks.associate_peak`) the DIM peak is taken
    inside the window ``[v_m - 20, v_m + 10]`` km/h around the MLM peak ``v_m``, so only the DIM
    values there, the refinement speeds around them (:data:`WINDOW_MARGIN_KMH`) and one more paper
    speed beyond each end (the neighbours that decide whether a speed of the window is a local
    maximum) can change the result. The window grid is that contiguous part of the paper grid
    ``paper_kmh`` (the 5 km/h coarse points far from the MLM peak are dropped); the run also holds the
    paper grid's fastest speed, which sets the sweep's number of steps (:func:`adm_sim.integrate.step_grid.make_grid`),
    so every DIM value is the paper grid's value bit for bit. Whether the association on this part
    equals the one on the whole paper curve is checked case by case
    (:func:`adm_calib.peaks.association_decided`); where it is not certain the rest of the paper grid is run.

    Parameters
    ----------
    paper_kmh : ndarray (n,)
        The paper's DIM speeds of the case (:func:`dim_speeds_paper`), increasing.
    mlm_peak_kmh : float
    options : CalibrationOptions, optional

    Returns
    -------
    curve_kmh : ndarray (m,)
        The speeds of the DIM curve (a contiguous part of ``paper_kmh``).
    run_kmh : ndarray (m,) or (m + 1,)
        The speeds to run: ``curve_kmh`` and the fastest paper speed.
    """
    opt = options or CalibrationOptions()
    p = np.asarray(paper_kmh, dtype=float)
    lo = mlm_peak_kmh - opt.association_window_kmh[0] - WINDOW_MARGIN_KMH
    hi = mlm_peak_kmh + opt.association_window_kmh[1] + WINDOW_MARGIN_KMH
    inside = np.flatnonzero((p >= lo - 1e-9) & (p <= hi + 1e-9))
    if inside.size == 0:
        return p, p
    i0, i1 = max(int(inside[0]) - 1, 0), min(int(inside[-1]) + 1, p.size - 1)
    curve = p[i0:i1 + 1]
    run = curve if i1 == p.size - 1 else np.append(curve, p[-1])
    return curve, run


def dim_refinement(v, vd, dim_peak):
    """Extra DIM speeds when the associated DIM value lies where only the coarse grid ran, or None.

    The fine step of the MLM grid on +-5 km/h around the DIM value (Section 3.3's "minor
    refinements of the DIM speed steps where necessary").
    """
    if not dim_peak.found:
        return None
    fine = _fine_step(v)
    i = dim_peak.index
    gaps = [vd[i] - vd[i - 1] if i > 0 else 0.0, vd[i + 1] - vd[i] if i + 1 < vd.size else 0.0]
    if max(gaps) <= fine + 1e-9:
        return None
    extra = _grid_between(dim_peak.speed_kmh - 5.0, dim_peak.speed_kmh + 5.0, fine, vmin=v.min(), vmax=v.max())
    extra = np.setdiff1d(np.round(extra, 9), vd)
    return extra if extra.size else None


def merge_curve(vd, dim, extra, acc_extra):
    """The DIM curve with the extra speeds merged in speed order."""
    all_v, all_a = np.concatenate([vd, extra]), np.concatenate([dim, acc_extra])
    order = np.argsort(all_v)
    return all_v[order], all_a[order]


def relocation_speeds(v, mlm_peak, options):
    """MLM speeds re-evaluated at every trial damping: the window around the MLM peak."""
    h = options.relocation_window_kmh
    return v[(v >= mlm_peak.speed_kmh - h - 1e-9) & (v <= mlm_peak.speed_kmh + h + 1e-9)]


#: Stages of the refined mode (km/h): a coarse pass over the neighbours' interval, then the final
#: resolution around its best point (a peak is a few km/h wide, so it is unimodal at 0.25 km/h).
REFINE_COARSE_KMH = 0.25


def _grid(lo, hi, step):
    n = int(math.floor((hi - lo) / step + 1e-9))
    return np.round(lo + step * np.arange(n + 1), 9)


def refine_peaks(lanes, model, phase, *, curves, intervals, resolution_kmh):
    """Peaks located to ``resolution_kmh`` on their intervals by extra lanes, all cases together.

    For each case ``c`` with an interval ``(lo, hi)`` (the neighbours of its peak on the sampled
    curve): pass 1 runs the speeds of ``[lo, hi]`` at 0.25 km/h, pass 2 those of
    ``[v1 - 0.25, v1 + 0.25]`` at ``resolution_kmh`` around the best point ``v1`` of pass 1; each
    pass is one request of lanes (phase ``phase``), each case one sweep. Speeds already on the
    curve are not run again.

    Parameters
    ----------
    lanes : lane runner
    model : {"mlm", "dim"}
    phase : str
    curves : list of (ndarray, ndarray)
        Per case its curve ``(speeds_kmh, max_acc_m_s2)``, speeds increasing.
    intervals : list of (float, float) or None
        Per case the interval to refine, or ``None``.
    resolution_kmh : float

    Returns
    -------
    curves : list of (ndarray, ndarray)
        The curves with the new speeds merged in.
    best : list of int or None
        Per case the index (in its merged curve) of the largest value inside its interval.
    """
    curves = [(np.asarray(v, float), np.asarray(a, float)) for v, a in curves]
    best = [None] * len(curves)

    def top(c):
        v, a = curves[c]
        lo, hi = intervals[c]
        inside = np.flatnonzero((v >= lo - 1e-9) & (v <= hi + 1e-9))
        return int(inside[np.argmax(a[inside])])

    steps = (REFINE_COARSE_KMH, resolution_kmh) if resolution_kmh < REFINE_COARSE_KMH else (resolution_kmh,)
    for k, step in enumerate(steps):
        req, which = Requests(), []
        for c, iv in enumerate(intervals):
            if iv is None:
                continue
            if k == 0:
                lo, hi = iv
            else:
                centre = curves[c][0][top(c)]
                lo, hi = max(iv[0], centre - steps[k - 1]), min(iv[1], centre + steps[k - 1])
            new = np.setdiff1d(_grid(lo, hi, step), np.round(curves[c][0], 9))
            if new.size:
                req.add(c, new)
                which.append((c, new))
        for (c, new), acc in zip(which, req.run(lanes, model, phase)):
            curves[c] = merge_curve(curves[c][0], curves[c][1], new, acc)
    for c, iv in enumerate(intervals):
        if iv is not None:
            best[c] = top(c)
    return curves, best


def _neighbours(v, i):
    return float(v[max(i - 1, 0)]), float(v[min(i + 1, v.size - 1)])


def relocate_peaks(lanes, model, phase, *, speeds, curves, peaks, resolution_kmh):
    """Every found peak located to ``resolution_kmh`` between its sampled neighbours
    (:func:`refine_peaks`); returns the merged speeds, curves and the relocated peaks (lists)."""
    ivs = [_neighbours(speeds[c], p.index) if p.found else None for c, p in enumerate(peaks)]
    merged, best = refine_peaks(lanes, model, phase, curves=list(zip(speeds, curves)), intervals=ivs,
                                resolution_kmh=resolution_kmh)
    speeds, curves, peaks = list(speeds), list(curves), list(peaks)
    for c, (vc, ac) in enumerate(merged):
        speeds[c], curves[c] = vc, ac
        if best[c] is not None:
            p, i = peaks[c], best[c]
            peaks[c] = replace(p, index=i, speed_kmh=float(vc[i]), acc_m_s2=float(ac[i]),
                               reason=f"{p.reason}; located to {resolution_kmh:g} km/h")
    return speeds, curves, peaks


def _reference_mlm(bridge, train, speeds_kmh):
    """MLM maxima (m/s^2) at the governing point on the reference grid: the exact envelope of a simply
    supported span; on a continuous deck (which has no exact envelope) the compiled RK4 sweep at every
    span's midspan, the largest (:func:`adm_calib.lanes.response_points_m`)."""
    if not bridge.is_continuous:
        return sweep_exact(bridge, train, speeds_kmh)[0].max_acc_m_s2
    return np.max([run_sweep_compiled(bridge, train, "mlm", speeds_kmh, where=x).max_acc_m_s2
                   for x in response_points_m(bridge)], axis=0)


def speed_grid_finding(bridge, train, speeds_kmh):
    """Whether a given MLM speed grid can show the resonance the calibration matches:
    ``None`` or ``(status, message)``.

    The reference is the paper's grid (Section 3.3: 1 km/h, 160..350 km/h) widened to the given
    range, with the given speeds added; the MLM maxima come from the exact envelope
    (:func:`adm_sim.integrate.sweep.sweep_exact`, ~0.1 s for 350 speeds). A grid that holds every reference
    speed is fine as it is (the default grid, and any finer or wider one): no computation.

    * ``grid_too_coarse``: the grid's MLM maximum lies more than :data:`GRID_RTOL` below the
      maximum over its own range on the 1 km/h grid (a 50 km/h grid, a list of three speeds);
    * ``no_resonance_in_range``: the grid's maximum is below :data:`NO_RESONANCE_FRACTION` of the
      maximum over the widened reference range (1..10 km/h: a quasi-static "peak").
    """
    v = np.asarray(speeds_kmh, dtype=float)
    lo, hi = min(v.min(), DEFAULT_SPEEDS_KMH[0]), max(v.max(), DEFAULT_SPEEDS_KMH[-1])
    ref = np.union1d(np.arange(lo, hi + 0.5, 1.0), v)
    on_grid = np.isin(np.round(ref, 9), np.round(v, 9))
    if on_grid.all():
        return None
    acc = _reference_mlm(bridge, train, ref)
    a_grid = float(acc[on_grid].max())
    inside = (ref >= v.min()) & (ref <= v.max())
    i_in = np.flatnonzero(inside)[np.argmax(acc[inside])]
    i_all = int(np.argmax(acc))
    rng = f"{v.min():g}..{v.max():g} km/h"
    if a_grid < (1.0 - GRID_RTOL) * acc[i_in]:
        return ("grid_too_coarse",
                f"the speed grid misses the resonance: on a 1 km/h grid the MLM maximum over {rng} is "
                f"{acc[i_in]:.4f} m/s^2 at {ref[i_in]:g} km/h, {100 * (acc[i_in] / a_grid - 1):.1f} % above the "
                f"grid's {a_grid:.4f} m/s^2 (exact MLM envelope; allowed {100 * GRID_RTOL:g} %): use a finer grid")
    if a_grid < NO_RESONANCE_FRACTION * acc[i_all]:
        return ("no_resonance_in_range",
                f"the speed range {rng} holds no resonance: its MLM maximum {a_grid:.4f} m/s^2 is "
                f"{100 * a_grid / acc[i_all]:.1f} % of the {acc[i_all]:.4f} m/s^2 at {ref[i_all]:g} km/h (exact MLM "
                f"envelope, 1 km/h over {lo:g}..{hi:g} km/h; a resonance needs >= {100 * NO_RESONANCE_FRACTION:g} %): "
                f"widen the range")
    return None
