"""Cost of a DIM sweep on a rough track against the same sweep on a smooth one (same lanes, same run).

Run: ``.venv/bin/python bench/bench_irregularity.py [--reps N]``.

The case: the six mass functions of the 20 m, f-index 3 bridges of the study (L20-f3-mu1..mu6)
under ICE-2 at 8 speeds 160..350 km/h = 48 lanes of one :class:`adm_sim.integrate.compiled_batch.BatchRunner`
on the group's calibration step (as ``bench/bench_kernels.py``), as a DIM run on the smooth track
and on a German high disturbance profile (seed 1). One process: both runners are built and run
once untimed (numba compile or cache load, tables), then ``--reps`` timed repetitions, the two
interleaved; times are CPU seconds (``time.process_time``: on a shared 2-core machine the wall
clock also counts the other processes). Prints the min time of each, the ratio rough/smooth
(target <= 1.2) and the table build time of the profile (spline evaluation at every axle row).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=5)
    args = ap.parse_args(argv)
    from adm_calib.calibrate import batch_step
    from adm_calib.study import select_cases
    from adm_sim.integrate.compiled_batch import BatchRunner
    from adm_sim.inputs.track_profile import parse_irregularity
    from adm_sim.inputs.train_files import load_train

    bridges = [c.bridge for c in select_cases(["ICE-2"], ["mu1", "mu2", "mu3", "mu4", "mu5", "mu6"], (20, 20), [3])]
    train = load_train("ICE-2")
    ds = batch_step(bridges, train).ds_m
    speeds = np.linspace(160.0, 350.0, 8)
    case = np.repeat(np.arange(len(bridges)), speeds.size)
    v = np.tile(speeds, len(bridges))
    profile = parse_irregularity("german-high:seed=1", 20.0)
    runners = {"smooth": BatchRunner(bridges, train, ds), "rough": BatchRunner(bridges, train, ds, irregularity=profile)}
    acc = {}
    for name, r in runners.items():  # warm-up: compile or load, build the tables
        t = time.process_time()
        acc[name] = r.run("dim", case, v)[0]
        print(f"{name}: first run (tables, compile or cache load) {time.process_time() - t:.2f} s CPU")
    times = {k: [] for k in runners}
    for _ in range(args.reps):
        for name, r in runners.items():
            t = time.process_time()
            r.run("dim", case, v)
            times[name].append(time.process_time() - t)
    t = time.process_time()
    runners["rough"]._track_table(runners["rough"]._axle_rows, 2 * runners["rough"]._rows + 1)
    t_table = time.process_time() - t
    s, r = min(times["smooth"]), min(times["rough"])
    print(f"DIM, {v.size} lanes (L20-f3-mu1..mu6 x ICE-2, 8 speeds), ds = {ds:.4f} m, {args.reps} reps, min CPU s:")
    print(f"  smooth track      {s:.3f} s")
    print(f"  German high, s1   {r:.3f} s   ratio rough/smooth {r / s:.3f} (target <= 1.2)")
    print(f"  profile table (spline at every axle row): {t_table:.3f} s, in the rough run's first call only")
    print(f"  peak change by the profile: {np.round(100 * (acc['rough'] / acc['smooth'] - 1), 1).min():+.1f} .. "
          f"{np.round(100 * (acc['rough'] / acc['smooth'] - 1), 1).max():+.1f} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
