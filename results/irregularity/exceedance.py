"""How often the rough-track DIM peak exceeds the smooth-track MLM peak without any added damping.

For every shipped rough-track calibration of the μ2 set (``runs/<spectrum>-s1`` and ``-s2``: every
μ2 bridge x ICE-2 and Railjet; seeds 3..5 hold only the slice and are left out so every seed counts
the same bridges), the DIM peak on rough track (associated with the MLM peak, Section 4 Step 2)
against the MLM peak at the bridge's own damping (Δζ = 0; the MLM has no wheels, so it is the
smooth-track MLM of the shipped study), split by the MLM peak below and at or above 3.5 m/s² (the
ballasted-track limit, EN 1990 A2.4.4.2.1). Prints the markdown table of results/irregularity/README.md
(tests/model/test_irregularity_framing.py keeps the two equal):

    PYTHONPATH=src .venv/bin/python results/irregularity/exceedance.py

The DIM assumes every wheel stays on the rail (paper Section 2); a line whose DIM peak comes from a
run in which a wheel would lift off has the status ``contact_lost`` (``adm_sim.integrate.contact``).
Those cases are counted in a column of their own and left out of the share and the excess, which
are over the cases that keep contact; :func:`contact_lost_table` lists them (speed of the DIM peak,
axle, time and force, from the line's message).
"""

import gzip
import json
import re
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SPECTRA = (("german-low", "German low"), ("fra-6", "FRA class 6"), ("german-high", "German high"))
SEEDS = (1, 2)
LIMIT_M_S2 = 3.5
CONTACT_LOST = "contact_lost"
#: The calibration's message of a contact_lost line (adm_calib.lanes.contact_message).
_LOSS_RE = re.compile(r"DIM peak at ([0-9.]+) km/h .* axle (\d+) would lift off the rail \(t = ([0-9.e+-]+) s, "
                      r"contact force ([0-9.e+-]+) kN < 0\)")


def _row(label, seed, r):
    m, d = r.get("mlm_peak"), r.get("dim_peak")
    if not (m and d):
        return None
    return (label, seed, float(m["acc_m_s2"]), float(d["acc_m_s2"]), r.get("status") == CONTACT_LOST,
            f"{r['bridge']} x {r['train']}", r.get("message") or "")


def smooth_rows():
    """The shipped smooth-track study's lines of the same cases (μ2, ICE-2 and Railjet), as :func:`rows`."""
    out = []
    with gzip.open(HERE.parent / "study" / "results.jsonl.gz", "rt") as fh:
        for line in fh:
            r = json.loads(line)
            if r["mass_function"] == "mu2" and r["train"] in ("ICE-2", "Railjet"):
                row = _row("smooth (shipped study)", 0, r)
                if row:
                    out.append(row)
    return out


def rows():
    """``[(spectrum label, seed, mlm_peak m/s2, rough dim_peak m/s2, contact lost, case, message)]`` of
    every line with both peaks."""
    out = smooth_rows()
    for key, label in SPECTRA:
        for seed in SEEDS:
            for line in (HERE / "runs" / f"{key}-s{seed}" / "results.jsonl").read_text().splitlines():
                if line.strip():
                    row = _row(label, seed, json.loads(line))
                    if row:
                        out.append(row)
    return out


def table():
    data = rows()
    lines = ["| track (seeds 1, 2; μ2 set, ICE-2 and Railjet) | MLM peak | cases | contact lost at the DIM peak | "
             "DIM > MLM (Δζ = 0), cases keeping contact | excess, median / max |",
             "|---|---|---|---|---|---|"]
    for label in ("smooth (shipped study)", *(label for _, label in SPECTRA)):
        for name, sel in ((f"< {LIMIT_M_S2:g} m/s²", lambda m: m < LIMIT_M_S2),
                          (f">= {LIMIT_M_S2:g} m/s²", lambda m: m >= LIMIT_M_S2)):
            sel_rows = [x for x in data if x[0] == label and sel(x[2])]
            lost = [x for x in sel_rows if x[4]]
            kept = [(x[2], x[3]) for x in sel_rows if not x[4]]
            ex = np.array([d / m - 1.0 for m, d in kept if d > m])
            share = f"{ex.size} ({100 * ex.size / len(kept):.0f} %)" if kept else "0"
            excess = f"+{100 * np.median(ex):.1f} % / +{100 * ex.max():.1f} %" if ex.size else "-"
            lost_txt = f"{len(lost)} ({sum(d > m for _, _, m, d, *_ in lost)} with DIM > MLM)" if lost else "0"
            lines.append(f"| {label} | {name} | {len(sel_rows)} | {lost_txt} | {share} | {excess} |")
    return "\n".join(lines) + "\n"


def contact_lost_table():
    """Every line of :func:`rows` with the status contact_lost: track, seed, case, MLM and DIM peaks, and
    the loss its message names (speed of the DIM peak, axle counted from the leading one, time, force)."""
    lines = ["| track | seed | case | MLM peak (m/s²) | DIM peak (m/s²) | DIM peak speed (km/h) | axle | t (s) | "
             "contact force (kN) |", "|---|---|---|---|---|---|---|---|---|"]
    for label, seed, m, d, lost, case, msg in rows():
        if lost:
            g = _LOSS_RE.search(msg)
            v, axle, t, f = g.groups() if g else ("?",) * 4
            lines.append(f"| {label} | {seed or '-'} | {case} | {m:.2f} | {d:.2f} | {v} | {axle} | {t} | {f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(table(), end="")
    print()
    print(contact_lost_table(), end="")
