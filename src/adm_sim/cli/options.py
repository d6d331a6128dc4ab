"""Option groups that several subcommands of ``adm-sim`` share (the single options are in :mod:`adm_sim.cliutil`)."""

from __future__ import annotations

from adm_sim.cliutil import add_overwrite, add_progress


def add_output_options(parser, outputs, overwrite_help):
    """The output files (``--json`` etc., each with its help), ``--overwrite`` and ``--progress``."""
    for name, text in outputs.items():
        parser.add_argument(f"--{name}", help=text)
    add_overwrite(parser, overwrite_help)
    add_progress(parser)
