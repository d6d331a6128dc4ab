"""CPU time of the study's unit of work (one batch through ``adm_calib.study.run_batch``) against a baseline tree.

Run: ``.venv/bin/python bench/bench_study_baseline.py --baseline SRC [--span 20] [--freq-index 3] [--rounds 3] [--reps 2]``.

The case: the six mass functions of one (span, frequency index) pair under ICE-2, one batch, the
study's settings (``StudySettings()``): what a study worker runs, phases and all. Every timing
runs in a worker subprocess (``PYTHONPATH=<src>``, numba cache in a temporary directory) that
first runs the batch once untimed (compile or cache load), then ``--reps`` timed runs; the
baseline's and this tree's workers alternate for ``--rounds`` rounds. Times are the worker's CPU
seconds (``time.process_time``: on a shared machine the wall clock counts the others too). The
bench prints the min time of each, the ratio this/baseline, and the largest difference of the
Δζ_VBI and the statuses of the two (equal numbers: the same study).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE_SRC = str(Path(__file__).resolve().parents[1] / "src")


def worker(span, fi, reps):
    from adm_calib.study import StudySettings, run_batch, select_cases

    cases = select_cases(["ICE-2"], ["mu1", "mu2", "mu3", "mu4", "mu5", "mu6"], (span, span), [fi])
    recs = run_batch(cases)  # warm-up: compile or load the kernels
    times = []
    for _ in range(reps):
        t0 = time.process_time()
        recs = run_batch(cases, StudySettings())
        times.append(time.process_time() - t0)
    print(json.dumps({"times": times, "dz": [r.get("delta_zeta_vbi_pct") for r in recs],
                      "status": [r["status"] for r in recs]}))


def _spawn(src, args, cache):
    env = dict(os.environ, PYTHONPATH=src, NUMBA_CACHE_DIR=cache, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               ADM_SIM_QUIET_COMPILE="1")
    res = subprocess.run([sys.executable, __file__, "--worker", "--span", str(args.span), "--freq-index",
                          str(args.freq_index), "--reps", str(args.reps)], env=env, capture_output=True, text=True,
                         timeout=3600)
    if res.returncode != 0:
        sys.exit(f"worker for {src} failed:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="src directory of the baseline checkout (required)")
    ap.add_argument("--span", type=float, default=20.0, help="span in m (default 20)")
    ap.add_argument("--freq-index", type=int, default=3, help="frequency index 1..5 (default 3)")
    ap.add_argument("--rounds", type=int, default=3, help="alternating worker rounds (default 3)")
    ap.add_argument("--reps", type=int, default=2, help="timed runs per worker (default 2)")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.span, args.freq_index, args.reps)
        return
    if args.baseline is None:
        ap.error("--baseline SRC is required (the src directory of the tree to compare with)")
    trees = {"baseline": args.baseline, "this": HERE_SRC}
    runs = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.rounds):  # alternate which tree goes first
            for name, src in (list(trees.items()) if i % 2 == 0 else list(trees.items())[::-1]):
                runs[name].append(_spawn(src, args, os.path.join(tmp, name)))
    best = {name: min(t for r in rs for t in r["times"]) for name, rs in runs.items()}
    dz = {name: rs[0]["dz"] for name, rs in runs.items()}
    diff = max((abs(a - b) for a, b in zip(dz["this"], dz["baseline"]) if a is not None and b is not None), default=0.0)
    print(f"one study batch: L = {args.span:g} m, f-index {args.freq_index}, mu1..mu6 x ICE-2; min CPU time of "
          f"{args.rounds} x {args.reps} runs after a warm-up")
    print(f"this {best['this']:.3f} s  baseline {best['baseline']:.3f} s  this/baseline "
          f"{best['this'] / best['baseline']:.3f}  max |d dz_VBI| {diff:.2e} %  statuses this {runs['this'][0]['status']} "
          f"baseline {runs['baseline'][0]['status']}")


if __name__ == "__main__":
    main()
