"""The root finder of Δζ_VBI (paper Section 4, step 3): one for the whole project.

For case ``c``, ``f_c(dz) = max_{|v - v_c| <= h} a_MLM(v; zeta_c + dz) / target_c - 1`` over a fixed
speed window; the roots are bracketed over a ladder of trial dampings (``-0.95 zeta`` .. 20 %) and
found by :func:`scipy.optimize.elementwise.find_root` (Chandrupatla, vectorised over cases) to
``xtol``; each root is checked against the paper's 0.1 % peak match.

Every damping is evaluated once: the finder's first two evaluations are the ends of the bracket,
whose maxima the ladder run already holds, and its root is one of the dampings it evaluated, so
neither is run again (the maxima are the ones of the run that computed them, the same numbers).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from adm_sim.limits import MAX_DELTA_ZETA

from adm_calib import peaks as pk
from adm_calib.calibration_options import CalibrationOptions

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


def solve_delta_zetas(evaluate, windows, *, peak_speeds_kmh, targets_m_s2, zetas, options=None, on_trial=None):
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
    trials = _Trials(evaluate, windows, peak_speeds_kmh, targets_m_s2, half=half, on_trial=on_trial)
    todo = [c for c in range(len(windows)) if windows[c] is not None]
    out = [None] * len(windows)
    brackets, unbracketed = _bracket_roots(trials, todo, {c: _ladder(zetas[c]) for c in todo}, opt)
    for c, solve in unbracketed.items():
        out[c] = solve
    roots = _find_roots(trials, brackets, opt)  # {case: (root, iterations, function calls)}
    order = sorted(roots)
    for c, acc in zip(order, trials.run([(c, roots[c][0]) for c in order], "check")):
        (lo, hi, exact), (root, iterations, calls) = brackets[c], roots[c]
        out[c] = finish_solve(root, windows[c], acc, peak_speed_kmh=peak_speeds_kmh[c],
                              target_acc_m_s2=targets_m_s2[c], bracket=(lo, hi), iterations=iterations, calls=calls,
                              options=opt, method="exact" if exact is not None else "find_root")
    return out


class _Trials:
    """The trial dampings of one solve: each ``(case, dz)`` evaluated once (``known``: its MLM maxima over
    the case's window), its re-located MLM peak, and the ``on_trial`` report."""

    def __init__(self, evaluate, windows, peak_speeds_kmh, targets_m_s2, *, half, on_trial):
        self.evaluate, self.windows, self.half, self.on_trial = evaluate, windows, half, on_trial
        self.peak_speeds_kmh, self.targets_m_s2 = peak_speeds_kmh, targets_m_s2
        self.known = {}  # (case, dz) -> maxima over the case's window: every damping is run once

    def peak(self, c, acc):
        """The re-located MLM peak of case ``c`` (m/s^2) from its maxima ``acc`` over its window."""
        return pk.window_max(self.windows[c], acc, self.peak_speeds_kmh[c], self.half)[1]

    def report(self, c, dz, value):
        if self.on_trial is not None:
            self.on_trial(c, float(dz), float(value), float(self.targets_m_s2[c]))

    def run(self, requests, phase):
        """Maxima of each ``(case, dz)``: the known ones as they are, the others in one request."""
        todo = [(c, dz) for c, dz in requests if (c, dz) not in self.known]
        if todo:
            for (c, dz), acc in zip(todo, self.evaluate([(c, np.array([dz])) for c, dz in todo], phase)):
                self.known[(c, dz)] = acc[0]
                self.report(c, dz, self.peak(c, acc[0]))
        return [self.known[(c, dz)] for c, dz in requests]


def _bracket_roots(trials, todo, ladders, opt):
    """The bracket of every case from its damping ladder (:func:`ladder_bracket`): ``({case: (lo, hi,
    exact root or None)}, {case: DampingSolve of a case not bracketed})``."""
    brackets, unbracketed = {}, {}
    for c, ladder, values in _ladder_values(trials, todo, ladders, first_stage=opt.ladder_first_stage):
        for dz, value in zip(ladder, values):
            trials.report(c, dz, value)
        fl = values / trials.targets_m_s2[c] - 1.0
        b = ladder_bracket(ladder, fl)
        if isinstance(b, DampingSolve):  # not bracketed
            unbracketed[c] = b
            continue
        i, lo, hi = b
        brackets[c] = (lo, hi, (lo if fl[i] == 0.0 else hi) if (fl[i] == 0.0 or fl[i + 1] == 0.0) else None)
    return brackets, unbracketed


def _find_roots(trials, brackets, opt):
    """The root of every bracketed case: a ladder point where ``f_c = 0``, else all open brackets together by
    :func:`scipy.optimize.elementwise.find_root` to ``xtol``; ``{case: (root, iterations, function calls)}``."""
    roots = {c: (exact, 0, 0) for c, (_lo, _hi, exact) in brackets.items() if exact is not None}
    open_ = [c for c in brackets if brackets[c][2] is None]
    if not open_:
        return roots
    from scipy.optimize import elementwise  # noqa: PLC0415  scipy.optimize (~0.3-1 s) when a root is searched, not at a node's start

    def f(x, idx):
        x = np.atleast_1d(x)
        idx = np.broadcast_to(np.atleast_1d(idx), x.shape)
        cs, dzs = [int(c) for c in idx.ravel()], [float(dz) for dz in x.ravel()]
        vals = [trials.peak(c, acc) for c, acc in zip(cs, trials.run(list(zip(cs, dzs)), "root"))]
        return (np.array(vals) / np.array([trials.targets_m_s2[c] for c in cs]) - 1.0).reshape(x.shape)

    res = elementwise.find_root(
        f, (np.array([brackets[c][0] for c in open_]), np.array([brackets[c][1] for c in open_])),
        args=(np.array(open_),),
        tolerances=dict(xatol=opt.xtol, xrtol=4 * np.finfo(float).eps, fatol=0.0, frtol=0.0))
    for k, c in enumerate(open_):
        roots[c] = (float(res.x[k]), int(res.nit[k]), int(res.nfev[k]))
    return roots


def _ladder_values(trials, todo, ladders, *, first_stage):
    """The re-located MLM peak over each case's ladder: ``(case, ladder, values)`` per case; the
    maxima of every damping run go into ``trials.known`` (``{(case, dz): maxima}``, run once).

    ``first_stage`` None: the whole ladder of every case in one request. Else the dampings up to
    ``first_stage`` first; the rest only for the cases whose values change sign nowhere in that
    part (``value / target - 1`` is the function whose sign changes). :func:`ladder_bracket` takes the first sign
    change, which depends on the ladder up to it alone, so both give the same bracket (the returned
    ladder is then the part that was run).
    """
    evaluate, peak, known = trials.evaluate, trials.peak, trials.known

    def ratio(c, v):
        return v / trials.targets_m_s2[c] - 1.0

    def values(c, dzs, acc):
        known.update({(c, float(dz)): row for dz, row in zip(dzs, acc)})
        return np.array([peak(c, row) for row in acc])

    if first_stage is None:
        return [(c, ladders[c], values(c, ladders[c], acc))
                for c, acc in zip(todo, evaluate([(c, ladders[c]) for c in todo], "ladder"))]
    head = {c: ladders[c][ladders[c] <= first_stage + 1e-15] for c in todo}
    vals = {c: values(c, head[c], acc) for c, acc in zip(todo, evaluate([(c, head[c]) for c in todo], "ladder"))}
    rest = []
    for c in todo:
        s = np.sign(ratio(c, vals[c]))
        if head[c].size < ladders[c].size and not np.any(s[:-1] * s[1:] <= 0):
            rest.append(c)
    out = {c: (head[c], vals[c]) for c in todo}
    for c, acc in zip(rest, evaluate([(c, ladders[c][head[c].size:]) for c in rest], "ladder")):
        out[c] = (ladders[c], np.concatenate([vals[c], values(c, ladders[c][head[c].size:], acc)]))
    return [(c, *out[c]) for c in todo]


def solve_delta_zeta(mlm_eval, peak_speed_kmh, speed_window_kmh, target_acc_m_s2, zeta, *, options=None):
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

    return solve_delta_zetas(evaluate, [w], peak_speeds_kmh=[peak_speed_kmh], targets_m_s2=[target_acc_m_s2], zetas=[zeta],
                             options=options)[0]


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


def finish_solve(root, w, acc_root, *, peak_speed_kmh, target_acc_m_s2, bracket, iterations, calls, options,
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
