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
   vectorised over the cases of a batch) to ``xtol`` (1e-8 = 1e-6 %), well inside the paper's
   acceptance of 0.1 % in the peak value, which is checked.

DIM speeds (``dim_grid="paper"``, Section 3.3): 5 km/h steps over the range plus the MLM step
(1 km/h) on ``[v_max - 20, v_max + 5]`` around the MLM peak, all in one run; if the associated DIM
value lies where only the coarse grid was run, the DIM is run again at the fine step on
``+-5 km/h`` around it (``dim_refined``). ``dim_grid="full"`` runs the DIM at every MLM speed.

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

import json
import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import elementwise

from adm_sim.fields import FIELDS
from adm_sim.errors import InputError
from adm_sim.fields import check_range
from adm_sim.limits import MAX_DELTA_ZETA, default_speeds_kmh
from adm_sim.stepping import StepOptions, make_grid, speeds_to_m_s

from adm_calib import peaks as pk
from adm_calib.lanes import CompiledLanes, HookLanes, SteppedLanes
from adm_calib.reference import adm_delta_zeta_pct, eada_for, lower_bound_for

#: Default speed range (km/h), Section 3.3 (one home: :mod:`adm_sim.limits`).
DEFAULT_SPEEDS_KMH = default_speeds_kmh()
STATUSES = ("ok", "no_mlm_peak", "no_dim_peak", "not_bracketed", "no_match")


@dataclass(frozen=True)
class CalibrationOptions:
    """Settings of one calibration (speeds in km/h, damping as fractions).

    Parameters
    ----------
    dim_grid : {"paper", "full"}
        DIM speeds as in Section 3.3 (coarse + refined) or at every MLM speed.
    dim_coarse_step_kmh : float
        Coarse DIM step (paper: 5 km/h).
    dim_refine_kmh : (float, float)
        Fine DIM interval ``[v_max - below, v_max + above]`` around the MLM peak (paper: 20, 5).
    association_window_kmh : (float, float)
        DIM peak association window below/above the MLM peak speed (see :mod:`adm_calib.peaks`).
    relocation_window_kmh : float
        Half width of the window in which the MLM peak is re-located at trial dampings.
    xtol : float
        Absolute tolerance of the root in Δζ (fraction).
    match_rtol : float
        Acceptance of the peak match (paper: 0.1 %).
    min_prominence_rel : float
        Smallest relative prominence of a peak.
    step : adm_sim.stepping.StepOptions or None
        Time-integration settings of the core (``None``: its defaults).
    speed_refinement_kmh : float or None
        Refined mode: locate the MLM peak and the DIM peak to this speed resolution (e.g. 0.05
        km/h) between the neighbours of the peak on the MLM speed grid (:func:`refine_peaks`).
        ``None`` (default): the paper's rule, peaks as sampled on the 1 km/h grid.
    """

    dim_grid: str = "paper"
    dim_coarse_step_kmh: float = 5.0
    dim_refine_kmh: tuple = (20.0, 5.0)
    association_window_kmh: tuple = pk.ASSOCIATION_WINDOW_KMH
    relocation_window_kmh: float = 5.0
    xtol: float = 1e-8
    match_rtol: float = 1e-3
    min_prominence_rel: float = pk.MIN_PROMINENCE_REL
    step: StepOptions | None = None
    speed_refinement_kmh: float | None = None

    def __post_init__(self):
        FIELDS["dim_grid"].check(self.dim_grid)
        check_range("dim_coarse_step_kmh", self.dim_coarse_step_kmh, "km/h", 0.0, 100.0, lo_open=True)
        check_range("relocation_window_kmh", self.relocation_window_kmh, "km/h", 0.0, 100.0, lo_open=True)
        check_range("xtol", self.xtol, "- (fraction)", 0.0, 1e-4, lo_open=True)
        check_range("match_rtol", self.match_rtol, "-", 0.0, 0.1, lo_open=True)
        if self.speed_refinement_kmh is not None:
            check_range("speed_refinement_kmh", self.speed_refinement_kmh, "km/h", 0.001, 1.0)


@dataclass(frozen=True, repr=False)
class DampingSolve:
    """Outcome of the root finding for Δζ (fractions)."""

    status: str
    message: str
    delta_zeta: float | None = None
    bracket: tuple | None = None
    iterations: int = 0
    function_calls: int = 0
    ladder_runs: int = 0
    residual_rel: float | None = None
    adapted_peak: pk.Peak = field(default_factory=lambda: pk.Peak(found=False))
    method: str = "brentq"

    def __repr__(self):
        if self.delta_zeta is None:
            return f"DampingSolve({self.status}: {self.message})"
        return (f"DampingSolve(dz={100 * self.delta_zeta:.4f} %, {self.iterations} iterations, "
                f"{self.function_calls} calls, residual {self.residual_rel:.2e})")


def _ladder(zeta):
    neg = [-f * zeta for f in (0.95, 0.75, 0.5, 0.25)] if zeta > 0 else []
    pos = [0.0, 0.001, 0.002, 0.004, 0.007, 0.01, 0.015, 0.02, 0.03, 0.05, 0.08, 0.12, MAX_DELTA_ZETA]
    return np.array(neg + pos)


def solve_delta_zetas(evaluate, windows, peak_speeds_kmh, targets_m_s2, zetas, options=None, on_trial=None):
    """Δζ of every case such that its re-located MLM peak equals its target (Step 3), all together.

    The one root finder of the project. For case ``c``:
    ``f_c(dz) = max_{|v - v_c| <= h} a_MLM(v; zeta_c + dz) / target_c - 1`` over the fixed speed
    window ``windows[c]`` (a max over a fixed set of speeds is continuous in ``dz``, which a
    bracketing root finder needs). The roots are bracketed by the first sign change of ``f_c`` over
    a ladder of trial dampings (``-0.95 zeta`` .. 20 %), then found for all bracketed cases at once
    by :func:`scipy.optimize.elementwise.find_root` (Chandrupatla's bracketing method, vectorised:
    one evaluation request per iteration) to ``xtol`` on Δζ. A ladder point with ``f_c = 0`` is
    the root (``method="exact"``). Each root is checked against the paper's 0.1 % peak match.

    Parameters
    ----------
    evaluate : callable(requests, phase) -> list of ndarray
        ``requests`` is a list of ``(case, dz (k,))``; returns for each request the MLM maxima
        (m/s^2) over ``windows[case]`` at each damping, shape ``(k, n_window)``. Each request is one
        speed sweep. ``phase`` is ``"ladder"``, ``"root"`` or ``"check"``.
    windows : sequence of ndarray (n_window_c,)
        Speeds (km/h) re-evaluated per case; ``None`` for a case not to solve.
    peak_speeds_kmh, targets_m_s2, zetas : sequence of float
        MLM peak speed at the structural damping, DIM peak value (m/s^2), structural damping
        (fraction) per case.
    options : CalibrationOptions, optional
    on_trial : callable(case, delta_zeta, mlm_peak_m_s2, target_m_s2), optional
        Called for every trial damping (ladder, root iterations, check).

    Returns
    -------
    list of DampingSolve or None
        ``None`` for cases without a window.
    """
    opt = options or CalibrationOptions()
    half = (opt.relocation_window_kmh, opt.relocation_window_kmh)
    n = len(windows)
    todo = [c for c in range(n) if windows[c] is not None]
    out = [None] * n

    def peak(c, acc):
        return pk.window_max(windows[c], acc, peak_speeds_kmh[c], half)[1]

    def trial(c, dz, value):
        if on_trial is not None:
            on_trial(c, float(dz), float(value), float(targets_m_s2[c]))

    ladders = {c: _ladder(zetas[c]) for c in todo}
    brackets = {}
    for c, acc in zip(todo, evaluate([(c, ladders[c]) for c in todo], "ladder")):
        values = np.array([peak(c, row) for row in acc])
        for dz, value in zip(ladders[c], values):
            trial(c, dz, value)
        fl = values / targets_m_s2[c] - 1.0
        b = ladder_bracket(ladders[c], fl)
        if isinstance(b, DampingSolve):  # not bracketed
            out[c] = b
            continue
        i, lo, hi = b
        brackets[c] = (lo, hi, (lo if fl[i] == 0.0 else hi) if (fl[i] == 0.0 or fl[i + 1] == 0.0) else None)
    roots, iters, calls = {}, {}, {}
    for c, (_lo, _hi, exact) in brackets.items():
        if exact is not None:
            roots[c], iters[c], calls[c] = exact, 0, 0
    open_ = [c for c in brackets if brackets[c][2] is None]
    if open_:
        def f(x, idx):
            x = np.atleast_1d(x)
            idx = np.broadcast_to(np.atleast_1d(idx), x.shape)
            cs, dzs = [int(c) for c in idx.ravel()], x.ravel()
            vals = []
            for c, dz, acc in zip(cs, dzs, evaluate([(c, np.array([dz])) for c, dz in zip(cs, dzs)], "root")):
                vals.append(peak(c, acc[0]))
                trial(c, dz, vals[-1])
            return (np.array(vals) / np.array([targets_m_s2[c] for c in cs]) - 1.0).reshape(x.shape)

        res = elementwise.find_root(
            f, (np.array([brackets[c][0] for c in open_]), np.array([brackets[c][1] for c in open_])),
            args=(np.array(open_),),
            tolerances=dict(xatol=opt.xtol, xrtol=4 * np.finfo(float).eps, fatol=0.0, frtol=0.0))
        for k, c in enumerate(open_):
            roots[c], iters[c], calls[c] = float(res.x[k]), int(res.nit[k]), int(res.nfev[k])
    order = sorted(roots)
    for c, acc in zip(order, evaluate([(c, np.array([roots[c]])) for c in order], "check")):
        lo, hi, exact = brackets[c]
        trial(c, roots[c], peak(c, acc[0]))
        out[c] = finish_solve(roots[c], windows[c], acc[0], peak_speeds_kmh[c], targets_m_s2[c], (lo, hi),
                              iters[c], calls[c], opt, method="exact" if exact is not None else "find_root")
    return out


def solve_delta_zeta(mlm_eval, peak_speed_kmh, speed_window_kmh, target_acc_m_s2, zeta, options=None):
    """Δζ of one case by :func:`solve_delta_zetas` with a plain evaluation function.

    Parameters
    ----------
    mlm_eval : callable(speeds_kmh (n,), delta_zeta (n,)) -> ndarray (n,)
        Maximum MLM acceleration (m/s^2) at each (speed, extra damping) lane.
    peak_speed_kmh : float
        Speed of the MLM peak at the structural damping.
    speed_window_kmh : ndarray (m,)
        Speeds re-evaluated at each trial damping (around the peak).
    target_acc_m_s2 : float
        DIM peak value.
    zeta : float
        Structural damping (fraction); trial values stay ``>= -0.95 zeta``.
    options : CalibrationOptions, optional

    Returns
    -------
    DampingSolve
    """
    w = np.asarray(speed_window_kmh, dtype=float)

    def evaluate(requests, phase):
        return [np.asarray(mlm_eval(np.tile(w, dz.size), np.repeat(dz, w.size)), float).reshape(dz.size, w.size)
                for _, dz in requests]

    return solve_delta_zetas(evaluate, [w], [peak_speed_kmh], [target_acc_m_s2], [zeta], options)[0]


def ladder_bracket(ladder, fl):
    """The first sign change of ``fl`` over the damping ladder: ``(i, a, b)``, or a failed solve."""
    sign = np.sign(fl)
    change = np.flatnonzero(sign[:-1] * sign[1:] <= 0)
    if change.size == 0:
        if fl[-1] > 0:
            msg = (f"the MLM peak stays above the DIM peak up to dz={100 * ladder[-1]:g} % "
                   f"(ratio {fl[-1] + 1:.4f})")
        else:
            msg = (f"the MLM peak stays below the DIM peak down to dz={100 * ladder[0]:g} % "
                   f"(ratio {fl[0] + 1:.4f})")
        return DampingSolve(status="not_bracketed", message=msg, ladder_runs=1)
    i = int(change[0])
    return i, float(ladder[i]), float(ladder[i + 1])


def finish_solve(root, w, acc_root, peak_speed_kmh, target_acc_m_s2, bracket, iterations, calls, options,
                 method="find_root"):
    """Check the root: re-located MLM peak at ``zeta + root`` against the target (Step 3's 0.1 %)."""
    opt = options
    half = opt.relocation_window_kmh
    a, b = bracket
    j, value = pk.window_max(w, acc_root, peak_speed_kmh, (half, half))
    resid = value / target_acc_m_s2 - 1.0
    local = pk.local_maxima(acc_root, opt.min_prominence_rel)
    adapted = pk.Peak(found=True, index=j, speed_kmh=float(w[j]), acc_m_s2=value, is_local_max=bool(j in local),
                      reason="re-located MLM peak at zeta + dz")
    if abs(resid) > opt.match_rtol:
        return DampingSolve(status="no_match", delta_zeta=None, bracket=(a, b), iterations=iterations,
                            function_calls=calls, ladder_runs=1, residual_rel=resid, adapted_peak=adapted,
                            method=method,
                            message=(f"the MLM peak jumps across the DIM peak near dz={100 * root:.4f} %: "
                                     f"mismatch {100 * resid:.3f} % > {100 * opt.match_rtol:g} %"))
    return DampingSolve(status="ok", message="peaks matched", delta_zeta=float(root), bracket=(a, b),
                        iterations=iterations, function_calls=calls, ladder_runs=1, residual_rel=resid,
                        adapted_peak=adapted, method=method)


# ---------------------------------------------------------------------- result
def _f(x):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)


@dataclass(frozen=True, repr=False)
class CalibrationResult:
    """Δζ_VBI of one bridge and train with the peaks, flags, curves and reference methods.

    Damping values are fractions (``delta_zeta_vbi``) and percent in :meth:`to_dict`.
    Curves: ``mlm_speeds_kmh``/``mlm_acc_m_s2`` (n_mlm,), ``dim_*`` (n_dim,), ``adapted_*``
    (n_mlm,) for the MLM at ``zeta + Δζ_VBI`` (empty when there is no Δζ_VBI).
    """

    bridge: object
    train_name: str
    status: str
    message: str
    delta_zeta_vbi: float | None
    mlm_peak: pk.Peak
    dim_peak: pk.Peak
    adapted_peak: pk.Peak
    solve: DampingSolve | None
    delta_zeta_adm_pct: float
    delta_zeta_eada_pct: float | None
    eada_note: str
    delta_zeta_lb_pct: float | None
    lb_note: str
    mlm_speeds_kmh: np.ndarray
    mlm_acc_m_s2: np.ndarray
    dim_speeds_kmh: np.ndarray
    dim_acc_m_s2: np.ndarray
    adapted_speeds_kmh: np.ndarray
    adapted_acc_m_s2: np.ndarray
    dim_grid: str = "paper"
    dim_refined: bool = False
    ds_m: float = float("nan")
    timings_s: dict = field(default_factory=dict)

    @property
    def delta_zeta_vbi_pct(self):
        return None if self.delta_zeta_vbi is None else 100.0 * self.delta_zeta_vbi

    @property
    def zeta_pct(self):
        return 100.0 * self.bridge.damping_ratio

    def to_dict(self, curves=True):
        """JSON-ready mapping; damping in percent (``*_pct``)."""
        s = self.solve
        d = {
            "bridge": self.bridge.name or self.bridge.describe(),
            "bridge_description": self.bridge.describe(),
            "train": self.train_name,
            "status": self.status,
            "message": self.message,
            "zeta_pct": self.zeta_pct,
            "delta_zeta_vbi_pct": _f(self.delta_zeta_vbi_pct),
            "delta_zeta_adm_pct": _f(self.delta_zeta_adm_pct),
            "delta_zeta_eada_pct": _f(self.delta_zeta_eada_pct),
            "eada_note": self.eada_note,
            "delta_zeta_lb_pct": _f(self.delta_zeta_lb_pct),
            "lb_note": self.lb_note,
            "mlm_peak": self.mlm_peak.to_dict(),
            "dim_peak": self.dim_peak.to_dict(),
            "adapted_mlm_peak": self.adapted_peak.to_dict(),
            "mlm_max_at_range_end": bool(self.mlm_peak.max_at_range_end),
            "dim_is_local_max": bool(self.dim_peak.found and self.dim_peak.is_local_max),
            "dim_max_at_range_end": bool(self.dim_peak.max_at_range_end),
            "dim_speed_shift_kmh": (_f(self.dim_peak.speed_kmh - self.mlm_peak.speed_kmh)
                                    if self.mlm_peak.found and self.dim_peak.found else None),
            "adapted_is_local_max": bool(self.adapted_peak.found and self.adapted_peak.is_local_max),
            "association_rule": self.dim_peak.reason,
            "solver": None if s is None else {
                "method": s.method, "iterations": s.iterations, "function_calls": s.function_calls,
                "ladder_runs": s.ladder_runs,
                "bracket_pct": None if s.bracket is None else [100 * s.bracket[0], 100 * s.bracket[1]],
                "residual_rel": _f(s.residual_rel), "status": s.status, "message": s.message},
            "dim_grid": self.dim_grid,
            "dim_refined": self.dim_refined,
            "ds_m": self.ds_m,
            "timings_s": dict(self.timings_s),
        }
        if curves:
            d["curves"] = {
                "mlm": {"speeds_kmh": self.mlm_speeds_kmh.tolist(), "max_acc_m_s2": self.mlm_acc_m_s2.tolist()},
                "dim": {"speeds_kmh": self.dim_speeds_kmh.tolist(), "max_acc_m_s2": self.dim_acc_m_s2.tolist()},
                "mlm_adapted": {"speeds_kmh": self.adapted_speeds_kmh.tolist(),
                                "max_acc_m_s2": self.adapted_acc_m_s2.tolist()},
            }
        return d

    def to_json(self, curves=True, **kw):
        return json.dumps(self.to_dict(curves=curves), indent=kw.pop("indent", 2), **kw)

    def summary(self):
        """Readable multi-line report."""
        def pct(x):
            return "n/a" if x is None else f"{x:.3f} %"

        def peak(p):
            return "none" if not p.found else f"{p.acc_m_s2:.4f} m/s^2 at {p.speed_kmh:g} km/h"

        lines = [f"{self.bridge.describe()}", f"train {self.train_name}; status {self.status}: {self.message}",
                 f"MLM peak       {peak(self.mlm_peak)}"
                 f"{'  (largest MLM value at an end of the speed range)' if self.mlm_peak.max_at_range_end else ''}",
                 f"DIM peak       {peak(self.dim_peak)}"
                 f"{'' if self.dim_peak.is_local_max or not self.dim_peak.found else '  (not a local maximum)'}",
                 f"adapted MLM    {peak(self.adapted_peak)}"]
        if self.solve is not None and self.solve.delta_zeta is not None:
            lines.append(f"dz_VBI         {pct(self.delta_zeta_vbi_pct)}  ({self.solve.method}, {self.solve.iterations} iterations, "
                         f"peak mismatch {100 * self.solve.residual_rel:.2e} %)")
        else:
            lines.append("dz_VBI         n/a")
        lines += [f"dz_ADM         {pct(self.delta_zeta_adm_pct)}  (EN 1991-2 6.4.6.3.1)",
                  f"dz_EADA        {pct(self.delta_zeta_eada_pct)}  ({self.eada_note})",
                  f"dz_LB          {pct(self.delta_zeta_lb_pct)}  ({self.lb_note})",
                  f"zeta           {self.zeta_pct:.3f} %"]
        return "\n".join(lines)

    def __repr__(self):
        dz = "n/a" if self.delta_zeta_vbi is None else f"{100 * self.delta_zeta_vbi:.4f} %"
        return (f"CalibrationResult({self.bridge.name or 'bridge'} x {self.train_name}, {self.status}, "
                f"dz_VBI={dz}, MLM {self.mlm_peak!r}, DIM {self.dim_peak!r})")


# ---------------------------------------------------------------------- driver
def _fine_step(speeds):
    d = np.diff(speeds)
    return float(np.median(d)) if d.size else 1.0


def _grid_between(lo, hi, step, vmin, vmax):
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
    coarse = _grid_between(vmin, vmax, max(opt.dim_coarse_step_kmh, fine), vmin, vmax)
    parts = [coarse, [vmax]]
    if mlm_peak_kmh is not None:
        parts.append(_grid_between(mlm_peak_kmh - opt.dim_refine_kmh[0], mlm_peak_kmh + opt.dim_refine_kmh[1],
                                   fine, vmin, vmax))
    return _merge(*parts)


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
    extra = _grid_between(dim_peak.speed_kmh - 5.0, dim_peak.speed_kmh + 5.0, fine, v.min(), v.max())
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


def make_result(bridge, train, status, message, solve, mlm_peak, dim_peak, v, mlm, vd, dim, v_ad, a_ad,
                dim_grid, refined, ds, timings):
    """The :class:`CalibrationResult` with the reference methods evaluated."""
    adapted = pk.Peak(found=False) if solve is None else solve.adapted_peak
    eada, eada_note = eada_for(bridge, train)
    lb, lb_note = lower_bound_for(bridge, train)
    return CalibrationResult(
        bridge=bridge, train_name=train.name, status=status, message=message,
        delta_zeta_vbi=None if solve is None else solve.delta_zeta, mlm_peak=mlm_peak, dim_peak=dim_peak,
        adapted_peak=adapted, solve=solve, delta_zeta_adm_pct=adm_delta_zeta_pct(bridge.span_m),
        delta_zeta_eada_pct=eada, eada_note=eada_note, delta_zeta_lb_pct=lb, lb_note=lb_note,
        mlm_speeds_kmh=v, mlm_acc_m_s2=mlm, dim_speeds_kmh=np.asarray(vd, float), dim_acc_m_s2=dim,
        adapted_speeds_kmh=v_ad, adapted_acc_m_s2=a_ad, dim_grid=dim_grid, dim_refined=refined, ds_m=ds,
        timings_s=timings)

class _Requests:
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


def _speeds(speeds_kmh):
    v = DEFAULT_SPEEDS_KMH if speeds_kmh is None else np.asarray(speeds_kmh, dtype=float)
    if v.ndim != 1 or v.size < 3:
        raise InputError(f"speeds: need at least 3 speeds (km/h), got {v.size}")
    v = np.unique(v)
    speeds_to_m_s(v)
    return v


def calibration_step(bridge, train, speeds_kmh=None, options=None):
    """The core's step settings shared by every run of one calibration (fixed ``ds_m``)."""
    opt = options or CalibrationOptions()
    v = _speeds(speeds_kmh)
    base = opt.step or StepOptions()
    return replace(base, ds_m=make_grid(bridge, train.length_m, speeds_to_m_s(v), base).ds_m)


def batch_step(bridges, train, speeds_kmh=None, options=None):
    """Shared step settings of a batch: the smallest ``ds`` of the bridges' own calibrations.

    The study batches the six mass functions of one (span, frequency) pair, whose own steps are
    equal (the step depends on the highest mode's frequency only), so every case runs on exactly
    the grid it would get alone.
    """
    opt = options or CalibrationOptions()
    v = _speeds(speeds_kmh)
    ds = min(calibration_step(b, train, v, opt).ds_m for b in bridges)
    return replace(opt.step or StepOptions(), ds_m=ds)


#: Stages of the refined mode (km/h): a coarse pass over the neighbours' interval, then the final
#: resolution around its best point (a peak is a few km/h wide, so it is unimodal at 0.25 km/h).
REFINE_COARSE_KMH = 0.25


def _grid(lo, hi, step):
    n = int(math.floor((hi - lo) / step + 1e-9))
    return np.round(lo + step * np.arange(n + 1), 9)


def refine_peaks(lanes, model, phase, curves, intervals, resolution_kmh):
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
        req, which = _Requests(), []
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


def _relocate_peaks(lanes, model, phase, speeds, curves, peaks, resolution_kmh):
    """Every found peak located to ``resolution_kmh`` between its sampled neighbours
    (:func:`refine_peaks`); returns the merged speeds, curves and the relocated peaks (lists)."""
    ivs = [_neighbours(speeds[c], p.index) if p.found else None for c, p in enumerate(peaks)]
    merged, best = refine_peaks(lanes, model, phase, list(zip(speeds, curves)), ivs, resolution_kmh)
    speeds, curves, peaks = list(speeds), list(curves), list(peaks)
    for c, (vc, ac) in enumerate(merged):
        speeds[c], curves[c] = vc, ac
        if best[c] is not None:
            p, i = peaks[c], best[c]
            peaks[c] = replace(p, index=i, speed_kmh=float(vc[i]), acc_m_s2=float(ac[i]),
                               reason=f"{p.reason}; located to {resolution_kmh:g} km/h")
    return speeds, curves, peaks


def calibrate_cases(bridges, train, lanes, speeds_kmh=None, options=None, step=None, adapted_curve=False,
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
    bridges : sequence of adm_sim.bridge.Bridge
    train : adm_sim.trains.Train
    lanes : lane runner
        A backend of :mod:`adm_calib.lanes` built on ``bridges``, ``train`` and ``step``.
    speeds_kmh : array_like, optional
        MLM speeds (km/h); default 160..350 at 1 km/h.
    options : CalibrationOptions, optional
    step : adm_sim.stepping.StepOptions, optional
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
    v = _speeds(speeds_kmh)
    step = step or batch_step(bridges, train, v, opt)
    n = len(bridges)
    given = dim_curves is not None
    timings = {}

    # step 1: MLM over every speed
    t0 = time.perf_counter()
    req = _Requests()
    for c in range(n):
        req.add(c, v)
    mlm = req.run(lanes, "mlm", "mlm")
    mlm_peaks = [pk.find_peak(v, mlm[c], opt.min_prominence_rel) for c in range(n)]
    sampled_peaks = list(mlm_peaks)  # on the MLM grid: the DIM grid and the association use these
    vm = [v] * n
    if opt.speed_refinement_kmh is not None:
        vm, mlm, mlm_peaks = _relocate_peaks(lanes, "mlm", "mlm_refine", vm, mlm, mlm_peaks,
                                             opt.speed_refinement_kmh)
    timings["mlm_sweep"] = time.perf_counter() - t0

    # step 1-2: DIM on the paper's grid, association, refinement where the DIM value lies on the coarse grid
    t0 = time.perf_counter()
    if given:
        vd, dim = [], []
        for curve in dim_curves:
            s, a = (np.asarray(x, dtype=float) for x in curve)
            order = np.argsort(s)
            vd.append(s[order])
            dim.append(a[order])
    else:
        vd = [v if opt.dim_grid == "full" else dim_speeds_paper(v, p.speed_kmh if p.found else None, opt)
              for p in sampled_peaks]
        req = _Requests()
        for c in range(n):
            req.add(c, vd[c])
        dim = req.run(lanes, "dim", "dim")
    dim_peaks = [pk.Peak(found=False, reason="no MLM peak to associate with")] * n
    refined = [False] * n

    def associate(c):
        return pk.associate_peak(vd[c], dim[c], sampled_peaks[c].speed_kmh, opt.association_window_kmh,
                                 opt.min_prominence_rel)

    for c in range(n):
        if mlm_peaks[c].found:
            dim_peaks[c] = associate(c)
    for round_ in range(2):
        if opt.dim_grid == "full" or given:
            break
        req, which = _Requests(), []
        for c in range(n):
            extra = dim_refinement(v, vd[c], dim_peaks[c]) if mlm_peaks[c].found else None
            if extra is not None and (round_ == 0 or refined[c]):
                req.add(c, extra)
                which.append((c, extra))
        if not which:
            break
        for (c, extra), acc in zip(which, req.run(lanes, "dim", "dim_refine")):
            vd[c], dim[c] = merge_curve(vd[c], dim[c], extra, acc)
            refined[c] = True
            dim_peaks[c] = associate(c)
    if opt.speed_refinement_kmh is not None and not given:
        vd, dim, dim_peaks = _relocate_peaks(lanes, "dim", "dim_peak_refine", vd, dim, dim_peaks,
                                             opt.speed_refinement_kmh)
    timings["dim_sweep"] = time.perf_counter() - t0

    # step 3: damping ladder (bracket), then all roots together
    t0 = time.perf_counter()
    todo = [mlm_peaks[c].found and dim_peaks[c].found for c in range(n)]
    windows = [relocation_speeds(vm[c], mlm_peaks[c], opt) if todo[c] else None for c in range(n)]
    if opt.speed_refinement_kmh is not None:  # the MLM grid's window plus the finest pass around the peak
        for c in range(n):
            if windows[c] is not None:
                w = windows[c]
                keep = np.isin(np.round(w, 9), np.round(v, 9)) | (
                    np.abs(w - mlm_peaks[c].speed_kmh) <= REFINE_COARSE_KMH + 1e-9)
                windows[c] = w[keep]

    def evaluate(requests, phase):
        r = _Requests()
        for c, dz in requests:
            r.add(c, np.tile(windows[c], dz.size), np.repeat(dz, windows[c].size))
        return [acc.reshape(dz.size, windows[c].size) for (c, dz), acc in zip(requests, r.run(lanes, "mlm", phase))]

    solves = solve_delta_zetas(evaluate, windows, [p.speed_kmh for p in mlm_peaks],
                               [p.acc_m_s2 for p in dim_peaks], [b.damping_ratio for b in bridges], opt, on_trial)
    adapted = [(np.zeros(0), np.zeros(0))] * n
    if adapted_curve:
        req, which = _Requests(), [c for c in range(n) if solves[c] is not None and solves[c].delta_zeta is not None]
        for c in which:
            req.add(c, vm[c], solves[c].delta_zeta)
        for c, acc in zip(which, req.run(lanes, "mlm", "adapted")):
            adapted[c] = (vm[c], acc)
    timings["solve"] = time.perf_counter() - t0

    per_case = {k: t / n for k, t in timings.items()}
    if n > 1:
        per_case["batch_size"] = n
    out = []
    for c in range(n):
        s = solves[c]
        if not mlm_peaks[c].found:
            status, message = "no_mlm_peak", mlm_peaks[c].reason
        elif not dim_peaks[c].found:
            status, message = "no_dim_peak", dim_peaks[c].reason
        else:
            status, message = s.status, s.message
        out.append(make_result(bridges[c], train, status, message, s, mlm_peaks[c], dim_peaks[c], vm[c], mlm[c],
                               vd[c], dim[c], *adapted[c], "given" if given else opt.dim_grid, refined[c],
                               step.ds_m, per_case))
    return out


class _ProgressLanes:
    """A lane runner that reports every finished request: ``progress(n_done, None, phase)``."""

    def __init__(self, lanes, progress):
        self.lanes, self.progress, self.done = lanes, progress, 0

    def run(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase=""):
        out = self.lanes.run(model, case, speeds_kmh, delta_zeta, sweep, phase)
        self.done += 1
        self.progress(self.done, None, phase)
        return out


BACKENDS = ("compiled", "numpy")


def calibrate(bridge, train, speeds_kmh=None, options=None, progress=None, adapted_curve=True, dim_curve=None,
              sweep=None, on_trial=None, backend="compiled"):
    """Calibrate Δζ_VBI for a bridge and a train and evaluate the reference methods.

    The batch of one of :func:`calibrate_cases`.

    Parameters
    ----------
    bridge : adm_sim.bridge.Bridge
    train : adm_sim.trains.Train
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
        :class:`~adm_sim.stepping.StepOptions`, ``phase`` (if the hook takes it) the phase.
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
    v = _speeds(speeds_kmh)
    step = calibration_step(bridge, train, v, opt)
    if sweep is not None:
        lanes = HookLanes(sweep, step)
    elif backend == "compiled":
        lanes = CompiledLanes([bridge], train, step)
    else:
        lanes = SteppedLanes([bridge], train, step)
    if progress is not None:
        lanes = _ProgressLanes(lanes, progress)
    trial = None if on_trial is None else (lambda c, dz, peak, target: on_trial(dz, peak, target))
    return calibrate_cases([bridge], train, lanes, v, opt, step, adapted_curve=adapted_curve,
                           dim_curves=None if dim_curve is None else [dim_curve], on_trial=trial)[0]


def calibrate_batch(bridges, train, speeds_kmh=None, options=None, step=None):
    """Calibrate Δζ_VBI for every bridge (one span) under ``train``, all in lockstep.

    Runs :func:`calibrate_cases` (the one calibration) over :class:`adm_calib.lanes.CompiledLanes`: every sweep of every bridge is a lane of one compiled
    run (:class:`adm_sim.compiled_batch.BatchRunner`):

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
    return calibrate_cases(bridges, train, CompiledLanes(bridges, train, step), v, opt, step)
