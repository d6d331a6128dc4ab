"""One module per subcommand: ``adm-sim`` and ``adm-calib`` list ``(name, module, help)`` and import only the
module of the subcommand that runs, so ``--help``, ``--version`` and a refusal do not pay for the others."""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from adm_calib import calib_commands
from adm_sim.cli import sim_commands
from adm_sim.cliutil import command_named

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = {"adm-sim": sim_commands, "adm-calib": calib_commands}
#: every subcommand module of both programs
COMMAND_MODULES = sorted(m for p in PROGRAMS.values() for _, m, _ in p.COMMANDS)


def _subparsers(parser):
    return next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction").choices


@pytest.mark.parametrize("program", PROGRAMS)
def test_every_subcommand_is_one_module_named_after_it(program):
    """Each subcommand's module holds ``add_arguments`` and ``run``, lives in the program's ``cli`` folder and
    is named after the subcommand (``study-fit`` -> ``study_fit``); the table lists each name once."""
    entry = PROGRAMS[program]
    names = [name for name, _, _ in entry.COMMANDS]
    assert len(set(names)) == len(names) >= 6
    package = "adm_sim.cli" if program == "adm-sim" else "adm_calib.cli"
    for name, module, text in entry.COMMANDS:
        assert module == f"{package}.{name.replace('-', '_')}"
        mod = importlib.import_module(module)
        assert callable(mod.add_arguments) and callable(mod.run), module
        assert text and mod.__doc__.startswith(f"``{program} {name}``"), module


@pytest.mark.parametrize("program", PROGRAMS)
def test_the_parser_of_one_subcommand_is_the_one_of_the_whole_program(program):
    """``build_parser(name)`` (what a run builds) gives the subcommand the same options and help as the
    parser of every subcommand (what docs/cli.md is checked against), and the others none."""
    entry = PROGRAMS[program]
    full = _subparsers(entry.build_parser())
    for name, _, _ in entry.COMMANDS:
        one = _subparsers(entry.build_parser(name))
        assert list(one) == list(full)
        assert one[name].format_help() == full[name].format_help()
        others = [n for n in one if n != name]
        assert all(len(one[n]._actions) == 1 for n in others)  # --help alone
    none = _subparsers(entry.build_parser(""))
    assert all(len(p._actions) == 1 for p in none.values())


@pytest.mark.parametrize("argv, named", [([], ""), (["--version"], ""), (["--help"], ""), (["sweep"], "sweep"),
                                         (["sweep", "--speeds", "x"], "sweep"), (["--help", "check"], "check"),
                                         (["swep", "--speeds", "x"], "swep")])
def test_command_named(argv, named):
    assert command_named(argv) == named


PROBE = """
import contextlib, io, json, sys
from importlib import import_module
entry = import_module(sys.argv[1])
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    try:
        rc = entry.main(json.loads(sys.argv[2]))
    except SystemExit as exc:  # argparse's --help and --version
        rc = exc.code
print(json.dumps({"rc": rc, "loaded": sorted(m for m in json.loads(sys.argv[3]) if m in sys.modules)}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("program, argv, code, loaded", [
    ("adm-sim", ["--help"], 0, []),
    ("adm-sim", ["--version"], 0, []),
    ("adm-sim", ["swep"], 2, []),
    ("adm-sim", ["sweep", "--speeds", "x"], 2, ["adm_sim.cli.sweep"]),
    ("adm-sim", ["check", "--max-line-speed", "200", "--where", "roof"], 2, ["adm_sim.cli.check"]),
    ("adm-calib", ["--help"], 0, []),
    ("adm-calib", ["recommend", "--train", "ICE-2", "--n0", "x", "--mu", "15000", "--type", "cfb"], 2,
     ["adm_calib.cli.recommend"]),
    ("adm-calib", ["check", "--max-line-speed", "x"], 2, ["adm_calib.cli.check", "adm_sim.cli.check"]),
])
def test_a_run_imports_only_the_module_of_its_subcommand(program, argv, code, loaded):
    """In a fresh process: the program's ``--help``, ``--version`` and an unknown subcommand import no
    subcommand module; a refusal imports its own (and ``adm-calib check`` the core's check it extends)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    p = subprocess.run([sys.executable, "-c", PROBE, PROGRAMS[program].__name__, json.dumps(argv),
                        json.dumps(COMMAND_MODULES)], capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert out == {"rc": code, "loaded": loaded}
