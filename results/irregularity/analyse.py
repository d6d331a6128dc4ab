"""Tables of results/irregularity/README.md from the irregularity studies and the shipped smooth study.

Reads ``runs/<spectrum>-s<seed>/results.jsonl`` (whatever has finished) and
``results/study/results.jsonl.gz`` (the smooth track, same settings), keeps the cases of the
slice (``run_slice.slice_cases``) and writes ``summary.md`` (the tables) and ``cases.csv`` (one
row per bridge, train, spectrum and seed).

    PYTHONPATH=src .venv/bin/python results/irregularity/analyse.py
"""

import csv
import re
import sys
import time
from pathlib import Path

import numpy as np

from adm_calib import peaks
from adm_calib.reference import lower_bound_table
from adm_calib.study import read_results, select_cases

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from run_slice import SPECTRA, slice_cases  # noqa: E402

SMOOTH = HERE.parent / "study" / "results.jsonl.gz"
MU2_SEEDS = (1, 2)  # seeds run over the whole mu2 set (run_mu2_seed1.sh, run_mu2_seed2.sh)
SPAN_GROUPS_M = ((4.0, 12.0), (13.0, 24.0), (25.0, 40.0))
TOP_CASES = 5
SEED_HEADING = "## Seed 2 against seed 1 over the whole mu2 set"


def dz(rec):
    """The line's Δζ_VBI where it has one (``ok``, or ``range_end`` / ``not_associated``: computed, not
    determined; lines written before those statuses said ``ok`` for all of them), else ``None``; a
    ``contact_lost`` line counts as none (its DIM peak breaks the DIM's assumption; the study's fit
    leaves it out too)."""
    return rec.get("delta_zeta_vbi_pct") if peaks.has_delta_zeta(rec.get("status")) else None


def main():
    keys = {(c.bridge.name, c.train): c for c in slice_cases()}
    smooth = {(r["bridge"], r["train"]): r for r in read_results(SMOOTH).records if (r["bridge"], r["train"]) in keys}
    paper, cons = lower_bound_table("paper"), lower_bound_table("conservative")
    rows, runs = [], {}
    for d in sorted((HERE / "runs").glob("*-s*")):
        spec, seed = d.name.rsplit("-s", 1)
        recs = [r for r in read_results(d / "results.jsonl").records if (r["bridge"], r["train"]) in keys]
        runs[(spec, int(seed))] = len(recs)
        for r in recs:
            s = smooth[(r["bridge"], r["train"])]
            n0 = r["n0_hz"]
            rows.append({"spectrum": spec, "seed": int(seed), "bridge": r["bridge"], "train": r["train"],
                         "span_m": r["span_m"], "n0_hz": n0, "status": r["status"],
                         "dz_smooth_pct": dz(s), "dz_rough_pct": dz(r),
                         "lb_paper_pct": float(paper[r["train"]]["mu2"].value_pct(n0)),
                         "lb_conservative_pct": float(cons[r["train"]]["mu2"].value_pct(n0)),
                         "dim_peak_smooth": s["dim_peak"]["acc_m_s2"] if s.get("dim_peak") else None,
                         "dim_peak_rough": r["dim_peak"]["acc_m_s2"] if r.get("dim_peak") else None})
    with open(HERE / "cases.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    out = [f"Cases of the slice: {len(keys)} (bridge, train); runs finished: "
           + ", ".join(f"{s} seed {k}: {n}" for (s, k), n in sorted(runs.items())), ""]
    out += ["| track | cases (ok) | Δζ_VBI shift, median [5 %, 95 %] (% points) | per-bridge mean shift over seeds: min .. max | "
            "spread over seeds (max - min), median | DIM peak change, median | below paper LB | below conservative LB |",
            "|---|---|---|---|---|---|---|---|"]
    sm = [smooth[k] for k in keys]
    ok_s = [r for r in sm if dz(r) is not None]
    below_p = sum(dz(r) < float(paper[r["train"]]["mu2"].value_pct(r["n0_hz"])) for r in ok_s)
    below_c = sum(dz(r) < float(cons[r["train"]]["mu2"].value_pct(r["n0_hz"])) for r in ok_s)
    out.append(f"| smooth (shipped study) | {len(sm)} ({len(ok_s)}) | - | - | - | - | {below_p} | {below_c} |")
    for spec in SPECTRA:
        rs = [r for r in rows if r["spectrum"] == spec]
        ok = [r for r in rs if r["dz_rough_pct"] is not None and r["dz_smooth_pct"] is not None]
        if not ok:
            continue
        sh = np.array([r["dz_rough_pct"] - r["dz_smooth_pct"] for r in ok])
        per = {}
        for r in ok:
            per.setdefault((r["bridge"], r["train"]), []).append(r["dz_rough_pct"] - r["dz_smooth_pct"])
        means = np.array([np.mean(v) for v in per.values()])
        spread = np.array([max(v) - min(v) for v in per.values() if len(v) > 1] or [np.nan])
        pk = np.array([r["dim_peak_rough"] / r["dim_peak_smooth"] - 1 for r in ok
                       if r["dim_peak_rough"] and r["dim_peak_smooth"]])
        bp = sum(r["dz_rough_pct"] < r["lb_paper_pct"] for r in ok)
        bc = sum(r["dz_rough_pct"] < r["lb_conservative_pct"] for r in ok)
        bridges_bp = len({(r["bridge"], r["train"]) for r in ok if r["dz_rough_pct"] < r["lb_paper_pct"]})
        bridges_bc = len({(r["bridge"], r["train"]) for r in ok if r["dz_rough_pct"] < r["lb_conservative_pct"]})
        q = np.percentile(sh, [50, 5, 95])
        out.append(f"| {spec} (seeds {', '.join(str(s) for s in sorted({r['seed'] for r in rs}))}) | {len(rs)} ({len(ok)}) | "
                   f"{q[0]:+.3f} [{q[1]:+.3f}, {q[2]:+.3f}] | {means.min():+.3f} .. {means.max():+.3f} | "
                   f"{np.nanmedian(spread):.3f} | {100 * np.median(pk):+.1f} % | {bp} cases ({bridges_bp} bridges) | "
                   f"{bc} cases ({bridges_bc} bridges) |")
    out += ["", "Per bridge (ICE-2 and Railjet), Δζ_VBI (%) smooth and on each track, mean [min, max] over seeds; "
            "LB = paper's Table B bound (mu2), cons. = conservative bound:", "",
            "| bridge | train | n0 (Hz) | smooth | LB | cons. | " + " | ".join(SPECTRA) + " |",
            "|---|---|---|---|---|---|" + "---|" * len(SPECTRA)]
    for (b, t), c in keys.items():
        s = dz(smooth[(b, t)])
        cells = []
        for spec in SPECTRA:
            v = [r["dz_rough_pct"] for r in rows if r["spectrum"] == spec and (r["bridge"], r["train"]) == (b, t)
                 and r["dz_rough_pct"] is not None]
            cells.append(f"{np.mean(v):.2f} [{min(v):.2f}, {max(v):.2f}]" if v else "-")
        lbp = float(paper[t]["mu2"].value_pct(c.bridge.n0_hz))
        lbc = float(cons[t]["mu2"].value_pct(c.bridge.n0_hz))
        out.append(f"| {b} | {t} | {c.bridge.n0_hz:.2f} | {'-' if s is None else f'{s:.2f}'} | {lbp:.2f} | {lbc:.2f} | "
                   + " | ".join(cells) + " |")
    out += extension(paper, cons)
    out += seed_comparison(paper, cons)
    out += seeds_needed(rows)
    (HERE / "summary.md").write_text("\n".join(out) + "\n")
    print("\n".join(out[:8] + out[out.index(SEED_HEADING):]))


def extension(paper, cons):
    """Seeds 1 and 2 over the whole mu2 set (185 bridges x 2 trains), per spectrum whose run is complete."""
    keys = {(c.bridge.name, c.train) for c in select_cases(trains=("ICE-2", "Railjet"), mass_functions=("mu2",))}
    smooth = {(r["bridge"], r["train"]): r for r in read_results(SMOOTH).records if (r["bridge"], r["train"]) in keys}
    out = ["", f"Seeds 1 and 2 over the whole mu2 set ({len(keys)} cases: 185 bridges x ICE-2, Railjet); counts over the cases "
           "with a Δζ_VBI on both tracks:", "",
           "| track | cases with Δζ_VBI on both (not bracketed rough) | shift rough - smooth, median [5 %, 95 %] (% points) "
           "| lower than smooth | Δζ_VBI < 0 rough / smooth | below the paper's bound rough / smooth "
           "| below the conservative bound rough / smooth |",
           "|---|---|---|---|---|---|---|"]
    for seed, spec in ((seed, spec) for seed in MU2_SEEDS for spec in SPECTRA):
        f = HERE / "runs" / f"{spec}-s{seed}" / "results.jsonl"
        recs = [r for r in read_results(f).records if (r["bridge"], r["train"]) in keys]
        if len(recs) < len(keys):
            out.append(f"| {spec} seed {seed} | {len(recs)} of {len(keys)} finished | | | | | |")
            continue
        ok = [(r, smooth[(r["bridge"], r["train"])]) for r in recs
              if dz(r) is not None and dz(smooth[(r["bridge"], r["train"])]) is not None]
        sh = np.array([dz(r) - dz(s) for r, s in ok])

        def below(rec, table):
            return dz(rec) < float(table[rec["train"]]["mu2"].value_pct(rec["n0_hz"]))

        q = np.percentile(sh, [50, 5, 95])
        out.append(f"| {spec} seed {seed} | {len(ok)} ({sum(dz(r) is None for r in recs)}) | "
                   f"{q[0]:+.3f} [{q[1]:+.3f}, {q[2]:+.3f}] | {int(np.sum(sh < 0))} | "
                   f"{sum(dz(r) < 0 for r, _ in ok)} / {sum(dz(s) < 0 for _, s in ok)} | "
                   f"{sum(below(r, paper) for r, _ in ok)} / {sum(below(s, paper) for _, s in ok)} | "
                   f"{sum(below(r, cons) for r, _ in ok)} / {sum(below(s, cons) for _, s in ok)} |")
    return out


def run_log_times(log):
    """Per spectrum (submitted cases, study seconds), the wall time start..last done (s) and those two
    clock times of a run_mu2_*.sh log."""
    per, stamps = {}, []
    spec = None
    for line in log.read_text().splitlines():
        m = re.match(r"== (\d\d):(\d\d):(\d\d) (\S+) seed \d+: (start|done)", line)
        if m:
            h, mi, se = (int(x) for x in m.group(1, 2, 3))
            stamps.append(h * 3600 + mi * 60 + se)
            spec = m.group(4)
            continue
        m = re.match(r"study: (\d+) of (\d+) submitted cases finished in ([0-9.]+) s", line)
        if m and spec:
            per[spec] = (int(m.group(1)), float(m.group(3)))
    wall = (stamps[-1] - stamps[0]) % 86400 if len(stamps) > 1 else None
    span = tuple(time.strftime("%H:%M:%S", time.gmtime(t)) for t in (stamps[0], stamps[-1])) if stamps else None
    return per, wall, span


def at_window_edge(rec):
    """True when the DIM peak speed is a bound of the association window ('... window [a, b] km/h')."""
    m = re.search(r"window \[([0-9.]+), ([0-9.]+)\] km/h", rec.get("association_rule") or "")
    v = (rec.get("dim_peak") or {}).get("speed_kmh")
    return bool(m and v is not None and v in (float(m.group(1)), float(m.group(2))))


def seed_comparison(paper, cons):
    """Seed 2 against seed 1 per case over the whole mu2 set; writes seeds_mu2.csv (one row per case and spectrum)."""
    cases = {(c.bridge.name, c.train): c for c in select_cases(trains=("ICE-2", "Railjet"), mass_functions=("mu2",))}
    smooth = {(r["bridge"], r["train"]): r for r in read_results(SMOOTH).records if (r["bridge"], r["train"]) in cases}
    out = ["", SEED_HEADING, "",
           f"Per case ({len(cases)}: 185 bridges x ICE-2, Railjet), d = Δζ_VBI(seed 2) - Δζ_VBI(seed 1) on the same "
           "spectrum, over the cases with a Δζ_VBI in both seeds (% points):", "",
           "| spectrum | cases in both seeds (finished seed 2) | median abs(d) [5 %, 95 %] | max abs(d) | median d "
           "| abs(d) > 0.25 / > 0.5 | correlation seed 1 vs seed 2 of the shift rough - smooth "
           "| median abs(d) by span " + ", ".join(f"{a:.0f}..{b:.0f} m" for a, b in SPAN_GROUPS_M)
           + " | median abs(d) ICE-2 / Railjet |",
           "|---|---|---|---|---|---|---|---|---|"]
    bounds = ["", "Below the smooth-track bounds per seed and over both seeds (a case whose rough-track DIM is not "
              "bracketed counts as below; 'either' = the lower of the two seeds is below, the design value a "
              "two-realisation minimum would give; smooth = the shipped study on the same cases):", "",
              "| spectrum | bound | smooth | seed 1 | seed 2 | either seed | both seeds | below in one seed only |",
              "|---|---|---|---|---|---|---|---|"]
    csv_rows, stats = [], {}
    tops = ["", f"The {TOP_CASES} cases with the largest abs(d) per spectrum, Δζ_VBI smooth / seed 1 / seed 2 (%):", ""]
    for spec in SPECTRA:
        by_seed = {}
        for seed in MU2_SEEDS:
            f = HERE / "runs" / f"{spec}-s{seed}" / "results.jsonl"
            by_seed[seed] = {(r["bridge"], r["train"]): r for r in read_results(f).records
                             if (r["bridge"], r["train"]) in cases}
        both = [k for k in cases if all(k in by_seed[s] for s in MU2_SEEDS)]
        for k in both:
            r1, r2, c = by_seed[1][k], by_seed[2][k], cases[k]
            n0 = c.bridge.n0_hz
            csv_rows.append({"spectrum": spec, "bridge": k[0], "train": k[1], "span_m": c.span_m, "n0_hz": n0,
                             "dz_smooth_pct": dz(smooth[k]), "dz_seed1_pct": dz(r1), "dz_seed2_pct": dz(r2),
                             "status_seed1": r1["status"], "status_seed2": r2["status"],
                             "lb_paper_pct": float(paper[k[1]]["mu2"].value_pct(n0)),
                             "lb_conservative_pct": float(cons[k[1]]["mu2"].value_pct(n0))})
        ok = [k for k in both if dz(by_seed[1][k]) is not None and dz(by_seed[2][k]) is not None]
        if not ok:
            out.append(f"| {spec} | 0 ({len(by_seed[2])} of {len(cases)}) | | | | | | | |")
            continue
        d = np.array([dz(by_seed[2][k]) - dz(by_seed[1][k]) for k in ok])
        a = np.abs(d)
        sm_ok = [k for k in ok if dz(smooth[k]) is not None]
        sh1 = np.array([dz(by_seed[1][k]) - dz(smooth[k]) for k in sm_ok])
        sh2 = np.array([dz(by_seed[2][k]) - dz(smooth[k]) for k in sm_ok])
        rho = float(np.corrcoef(sh1, sh2)[0, 1])
        q = np.percentile(a, [50, 5, 95])
        spans = np.array([cases[k].span_m for k in ok])
        trains = np.array([k[1] for k in ok])
        by_span = [np.median(a[(spans >= lo) & (spans <= hi)]) for lo, hi in SPAN_GROUPS_M]
        out.append(f"| {spec} | {len(ok)} ({len(by_seed[2])} of {len(cases)}) | {q[0]:.3f} [{q[1]:.3f}, {q[2]:.3f}] | "
                   f"{a.max():.3f} | {np.median(d):+.3f} | {int(np.sum(a > 0.25))} / {int(np.sum(a > 0.5))} | "
                   f"{rho:.2f} | " + " / ".join(f"{v:.3f}" for v in by_span) + " | "
                   f"{np.median(a[trains == 'ICE-2']):.3f} / {np.median(a[trains == 'Railjet']):.3f} |")
        stats[spec] = {"n": len(ok), "median": q[0], "p95": q[2], "max": a.max()}
        top = sorted(range(len(ok)), key=lambda i: -a[i])[:TOP_CASES]
        tops.append(f"* {spec}: " + "; ".join(
            f"{ok[i][0]} x {ok[i][1]} {dz(smooth[ok[i]]):+.2f} / {dz(by_seed[1][ok[i]]):+.2f} / {dz(by_seed[2][ok[i]]):+.2f}"
            + "".join(f" (seed {sd}: DIM peak at the edge of its association window)" for sd in MU2_SEEDS
                      if at_window_edge(by_seed[sd][ok[i]]))
            for i in top)
            + "; DIM peak at the edge of its association window in "
            + ", ".join(f"{sum(at_window_edge(by_seed[sd][k]) for k in ok)} (seed {sd})" for sd in MU2_SEEDS)
            + f" of the {len(ok)} cases")

        def below(rec, k, table):
            v = dz(rec)
            return v is None or v < float(table[k[1]]["mu2"].value_pct(cases[k].bridge.n0_hz))

        for name, table in (("paper", paper), ("conservative", cons)):
            b1 = {k for k in both if below(by_seed[1][k], k, table)}
            b2 = {k for k in both if below(by_seed[2][k], k, table)}
            bs = sum(dz(smooth[k]) is not None and below(smooth[k], k, table) for k in both)
            bounds.append(f"| {spec} ({len(both)} cases) | {name} | {bs} | {len(b1)} | {len(b2)} | {len(b1 | b2)} "
                          f"({100 * len(b1 | b2) / len(both):.0f} %) | {len(b1 & b2)} | {len(b1 ^ b2)} |")
            stats[spec][name] = (len(b1), len(b2), len(b1 | b2), bs, len(both))
    if csv_rows:
        with open(HERE / "seeds_mu2.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(csv_rows[0]))
            w.writeheader()
            w.writerows(csv_rows)
    out += bounds + (tops if len(tops) > 3 else [])
    log = HERE / "run_mu2_seed2.log"
    per, wall, span = run_log_times(log) if log.exists() else ({}, None, None)
    if per:
        out += ["", "Seed 2 run (`run_mu2_seed2.sh`, one worker process, `run_mu2_seed2.log`): "
                + "; ".join(f"{spec} {n} cases in {t:.0f} s ({t / n:.2f} s per case)" for spec, (n, t) in per.items())
                + (f"; wall time start to last done {wall // 60:.0f} min {wall % 60:.0f} s ({span[0]} to {span[1]} UTC)"
                   if wall is not None else "")
                + "."]
    if csv_rows:
        lbs = {name: np.array([r[col] for r in csv_rows if r["spectrum"] == SPECTRA[0]])
               for name, col in (("paper", "lb_paper_pct"), ("conservative", "lb_conservative_pct"))}
        out += ["", "The bounds at these cases' n0 (% points): " + "; ".join(
            f"{name} median {np.median(v):.2f}, max {v.max():.2f}, zero in {int(np.sum(v == 0))} of {len(v)}"
            for name, v in lbs.items()) + "."]
    if stats:
        lines = []
        for spec, st in stats.items():
            txt = (f"{spec}: seed 2 moves Δζ_VBI of a case by a median {st['median']:.2f} % points "
                   f"(95 % quantile {st['p95']:.2f}, max {st['max']:.2f}; {st['n']} cases)")
            if "conservative" in st:
                c1, c2, ce, cs, n = st["conservative"]
                txt += (f"; below the conservative bound: seed 1 {c1}, seed 2 {c2}, either seed {ce} of {n} "
                        f"(smooth {cs})")
            lines.append(txt + ".")
        out += [""] + [f"* {t}" for t in lines]
    return out


def seeds_needed(rows):
    """Slice (60 cases, seeds 1..5): cases below each bound in at least one of the first k seeds, k = 1..5."""
    out = ["", "Slice (60 cases, 5 seeds): cases below the bound in at least one of the first k seeds (not bracketed "
           "counts as below), i.e. how the count under a k-realisation minimum grows with k:", "",
           "| spectrum | bound | " + " | ".join(f"k = {k}" for k in range(1, 6)) + " |", "|---|---|" + "---|" * 5]
    for spec in SPECTRA:
        rs = [r for r in rows if r["spectrum"] == spec]
        for name, col in (("paper", "lb_paper_pct"), ("conservative", "lb_conservative_pct")):
            cells = []
            for k in range(1, 6):
                sel = [r for r in rs if r["seed"] <= k]
                if len({r["seed"] for r in sel}) < k:
                    cells.append("-")
                    continue
                cells.append(str(len({(r["bridge"], r["train"]) for r in sel
                                      if r["dz_rough_pct"] is None or r["dz_rough_pct"] < r[col]})))
            out.append(f"| {spec} | {name} | " + " | ".join(cells) + " |")
    return out


if __name__ == "__main__":
    main()
