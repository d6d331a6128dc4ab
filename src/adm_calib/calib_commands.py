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

Each subcommand is one module of :mod:`adm_calib.cli` with ``add_arguments(parser)`` and ``run(args)``
(:data:`COMMANDS`); only the module of the subcommand that runs is imported
(:func:`adm_sim.cliutil.add_commands`).
"""

from __future__ import annotations

import sys

from adm_sim.cliutil import Parser, add_commands, run_cli, run_command

#: ``(name, module, help)`` of every subcommand, in the order of ``adm-calib --help``.
COMMANDS = (
    ("calibrate", "adm_calib.cli.calibrate", "calibrate dz_VBI for one bridge and one train"),
    ("table4", "adm_calib.cli.table4", "Table 4 and Fig. 19 for the bridges B1-B4 and the four trains"),
    ("recommend", "adm_calib.cli.recommend", "dz from the lower-bound functions by the rules of Section 4.3"),
    ("study", "adm_calib.cli.study", "the parametric study (Section 3.3) on a dask cluster, resumable"),
    ("study-fit", "adm_calib.cli.study_fit", "lower-bound functions (Section 4.2.1, Tables B1-B4) from study results"),
    ("check", "adm_calib.cli.check", "EN 1991-2 dynamic check as adm-sim check, with all four damping methods "
                                     "(none, adm, lb: the paper's lower bounds, vbi: calibrated Δζ_VBI)"),
)


def build_parser(command=None):
    """The parser of ``adm-calib``, with the options of ``command`` (None: of every subcommand)."""
    p = Parser(prog="adm-calib", description="Additional-damping calibration (MLM vs DIM) and comparison "
                                               "with the Eurocode ADM, EADA and the lower-bound functions.")
    p.add_version()
    add_commands(p, COMMANDS, dest="command", command=command)
    return p


def main(argv=None):
    return run_cli(lambda: run_command(build_parser, argv))


if __name__ == "__main__":
    sys.exit(main())
