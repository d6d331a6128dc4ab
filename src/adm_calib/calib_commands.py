"""``adm-calib``: additional-damping calibration and comparison from the command line.

Subcommands::

    adm-calib calibrate --bridge B1 --train ICE-2 [--speeds 160:350:1] [--json FILE] [--plot FILE.png]
                        [--dense-maxima] [--refine-speed]
    adm-calib table4 [--out DIR] [--bridges B1,B2,B3,B4] [--trains ICE-2,...] [--jobs N] [--dense-maxima]
                     [--refine-speed]
    adm-calib recommend --train T --n0 HZ --mu KG_PER_M --type cfb|sc [--span M] [--interpolate]
                        [--functions paper|ours|conservative] [--extrapolate]
    adm-calib study --out DIR [--trains ...] [--mass-functions mu1,...] [--spans 4:40] [--freq-index 1,...]
                    [--limit N] [--workers 2 | --scheduler tcp://127.0.0.1:PORT] [--dense-maxima] [--refine-speed]
    adm-calib check --max-line-speed KMH [--bridge B1] [--trains hslm,ICE-2,...] [--damping none|adm|lb|vbi]
                    [the other options of adm-sim check]
    adm-calib study-fit --results DIR/results.jsonl [--out DIR] [--exclude none|step2|strict]
                        [--fit-range-hz 2:21] [--tag NAME]

Errors are one line ``error: ...`` on stderr: bad input exits with code 2, a run that fails for
another reason (an unstable integration, a study cluster that fails) with 1, an interrupt with 130
(:func:`adm_sim.cliutil.run_cli`). Output paths are checked before any computation; files are never
overwritten unless ``--overwrite`` (alias ``--force``) is given, and then replaced only by complete
ones. Mass per length is kg/m in and out (t/m shown beside it).
"""

from __future__ import annotations

import json
import re
import signal
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from adm_sim.files import OutputSet, check_output_folder, claim_output, input_file, make_output_folder
from adm_sim.inputs.measured import add_measured_argument
from adm_sim.cli.sim_commands import add_check_arguments, cmd_check
from adm_sim.cliutil import (Parser, add_choice, add_dim_grid, add_max_work, add_overwrite, add_progress, add_speeds,
                             add_steps_per_period, check_option, option_help, option_view, progress_callback, run_cli)
from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.fields import FIELDS, check_range
from adm_sim.limits import MAX_DELTA_ZETA_PCT
from adm_sim.integrate.step_grid import StepOptions

#: Range of recommend --mu (kg/m): the 0.5-100 t/m the lower-bound rules accept (the registry's).
MU_RANGE_KG_M = (option_view("--mu").lo, option_view("--mu").hi)


def _out_dir(text, option, names, overwrite, inputs=None):
    """Check an output folder and its files before any computation (the folder rule of
    :mod:`adm_sim.files`); returns ``(folder, paths)``. The files of a folder that exists are
    claimed here; a folder that does not exist yet is created by :func:`adm_sim.files.make_output_folder`
    once every input is checked."""
    out = check_output_folder(text, option, names, inputs)
    if out.is_dir():
        return out, [claim_output(str(out / n), option, overwrite, inputs=inputs) for n in names]
    return out, [out / n for n in names]


def _once(values, field, text):
    """``values`` (canonical names of the items of ``text``) if none repeats, else one line naming ``field``."""
    if len(set(values)) != len(values):
        raise InputError(f"{field}: {text!r} names an item twice; give each once")
    return values


def _list(text, field):
    items = [s.strip() for s in text.split(",") if s.strip()]
    if not items:
        raise InputError(f"{field}: {text!r} is empty; give a comma-separated list")
    return items


def _options(args):

    from adm_calib.calibrate import CalibrationOptions  # noqa: PLC0415  scipy (~1.3 s): only this subcommand

    from adm_calib.study.cases import REFINED_SPEED_STEP_KMH  # noqa: PLC0415  start-up: only this subcommand (316 ms)

    step = None
    if args.steps_per_period is not None or args.dense_maxima:
        spp = StepOptions.steps_per_period if args.steps_per_period is None else _steps_per_period(args.steps_per_period)
        step = StepOptions(steps_per_period=spp, dense_maxima=args.dense_maxima)
    return CalibrationOptions(dim_grid=args.dim_grid, step=step,
                              speed_refinement_kmh=REFINED_SPEED_STEP_KMH if args.refine_speed else None)


def _steps_per_period(text):
    return check_option("--steps-per-period", text)


def _speeds(text):
    from adm_sim.inputs.speeds import parse_speeds  # noqa: PLC0415  start-up: only this subcommand (60 ms)

    return parse_speeds(text, field="--speeds")


def cmd_calibrate(args):
    from adm_sim.inputs.bridges import resolve_bridge  # noqa: PLC0415  start-up: only this subcommand (16 ms)
    from adm_sim.inputs.train_files import load_train  # noqa: PLC0415  start-up: only this subcommand (47 ms)

    from adm_calib.calibrate import calibrate  # noqa: PLC0415  scipy (~1.3 s): only this subcommand

    from adm_sim.inputs.measured import measured_bridge  # noqa: PLC0415  start-up: only this subcommand

    inputs = {"--bridge": args.bridge, "--train": args.train, "--measured": args.measured}
    json_path = claim_output(args.json, "--json", args.force, ".json", inputs) if args.json is not None else None
    plot_path = claim_output(args.plot, "--plot", args.force, ".png", inputs) if args.plot is not None else None
    bridge = resolve_bridge(args.bridge, continuous=True)  # a continuous deck: its largest midspan peak
    if bridge.is_continuous and len(bridge.spans_m) > 1 and args.measured is not None:
        raise InputError(f"--measured: {args.measured!r} sets n0 and zeta of a simply supported span (EJ from Eq. 18); "
                         f"--bridge {args.bridge!r} is a continuous deck of {len(bridge.spans_m)} spans: give its "
                         f"n0 or EJ and zeta_pct in the spec instead")
    bridge, measured = measured_bridge(args, bridge)  # --measured: n0, zeta of the monitored bridge
    train = load_train(args.train)
    speeds = _speeds(args.speeds)
    options = _options(args)
    cb, close = progress_callback(f"calibrate {bridge.name or 'bridge'} x {train.name}", args.progress, unit=" runs")
    t0 = time.perf_counter()
    try:
        res = calibrate(bridge, train, speeds_kmh=speeds, options=options, progress=cb)
    finally:
        close()
    wall = time.perf_counter() - t0
    _check_plausible(res)
    print(res.summary())
    print(f"wall time      {wall:.2f} s")
    with OutputSet() as outs:  # --json and --plot: both or neither
        if json_path:
            text = res.to_json() if measured is None else json.dumps({**json.loads(res.to_json()),
                                                                       "measured": measured.to_dict()}, indent=1)
            outs.write(json_path, lambda p: p.write_text(text + "\n"), "--json", note=f"wrote {json_path}")
        if plot_path:
            from adm_calib.plots import plot_calibration  # noqa: PLC0415  start-up: only this subcommand (239 ms)

            outs.write(plot_path, lambda p: plot_calibration(res, p), "--plot", note=f"wrote {plot_path}")
    return 0


def _check_plausible(res):
    """Plausibility warnings on a calibration's MLM and DIM curves: each curve's largest
    acceleration, named by bridge, train, model and speed (:mod:`adm_sim.model.plausibility`)."""
    from adm_sim.model.plausibility import check_response  # noqa: PLC0415  start-up: only this subcommand (12 ms)

    for model, v, a in (("MLM", res.mlm_speeds_kmh, res.mlm_acc_m_s2), ("DIM", res.dim_speeds_kmh, res.dim_acc_m_s2)):
        if a.size:
            i = int(np.argmax(a))
            check_response(res.bridge.span_m, a[i], None,
                           f"{res.bridge.name or 'bridge'} x {res.train_name}: {model} at {v[i]:g} km/h")


def cmd_table4(args):
    from adm_sim.model.bridge import named_bridge  # noqa: PLC0415  start-up: only this subcommand (16 ms)
    from adm_sim.inputs.train_files import load_train  # noqa: PLC0415  start-up: only this subcommand (47 ms)

    from adm_calib.plots import plot_total_damping  # noqa: PLC0415  start-up: only this subcommand (239 ms)
    from adm_calib.table4 import run_table4  # noqa: PLC0415  scipy (~1.2 s): only this subcommand

    names = ("table4.csv", "table4.txt", "table4.json", "fig19_total_damping.png")
    out, paths = _out_dir(args.out, "--out", names, args.force)
    bridges = _once([_as_option("--bridges", "bridge", named_bridge, b).name for b in _list(args.bridges, "--bridges")],
                    "--bridges", args.bridges)
    trains = _once([_study_train(t, "--trains") for t in _list(args.trains, "--trains")], "--trains", args.trains)
    for t in trains:
        load_train(t)
    jobs = check_option("--jobs", args.jobs)
    speeds, options = _speeds(args.speeds), _options(args)
    make_output_folder(out, "--out")
    t0 = time.perf_counter()
    cb, close = progress_callback("table4", args.progress, unit="it", leave=True)
    try:
        table = run_table4(bridges, trains, speeds_kmh=speeds, options=options, jobs=jobs, progress=cb)
    finally:
        close()
    for res in table.results.values():
        _check_plausible(res)
    text = table.to_text()
    print(text)
    with OutputSet() as outs:  # the four files: all or none
        outs.write(paths[0], lambda p: p.write_text(table.to_csv()), "--out")
        outs.write(paths[1], lambda p: p.write_text(text + "\n"), "--out")
        outs.write(paths[2], lambda p: p.write_text(table.to_json() + "\n"), "--out")
        outs.write(paths[3], lambda p: plot_total_damping(table, p), "--out")
    print(f"wrote {', '.join(str(p) for p in paths)} ({time.perf_counter() - t0:.1f} s)")
    return 0


def _recommend_mu_kg_m(text):
    """``recommend --mu`` in kg/m, like the bridge specs. A value that is a mass per length in t/m
    (0.5..100) cannot be one in kg/m (500..100000), so the hint shows the conversion."""
    lo, hi = MU_RANGE_KG_M
    try:
        return check_option("--mu", text)
    except InputError as exc:
        try:
            x = float(text)
        except ValueError:
            x = float("nan")
        if lo / 1000.0 <= x <= hi / 1000.0:
            raise InputError(f"{exc} (--mu is in kg/m like the bridge specs: {x:g} t/m = {1000 * x:g} kg/m)") from None
        raise


def _as_option(option, label, fn, *args):
    """``fn(*args)``; an :class:`InputError` labelled ``label`` is relabelled with the ``option`` typed."""
    try:
        return fn(*args)
    except InputError as exc:
        raise InputError(f"{option}: {str(exc).removeprefix(label + ': ')}") from None


def _study_train(text, option):
    """A study train's canonical name; the error names ``option`` as typed."""
    from adm_calib.reference import canonical_train_name  # noqa: PLC0415  start-up: only this subcommand (91 ms)

    return _as_option(option, "train", canonical_train_name, text)


def _recommend_measured(args):
    """``--measured``: sets ``args.n0`` to the measured n0 (median f1); exactly one of --n0 and
    --measured. Returns the :class:`adm_sim.inputs.measured.MeasuredModes` or None."""
    if args.measured is None:
        if args.n0 is None:
            raise InputError("--n0: not given; give the first natural frequency (Hz) or --measured PASSAGES.json")
        return None
    if args.n0 is not None:
        raise InputError(f"--n0: {args.n0!r} given with --measured {args.measured!r}; give one of them")
    from adm_sim.inputs.measured import read_measured  # noqa: PLC0415  start-up: only this subcommand

    measured = read_measured(args.measured)
    args.n0 = repr(measured.f1_hz)
    return measured


def _own_functions(args):
    """``recommend --functions FILE``: the least-squares functions of a train outside the paper's, from
    the functions file ``study-fit`` wrote beside its study, for ``--train`` the same train file
    (same SHA-256); ``{"train", "table", "source", "cases"}``. None for the built-in sets."""
    from adm_calib.reference import LOWER_BOUND_FILES  # noqa: PLC0415  start-up: only this subcommand (91 ms)

    if args.functions in LOWER_BOUND_FILES:
        return None
    text = str(args.functions)
    if not (text.endswith(".toml") or Path(text).is_file()):
        raise InputError(f"--functions: {text!r} is not a set or a file; allowed {', '.join(LOWER_BOUND_FILES)} or a "
                         f"functions file of adm-calib study-fit (functions_<train>.toml)")
    from adm_calib.study.own_train import read_functions, read_train_file  # noqa: PLC0415  start-up: only with a functions file

    fn = read_functions(text, "--functions")
    if not fn.sets["least_squares"]:
        raise InputError(f"--functions: {text!r} holds no least-squares function (too few interval minima in its "
                         f"study); allowed a functions file with the six mass functions")
    if not (str(args.train).endswith(".toml") or Path(str(args.train)).is_file()):
        raise InputError(f"--train: {args.train!r} is not a file; with --functions FILE give the train file its "
                         f"functions were made for ({fn.train_file!r}, train {fn.train!r})")
    tf = read_train_file(args.train, "--train")
    if tf.sha256 != fn.train_sha256:
        raise InputError(f"--functions: {text!r} was made for train {fn.train!r} (file {fn.train_file!r}, SHA-256 "
                         f"{fn.train_sha256[:16]}...), not for --train {args.train!r} (train {tf.name!r}, SHA-256 "
                         f"{tf.sha256[:16]}...); allowed the functions file of that train (adm-calib study-fit on "
                         f"its study)")
    source = (f"{fn.train}: least-squares cubics of its own study (Section 4.2.1, rule {fn.rule}; functions file "
              f"{Path(text).name})")
    return {"train": fn.train, "table": fn.sets["least_squares"], "source": source, "cases": fn.cases}


def cmd_recommend(args):
    from adm_sim.model.plausibility import check_studied_field  # noqa: PLC0415  start-up: only this subcommand (12 ms)

    from adm_calib.reference import (STUDY_N0_MAX_HZ, STUDY_SPAN_RANGE_M, lower_bound_table,  # noqa: PLC0415  start-up: only this subcommand (91 ms)
                                     recommend, span_from_frequency_m)

    _recommend_deck(args)  # --deck-spans: refused, or with --extrapolate the longest span with a warning
    own = _own_functions(args)  # --functions FILE (a train of a file), else None
    train = own["train"] if own else _study_train(args.train, "--train")
    measured = _recommend_measured(args)  # --measured: n0 from the monitored bridge
    lo_hz = next(iter((own["table"] if own else lower_bound_table(args.functions)[train]).values())).lower_limit_hz
    try:
        n0 = check_range("--n0", args.n0, "Hz", lo_hz, STUDY_N0_MAX_HZ)
    except InputError as exc:
        raise InputError(f"{exc} (validity of the lower-bound functions: {lo_hz:g} Hz up to the highest "
                         f"frequency of the studied bridges, Section 4.2.2)") from None
    mu_kg_m = _recommend_mu_kg_m(args.mu)
    span_range = FIELDS["span_m"].range if args.extrapolate else STUDY_SPAN_RANGE_M  # beyond 4..40 m: warned below
    span_view = option_view("--span")  # the studied spans; with --extrapolate the bridge's
    span = None if args.span is None else (span_view.field.check(args.span, name="--span") if args.extrapolate
                                           else span_view.check(args.span))
    if span is None and not span_range[0] <= span_from_frequency_m(n0) <= span_range[1]:
        raise InputError(f"--n0: {n0:g} Hz gives an estimated span of {span_from_frequency_m(n0):.3g} m "
                         f"(n0 = 97.76 L^-0.9124), outside the studied spans [{STUDY_SPAN_RANGE_M[0]:g}, "
                         f"{STUDY_SPAN_RANGE_M[1]:g}] m; give --span")
    # the field the paper studied (Section 3.1): refused outside it, warned with --extrapolate
    check_studied_field(span_from_frequency_m(n0) if span is None else span, n0, mu_kg_m, args.extrapolate,
                        names={"span_m": "--span" if span is not None else "span (estimated from --n0)",
                               "n0_hz": "--n0", "mu_kg_m": "--mu", "extrapolate": "--extrapolate"})
    speeds, speeds_text = _recommend_speeds(args)
    zeta_arg = None if args.zeta_pct is None else check_option("--zeta-pct", args.zeta_pct)
    if zeta_arg is None and measured is not None:  # --measured: the monitored bridge's zeta (its stated quantile)
        zeta_arg = measured.zeta1_pct
    rec = recommend(train, n0, mu_kg_m / 1000.0, args.type, span_m=span, interpolate=args.interpolate,
                    functions=own["source"] if own else args.functions, extrapolate=args.extrapolate,
                    table=own["table"] if own else None)
    return print_recommendation(args, rec, mu_kg_m, zeta_arg, speeds, speeds_text, own=own, measured=measured)


def _recommend_deck(args):
    """``recommend --deck-spans A/B/...``: the paper's functions were fitted on simply supported spans
    (Section 3.1), so a continuous deck of two or more spans is refused in one line, or with
    ``--extrapolate`` answered for its longest span with a warning; one span is ``--span``."""
    from adm_calib.reference import DECK_NOTE  # noqa: PLC0415  start-up: only this subcommand (91 ms)

    text = args.deck_spans
    if text is None:
        return
    each = FIELDS["span_m"]  # a deck's span takes the bridge model's span range (deck_spans_m's, each)
    spans = [each.check(p.strip(), name="--deck-spans") for p in str(text).split("/")]
    n_max = FIELDS["n_spans"].hi
    if len(spans) > n_max:
        raise InputError(f"--deck-spans: {text!r} names {len(spans)} spans; allowed 1 to {n_max} spans joined by '/' "
                         f"(e.g. 15/15)")
    if args.span is not None:
        raise InputError(f"--deck-spans {text!r} and --span {args.span!r}: give one of them")
    if len(spans) > 1 and not args.extrapolate:
        raise InputError(f"--deck-spans: {text!r} is a continuous deck of {len(spans)} spans; {DECK_NOTE}, so no "
                         f"recommendation (allowed: one span, or --extrapolate for the longest span with a warning; "
                         f"the deck's own dz_VBI: adm-calib calibrate --bridge spans={text},...)")
    if len(spans) > 1 and getattr(args, "verify", False):
        raise InputError(f"--verify: calibrates a simply supported span; --deck-spans {text!r} is a continuous deck "
                         f"(calibrate it with adm-calib calibrate --bridge spans={text},...)")
    if len(spans) > 1:
        warnings.warn(f"--deck-spans {text}: a continuous deck of {len(spans)} spans; {DECK_NOTE}: answered for its "
                      f"longest span {max(spans):g} m (--extrapolate; results/continuous/README.md compares the "
                      f"bound with two-span decks)", PlausibilityWarning, stacklevel=2)
    args.span = repr(max(spans))


def _recommend_speeds(args):
    """The design speed range of ``recommend`` (km/h): ``--speeds``, or 40 m/s .. 1.2 V from
    ``--max-line-speed`` (EN 1991-2 6.4.6.2(1), as ``check``), or the study's 160..350 km/h;
    ``(speeds or None, text)``."""
    if args.speeds is not None and args.max_line_speed is not None:
        raise InputError(f"--speeds {args.speeds} and --max-line-speed {args.max_line_speed}: give one design speed "
                         f"range, not both")
    if args.max_line_speed is not None:
        from adm_sim.design.check import check_speeds_kmh  # noqa: PLC0415  start-up: only with this option

        v = _as_option("--max-line-speed", "max_line_speed_kmh", check_speeds_kmh, args.max_line_speed)
        return v, (f"{v[0]:g}..{v[-1]:g} km/h (40 m/s .. 1.2 V, V = --max-line-speed {args.max_line_speed} km/h, "
                   f"EN 1991-2 6.4.6.2(1))")
    if args.speeds is not None:
        v = _speeds(args.speeds)
        return v, f"{v[0]:g}..{v[-1]:g} km/h (--speeds {args.speeds})"
    return None, "160..350 km/h (the study's range, Section 3.3)"


def recommendation_zeta(rec, zeta_pct=None, source=None):
    """ζ (%) of the bridge of a recommendation and its source: the user's (``--zeta-pct``, measured or
    chosen) or EN 1991-2 Table 6.6's lower limit for its type and span (paper Table 2)."""
    from adm_sim.model.bridge import eurocode_damping_pct  # noqa: PLC0415  start-up: only this subcommand (16 ms)

    if zeta_pct is not None:
        return float(zeta_pct), source or "user, --zeta-pct"
    return (eurocode_damping_pct(rec.span_m, rec.bridge_type),
            f"EN 1991-2 Table 6.6 lower limit for {rec.bridge_type.upper()}, L = {rec.span_m:.3g} m (paper Table 2)")


def verify_recommendation(rec, mu_kg_m, zeta_pct=None, speeds=None, speeds_text="", option="--speeds", train=None,
                          zeta_source=None):
    """``recommend --verify``: the calibration of the asked bridge (L, n0, mu, ζ of the
    recommendation) under its train (:func:`adm_calib.recommend_verify.verify`). A range whose
    calibration finds no resonance is refused (one line naming ``option``)."""
    from adm_sim.model.bridge import Bridge  # noqa: PLC0415  start-up: only this subcommand (16 ms)
    from adm_sim.inputs.train_files import load_train  # noqa: PLC0415  start-up: only this subcommand (47 ms)

    from adm_calib.recommend_verify import verify  # noqa: PLC0415  start-up: only with --verify

    zeta, source = recommendation_zeta(rec, zeta_pct, zeta_source)
    bridge = Bridge.from_frequency(rec.span_m, rec.n0_hz, mu_kg_m, zeta / 100.0, bridge_type=rec.bridge_type)
    ver = verify(rec.delta_zeta_pct, bridge, load_train(train or rec.train), speeds, zeta_source=source, speeds_text=speeds_text)
    r = ver.calibration
    if r.status in ("no_mlm_peak", "no_resonance_in_range", "grid_too_coarse"):
        raise InputError(f"{option}: {speeds_text or '160..350 km/h'} cannot show the resonance of {rec.train} on this "
                         f"bridge ({r.status}: {r.message}); allowed: a range holding an MLM peak, e.g. --speeds "
                         f"160:420:1")
    return ver


def print_recommendation(args, rec, mu_kg_m, zeta_pct=None, speeds=None, speeds_text="", own=None, measured=None):
    """Print one recommendation (text or ``--json``) with its conservative verdict and, with
    ``--verify``, the own calibration beside it. Other options (``--functions``, ``--measured``)
    reach here through ``args`` and ``rec``."""
    from adm_calib.recommend_verify import study_verdict  # noqa: PLC0415  start-up: only this subcommand
    from adm_calib.recommend_warnings import recommendation_warnings  # noqa: PLC0415  start-up: only this subcommand (reads the study's cases)
    from adm_calib.reference import FUNCTION_SOURCES  # noqa: PLC0415  start-up: only this subcommand (91 ms)

    zeta_source = (f"measured, --measured ({measured.n_used} passages)"
                   if measured is not None and getattr(args, "zeta_pct", None) is None else None)
    option = "--max-line-speed" if getattr(args, "max_line_speed", None) is not None else "--speeds"
    ver = (verify_recommendation(rec, mu_kg_m, zeta_pct, speeds, speeds_text, option,
                                 train=args.train if own else None, zeta_source=zeta_source)
           if getattr(args, "verify", False) else None)
    cases = own["cases"] if own else None  # a train of a file: the cases of its own study
    verdict = ver.verdict if ver is not None else study_verdict(rec, cases)
    zeta, zeta_source = recommendation_zeta(rec, zeta_pct, zeta_source)
    study_warnings = recommendation_warnings(rec, cases=cases)
    for w in study_warnings:  # one line "warning: ..." on stderr each (run_cli)
        warnings.warn(w, PlausibilityWarning, stacklevel=2)
    if args.json:
        d = rec.to_dict()
        if measured is not None:
            d["measured"] = measured.to_dict()
        d.update(verdict.to_dict())
        d["study_warnings"] = study_warnings
        d["mu_kg_m"] = mu_kg_m
        d["mass_function_kg_m"] = {m: 1000.0 * v for m, v in rec.mass_function_t_m.items()}
        d["zeta_pct"], d["zeta_source"], d["speeds"] = zeta, zeta_source, speeds_text
        d["verification"] = None if ver is None else ver.to_dict()
        print(json.dumps(d, indent=2))
    else:
        if measured is not None:
            print("\n".join(measured.lines()))
        print(f"dz_LB = {rec.delta_zeta_pct:.4f} %  conservative: {str(verdict.conservative).lower()} ({verdict.reason})")
        if ver is not None:
            print("\n".join(ver.lines()))
        print(f"zeta = {zeta:.3f} % ({zeta_source}); design speeds {speeds_text}")
        print(f"functions: {FUNCTION_SOURCES.get(rec.functions, rec.functions)}")
        print(f"mu = {mu_kg_m:g} kg/m ({mu_kg_m / 1000:g} t/m)")
        print(f"rule: {rec.rule}")
        print("mass functions: " + ", ".join(
            f"{m} (mu={1000 * rec.mass_function_t_m[m]:.0f} kg/m = {rec.mass_function_t_m[m]:.3f} t/m, "
            f"weight {w:.3f}, dz={v:.4f} %)"
            for m, w, v in zip(rec.mass_functions, rec.weights, rec.function_values_pct)))
        if rec.span_estimated:
            print(f"span: {rec.span_m:.2f} m estimated from n0 by n0 = 97.76 L^-0.9124 (give --span to set it)")
        if rec.beyond_root:
            print("n0 lies beyond the first root of the lower-bound function: dz = 0 (paper Section 4.2.1)")
    return 0


# ---------------------------------------------------------------------- parametric study
def _mass_functions(text):
    from adm_calib.study import MASS_FUNCTION_NAMES  # noqa: PLC0415  start-up: only this subcommand (370 ms)

    out = []
    for m in _list(text, "--mass-functions"):
        if m.lower() not in MASS_FUNCTION_NAMES:
            raise InputError(f"--mass-functions: {m!r} is unknown; allowed {', '.join(MASS_FUNCTION_NAMES)}")
        out.append(m.lower())
    return out


def _spans(text):

    parts = [p.strip() for p in str(text).split(":")]
    if len(parts) not in (1, 2) or not all(parts):
        raise InputError(f"--spans: {text!r} is not lo:hi in m (e.g. 4:40)")
    spans = option_view("--spans")
    lo, hi = (spans.check(p) for p in (parts[0], parts[-1]))
    if lo > hi:
        raise InputError(f"--spans: {text!r} is empty; allowed lo:hi with lo <= hi in {spans.range_text()}")
    return lo, hi


def _freq_indices(text):
    return sorted(_once([check_option("--freq-index", p) for p in _list(text, "--freq-index")], "--freq-index", text))


def _scheduler(text):
    """``--scheduler``: an address like tcp://127.0.0.1:8786 where a dask scheduler answers
    (connected with a timeout and checked for the dask handshake before anything is written)."""
    from adm_calib.study.execution import check_scheduler  # noqa: PLC0415  start-up: only this subcommand (235 ms)

    return check_scheduler(text)


def _check_study_work(cases, settings):
    """The work of every batch's runs (lanes x steps x modes of each sweep, :func:`adm_sim.limits.check_work`),
    refused before anything is written, as the workers would refuse it case by case."""
    from adm_calib.study.cases import _train  # noqa: PLC0415  start-up: only this subcommand
    from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s  # noqa: PLC0415

    v = speeds_to_m_s(settings.speeds_kmh())
    opts = StepOptions(**({} if settings.steps_per_period is None else {"steps_per_period": settings.steps_per_period}))
    trains, seen = {}, set()
    for c in cases:
        if c.batch_key in seen:
            continue
        seen.add(c.batch_key)
        t = trains.setdefault(c.train, _train(c.train))
        make_grid(c.bridge, t.length_m, v, opts)


def cmd_study(args):
    from adm_calib.study import StudySettings, run_study, select_cases  # noqa: PLC0415  start-up: only this subcommand (370 ms)

    from adm_calib.study.own_train import check_dim_step, study_step_s, study_trains  # noqa: PLC0415  start-up: only this subcommand

    out, _ = _out_dir(args.out, "--out", (), True)
    trains, files = study_trains(_list(args.trains, "--trains"), "--trains")
    mfs = _once(_mass_functions(args.mass_functions), "--mass-functions", args.mass_functions)
    spans = _spans(args.spans)
    layout = check_option("--spans-layout", args.spans_layout)
    fis = _freq_indices(args.freq_index)
    workers = check_option("--workers", args.workers)
    limit = None if args.limit is None else check_option("--limit", args.limit)
    scheduler = None if args.scheduler is None else _scheduler(args.scheduler)
    spp = None if args.steps_per_period is None else _steps_per_period(args.steps_per_period)
    _speeds(args.speeds)
    if args.irregularity:
        from adm_sim.inputs.track_profile import parse_irregularity  # noqa: PLC0415  scipy.interpolate only for rough-track studies

        for span in (4.0, 40.0):  # bad input (spectrum, class, band, file, slope, curvature) refused before
            parse_irregularity(args.irregularity, span)  # anything is written (every selected span below)
    settings = StudySettings(speeds=args.speeds, dim_grid=args.dim_grid, steps_per_period=spp,
                             dense_maxima=args.dense_maxima, refine_speed=args.refine_speed,
                             irregularity=args.irregularity, spans_layout=layout)
    cases = select_cases(trains, mfs, spans, fis, own=files, spans_layout=layout)
    if not cases:
        raise InputError(f"--spans/--freq-index: the options select no case (spans are the integers "
                         f"4..40 m; --spans {args.spans!r} holds none)")
    for tf in files.values():  # vehicles the DIM's RK4 step cannot follow: refused before anything is written
        check_dim_step(tf, study_step_s(cases, spp))
    if args.irregularity:
        for span in sorted({c.bridge.span_m for c in cases}):  # a random profile differs per deck length
            parse_irregularity(args.irregularity, span)
    _check_study_work(cases, settings)
    make_output_folder(out, "--out")
    options = {"trains": trains, "mass_functions": mfs, "spans_m": list(spans), "spans_layout": layout, "freq_index": fis,
               "limit": limit, "workers": workers, "scheduler": scheduler, "retry_errors": args.retry_errors,
               "train_files": {n: f.path for n, f in files.items()}, "argv": sys.argv[1:]}
    print(f"study: {len(cases)} cases selected ({len(trains)} trains); results in {Path(args.out) / 'results.jsonl'}",
          flush=True)

    def on_term(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, on_term)
    cb, close = progress_callback("study", None, unit="case", leave=True, mininterval=0.1)  # bar on a terminal
    try:
        run = run_study(args.out, cases, settings=settings, workers=workers, scheduler=scheduler, limit=limit,
                        progress=cb, retry_errors=args.retry_errors, options=options, train_files=files)
    except KeyboardInterrupt:
        print("error: interrupted while closing the cluster; rerun the same command to resume", file=sys.stderr)
        return 130
    except (InputError, OSError):
        raise
    except Exception as exc:  # cluster failures: one line, results so far are kept
        msg = " ".join(str(exc).split())
        print(f"error: study stopped by {type(exc).__name__}: {msg}; rerun the same command to resume",
              file=sys.stderr)
        return 1
    finally:
        close()
        signal.signal(signal.SIGTERM, old)
    print(run.summary())
    return 130 if run.interrupted else 0


def _refuse_deck_study(records, option, path):
    """Refuse a study of continuous decks (``--spans-layout`` N > 1): the paper's lower-bound functions
    are fitted to simply supported spans (Section 4.2.1), so a fit of deck results would be given their
    meaning without their basis."""
    decks = [r for r in records if len(r.get("spans_m") or ()) > 1]
    if decks:
        n = sorted({len(r["spans_m"]) for r in decks})
        raise InputError(f"{option}: {str(path)!r} is a study of continuous decks ({len(decks)} of {len(records)} "
                         f"records, {'/'.join(map(str, n))} spans, e.g. {decks[0]['bridge']}): the paper's lower-bound "
                         f"functions (Section 4.2.1) are fitted to simply supported spans; allowed a study of simply "
                         f"supported spans (adm-calib study --spans-layout 1); a deck study is compared with the "
                         f"functions by results/continuous/run_field.py")


def _check_fit_records(records, option, path):
    """Refuse result lines the fit cannot use as they are: a NaN or text where a number belongs."""
    from adm_calib.peaks import has_delta_zeta  # noqa: PLC0415  start-up: only this subcommand
    from adm_calib.study import MASS_FUNCTION_NAMES  # noqa: PLC0415  start-up: only this subcommand (370 ms)

    for no, rec in enumerate(records, start=1):
        where = f"{option}: {str(path)!r}: record {no} ({rec['bridge']}, {rec['train']})"
        status = rec.get("status")
        if not isinstance(status, str):
            raise InputError(f"{where}: status: {status!r} must be text ('ok', 'error', ...)")
        for flag in ("dim_is_local_max", "mlm_max_at_range_end"):
            if flag in rec and not isinstance(rec[flag], bool):
                raise InputError(f"{where}: {flag}: {rec[flag]!r} must be true or false")
        pk = rec.get("mlm_peak")
        if pk is not None and not (isinstance(pk, dict) and all(
                isinstance(pk.get(k), (int, float)) and not isinstance(pk.get(k), bool) for k in ("speed_kmh", "acc_m_s2"))):
            raise InputError(f"{where}: mlm_peak: {pk!r} must be null or {{speed_kmh (km/h), acc_m_s2 (m/s^2)}}")
        if not has_delta_zeta(status) or rec.get("delta_zeta_vbi_pct") is None:
            continue  # excluded from the fit (error / no dz), whatever else it holds
        if rec.get("mass_function") not in MASS_FUNCTION_NAMES:
            raise InputError(f"{where}: mass_function: {rec.get('mass_function')!r} is unknown; "
                             f"allowed {', '.join(MASS_FUNCTION_NAMES)}")
        for key, unit, lo, hi in (("delta_zeta_vbi_pct", "%", None, None), ("n0_hz", "Hz", 0.0, None),
                                  ("span_m", "m", 0.0, None)):
            value = rec.get(key)
            if isinstance(value, str) or value is None:
                raise InputError(f"{where}: {key}: {value!r} is not a number ({unit})")
            check_range(f"{where}: {key}", value, unit, lo, hi, lo_open=lo is not None)
        # a calibration's Δζ lies in (-ζ, 20 %] (ζ + Δζ > 0, the bracketing ladder's top); where the
        # record does not carry ζ, in [-20 %, 20 %]
        zeta = rec.get("zeta_pct")
        known = isinstance(zeta, (int, float)) and not isinstance(zeta, bool) and zeta > 0
        check_range(f"{where}: delta_zeta_vbi_pct", rec["delta_zeta_vbi_pct"], "%",
                    -float(zeta) if known else -MAX_DELTA_ZETA_PCT, MAX_DELTA_ZETA_PCT, lo_open=known)


def _fit_range_hz(text):
    """``--fit-range-hz lo:hi`` (Hz) -> the interval boundaries of the fit (:func:`fit_edges_hz`)."""
    from adm_calib.study import fit_edges_hz  # noqa: PLC0415  start-up: only this subcommand (370 ms)

    parts = [p.strip() for p in str(text).split(":")]
    try:
        if len(parts) != 2:
            raise ValueError
        lo, hi = (float(p) for p in parts)
    except ValueError:
        raise InputError(f"--fit-range-hz: {text!r} is not lo:hi in Hz (e.g. 2:16); allowed within [2, 21] Hz") from None
    return _as_option("--fit-range-hz", "fit_range_hz", fit_edges_hz, lo, hi)


def _tag(text):
    if text and not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,39}", text):
        raise InputError(f"--tag: {text!r} is not a file-name suffix; allowed 1-40 letters, digits, '_', '.', '-' "
                         f"(starting with a letter or digit)")
    return text


def cmd_study_fit(args):
    from adm_calib import plots  # noqa: PLC0415  start-up: only this subcommand (239 ms)
    from adm_calib import study as st  # noqa: PLC0415  start-up: only this subcommand (370 ms)
    from adm_calib.study.conservative import conservative_markdown, conservative_study, conservative_toml  # noqa: PLC0415  start-up: only this subcommand (261 ms)

    from adm_calib.study import own_train  # noqa: PLC0415  start-up: only this subcommand

    res = input_file(args.results, "--results", "results file")
    own = own_train.study_train_files(res, "--results")  # a train file changed since the study: refused here
    rule = "strict" if args.exclude_flagged else args.exclude
    if args.exclude_flagged and args.exclude not in ("strict", st.DEFAULT_RULE):
        raise InputError(f"--exclude-flagged means --exclude strict; it conflicts with --exclude {args.exclude}")
    edges = _fit_range_hz(args.fit_range_hz)
    user_tag = _tag(args.tag)
    tag = ("" if rule == st.DEFAULT_RULE else f"_{rule}")
    if edges != st.INTERVAL_EDGES_HZ:
        tag += f"_fit{edges[0]:g}-{edges[-1]:g}hz"
    tag += f"_{user_tag}" if user_tag else ""
    names = [f"lower_bounds_fit{tag}.csv", f"interval_minima{tag}.csv", f"lower_bounds_fit{tag}.txt",
             f"fig16_dz_vs_span{tag}.png", f"fig18_lower_bounds{tag}.png", f"lower_bounds_study{tag}.toml",
             f"appendix_b_comparison{tag}.md", f"fig17_lower_bound_ICE-2_mu3{tag}.png",
             f"conservative_lower_bounds{tag}.md", f"lower_bounds_conservative{tag}.toml"]
    fig17 = {t: f"fig17_lower_bound_{own_train.safe_name(t)}{tag}.png"
             for t in dict.fromkeys((*st.STUDY_TRAINS, *st.TRAIN_VARIANTS, *own))}
    functions = {t: f"functions_{own_train.safe_name(t)}{tag}.toml" for t in own}
    names += list(fig17.values()) + list(functions.values())
    out, path_list = _out_dir(args.out if args.out is not None else str(res.parent), "--out", names, args.force,
                              inputs={"--results": res})
    paths = dict(zip(names, path_list))
    content = st.read_results(res)
    if not content.records:
        raise InputError(f"--results: {str(res)!r} holds no complete result line")
    _check_fit_records(content.records, "--results", res)
    _refuse_deck_study(content.records, "--results", res)
    make_output_folder(out, "--out")
    fit = st.fit_study(content.records, rule=rule, edges_hz=edges, own_trains=own)
    text = fit.to_text()
    quantities = {t: own_train.quantities_of_file(tf) for t, (_, tf) in own.items()}
    for t, q in quantities.items():
        text += f"\nSection 4.2.2 quantities of the train file {own[t][0].get('file_name', '')!r}:\n{q.to_text()}"
    if content.truncated_tail:
        text += f"\n(a truncated last {content.describe_tail()} of the results file was ignored)"
    print(text)
    written = []

    def write(name, fn):
        outs.write(paths[name], fn, "--out")
        written.append(name)

    with OutputSet() as outs:  # every file of the fit, or none: an interrupted fit leaves nothing in the way
        write(names[0], lambda p: p.write_text(fit.to_csv()))
        write(names[1], lambda p: p.write_text(fit.minima_csv()))
        write(names[2], lambda p: p.write_text(text + "\n"))
        write(names[3], lambda p: plots.plot_dz_vs_span(fit.records_used, p))
        write(names[4], lambda p: plots.plot_lower_bounds(fit, p))
        command = (f"adm-calib study-fit --results {res} --exclude {rule} --fit-range-hz {edges[0]:g}:{edges[-1]:g}"
                   + (f" --tag {user_tag}" if user_tag else ""))
        write(names[5], lambda p: p.write_text(fit.to_toml(command=command)))
        write(names[6], lambda p: p.write_text(st.comparison_markdown(content.records, rule=rule, edges_hz=edges,
                                                                      own_trains=own)))
        rows = conservative_study(fit)
        cons = {(r.train, r.mass_function): r.fit for r in rows}
        if ("ICE-2", "mu3") in fit.fits:
            write(names[7], lambda p: plots.plot_lower_bound_set(fit, "ICE-2", "mu3", p, cons))
        write(names[8], lambda p: p.write_text(conservative_markdown(rows, fit)))
        write(names[9], lambda p: p.write_text(conservative_toml(rows, fit, command=command)))
        for t in fit.trains:
            write(fig17[t], lambda p, t=t: plots.plot_lower_bounds_train(fit, t, p, cons))
        if own:
            from adm_calib.recommend_warnings import study_cases_csv  # noqa: PLC0415  start-up: only with train files

            for t, (rec, _) in own.items():
                cases = study_cases_csv([r for r in content.records if r["train"] == t], rule)
                write(functions[t], lambda p, t=t, rec=rec, cases=cases: p.write_text(own_train.functions_toml(
                    t, rec, fit, rows, cases, quantities[t], command=command, study_dir=res.parent.resolve())))
    print(f"wrote {len(written)} files to {out}")
    return 0


def cmd_check_calib(args):
    """``adm-calib check``: the core's EN 1991-2 check (:func:`adm_sim.cli.sim_commands.cmd_check`) with all four
    damping methods; ``lb`` and ``vbi`` from :func:`adm_calib.check.calibrated_damping`."""
    from adm_calib.check import calibrated_damping  # noqa: PLC0415  start-up: only this subcommand (186 ms)

    return cmd_check(args, damping_provider=calibrated_damping)


def _common(sp):
    """The options calibrate and table4 share."""
    add_speeds(sp, "MLM speeds in km/h, start:stop:step", show_default=True)
    add_dim_grid(sp, "DIM speeds: paper = 5 km/h plus 1 km/h near the MLM peak (Section 3.3); full = all")
    add_steps_per_period(sp, "integration steps per period of the highest mode (core default 16)")
    add_progress(sp, negatable=False, text="show progress bars on stderr")
    add_overwrite(sp, "replace existing output files (only once the new ones are complete)", force_alias=True)
    _peaks_options(sp)


def _peaks_options(sp):
    """--dense-maxima and --refine-speed (calibrate, table4, study)."""
    sp.add_argument("--dense-maxima", action="store_true",
                    help="maximum acceleration also between time steps, from the RK4 step's dense output "
                         "(quintic Hermite); default: at the steps, as the shipped results")
    sp.add_argument("--refine-speed", action="store_true",
                    help="refined mode: locate the MLM and the DIM peak to 0.05 km/h; default: the paper's "
                         "1 km/h speed grid")


def _add_calibrate(sub):
    """``adm-calib calibrate``."""
    c = sub.add_parser("calibrate", help="calibrate dz_VBI for one bridge and one train")
    add_max_work(c)
    c.add_argument("--bridge", required=True, help="B1..B4, a spec L=15,n0=8.26,mu=19042,zeta_pct=1.85,class=cfb "
                   "(L m, n0 Hz or EJ N m^2, mu kg/m, zeta_pct %% or type=cfb|sc for the Table 2 damping; class=cfb|sc "
                   "classes a bridge of given damping for the lower-bound functions), a continuous deck "
                   "spans=15/15,n0=8.26,mu=19042,zeta_pct=1.85,class=cfb (the peaks are the largest of the maxima at "
                   "the middle of every span, MLM and DIM alike; ADM, EADA and the lower bound are not evaluated on "
                   "a deck), or a TOML file with these keys")
    c.add_argument("--train", required=True, help="ICE-2, Eurostar, Railjet, ICE-4 or a TOML train file")
    add_measured_argument(c)
    c.add_argument("--json", help="write the result as JSON to this file")
    c.add_argument("--plot", help="write the Fig. 15 analogue to this PNG file")
    _common(c)
    c.set_defaults(func=cmd_calibrate)


def _add_table4(sub):
    """``adm-calib table4``."""
    t = sub.add_parser("table4", help="Table 4 and Fig. 19 for the bridges B1-B4 and the four trains")
    t.add_argument("--out", default="table4_out", help="output directory (default table4_out)")
    t.add_argument("--bridges", default="B1,B2,B3,B4", help="comma list of B1..B4 (default B1,B2,B3,B4)")
    t.add_argument("--trains", default="ICE-2,Eurostar,Railjet,ICE-4",
                   help="comma list of ICE-2, Eurostar, Railjet, ICE-4 (default all four)")
    t.add_argument("--jobs", default="1", help=option_help("--jobs", "worker processes (default 1)"))
    _common(t)
    t.set_defaults(func=cmd_table4)


def _add_recommend(sub):
    """``adm-calib recommend``."""
    r = sub.add_parser("recommend", help="dz from the lower-bound functions by the rules of Section 4.3")
    r.add_argument("--train", required=True, help="ICE-2, Eurostar, Railjet or ICE-4; with --functions FILE the "
                                                   "train or vehicle file of that study")
    r.add_argument("--n0", default=None, help="first natural frequency (Hz), 2.1 Hz up to the highest n0 of the study "
                                              "(or --measured)")
    r.add_argument("--measured", default=None, metavar="PASSAGES.json",
                   help="the monitor's JSON (monitor.py --json): n0 = the median f1 of its identified passages "
                        "(at least 3) instead of --n0")
    r.add_argument("--mu", required=True, help=option_help("--mu", "mass per length in kg/m, like the bridge specs "
                                                                   "(Table 1 / Eq. 19 print t/m: 1 t/m = 1000 kg/m); "
                                                                   "printed in both"))
    add_choice(r, "--type", "cfb: concrete/filler beam, sc: steel/composite", required=True)
    r.add_argument("--span", default=None, help=option_help("--span", "span; estimated from n0 when omitted"))
    r.add_argument("--deck-spans", default=None,
                   help=option_help("--deck-spans", "a continuous deck's spans joined by '/', e.g. 15/15: refused, "
                                                    "since the lower-bound functions were fitted on simply supported "
                                                    "spans; with --extrapolate answered for the longest span with a "
                                                    "warning; one span is --span"))
    r.add_argument("--interpolate", action="store_true",
                   help="interpolate linearly between the adjacent mass functions instead of the safe side")
    r.add_argument("--functions", default="paper",
                   help="lower-bound functions: paper = Tables B1-B4 (default); ours = re-derived from the "
                        "study shipped in results/study (adm-calib study-fit, least squares as the paper); "
                        "conservative = the largest cubic below every retained case of that study (linear programme); "
                        "or FILE, the functions_<train>.toml that study-fit writes for a study of a train file "
                        "(docs/own_train.md)")
    r.add_argument("--extrapolate", action="store_true",
                   help="answer outside the studied field (span 4..40 m, n0 in the Fig. 8 band, mu within "
                        "Table 1) with a warning instead of refusing (docs/plausibility.md)")
    r.add_argument("--verify", action="store_true",
                   help="calibrate dz_VBI of this bridge and train (Section 4, seconds) and print min(dz_LB, dz_VBI) "
                        "beside the bound with the calibration's status")
    r.add_argument("--speeds", default=None, help=option_help("--speeds", "design speed range of --verify, "
                                                                          "start:stop:step (default 160:350:1)"))
    r.add_argument("--max-line-speed", default=None,
                   help=option_help("--max-line-speed", "maximum line speed V: design speeds 40 m/s .. 1.2 V "
                                                        "(instead of --speeds)"))
    r.add_argument("--zeta-pct", default=None,
                   help=option_help("--zeta-pct", "the bridge's damping (measured or chosen); default the "
                                                  "EN 1991-2 Table 6.6 lower limit for --type and the span"))
    r.add_argument("--json", action="store_true", help="print JSON")
    r.set_defaults(func=cmd_recommend)


def _add_study(sub):
    """``adm-calib study``."""
    s = sub.add_parser("study", help="the parametric study (Section 3.3) on a dask cluster, resumable")
    add_max_work(s)
    s.add_argument("--out", required=True, help="study directory: results.jsonl (one line per case) and study.json; "
                                                "rerun with the same --out to resume")
    s.add_argument("--trains", default="ICE-2,Eurostar,Railjet,ICE-4",
                   help="comma list of ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table and train or vehicle files "
                        "(.toml; the study records each file's content and SHA-256, docs/own_train.md)")
    s.add_argument("--mass-functions", default="mu1,mu2,mu3,mu4,mu5,mu6", help="Table 1 mass functions")
    s.add_argument("--spans", default="4:40", help=option_help("--spans", "span range lo:hi (integer spans of the "
                                                                          "field), each end"))
    s.add_argument("--spans-layout", default="1", help=option_help(
        "--spans-layout", "1 (default): the paper's simply supported spans; N: every case a continuous deck of N "
        "equal spans of the case's span L (pinned over the supports), each span with the mu of the mass function "
        "at L (Eq. 19) and EJ from Eq. (18) with L and the case's n0 at L, so the deck's first frequency is that "
        "n0; damping Table 2 with L the span, the longest (Rayleigh at the deck's modes 1 and 3); 3 N modes; dz_VBI matched "
        "on the largest of the maxima at the middle of every span (MLM and DIM alike); each deck a batch of its "
        "own"))
    s.add_argument("--freq-index", default="1,2,3,4,5", help=option_help(
        "--freq-index", "n0 per span: 1 = LB ... 3 = fit ... 5 = UB power law; a comma list, each"))
    s.add_argument("--limit", default=None, help=option_help("--limit", "run at most N of the pending cases"))
    s.add_argument("--workers", default="2", help=option_help("--workers", "worker processes of the local cluster "
                                                                           "(default 2)"))
    s.add_argument("--scheduler", default=None, help="address of a running dask scheduler, e.g. "
                                                     "tcp://127.0.0.1:8786 (instead of a local cluster)")
    s.add_argument("--retry-errors", action="store_true", help="run the cases recorded with status error again")
    add_speeds(s, "MLM speeds in km/h, start:stop:step", show_default=True)
    add_dim_grid(s, "DIM speeds: window (default) = the paper's speeds where the associated DIM peak can lie, "
                    "the same results in half the time; paper = the paper's whole grid (Section 3.3); full = all")
    add_steps_per_period(s, "integration steps per period of the highest mode (core default 16)")
    _peaks_options(s)
    s.add_argument("--irregularity", default="", help="track irregularity on every deck (DIM only), e.g. "
                   "german-high:seed=3, fra-6:seed=1, german-low:seed=2:band=2:80, file=profile.csv, "
                   "ramp:at=0:length=3:height=0.002 (parts joined by +); default: smooth track as the paper "
                   "(docs/irregularities.md)")
    s.set_defaults(func=cmd_study, dim_grid="window")


def _add_study_fit(sub):
    """``adm-calib study-fit``."""
    f = sub.add_parser("study-fit", help="lower-bound functions (Section 4.2.1, Tables B1-B4) from study results")
    f.add_argument("--results", required=True, help="results.jsonl of a study")
    f.add_argument("--out", default=None, help="output directory (default: the results' directory)")
    f.add_argument("--exclude", choices=("none", "step2", "strict"), default="step2",
                   help="exclusion rule: none = only cases without dz_VBI; step2 (default) = also cases whose "
                        "DIM value is not a local maximum (Section 4, Step 2); strict = also cases whose largest "
                        "MLM value lies at an end of the speed range")
    f.add_argument("--exclude-flagged", action="store_true", help="the same as --exclude strict")
    f.add_argument("--fit-range-hz", default="2:21",
                   help="n0 range of the fit lo:hi in Hz within 2:21 (default 2:21, the paper's intervals; e.g. 2:16 "
                        "keeps the boundaries up to 16 Hz); the fitted functions are 0 above hi")
    f.add_argument("--tag", default="", help="suffix of every output file name (e.g. eurostar_table)")
    add_overwrite(f, "replace existing output files (only once the new ones are complete)", force_alias=True)
    f.set_defaults(func=cmd_study_fit)


def _add_check(sub):
    """``adm-calib check``."""
    k = sub.add_parser("check", help="EN 1991-2 dynamic check as adm-sim check, with all four damping methods "
                                     "(none, adm, lb: the paper's lower bounds, vbi: calibrated Δζ_VBI)")
    add_check_arguments(k)
    k.set_defaults(func=cmd_check_calib)


def build_parser():
    p = Parser(prog="adm-calib", description="Additional-damping calibration (MLM vs DIM) and comparison "
                                               "with the Eurocode ADM, EADA and the lower-bound functions.")
    p.add_version()
    sub = p.add_subparsers(dest="command", required=True)

    _add_calibrate(sub)
    _add_table4(sub)
    _add_recommend(sub)
    _add_study(sub)
    _add_study_fit(sub)
    _add_check(sub)
    return p


def main(argv=None):
    def work():
        args = build_parser().parse_args(argv)
        return args.func(args)

    return run_cli(work)


if __name__ == "__main__":
    sys.exit(main())
