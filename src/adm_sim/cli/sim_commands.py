"""``adm-sim``: speed sweeps, train data checks, kernel compilation and MCAP salvage from the command line.

Errors are one line ``error: ...`` on stderr: bad input exits with code 2, a run that fails for
another reason (e.g. an integration that became unstable) with 1, an interrupt with 130
(:func:`adm_sim.cliutil.run_cli`). Mass per length is kg/m in and out (t/m shown beside it).

Each subcommand is one module of :mod:`adm_sim.cli` with ``add_arguments(parser)`` and ``run(args)``
(:data:`COMMANDS`); only the module of the subcommand that runs is imported
(:func:`adm_sim.cliutil.add_commands`).
"""

from __future__ import annotations

import sys

from adm_sim.cliutil import Parser, add_commands, freeze_at_exit, run_cli, run_command

#: ``(name, module, help)`` of every subcommand, in the order of ``adm-sim --help``.
COMMANDS = (
    ("sweep", "adm_sim.cli.sweep", "max midspan acceleration over a speed range"),
    ("check", "adm_sim.cli.check", "EN 1991-2 dynamic check: envelopes of HSLM-A and real trains, verdict "
                                   "(--damping lb|vbi: adm-calib check)"),
    ("trains", "adm_sim.cli.trains", "list trains; --check compares axle loads and bogie frequencies"),
    ("bridges", "adm_sim.cli.bridges", "list bridges B1-B4 or (--field) the 1110-bridge parametric field"),
    ("compile", "adm_sim.cli.compile", "compile the numba kernels once, ahead of the first run (set-up)"),
    ("salvage", "adm_sim.cli.salvage", "recover a killed run's MCAP log"),
)


def build_parser(command=None):
    """The parser of ``adm-sim``, with the options of ``command`` (None: of every subcommand)."""
    p = Parser(prog="adm-sim", description=__doc__.splitlines()[0], name_prog=True)
    p.add_version()
    add_commands(p, COMMANDS, dest="cmd", command=command)
    return p


def main(argv=None):
    if argv is None:  # the process's own command line: its exit skips the last garbage collections
        freeze_at_exit()
    return run_cli(lambda: run_command(build_parser, argv))


if __name__ == "__main__":
    sys.exit(main())
