"""``adm-sim check``: the EN 1991-2 dynamic check of a bridge, its verdict, report and tables.

The options (:func:`add_arguments`) are one definition for ``adm-sim check`` and ``adm-calib check``
(:mod:`adm_calib.cli.check`, which hands :func:`run` the damping methods ``lb`` and ``vbi``); the
computation is :mod:`adm_sim.design.check` (one span) and :mod:`adm_sim.design.check_deck` (a
continuous deck).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from adm_sim.cli import figures
from adm_sim.cli.options import add_output_options
from adm_sim.cliutil import option_help, progress_callback
from adm_sim.design.check import (CALIB_DAMPING_METHODS, DAMPING_MODELS, calib_methods_refusal, parse_bounds,
                                  resolve_trains, run_check)
from adm_sim.design import check_report
from adm_sim.design.check_defaults import defaults_dict
from adm_sim.design.check_rough import check_spec
from adm_sim.design.check_sls import check_deck_end_height, check_lateral_frequency
from adm_sim.design.check_text import summary as check_summary
from adm_sim.errors import InputError, RunError
from adm_sim.fields import FIELDS
from adm_sim.files import OutputSet, check_output_folder, claim_output, make_output_folder
from adm_sim.inputs.bridges import bridge_from_mapping, resolve_bridge
from adm_sim.inputs.job import Job, input_sources, job_from_options, read_job_file
from adm_sim.inputs.measured import add_measured_argument, measured_bridge
from adm_sim.integrate.where import parse_where
from adm_sim.limits import ACC_LIMITS_M_S2, TRACK_ALIASES, check_track_type
from adm_sim.model.plausibility import check_response


def _check_job(args):
    """The job (:class:`adm_sim.inputs.job.Job`: ``--job`` file, the identification options over it)
    and the bridge and trains specs (the options over the job file's, else B1 and hslm)."""
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
    names = [f"{n}.csv" for n in check_report.TABLE_NAMES]
    out = check_output_folder(text, "--tables", names, inputs)
    if out.is_dir():
        for n in names:
            claim_output(str(out / n), "--tables", args.overwrite, ".csv", inputs)
    return out


def _write_check_outputs(args, res, *, outs, pdf, tables, job, sources, measured, wall):
    """The check's files: ``--json``, ``--csv``, ``--plot``, ``--report`` and ``--tables``, all or none."""
    with OutputSet() as files:  # --json, --csv, --plot, --report: all or none
        if "json" in outs:
            d = res.to_dict()
            d["wall_time_s"] = wall
            if measured is not None:
                d["measured"] = measured.to_dict()
            d.update(defaults_dict())
            d["job"] = job.to_dict()
            d["inputs"] = [{"input": k, "value": v, "source": s} for k, v, s in sources]
            files.write(outs["json"], lambda p: p.write_text(json.dumps(d, indent=1)), "--json",
                        note=f"wrote {args.json}")
        if "csv" in outs:
            files.write(outs["csv"], res.write_csv, "--csv", note=f"wrote {args.csv}")
        if "plot" in outs:
            files.write(outs["plot"], lambda p: figures.plot_check(res, p), "--plot", note=f"wrote {args.plot}")
        if "report" in outs:
            write = check_report.write_pdf if pdf else check_report.write_report
            files.write(outs["report"], lambda p: write(res, p, job=job, sources=sources), "--report",
                        note=f"wrote {args.report}")
        if tables is not None:
            make_output_folder(tables, "--tables")
            check_report.write_tables(res, tables, job=job, sources=sources, outs=files)
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
        if check_report.find_chromium() is None:
            raise RunError(f"--report {args.report}: no headless Chromium on this machine (chromium not on PATH); "
                           f"write --report X.html and print it to PDF from a browser")
    return outs, pdf


def _check_trains(args, trains_spec, bridge):
    """The trains of ``--trains``; ``--irregularity`` and ``--comfort`` refused before any work when no train
    has vehicles, named by their flags."""
    trains = resolve_trains(trains_spec)
    if args.irregularity is not None:  # refused before any work, named by its flag
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


def run(args, damping_provider=None):
    """EN 1991-2 dynamic check (:mod:`adm_sim.design.check`). ``--damping none|adm`` are the core's;
    ``lb|vbi`` need adm-calib's ``damping_provider`` (``adm-calib check`` passes it) and are refused
    here, before any work, without one. The core never imports adm_calib."""
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
        bridge = bridge_from_mapping(bridge_spec, source=f"--job {job.path}: [bridge]", typed=True)
    else:
        bridge = resolve_bridge(bridge_spec, continuous=True)  # a continuous deck: adm_sim.design.check_deck
    if bridge.is_continuous:
        _refuse_on_deck(args, tables)
    bridge, measured = measured_bridge(args, bridge)  # --measured: n0, zeta (and EJ) of the monitored bridge
    parse_where(args.where, bridge.span_m)  # refused before any work
    if args.damping_model is not None and args.damping_model not in DAMPING_MODELS:
        raise InputError(f"--damping-model: {args.damping_model!r} is not allowed; allowed {', '.join(DAMPING_MODELS)}")
    trains = _check_trains(args, trains_spec, bridge)
    if args.lateral_frequency is not None:
        try:  # refused before any work, named by its flag
            check_lateral_frequency(args.lateral_frequency)
        except InputError as exc:
            raise InputError("--lateral-frequency" + str(exc)[len("lateral_frequency"):]) from None
    mass_bounds, stiffness_bounds = (parse_bounds(getattr(args, k), f"--{k.replace('_', '-')}")
                                     for k in ("mass_bounds", "stiffness_bounds"))
    ballast = None if args.ballast is None else parse_bounds(f"standard:{args.ballast}", "--ballast")
    deck_end_height = None
    if args.deck_end_height is not None:
        deck_end_height = check_deck_end_height(args.deck_end_height, "--deck-end-height")
    track = check_track_type("--track", args.track, aliases=True)  # one vocabulary: direct -> direct_fastening
    cb, close = progress_callback("check", None if args.progress is None else args.progress)
    t0 = time.perf_counter()
    try:
        if bridge.is_continuous:
            res = _run_deck_check(args, bridge, trains, track=track, progress=cb, deck_end_height=deck_end_height)
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
    sources = input_sources(bridge_spec, trains_spec, trains)
    for line in job.lines():
        print(line)
    print(res.summary() if getattr(res, "is_deck", False) else check_summary(res))
    print(f"{len(trains)} trains, {wall:.2f} s")
    _write_check_outputs(args, res, outs=outs, pdf=pdf, tables=tables, job=job, sources=sources, measured=measured,
                         wall=wall)
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


def _run_deck_check(args, bridge, trains, *, track, progress, deck_end_height):
    """The check of a continuous deck (:func:`adm_sim.design.check_deck.run_deck_check`)."""
    from adm_sim.design.check_deck import run_deck_check  # noqa: PLC0415  numba and scipy (~1 s): only on a continuous deck, not before a refusal
    return run_deck_check(bridge, args.max_line_speed, trains, track=track, step_kmh=args.speed_step,
                          progress=progress, n_modes=args.modes, where=args.where, damping_model=args.damping_model,
                          track_maintenance=args.track_maintenance, alpha=args.alpha,
                          lateral_frequency_hz=args.lateral_frequency, deck_end_height_m=deck_end_height)


def _check_plausible(res):
    """Plausibility warnings on a check's results: the largest acceleration and deflection over all
    trains and speeds, each named by its train and speed (:mod:`adm_sim.model.plausibility`)."""
    if not res.trains:
        return
    acc = max((float(c.max_acc_m_s2.max()), c.name, float(c.speeds_kmh[int(c.max_acc_m_s2.argmax())]))
              for c in res.trains)
    disp = max((float(c.max_disp_m.max()), c.name, float(c.speeds_kmh[int(c.max_disp_m.argmax())]))
               for c in res.trains)
    check_response(res.bridge.span_m, acc[0], disp[0], f"check: {acc[1]} at {acc[2]:g} km/h",
                   f"check: {disp[1]} at {disp[2]:g} km/h")


def add_arguments(c):
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
                   help=option_help("--modes", "more modes than EN 1990 A2.4.4.2.1 asks for; default: exactly those; "
                                               f"a continuous deck takes up to {FIELDS['deck_n_modes'].hi}; one span"))
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
    add_output_options(c, {"json": "write the verdict and every curve as JSON",
                        "csv": "write every curve as CSV (train, speed, acc and its position, disp, midspan moment, "
                               "zeta per mode)",
                        "plot": "write the acceleration envelopes as PNG",
                        "report": "write the report: X.html one self-contained page (inline figures, no network), "
                                  "X.pdf the same printed by headless Chromium: identification, inputs and their "
                                  "sources, verdict per clause, envelopes, governing cases, defaults, what is not "
                                  "checked"},
                    "replace existing output files (once the check has finished)")
