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
come from their ``study.json``. The case-by-case loop is :func:`study_pairs.compare_cases`.
"""

import json
import sys
from pathlib import Path

import study_pairs as sp

#: Fields of a result line that describe the run, not the result.
RUN_FIELDS = {"timings_s", "wall_s", "host", "pid", "batch_size", "dim_grid", "dim_max_at_range_end"}
#: Acceptance of a change of Δζ_VBI (%).
DZ_TOL_PCT = 1e-6
#: Tolerances of the other floats: relative, and absolute for values near zero (the root's
#: residual ``residual_rel`` is ~1e-8, and round-off moves it by ~1e-15 absolute).
RTOL = 1e-9
ATOL = 1e-12


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
    old, new, keys = sp.matched(a, b)
    print(f"paper grid: {a} ({len(old)} cases); window grid: {b} ({len(new)} cases); {len(keys)} in both")
    for name, p in (("paper grid", a), ("window grid", b)):
        w = _wall(p)
        if w is not None:
            print(f"{name}: {w[1]} cases in {w[0]:.1f} s wall ({w[0] / 60:.1f} min; dim_grid {w[2]})")
    changes, status_changed, fields = [], [], {}
    for c in sp.compare_cases(old, new, keys, other_fields_except=RUN_FIELDS, rtol=RTOL, atol=ATOL):
        if c.status_changed:
            status_changed.append((c.key, *c.status))
        if c.dz_presence_changed:
            status_changed.append((c.key, f"dz {c.dz_pct[0]}", f"dz {c.dz_pct[1]}"))
        elif c.dz_change_pct is not None:
            changes.append((abs(c.dz_change_pct), c.key))
        for f in c.fields:
            fields.setdefault(f, []).append(c.key)
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
