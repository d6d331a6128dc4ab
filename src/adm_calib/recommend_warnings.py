"""Where the shipped study says VBI raises the response: warnings for ``recommend`` and the list of
excluded cases below the conservative bound (results/study/README.md).

A study case has ``Δζ_VBI < 0`` when the DIM peak lies above the MLM peak at the bridge's own damping
(the vehicles raise the response; paper Section 4.2.1 notes such cases). A recommendation Δζ_LB is
not conservative for a bridge like a study case whose Δζ_VBI is smaller. ``recommend`` therefore
looks at the study cases of the same train and mass function(s) with n0 within
:data:`NEIGHBOURHOOD_HZ` of the asked one and names those with ``Δζ_VBI < 0`` and those below the
value it returns, retained and excluded alike (an excluded case says why it was excluded).

The cases come from ``data/study_cases.csv`` (train, mass function, bridge, n0, Δζ_VBI, the
exclusion reason of the default rule), written by :func:`study_cases_csv` from the shipped
``results/study/results.jsonl.gz`` (a test keeps the two equal), so an installed package carries
them without the 4440-line results file.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

from adm_calib import peaks as pk
from adm_calib.reference import lower_bound_table
from adm_calib.study.fit import DEFAULT_RULE, EXCLUSIONS, _exclusion

#: Half width (Hz) of the neighbourhood of the asked n0: the 0.5 Hz intervals of Section 4.2.1.
NEIGHBOURHOOD_HZ = 0.5
#: The study's cases shipped with the package.
CASES_FILE = "data/study_cases.csv"
_COLUMNS = ("train", "mass_function", "bridge", "n0_hz", "delta_zeta_vbi_pct", "excluded", "detail")
#: Cases named per warning line (the rest counted).
MAX_NAMED = 8


@dataclass(frozen=True)
class StudyCase:
    """One case of the shipped study with a Δζ_VBI (%); ``excluded``: the key of
    :data:`adm_calib.study.fit.EXCLUSIONS` under the default rule, or ``""`` (retained)."""

    train: str
    mass_function: str
    bridge: str
    n0_hz: float
    delta_zeta_vbi_pct: float
    excluded: str
    detail: str = ""

    def label(self):
        why = f", excluded: {EXCLUSIONS[self.excluded]}" if self.excluded else ""
        return f"{self.bridge} ({self.n0_hz:.2f} Hz, dz_VBI {self.delta_zeta_vbi_pct:+.2f} %{why})"


def study_cases_csv(records, rule=DEFAULT_RULE):
    """CSV text of every study record with a Δζ_VBI (the last line per (bridge, train) counts; n0 and
    Δζ to 1e-6 Hz and 1e-6 %)."""
    by_key = {(r["bridge"], r["train"]): r for r in records}
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_COLUMNS)
    for r in sorted(by_key.values(), key=lambda r: (r["train"], r["mass_function"], r["n0_hz"], r["bridge"])):
        if not pk.has_delta_zeta(r.get("status")) or r.get("delta_zeta_vbi_pct") is None:
            continue
        why = _exclusion(r, rule) or ""
        w.writerow([r["train"], r["mass_function"], r["bridge"], f"{r['n0_hz']:.6f}",
                    f"{r['delta_zeta_vbi_pct']:.6f}", why, _detail(r) if why else ""])
    return buf.getvalue()


_AT_END = "largest DIM value at an end of the speed range"


def _detail(r):
    """Why the peaks of an excluded case were not used, from its record (speeds in km/h)."""
    mlm, dim = r.get("mlm_peak") or {}, r.get("dim_peak") or {}
    text = (f"MLM peak {mlm.get('speed_kmh', float('nan')):g} km/h, DIM value at {dim.get('speed_kmh', float('nan')):g} "
            f"km/h: {r.get('association_rule', '')}")
    if r.get("dim_max_at_range_end"):
        text += f"; {_AT_END}"
    return text


def parse_cases(text):
    rows = list(csv.reader(io.StringIO(text)))
    return tuple(StudyCase(t, m, b, float(n0), float(dz), why, det) for t, m, b, n0, dz, why, det in rows[1:])


@lru_cache(maxsize=1)
def study_cases():
    """The shipped study's cases with a Δζ_VBI (:class:`StudyCase`, tuple)."""
    return parse_cases(resources.files("adm_calib").joinpath(CASES_FILE).read_text())


def neighbourhood(train, mass_functions, n0_hz, *, cases=None, half_width_hz=NEIGHBOURHOOD_HZ):
    """Cases of ``train`` and ``mass_functions`` with ``|n0_i - n0| <= half_width_hz``, by n0."""
    cases = study_cases() if cases is None else cases
    out = [c for c in cases if c.train == train and c.mass_function in mass_functions
           and abs(c.n0_hz - n0_hz) <= half_width_hz]
    return sorted(out, key=lambda c: (c.n0_hz, c.bridge))


def _named(cases):
    shown = "; ".join(c.label() for c in cases[:MAX_NAMED])
    more = len(cases) - MAX_NAMED
    return shown + (f"; and {more} more" if more > 0 else "")


def recommendation_warnings(rec, cases=None, half_width_hz=NEIGHBOURHOOD_HZ):
    """Warnings (one line each, without the ``warning:`` prefix the command line adds) for a
    :class:`adm_calib.reference.Recommendation`: the neighbouring study cases (same train and mass
    function(s), n0 within ``half_width_hz``) with Δζ_VBI < 0, and those below the returned Δζ_LB.
    Empty when there are none."""
    near = neighbourhood(rec.train, rec.mass_functions, rec.n0_hz, cases=cases, half_width_hz=half_width_hz)
    where = (f"{rec.train} {'/'.join(rec.mass_functions)} within +/-{half_width_hz:g} Hz of n0 = {rec.n0_hz:g} Hz "
             f"({len(near)} study cases)")
    out = []
    neg = [c for c in near if c.delta_zeta_vbi_pct < 0.0]
    if neg:
        out.append(f"{len(neg)} of the {where} have dz_VBI < 0, the DIM peak above the MLM peak at the "
                   f"bridge's own damping (VBI raises the response): {_named(neg)}")
    below = [c for c in near if c.delta_zeta_vbi_pct < rec.delta_zeta_pct]
    if below:
        out.append(f"{len(below)} of the {where} lie below the returned dz_LB = {rec.delta_zeta_pct:.4f} % "
                   f"(for such bridges it is not conservative): {_named(below)}")
    return out


# ---------------------------------------------------------------------- the study README's list
def excluded_below_bound(cases=None, functions="conservative"):
    """Excluded cases (default rule) of the four study trains whose Δζ_VBI lies below the lower
    bound ``functions`` of their train and mass function at their n0 where that bound is positive
    (a negative Δζ beyond the bound's root lies below any bound, the paper's too: counted apart by
    :func:`excluded_negative_beyond_root`), by train, mass function, n0; ``[(case, bound_pct)]``."""
    cases = study_cases() if cases is None else cases
    table = lower_bound_table(functions)
    out = []
    for c in cases:
        if not c.excluded or c.train not in table or c.mass_function not in table[c.train]:
            continue
        b = table[c.train][c.mass_function]
        if c.n0_hz < b.lower_limit_hz:
            continue
        bound = float(b.value_pct(c.n0_hz))
        if c.delta_zeta_vbi_pct < bound and bound > 0.0:
            out.append((c, bound))
    return out


def excluded_negative_beyond_root(cases=None, functions="conservative"):
    """Excluded cases with Δζ_VBI < 0 where the bound ``functions`` is 0 (beyond its root)."""
    cases = study_cases() if cases is None else cases
    table = lower_bound_table(functions)
    return [c for c in cases if c.excluded and c.delta_zeta_vbi_pct < 0.0 and c.train in table
            and c.mass_function in table[c.train] and c.n0_hz >= table[c.train][c.mass_function].lower_limit_hz
            and float(table[c.train][c.mass_function].value_pct(c.n0_hz)) <= 0.0]


def excluded_below_bound_markdown(cases=None):
    """The README's table of :func:`excluded_below_bound` (conservative bound)."""
    cases = study_cases() if cases is None else cases
    rows = excluded_below_bound(cases)
    neg = excluded_negative_beyond_root(cases)
    n_excl = sum(1 for c in cases if c.excluded)
    lines = [f"{len(rows)} of the {n_excl} excluded cases with a Δζ_VBI (rule {DEFAULT_RULE}) lie below the "
             f"conservative bound of their set where it is positive; {len(neg)} more have Δζ_VBI < 0 beyond its "
             f"root (below any bound). {sum(_AT_END in c.detail for c, _ in rows)} of the {len(rows)} have their "
             f"largest DIM value at an end of the speed range. Generated by `adm_calib.recommend_warnings.excluded_below_bound_markdown` "
             f"(tests/calib/test_recommend_warnings.py keeps this list equal to it); `recommend` warns about such "
             f"cases near the asked n0.", "",
             "| case | n0 (Hz) | Δζ_VBI (%) | conservative bound (%) | excluded because | peaks |",
             "|---|---|---|---|---|---|"]
    for c, bound in rows:
        lines.append(f"| {c.train} {c.bridge} | {c.n0_hz:.3f} | {c.delta_zeta_vbi_pct:.3f} | {bound:.3f} | "
                     f"{EXCLUSIONS[c.excluded]} | {c.detail} |")
    return "\n".join(lines) + "\n"
