"""results/irregularity/run_slice.py: its command line is read in ``main`` only (importing it, as
analyse.py does, under any command line works), bad arguments are one line and exit 2, and its
settings are those of the shipped runs."""

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HERE = ROOT / "results" / "irregularity"


@pytest.fixture
def run_slice(monkeypatch):
    # the importer's own command line must not be read: an argument that is no seed
    monkeypatch.setattr(sys, "argv", ["analyse.py", "--not-a-seed", "x"])
    spec = importlib.util.spec_from_file_location("run_slice", HERE / "run_slice.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_import_ignores_argv_and_the_slice_is_60_cases(run_slice):
    cases = run_slice.slice_cases()
    assert len(cases) == 60
    assert sorted({c.span_m for c in cases}) == [float(s) for s in range(4, 41, 4)]
    assert {c.freq_index for c in cases} == {1, 3, 5} and {c.mass_function for c in cases} == {"mu2"}
    assert {c.train for c in cases} == {"ICE-2", "Railjet"}


def test_arguments(run_slice):
    a = run_slice.parse_args([])
    assert a.seeds == (1, 2, 3, 4, 5) and a.workers == 2 and a.out == HERE / "runs"
    a = run_slice.parse_args(["--seeds", "3,4", "--workers", "1", "--out", "/tmp/x"])
    assert a.seeds == (3, 4) and a.workers == 1 and a.out == Path("/tmp/x")
    assert run_slice.parse_args(["--seeds", "0 7"]).seeds == (0, 7)


@pytest.mark.parametrize("argv,line", [
    (["--seeds", "x"], "error: argument --seeds: 'x' is not an integer (allowed: integers >= 0, a comma list)"),
    (["--seeds=-3"], "error: argument --seeds: -3 is negative (allowed: integers >= 0, a comma list)"),
    (["--seeds", ","], "error: argument --seeds: ',' holds no seed (allowed: integers >= 0, a comma list)"),
    (["--workers", "0"], "error: argument --workers: 0 processes is outside [1, 64]"),
    (["--workers", "two"], "error: argument --workers: 'two' is not an integer (allowed: integers in [1, 64] processes)"),
    (["1", "2"], "error: unrecognized arguments: 1 2"),
])
def test_bad_arguments_one_line_exit_2(run_slice, capsys, argv, line):
    with pytest.raises(SystemExit) as exc:
        run_slice.main(argv)
    assert exc.value.code == 2
    out = capsys.readouterr()
    assert out.err == line + "\n" and out.out == ""


def test_settings_are_the_shipped_runs(run_slice):
    """Every shipped run directory was computed on the DIM grid the script asks for."""
    grids = {json.loads((d / "study.json").read_text())["settings"]["dim_grid"] for d in (HERE / "runs").glob("*-s*")}
    assert grids == {run_slice.DIM_GRID} == {"paper"}
