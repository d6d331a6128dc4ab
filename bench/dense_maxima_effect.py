"""What the dense-output maxima (StepOptions.dense_maxima) change in Δζ_VBI: Table 4 and one span.

Run: ``.venv/bin/python bench/dense_maxima_effect.py [--span 20]``. Prints Table 4's 16 Δζ_VBI
sampled -> dense, and for every case of one span of the study (4 trains x 6 mass functions x 5
frequencies) the change in Δζ_VBI and in the DIM and MLM peaks (statistics per train).
"""

import argparse
import time

import numpy as np

from adm_sim.integrate.step_grid import StepOptions

from adm_calib.calibrate import CalibrationOptions
from adm_calib import study as st
from adm_calib.table4 import run_table4


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--span", type=float, default=20.0, help="span of the study to compare (m)")
    args = ap.parse_args()
    dense = CalibrationOptions(step=StepOptions(dense_maxima=True))
    t0 = time.perf_counter()
    old, new = run_table4(), run_table4(options=dense)
    print(f"Table 4, dz_VBI (%), sampled -> dense ({time.perf_counter() - t0:.1f} s)")
    diffs = []
    for t, b in old.columns():
        a, c = old.value("VBI", t, b), new.value("VBI", t, b)
        ro, rn = old.results[(t, b)], new.results[(t, b)]
        d = None if a is None or c is None else c - a
        diffs.append(d)
        print(f"  {t:9} {b}: {a:.4f} -> {c:.4f} ({d:+.4f} %); DIM peak {ro.dim_peak.acc_m_s2:.5f} -> "
              f"{rn.dim_peak.acc_m_s2:.5f}, MLM peak {ro.mlm_peak.acc_m_s2:.5f} -> {rn.mlm_peak.acc_m_s2:.5f}")
    d = np.array([x for x in diffs if x is not None])
    print(f"  |change| max {np.abs(d).max():.4f} %, mean {np.abs(d).mean():.4f} %")
    settings_old = st.StudySettings()
    settings_new = st.StudySettings(dense_maxima=True)
    print(f"study, span {args.span:g} m: dz_VBI sampled -> dense, per train")
    for train in st.STUDY_TRAINS:
        cases = st.select_cases([train], st.MASS_FUNCTION_NAMES, (args.span, args.span), list(st.FREQ_INDICES))
        rows = []
        for batch in st.make_batches(cases):
            for ro, rn in zip(st.run_batch(batch, settings_old), st.run_batch(batch, settings_new)):
                if ro["delta_zeta_vbi_pct"] is not None and rn["delta_zeta_vbi_pct"] is not None:
                    rows.append((rn["delta_zeta_vbi_pct"] - ro["delta_zeta_vbi_pct"],
                                 rn["dim_peak_acc_m_s2"] / ro["dim_peak_acc_m_s2"] - 1,
                                 rn["mlm_peak_acc_m_s2"] / ro["mlm_peak_acc_m_s2"] - 1, ro["bridge"],
                                 ro["delta_zeta_vbi_pct"], rn["delta_zeta_vbi_pct"]))
        r = np.array([x[:3] for x in rows])
        worst = max(rows, key=lambda x: abs(x[0]))
        print(f"  {train:9}: {len(rows)} cases; dz change mean {r[:, 0].mean():+.4f} %, max |.| "
              f"{np.abs(r[:, 0]).max():.4f} % ({worst[3]}: {worst[4]:.4f} -> {worst[5]:.4f} %); DIM peak "
              f"+{100 * r[:, 1].mean():.3f} % mean (max {100 * r[:, 1].max():.3f} %), MLM peak "
              f"+{100 * r[:, 2].mean():.3f} % mean (max {100 * r[:, 2].max():.3f} %)")


if __name__ == "__main__":
    main()
