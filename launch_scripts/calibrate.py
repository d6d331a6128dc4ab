#!/usr/bin/env python
"""Δζ calibration over ROS 2: the bridge and train nodes in one process, the calibration node in another.

    .venv/bin/python launch_scripts/calibrate.py [--bridge B1 --train ICE-2] [--out DIR]
        [--params-file ros_ws/params/b1_ice2.yaml] [--speeds 160:350:1] [--dim-grid window|paper|full]
        [--spawn | --connect URL] [--separate-nodes]

The bridge and train nodes share a process (:mod:`adm_sim.nodes.composed`, one executor: a DIM
round trip wakes no other process); ``--separate-nodes`` starts each in a process of its own.

Writes into ``DIR`` (default ``runs/calibrate_<bridge>_<train>_<time>``): ``run.mcap`` (every
monitoring topic, ROS 2 profile), ``run.rrd`` (rerun), ``summary.json`` (the keys of
``adm-calib calibrate --json``) and ``logs/<node>.log``. Shows the progress of every run and each
Δζ iteration, prints the result, and stops every process it started, also on Ctrl-C, SIGTERM or
when a node dies (exit status 1, naming the node). Exit status 0 on success, 2 on bad input
(everything, the params file and the values each node will start with included, is checked
before any process starts or any folder is created); an earlier run in ``--out`` is kept unless
``--overwrite``, and a folder another launch is writing is refused. Ctrl-C or SIGTERM: ``error:
interrupted``, exit status 130, the outputs of the interrupted run removed. The nodes end with
the launcher however it ends (SIGKILL included, see :mod:`adm_sim.processes.supervisor`).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from _supervisor import (PARAMS_DIR, ROOT, add_graph_options, graph_lines, launch, preflight, run_graph,
                         supervise_graph)

from adm_sim.cliutil import Parser, add_choice, add_domain_id, add_max_work, add_overwrite, progress_bar
from adm_sim.files import write_atomic
from adm_sim.model.plausibility import check_response
from adm_sim.protocol import parse_driver_line


def parse_args(argv=None):
    ap = Parser(prog=Path(__file__).name, description=__doc__.split("\n\n")[0])
    ap.add_argument("--bridge", help="bridge preset for the bridge node (B1..B4, spec, a continuous deck spans=15/15,... or TOML file)")
    ap.add_argument("--train", help="train name or TOML file for the train node")
    ap.add_argument("--speeds", help="MLM speed range, start:stop:step (km/h)")
    add_choice(ap, "--dim-grid", "DIM speeds of the calibration node (default: the params file's, window): window = "
               "the paper's speeds where the associated DIM peak can lie (the same result, about half the DIM lanes); "
               "paper = the paper's whole grid (Section 3.3); full = every MLM speed")
    ap.add_argument("--params-file", default=str(PARAMS_DIR / "b1_ice2.yaml"),
                    help="ROS 2 params YAML applied to every node (default ros_ws/params/b1_ice2.yaml)")
    ap.add_argument("--out", help="output folder")
    ap.add_argument("--no-rrd", action="store_true", help="do not write run.rrd")
    add_domain_id(ap)
    add_max_work(ap)
    add_graph_options(ap)
    ap.add_argument("--quiet", action="store_true", help="no progress bars")
    add_overwrite(ap, "replace the outputs of an earlier run in --out")
    return ap.parse_args_or_exit(argv)


def node_params(args, out):
    bridge = {} if args.bridge is None else {"bridge": args.bridge}
    train = {} if args.train is None else {"train": args.train}
    cal = {"record_path": str(out / "run.mcap"), "summary_path": str(out / "summary.json"), "overwrite": args.overwrite,
           "wait_clients": args.wait_clients}
    if not args.no_rrd:
        cal["rrd_path"] = str(out / "run.rrd")
    if args.spawn:
        cal["rerun_spawn"] = True
    if args.connect:
        cal["rerun_connect"] = args.connect
    if args.speeds is not None:
        cal["speeds_kmh"] = args.speeds
    if args.dim_grid is not None:
        cal["dim_grid"] = args.dim_grid
    return bridge, train, cal


class Progress:
    """tqdm bar of the current run's steps and lines for runs and Δζ iterations."""

    def __init__(self, quiet):
        self.quiet = quiet
        self.bar = None

    def write(self, text):
        if self.bar is not None:
            self.bar.write(text)
        else:
            print(text, flush=True)

    def handle(self, line):
        kind, d = parse_driver_line(line)
        if kind is None:
            self.write(line)
            return
        if kind == "progress" and not self.quiet and d["run_id"] == getattr(self, "_run", None):
            if self.bar is None or self.bar.total != d["n_steps"]:
                self._new_bar(d)
            self.bar.n = d["step"]
            self.bar.refresh()
        elif kind == "run" and d["state"] == "started":
            self._close_bar()
            self._run = d["run_id"]
            self._label = f"run {d['run_id']} {d['label']} ({d['lanes']} lanes)"
        elif kind == "run" and d["state"] == "done":
            self._close_bar()
            self.write(f"run {d['run_id']:>3} {d['label']:<12} {d['wall_s']:7.2f} s   max |a| "
                       f"{d['max_acc_m_s2']:.4f} m/s^2 at {d['speed_kmh']:g} km/h")
        elif kind == "iteration":
            self.write(f"    dz iteration {d['i']:>2}: dz = {d['delta_zeta_pct']:+.5f} %  MLM peak "
                       f"{d['mlm_peak_m_s2']:.5f}  DIM peak {d['dim_peak_m_s2']:.5f}  ratio {d['ratio']:.5f}")
        elif kind == "calibration":
            self.write(f"calibrating {d['bridge']} x {d['train']}: {d['speeds']} speeds, ds = {1000 * d['ds_m']:.2f} mm")

    def _new_bar(self, d):
        self._close_bar()
        self.bar = progress_bar(getattr(self, "_label", f"run {d['run_id']}"), total=d["n_steps"])

    def _close_bar(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def print_result(summary):
    def peak(p):
        return "none" if not p else f"{p['acc_m_s2']:.4f} m/s^2 at {p['speed_kmh']:g} km/h"

    def pct(x):
        return "n/a" if x is None else f"{x:.3f} %"

    print(f"\n{summary['bridge_description']}\ntrain {summary['train']}: {summary['status']} ({summary['message']})")
    print(f"  MLM peak    {peak(summary['mlm_peak'])}\n  DIM peak    {peak(summary['dim_peak'])}")
    print(f"  dz_VBI      {pct(summary['delta_zeta_vbi_pct'])}\n  dz_ADM      {pct(summary['delta_zeta_adm_pct'])}")
    print(f"  dz_EADA     {pct(summary['delta_zeta_eada_pct'])}\n  dz_LB       {pct(summary['delta_zeta_lb_pct'])}")


def warn_implausible(summary):
    """The plausibility warnings of the calibration's MLM and DIM peaks (as ``adm-calib calibrate``
    gives them, :func:`adm_sim.model.plausibility.check_response`): one line each peak no real deck
    survives, named by bridge, train, model and speed; once per run."""
    for model in ("mlm", "dim"):
        p = summary.get(f"{model}_peak")
        if p and p.get("acc_m_s2") is not None:
            check_response(None, p["acc_m_s2"], None,
                           f"{summary['bridge']} x {summary['train']}: {model.upper()} at {p['speed_kmh']:g} km/h")


def main(argv=None):
    args = parse_args(argv)
    return launch(_main, args)


def _main(args):
    t_start = time.perf_counter()
    tag = f"{(args.bridge or 'B1')}_{(args.train or 'ICE-2')}".replace("/", "_").replace("=", "").replace(",", "_")
    default_out = ROOT / "runs" / f"calibrate_{tag}_{time.strftime('%Y%m%d-%H%M%S')}"
    t_launch = time.time()  # a recording older than this is an earlier run's
    out, env, created, old = preflight(args, default_out, dim=True)
    pb, pt, pc = node_params(args, out)
    prog = Progress(args.quiet)
    def start(sup):
        graph_lines(sup, out, args.namespace)
        run_graph(sup, args.params_file, pb, pt, "calibration", "adm_calib.nodes.calibration_node", pc,
                  prog.handle, composed=not args.separate_nodes, namespace=args.namespace)

    code = supervise_graph(out, env, created, old, t_launch, start, on_stop=prog._close_bar)
    if code is not None:
        return code
    summary = json.loads((out / "summary.json").read_text())
    summary["wall_s"] = time.perf_counter() - t_start
    write_atomic(out / "summary.json", lambda tmp: tmp.write_text(json.dumps(summary, indent=2) + "\n"))
    if args.no_rrd and "run.rrd" in old:  # the earlier run's recording does not belong to this one
        (out / "run.rrd").unlink()
    warn_implausible(summary)
    print_result(summary)
    print(f"\nwrote {out / 'summary.json'}, {out / 'run.mcap'}" + ("" if args.no_rrd else f", {out / 'run.rrd'}"))
    print(f"wall time {summary['wall_s']:.1f} s (processes started and stopped included)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
