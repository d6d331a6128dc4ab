#!/usr/bin/env python
"""In-process sweep vs the same sweep co-simulated by the bridge and train nodes.

    .venv/bin/python bench/bench_ros.py [--bridge B1] [--train ICE-2] [--speeds 160:350:1] [--repeat 1]
        [--main-job] [--hogs 2] [--separate-nodes]

The bridge and train nodes run in one process (:mod:`adm_sim.nodes.composed`, as ``calibrate.py``
runs them) or, with ``--separate-nodes``, in two (the main job then gets ``--separate-nodes`` too);
the CPU time of each node process per round trip of the last co-simulated run is printed.

Prints for the MLM and the DIM: the in-process :func:`adm_sim.integrate.sweep.run_sweep` time, the
co-simulated time (from the run request to the result: parameter set, set-up handshake, every
exchange and the monitoring topics at their default decimation, no recorder), their ratio
(targets: MLM <= 3x, DIM <= 10x), the lockstep round trips and lane-steps per second over ROS.
The co-simulated maxima are checked against the in-process ones (1e-9 relative). ``--main-job``
also times the main job (``launch_scripts/calibrate.py``, B1 x ICE-2, MCAP and ``.rrd`` recorded
under flow control) from start to exit, and splits it: start-up (process start to the end of the
first run, less that run), the runs, the gaps between runs, the stop (end of the last run to
exit), and the CPU time of each of its processes (launcher, bridge, train and calibration node;
read from /proc, less sensitive to the load of the machine than the wall times); ``--hogs N`` runs everything while N busy processes hog the cores (killed at the end).

``--baseline TREE`` measures this tree and another checkout (e.g. ``git archive <commit>``
unpacked, its numba cache warmed) alternately, ``--rounds`` times each, every measurement in a
process of its own with that tree's ``src`` first on ``PYTHONPATH`` (the bench and its fixtures are
this tree's); prints both, the best of the rounds, and the load average before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import threading
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402

from adm_sim.inputs.bridges import resolve_bridge  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.inputs.speeds import parse_speeds  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bridge", default="B1")
    ap.add_argument("--train", default="ICE-2")
    ap.add_argument("--speeds", default="160:350:1")
    ap.add_argument("--models", default="mlm,dim", help="co-simulated sweeps to time (none: only --main-job)")
    ap.add_argument("--repeat", type=int, default=1, help="co-simulated runs per model (best is kept)")
    ap.add_argument("--main-job", action="store_true", help="also time launch_scripts/calibrate.py (B1 x ICE-2)")
    ap.add_argument("--hogs", type=int, default=0, help="busy processes running meanwhile")
    ap.add_argument("--separate-nodes", action="store_true",
                    help="the bridge and train nodes as two processes (the main job: calibrate.py --separate-nodes; "
                         "default: one process hosting both)")
    ap.add_argument("--root", default=str(ROOT), help="checkout whose launch scripts the main job runs")
    ap.add_argument("--json", help="write the figures to this file")
    ap.add_argument("--baseline", help="another checkout measured alternately with this one")
    ap.add_argument("--rounds", type=int, default=2, help="with --baseline: measurements per tree")
    args = ap.parse_args(argv)
    if args.baseline:
        return _compare(args, argv if argv is not None else sys.argv[1:])
    import subprocess

    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.hogs)]
    try:
        return _bench(args)
    finally:
        for h in hogs:
            h.kill()
            h.wait()


RUN_LINE = re.compile(r"^run\s+(\d+)\s+(.*?)\s+([0-9.]+) s\s+max")


def _main_job(root=ROOT, extra=()):
    """The main job from process start to exit: ``{"wall_s", "start_s", "runs_s", "gaps_s", "stop_s",
    "n_runs", "dz_vbi_pct"}`` (times of the run lines as they are printed)."""
    import subprocess

    out = Path(tempfile.mkdtemp(prefix="bench_ros_main_")) / "out"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, str(Path(root) / "launch_scripts" / "calibrate.py"), "--out", str(out),
                          "--quiet", *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=root, env=env)
    runs = []  # (time the line came, run wall)
    cpu = {}  # process -> CPU seconds (user + system), sampled while it lives
    stop = threading.Event()

    def sample():
        while not stop.is_set():
            cpu.update(_tree_cpu_s(p.pid))
            stop.wait(0.25)

    threading.Thread(target=sample, daemon=True).start()
    snaps = [{}]  # CPU of each process when each run line came
    for line in p.stdout:
        m = RUN_LINE.match(line)
        if m:
            runs.append((time.perf_counter() - t0, float(m.group(3)), m.group(2).split()[0]))
            snaps.append(_tree_cpu_s(p.pid))
    err = p.stderr.read()
    p.wait()
    wall = time.perf_counter() - t0
    stop.set()
    if p.returncode != 0 or not runs:
        raise SystemExit(f"error: main job failed (exit status {p.returncode}): {err.strip()[-400:]}")
    summary = json.loads((out / "summary.json").read_text())
    runs_s = sum(r[1] for r in runs)
    start_s = runs[0][0] - runs[0][1]
    stop_s = wall - runs[-1][0]
    return {"wall_s": wall, "start_s": start_s, "runs_s": runs_s, "gaps_s": wall - start_s - stop_s - runs_s,
            "stop_s": stop_s, "n_runs": len(runs), "dz_vbi_pct": summary["delta_zeta_vbi_pct"],
            "dim_runs_s": sum(r[1] for r in runs if r[2] == "DIM"), "mlm_runs_s": sum(r[1] for r in runs if r[2] == "MLM"),
            **{f"cpu_{name}_s": v for name, v in sorted(cpu.items())},
            # CPU from the run line before the DIM run to the DIM run's line (the DIM run and its set-up)
            **{f"dimcpu_{name}_s": snaps[i + 1].get(name, 0.0) - snaps[i].get(name, 0.0)
               for i, r in enumerate(runs) if r[2] == "DIM" for name in sorted(snaps[i + 1])}}


def _tree_cpu_s(pid):
    """CPU seconds (user + system) of process ``pid`` and its children, by name (``launcher`` or
    the node module's last part, e.g. ``calibration_node``), from /proc; what cannot be read is left out."""
    tck = os.sysconf("SC_CLK_TCK")
    try:
        kids = [int(x) for x in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        kids = []
    out = {}
    for q in [pid, *kids]:
        try:
            cmd = Path(f"/proc/{q}/cmdline").read_text().split("\0")
            f = Path(f"/proc/{q}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        name = next((a.rsplit(".", 1)[-1] for a in cmd if ".nodes." in a), "launcher" if q == pid else None)
        if name:
            out[name] = (int(f[11]) + int(f[12])) / tck
    return out


def _cpu_s(pid):
    """CPU seconds (user + system) of process ``pid`` so far (0.0 when it cannot be read)."""
    try:
        f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def _compare(args, argv):
    """This tree and ``--baseline`` alternately, one process per measurement; prints both."""
    import subprocess

    drop = {"--baseline", "--rounds", "--json", "--root"}
    child, skip = [], False
    for a in argv:
        if skip:
            skip = False
            continue
        if a.split("=")[0] in drop:
            skip = "=" not in a
            continue
        child.append(a)
    trees = {"this": ROOT, "baseline": Path(args.baseline).resolve()}
    got = {name: [] for name in trees}
    load0 = os.getloadavg()
    for _ in range(args.rounds):
        for name, tree in trees.items():
            out = Path(tempfile.mkdtemp(prefix="bench_ros_cmp_")) / "r.json"
            env = dict(os.environ, PYTHONPATH=str(tree / "src"))
            p = subprocess.run([sys.executable, __file__, *child, "--root", str(tree), "--json", str(out)], env=env,
                               capture_output=True, text=True)
            if p.returncode not in (0, 1) or not out.exists():
                raise SystemExit(f"error: bench of {tree} failed (exit status {p.returncode}): {p.stderr.strip()[-400:]}")
            got[name].append(json.loads(out.read_text()))
            print(f"[{name}] load {os.getloadavg()[0]:.2f}\n{p.stdout}", flush=True)
    load1 = os.getloadavg()
    print(f"load average (1/5/15 min) before {load0[0]:.2f}/{load0[1]:.2f}/{load0[2]:.2f}, "
          f"after {load1[0]:.2f}/{load1[1]:.2f}/{load1[2]:.2f}; best of {args.rounds} per tree\n")
    keys = [k for k in got["this"][0] if isinstance(got["this"][0][k], (int, float))]
    print(f"{'figure':22} {'this':>10} {'baseline':>10} {'this/base':>10}")
    def best(rows, k):  # times: the least; rates: the most; ratios and counts: the last round's
        if k.endswith("_per_s"):
            return max(r[k] for r in rows)
        return min(r[k] for r in rows) if k.endswith("_s") else rows[-1][k]

    for k in keys:
        a, b = best(got["this"], k), best(got["baseline"], k)
        print(f"{k:22} {a:10.4g} {b:10.4g} {a / b if b else float('nan'):10.3f}")
    return 0


def _bench(args):

    from ros_fixtures import NodeProcs, driver_node

    from adm_sim.nodes import driver

    driver.QUIET = True

    from adm_sim.processes.dds_env import local_ros_env

    bridge, train = resolve_bridge(args.bridge), load_train(args.train)
    speeds = parse_speeds(args.speeds)
    rows = []
    figures = {}
    with local_ros_env() as env:
        env["OPENBLAS_NUM_THREADS"] = "1"
        procs = NodeProcs(env, tempfile.mkdtemp(prefix="bench_ros_"))
        t_start = time.perf_counter()
        if args.separate_nodes:
            procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": args.bridge})
            procs.start("train", "adm_sim.nodes.train_node", {"train": args.train, "speeds_kmh": args.speeds})
        else:  # one process hosting both (as calibrate.py runs them)
            procs.start("bridge_train", "adm_sim.nodes.composed",
                        {"bridge:bridge": args.bridge, "train:train": args.train, "train:speeds_kmh": args.speeds})
        try:
            with driver_node(env.domain_id) as d:
                d.wait_for_graph()
                t_graph = time.perf_counter() - t_start
                for model in [m for m in args.models.split(",") if m not in ("", "none")]:
                    t0 = time.perf_counter()
                    ref = run_sweep(bridge, train, model, speeds, options=StepOptions())
                    t_in = time.perf_counter() - t0
                    best = None
                    for _ in range(args.repeat):
                        cpu0 = {k: _cpu_s(p.pid) for k, p in procs.procs.items()}
                        r = d.request_run(model=model)
                        cpu = {k: _cpu_s(p.pid) - cpu0[k] for k, p in procs.procs.items()}
                        best = r if best is None or r["wall_s"] < best["wall_s"] else best
                    n = ref.n_steps
                    trips = 4 * n if model == "dim" else -(-n // 2048)
                    print(f"{model.upper()} co-simulation CPU a round trip (last run): "
                          + ", ".join(f"{k} {1e6 * v / trips:.0f} us" for k, v in cpu.items()), flush=True)
                    figures.update({f"{model}_cpu_{k}_us_per_trip": 1e6 * v / trips for k, v in cpu.items()})
                    rel = float(np.max(np.abs(best["max_acc_m_s2"] / ref.max_acc_m_s2 - 1.0)))
                    rows.append((model, t_in, best["wall_s"], n, trips, rel))
                    figures.update({f"{model}_in_process_s": t_in, f"{model}_cosim_s": best["wall_s"],
                                    f"{model}_ratio": best["wall_s"] / t_in, f"{model}_trips_per_s": trips / best["wall_s"],
                                    f"{model}_max_rel_diff": rel})
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
    figures["graph_up_s"] = t_graph
    if args.main_job:
        mj = _main_job(args.root, ["--separate-nodes"] if args.separate_nodes else [])
        figures.update({f"main_{k}": v for k, v in mj.items()})
        print(f"\nmain job (calibrate.py B1 x ICE-2, MCAP + .rrd): {mj['wall_s']:.1f} s wall"
              f"{f' with {args.hogs} busy processes' if args.hogs else ''}: start-up {mj['start_s']:.1f} s, "
              f"{mj['n_runs']} runs {mj['runs_s']:.1f} s (DIM {mj['dim_runs_s']:.1f} s, MLM {mj['mlm_runs_s']:.1f} s), between runs {mj['gaps_s']:.1f} s, stop {mj['stop_s']:.1f} s; "
              f"dz_VBI {mj['dz_vbi_pct']:.7f} %")
        print("main job CPU (user + system): " + ", ".join(f"{k[4:-2]} {v:.1f} s" for k, v in mj.items()
                                                           if k.startswith("cpu_")))
        print("its DIM run's CPU (41 840 round trips), us a trip: " + ", ".join(
            f"{k[7:-2]} {1e6 * v / 41840:.0f}" for k, v in mj.items() if k.startswith("dimcpu_")))
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1) + "\n")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
