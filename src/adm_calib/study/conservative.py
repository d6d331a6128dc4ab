"""A lower bound that is one: the largest cubic below every retained case (beyond the paper).

The paper's lower-bound function (Eq. 20, Section 4.2.1) is a least-squares cubic through the
interval minima, so bridges fall below it (its own minimum residuals are negative, Tables
B1-B4). Here, per train and mass function, the bound is the cubic
``p(n0) = a n0^3 + b n0^2 + c n0 + d`` applied with the rules of Eq. (20) (from 2.1 Hz to its
first root ``R``, 0 beyond; :func:`adm_calib.lower_bound.lower_bound_pct`) that

* lies below every retained case with ``2.1 Hz <= n0_i <= R``: ``p(n0_i) <= dz_i``;
* is a bound in the sense of Eq. (20): ``p >= 0`` on ``[2.1 Hz, R]``, ``p(R) = 0`` and
  ``p'(R) <= -1e-4 %/Hz`` (so ``R`` is its first root and a simple one that rounding cannot lose;
  a negative additional damping is never recommended);
* has the largest integral over ``[2.1 Hz, R]`` (the area under the bound as applied).

For a fixed ``R`` this is a linear programme in ``(a, b, c, d)`` (:func:`scipy.optimize.linprog`,
HiGHS; ``p >= 0`` imposed on a 0.01 Hz grid, then at the cubic's minima by cutting planes).
``R`` is scanned from 2.15 Hz to the end of the fitted range ``hi`` in 0.05 Hz steps, plus the
candidate "no root before ``hi``" (then the bound is 0 above ``hi``, no extrapolation), and the
best ``R`` is refined to 1e-4 Hz by a bounded scalar search. A retained case with a negative Δζ below ``R`` makes ``R`` infeasible, so the bound
ends before the first negative case; negative cases beyond the root lie below any bound that is 0
there (the paper's too) and are counted (``n_negative_beyond_root``).

The programmes are solved in the scaled variable ``x = n0 / hi``; the answer is then shifted down by
its largest remaining violation of ``p(n0_i) <= dz_i`` (of the order of the solver's feasibility
tolerance, reported as ``shift_pct``), so that the bound holds in floating point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError

from adm_calib.lower_bound import LOWER_LIMIT_HZ, first_root_hz, lower_bound_pct
from adm_calib.study.fit import toml_key

#: Step (Hz) of the scan over the first root.
ROOT_STEP_HZ = 0.05
#: Step (Hz) of the grid on which p >= 0 is imposed before the cutting planes (a finer grid needs
#: fewer cutting-plane rounds: 2.5x faster than 0.05 Hz on ICE-2 mu1, same bound to 1e-5).
POSITIVE_GRID_HZ = 0.01
_INFEASIBLE = 1e30
#: p >= this (%) on the grid before the last step to its root, so that touching zero between grid
#: points cannot end the bound early (the applied bound is 0 from the first root on).
POSITIVE_MARGIN_PCT = 1e-6
#: The cubic crosses zero at its root with at least this slope (% per Hz), so the root is simple.
ROOT_SLOPE_PCT_PER_HZ = 1e-4


@dataclass(frozen=True, repr=False)
class ConservativeFit:
    """The LP bound of one set (Δζ in %, n0 in Hz); ``n0_hz``/``delta_zeta_pct``: the set's retained
    cases in ``[2.1 Hz, fit_range_max_hz]``; ``upper_limit_hz``: the first root of the cubic."""

    coefficients: tuple
    n0_hz: np.ndarray
    delta_zeta_pct: np.ndarray
    fit_range_max_hz: float
    upper_limit_hz: float
    objective_pct_hz: float
    shift_pct: float
    n_negative_beyond_root: int

    @property
    def zero_from_hz(self):
        return min(self.upper_limit_hz, self.fit_range_max_hz)

    def value_pct(self, n0_hz):
        """The bound as applied (Eq. 20 rules): the cubic up to its first root or the range end, 0 beyond."""
        return lower_bound_pct(self.coefficients, n0_hz, LOWER_LIMIT_HZ, self.fit_range_max_hz)


    def __repr__(self):
        a, b, c, d = self.coefficients
        return (f"ConservativeFit(a={a:.4g}, b={b:.4g}, c={c:.4g}, d={d:.4g}, root {self.upper_limit_hz:.2f} Hz, "
                f"{self.n0_hz.size} cases)")


def cubic_integral(coefficients, lo_hz, hi_hz):
    """Integral of the cubic over ``[lo_hz, hi_hz]`` (% Hz), in closed form."""
    a, b, c, d = coefficients
    return (a * (hi_hz**4 - lo_hz**4) / 4.0 + b * (hi_hz**3 - lo_hz**3) / 3.0
            + c * (hi_hz**2 - lo_hz**2) / 2.0 + d * (hi_hz - lo_hz))


def _basis(x):
    x = np.asarray(x, dtype=float)
    return np.stack([x**3, x**2, x, np.ones_like(x)], axis=-1)


def _solve_for_root(x, y, lo, r, h, with_root):
    """LP for a fixed first root ``r`` (Hz): ``(coefficients, area)`` or ``None`` if infeasible or unbounded.

    ``p >= 0`` is imposed on a grid (``>= POSITIVE_MARGIN_PCT`` up to one grid step before ``r``),
    then at the minima of the solution between grid points until none is negative (cutting planes).
    ``area`` is the integral of the bound as applied: up to the cubic's actual first root.
    """
    from scipy.optimize import linprog  # noqa: PLC0415  scipy.optimize (~1.7 s to import) only for the conservative fit

    xs, los, rs = x / h, lo / h, r / h
    sel = x <= r
    n_grid = max(8, int(math.ceil((r - lo) / POSITIVE_GRID_HZ)) + 1)
    g = list(np.linspace(los, rs, n_grid))
    w = np.array([(rs**4 - los**4) / 4, (rs**3 - los**3) / 3, (rs**2 - los**2) / 2, rs - los])
    eq = dict(A_eq=_basis(np.array([rs])), b_eq=np.zeros(1)) if with_root else {}
    edge = rs - ROOT_STEP_HZ / h
    # a root with a sign change: p'(R) <= -ROOT_SLOPE (a tangent root could be lost to rounding)
    slope = [np.array([[3 * rs**2, 2 * rs, 1.0, 0.0]])] if with_root else []
    slope_b = [-ROOT_SLOPE_PCT_PER_HZ * h] if with_root else []
    for _ in range(30):
        ga = np.array(g)
        margin = np.where(ga <= edge, POSITIVE_MARGIN_PCT, 0.0)
        A_ub = np.vstack([_basis(xs[sel]), -_basis(ga), *slope])
        b_ub = np.concatenate([y[sel], -margin, slope_b])
        res = linprog(-w, A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 4, method="highs", **eq)
        if res.status != 0:
            return None
        q = res.x
        crit = [c.real for c in np.roots([3 * q[0], 2 * q[1], q[2]]) if abs(c.imag) < 1e-12 and los < c.real < rs]
        low = [c for c in crit if np.polyval(q, c) < (POSITIVE_MARGIN_PCT if c <= edge else 0.0) - 1e-9]
        if not low:
            break
        g += low
    else:
        return None
    coef = np.array([q[0] / h**3, q[1] / h**2, q[2] / h, q[3]])
    top = min(first_root_hz(tuple(coef), lo), r)
    return coef, cubic_integral(coef, lo, top)


def conservative_cubic(n0_hz, delta_zeta_pct, fit_range_max_hz=21.0, lower_limit_hz=LOWER_LIMIT_HZ):
    """The conservative lower bound of one set (module docstring).

    Parameters
    ----------
    n0_hz, delta_zeta_pct : array_like (n,)
        Retained cases of one set; those outside ``[lower_limit_hz, fit_range_max_hz]`` are ignored.
    fit_range_max_hz : float
        End of the range (Hz); the bound is 0 above it where its cubic has no root before.

    Returns
    -------
    ConservativeFit

    Raises
    ------
    InputError
        No first root in the range gives a feasible, bounded programme (e.g. a negative Δζ right
        above 2.1 Hz, or fewer than 4 cases before every candidate root).
    """
    from scipy.optimize import minimize_scalar  # noqa: PLC0415  scipy.optimize, as above

    x = np.asarray(n0_hz, dtype=float)
    y = np.asarray(delta_zeta_pct, dtype=float)
    keep = (x >= lower_limit_hz) & (x <= fit_range_max_hz)
    x, y = x[keep], y[keep]
    lo, h = float(lower_limit_hz), float(fit_range_max_hz)
    best = None  # (integral, r, with_root, coef)
    n_steps = int(math.floor((h - lo) / ROOT_STEP_HZ + 1e-9))
    for k in range(1, n_steps + 1):
        r = round(lo + k * ROOT_STEP_HZ, 10)
        if np.any(y[x <= r] < 0.0):
            break  # a negative case below r: this and every larger root are infeasible
        sol = _solve_for_root(x, y, lo, r, h, True)
        if sol is not None and (best is None or sol[1] > best[0]):
            best = (sol[1], r, True, sol[0])
    else:
        sol = _solve_for_root(x, y, lo, h, h, False)  # no root before the range end
        if sol is not None and (best is None or sol[1] > best[0]):
            best = (sol[1], h, False, sol[0])
    if best is None:
        raise InputError(f"conservative fit: no first root in [{lo:g}, {h:g}] Hz gives a feasible, bounded "
                         f"programme ({x.size} cases)")
    if best[2]:  # refine the root between its scan neighbours
        def neg(r):  # minus the area; a large finite value where infeasible (Brent's step needs numbers)
            if np.any(y[x <= r] < 0.0):
                return _INFEASIBLE
            sol = _solve_for_root(x, y, lo, r, h, True)
            return _INFEASIBLE if sol is None else -sol[1]

        r0 = best[1]
        opt = minimize_scalar(neg, bounds=(max(lo + 1e-3, r0 - ROOT_STEP_HZ), min(h, r0 + ROOT_STEP_HZ)),
                              method="bounded", options={"xatol": 1e-4})
        if opt.success and opt.fun < _INFEASIBLE and -opt.fun > best[0]:
            best = (-opt.fun, float(opt.x), True, _solve_for_root(x, y, lo, float(opt.x), h, True)[0])
    coef = np.array(best[3], dtype=float)
    shift = 0.0
    for _ in range(3):  # move down by the remaining violation (solver tolerance) until none is left
        sel = x <= min(first_root_hz(tuple(coef), lo), h)
        viol = float(np.max(np.polyval(coef, x[sel]) - y[sel])) if np.any(sel) else 0.0
        if viol <= 0.0:
            break
        coef[3] -= viol
        shift += viol
    coef_t = tuple(float(c) for c in coef)
    root = first_root_hz(coef_t, lo)
    top = min(root, h)
    beyond = int(np.count_nonzero((x >= top) & (y < 0.0)))
    return ConservativeFit(coefficients=coef_t, n0_hz=x, delta_zeta_pct=y, fit_range_max_hz=h,
                           upper_limit_hz=root, objective_pct_hz=cubic_integral(coef_t, lo, top),
                           shift_pct=shift, n_negative_beyond_root=beyond)


@dataclass(frozen=True)
class ConservativeRow:
    """One set of the comparison: the LP bound against the paper's and our least-squares bounds."""

    train: str
    mass_function: str
    fit: ConservativeFit
    below_paper_max_pct: float
    below_paper_mean_pct: float
    below_ours_max_pct: float
    below_ours_mean_pct: float
    cases_below_paper: int
    cases_below_ours: int
    n_cases: int


def _grid(hi_hz):
    """n0 grid (Hz) on which the bounds are compared: 2.1 Hz to the end of the range, 0.01 Hz apart."""
    return np.linspace(LOWER_LIMIT_HZ, hi_hz, int(round((hi_hz - LOWER_LIMIT_HZ) / 0.01)) + 1)


def conservative_study(study_fit):
    """The LP bound of every set of a :class:`~adm_calib.study.fit.StudyFit` (its retained cases and
    its fit range), compared with the published and the least-squares bounds.

    Returns
    -------
    list of ConservativeRow
        "below" = other bound minus the LP bound on ``[2.1 Hz, range end]`` (max and mean, %);
        ``cases_below_*``: retained cases of the range whose Δζ lies below that bound as applied.
    """
    hi = study_fit.fit_range_hz[1]
    grid = _grid(hi)
    rows = []
    for (t, m), f in study_fit.fits.items():
        recs = [r for r in study_fit.records_used if r["train"] == t and r["mass_function"] == m]
        x = np.array([r["n0_hz"] for r in recs], dtype=float)
        y = np.array([r["delta_zeta_vbi_pct"] for r in recs], dtype=float)
        try:
            cf = conservative_cubic(x, y, fit_range_max_hz=hi)
        except InputError:
            continue
        lp = cf.value_pct(grid)
        inr = (x >= LOWER_LIMIT_HZ) & (x <= hi)
        nan = float("nan")
        pmax = pmean = omax = omean = nan
        below_p = below_o = -1
        if f.published is not None:
            d = f.published.value_pct(grid) - lp
            pmax, pmean = float(d.max()), float(d.mean())
            below_p = int(np.count_nonzero(y[inr] < f.published.value_pct(x[inr])))
        if f.fit is not None:
            d = f.fit.value_pct(grid) - lp
            omax, omean = float(d.max()), float(d.mean())
            below_o = int(np.count_nonzero(y[inr] < f.fit.value_pct(x[inr])))
        rows.append(ConservativeRow(train=t, mass_function=m, fit=cf, below_paper_max_pct=pmax,
                                    below_paper_mean_pct=pmean, below_ours_max_pct=omax, below_ours_mean_pct=omean,
                                    cases_below_paper=below_p, cases_below_ours=below_o, n_cases=int(inr.sum())))
    return rows


def conservative_markdown(rows, study_fit):
    """The comparison table (Markdown) of :func:`conservative_study`."""
    lo, hi = study_fit.fit_range_hz
    out = [f"Conservative lower bound (linear programmes, `adm_calib.study.conservative`): per set the cubic that is "
           f">= 0 from 2.1 Hz to its first root R and lies below every retained case (rule **{study_fit.rule}**) "
           f"with 2.1 Hz <= n0 <= R, with the largest integral over [2.1 Hz, R] (R scanned up to {hi:g} Hz); applied "
           f"as Eq. (20): 0 from R (and above {hi:g} Hz). \"Paper - LP\" and \"ours - LP\": the published (Tables "
           f"B1-B4) and our least-squares bound minus the LP bound on 2.1-{hi:g} Hz (0.01 Hz grid), in % of critical "
           f"damping. \"cases below\": retained cases of 2.1-{hi:g} Hz whose Δζ_VBI lies below that bound as "
           f"applied (for the LP bound: only the negative Δζ beyond its root, last column).", "",
           "| set | a | b | c | d | root (Hz) | cases | paper - LP max | paper - LP mean | cases below paper | "
           "ours - LP max | ours - LP mean | cases below ours | Δζ<0 beyond LP root |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]

    def g(v, f="{:.3f}"):
        return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f.format(v)

    for r in rows:
        a, b, c, d = r.fit.coefficients
        out.append(f"| {r.train} {r.mass_function} | {a:.4g} | {b:.4g} | {c:.4g} | {d:.4g} | "
                   f"{g(r.fit.upper_limit_hz, '{:.2f}')} | {r.n_cases} | {g(r.below_paper_max_pct)} | "
                   f"{g(r.below_paper_mean_pct)} | {r.cases_below_paper if r.cases_below_paper >= 0 else '-'} | "
                   f"{g(r.below_ours_max_pct)} | {g(r.below_ours_mean_pct)} | {r.cases_below_ours} | "
                   f"{r.fit.n_negative_beyond_root} |")
    return "\n".join(out) + "\n"


def conservative_toml(rows, study_fit, command=""):
    """The LP bounds in the format of ``data/lower_bounds.toml`` (for ``recommend --functions conservative``).

    ``r2`` is not defined for this fit (written as nan); ``max_res_pct``/``min_res_pct`` are the
    largest and smallest ``dz_i - p(n0_i)`` over the constraints (the smallest is >= 0).
    """
    hi = study_fit.fit_range_hz[1]
    lines = ["# Conservative lower-bound functions (linear programme, adm_calib.study.conservative):",
             "#   delta_zeta(n0) = a n0^3 + b n0^2 + c n0 + d   Eq. (20); delta_zeta in %, n0 in Hz",
             f"# the cubic >= 0 up to its first root R with the largest integral over [2.1 Hz, R], below every "
             f"retained case (rule {study_fit.rule}) with n0 <= R; R scanned up to {hi:g} Hz", *([f"# command: {command}"] if command else []),
             f"# zero from the first root, or from {hi:g} Hz where there is none", "",
             f"lower_limit_hz = {LOWER_LIMIT_HZ}", f"fit_range_max_hz = {hi}",
             'columns = ["a", "b", "c", "d", "upper_limit_hz", "r2", "max_res_pct", "min_res_pct"]']
    trains = []
    for r in rows:
        if r.train not in trains:
            trains.append(r.train)
            lines += ["", f"[tables.{toml_key(r.train)}]", f'source = "linear programme, rule {study_fit.rule}"']
        slack = r.fit.delta_zeta_pct - np.polyval(r.fit.coefficients, r.fit.n0_hz)
        vals = [*r.fit.coefficients, r.fit.upper_limit_hz, float("nan"), float(slack.max()), float(slack.min())]
        lines.append(f"{r.mass_function} = [{', '.join(repr(float(v)) for v in vals)}]")
    return "\n".join(lines) + "\n"


__all__ = ["ConservativeFit", "ConservativeRow", "conservative_cubic", "conservative_study", "conservative_markdown",
           "conservative_toml", "cubic_integral"]
