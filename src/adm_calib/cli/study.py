"""``adm-calib study``: the parametric study of paper Section 3.3 on a dask cluster, resumable.

Every input is checked (trains, mass functions, spans, the work of every batch, a scheduler's handshake)
before the study folder is written; then the cases run as batches (:mod:`adm_calib.study.execution`) and
each result is one line of ``results.jsonl``.
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

from adm_sim.cliutil import (add_dim_grid, add_max_work, add_speeds, add_steps_per_period, check_option, option_help,
                             option_view, progress_callback)
from adm_sim.errors import InputError
from adm_sim.files import make_output_folder
from adm_sim.inputs.track_profile import parse_irregularity
from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s

from adm_calib.cli.options import add_peaks_options, comma_list, once, out_dir, speeds_option, steps_per_period_option
from adm_calib.study import MASS_FUNCTION_NAMES, StudySettings, run_study, select_cases
from adm_calib.study.cases import _train
from adm_calib.study.execution import check_scheduler
from adm_calib.study.own_train import check_dim_step, study_step_s, study_trains


def add_arguments(parser):
    """The options of ``adm-calib study``."""
    add_max_work(parser)
    parser.add_argument("--out", required=True, help="study directory: results.jsonl (one line per case) and study.json; "
                                                "rerun with the same --out to resume")
    parser.add_argument("--trains", default="ICE-2,Eurostar,Railjet,ICE-4",
                   help="comma list of ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table and train or vehicle files "
                        "(.toml; the study records each file's content and SHA-256, docs/own_train.md)")
    parser.add_argument("--mass-functions", default="mu1,mu2,mu3,mu4,mu5,mu6", help="Table 1 mass functions")
    parser.add_argument("--spans", default="4:40", help=option_help("--spans", "span range lo:hi (integer spans of the "
                                                                          "field), each end"))
    parser.add_argument("--spans-layout", default="1", help=option_help(
        "--spans-layout", "1 (default): the paper's simply supported spans; N: every case a continuous deck of N "
        "equal spans of the case's span L (pinned over the supports), each span with the mu of the mass function "
        "at L (Eq. 19) and EJ from Eq. (18) with L and the case's n0 at L, so the deck's first frequency is that "
        "n0; damping Table 2 with L the span, the longest (Rayleigh at the deck's modes 1 and 3); 3 N modes; dz_VBI matched "
        "on the largest of the maxima at the middle of every span (MLM and DIM alike); each deck a batch of its "
        "own"))
    parser.add_argument("--freq-index", default="1,2,3,4,5", help=option_help(
        "--freq-index", "n0 per span: 1 = LB ... 3 = fit ... 5 = UB power law; a comma list, each"))
    parser.add_argument("--limit", default=None, help=option_help("--limit", "run at most N of the pending cases"))
    parser.add_argument("--workers", default="2", help=option_help("--workers", "worker processes of the local cluster "
                                                                           "(default 2)"))
    parser.add_argument("--scheduler", default=None, help="address of a running dask scheduler, e.g. "
                                                     "tcp://127.0.0.1:8786 (instead of a local cluster)")
    parser.add_argument("--retry-errors", action="store_true", help="run the cases recorded with status error again")
    add_speeds(parser, "MLM speeds in km/h, start:stop:step", show_default=True)
    add_dim_grid(parser, "DIM speeds: window (default) = the paper's speeds where the associated DIM peak can lie, "
                    "the same results in half the time; paper = the paper's whole grid (Section 3.3); full = all")
    add_steps_per_period(parser, "integration steps per period of the highest mode (core default 16)")
    add_peaks_options(parser)
    parser.add_argument("--irregularity", default="", help="track irregularity on every deck (DIM only), e.g. "
                   "german-high:seed=3, fra-6:seed=1, german-low:seed=2:band=2:80, file=profile.csv, "
                   "ramp:at=0:length=3:height=0.002 (parts joined by +); default: smooth track as the paper "
                   "(docs/irregularities.md)")
    parser.set_defaults(dim_grid="window")


def _mass_functions(text):
    out = []
    for m in comma_list(text, "--mass-functions"):
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
    return sorted(once([check_option("--freq-index", p) for p in comma_list(text, "--freq-index")], "--freq-index", text))


def _scheduler(text):
    """``--scheduler``: an address like tcp://127.0.0.1:8786 where a dask scheduler answers
    (connected with a timeout and checked for the dask handshake before anything is written)."""
    return check_scheduler(text)


def _check_study_work(cases, settings, files=None):
    """The work of every batch's runs (lanes x steps x modes of each sweep, :func:`adm_sim.limits.check_work`),
    refused before anything is written, as the workers would refuse it case by case. ``files``: the trains
    read from files (``{name: TrainFile}``), whose names are no built-in train's."""
    files = files or {}
    v = speeds_to_m_s(settings.speeds_kmh())
    opts = StepOptions(**({} if settings.steps_per_period is None else {"steps_per_period": settings.steps_per_period}))
    trains, seen = {}, set()
    for c in cases:
        if c.batch_key in seen:
            continue
        seen.add(c.batch_key)
        if c.train not in trains:
            trains[c.train] = files[c.train].train if c.train in files else _train(c.train)
        t = trains[c.train]
        make_grid(c.bridge, t.length_m, v, opts)


def run(args):
    """Check every input, then run the pending cases of the study in ``--out``; 130 when interrupted (resumable)."""
    out, _ = out_dir(args.out, "--out", (), True)
    trains, files = study_trains(comma_list(args.trains, "--trains"), "--trains")
    mfs = once(_mass_functions(args.mass_functions), "--mass-functions", args.mass_functions)
    spans = _spans(args.spans)
    layout = check_option("--spans-layout", args.spans_layout)
    fis = _freq_indices(args.freq_index)
    workers = check_option("--workers", args.workers)
    limit = None if args.limit is None else check_option("--limit", args.limit)
    scheduler = None if args.scheduler is None else _scheduler(args.scheduler)
    spp = None if args.steps_per_period is None else steps_per_period_option(args.steps_per_period)
    speeds_option(args.speeds)
    if args.irregularity:
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
    _check_study_work(cases, settings, files)
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
        done = run_study(args.out, cases, settings=settings, workers=workers, scheduler=scheduler, limit=limit,
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
    print(done.summary())
    return 130 if done.interrupted else 0
