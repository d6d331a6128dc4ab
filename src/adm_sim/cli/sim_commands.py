"""``adm-sim``: speed sweeps, train data checks, kernel compilation and MCAP salvage from the command line.

Errors are one line ``error: ...`` on stderr: bad input exits with code 2, a run that fails for
another reason (e.g. an integration that became unstable) with 1, an interrupt with 130
(:func:`adm_sim.cliutil.run_cli`). Mass per length is kg/m in and out (t/m shown beside it).
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

from adm_sim.cliutil import (Parser, add_choice, add_delta_zeta_pct, add_max_work, add_overwrite, add_progress, add_speeds,
                             add_steps_per_period, check_option, option_help, option_view,
                             progress_callback)
from adm_sim.errors import InputError
from adm_sim.cliutil import freeze_at_exit, run_cli
from adm_sim.fields import FIELDS
from adm_sim.files import OutputSet, claim_output, mcap_input
from adm_sim.inputs.measured import add_measured_argument
from adm_sim.cli.figures import plot_check, plot_sweep
from adm_sim.limits import ACC_LIMITS_M_S2, TRACK_ALIASES, check_track_type
from adm_sim.integrate.where import parse_where, where_text
from adm_sim.integrate import _jit


#: ``--damping-model`` of sweep and check -> ``Bridge.damping_model`` (as adm_sim.design.check.DAMPING_MODELS).
SWEEP_DAMPING_MODELS = {"rayleigh13": "rayleigh", "modal": "modal"}


def _sweep_modes(bridge, modes, damping_model):
    """The bridge with ``--modes`` and ``--damping-model`` applied (None: the bridge's own). A
    continuous deck takes up to 50 modes (fewer than its rule asks: a warning naming the rule), one
    span the registry's ``n_modes`` range."""
    import dataclasses  # noqa: PLC0415
    import warnings  # noqa: PLC0415

    kw = {}
    if damping_model is not None:
        kw["damping_model"] = SWEEP_DAMPING_MODELS[damping_model]
    if modes is not None:
        field = FIELDS["deck_n_modes" if bridge.is_continuous else "n_modes"]
        kw["n_modes"] = field.check(modes, name="--modes")
        if bridge.is_continuous:
            from adm_sim.model.spans import RULE_TEXT, rule_mode_count  # noqa: PLC0415

            need = rule_mode_count(bridge.spans_m, bridge.span_EJ_Nm2, bridge.span_mu_kg_m)
            if kw["n_modes"] < need:
                from adm_sim.errors import PlausibilityWarning  # noqa: PLC0415

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
    from adm_sim.integrate.sweep import lane_damping  # noqa: PLC0415  start-up: only this subcommand (52 ms)

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


def _sweep_outputs(args, res, env, bridge, zeta, where, method, backend, wall, json_path, plot_path):
    """The sweep's plausibility warnings, then ``--json`` and ``--plot`` (both or neither)."""
    from adm_sim.model.plausibility import check_response  # noqa: PLC0415  start-up: only this subcommand (7 ms)

    ia, idisp = int(res.max_acc_m_s2.argmax()), int(res.max_disp_m.argmax())
    check_response(bridge.span_m, res.max_acc_m_s2[ia], res.max_disp_m[idisp],  # warnings, not refusals
                   f"sweep: at {res.speeds_kmh[ia]:g} km/h", f"sweep: at {res.speeds_kmh[idisp]:g} km/h")
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
            outs.write(plot_path, lambda p: plot_sweep(res, p, where=where), "--plot", note=f"wrote {args.plot}")


def cmd_sweep(args):
    from adm_sim.inputs.bridges import resolve_bridge  # noqa: PLC0415  start-up: only this subcommand (20 ms)
    from adm_sim.integrate.step_grid import StepOptions  # noqa: PLC0415  start-up: only this subcommand (6 ms)
    from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled, sweep_exact  # noqa: PLC0415  start-up: only this subcommand (52 ms)
    from adm_sim.inputs.speeds import parse_speeds  # noqa: PLC0415  start-up: only this subcommand (52 ms)
    from adm_sim.inputs.train_files import load_train  # noqa: PLC0415  start-up: only this subcommand (58 ms)

    inputs = {"--train": args.train, "--bridge": args.bridge}
    json_path = None if args.json is None else claim_output(args.json, "--json", args.overwrite, inputs=inputs)
    if json_path is not None and args.plot is not None and json_path.resolve() == Path(args.plot).resolve():
        raise InputError(f"--plot: {args.plot!r} is the --json file; give two different files")
    plot_path = None if args.plot is None else claim_output(args.plot, "--plot", args.overwrite, ".png", inputs)
    bridge = _sweep_modes(resolve_bridge(args.bridge, continuous=True), args.modes, args.damping_model)
    train = load_train(args.train)
    speeds = parse_speeds(args.speeds, field="--speeds")
    dz = _delta_zeta_option(args.delta_zeta_pct, bridge)  # its range: lane_damping in _sweep_method
    profile = None
    if args.irregularity:
        if args.model != "dim":
            raise InputError(f"--irregularity: {args.irregularity!r} acts on the DIM's wheels; the MLM has none "
                             f"(allowed with --model dim)")
        from adm_sim.inputs.track_profile import parse_irregularity  # noqa: PLC0415  scipy.interpolate only on a rough track

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
    _sweep_outputs(args, res, env, bridge, zeta, where, method, backend, wall, json_path, plot_path)
    return 0


def _check_job(args):
    """The job (:class:`adm_sim.inputs.job.Job`: ``--job`` file, the identification options over it)
    and the bridge and trains specs (the options over the job file's, else B1 and hslm)."""
    from adm_sim.inputs.job import Job, job_from_options, read_job_file  # noqa: PLC0415  start-up: only this subcommand

    names = ("project", "structure", "element", "author", "checker", "revision", "date")
    given = job_from_options({k: getattr(args, k, None) for k in names})
    job = read_job_file(args.job) if getattr(args, "job", None) is not None else Job()
    job = Job(fields={**job.fields, **given.fields}, bridge=job.bridge, trains=job.trains, path=job.path)
    bridge = args.bridge if args.bridge is not None else job.bridge if job.bridge is not None else "B1"
    trains = args.trains if args.trains is not None else job.trains if job.trains is not None else "hslm"
    return job, bridge, trains


def _check_tables(args, inputs):
    """``--tables DIR``: checked (and its files claimed) before any work; None without it."""
    text = getattr(args, "tables", None)
    if text is None:
        return None
    from adm_sim.design.check_report import TABLE_NAMES  # noqa: PLC0415  start-up: only this subcommand
    from adm_sim.files import check_output_folder  # noqa: PLC0415

    names = [f"{n}.csv" for n in TABLE_NAMES]
    out = check_output_folder(text, "--tables", names, inputs)
    if out.is_dir():
        for n in names:
            claim_output(str(out / n), "--tables", args.overwrite, ".csv", inputs)
    return out


def _write_check_outputs(args, res, outs, pdf, tables, job, sources, measured, wall):
    """The check's files: ``--json``, ``--csv``, ``--plot``, ``--report`` and ``--tables``, all or none."""
    with OutputSet() as files:  # --json, --csv, --plot, --report: all or none
        if "json" in outs:
            d = res.to_dict()
            d["wall_time_s"] = wall
            if measured is not None:
                d["measured"] = measured.to_dict()
            from adm_sim.design.check_defaults import defaults_dict  # noqa: PLC0415  start-up: only with --json

            d.update(defaults_dict())
            d["job"] = job.to_dict()
            d["inputs"] = [{"input": k, "value": v, "source": s} for k, v, s in sources]
            files.write(outs["json"], lambda p: p.write_text(json.dumps(d, indent=1)), "--json",
                        note=f"wrote {args.json}")
        if "csv" in outs:
            files.write(outs["csv"], res.write_csv, "--csv", note=f"wrote {args.csv}")
        if "plot" in outs:
            files.write(outs["plot"], lambda p: plot_check(res, p), "--plot", note=f"wrote {args.plot}")
        if "report" in outs:
            from adm_sim.design.check_report import write_pdf, write_report  # noqa: PLC0415  start-up: only this subcommand (138 ms)

            write = write_pdf if pdf else write_report
            files.write(outs["report"], lambda p: write(res, p, job=job, sources=sources), "--report",
                        note=f"wrote {args.report}")
        if tables is not None:
            from adm_sim.design.check_report import write_tables  # noqa: PLC0415  start-up: only this subcommand
            from adm_sim.files import make_output_folder  # noqa: PLC0415  start-up: only with --tables

            make_output_folder(tables, "--tables")
            write_tables(res, tables, job=job, sources=sources, outs=files)
            print(f"wrote the tables to {args.tables}")


def _check_outputs(args, inputs):
    """``--json``, ``--csv``, ``--plot``, ``--report`` claimed before any work: ``({option: path}, pdf)``."""
    outs, seen = {}, {}
    for opt, suffix in (("json", None), ("csv", ".csv"), ("plot", ".png"), ("report", None)):
        text = getattr(args, opt, None)
        if text is not None:
            if str(text).strip() and Path(text).resolve() in seen:
                raise InputError(f"--{opt}: {text!r} is the --{seen[Path(text).resolve()]} file; give different files")
            outs[opt] = claim_output(text, f"--{opt}", args.overwrite, suffix, inputs)
            if opt == "report" and outs[opt].suffix.lower() not in (".html", ".pdf"):
                raise InputError(f"--report: {text!r} must end with .html or .pdf")
            seen[outs[opt].resolve()] = opt
    pdf = "report" in outs and outs["report"].suffix.lower() == ".pdf"
    if pdf:
        from adm_sim.design.check_report import find_chromium  # noqa: PLC0415  start-up: only this subcommand
        from adm_sim.errors import RunError  # noqa: PLC0415  start-up: only with a PDF report

        if find_chromium() is None:
            raise RunError(f"--report {args.report}: no headless Chromium on this machine (chromium not on PATH); "
                           f"write --report X.html and print it to PDF from a browser")
    return outs, pdf


def _check_trains(args, trains_spec, bridge):
    """The trains of ``--trains``; ``--irregularity`` and ``--comfort`` refused before any work when no train
    has vehicles, named by their flags."""
    from adm_sim.design.check import resolve_trains  # noqa: PLC0415  start-up: only this subcommand

    trains = resolve_trains(trains_spec)
    if args.irregularity is not None:  # refused before any work, named by its flag
        from adm_sim.design.check_rough import check_spec  # noqa: PLC0415  start-up: only with --irregularity

        check_spec(args.irregularity, args.seeds, bridge.span_m)
        if not any(t.units for t in trains):
            raise InputError(f"--irregularity: the trains checked ({', '.join(t.name for t in trains)}) have no "
                             f"vehicles; the rough-track DIM needs a real train (add ICE-2, Eurostar, Railjet, ICE-4 or "
                             f"a .toml train to --trains)")
    if args.comfort and not any(t.units for t in trains):  # comfort is computed for trains with vehicles only
        raise InputError(f"--comfort: the trains checked ({', '.join(t.name for t in trains)}) are load models "
                         f"without vehicles; passenger comfort b_v needs the DIM of a real train (add ICE-2, "
                         f"Eurostar, Railjet, ICE-4 or a .toml train to --trains) or omit --comfort")
    return trains


def cmd_check(args, damping_provider=None):
    """EN 1991-2 dynamic check (:mod:`adm_sim.design.check`). ``--damping none|adm`` are the core's;
    ``lb|vbi`` need adm-calib's ``damping_provider`` (``adm-calib check`` passes it) and are refused
    here, before any work, without one. The core never imports adm_calib."""
    from adm_sim.inputs.bridges import resolve_bridge  # noqa: PLC0415  start-up: only this subcommand (20 ms)
    from adm_sim.design.check import CALIB_DAMPING_METHODS, DAMPING_MODELS, calib_methods_refusal, run_check  # noqa: PLC0415  start-up: only this subcommand (114 ms)
    from adm_sim.design.check_text import summary as check_summary  # noqa: PLC0415  start-up: only this subcommand (138 ms)

    if args.damping in CALIB_DAMPING_METHODS and damping_provider is None:
        raise calib_methods_refusal(args.damping)
    job, bridge_spec, trains_spec = _check_job(args)
    inputs = ([("--job", str(job.path))] if job.path is not None else []) + [
        ("--bridge", bridge_spec if isinstance(bridge_spec, str) else ""),
        ("--measured", getattr(args, "measured", None))] + [
        ("--trains", t.strip()) for t in str(trains_spec).split(",")]
    outs, pdf = _check_outputs(args, inputs)
    tables = _check_tables(args, inputs)
    if isinstance(bridge_spec, dict):
        from adm_sim.inputs.bridges import bridge_from_mapping  # noqa: PLC0415  start-up: only with a job file

        bridge = bridge_from_mapping(bridge_spec, source=f"--job {job.path}: [bridge]")
    else:
        bridge = resolve_bridge(bridge_spec, continuous=True)  # a continuous deck: adm_sim.design.check_deck
    if bridge.is_continuous:
        _refuse_on_deck(args, tables)
    from adm_sim.inputs.measured import measured_bridge  # noqa: PLC0415  start-up: only this subcommand

    bridge, measured = measured_bridge(args, bridge)  # --measured: n0, zeta (and EJ) of the monitored bridge
    parse_where(args.where, bridge.span_m)  # refused before any work
    if args.damping_model is not None and args.damping_model not in DAMPING_MODELS:
        raise InputError(f"--damping-model: {args.damping_model!r} is not allowed; allowed {', '.join(DAMPING_MODELS)}")
    trains = _check_trains(args, trains_spec, bridge)
    if args.lateral_frequency is not None:
        from adm_sim.design.check_sls import check_lateral_frequency  # noqa: PLC0415  start-up: only this subcommand (16 ms)

        try:  # refused before any work, named by its flag
            check_lateral_frequency(args.lateral_frequency)
        except InputError as exc:
            raise InputError("--lateral-frequency" + str(exc)[len("lateral_frequency"):]) from None
    from adm_sim.design.check import parse_bounds  # noqa: PLC0415  start-up: only this subcommand (114 ms)

    mass_bounds, stiffness_bounds = (parse_bounds(getattr(args, k), f"--{k.replace('_', '-')}")
                                     for k in ("mass_bounds", "stiffness_bounds"))
    ballast = None if args.ballast is None else parse_bounds(f"standard:{args.ballast}", "--ballast")
    deck_end_height = None
    if args.deck_end_height is not None:
        from adm_sim.design.check_sls import check_deck_end_height  # noqa: PLC0415  start-up: only this subcommand

        deck_end_height = check_deck_end_height(args.deck_end_height, "--deck-end-height")
    track = check_track_type("--track", args.track, aliases=True)  # one vocabulary: direct -> direct_fastening
    cb, close = progress_callback("check", None if args.progress is None else args.progress)
    t0 = time.perf_counter()
    try:
        if bridge.is_continuous:
            res = _run_deck_check(args, bridge, trains, track, cb, deck_end_height)
        else:
            res = run_check(bridge, args.max_line_speed, trains, track=track, damping=args.damping,
                            step_kmh=args.speed_step, progress=cb, comfort=args.comfort, n_modes=args.modes,
                            where=args.where, damping_model=args.damping_model,
                            track_maintenance=args.track_maintenance, alpha=args.alpha,
                            damping_provider=damping_provider, lateral_frequency_hz=args.lateral_frequency,
                            mass_bounds=mass_bounds, stiffness_bounds=stiffness_bounds,
                            deck_end_height_m=deck_end_height, ballast=ballast, irregularity=args.irregularity,
                            seeds=args.seeds)
    finally:
        close()
    wall = time.perf_counter() - t0
    _check_plausible(res)
    from adm_sim.inputs.job import input_sources  # noqa: PLC0415  start-up: only this subcommand

    sources = input_sources(bridge_spec, trains_spec, trains)
    for line in job.lines():
        print(line)
    print(res.summary() if getattr(res, "is_deck", False) else check_summary(res))
    print(f"{len(trains)} trains, {wall:.2f} s")
    _write_check_outputs(args, res, outs, pdf, tables, job, sources, measured, wall)
    return 0


#: Options of the check not wired for a continuous deck (adm_sim.design.check_deck), with the reason.
DECK_REFUSED = (("measured", "the monitored bridge's n0 and zeta are of one span"),
                ("comfort", "the DIM's passenger comfort is not wired for a continuous deck"),
                ("irregularity", "the rough-track DIM is not wired for a continuous deck"),
                ("mass_bounds", "mass bounds are not wired for a continuous deck"),
                ("stiffness_bounds", "stiffness bounds are not wired for a continuous deck"),
                ("ballast", "mass bounds are not wired for a continuous deck"))


def _refuse_on_deck(args, tables):
    """One line for an option the deck check does not take, before any work."""
    for key, why in DECK_REFUSED:
        if getattr(args, key, None) not in (None, False):
            raise InputError(f"--{key.replace('_', '-')}: {getattr(args, key)!r} is refused on a continuous deck "
                             f"({why}); omit it")
    if tables is not None:
        raise InputError(f"--tables: {args.tables!r}: the report's tables are of one span; on a continuous deck "
                         f"write --json or --report")
    if args.damping != "none":
        raise InputError(f"--damping: {args.damping!r} is not wired for a continuous deck (the Eurocode ADM of EN "
                         f"1991-2 6.4.6.3.1 and the paper's additional damping are for simply supported spans, our "
                         f"reading); allowed --damping none")


def _run_deck_check(args, bridge, trains, track, progress, deck_end_height):
    """The check of a continuous deck (:func:`adm_sim.design.check_deck.run_deck_check`)."""
    from adm_sim.design.check_deck import run_deck_check  # noqa: PLC0415  start-up: only on a continuous deck

    return run_deck_check(bridge, args.max_line_speed, trains, track=track, step_kmh=args.speed_step,
                          progress=progress, n_modes=args.modes, where=args.where, damping_model=args.damping_model,
                          track_maintenance=args.track_maintenance, alpha=args.alpha,
                          lateral_frequency_hz=args.lateral_frequency, deck_end_height_m=deck_end_height)


def _check_plausible(res):
    """Plausibility warnings on a check's results: the largest acceleration and deflection over all
    trains and speeds, each named by its train and speed (:mod:`adm_sim.model.plausibility`)."""
    from adm_sim.model.plausibility import check_response  # noqa: PLC0415  start-up: only this subcommand (7 ms)

    if not res.trains:
        return
    acc = max((float(c.max_acc_m_s2.max()), c.name, float(c.speeds_kmh[int(c.max_acc_m_s2.argmax())]))
              for c in res.trains)
    disp = max((float(c.max_disp_m.max()), c.name, float(c.speeds_kmh[int(c.max_disp_m.argmax())]))
               for c in res.trains)
    check_response(res.bridge.span_m, acc[0], disp[0], f"check: {acc[1]} at {acc[2]:g} km/h",
                   f"check: {disp[1]} at {disp[2]:g} km/h")


def cmd_trains(args):
    from adm_sim.fields import AXLE_LOAD_REL_TOL  # noqa: PLC0415  start-up: only this subcommand (58 ms)
    from adm_sim.model.trains import TRAIN_NAMES, consistency_rows  # noqa: PLC0415  start-up: only this subcommand (58 ms)
    from adm_sim.inputs.train_files import load_train  # noqa: PLC0415  start-up: only this subcommand (58 ms)

    if args.train is not None and not args.train.strip():
        raise InputError("--train: '' is empty; give a train name or a TOML train file (or omit --train for all)")
    names = [args.train] if args.train else list(TRAIN_NAMES) + ["Eurostar-table"]
    bad = 0
    for name in names:
        t = load_train(name)
        print(t.describe())
        if t.description:
            print(f"  {t.description}")
        if args.check:
            for r in consistency_rows(t, rel_tol=AXLE_LOAD_REL_TOL):
                flag = "ok " if r.ok else "MISMATCH"
                print(f"  {flag:8s} {r.item:42s} table {r.table_value:9.3f} {r.unit:3s} "
                      f"computed {r.computed_value:9.3f} {r.unit:3s}  ({r.note})")
                bad += not r.ok
    if args.check:
        print("MLM axle loads: the F column of Table A1 (per bogie for Jacobs sets), the same static "
              "loads the DIM carries; see the train files for choices made.")
        if bad:
            print(f"{bad} check(s) disagree with the paper's numbers (documented in the train files).")
    return 0


def cmd_bridges(args):
    from adm_sim.model.bridge import TABLE3, named_bridge, parametric_field  # noqa: PLC0415  start-up: only this subcommand (20 ms)

    if args.field:
        field = parametric_field()
        print(f"parametric field: {len(field)} bridges (Section 3.3); mu in kg/m and t/m", file=sys.stderr)
        print("name,span_m,n0_hz,mu_kg_m,mu_t_m,EJ_Nm2,zeta_pct,type")
        for b in field:
            print(f"{b.name},{b.span_m:g},{b.n0_hz:.4f},{b.mass_per_length_kg_m:.1f},{b.mass_per_length_kg_m / 1000:.4f},"
                  f"{b.EJ_Nm2:.5g},{b.damping_ratio * 100:.4g},{b.bridge_type}")
    else:
        for name in TABLE3:
            print(named_bridge(name).describe())
    return 0


def cmd_salvage(args):
    try:
        from adm_sim.recording.mcap_log import salvage  # noqa: PLC0415  start-up: only this subcommand (28 ms)
    except ImportError as exc:
        raise InputError(f"salvage needs the ROS/MCAP extras ({exc})") from None
    src = mcap_input(args.src, "salvage SRC", damaged_magic=True)  # a damaged magic is what salvage is for
    if Path(args.dst).resolve() == src.resolve():
        raise InputError(f"salvage DST: {args.dst!r} is SRC; give another file")
    dst = claim_output(args.dst, "salvage DST", args.overwrite, ".mcap")
    report = {}
    n = salvage(src, dst, overwrite=args.overwrite, report=report)
    print(f"recovered {n} messages into {args.dst}")
    if report.get("lost_chunks") or report.get("orphan_messages"):
        print(f"lost: {report['lost_chunks']} of {report['chunks']} chunks were damaged and skipped"
              + (f", {report['orphan_messages']} messages of channels declared in them" if report["orphan_messages"]
                 else ""))
    for line in report.get("damage", ()):  # each damaged place: offset, topics, messages lost (or none)
        print(f"{'damaged' if line.endswith('no message lost') else 'dropped'}: {line}")
    return 0


def cmd_compile(args):
    """Compile every numba kernel once (:mod:`adm_sim.cli.precompile`), at set-up rather than in the first
    real command; with numba's cache in place it only loads the kernels."""
    from adm_sim.cli.precompile import compile_kernels  # noqa: PLC0415  start-up: only this subcommand (113 ms)

    if not _jit.numba_available():
        print("numba is not installed: the kernels run as plain Python, nothing to compile")
        return 0
    print("compiling kernels (once): every code path on a tiny case; numba keeps the machine code in __pycache__ "
          "beside the source (15-60 s the first time on a quiet 2-core machine, a few seconds once cached)",
          file=sys.stderr, flush=True)
    _jit.notice_given()
    total = compile_kernels(report=lambda name, s: print(f"  {name}: {s:.2f} s", flush=True))
    print(f"kernels ready in {total:.2f} s; later runs load them from the cache")
    return 0


def _output_options(parser, outputs, overwrite_help):
    """The output files (``--json`` etc., each with its help), ``--overwrite`` and ``--progress``."""
    for name, text in outputs.items():
        parser.add_argument(f"--{name}", help=text)
    add_overwrite(parser, overwrite_help)
    add_progress(parser)


def add_check_arguments(c):
    """The options of the EN 1991-2 check, one definition for ``adm-sim check`` and ``adm-calib check``
    (``--damping lb|vbi`` are computed only by ``adm-calib check``)."""
    c.add_argument("--bridge", default=None, help="B1..B4 (default B1), a spec L=15,n0=8.26,mu=19042,zeta_pct=1.85, a "
                                                  "continuous deck spans=12/16/12,EJ=..,mu=..,zeta_pct=.. (1-6 spans), or "
                                                  "a TOML file; or the job file's bridge")
    add_measured_argument(c)
    c.add_argument("--max-line-speed", type=float, required=True,
                   help=option_help("--max-line-speed", "maximum line speed V; speeds 40 m/s .. 1.2 V are checked"))
    c.add_argument("--trains", default=None,
                   help="comma list: hslm (HSLM-A1..A10), HSLM-Ak, HSLM-B:N=<forces>:d=<spacing m> (spans "
                        "under 7 m; N and d from EN 1991-2 Fig. E.8), ICE-2, Eurostar, Railjet, ICE-4, .toml files")
    c.add_argument("--track", choices=(*ACC_LIMITS_M_S2, *TRACK_ALIASES), default="ballasted",
                   help="deck acceleration limit, EN 1990 A2.4.4.2.1: "
                        + ", ".join(f"{a:g} m/s2 {t}" for t, a in ACC_LIMITS_M_S2.items())
                        + "".join(f" ({k} = {v})" for k, v in TRACK_ALIASES.items()))
    c.add_argument("--damping", choices=FIELDS["damping"].choices, default="none",
                   help="additional damping: none, Eurocode ADM (EN 1991-2 6.4.6.3.1), the paper's lower bounds or the "
                        "calibrated VBI (lb and vbi: adm-calib check only)")
    c.add_argument("--where", default="deck",
                   help="where the acceleration is taken: deck (default: anywhere on the deck, with the position, "
                        "EN 1990 A2.4.4.2.1), midspan, or x=<m> (0 < x < L)")
    c.add_argument("--track-maintenance", default=None,
                   help="EN 1991-2 6.4.5.2 track maintenance for the LM71 dynamic factor of the 6.4.6.5(3) "
                        "comparison: standard (Phi3 with phi'', the default: 6.4.5.2(3)P, where no dynamic factor "
                        "is specified) or careful (Phi2 with phi''/2)")
    c.add_argument("--alpha", default="1.0",
                   help="LM71 classification factor alpha, EN 1991-2 6.3.2(3): 0.75, 0.83, 0.91, 1.00 (default), "
                        "1.10, 1.21, 1.33, 1.46")
    c.add_argument("--damping-model", default="modal",
                   help="damping per mode: modal (default: zeta on every mode, what EN 1991-2 6.4.6.3.1 implies) or "
                        "rayleigh13 (Rayleigh anchored at modes 1 and 3; mode 2 gets 0.625 zeta with 3 modes)")
    c.add_argument("--lateral-frequency", default=None,
                   help="first lateral natural frequency of the span (Hz), checked against 1.2 Hz "
                        "(EN 1990 A2.4.4.2.4(3)); not checked without it")
    c.add_argument("--mass-bounds", default=None,
                   help="lower,upper bound of the mass per length as fractions of the nominal (write "
                        "--mass-bounds=-0.1,0.15; EN 1991-2 6.4.6.3.2), or standard:B,RHO[,RHO_MAX] for the "
                        "standard's bounds from B kg/m of ballast at RHO kg/m3: the check runs at each, the verdict "
                        "is the envelope")
    c.add_argument("--ballast", default=None,
                   help="B,RHO: the ballast in the nominal mass per length (B kg/m at RHO kg/m3); turns the mass "
                        "bounds of EN 1991-2 6.4.6.3.2 on (lower 1700 kg/m3; upper 2100 kg/m3 and +30 %% depth, the "
                        "project's choice) unless --mass-bounds is given")
    c.add_argument("--deck-end-height", default=None,
                   help="h (m): height from the bearings' axis of rotation to the top of the deck; checks the "
                        "deck-end displacement delta_H = theta h of EN 1991-2 6.5.4.5.2 (8 / 10 mm); not checked "
                        "without it")
    c.add_argument("--stiffness-bounds", default=None,
                   help="lower,upper bound of the bending stiffness EJ as fractions of the nominal "
                        "(--stiffness-bounds=-0.1,0; EN 1991-2 6.4.6.3.3)")
    c.add_argument("--speed-step", type=float, default=1.0, help=option_help("--speed-step", "speed step"))
    c.add_argument("--modes", type=float,
                   help=option_help("--modes", "more modes than EN 1990 A2.4.4.2.1 asks for; default: exactly those"))
    c.add_argument("--comfort", action="store_true",
                   help="also run the DIM of the real trains: passenger comfort b_v (EN 1990 A2.4.4.3)")
    c.add_argument("--irregularity", default=None,
                   help="beyond the standard: also run the DIM of the real trains on a rough track of this spectrum "
                        "(german-low, german-high, fra-1..fra-6, iso-a..iso-h[:band=LO:HI]), one profile per seed, "
                        "midspan acceleration per seed beside the smooth check (docs/irregularities.md)")
    c.add_argument("--seeds", default="1", help="with --irregularity: the profiles of seeds 1..N (1..20, default 1)")
    c.add_argument("--job", default=None,
                   help="TOML job file: a [job] table with project, structure, element, author, checker, revision, "
                        "date (all required), and optionally bridge and trains (docs/check.md)")
    for name in ("project", "structure", "element", "author", "checker", "revision", "date"):
        c.add_argument(f"--{name}", default=None,
                       help=f"the job's {name}, printed on the report's first lines (overrides the job file's)")
    c.add_argument("--tables", default=None, help="write every table of the report as CSV into this folder "
                                                 "(job, inputs, verdict, governing, trains, effects, bounds, defaults, "
                                                 "not_checked)")
    _output_options(c, {"json": "write the verdict and every curve as JSON",
                        "csv": "write every curve as CSV (train, speed, acc and its position, disp, midspan moment, "
                               "zeta per mode)",
                        "plot": "write the acceleration envelopes as PNG",
                        "report": "write the report: X.html one self-contained page (inline figures, no network), "
                                  "X.pdf the same printed by headless Chromium: identification, inputs and their "
                                  "sources, verdict per clause, envelopes, governing cases, defaults, what is not "
                                  "checked"},
                    "replace existing output files (once the check has finished)")


def build_parser():
    p = Parser(prog="adm-sim", description=__doc__.splitlines()[0], name_prog=True)
    p.add_version()
    sub = p.add_subparsers(dest="cmd", required=True)

    s = sub.add_parser("sweep", help="max midspan acceleration over a speed range")
    s.add_argument("--bridge", default="B1", help="B1..B4, a spec L=15,n0=8.26,mu=19042,zeta_pct=1.85 (L m, n0 Hz or "
                   "EJ N m^2, mu kg/m, zeta_pct %% or type=cfb|sc for the Table 2 damping; class=cfb|sc classes a bridge "
                   "of given damping; spans=12/16/12 a continuous deck, EJ and mu then one value or one per span, a/b/c), or a "
                   "TOML file with these keys (spans = [..] in m)")
    s.add_argument("--train", default="ICE-2", help="ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table, HSLM-A1..A10 (MLM only), or a TOML file")
    add_choice(s, "--model", "mlm (default): moving loads; dim: the detailed vehicles (Detailed Interaction Model)", default="mlm")
    add_speeds(s, "km/h, start:stop:step or a comma list")
    add_delta_zeta_pct(s)
    add_steps_per_period(s, "RK4 steps per period of the highest bridge mode (DIM and --method rk4)", default="16")
    s.add_argument("--method", choices=("exact", "rk4"), default=None,
                   help="MLM: exact (default: the closed-form envelope, true maximum per speed) or rk4 (the lockstep "
                        "RK4 run, maxima sampled at its steps); the DIM is always rk4")
    s.add_argument("--backend", choices=("compiled", "numpy"), default=None,  # adm_sim.integrate.sweep.BACKENDS
                   help="RK4 runs (the DIM, MLM --method rk4): compiled (default: the numba kernels, every speed a lane "
                        "of one run) or numpy (the numpy stepper, the reference the kernels are tested against; equal "
                        "to 1e-12)")
    s.add_argument("--modes", default=None,
                   help=option_help("--modes", "retained modes (default: the bridge's: 3 for one span, the rule's "
                                               "count for a continuous deck: every mode up to 30 Hz, 1.5 n0 or the "
                                               "third); a continuous deck takes up to 50; one span"))
    s.add_argument("--damping-model", choices=tuple(SWEEP_DAMPING_MODELS), default=None,
                   help="damping per mode: rayleigh13 (Rayleigh anchored at modes 1 and 3) or modal (zeta on every "
                        "mode); default: the bridge's (rayleigh13 unless its file says modal)")
    s.add_argument("--where", default="midspan",
                   help="midspan (default; a continuous deck: the middle of its longest span), deck (MLM exact: "
                        "anywhere on the deck, with the position) or x=<m> from the left abutment (0 < x < L, L the "
                        "deck length)")
    add_max_work(s)
    s.add_argument("--irregularity", default="",
                   help="DIM: track irregularity on the deck, e.g. german-high:seed=3, file=profile.csv, "
                        "joint:at=7:length=1:depth=0.002 (parts joined by +; docs/irregularities.md); default: smooth")
    _output_options(s, {"json": "write results as JSON", "plot": "write max acceleration vs speed as PNG"},
                    "replace existing --json/--plot files (once the run has finished)")
    s.set_defaults(func=cmd_sweep)

    c = sub.add_parser("check", help="EN 1991-2 dynamic check: envelopes of HSLM-A and real trains, verdict "
                                     "(--damping lb|vbi: adm-calib check)")
    add_check_arguments(c)
    c.set_defaults(func=cmd_check)

    t = sub.add_parser("trains", help="list trains; --check compares axle loads and bogie frequencies")
    t.add_argument("--train", help="one train: a name or a TOML train file (default: all)")
    t.add_argument("--check", action="store_true", help="axle loads (kN) against the masses (kg) times g, bogie frequencies (Hz)")
    t.set_defaults(func=cmd_trains)

    b = sub.add_parser("bridges", help="list bridges B1-B4 or (--field) the 1110-bridge parametric field")
    b.add_argument("--field", action="store_true", help="the parametric field as CSV (mu in kg/m and t/m)")
    b.set_defaults(func=cmd_bridges)

    k = sub.add_parser("compile", help="compile the numba kernels once, ahead of the first run (set-up)")
    k.set_defaults(func=cmd_compile)

    v = sub.add_parser("salvage", help="recover a killed run's MCAP log")
    v.add_argument("src")
    v.add_argument("dst")
    add_overwrite(v, "replace an existing DST")
    v.set_defaults(func=cmd_salvage)
    return p


def main(argv=None):
    def work():
        args = build_parser().parse_args(argv)
        return args.func(args)

    if argv is None:  # the process's own command line: its exit skips the last garbage collections
        freeze_at_exit()
    return run_cli(work)


if __name__ == "__main__":
    sys.exit(main())
