#!/usr/bin/env python
"""In-process sweep vs the same sweep co-simulated by the bridge and train nodes (two processes).

    .venv/bin/python bench/bench_ros.py [--bridge B1] [--train ICE-2] [--speeds 160:350:1] [--repeat 1]
        [--main-job] [--hogs 2]

Prints for the MLM and the DIM: the in-process :func:`adm_sim.sweep.run_sweep` time, the
co-simulated time (from the run request to the result: parameter set, set-up handshake, every
exchange and the monitoring topics at their default decimation, no recorder), their ratio
(targets: MLM <= 3x, DIM <= 10x), the lockstep round trips and lane-steps per second over ROS.
The co-simulated maxima are checked against the in-process ones (1e-9 relative). ``--main-job``
also times the main job (``launch_scripts/calibrate.py``, B1 x ICE-2, MCAP and ``.rrd`` recorded
under flow control) from start to exit; ``--hogs N`` runs everything while N busy processes hog
the cores (killed at the end).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402

from adm_sim.bridge import resolve_bridge  # noqa: E402
from adm_sim.step_grid import StepOptions  # noqa: E402
from adm_sim.sweep import parse_speeds, run_sweep  # noqa: E402
from adm_sim.trains import load_train  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bridge", default="B1")
    ap.add_argument("--train", default="ICE-2")
    ap.add_argument("--speeds", default="160:350:1")
    ap.add_argument("--models", default="mlm,dim")
    ap.add_argument("--repeat", type=int, default=1, help="co-simulated runs per model (best is kept)")
    ap.add_argument("--main-job", action="store_true", help="also time launch_scripts/calibrate.py (B1 x ICE-2)")
    ap.add_argument("--hogs", type=int, default=0, help="busy processes running meanwhile")
    args = ap.parse_args(argv)
    import subprocess

    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.hogs)]
    try:
        return _bench(args)
    finally:
        for h in hogs:
            h.kill()
            h.wait()


def _main_job():
    """Wall time (s) of the main job, process start to exit."""
    import subprocess

    out = Path(tempfile.mkdtemp(prefix="bench_ros_main_")) / "out"
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "calibrate.py"), "--out", str(out), "--quiet"],
                       capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"error: main job failed (exit status {p.returncode}): {p.stderr.strip()[-400:]}")
    return wall


def _bench(args):

    from ros_fixtures import NodeProcs, driver_node

    from adm_sim.nodes import driver

    driver.QUIET = True

    from adm_sim.processes.dds_env import local_ros_env

    bridge, train = resolve_bridge(args.bridge), load_train(args.train)
    speeds = parse_speeds(args.speeds)
    rows = []
    with local_ros_env() as env:
        env["OPENBLAS_NUM_THREADS"] = "1"
        procs = NodeProcs(env, tempfile.mkdtemp(prefix="bench_ros_"))
        t_start = time.perf_counter()
        procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": args.bridge})
        procs.start("train", "adm_sim.nodes.train_node", {"train": args.train, "speeds_kmh": args.speeds})
        try:
            with driver_node(env.domain_id) as d:
                d.wait_for_graph()
                t_graph = time.perf_counter() - t_start
                for model in args.models.split(","):
                    t0 = time.perf_counter()
                    ref = run_sweep(bridge, train, model, speeds, options=StepOptions())
                    t_in = time.perf_counter() - t0
                    best = None
                    for _ in range(args.repeat):
                        r = d.request_run(model=model)
                        best = r if best is None or r["wall_s"] < best["wall_s"] else best
                    rel = float(np.max(np.abs(best["max_acc_m_s2"] / ref.max_acc_m_s2 - 1.0)))
                    n = ref.n_steps
                    trips = 4 * n if model == "dim" else -(-n // 2048)
                    rows.append((model, t_in, best["wall_s"], n, trips, rel))
        finally:
            procs.stop_all()
    print(f"{bridge.describe()}\n{train.describe()}\n{speeds.size} speed lanes {speeds.min():g}..{speeds.max():g} km/h; "
          f"nodes up and matched in {t_graph:.2f} s\n")
    print(f"{'model':5} {'in-process':>11} {'co-sim':>9} {'ratio':>7} {'target':>7} {'steps':>7} {'round trips':>12} "
          f"{'trips/s':>8} {'lane-steps/s':>13} {'max rel diff':>13}")
    ok = True
    for model, t_in, t_co, n, trips, rel in rows:
        target = 3.0 if model == "mlm" else 10.0
        ok &= rel <= 1e-9
        print(f"{model.upper():5} {t_in:10.2f}s {t_co:8.2f}s {t_co / t_in:6.2f}x {target:6.0f}x {n:7d} {trips:12d} "
              f"{trips / t_co:8.0f} {speeds.size * n / t_co:13.3g} {rel:13.1e}")
    if args.main_job:
        print(f"\nmain job (calibrate.py B1 x ICE-2, MCAP + .rrd): {_main_job():.1f} s wall"
              f"{f' with {args.hogs} busy processes' if args.hogs else ''}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
