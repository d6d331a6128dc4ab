"""Time of the compiled kernels (``kernels.dim_blocks``, ``kernels.mlm_blocks``) on one batch.

Run: ``.venv/bin/python bench/bench_kernels.py [--rounds N] [--reps N] [--speeds N] [--baseline SRC] [--numpy]``.

The case: the six mass functions of the 20 m, f-index 3 bridges of the study (L20-f3-mu1..mu6)
under ICE-2 at 8 speeds 160..350 km/h = 48 lanes (``--speeds 32``: 32 speeds, 192 lanes in blocks of
32, the size of most of the study's DIM blocks) of one :class:`adm_sim.integrate.compiled_batch.BatchRunner`
on the calibration step of the group, run as DIM and MLM, with and without dense maxima. Every
timing runs in a worker subprocess (``PYTHONPATH=<src>``) that first runs every configuration
once untimed (numba compile or cache load), then ``--reps`` timed repetitions, the four
configurations interleaved; times are CPU seconds of the worker (``time.process_time``: on a
shared 2-core machine the wall clock also counts the other processes). With ``--baseline SRC`` (e.g. another checkout's ``src``) the
baseline's and this tree's workers alternate for ``--rounds`` rounds (first one, then the other); the bench prints the min
time of each (over all rounds and repetitions), the ratio this/baseline, the median over the rounds
of each round's ratio (each tree's best repetition in that round: the two met the same load) and
whether the per-lane maxima of both are equal bit for bit (``np.array_equal``). numba's cache goes to a temporary
directory, so no other checkout is written to. ``--numpy`` also times the numpy stepper
(:func:`adm_sim.integrate.sweep.run_sweep`, one sweep per bridge) on the DIM and MLM lanes once, in process.
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

import numpy as np

HERE_SRC = str(Path(__file__).resolve().parents[1] / "src")
SPEEDS_KMH = np.linspace(160.0, 350.0, 8)
CONFIGS = [("dim", False), ("dim", True), ("mlm", False), ("mlm", True)]


def _case():
    from adm_calib.calibrate import batch_step
    from adm_calib.study import select_cases
    from adm_sim.inputs.train_files import load_train

    bridges = [c.bridge for c in select_cases(["ICE-2"], ["mu1", "mu2", "mu3", "mu4", "mu5", "mu6"], (20, 20), [3])]
    train = load_train("ICE-2")
    return bridges, train, batch_step(bridges, train).ds_m


def worker(reps, n_speeds=8):
    """Warm-up, then ``reps`` interleaved timed runs of every configuration; JSON on stdout."""
    from adm_sim.integrate.compiled_batch import BatchRunner

    bridges, train, ds = _case()
    grid = np.linspace(SPEEDS_KMH[0], SPEEDS_KMH[-1], n_speeds)
    case = np.repeat(np.arange(len(bridges)), grid.size)
    speeds = np.tile(grid, len(bridges))
    runners = {dense: BatchRunner(bridges, train, ds, dense_maxima=dense) for dense in (False, True)}
    out = {}
    for model, dense in CONFIGS:  # warm-up: compile or load, build the tables
        acc, disp = runners[dense].run(model, case, speeds)
        out[f"{model}{'+dense' if dense else ''}"] = {"times": [], "acc": acc.tolist(), "disp": disp.tolist()}
    for _ in range(reps):
        for model, dense in CONFIGS:
            t0 = time.process_time()
            runners[dense].run(model, case, speeds)
            out[f"{model}{'+dense' if dense else ''}"]["times"].append(time.process_time() - t0)
    print(json.dumps(out))


def _spawn(src, reps, cache_dir, n_speeds=8):
    env = dict(os.environ, PYTHONPATH=src, NUMBA_CACHE_DIR=cache_dir)
    res = subprocess.run([sys.executable, __file__, "--worker", "--reps", str(reps), "--speeds", str(n_speeds)], env=env,
                         capture_output=True, text=True, timeout=1800)
    if res.returncode != 0:
        sys.exit(f"worker for {src} failed:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def _numpy_times():
    from adm_sim.integrate.step_grid import StepOptions
    from adm_sim.integrate.sweep import run_sweep

    bridges, train, ds = _case()
    out = {}
    for model in ("dim", "mlm"):
        t0 = time.process_time()
        for b in bridges:
            run_sweep(b, train, model, SPEEDS_KMH, options=StepOptions(ds_m=ds))
        out[model] = time.process_time() - t0
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="alternating worker rounds (default 3)")
    ap.add_argument("--reps", type=int, default=3, help="timed repetitions per worker (default 3)")
    ap.add_argument("--speeds", type=int, default=8, help="speeds per bridge, 160..350 km/h (default 8)")
    ap.add_argument("--baseline", default=None, help="src directory of the baseline checkout")
    ap.add_argument("--numpy", action="store_true", help="also time the numpy stepper once")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.reps, args.speeds)
        return
    trees = {"this": HERE_SRC} if args.baseline is None else {"baseline": args.baseline, "this": HERE_SRC}
    runs = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as tmp:
        caches = {name: os.path.join(tmp, name) for name in trees}
        for i in range(args.rounds):  # alternate which tree goes first
            for name, src in (list(trees.items()) if i % 2 == 0 else list(trees.items())[::-1]):
                runs[name].append(_spawn(src, args.reps, caches[name], args.speeds))
    bridges, train, ds = _case()
    print(f"{len(bridges) * args.speeds} lanes: {len(bridges)} bridges L20-f3-mu1..6 x ICE-2 x {args.speeds} speeds 160..350 km/h, "
          f"ds = {ds:.4g} m; min CPU time of {args.rounds} x {args.reps} runs after a warm-up")
    for key in runs["this"][0]:
        best = {name: min(t for r in rs for t in r[key]["times"]) for name, rs in runs.items()}
        line = f"{key:10s} this {best['this']:.4f} s"
        if "baseline" in best:
            same = all(np.array_equal(np.array(r[key][f]), np.array(runs["baseline"][0][key][f]))
                       for rs in runs.values() for r in rs for f in ("acc", "disp"))
            per_round = [min(t[key]["times"]) / min(b[key]["times"]) for t, b in zip(runs["this"], runs["baseline"])]
            line += (f"  baseline {best['baseline']:.4f} s  this/baseline {best['this'] / best['baseline']:.3f}"
                     f"  median of rounds {float(np.median(per_round)):.3f}  maxima bit for bit equal: {same}")
        print(line)
    if args.numpy:
        sys.path.insert(0, HERE_SRC)
        t = _numpy_times()
        for model in ("dim", "mlm"):
            best = min(t for r in runs["this"] for t in r[model]["times"])
            print(f"numpy stepper {model}: {t[model]:.3f} s (one run); compiled/numpy {best / t[model]:.4f}")


if __name__ == "__main__":
    main()
