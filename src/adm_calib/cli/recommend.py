"""``adm-calib recommend``: Δζ from the lower-bound functions by the rules of paper Section 4.3.

The bridge's n0, mu, type and span (or ``--measured``: n0 and zeta of a monitored bridge), checked against
the field the paper studied; the answer with its conservative verdict, and with ``--verify`` the bridge's
own calibration beside it. ``--functions FILE``: the functions of a train file's own study.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

from adm_sim.cliutil import add_choice, check_option, option_help, option_view
from adm_sim.design.check import check_speeds_kmh
from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.fields import FIELDS, check_range
from adm_sim.inputs.measured import read_measured
from adm_sim.inputs.train_files import load_train
from adm_sim.model.bridge import Bridge, eurocode_damping_pct
from adm_sim.model.plausibility import check_studied_field

from adm_calib.cli.options import as_option, speeds_option, study_train
from adm_calib.recommend_verify import study_verdict, verify
from adm_calib.recommend_warnings import recommendation_warnings
from adm_calib.reference import (DECK_NOTE, FUNCTION_SOURCES, LOWER_BOUND_FILES, STUDY_N0_MAX_HZ, STUDY_SPAN_RANGE_M,
                                 lower_bound_table, recommend, span_from_frequency_m)
from adm_calib.study.own_train import read_functions, read_train_file

#: Range of recommend --mu (kg/m): the 0.5-100 t/m the lower-bound rules accept (the registry's).
MU_RANGE_KG_M = (option_view("--mu").lo, option_view("--mu").hi)


def add_arguments(parser):
    """The options of ``adm-calib recommend``."""
    parser.add_argument("--train", required=True, help="ICE-2, Eurostar, Railjet or ICE-4; with --functions FILE the "
                                                   "train or vehicle file of that study")
    parser.add_argument("--n0", default=None, help="first natural frequency (Hz), 2.1 Hz up to the highest n0 of the study "
                                              "(or --measured)")
    parser.add_argument("--measured", default=None, metavar="PASSAGES.json",
                   help="the monitor's JSON (monitor.py --json): n0 = the median f1 of its identified passages "
                        "(at least 3) instead of --n0")
    parser.add_argument("--mu", required=True, help=option_help("--mu", "mass per length in kg/m, like the bridge specs "
                                                                   "(Table 1 / Eq. 19 print t/m: 1 t/m = 1000 kg/m); "
                                                                   "printed in both"))
    add_choice(parser, "--type", "cfb: concrete/filler beam, sc: steel/composite", required=True)
    parser.add_argument("--span", default=None, help=option_help("--span", "span; estimated from n0 when omitted"))
    parser.add_argument("--deck-spans", default=None,
                   help=option_help("--deck-spans", "a continuous deck's spans joined by '/', e.g. 15/15: refused, "
                                                    "since the lower-bound functions were fitted on simply supported "
                                                    "spans; with --extrapolate answered for the longest span with a "
                                                    "warning; one span is --span"))
    parser.add_argument("--interpolate", action="store_true",
                   help="interpolate linearly between the adjacent mass functions instead of the safe side")
    parser.add_argument("--functions", default="paper",
                   help="lower-bound functions: paper = Tables B1-B4 (default); ours = re-derived from the "
                        "study shipped in results/study (adm-calib study-fit, least squares as the paper); "
                        "conservative = the largest cubic below every retained case of that study (linear programme); "
                        "or FILE, the functions_<train>.toml that study-fit writes for a study of a train file "
                        "(docs/own_train.md)")
    parser.add_argument("--extrapolate", action="store_true",
                   help="answer outside the studied field (span 4..40 m, n0 in the Fig. 8 band, mu within "
                        "Table 1) with a warning instead of refusing (docs/plausibility.md)")
    parser.add_argument("--verify", action="store_true",
                   help="calibrate dz_VBI of this bridge and train (Section 4, seconds) and print min(dz_LB, dz_VBI) "
                        "beside the bound with the calibration's status")
    parser.add_argument("--speeds", default=None, help=option_help("--speeds", "design speed range of --verify, "
                                                                          "start:stop:step (default 160:350:1)"))
    parser.add_argument("--max-line-speed", default=None,
                   help=option_help("--max-line-speed", "maximum line speed V: design speeds 40 m/s .. 1.2 V "
                                                        "(instead of --speeds)"))
    parser.add_argument("--zeta-pct", default=None,
                   help=option_help("--zeta-pct", "the bridge's damping (measured or chosen); default the "
                                                  "EN 1991-2 Table 6.6 lower limit for --type and the span"))
    parser.add_argument("--json", action="store_true", help="print JSON")


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


def _recommend_measured(args):
    """``--measured``: sets ``args.n0`` to the measured n0 (median f1); exactly one of --n0 and
    --measured. Returns the :class:`adm_sim.inputs.measured.MeasuredModes` or None."""
    if args.measured is None:
        if args.n0 is None:
            raise InputError("--n0: not given; give the first natural frequency (Hz) or --measured PASSAGES.json")
        return None
    if args.n0 is not None:
        raise InputError(f"--n0: {args.n0!r} given with --measured {args.measured!r}; give one of them")

    measured = read_measured(args.measured)
    args.n0 = repr(measured.f1_hz)
    return measured


def _own_functions(args):
    """``recommend --functions FILE``: the least-squares functions of a train outside the paper's, from
    the functions file ``study-fit`` wrote beside its study, for ``--train`` the same train file
    (same SHA-256); ``{"train", "table", "source", "cases"}``. None for the built-in sets."""
    if args.functions in LOWER_BOUND_FILES:
        return None
    text = str(args.functions)
    if not (text.endswith(".toml") or Path(text).is_file()):
        raise InputError(f"--functions: {text!r} is not a set or a file; allowed {', '.join(LOWER_BOUND_FILES)} or a "
                         f"functions file of adm-calib study-fit (functions_<train>.toml)")

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


def run(args):
    """Check the bridge against the studied field, recommend Δζ_LB, print it (text or ``--json``)."""
    _recommend_deck(args)  # --deck-spans: refused, or with --extrapolate the longest span with a warning
    own = _own_functions(args)  # --functions FILE (a train of a file), else None
    train = own["train"] if own else study_train(args.train, "--train")
    measured = _recommend_measured(args)  # --measured: n0 from the monitored bridge
    lo_hz = next(iter((own["table"] if own else lower_bound_table(args.functions)[train]).values())).lower_limit_hz
    try:
        n0 = check_range("--n0", args.n0, "Hz", lo=lo_hz, hi=STUDY_N0_MAX_HZ)
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
    return print_recommendation(args, rec, mu_kg_m, zeta_pct=zeta_arg, speeds=speeds, speeds_text=speeds_text, own=own,
                                measured=measured)


def _recommend_deck(args):
    """``recommend --deck-spans A/B/...``: the paper's functions were fitted on simply supported spans
    (Section 3.1), so a continuous deck of two or more spans is refused in one line, or with
    ``--extrapolate`` answered for its longest span with a warning; one span is ``--span``."""
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
        v = as_option("--max-line-speed", "max_line_speed_kmh", check_speeds_kmh, args.max_line_speed)
        return v, (f"{v[0]:g}..{v[-1]:g} km/h (40 m/s .. 1.2 V, V = --max-line-speed {args.max_line_speed} km/h, "
                   f"EN 1991-2 6.4.6.2(1))")
    if args.speeds is not None:
        v = speeds_option(args.speeds)
        return v, f"{v[0]:g}..{v[-1]:g} km/h (--speeds {args.speeds})"
    return None, "160..350 km/h (the study's range, Section 3.3)"


def recommendation_zeta(rec, zeta_pct=None, source=None):
    """ζ (%) of the bridge of a recommendation and its source: the user's (``--zeta-pct``, measured or
    chosen) or EN 1991-2 Table 6.6's lower limit for its type and span (paper Table 2)."""
    if zeta_pct is not None:
        return float(zeta_pct), source or "user, --zeta-pct"
    return (eurocode_damping_pct(rec.span_m, rec.bridge_type),
            f"EN 1991-2 Table 6.6 lower limit for {rec.bridge_type.upper()}, L = {rec.span_m:.3g} m (paper Table 2)")


def verify_recommendation(rec, mu_kg_m, *, zeta_pct=None, speeds=None, speeds_text="", option="--speeds", train=None,
                          zeta_source=None):
    """``recommend --verify``: the calibration of the asked bridge (L, n0, mu, ζ of the
    recommendation) under its train (:func:`adm_calib.recommend_verify.verify`). A range whose
    calibration finds no resonance is refused (one line naming ``option``)."""
    zeta, source = recommendation_zeta(rec, zeta_pct, zeta_source)
    bridge = Bridge.from_frequency(rec.span_m, rec.n0_hz, mu_kg_m, zeta / 100.0, bridge_type=rec.bridge_type)
    ver = verify(rec.delta_zeta_pct, bridge, load_train(train or rec.train), speeds, zeta_source=source, speeds_text=speeds_text)
    r = ver.calibration
    if r.status in ("no_mlm_peak", "no_resonance_in_range", "grid_too_coarse"):
        raise InputError(f"{option}: {speeds_text or '160..350 km/h'} cannot show the resonance of {rec.train} on this "
                         f"bridge ({r.status}: {r.message}); allowed: a range holding an MLM peak, e.g. --speeds "
                         f"160:420:1")
    return ver


def print_recommendation(args, rec, mu_kg_m, *, zeta_pct=None, speeds=None, speeds_text="", own=None, measured=None):
    """Print one recommendation (text or ``--json``) with its conservative verdict and, with
    ``--verify``, the own calibration beside it. Other options (``--functions``, ``--measured``)
    reach here through ``args`` and ``rec``."""
    zeta_source = (f"measured, --measured ({measured.n_used} passages)"
                   if measured is not None and getattr(args, "zeta_pct", None) is None else None)
    option = "--max-line-speed" if getattr(args, "max_line_speed", None) is not None else "--speeds"
    ver = (verify_recommendation(rec, mu_kg_m, zeta_pct=zeta_pct, speeds=speeds, speeds_text=speeds_text, option=option,
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

