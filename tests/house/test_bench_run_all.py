"""``bench/run_all.py``: it reads each figure and its same-run baseline from what the bench scripts
print, computes the ratio, and rewrites only the table between the markers of docs/benchmarks.md,
whose table has a row for every figure of the default run.

The bench outputs below are lines as the scripts print them (their format strings, filled with
numbers of a run on this machine)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import run_all  # noqa: E402

OUTPUTS = {
    "calibrate": ("calibrate B1 x ICE-2: best 0.182 s of compute (target <= 1 s)\n"
                  "calibrate B1 x ICE-2 on the numpy stepper: 4.550 s (numpy / compiled 25.0x); dz_VBI 0.5533 %\n"),
    "core": ("MLM sweep    0.260 s  peak 2.24652 m/s2 at 263 km/h; half step 2.24690 (change 0.0168 %)\n"
             "LSODA per speed (rtol 1e-06, peak within 0.097 % of ours): 0.600 s -> 114.6 s for 191 speeds\n"
             "ratio MLM sweep vs LSODA per speed: 441x (target >= 200x)\n"),
    "kernels": ("dim        this 0.1389 s\ndim+dense  this 0.1500 s\nmlm        this 0.0065 s\n"
                "numpy stepper dim: 3.892 s (one run); compiled/numpy 0.0357\n"
                "numpy stepper mlm: 0.650 s (one run); compiled/numpy 0.0100\n"),
    "check": ("whole check, whole deck (+ 2346 refinement speeds, every effect, SLS):   1.006 /   0.998 s (target <= 3 s)\n"
              "whole check with mass bounds -10 %/+15 % (three bridges):       2.000 /   1.900 s\n"
              "per-speed per-train RK4 loop:                          2,103.6 /   421.2 s (84 runs measured)\n"),
    "irregularity": "  smooth track      0.068 s\n  German high, s1   0.071 s   ratio rough/smooth 1.044 (target <= 1.2)\n",
    "spans": ("MLM 1x30          191 speeds   3126 steps  3 modes   0.005 s    2.47 ns per lane-step-mode\n"
              "MLM 2x15          191 speeds   4717 steps  3 modes   0.007 s    2.50 ns per lane-step-mode\n"
              "MLM 1x30 tables   191 speeds   3126 steps  3 modes   0.005 s    2.70 ns per lane-step-mode\n"
              "DIM 1x30           39 speeds   3126 steps  3 modes   0.042 s  107.00 ns per lane-step-mode\n"
              "DIM 2x15           39 speeds   4717 steps  3 modes   0.079 s  132.00 ns per lane-step-mode\n"
              "DIM 1x30 tables    39 speeds   3126 steps  3 modes   0.043 s  118.66 ns per lane-step-mode\n"),
    "ros": ("MLM co-simulation CPU a round trip (last run): bridge_train 180000 us\n"
            "model  in-process    co-sim   ratio  target\n"
            "MLM         0.33s     0.78s   2.36x      3x   10460            6\n"
            "DIM         3.90s    30.70s   7.87x     10x   10460        41840\n"),
    "study": ("  (a) batched, 30 cases of L = 15 m                  3.300 case/s  (9.1 s)\n"
              "  (a) one by one (calibrate), 30 cases                0.104 case/s  (287.0 s)\n"
              "  (b) run_study, 1 worker, 60 cases, L = 39+40 m         49.4 s  (overhead o_1 +1.0 s)\n"
              "  (b) run_study, 2 workers                               32.0 s  (overhead o_2 +1.0 s)\n"),
}
#: (A, B) per row, as the lines above give them
EXPECTED = {"calibrate": [(4.55, 0.182)], "core": [(114.6, 0.26)], "kernels": [(3.892, 0.1389), (0.65, 0.0065)],
            "check": [(421.2, 0.998)], "irregularity": [(0.071, 0.068)],
            "spans": [(2.5, 2.47), (132.0, 107.0)], "ros": [(0.78, 0.33), (30.7, 3.9)],
            "study": [(3.3, 0.104), (49.4, 32.0)]}


@pytest.mark.parametrize("bench", run_all.BENCHES, ids=lambda b: b.name)
def test_each_figure_and_its_baseline_are_read(bench):
    rows = run_all.read_rows(bench, OUTPUTS[bench.name])
    assert [(a, b) for _, a, b in rows] == EXPECTED[bench.name]


@pytest.mark.slow  # runs the bench scripts as processes
def test_the_table_prints_the_ratio_and_names_a_missing_figure():
    calibrate = next(b for b in run_all.BENCHES if b.name == "calibrate")
    core = next(b for b in run_all.BENCHES if b.name == "core")
    text = run_all.table([(calibrate, run_all.read_rows(calibrate, OUTPUTS["calibrate"])),
                          (core, run_all.read_rows(core, "MLM sweep    0.260 s\n"))], (1.0, 2.0))
    rows = [line for line in text.splitlines() if line.startswith("| one calibration") or line.startswith("| MLM")]
    assert f"**{4.55 / 0.182:.3g}x**" in rows[0] and "**25x**" in rows[0]  # 25.0: three digits from 10 up
    assert "missing" in rows[1] and "n/a" in rows[1]
    assert "load average 1.0 before and 2.0 after" in text
    assert run_all.fmt_ratio(0.071, 0.068) == "1.04" and run_all.fmt_ratio(114.6, 0.26) == "441"


def test_write_replaces_only_the_table_between_the_markers(tmp_path):
    page = tmp_path / "b.md"
    page.write_text(f"# B\n\nbefore\n{run_all.MARK}\nold table\n{run_all.MARK}\nafter\n", encoding="utf-8")
    run_all.write_table(page, "| new |")
    assert page.read_text(encoding="utf-8") == f"# B\n\nbefore\n{run_all.MARK}\n| new |\n{run_all.MARK}\nafter\n"
    page.write_text("no markers\n", encoding="utf-8")
    with pytest.raises(SystemExit, match="needs exactly two .* found 0"):
        run_all.write_table(page, "| new |")
    assert page.read_text(encoding="utf-8") == "no markers\n"


def test_docs_benchmarks_table_has_every_row_of_the_default_run():
    text = (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8")
    assert text.count(run_all.MARK) == 2
    table = text.split(run_all.MARK)[1]
    missing = [row.measure for b in run_all.BENCHES if b.default for row in b.rows if f"| {row.measure} |" not in table]
    assert not missing, f"docs/benchmarks.md: rows missing (bench/run_all.py --write docs/benchmarks.md): {missing}"


def test_outputs_are_refused_before_any_bench_runs(tmp_path, capsys):
    """A page without markers, a missing page and a log that exists: one line, exit 2, nothing run
    or written (the refusal comes before the first bench)."""
    page = tmp_path / "page.md"
    page.write_text("no markers\n", encoding="utf-8")
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs" / "irregularity.out").write_text("earlier\n", encoding="utf-8")
    for argv, words in ((["--write", str(page)], "needs exactly two"),
                        (["--write", str(tmp_path / "none.md")], "is not a file"),
                        (["--log", str(tmp_path / "logs")], "irregularity.out exists")):
        assert run_all.main(["--only", "irregularity", *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("error: --") and words in err, err
    assert page.read_text(encoding="utf-8") == "no markers\n"
    assert (tmp_path / "logs" / "irregularity.out").read_text(encoding="utf-8") == "earlier\n"


def test_baseline_comparison_sets_our_figure_of_each_tree_side_by_side():
    """Per row the project's own figure (the compiled calibration; the co-simulated sweep) on both
    trees and their ratio, and each tree's A / B."""
    calibrate = next(b for b in run_all.BENCHES if b.name == "calibrate")
    ros = next(b for b in run_all.BENCHES if b.name == "ros")
    this = [(calibrate, run_all.read_rows(calibrate, OUTPUTS["calibrate"])), (ros, run_all.read_rows(ros, OUTPUTS["ros"]))]
    slower = OUTPUTS["calibrate"].replace("best 0.182 s", "best 0.364 s")
    base = [(calibrate, run_all.read_rows(calibrate, slower)), (ros, run_all.read_rows(ros, ""))]
    rows = run_all.compare_table(this, base, "main").splitlines()[4:]
    assert rows[0].split(" | ")[1:4] == ["compiled kernels: 0.182", "0.364", "**0.500**"]
    assert rows[0].endswith(f"| {4.55 / 0.182:.3g}x | {4.55 / 0.364:.3g}x |")
    assert rows[1].split(" | ")[1:4] == ["co-simulated: 0.78", "missing", "n/a"]  # ours is A for the graph


@pytest.mark.slow  # git starts as a process
def test_an_unknown_baseline_is_refused_before_any_bench_runs(capsys):
    assert run_all.main(["--only", "irregularity", "--baseline", "no-such-revision-here"]) == 2
    err = capsys.readouterr().err
    assert err == "error: --baseline: 'no-such-revision-here' is not a revision of this repository\n"
