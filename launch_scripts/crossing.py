#!/usr/bin/env python
"""One crossing (or one speed sweep) over ROS 2, published live.

    .venv/bin/python launch_scripts/crossing.py [--params-file ros_ws/params/crossing_b3_300.yaml]
        [--bridge B3] [--train ICE-2] [--model dim|mlm] [--speeds 300] [--out DIR] [--overwrite]
        [--spawn | --connect URL] [--separate-nodes]

Starts the bridge and train nodes in one process (:mod:`adm_sim.nodes.composed`, one executor: a
DIM round trip wakes no other process; ``--separate-nodes`` starts each in a process of its own)
and a driver node in another (records ``run.mcap`` and ``run.rrd`` in ``DIR``, writes
``summary.json``); every topic of the graph is live while it runs (``/adm/midspan/accel``,
``/diagnostics``, ``/clock``...), so a monitoring client on the same ``ROS_DOMAIN_ID`` (printed;
``--domain-id`` to choose it) sees the crossing. Stops every process on exit, Ctrl-C, SIGTERM or
when a node dies (exit status 1, naming the node); the nodes end with the launcher however it
ends (SIGKILL included). Bad input, the params file and the values each node will start with
included, is refused before any process starts or any folder is created (exit 2); an earlier run
in ``--out`` is kept unless ``--overwrite``, a folder another launch is writing is refused.
Ctrl-C or SIGTERM: ``error: interrupted``, exit 130, the outputs of the interrupted run removed.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
from _supervisor import (PARAMS_DIR, ROOT, add_graph_options, graph_lines, launch, preflight, run_graph,
                         supervise_graph)

from adm_sim.cliutil import Parser, add_choice, add_domain_id, add_max_work, add_overwrite
from adm_sim.model.plausibility import check_response
from adm_sim.protocol import parse_driver_line


def main(argv=None):
    ap = Parser(prog=Path(__file__).name, description=__doc__.split("\n\n")[0])
    ap.add_argument("--params-file", default=str(PARAMS_DIR / "crossing_b3_300.yaml"),
                    help="ROS 2 params YAML applied to every node (default ros_ws/params/crossing_b3_300.yaml)")
    ap.add_argument("--bridge", help="bridge preset for the bridge node (B1..B4, spec, a continuous deck spans=15/15,... or TOML file)")
    ap.add_argument("--train", help="train name or TOML file for the train node")
    add_choice(ap, "--model", "dim (vehicles on the deck) or mlm (moving loads); default: the params file's")
    ap.add_argument("--speeds", help="km/h: one speed, a comma list or start:stop:step")
    ap.add_argument("--out", help="output folder (default runs/crossing_<time>)")
    add_domain_id(ap)
    add_max_work(ap)
    add_graph_options(ap)
    add_overwrite(ap, "replace the outputs of an earlier run in --out")
    args = ap.parse_args_or_exit(argv)
    return launch(_main, args)


def _main(args):
    default_out = ROOT / "runs" / f"crossing_{time.strftime('%Y%m%d-%H%M%S')}"
    t_launch = time.time()  # a recording older than this is an earlier run's
    out, env, created, old = preflight(args, default_out, model=args.model)
    pb = {"bridge": args.bridge} if args.bridge is not None else {}
    pt = {k: v for k, v in (("train", args.train), ("model", args.model), ("speeds_kmh", args.speeds))
          if v is not None}
    pd = {"record_path": str(out / "run.mcap"), "rrd_path": str(out / "run.rrd"),
          "summary_path": str(out / "summary.json"), "rerun_spawn": args.spawn, "overwrite": args.overwrite,
          "wait_clients": args.wait_clients}
    if args.connect:
        pd["rerun_connect"] = args.connect
    t0 = time.perf_counter()
    last = -1

    def on_line(line):
        nonlocal last
        kind, d = parse_driver_line(line)
        if kind == "progress":
            pct = int(100 * d["step"] / d["n_steps"])
            if pct >= last + 10:
                print(f"  step {d['step']:>7} / {d['n_steps']}  sim time {d['sim_time_s']:.3f} s", flush=True)
                last = pct
        elif kind is None:
            print(line, flush=True)

    def start(sup):
        graph_lines(sup, out, args.namespace)
        run_graph(sup, args.params_file, pb, pt, "driver", "adm_sim.nodes.driver", pd, on_line,
                  composed=not args.separate_nodes, namespace=args.namespace)

    code = supervise_graph(out, env, created, old, t_launch, start)
    if code is not None:
        return code
    s = json.loads((out / "summary.json").read_text())
    warn_implausible(s)
    print(f"{s['bridge']}\ntrain {s['train']}, {s['model'].upper()}: run {s['run_id']} in {s['wall_s']:.2f} s")
    for v, a in zip(s["speeds_kmh"][:20], s["max_acc_m_s2"][:20]):
        print(f"  {v:7.1f} km/h   max |a| {a:.4f} m/s^2")
    if len(s["speeds_kmh"]) > 20:
        print(f"  ... {len(s['speeds_kmh'])} speeds, max {max(s['max_acc_m_s2']):.4f} m/s^2")
    print(f"wrote {out}/summary.json, run.mcap, run.rrd; wall time {time.perf_counter() - t0:.1f} s")
    return 0


def warn_implausible(s):
    """The plausibility warnings of the run's result (:func:`adm_sim.model.plausibility.check_response`,
    as ``adm-sim sweep`` gives them): its largest acceleration and deflection, named by the run,
    its model and speed; once per run."""
    acc, disp, v = (np.asarray(s[k], dtype=float) for k in ("max_acc_m_s2", "max_disp_m", "speeds_kmh"))
    if acc.size:
        i, j = int(np.argmax(acc)), int(np.argmax(disp))
        run = f"run {s['run_id']} ({s['model'].upper()})"
        check_response(s.get("span_m"), acc[i], disp[j] if s.get("span_m") else None, f"{run} at {v[i]:g} km/h",
                       f"{run} at {v[j]:g} km/h")


if __name__ == "__main__":
    sys.exit(main())
