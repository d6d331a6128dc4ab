"""``adm-calib table4``: the four approaches of paper Table 4 and Figure 19 for the bridges B1-B4 under the four trains."""

from __future__ import annotations

import time

from adm_sim.cliutil import check_option, option_help, progress_callback
from adm_sim.files import OutputSet, make_output_folder
from adm_sim.inputs.train_files import load_train
from adm_sim.model.bridge import named_bridge

from adm_calib import plots
from adm_calib.cli.calibrate import add_calibration_options, calibration_options, check_plausible
from adm_calib.cli.options import as_option, comma_list, once, out_dir, speeds_option, study_train
from adm_calib.table4 import run_table4


def add_arguments(parser):
    """The options of ``adm-calib table4``."""
    parser.add_argument("--out", default="table4_out", help="output directory (default table4_out)")
    parser.add_argument("--bridges", default="B1,B2,B3,B4", help="comma list of B1..B4 (default B1,B2,B3,B4)")
    parser.add_argument("--trains", default="ICE-2,Eurostar,Railjet,ICE-4",
                   help="comma list of ICE-2, Eurostar, Railjet, ICE-4 (default all four)")
    parser.add_argument("--jobs", default="1", help=option_help("--jobs", "worker processes (default 1)"))
    add_calibration_options(parser)


def run(args):
    """Calibrate every bridge x train, print Table 4, write its four files (all or none)."""
    names = ("table4.csv", "table4.txt", "table4.json", "fig19_total_damping.png")
    out, paths = out_dir(args.out, "--out", names, args.force)
    bridges = once([as_option("--bridges", "bridge", named_bridge, b).name for b in comma_list(args.bridges, "--bridges")],
                    "--bridges", args.bridges)
    trains = once([study_train(t, "--trains") for t in comma_list(args.trains, "--trains")], "--trains", args.trains)
    for t in trains:
        load_train(t)
    jobs = check_option("--jobs", args.jobs)
    speeds, options = speeds_option(args.speeds), calibration_options(args)
    make_output_folder(out, "--out")
    t0 = time.perf_counter()
    cb, close = progress_callback("table4", args.progress, unit="it", leave=True)
    try:
        table = run_table4(bridges, trains, speeds_kmh=speeds, options=options, jobs=jobs, progress=cb)
    finally:
        close()
    for res in table.results.values():
        check_plausible(res)
    text = table.to_text()
    print(text)
    with OutputSet() as outs:  # the four files: all or none
        outs.write(paths[0], lambda p: p.write_text(table.to_csv()), "--out")
        outs.write(paths[1], lambda p: p.write_text(text + "\n"), "--out")
        outs.write(paths[2], lambda p: p.write_text(table.to_json() + "\n"), "--out")
        outs.write(paths[3], lambda p: plots.plot_total_damping(table, p), "--out")
    print(f"wrote {', '.join(str(p) for p in paths)} ({time.perf_counter() - t0:.1f} s)")
    return 0
