"""Tables of results/irregularity/README.md from the irregularity studies and the shipped smooth study.

Reads ``runs/<spectrum>-s<seed>/results.jsonl`` (whatever has finished) and
``results/study/results.jsonl.gz`` (the smooth track, same settings), keeps the cases of the
slice (``run_slice.slice_cases``) and writes ``summary.md`` (the tables) and ``cases.csv`` (one
row per bridge, train, spectrum and seed).

    PYTHONPATH=src .venv/bin/python results/irregularity/analyse.py
"""

import csv
import sys
from pathlib import Path

import numpy as np

from adm_calib.reference import lower_bound_table
from adm_calib.study import read_results, select_cases

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from run_slice import SPECTRA, slice_cases  # noqa: E402

SMOOTH = HERE.parent / "study" / "results.jsonl.gz"


def dz(rec):
    return rec.get("delta_zeta_vbi_pct") if rec.get("status") == "ok" else None


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
    (HERE / "summary.md").write_text("\n".join(out) + "\n")
    print("\n".join(out[:8] + out[-8:]))


def extension(paper, cons):
    """Seed 1 over the whole mu2 set (185 bridges x 2 trains), per spectrum whose run is complete."""
    keys = {(c.bridge.name, c.train) for c in select_cases(trains=("ICE-2", "Railjet"), mass_functions=("mu2",))}
    smooth = {(r["bridge"], r["train"]): r for r in read_results(SMOOTH).records if (r["bridge"], r["train"]) in keys}
    out = ["", f"Seed 1 over the whole mu2 set ({len(keys)} cases: 185 bridges x ICE-2, Railjet); counts over the cases "
           "with a Δζ_VBI on both tracks:", "",
           "| track | cases with Δζ_VBI on both (not bracketed rough) | shift rough - smooth, median [5 %, 95 %] (% points) "
           "| lower than smooth | Δζ_VBI < 0 rough / smooth | below the paper's bound rough / smooth "
           "| below the conservative bound rough / smooth |",
           "|---|---|---|---|---|---|---|"]
    for spec in SPECTRA:
        f = HERE / "runs" / f"{spec}-s1" / "results.jsonl"
        recs = [r for r in read_results(f).records if (r["bridge"], r["train"]) in keys]
        if len(recs) < len(keys):
            out.append(f"| {spec} seed 1 | {len(recs)} of {len(keys)} finished | | | | | |")
            continue
        ok = [(r, smooth[(r["bridge"], r["train"])]) for r in recs
              if dz(r) is not None and dz(smooth[(r["bridge"], r["train"])]) is not None]
        sh = np.array([dz(r) - dz(s) for r, s in ok])

        def below(rec, table):
            return dz(rec) < float(table[rec["train"]]["mu2"].value_pct(rec["n0_hz"]))

        q = np.percentile(sh, [50, 5, 95])
        out.append(f"| {spec} seed 1 | {len(ok)} ({sum(dz(r) is None for r in recs)}) | "
                   f"{q[0]:+.3f} [{q[1]:+.3f}, {q[2]:+.3f}] | {int(np.sum(sh < 0))} | "
                   f"{sum(dz(r) < 0 for r, _ in ok)} / {sum(dz(s) < 0 for _, s in ok)} | "
                   f"{sum(below(r, paper) for r, _ in ok)} / {sum(below(s, paper) for _, s in ok)} | "
                   f"{sum(below(r, cons) for r, _ in ok)} / {sum(below(s, cons) for _, s in ok)} |")
    return out


if __name__ == "__main__":
    main()
