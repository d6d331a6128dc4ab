"""How often the rough-track DIM peak exceeds the smooth-track MLM peak without any added damping.

For every shipped rough-track calibration of the μ2 set (``runs/<spectrum>-s1`` and ``-s2``: every
μ2 bridge x ICE-2 and Railjet; seeds 3..5 hold only the slice and are left out so every seed counts
the same bridges), the DIM peak on rough track (associated with the MLM peak, Section 4 Step 2)
against the MLM peak at the bridge's own damping (Δζ = 0; the MLM has no wheels, so it is the
smooth-track MLM of the shipped study), split by the MLM peak below and at or above 3.5 m/s² (the
ballasted-track limit, EN 1990 A2.4.4.2.1). Prints the markdown table of results/irregularity/README.md
(tests/model/test_irregularity_framing.py keeps the two equal):

    PYTHONPATH=src .venv/bin/python results/irregularity/exceedance.py
"""

import gzip
import json
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SPECTRA = (("german-low", "German low"), ("fra-6", "FRA class 6"), ("german-high", "German high"))
SEEDS = (1, 2)
LIMIT_M_S2 = 3.5


def smooth_rows():
    """The shipped smooth-track study's lines of the same cases (μ2, ICE-2 and Railjet), as :func:`rows`."""
    out = []
    with gzip.open(HERE.parent / "study" / "results.jsonl.gz", "rt") as fh:
        for line in fh:
            r = json.loads(line)
            m, d = r.get("mlm_peak"), r.get("dim_peak")
            if r["mass_function"] == "mu2" and r["train"] in ("ICE-2", "Railjet") and m and d:
                out.append(("smooth (shipped study)", 0, float(m["acc_m_s2"]), float(d["acc_m_s2"])))
    return out


def rows():
    """``[(spectrum label, seed, mlm_peak m/s2, rough dim_peak m/s2)]`` of every line with both peaks."""
    out = smooth_rows()
    for key, label in SPECTRA:
        for seed in SEEDS:
            for line in (HERE / "runs" / f"{key}-s{seed}" / "results.jsonl").read_text().splitlines():
                if not line.strip():
                    continue
                r = json.loads(line)
                m, d = r.get("mlm_peak"), r.get("dim_peak")
                if m and d:
                    out.append((label, seed, float(m["acc_m_s2"]), float(d["acc_m_s2"])))
    return out


def table():
    data = rows()
    lines = ["| track (seeds 1, 2; μ2 set, ICE-2 and Railjet) | MLM peak | cases | DIM > MLM (Δζ = 0) | "
             "excess, median / max |",
             "|---|---|---|---|---|"]
    for label in ("smooth (shipped study)", *(label for _, label in SPECTRA)):
        for name, sel in ((f"< {LIMIT_M_S2:g} m/s²", lambda m: m < LIMIT_M_S2),
                          (f">= {LIMIT_M_S2:g} m/s²", lambda m: m >= LIMIT_M_S2)):
            x = [(m, d) for s, _, m, d in data if s == label and sel(m)]
            ex = np.array([d / m - 1.0 for m, d in x if d > m])
            share = f"{ex.size} ({100 * ex.size / len(x):.0f} %)" if x else "0"
            excess = f"+{100 * np.median(ex):.1f} % / +{100 * ex.max():.1f} %" if ex.size else "-"
            lines.append(f"| {label} | {name} | {len(x)} | {share} | {excess} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(table(), end="")
