"""The study on the DIM ``window`` grid against the paper's whole DIM grid, case by case.

Run: ``.venv/bin/python bench/study_grid_compare.py [PAPER_RESULTS] [WINDOW_RESULTS]`` (default
``results/study/results.jsonl.gz``, the shipped study on the paper's grid, and
``results/study_window/results.jsonl.gz``); it prints to stdout (shipped in
``results/study_window/comparison.txt``).

Cases are matched on their key (bridge, train). Per case: Δζ_VBI (its largest absolute change in
%, the acceptance is 1e-6 %), the status, and every other field of the result line except the
ones that describe the run rather than the result (timings, wall time, host, pid, batch size,
``dim_grid``) and ``dim_max_at_range_end`` (a window curve does not reach the ends of the speed
range, so the window study records it as unknown, ``null``). Floats are compared to 1e-9
relative or 1e-12 absolute (the DIM values of both grids are the same lanes; the shipped study was computed by an
earlier build, whose numbers differ from today's by round-off). The wall times of both studies
come from their ``study.json``.
"""

import json
import math
import sys
from pathlib import Path

from adm_calib import study as st

#: Fields of a result line that describe the run, not the result.
RUN_FIELDS = {"timings_s", "wall_s", "host", "pid", "batch_size", "dim_grid", "dim_max_at_range_end"}
#: Acceptance of a change of Δζ_VBI (%).
DZ_TOL_PCT = 1e-6
#: Tolerances of the other floats: relative, and absolute for values near zero (the root's
#: residual ``residual_rel`` is ~1e-8, and round-off moves it by ~1e-15 absolute).
RTOL = 1e-9
ATOL = 1e-12


def _diff(a, b, path=""):
    """Paths where two JSON values differ (floats to RTOL)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += _diff(a.get(k), b.get(k), f"{path}.{k}" if path else k)
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _diff(x, y, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, float):
        return [] if math.isclose(a, b, rel_tol=RTOL, abs_tol=ATOL) else [path]
    return [] if a == b else [path]


def _wall(results_path):
    meta = Path(results_path).parent / "study.json"
    if not meta.exists():
        return None
    runs = json.loads(meta.read_text()).get("runs", [])
    return sum(r.get("wall_s") or 0.0 for r in runs), sum(r.get("completed") or 0 for r in runs), \
        json.loads(meta.read_text()).get("settings", {}).get("dim_grid")


def main():
    a = Path(sys.argv[1] if len(sys.argv) > 1 else "results/study/results.jsonl.gz")
    b = Path(sys.argv[2] if len(sys.argv) > 2 else "results/study_window/results.jsonl.gz")
    old = {st.record_key(r): r for r in st.read_results(a).records}
    new = {st.record_key(r): r for r in st.read_results(b).records}
    keys = sorted(set(old) & set(new))
    print(f"paper grid: {a} ({len(old)} cases); window grid: {b} ({len(new)} cases); {len(keys)} in both")
    for name, p in (("paper grid", a), ("window grid", b)):
        w = _wall(p)
        if w is not None:
            print(f"{name}: {w[1]} cases in {w[0]:.1f} s wall ({w[0] / 60:.1f} min; dim_grid {w[2]})")
    changes, status_changed, fields = [], [], {}
    for k in keys:
        r0, r1 = old[k], new[k]
        if r0["status"] != r1["status"]:
            status_changed.append((k, r0["status"], r1["status"]))
        d0, d1 = r0.get("delta_zeta_vbi_pct"), r1.get("delta_zeta_vbi_pct")
        if (d0 is None) != (d1 is None):
            status_changed.append((k, f"dz {d0}", f"dz {d1}"))
        elif d0 is not None:
            changes.append((abs(d1 - d0), k))
        for f in _diff({x: r0.get(x) for x in r0 if x not in RUN_FIELDS and x != "delta_zeta_vbi_pct"},
                       {x: r1.get(x) for x in r1 if x not in RUN_FIELDS and x != "delta_zeta_vbi_pct"}):
            fields.setdefault(f, []).append(k)
    worst, worst_key = max(changes) if changes else (0.0, None)
    print(f"Δζ_VBI in both: {len(changes)} cases; largest |change| {worst:.3e} % ({worst_key}); "
          f"acceptance {DZ_TOL_PCT:g} %: {'PASS' if worst <= DZ_TOL_PCT and not status_changed else 'FAIL'}")
    print(f"status or Δζ presence changed: {len(status_changed)}")
    for k, s0, s1 in status_changed[:20]:
        print(f"  {k}: {s0} -> {s1}")
    print(f"other fields differing (floats beyond {RTOL:g} relative and {ATOL:g} absolute): {len(fields)}")
    for f, ks in sorted(fields.items()):
        print(f"  {f}: {len(ks)} cases, e.g. {ks[:3]}")
    flags = [r.get("dim_max_at_range_end") for r in new.values()]
    print(f"window study, dim_max_at_range_end: {flags.count(None)} unknown (window curve), "
          f"{len(flags) - flags.count(None)} known (the whole paper grid was run)")
    grids = [r.get("dim_grid") for r in new.values()]
    print(f"window study, dim_grid of the lines: {sorted(set(map(str, grids)))}")
    return 0 if worst <= DZ_TOL_PCT and not status_changed else 1


if __name__ == "__main__":
    sys.exit(main())
