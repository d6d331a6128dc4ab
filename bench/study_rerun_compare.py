"""A rerun of the shipped study against the shipped lines, case by case, and their fits.

Run: ``.venv/bin/python bench/study_rerun_compare.py SHIPPED_DIR RERUN_DIR`` (each a study directory
holding ``results.jsonl[.gz]``, ``study.json`` and, where ``study-fit`` ran, ``fit/``); it prints
to stdout (shipped in ``results/study/rerun_comparison.txt``). Exit 0 when every rule holds.

The rules, fixed before the rerun was looked at:

* **Cases**: both files hold the same 4440 keys (bridge, train), no ``error`` line.
* **Status**: the rerun's status is the status today's rules give the shipped line
  (:func:`adm_calib.peaks.record_status` with the rerun's ``mlm_max_at_range_end``: the shipped
  lines predate ``range_end`` / ``not_associated`` and the rechecked flag); every other status
  (``contact_lost`` among them) is listed with its message. ``message`` follows the status and is
  compared only where the status did not change.
* **Δζ_VBI**: present in both or absent in both; the largest |difference| is printed, the
  acceptance is 1e-9 % points (the expectation on the same grid is round-off, ~1e-12).
* **Every other field** of the shipped line: floats to 1e-9 relative or 1e-12 absolute (the peaks,
  ADM/EADA/LB values, the solver's counters and residual, ``ds_m``), the rest exactly; the fields
  that describe the run (``timings_s``, ``wall_s``, ``host``, ``pid``, ``batch_size``, ``crc32``)
  are not compared. The largest relative change of the MLM and DIM peaks is printed. Fields the
  rerun's lines have and the shipped ones do not are listed with their values' counts.
* **Fits** (where both directories have ``fit/``): every number of every ``lower_bounds_fit*.csv``
  (coefficients, upper limit, R², residuals, counts) to 1e-9 relative or 1e-12 absolute (the CSV
  holds 6 significant digits, so equal files are expected), and every ``appendix_b_comparison*.md``
  and ``conservative_lower_bounds*.md`` compared line by line (the Tables B1-B4 comparison).
"""

import csv
import json
import math
import sys
from collections import Counter
from pathlib import Path

import study_pairs as sp

from adm_calib import peaks as pk

RUN_FIELDS = {"timings_s", "wall_s", "host", "pid", "batch_size", "crc32"}
DZ_TOL_PCT = 1e-9
RTOL = 1e-9
ATOL = 1e-12
SHOW = 20


def _results(d):
    d = Path(d)
    return d / "results.jsonl.gz" if (d / "results.jsonl.gz").exists() else d / "results.jsonl"


def _wall(d):
    meta = json.loads((Path(d) / "study.json").read_text())
    runs = meta.get("runs", [])
    return (sum(r.get("wall_s") or 0.0 for r in runs), sum(r.get("completed") or 0 for r in runs),
            meta.get("settings", {}), [r.get("started") for r in runs])


def compare_lines(old, new, keys):
    """Print the case-by-case comparison; return the number of rule failures."""
    fails = 0
    if set(old) != set(new):
        print(f"FAIL keys: {len(set(old) - set(new))} only shipped, {len(set(new) - set(old))} only rerun")
        fails += 1
    errors = [k for k in keys if new[k]["status"] == "error"]
    if errors:
        print(f"FAIL error lines in the rerun: {len(errors)}, e.g. {errors[:3]}")
        fails += 1
    expected, unexpected, dz, peak_rel, fields = Counter(), [], [], {"mlm": 0.0, "dim": 0.0}, {}
    for c in sp.compare_cases(old, new, keys, other_fields_except=RUN_FIELDS | {"message", "status"},
                              rtol=RTOL, atol=ATOL):
        r0, r1 = old[c.key], new[c.key]
        want = pk.record_status(r0, mlm_max_at_range_end=r1.get("mlm_max_at_range_end"))
        if r1["status"] == want:
            expected[(r0["status"], r1["status"])] += 1
            if r0["status"] == r1["status"] and r0.get("message") != r1.get("message"):
                fields.setdefault("message", []).append(c.key)
        else:
            unexpected.append((c.key, r0["status"], want, r1["status"], r1.get("message")))
        if c.dz_presence_changed:
            unexpected.append((c.key, f"dz {c.dz_pct[0]}", "", f"dz {c.dz_pct[1]}", ""))
        elif c.dz_change_pct is not None:
            dz.append((abs(c.dz_change_pct), c.key))
        for kind in ("mlm", "dim"):
            a0, a1 = r0.get(f"{kind}_peak_acc_m_s2"), r1.get(f"{kind}_peak_acc_m_s2")
            if a0 is not None and a1 is not None:
                peak_rel[kind] = max(peak_rel[kind], abs(a1 / a0 - 1.0))
        for f in c.fields:
            if f.split(".")[0].split("[")[0] in r0:
                fields.setdefault(f, []).append(c.key)
    print("status, shipped -> rerun, as today's rules give the shipped line (peaks.record_status):")
    for (s0, s1), n in sorted(expected.items()):
        print(f"  {s0} -> {s1}: {n}")
    print(f"status or Δζ presence not as expected: {len(unexpected)}")
    for k, s0, want, s1, msg in unexpected[:SHOW]:
        print(f"  {k}: shipped {s0}, expected {want}, rerun {s1}: {msg}")
    fails += bool(unexpected)
    worst, wkey = max(dz) if dz else (0.0, None)
    ok = worst <= DZ_TOL_PCT
    print(f"Δζ_VBI in both: {len(dz)} cases; largest |change| {worst:.3e} % points ({wkey}); "
          f"acceptance {DZ_TOL_PCT:g}: {'PASS' if ok else 'FAIL'}")
    fails += not ok
    print(f"peaks, largest relative change: MLM {peak_rel['mlm']:.3e}, DIM {peak_rel['dim']:.3e}")
    print(f"shipped fields differing (floats beyond {RTOL:g} relative and {ATOL:g} absolute): {len(fields)}")
    for f, ks in sorted(fields.items()):
        print(f"  {f}: {len(ks)} cases, e.g. {ks[:3]}")
    new_fields = Counter(f for k in keys for f in new[k] if f not in old[k])
    print("fields only in the rerun's lines: " + (", ".join(f"{f} ({n})" for f, n in sorted(new_fields.items()))
                                                 or "none"))
    if "warnings" in new_fields:
        warned = [k for k in keys if new[k].get("warnings")]
        print(f"  lines with a plausibility warning: {len(warned)}" + (f", e.g. {warned[:3]}" if warned else ""))
    print("rerun statuses: " + ", ".join(f"{s} {n}" for s, n in Counter(new[k]['status'] for k in keys).most_common()))
    return fails


def _num(x):
    try:
        return float(x)
    except ValueError:
        return None


def compare_fits(a, b):
    """Compare the fit folders; return the number of failures."""
    fa, fb = Path(a) / "fit", Path(b) / "fit"
    if not (fa.is_dir() and fb.is_dir()):
        print("fits: not compared (a directory has no fit/)")
        return 0
    fails = 0
    for p in sorted(fa.glob("lower_bounds_fit*.csv")):
        q = fb / p.name
        if not q.exists():
            print(f"fit {p.name}: missing in the rerun")
            fails += 1
            continue
        ra, rb = list(csv.DictReader(p.open())), list(csv.DictReader(q.open()))
        diffs = []
        for x, y in zip(ra, rb):
            for col in x:
                u, v = _num(x[col]), _num(y.get(col, ""))
                if u is not None and v is not None:
                    same = (u == v) or math.isclose(u, v, rel_tol=RTOL, abs_tol=ATOL)
                else:
                    same = x[col] == y.get(col)
                if not same:
                    diffs.append(f"{x['train']} {x['mass_function']} {col}: {x[col]} -> {y.get(col)}")
        n = len(ra) == len(rb)
        print(f"fit {p.name}: {len(ra)} sets, {'same rows' if n else 'ROW COUNT DIFFERS'}; "
              f"numbers differing: {len(diffs)}")
        for d in diffs[:SHOW]:
            print(f"  {d}")
        fails += bool(diffs) or not n
    for pat in ("appendix_b_comparison*.md", "conservative_lower_bounds*.md"):
        for p in sorted(fa.glob(pat)):
            q = fb / p.name
            if not q.exists():
                print(f"fit {p.name}: missing in the rerun")
                fails += 1
                continue
            la, lb = p.read_text().splitlines(), q.read_text().splitlines()
            diff = [(i + 1, x, y) for i, (x, y) in enumerate(zip(la, lb)) if x != y]
            extra = abs(len(la) - len(lb))
            print(f"fit {p.name}: {len(diff)} lines differ, {extra} lines more in one file")
            for i, x, y in diff[:SHOW]:
                print(f"  line {i}:\n    shipped: {x}\n    rerun:   {y}")
            fails += bool(diff) or bool(extra)
    return fails


def main():
    a = Path(sys.argv[1] if len(sys.argv) > 1 else "results/study")
    b = Path(sys.argv[2])
    old, new, keys = sp.matched(_results(a), _results(b))
    print(f"shipped: {_results(a)} ({len(old)} cases); rerun: {_results(b)} ({len(new)} cases); {len(keys)} in both")
    for name, d in (("shipped", a), ("rerun", b)):
        wall, n, settings, started = _wall(d)
        print(f"{name}: {n} cases in {wall:.1f} s wall ({wall / 60:.1f} min), started {', '.join(map(str, started))}, "
              f"settings {json.dumps(settings, sort_keys=True)}")
    fails = compare_lines(old, new, keys)
    fails += compare_fits(a, b)
    print(f"rules failing: {fails}")
    return 0 if fails == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
