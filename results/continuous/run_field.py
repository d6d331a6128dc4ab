"""The Δζ question on two-span continuous decks: run the field and compare (results/continuous/README.md).

The field: every integer span L from 8 to 30 m, the five n0 of the Section 3.1.1 power laws at L,
the six mass functions of Table 1 at L and the four trains, each bridge a continuous deck of two
equal spans L (``adm-calib study --spans-layout 2``: EJ from Eq. (18) with L and n0, so the deck's
first frequency is n0; Table 2 damping with L; 6 modes). The simply supported span of equal first
frequency and equal mass per length is then the paper's field bridge (L, n0, mu) itself, whose
Δζ_VBI ships in ``results/study/results.jsonl.gz``. The lower bound is the Appendix B function of the
case's train and mass function at n0 as shipped in adm_calib (``lower_bound_table("paper")``).

Usage, from the repository root with the README's venv::

    .venv/bin/python results/continuous/run_field.py              # run what is missing, then compare
    .venv/bin/python results/continuous/run_field.py --compare    # only compare what is done

Resumable as the study is: the cases run in stages of one frequency index each (3 = the fitted law
first, then 1, 5, 2, 4) into ``results/continuous/study/``; a rerun skips the cases already there.
Writes ``comparison.csv`` (one row per deck case) and ``summary.md`` (the counts per train) beside it.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

from adm_calib.peaks import has_delta_zeta
from adm_calib.reference import lower_bound_table
from adm_calib.study import read_results

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
STUDY_DIR = HERE / "study"
SHIPPED = ROOT / "results" / "study" / "results.jsonl.gz"
SPANS = "8:30"
LAYOUT = 2
#: Frequency indices in the order they run: the fitted law first, then the band's edges.
FREQ_ORDER = (3, 1, 5, 2, 4)
TRAINS = ("ICE-2", "Eurostar", "Railjet", "ICE-4")
#: The deck's first frequency and the simply supported span's agree to this relative tolerance
#: (the deck's modes are bracketed by bisection to 1e-14, spans.py).
N0_RTOL = 1e-9


def run(workers):
    """Run the missing cases, one study call per frequency index; the study's exit code."""
    exe = Path(sys.executable).with_name("adm-calib")
    for fi in FREQ_ORDER:
        cmd = [str(exe), "study", "--out", str(STUDY_DIR), "--spans", SPANS, "--spans-layout", str(LAYOUT),
               "--freq-index", str(fi), "--workers", str(workers)]
        print("$", " ".join(cmd), flush=True)
        rc = subprocess.run(cmd, check=False).returncode
        if rc != 0:
            return rc
    return 0


def _key(rec):
    return (rec["train"], float(rec["span_m"]), int(rec["freq_index"]), rec["mass_function"])


def rows():
    """One row per deck case that has finished, with its simply supported twin and the lower bound."""
    ss = {_key(r): r for r in read_results(SHIPPED).records}
    table = lower_bound_table("paper")
    out = []
    for d in read_results(STUDY_DIR / "results.jsonl").records:
        s = ss[_key(d)]
        if abs(d["n0_hz"] - s["n0_hz"]) > N0_RTOL * s["n0_hz"] or abs(d["mu_t_m"] - s["mu_t_m"]) > 1e-12 * s["mu_t_m"]:
            raise RuntimeError(f"{d['bridge']}: n0 or mu differs from the simply supported {s['bridge']}")
        lb = table[d["train"]][d["mass_function"]].delta_zeta_pct(d["n0_hz"])
        dz = d["delta_zeta_vbi_pct"] if has_delta_zeta(d["status"]) else None
        sdz = s["delta_zeta_vbi_pct"] if has_delta_zeta(s["status"]) else None
        out.append({
            "train": d["train"], "span_m": d["span_m"], "freq_index": d["freq_index"],
            "mass_function": d["mass_function"], "n0_hz": d["n0_hz"], "mu_t_m": d["mu_t_m"], "zeta_pct": d["zeta_pct"],
            "deck_status": d["status"], "deck_dz_vbi_pct": dz, "ss_status": s["status"], "ss_dz_vbi_pct": sdz,
            "lb_pct": lb, "margin_pct": None if dz is None else dz - lb,
        })
    out.sort(key=lambda r: (TRAINS.index(r["train"]), r["span_m"], r["freq_index"], r["mass_function"]))
    return out


def _stats(rs, status_ok):
    """Counts and the worst margin of the rows ``rs`` whose deck status passes ``status_ok``."""
    use = [r for r in rs if r["margin_pct"] is not None and status_ok(r["deck_status"])]
    below = [r for r in use if r["margin_pct"] >= 0.0]
    worst = min(use, key=lambda r: r["margin_pct"]) if use else None
    return use, below, worst


def _case(r):
    return f"2x{r['span_m']:g} m f{r['freq_index']} {r['mass_function']} (n0 {r['n0_hz']:.2f} Hz)"


def summary(rs):
    """The per-train table of the README (markdown)."""
    lines = ["| train | decks run | Δζ_VBI determined (ok) | LB ≤ Δζ_VBI | LB > Δζ_VBI | worst margin Δζ_VBI − LB (%) "
             "| with the undetermined values: LB > Δζ | deck − simply supported Δζ (%), median [min, max] |",
             "|---|---|---|---|---|---|---|---|"]
    by = defaultdict(list)
    for r in rs:
        by[r["train"]].append(r)
    for t in TRAINS + ("all",):
        tr = rs if t == "all" else by.get(t, [])
        ok, below, worst = _stats(tr, lambda s: s == "ok")
        val, vbelow, _ = _stats(tr, lambda s: True)
        diffs = sorted(r["deck_dz_vbi_pct"] - r["ss_dz_vbi_pct"] for r in tr
                       if r["deck_status"] == "ok" and r["ss_status"] == "ok")
        med = f"{diffs[len(diffs) // 2]:+.3f} [{diffs[0]:+.3f}, {diffs[-1]:+.3f}] ({len(diffs)} pairs)" if diffs else "n/a"
        w = f"{worst['margin_pct']:+.3f} ({_case(worst)})" if worst else "n/a"
        lines.append(f"| {t} | {len(tr)} | {len(ok)} | {len(below)} | {len(ok) - len(below)} | {w} "
                     f"| {len(val) - len(vbelow)} of {len(val)} | {med} |")
    status = defaultdict(int)
    for r in rs:
        status[r["deck_status"]] += 1
    lines += ["", "Deck statuses: " + ", ".join(f"{k} {v}" for k, v in sorted(status.items())) + "."]
    above = [r for r in rs if r["margin_pct"] is not None and r["margin_pct"] < 0 and r["deck_status"] == "ok"]
    if above:
        lines += ["", "Determined cases with the lower bound above the deck's Δζ_VBI (margin %, worst first):", ""]
        for r in sorted(above, key=lambda r: r["margin_pct"]):
            lines.append(f"* {r['train']}, {_case(r)}: Δζ_VBI {r['deck_dz_vbi_pct']:.3f} %, LB {r['lb_pct']:.3f} %, "
                         f"margin {r['margin_pct']:+.3f} % (simply supported: "
                         f"{'n/a' if r['ss_dz_vbi_pct'] is None else format(r['ss_dz_vbi_pct'], '.3f')} %)")
    return "\n".join(lines) + "\n"


def compare():
    rs = rows()
    with open(HERE / "comparison.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rs[0]) if rs else ["train"])
        w.writeheader()
        w.writerows(rs)
    text = summary(rs)
    (HERE / "summary.md").write_text(text)
    print(text)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--compare", action="store_true", help="only compare the cases already run")
    p.add_argument("--workers", default="2", help="worker processes of the study (default 2)")
    args = p.parse_args(argv)
    rc = 0 if args.compare else run(args.workers)
    if (STUDY_DIR / "results.jsonl").is_file():
        compare()
    return rc


if __name__ == "__main__":
    sys.exit(main())
