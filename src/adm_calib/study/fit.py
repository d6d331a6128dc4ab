"""The lower-bound fit of paper Section 4.2.1 (Eq. 20) over study results, next to Tables B1-B4."""

from __future__ import annotations

import csv
import json
import io
from collections import Counter
import math
import re
from dataclasses import dataclass, field

import numpy as np

from adm_sim.errors import InputError

from adm_calib import peaks as pk
from adm_calib.lower_bound import first_root_hz, lower_bound_pct
from adm_calib.reference import STUDY_TRAINS, lower_bound_table
from adm_calib.study.cases import INTERVAL_EDGES_HZ, LOWER_LIMIT_HZ, TRAIN_VARIANTS, paper_train
from adm_calib.study.store import record_key

# ====================================================================== lower-bound fit
@dataclass(frozen=True)
class IntervalMinimum:
    """Smallest Δζ (%) in one n0 interval ``[lo_hz, hi_hz)`` and the case that has it."""

    lo_hz: float
    hi_hz: float
    n_cases: int
    n0_hz: float
    delta_zeta_pct: float
    bridge: str = ""


def interval_minima(n0_hz, delta_zeta_pct, names=None, edges_hz=INTERVAL_EDGES_HZ):
    """Data points of Section 4.2.1: the minimum Δζ of each n0 interval.

    Intervals are ``[e_k, e_k+1)``, the last one closed; empty intervals give no point; n0
    outside ``[edges_hz[0], edges_hz[-1]]`` is not used. Ties go to the lowest n0.

    Parameters
    ----------
    n0_hz, delta_zeta_pct : array_like (n,)
    names : sequence of str (n,), optional
        Bridge names carried into the result.

    Returns
    -------
    list of IntervalMinimum
    """
    x = np.asarray(n0_hz, dtype=float)
    y = np.asarray(delta_zeta_pct, dtype=float)
    names = list(names) if names is not None else [""] * x.size
    out = []
    e = np.asarray(edges_hz, dtype=float)
    for k in range(e.size - 1):
        last = k == e.size - 2
        sel = np.flatnonzero((x >= e[k]) & ((x <= e[k + 1]) if last else (x < e[k + 1])))
        if sel.size == 0:
            continue
        sel = sel[np.lexsort((x[sel], y[sel]))]
        i = int(sel[0])
        out.append(IntervalMinimum(lo_hz=float(e[k]), hi_hz=float(e[k + 1]), n_cases=int(sel.size),
                                   n0_hz=float(x[i]), delta_zeta_pct=float(y[i]), bridge=str(names[i])))
    return out


@dataclass(frozen=True, repr=False)
class CubicFit:
    """Least-squares cubic of Eq. (20) through the interval minima (Δζ in %, n0 in Hz).

    ``residuals_pct`` (n_points,) are ``data - fit``; ``upper_limit_hz`` is the first root above
    2.1 Hz; ``fit_range_max_hz`` the upper end of the n0 range fitted (no extrapolation beyond).
    """

    coefficients: tuple
    r2: float
    n0_hz: np.ndarray
    delta_zeta_pct: np.ndarray
    residuals_pct: np.ndarray
    upper_limit_hz: float
    fit_range_max_hz: float = INTERVAL_EDGES_HZ[-1]

    @property
    def max_res_pct(self):
        return float(self.residuals_pct.max())

    @property
    def min_res_pct(self):
        return float(self.residuals_pct.min())

    def value_pct(self, n0_hz):
        """The lower bound (:func:`adm_calib.lower_bound.lower_bound_pct`): Eq. (20) up to the first
        root or the end of the fitted range, 0 beyond."""
        return lower_bound_pct(self.coefficients, n0_hz, LOWER_LIMIT_HZ, self.fit_range_max_hz)

    def __repr__(self):
        a, b, c, d = self.coefficients
        return (f"CubicFit(a={a:.4g}, b={b:.4g}, c={c:.4g}, d={d:.4g}, R2={self.r2:.4f}, "
                f"upper limit {self.upper_limit_hz:.2f} Hz)")


def fit_cubic(n0_hz, delta_zeta_pct, lower_limit_hz=LOWER_LIMIT_HZ, fit_range_max_hz=INTERVAL_EDGES_HZ[-1]):
    """Fit Eq. (20) to data points by linear least squares (:func:`numpy.polyfit`, degree 3).

    ``R² = 1 - SS_res / SS_tot`` about the data points. Needs at least 4 points.
    ``fit_range_max_hz``: upper end of the n0 range the points come from (0 beyond it).
    """
    x = np.asarray(n0_hz, dtype=float)
    y = np.asarray(delta_zeta_pct, dtype=float)
    if x.size < 4:
        raise InputError(f"fit: {x.size} data points; a cubic needs at least 4")
    coef = np.polyfit(x, y, 3)
    res = y - np.polyval(coef, x)
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum(res**2)) / ss_tot if ss_tot > 0 else float("nan")
    return CubicFit(coefficients=tuple(float(c) for c in coef), r2=r2, n0_hz=x, delta_zeta_pct=y,
                    residuals_pct=res, upper_limit_hz=first_root_hz(coef, lower_limit_hz),
                    fit_range_max_hz=float(fit_range_max_hz))


@dataclass(frozen=True, repr=False)
class LowerBoundFit:
    """Fit of one train and mass function, next to the published function (Tables B1-B4)."""

    train: str
    mass_function: str
    n_cases: int
    minima: list
    fit: CubicFit | None
    published: object = None
    note: str = ""

    def __repr__(self):
        return f"LowerBoundFit({self.train} {self.mass_function}: {self.n_cases} cases, {self.fit!r})"


#: Exclusion reasons used by :func:`fit_study` (key -> text).
EXCLUSIONS = {
    "error": "status error (the case raised)",
    "no_dz": "no dz_VBI (no reasonable peak, not bracketed or no match)",
    "dim_not_local_max": "associated DIM value not a local maximum (rules step2, strict)",
    "mlm_max_at_range_end": "largest MLM value at an end of the speed range (rule strict)",
    "above_21hz": "n0 above 21 Hz (not fitted, Section 4.2.1)",
    "outside_fit_range": "n0 outside the chosen fit range (--fit-range-hz), within 2-21 Hz",
    "other_train": "not a study train",
}

#: Exclusion rules (README "Exclusion rules"). History (results/study/APPENDIX_B_FINDINGS.md): the
#: first comparison with Table B1 (0877165) used today's ``strict`` (then ``--exclude-flagged``);
#: ``step2`` was added after it (4eb2b23) and made the default later (fb8435b).
#:
#: * ``none``: only cases without a Δζ_VBI (no reasonable peak, no bracket, no match, errors);
#: * ``step2`` (default): also cases whose associated DIM value is not a local maximum: Step 2 of
#:   Section 4 "considered only peaks that are also local maxima", for the MLM and the DIM alike
#:   (our MLM peak is an interior local maximum by construction, so the rule acts on the DIM);
#: * ``strict``: also cases whose largest MLM value lies at an end of the speed range (the chosen
#:   MLM peak is then a lesser interior maximum), reading Step 2's "maximum accelerations at
#:   350 km/h were excluded from the further investigations" as excluding the whole case.
EXCLUSION_RULES = {
    "none": (),
    "step2": ("dim_not_local_max",),
    "strict": ("dim_not_local_max", "mlm_max_at_range_end"),
}
DEFAULT_RULE = "step2"

#: Differences (% Δζ) above which a set is explained in the comparison (README).
EXPLAIN_ABOVE_PCT = 0.15
#: n0 values (Hz) at which fitted and published lower bounds are compared (README).
COMPARE_N0_HZ = (2.5, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0)


def case_flags(rec):
    """The exclusion reasons that apply to one result line (all of them, in rule order)."""
    if rec.get("status") == "error":
        return ["error"]
    if not pk.has_delta_zeta(rec.get("status")) or rec.get("delta_zeta_vbi_pct") is None:
        return ["no_dz"]  # range_end / not_associated keep their Δζ_VBI: the rules below exclude them as before
    out = []
    if rec.get("dim_is_local_max") is False:
        out.append("dim_not_local_max")
    if rec.get("mlm_max_at_range_end"):
        out.append("mlm_max_at_range_end")
    return out


def fit_edges_hz(lo_hz=INTERVAL_EDGES_HZ[0], hi_hz=INTERVAL_EDGES_HZ[-1]):
    """Interval boundaries (Hz) of a fit over ``[lo_hz, hi_hz]``: the Section 4.2.1 boundaries inside
    the range, with ``lo_hz`` and ``hi_hz`` as the outer ones (``2, 21``: the paper's intervals).

    Raises
    ------
    InputError
        A range outside 2..21 Hz, reversed, or holding fewer than 4 intervals (a cubic needs 4 points).
    """
    e0, e1 = INTERVAL_EDGES_HZ[0], INTERVAL_EDGES_HZ[-1]
    for name, v in (("lo", lo_hz), ("hi", hi_hz)):
        if not (isinstance(v, (int, float)) and e0 <= v <= e1):
            raise InputError(f"fit_range_hz: {name} = {v!r} Hz is out of range; allowed [{e0:g}, {e1:g}] Hz "
                             f"(the intervals of Section 4.2.1)")
    if not lo_hz < hi_hz:
        raise InputError(f"fit_range_hz: {lo_hz:g}:{hi_hz:g} Hz is reversed or empty; allowed lo < hi in "
                         f"[{e0:g}, {e1:g}] Hz")
    edges = (float(lo_hz),) + tuple(e for e in INTERVAL_EDGES_HZ if lo_hz < e < hi_hz) + (float(hi_hz),)
    if len(edges) - 1 < 4:
        raise InputError(f"fit_range_hz: {lo_hz:g}:{hi_hz:g} Hz holds {len(edges) - 1} intervals; a cubic needs at "
                         f"least 4 (interval boundaries {', '.join(f'{e:g}' for e in INTERVAL_EDGES_HZ)} Hz)")
    return edges


def _train_order(train):
    """Sort key: the paper's train order, each variant right after its paper train."""
    base = paper_train(train)
    return (STUDY_TRAINS.index(base) if base in STUDY_TRAINS else len(STUDY_TRAINS), train != base, train)


@dataclass(repr=False)
class StudyFit:
    """Lower-bound fits of a study, ``fits[(train, mass_function)]``, with the excluded cases counted."""

    fits: dict
    records_used: list
    n_records: int
    excluded: Counter
    rule: str
    duplicates: int = 0
    flags_by_set: dict = field(default_factory=dict)
    edges_hz: tuple = INTERVAL_EDGES_HZ

    @property
    def fit_range_hz(self):
        """``(lo, hi)`` of the n0 range fitted (Hz)."""
        return (self.edges_hz[0], self.edges_hz[-1])

    @property
    def trains(self):
        """Trains of the fitted sets, in the paper's order (variants after their paper train)."""
        return sorted({t for t, _ in self.fits}, key=_train_order)

    def difference_pct(self, key, n0_hz=COMPARE_N0_HZ):
        """Fitted minus published lower bound (% Δζ) at ``n0_hz`` for set ``key`` (as applied:
        Eq. 20 up to the first root, 0 beyond); None when either is missing."""
        f = self.fits.get(key)
        if f is None or f.fit is None or f.published is None:
            return None
        n0 = np.asarray(n0_hz, dtype=float)
        return f.fit.value_pct(n0) - f.published.value_pct(n0)

    def to_toml(self, command=""):
        """The fitted functions in the format of ``data/lower_bounds.toml`` (for ``--functions ours``)."""
        lines = ["# Lower-bound functions re-derived from the parametric study (adm-calib study-fit).",
                 "#   delta_zeta(n0) = a n0^3 + b n0^2 + c n0 + d   Eq. (20); delta_zeta in %, n0 in Hz",
                 f"# exclusion rule: {self.rule}; cases read {self.n_records}, used {len(self.records_used)}",
                 *( [f"# command: {command}"] if command else []),
                 f"# fitted over {self.edges_hz[0]:g}-{self.edges_hz[-1]:g} Hz; zero from the first root, or from the "
                 f"end of the fitted range ({self.edges_hz[-1]:g} Hz) where there is none",
                 "", f"lower_limit_hz = {LOWER_LIMIT_HZ}", f"fit_range_max_hz = {self.edges_hz[-1]}",
                 'columns = ["a", "b", "c", "d", "upper_limit_hz", "r2", "max_res_pct", "min_res_pct"]']
        trains = []
        for (t, m), f in self.fits.items():
            if f.fit is None:
                continue
            if t not in trains:
                trains.append(t)
                lines += ["", f"[tables.{toml_key(t)}]", f'source = "study fit, rule {self.rule}"']
            c = f.fit
            vals = [*c.coefficients, c.upper_limit_hz, c.r2, c.max_res_pct, c.min_res_pct]
            lines.append(f"{m} = [{', '.join(repr(float(v)) for v in vals)}]")
        return "\n".join(lines) + "\n"

    def to_text(self):
        w = max([9] + [len(t) + 1 for t, _ in self.fits])
        head = (f"{'train':{w}}{'mass':5}{'':6}{'cases':>6}{'pts':>4}{'a':>11}{'b':>11}{'c':>11}{'d':>11}"
                f"{'upper Hz':>9}{'R2':>8}{'max res':>9}{'min res':>9}")
        lines = ["Lower-bound functions, Eq. (20): dz = a n0^3 + b n0^2 + c n0 + d (dz in %, n0 in Hz), "
                 "Section 4.2.1; 'paper' = Tables B1-B4", head, "-" * len(head)]

        def nums(a, b, c, d, up, r2, mx, mn):
            return f"{a:11.4g}{b:11.4g}{c:11.4g}{d:11.4g}{up:9.2f}{r2:8.4f}{mx:9.4f}{mn:9.4f}"

        for (t, m), f in self.fits.items():
            pre = f"{t:{w}}{m:5}{'fit':6}{f.n_cases:6d}{len(f.minima):4d}"
            if f.fit is None:
                lines.append(f"{pre}  {f.note}")
            else:
                c = f.fit
                lines.append(pre + nums(*c.coefficients, c.upper_limit_hz, c.r2, c.max_res_pct, c.min_res_pct))
            p = f.published
            if p is not None:
                lines.append(f"{'':{w + 5}}{'paper':6}{'':10}" + nums(p.a, p.b, p.c, p.d, p.upper_limit_hz, p.r2,
                                                                   p.max_res_pct, p.min_res_pct))
        used = len(self.records_used)
        lines.append(f"cases: {self.n_records} read, {used} used"
                     + (f", {self.duplicates} duplicate lines (last kept)" if self.duplicates else ""))
        for k, n in self.excluded.items():
            lines.append(f"  excluded {n:5d}: {EXCLUSIONS.get(k, k)}")
        return "\n".join(lines)

    def to_csv(self):
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        cols = ["a", "b", "c", "d", "upper_limit_hz", "r2", "max_res_pct", "min_res_pct"]
        w.writerow(["train", "mass_function", "n_cases", "n_points"] + cols + [f"paper_{c}" for c in cols] + ["note"])
        for (t, m), f in self.fits.items():
            if f.fit is None:
                fit = [""] * len(cols)
            else:
                c = f.fit
                fit = [*(f"{v:.6g}" for v in c.coefficients), f"{c.upper_limit_hz:.4f}", f"{c.r2:.4f}",
                       f"{c.max_res_pct:.5f}", f"{c.min_res_pct:.5f}"]
            p = f.published
            pub = [""] * len(cols) if p is None else [f"{getattr(p, c):.6g}" for c in cols]
            w.writerow([t, m, f.n_cases, len(f.minima)] + fit + pub + [f.note])
        return buf.getvalue()

    def minima_csv(self):
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["train", "mass_function", "lo_hz", "hi_hz", "n_cases", "n0_hz", "delta_zeta_pct", "bridge",
                    "fit_pct", "residual_pct"])
        for (t, m), f in self.fits.items():
            for p in f.minima:
                fv = "" if f.fit is None else float(np.polyval(f.fit.coefficients, p.n0_hz))
                w.writerow([t, m, f"{p.lo_hz:g}", f"{p.hi_hz:g}", p.n_cases, f"{p.n0_hz:.4f}",
                            f"{p.delta_zeta_pct:.5f}", p.bridge, "" if fv == "" else f"{fv:.5f}",
                            "" if fv == "" else f"{p.delta_zeta_pct - fv:.5f}"])
        return buf.getvalue()


def _exclusion(rec, rule):
    flags = case_flags(rec)
    if flags and flags[0] in ("error", "no_dz"):
        return flags[0]
    for f in EXCLUSION_RULES[rule]:
        if f in flags:
            return f
    return None


def toml_key(name):
    """``name`` as a TOML key: bare where it may be (``ICE-2``), else quoted (``"my train"``)."""
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name)


def fit_study(records, rule=DEFAULT_RULE, edges_hz=INTERVAL_EDGES_HZ, own_trains=()):
    """Lower-bound functions per train and mass function from study records (Section 4.2.1).

    Parameters
    ----------
    records : iterable of dict
        Result lines (``train``, ``mass_function``, ``n0_hz``, ``status``, ``delta_zeta_vbi_pct``,
        flags); for a repeated (bridge, train) key the last line counts.
    rule : {"none", "step2", "strict"}
        Exclusion rule (:data:`EXCLUSION_RULES`); default ``step2``.
    edges_hz : sequence of float
        Interval boundaries (Hz); :func:`fit_edges_hz` gives them for a narrower fit range. The
        fitted functions are 0 above the last one where their cubic has no root before it.
    own_trains : collection of str
        Trains read from files by the study (``study.json`` ``train_files``), fitted like the paper
        trains; lines of any other train are left out (``other_train``).

    Returns
    -------
    StudyFit
    """
    if rule not in EXCLUSION_RULES:
        raise InputError(f"exclude: {rule!r} is not a rule; allowed {', '.join(EXCLUSION_RULES)}")
    records = list(records)
    by_key = {record_key(r): r for r in records}
    dup = len(records) - len(by_key)
    excluded = Counter()
    flags_by_set = {}
    used = []
    groups = {}
    for rec in by_key.values():
        cnt = flags_by_set.setdefault((rec.get("train"), rec.get("mass_function")), Counter())
        cnt["cases"] += 1
        for f in case_flags(rec):
            cnt[f] += 1
        why = _exclusion(rec, rule)
        if why is None and paper_train(rec["train"]) not in STUDY_TRAINS and rec["train"] not in own_trains:
            why = "other_train"
        if why is not None:
            excluded[why] += 1
            continue
        used.append(rec)
        groups.setdefault((rec["train"], rec["mass_function"]), []).append(rec)
    table = lower_bound_table()
    fits = {}
    edges_hz = tuple(float(e) for e in edges_hz)
    for key in sorted(groups, key=lambda k: (_train_order(k[0]), k[1])):
        t, m = key
        recs = groups[key]
        x = np.array([r["n0_hz"] for r in recs], dtype=float)
        y = np.array([r["delta_zeta_vbi_pct"] for r in recs], dtype=float)
        over = int(np.count_nonzero(x > INTERVAL_EDGES_HZ[-1]))
        if over:
            excluded["above_21hz"] += over
        outside = int(np.count_nonzero((x <= INTERVAL_EDGES_HZ[-1]) & ((x < edges_hz[0]) | (x > edges_hz[-1]))))
        if outside:
            excluded["outside_fit_range"] += outside
        minima = interval_minima(x, y, [r["bridge"] for r in recs], edges_hz)
        fit, note = None, ""
        if len(minima) >= 4:
            fit = fit_cubic([p.n0_hz for p in minima], [p.delta_zeta_pct for p in minima],
                            fit_range_max_hz=edges_hz[-1])
        else:
            note = f"only {len(minima)} interval minima; a cubic needs 4"
        fits[key] = LowerBoundFit(train=t, mass_function=m, n_cases=len(recs), minima=minima, fit=fit,
                                  published=table.get(paper_train(t), {}).get(m), note=note)
    return StudyFit(fits=fits, records_used=used, n_records=len(by_key), excluded=excluded,
                    rule=rule, duplicates=dup, flags_by_set=flags_by_set, edges_hz=edges_hz)


def _g(x, fmt="{:.4g}"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def comparison_markdown(records, rule=DEFAULT_RULE, edges_hz=INTERVAL_EDGES_HZ, own_trains=()):
    """Markdown tables: our fit next to Tables B1-B4 per train, the differences of the lower bounds
    at :data:`COMPARE_N0_HZ`, the cases each flag excludes per set and the effect of each rule.

    A variant train (``Eurostar-table``) is compared with its paper train's table."""
    records = list(records)
    fits = {r: fit_study(records, rule=r, edges_hz=edges_hz, own_trains=own_trains) for r in EXCLUSION_RULES}
    main = fits[rule]
    lo, hi = main.fit_range_hz
    rng = "" if (lo, hi) == (INTERVAL_EDGES_HZ[0], INTERVAL_EDGES_HZ[-1]) else (
        f" Fit range **{lo:g}-{hi:g} Hz** (intervals {', '.join(f'{e:g}' for e in main.edges_hz)} Hz; our "
        f"functions are 0 above {hi:g} Hz where their cubic has no root before).")
    out = [f"Exclusion rule of the fits below: **{rule}**.{rng} Differences are ours minus the paper's lower bound "
           f"(Eq. 20 up to the first root, 0 beyond), in % of critical damping.", ""]
    for t in main.trains:
        out += _train_tables(main, t)
    out += _flag_table(main, fits)
    out += _explained_table(main, fits, records, rule)
    return "\n".join(out) + "\n"


def _train_tables(main, t):
    """:func:`comparison_markdown`'s lines of one train: the coefficients (ours, paper's) per set, then
    the differences at :data:`COMPARE_N0_HZ`; none for a train without a fitted set."""
    rows = [(m, f) for (tt, m), f in main.fits.items() if tt == t]
    if not rows:
        return []
    vs = f" (compared with Table B of {paper_train(t)})" if t in TRAIN_VARIANTS else ""
    out = [f"**{t}**{vs}", "",
           "| set | | a | b | c | d | upper limit (Hz) | R² | max res (%) | min res (%) | points |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for m, f in rows:
        c, p = f.fit, f.published
        if c is not None:
            out.append(f"| {m} | ours | {_g(c.coefficients[0])} | {_g(c.coefficients[1])} | "
                       f"{_g(c.coefficients[2])} | {_g(c.coefficients[3])} | {_g(c.upper_limit_hz, '{:.2f}')} | "
                       f"{c.r2:.3f} | {c.max_res_pct:.4f} | {c.min_res_pct:.4f} | {len(f.minima)} |")
        if p is not None:
            out.append(f"| | paper | {_g(p.a)} | {_g(p.b)} | {_g(p.c)} | {_g(p.d)} | {p.upper_limit_hz:.2f} | "
                       f"{p.r2:.3f} | {p.max_res_pct:.4f} | {p.min_res_pct:.4f} | |")
    out += ["", "| set | " + " | ".join(f"{x:g} Hz" for x in COMPARE_N0_HZ) + " | max abs |",
            "|---|" + "---|" * (len(COMPARE_N0_HZ) + 1)]
    for m, _f in rows:
        d = main.difference_pct((t, m))
        if d is None:
            continue
        out.append(f"| {m} | " + " | ".join(f"{x:+.3f}" for x in d) + f" | {np.max(np.abs(d)):.3f} |")
    out.append("")
    return out


def _flag_table(main, fits):
    """:func:`comparison_markdown`'s table of the cases per set, its flags and the largest difference
    under each rule."""
    out = ["Cases per set and what each flag concerns (a case can carry both flags); then the largest "
           "|ours - paper| over 2.5-13 Hz under each rule:", "",
           "| set | cases | no dz_VBI | DIM value not a local max | MLM max at range end | "
           + " | ".join(f"max diff, {r}" for r in EXCLUSION_RULES) + " |",
           "|---|---|---|---|---|" + "---|" * len(EXCLUSION_RULES)]
    for t in sorted({k[0] for k in main.flags_by_set}, key=_train_order):
        for m in sorted({k[1] for k in main.flags_by_set if k[0] == t}):
            cnt = main.flags_by_set[(t, m)]
            diffs = []
            for r in EXCLUSION_RULES:
                d = fits[r].difference_pct((t, m))
                diffs.append("-" if d is None else f"{np.max(np.abs(d)):.3f}")
            out.append(f"| {t} {m} | {cnt['cases']} | {cnt['no_dz'] + cnt['error']} | {cnt['dim_not_local_max']} | "
                       f"{cnt['mlm_max_at_range_end']} | " + " | ".join(diffs) + " |")
    return out


def _explained_table(main, fits, records, rule):
    """:func:`comparison_markdown`'s table of the sets whose bound differs from the paper's by more
    than :data:`EXPLAIN_ABOVE_PCT`, with the interval minimum that carries the fit there."""
    out = ["", f"Sets whose lower bound differs from the paper's by more than {EXPLAIN_ABOVE_PCT:g} % anywhere in "
           f"2.5-13 Hz (rule {rule}): where the difference is largest, our interval minimum nearest to that n0 "
           "(the data point that carries our fit there) with its flags, and the largest difference under the "
           "other rules:", "",
           "| set | max diff (%) | at n0 (Hz) | nearest interval minimum | its dz (%) | MLM peak | MLM max at "
           "range end | " + " | ".join(f"max diff, {r}" for r in EXCLUSION_RULES if r != rule) + " |",
           "|---|---|---|---|---|---|---|" + "---|" * (len(EXCLUSION_RULES) - 1)]
    recs = {record_key(r): r for r in records}
    grid = np.linspace(2.5, 13.0, 106)
    for key, f in main.fits.items():
        d = main.difference_pct(key, grid)
        if d is None or np.max(np.abs(d)) <= EXPLAIN_ABOVE_PCT:
            continue
        i = int(np.argmax(np.abs(d)))
        x = grid[i]
        pmin = min(f.minima, key=lambda q: abs(q.n0_hz - x))
        rec = recs.get((pmin.bridge, key[0]), {})
        pk_ = rec.get("mlm_peak") or {}
        others = []
        for r in EXCLUSION_RULES:
            if r == rule:
                continue
            dd = fits[r].difference_pct(key, grid)
            others.append("-" if dd is None else f"{np.max(np.abs(dd)):.3f}")
        out.append(f"| {key[0]} {key[1]} | {d[i]:+.3f} | {x:.1f} | {pmin.bridge} (n0 {pmin.n0_hz:.2f} Hz) | "
                   f"{pmin.delta_zeta_pct:+.3f} | {pk_.get('acc_m_s2', float('nan')):.2f} m/s² at "
                   f"{pk_.get('speed_kmh', float('nan')):g} km/h | {'yes' if rec.get('mlm_max_at_range_end') else 'no'} | "
                   + " | ".join(others) + " |")
    return out


# ====================================================================== Table B range check
@dataclass(frozen=True)
class RangeCheckRow:
    """One Table B set: the highest value an interval minimum in ``[lo_hz, hi_hz]`` could take.

    A least-squares point lies at ``cubic + residual`` and Table B prints the largest residual, so
    an interval minimum at ``n0`` in the interval is at most ``p(n0) + max_res``; ``ceiling_pct`` is
    the largest of that over the interval. ``zeta_max_pct``: the largest damping of the set's study
    bridges in the interval (the most lenient ``-ζ`` a point could stay above).
    """

    train: str
    mass_function: str
    ceiling_pct: float
    ceiling_n0_hz: float
    zeta_max_pct: float
    below_lowest: bool
    below_minus_zeta: bool


def table_b_range_check(records, lo_hz=16.0, hi_hz=21.0, table=None):
    """For every Table B1-B4 set: could the paper's fit have had a data point in ``[lo_hz, hi_hz]``?

    A point there would lie at most ``max over n0 of (p(n0) + max_res)`` (the cubic plus the set's
    own largest printed residual). Compared with the lowest Δζ_VBI of the whole study and with
    ``-ζ`` (Δζ < -ζ: a negative total damping) of the set's bridges in the interval.

    Parameters
    ----------
    records : iterable of dict
        Study result lines (``train``, ``mass_function``, ``n0_hz``, ``zeta_pct``, ``delta_zeta_vbi_pct``).
    table : dict, optional
        ``{train: {mass_function: LowerBound}}``; default the published Tables B1-B4.

    Returns
    -------
    (list of RangeCheckRow, float)
        The rows and the lowest Δζ_VBI (%) of all records.
    """
    records = list(records)
    table = table or lower_bound_table("paper")
    lowest = min(r["delta_zeta_vbi_pct"] for r in records if r.get("delta_zeta_vbi_pct") is not None)
    grid = np.linspace(lo_hz, hi_hz, int(round((hi_hz - lo_hz) / 0.001)) + 1)
    rows = []
    for t in STUDY_TRAINS:
        for m, lb in table.get(t, {}).items():
            v = np.polyval(lb.coefficients, grid) + lb.max_res_pct
            i = int(np.argmax(v))
            zs = [r["zeta_pct"] for r in records if r["train"] == t and r["mass_function"] == m
                  and lo_hz <= r["n0_hz"] <= hi_hz]
            zmax = max(zs) if zs else float("nan")
            rows.append(RangeCheckRow(train=t, mass_function=m, ceiling_pct=float(v[i]), ceiling_n0_hz=float(grid[i]),
                                      zeta_max_pct=zmax, below_lowest=bool(v[i] < lowest),
                                      below_minus_zeta=bool(v[i] < -zmax)))
    return rows, float(lowest)
