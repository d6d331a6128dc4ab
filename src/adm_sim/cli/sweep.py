"""``adm-sim sweep``: the maximum acceleration of one bridge under one train over a speed range.

The MLM by its closed-form envelope (:func:`adm_sim.integrate.sweep.sweep_exact`, default) or by RK4, the DIM
by RK4 (compiled lanes or the numpy stepper); ``--json`` and ``--plot`` are written both or neither.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
import warnings
from pathlib import Path

from adm_sim.cli import figures
from adm_sim.cli.options import add_output_options
from adm_sim.cliutil import (add_choice, add_delta_zeta_pct, add_max_work, add_speeds, add_steps_per_period,
                             check_option, option_help, option_view, progress_callback)
from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.fields import FIELDS
from adm_sim.files import OutputSet, claim_output
from adm_sim.inputs.bridges import resolve_bridge
from adm_sim.inputs.speeds import parse_speeds
from adm_sim.inputs.track_profile import parse_irregularity
from adm_sim.inputs.train_files import load_train
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import check_spans_for_train, lane_damping, run_sweep, run_sweep_compiled, sweep_exact
from adm_sim.integrate.where import parse_where, where_text
from adm_sim.model.plausibility import check_response
from adm_sim.model.spans import RULE_TEXT, rule_mode_count

#: ``--damping-model`` of sweep and check -> ``Bridge.damping_model`` (as adm_sim.design.check.DAMPING_MODELS).
SWEEP_DAMPING_MODELS = {"rayleigh13": "rayleigh", "modal": "modal"}


def _sweep_modes(bridge, modes, damping_model):
    """The bridge with ``--modes`` and ``--damping-model`` applied (None: the bridge's own). A
    continuous deck takes up to 50 modes (fewer than its rule asks: a warning naming the rule), one
    span the registry's ``n_modes`` range."""
    kw = {}
    if damping_model is not None:
        kw["damping_model"] = SWEEP_DAMPING_MODELS[damping_model]
    if modes is not None:
        field = FIELDS["deck_n_modes" if bridge.is_continuous else "n_modes"]
        kw["n_modes"] = field.check(modes, name="--modes")
        if bridge.is_continuous:
            need = rule_mode_count(bridge.spans_m, bridge.span_EJ_Nm2, bridge.span_mu_kg_m)
            if kw["n_modes"] < need:
                warnings.warn(f"--modes: {kw['n_modes']} modes is fewer than the {need} that the rule asks for on this "
                              f"deck ({RULE_TEXT})", PlausibilityWarning, stacklevel=2)
    return dataclasses.replace(bridge, **kw) if kw else bridge


def _sweep_method(args, bridge, dz, where):
    """``(method, backend)`` of the sweep from ``--method``, ``--model`` and ``--backend``; the combinations
    a method does not take refused in one line, before any work."""
    method = args.method or ("exact" if args.model == "mlm" and not bridge.is_continuous else "rk4")
    if method == "exact" and bridge.is_continuous:
        raise InputError(f"--method: 'exact' is the closed-form MLM envelope of one simply supported span; a continuous "
                         f"deck ({len(bridge.spans_m)} spans) runs RK4 (allowed --method rk4)")
    if args.model == "dim" and method == "exact":
        raise InputError("--method: 'exact' is the closed-form MLM envelope; the DIM runs RK4 only (allowed --method rk4)")
    if method == "exact" and args.backend == "numpy":
        raise InputError("--backend: 'numpy' is the RK4 stepper's; the exact MLM envelope has one backend "
                         "(allowed with --method exact: compiled, or give --method rk4)")
    backend = None if method == "exact" else (args.backend or "compiled")
    if where == "deck" and method != "exact":
        raise InputError(f"--where: {args.where!r} needs the exact MLM envelope (--model mlm --method exact); the RK4 "
                         f"runs record one point (allowed --where midspan or x=<m>)")
    if method == "exact" and bridge.damping_ratio + dz <= 0.0 and dz == 0.0:  # the bridge's own damping is 0
        raise InputError(f"--bridge: {args.bridge!r} has zeta_pct = 0 % (damping ratio zeta); the exact MLM envelope "
                         f"needs damping > 0 % (give zeta_pct > 0 in the bridge, --delta-zeta-pct > 0, or --method rk4)")
    exact = dict(positive_for="the exact MLM envelope", remedy=", or --method rk4") if method == "exact" else {}
    lane_damping(bridge, dz, (), DZ_OPTION, **exact)  # the one check of Δζ, as typed (%), before any output
    return method, backend


#: The option of the additional damping (%); a bad value is refused naming it, in %.
DZ_OPTION = "--delta-zeta-pct"


def _delta_zeta_option(text, bridge):
    """``--delta-zeta-pct`` as a fraction (the core's unit). Only a value that is no finite number is
    refused here (naming the option and its range); the range is checked once, by the sweep's own check
    (:func:`adm_sim.integrate.sweep.lane_damping`) before the sweep prints, in %."""
    v = option_view(DZ_OPTION)
    try:
        x = float(text)
    except (TypeError, ValueError):
        x = math.nan
    if not math.isfinite(x):
        v.check(text, lo_core=-bridge.damping_ratio)  # raises the option's one line
    return v.to_core(x)


def _sweep_outputs(args, res, *, env, bridge, zeta, where, method, backend, wall, json_path, plot_path):
    """The sweep's plausibility warnings, then ``--json`` and ``--plot`` (both or neither)."""
    ia, idisp = int(res.max_acc_m_s2.argmax()), int(res.max_disp_m.argmax())
    check_response(bridge.span_m, res.max_acc_m_s2[ia], res.max_disp_m[idisp],  # warnings, not refusals
                   label=f"sweep: at {res.speeds_kmh[ia]:g} km/h", disp_label=f"sweep: at {res.speeds_kmh[idisp]:g} km/h")
    with OutputSet() as outs:  # --json and --plot: both or neither
        if json_path is not None:
            out = res.to_dict()
            out["wall_time_s"] = wall
            out["method"] = method
            if backend is not None:
                out["backend"] = backend
            out["damping_model"] = bridge.damping_model
            out["zeta_per_mode_pct"] = [100 * float(z) for z in zeta]
            out["where"] = where
            if env is not None:
                out["x_acc_m"] = env.x_acc_m.tolist()
                out["x_disp_m"] = env.x_disp_m.tolist()
                out["max_disp_midspan_m"] = env.max_disp_midspan_m.tolist()
                out["max_moment_Nm"] = env.max_moment_Nm.tolist()
            outs.write(json_path, lambda p: p.write_text(json.dumps(out, indent=1)), "--json",
                       note=f"wrote {args.json}")
        if plot_path is not None:
            outs.write(plot_path, lambda p: figures.plot_sweep(res, p, where=where), "--plot", note=f"wrote {args.plot}")


def run(args):
    """Run ``adm-sim sweep``: check every input, sweep, print the peak, write ``--json`` and ``--plot``."""
    inputs = {"--train": args.train, "--bridge": args.bridge}
    json_path = None if args.json is None else claim_output(args.json, "--json", args.overwrite, inputs=inputs)
    if json_path is not None and args.plot is not None and json_path.resolve() == Path(args.plot).resolve():
        raise InputError(f"--plot: {args.plot!r} is the --json file; give two different files")
    plot_path = None if args.plot is None else claim_output(args.plot, "--plot", args.overwrite, suffix=".png",
                                                            inputs=inputs)
    bridge = _sweep_modes(resolve_bridge(args.bridge, continuous=True), args.modes, args.damping_model)
    train = load_train(args.train)
    check_spans_for_train(bridge, train)  # before the first line of output
    speeds = parse_speeds(args.speeds, field="--speeds")
    dz = _delta_zeta_option(args.delta_zeta_pct, bridge)  # its range: lane_damping in _sweep_method
    profile = None
    if args.irregularity:
        if args.model != "dim":
            raise InputError(f"--irregularity: {args.irregularity!r} acts on the DIM's wheels; the MLM has none "
                             f"(allowed with --model dim)")
        profile = parse_irregularity(args.irregularity, bridge.span_m)  # refused beyond the model's slope and curvature
    opts = StepOptions(steps_per_period=check_option("--steps-per-period", args.steps_per_period),
                       irregularity=profile)
    where = parse_where(args.where, bridge.span_m)
    method, backend = _sweep_method(args, bridge, dz, where)
    print(bridge.describe())
    print(train.describe())
    zeta = bridge.modal_damping_ratios(dz)
    print(f"damping per mode ({bridge.damping_model}): "
          + ", ".join(f"zeta_{j} = {100 * z:.4g} %" for j, z in enumerate(zeta, start=1)))
    print("modes: " + ", ".join(f"{f:.4g} Hz ({m / 1000:.5g} t)" for f, m in
                                zip(bridge.frequencies_hz, bridge.modal_mass_kg)) + " (frequency, modal mass)")
    if where == "midspan" and bridge.is_continuous:
        print(f"midspan: x = {bridge.midspan_m:g} m, the middle of the longest span (the first of equal ones)")
    cb, close = progress_callback(f"{args.model.upper()} sweep", None if args.progress is None else args.progress)
    t0 = time.perf_counter()
    try:
        if method == "exact":
            res, env = sweep_exact(bridge, train, speeds, delta_zeta=dz, where=where, delta_zeta_name=None)
        elif backend == "compiled":
            res, env = run_sweep_compiled(bridge, train, args.model, speeds, delta_zeta=dz, options=opts, progress=cb,
                                          where=where, delta_zeta_name=None), None
        else:
            res, env = run_sweep(bridge, train, args.model, speeds, delta_zeta=dz, options=opts, progress=cb,
                                 where=where, delta_zeta_name=None), None
    finally:
        close()
    wall = time.perf_counter() - t0
    pk = res.peak()
    if env is None:
        print(f"{args.model.upper()} sweep (RK4), {where_text(where)}: {len(speeds)} speeds {speeds.min():g}..{speeds.max():g} km/h, "
              f"{res.n_steps} steps of {res.ds_m * 1000:.2f} mm, maxima at the steps, {backend} backend, {wall:.2f} s")
    else:
        print(f"MLM sweep (exact envelope: closed form, maxima refined by Newton), {where_text(where)}: {len(speeds)} "
              f"speeds {speeds.min():g}..{speeds.max():g} km/h, {wall:.2f} s")
    at = ""
    if pk is not None and env is not None and where == "deck":
        at = f", x = {env.x_acc_m[pk['index']]:.3f} m"
    if pk is None:
        i = int(res.max_acc_m_s2.argmax())
        print(f"no interior peak: the largest value {res.max_acc_m_s2[i]:.4f} m/s2 lies at the end "
              f"of the speed range ({res.speeds_kmh[i]:g} km/h)")
    else:
        print(f"peak: {pk['acc_m_s2']:.4f} m/s2 at {pk['speed_kmh']:g} km/h{at}")
        top = float(res.max_acc_m_s2.max())
        if top > pk["acc_m_s2"]:
            i = int(res.max_acc_m_s2.argmax())
            print(f"note: the largest value {top:.4f} m/s2 lies at the end of the range ({res.speeds_kmh[i]:g} km/h)")
    if res.contact is not None:  # the DIM's own assumption: every wheel stays on the rail
        lost = res.contact.message("status contact_lost")
        if lost is None:
            fmin = float(res.contact.min_n.min())
            print(f"status ok: every wheel stays on the rail (smallest contact force {fmin / 1e3:.4g} kN)")
        else:
            print(lost)
    _sweep_outputs(args, res, env=env, bridge=bridge, zeta=zeta, where=where, method=method, backend=backend, wall=wall,
                   json_path=json_path, plot_path=plot_path)
    return 0


def add_arguments(parser):
    """The options of ``adm-sim sweep``."""
    parser.add_argument("--bridge", default="B1", help="B1..B4, a spec L=15,n0=8.26,mu=19042,zeta_pct=1.85 (L m, n0 Hz or "
                   "EJ N m^2, mu kg/m, zeta_pct %% or type=cfb|sc for the Table 2 damping; class=cfb|sc classes a bridge "
                   "of given damping; spans=12/16/12 a continuous deck, EJ and mu then one value or one per span, a/b/c), or a "
                   "TOML file with these keys (spans = [..] in m)")
    parser.add_argument("--train", default="ICE-2", help="ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table, HSLM-A1..A10 (MLM only), or a TOML file")
    add_choice(parser, "--model", "mlm (default): moving loads; dim: the detailed vehicles (Detailed Interaction Model)", default="mlm")
    add_speeds(parser, "km/h, start:stop:step or a comma list")
    add_delta_zeta_pct(parser)
    add_steps_per_period(parser, "RK4 steps per period of the highest bridge mode (DIM and --method rk4)", default="16")
    parser.add_argument("--method", choices=("exact", "rk4"), default=None,
                   help="MLM: exact (default: the closed-form envelope, true maximum per speed) or rk4 (the lockstep "
                        "RK4 run, maxima sampled at its steps); the DIM is always rk4")
    parser.add_argument("--backend", choices=("compiled", "numpy"), default=None,  # adm_sim.integrate.sweep.BACKENDS
                   help="RK4 runs (the DIM, MLM --method rk4): compiled (default: the numba kernels, every speed a lane "
                        "of one run) or numpy (the numpy stepper, the reference the kernels are tested against; equal "
                        "to 1e-12)")
    parser.add_argument("--modes", default=None,
                   help=option_help("--modes", "retained modes (default: the bridge's: 3 for one span, the rule's "
                                               "count for a continuous deck: every mode up to 30 Hz, 1.5 n0 or the "
                                               "third); a continuous deck takes up to 50; one span"))
    parser.add_argument("--damping-model", choices=tuple(SWEEP_DAMPING_MODELS), default=None,
                   help="damping per mode: rayleigh13 (Rayleigh anchored at modes 1 and 3) or modal (zeta on every "
                        "mode); default: the bridge's (rayleigh13 unless its file says modal)")
    parser.add_argument("--where", default="midspan",
                   help="midspan (default; a continuous deck: the middle of its longest span), deck (MLM exact: "
                        "anywhere on the deck, with the position) or x=<m> from the left abutment (0 < x < L, L the "
                        "deck length)")
    add_max_work(parser)
    parser.add_argument("--irregularity", default="",
                   help="DIM: track irregularity on the deck, e.g. german-high:seed=3, file=profile.csv, "
                        "joint:at=7:length=1:depth=0.002 (parts joined by +; docs/irregularities.md); default: smooth")
    add_output_options(parser, {"json": "write results as JSON", "plot": "write max acceleration vs speed as PNG"},
                    "replace existing --json/--plot files (once the run has finished)")
