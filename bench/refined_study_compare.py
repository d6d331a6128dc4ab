"""Default (1 km/h) study against the refined-speed study: does the μ4-μ6 scatter shrink?

Run: ``.venv/bin/python bench/refined_study_compare.py [DEFAULT_RESULTS] [REFINED_RESULTS]``
(default ``results/study/results.jsonl.gz`` and ``results/study_refined/results.jsonl.gz``). Cases are
compared on the keys both files hold, with the fit's default exclusion rule (``step2``). Per set
(train x mass function): the standard deviation of Δζ_VBI over the used cases, the interval
minima (Section 4.2.1: 18 n0 intervals), the R² and residual spread of the cubic through them, and
the change of Δζ case by case (:func:`study_pairs.compare_cases`).
"""

import sys
from pathlib import Path

import numpy as np
import study_pairs as sp

from adm_calib import study as st
from adm_calib.study.fit import fit_study


def main():
    a = Path(sys.argv[1] if len(sys.argv) > 1 else "results/study/results.jsonl.gz")
    b = Path(sys.argv[2] if len(sys.argv) > 2 else "results/study_refined/results.jsonl.gz")
    old, new, keys = sp.matched(a, b)
    cases = sp.compare_cases(old, new, keys)
    print(f"{len(keys)} cases in both ({len(old)} default, {len(new)} refined)")
    fo = fit_study([old[k] for k in keys])
    fn = fit_study([new[k] for k in keys])
    print(f"{'set':14} {'n':>4} {'std old':>8} {'std new':>8} {'R2 old':>7} {'R2 new':>7} "
          f"{'min-res old':>11} {'min-res new':>11} {'|d minima|':>10} {'|d dz| mean':>11} {'max':>6}")
    rows = []
    for key in fo.fits:
        f0, f1 = fo.fits[key], fn.fits.get(key)
        if f1 is None:
            continue
        y0 = np.array([old[st.record_key(r)]["delta_zeta_vbi_pct"] for r in fo.records_used
                       if (r["train"], r["mass_function"]) == key])
        y1 = np.array([r["delta_zeta_vbi_pct"] for r in fn.records_used if (r["train"], r["mass_function"]) == key])
        d = np.array([c.dz_change_pct for c in cases
                      if (old[c.key]["train"], old[c.key]["mass_function"]) == key and c.dz_change_pct is not None])
        m0 = {(p.lo_hz, p.hi_hz): p.delta_zeta_pct for p in f0.minima}
        m1 = {(p.lo_hz, p.hi_hz): p.delta_zeta_pct for p in f1.minima}
        dm = np.array([m1[i] - m0[i] for i in m0 if i in m1])

        def r2(f):
            return float("nan") if f.fit is None else f.fit.r2

        def res(f):
            if f.fit is None:
                return float("nan")
            x = np.array([p.n0_hz for p in f.minima])
            y = np.array([p.delta_zeta_pct for p in f.minima])
            return float(np.std(y - f.fit.value_pct(x)))

        rows.append((key, y0.std(), y1.std()))
        print(f"{key[0] + ' ' + key[1]:14} {len(y1):4d} {y0.std():8.3f} {y1.std():8.3f} {r2(f0):7.3f} {r2(f1):7.3f} "
              f"{res(f0):11.3f} {res(f1):11.3f} {np.abs(dm).mean():10.3f} {np.abs(d).mean():11.4f} "
              f"{np.abs(d).max():6.3f}")
    for group, mfs in (("mu1-mu3 (CFB)", ("mu1", "mu2", "mu3")), ("mu4-mu6 (SC)", ("mu4", "mu5", "mu6"))):
        r = [x for x in rows if x[0][1] in mfs]
        print(f"{group}: std per set, mean over sets {np.mean([x[1] for x in r]):.3f} -> {np.mean([x[2] for x in r]):.3f} %"
              f"; sets whose std shrinks: {sum(x[2] < x[1] for x in r)} of {len(r)}")


if __name__ == "__main__":
    main()
