"""``adm-calib study-fit``: the lower-bound functions of paper Section 4.2.1 (Tables B1-B4) from a study's results.

The result lines are checked first (a NaN or text where a number belongs is refused naming its record); the
fit, its figures, the comparison with Appendix B, the conservative bound and, for a train file's study,
its functions file are written all or none.
"""

from __future__ import annotations

import re

from adm_sim.cliutil import add_overwrite
from adm_sim.errors import InputError
from adm_sim.fields import check_range
from adm_sim.files import OutputSet, input_file, make_output_folder
from adm_sim.limits import MAX_DELTA_ZETA_PCT

from adm_calib import plots
from adm_calib import study as st
from adm_calib.cli.options import as_option, out_dir
from adm_calib.peaks import has_delta_zeta
from adm_calib.recommend_warnings import study_cases_csv
from adm_calib.study import MASS_FUNCTION_NAMES, fit_edges_hz, own_train
from adm_calib.study.conservative import conservative_markdown, conservative_study, conservative_toml


def add_arguments(parser):
    """The options of ``adm-calib study-fit``."""
    parser.add_argument("--results", required=True, help="results.jsonl of a study")
    parser.add_argument("--out", default=None, help="output directory (default: the results' directory)")
    parser.add_argument("--exclude", choices=("none", "step2", "strict"), default="step2",
                   help="exclusion rule: none = only cases without dz_VBI; step2 (default) = also cases whose "
                        "DIM value is not a local maximum (Section 4, Step 2); strict = also cases whose largest "
                        "MLM value lies at an end of the speed range")
    parser.add_argument("--exclude-flagged", action="store_true", help="the same as --exclude strict")
    parser.add_argument("--fit-range-hz", default="2:21",
                   help="n0 range of the fit lo:hi in Hz within 2:21 (default 2:21, the paper's intervals; e.g. 2:16 "
                        "keeps the boundaries up to 16 Hz); the fitted functions are 0 above hi")
    parser.add_argument("--tag", default="", help="suffix of every output file name (e.g. eurostar_table)")
    add_overwrite(parser, "replace existing output files (only once the new ones are complete)", force_alias=True)


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
            check_range(f"{where}: {key}", value, unit, lo=lo, hi=hi, lo_open=lo is not None)
        # a calibration's Δζ lies in (-ζ, 20 %] (ζ + Δζ > 0, the bracketing ladder's top); where the
        # record does not carry ζ, in [-20 %, 20 %]
        zeta = rec.get("zeta_pct")
        known = isinstance(zeta, (int, float)) and not isinstance(zeta, bool) and zeta > 0
        check_range(f"{where}: delta_zeta_vbi_pct", rec["delta_zeta_vbi_pct"], "%",
                    lo=-float(zeta) if known else -MAX_DELTA_ZETA_PCT, hi=MAX_DELTA_ZETA_PCT, lo_open=known)


def _fit_range_hz(text):
    """``--fit-range-hz lo:hi`` (Hz) -> the interval boundaries of the fit (:func:`fit_edges_hz`)."""
    parts = [p.strip() for p in str(text).split(":")]
    try:
        if len(parts) != 2:
            raise ValueError
        lo, hi = (float(p) for p in parts)
    except ValueError:
        raise InputError(f"--fit-range-hz: {text!r} is not lo:hi in Hz (e.g. 2:16); allowed within [2, 21] Hz") from None
    return as_option("--fit-range-hz", "fit_range_hz", fit_edges_hz, lo, hi)


def _tag(text):
    if text and not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,39}", text):
        raise InputError(f"--tag: {text!r} is not a file-name suffix; allowed 1-40 letters, digits, '_', '.', '-' "
                         f"(starting with a letter or digit)")
    return text


def run(args):
    """Check the results, fit, print the fit, write every file of it (all or none)."""
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
    out, path_list = out_dir(args.out if args.out is not None else str(res.parent), "--out", names, args.force,
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
            write(names[7], lambda p: plots.plot_lower_bound_set(fit, "ICE-2", "mu3", p, conservative=cons))
        write(names[8], lambda p: p.write_text(conservative_markdown(rows, fit)))
        write(names[9], lambda p: p.write_text(conservative_toml(rows, fit, command=command)))
        for t in fit.trains:
            write(fig17[t], lambda p, t=t: plots.plot_lower_bounds_train(fit, t, p, cons))
        if own:
            for t, (rec, _) in own.items():
                cases = study_cases_csv([r for r in content.records if r["train"] == t], rule)
                write(functions[t], lambda p, t=t, rec=rec, cases=cases: p.write_text(own_train.functions_toml(
                    t, rec, fit, rows, cases_csv=cases, quantities=quantities[t], command=command,
                    study_dir=res.parent.resolve())))
    print(f"wrote {len(written)} files to {out}")
    return 0
