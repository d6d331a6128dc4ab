"""``adm-calib calibrate``: Δζ_VBI of one bridge under one train (paper Section 4), with the reference methods.

Also the options and the plausibility warnings of every calibration (:func:`add_calibration_options`,
:func:`calibration_options`, :func:`check_plausible`), which ``adm-calib table4`` shares.
"""

from __future__ import annotations

import json
import time

import numpy as np

from adm_sim.cliutil import (add_dim_grid, add_max_work, add_overwrite, add_progress, add_speeds, add_steps_per_period,
                             progress_callback)
from adm_sim.errors import InputError
from adm_sim.files import OutputSet, claim_output
from adm_sim.inputs.bridges import resolve_bridge
from adm_sim.inputs.measured import add_measured_argument, measured_bridge
from adm_sim.inputs.train_files import load_train
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import check_spans_for_train
from adm_sim.model.plausibility import check_response

from adm_calib import plots
from adm_calib.calibrate import calibrate
from adm_calib.calibration_options import CalibrationOptions
from adm_calib.cli.options import add_peaks_options, speeds_option, steps_per_period_option
from adm_calib.study.cases import REFINED_SPEED_STEP_KMH


def add_arguments(parser):
    """The options of ``adm-calib calibrate``."""
    add_max_work(parser)
    parser.add_argument("--bridge", required=True, help="B1..B4, a spec L=15,n0=8.26,mu=19042,zeta_pct=1.85,class=cfb "
                   "(L m, n0 Hz or EJ N m^2, mu kg/m, zeta_pct %% or type=cfb|sc for the Table 2 damping; class=cfb|sc "
                   "classes a bridge of given damping for the lower-bound functions), a continuous deck "
                   "spans=15/15,n0=8.26,mu=19042,zeta_pct=1.85,class=cfb (the peaks are the largest of the maxima at "
                   "the middle of every span, MLM and DIM alike; ADM, EADA and the lower bound are not evaluated on "
                   "a deck), or a TOML file with these keys")
    parser.add_argument("--train", required=True, help="ICE-2, Eurostar, Railjet, ICE-4 or a TOML train file")
    add_measured_argument(parser)
    parser.add_argument("--json", help="write the result as JSON to this file")
    parser.add_argument("--plot", help="write the Fig. 15 analogue to this PNG file")
    add_calibration_options(parser)


def add_calibration_options(sp):
    """The options calibrate and table4 share."""
    add_speeds(sp, "MLM speeds in km/h, start:stop:step", show_default=True)
    add_dim_grid(sp, "DIM speeds: paper = 5 km/h plus 1 km/h near the MLM peak (Section 3.3); full = all")
    add_steps_per_period(sp, "integration steps per period of the highest mode (core default 16)")
    add_progress(sp, negatable=False, text="show progress bars on stderr")
    add_overwrite(sp, "replace existing output files (only once the new ones are complete)", force_alias=True)
    add_peaks_options(sp)


def calibration_options(args):
    """The :class:`~adm_calib.calibration_options.CalibrationOptions` of the calibration options."""
    step = None
    if args.steps_per_period is not None or args.dense_maxima:
        spp = StepOptions.steps_per_period if args.steps_per_period is None else steps_per_period_option(args.steps_per_period)
        step = StepOptions(steps_per_period=spp, dense_maxima=args.dense_maxima)
    return CalibrationOptions(dim_grid=args.dim_grid, step=step,
                              speed_refinement_kmh=REFINED_SPEED_STEP_KMH if args.refine_speed else None)


def run(args):
    """Calibrate, print the result, write ``--json`` and ``--plot`` (both or neither)."""
    inputs = {"--bridge": args.bridge, "--train": args.train, "--measured": args.measured}
    json_path = (claim_output(args.json, "--json", args.force, suffix=".json", inputs=inputs) if args.json is not None
                 else None)
    plot_path = (claim_output(args.plot, "--plot", args.force, suffix=".png", inputs=inputs) if args.plot is not None
                 else None)
    bridge = resolve_bridge(args.bridge, continuous=True)  # a continuous deck: its largest midspan peak
    if bridge.is_continuous and len(bridge.spans_m) > 1 and args.measured is not None:
        raise InputError(f"--measured: {args.measured!r} sets n0 and zeta of a simply supported span (EJ from Eq. 18); "
                         f"--bridge {args.bridge!r} is a continuous deck of {len(bridge.spans_m)} spans: give its "
                         f"n0 or EJ and zeta_pct in the spec instead")
    bridge, measured = measured_bridge(args, bridge)  # --measured: n0, zeta of the monitored bridge
    train = load_train(args.train)
    check_spans_for_train(bridge, train)  # a deck's span shorter than the train's longest axle group
    speeds = speeds_option(args.speeds)
    options = calibration_options(args)
    cb, close = progress_callback(f"calibrate {bridge.name or 'bridge'} x {train.name}", args.progress, unit=" runs")
    t0 = time.perf_counter()
    try:
        res = calibrate(bridge, train, speeds_kmh=speeds, options=options, progress=cb)
    finally:
        close()
    wall = time.perf_counter() - t0
    check_plausible(res)
    print(res.summary())
    print(f"wall time      {wall:.2f} s")
    with OutputSet() as outs:  # --json and --plot: both or neither
        if json_path:
            text = res.to_json() if measured is None else json.dumps({**json.loads(res.to_json()),
                                                                       "measured": measured.to_dict()}, indent=1)
            outs.write(json_path, lambda p: p.write_text(text + "\n"), "--json", note=f"wrote {json_path}")
        if plot_path:
            outs.write(plot_path, lambda p: plots.plot_calibration(res, p), "--plot", note=f"wrote {plot_path}")
    return 0


def check_plausible(res):
    """Plausibility warnings on a calibration's MLM and DIM curves: each curve's largest
    acceleration, named by bridge, train, model and speed (:mod:`adm_sim.model.plausibility`)."""
    for model, v, a in (("MLM", res.mlm_speeds_kmh, res.mlm_acc_m_s2), ("DIM", res.dim_speeds_kmh, res.dim_acc_m_s2)):
        if a.size:
            i = int(np.argmax(a))
            check_response(res.bridge.span_m, a[i], None,
                           f"{res.bridge.name or 'bridge'} x {res.train_name}: {model} at {v[i]:g} km/h")
