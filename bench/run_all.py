"""Every bench that carries its own baseline, run once, and one table of the results.

    .venv/bin/python bench/run_all.py [--table] [--only NAME ...] [--all] [--write docs/benchmarks.md]
        [--log DIR] [--baseline REV]

Each bench script of ``bench/`` runs in its own process, one after the other (a 2-core machine:
nothing runs beside them but what the bench itself starts), with short settings; every figure
is read from what the script prints. Each row sets a figure against a baseline **measured in the
same run** (the paper's way of integrating, a per-speed loop, the numpy stepper, the in-process
sweep, the smooth track), so the ratio holds on a machine whose speed varies from hour to hour
even when the absolute times do not. Asserts nothing about time.

The default run takes a few minutes on a quiet machine (the first run of a fresh checkout also
compiles the numba kernels: ``adm-sim compile`` first). ``--all`` adds the study bench (batched
against one-by-one cases: several minutes more). ``--table`` prints the Markdown table of
docs/benchmarks.md; ``--write FILE`` also replaces the table between the ``<!-- bench-table -->``
markers of FILE (asked for explicitly: nothing is written otherwise). ``--log DIR`` keeps each
bench's whole output in ``DIR/<name>.out`` (an existing file is not replaced).

``--baseline REV`` runs every bench also on the code of git revision REV (``src``, ``bench``,
``launch_scripts`` and ``ros_ws`` unpacked once into ``<tmp>/adm-sim-bench-<commit>``, its ``src``
first on ``PYTHONPATH``), the two trees alternating which goes first, and prints a second table:
per row the project's own figure on both trees and their ratio, and the A / B ratio of each tree.
Its first run compiles the baseline's numba kernels; later runs reuse them.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NUMBER = r"([0-9][0-9,]*\.?[0-9]*(?:e[-+]?\d+)?)"
MARK = "<!-- bench-table -->"


@dataclasses.dataclass(frozen=True)
class Row:
    """One figure against its baseline: ``a / b`` is the ratio printed."""

    measure: str
    a: str        #: what the first number is
    a_re: str     #: regex whose group 1 is it (in the bench's output)
    b: str
    b_re: str
    target: str = ""
    ours: str = "b"  #: which figure is the project's own path ("a" or "b"): compared across trees


@dataclasses.dataclass(frozen=True)
class Bench:
    name: str
    argv: tuple
    rows: tuple
    default: bool = True


BENCHES = (
    Bench("calibrate", ("bench_calibrate.py", "--no-table4", "--numpy"), (
        Row("one calibration, B1 x ICE-2 (Section 4), s of compute",
            "numpy stepper", r"on the numpy stepper: " + NUMBER + " s",
            "compiled kernels", r"best " + NUMBER + " s of compute", "compiled <= 1 s"),)),
    Bench("core", ("bench_core.py",), (
        Row("MLM sweep, B1 x ICE-2, 191 speeds (RK4, converged), s",
            "LSODA, one integration per speed (the paper's way)", r"-> " + NUMBER + " s for 191 speeds",
            "one vectorised sweep", r"MLM sweep\s+" + NUMBER + " s", ">= 200x"),)),
    Bench("kernels", ("bench_kernels.py", "--rounds", "1", "--reps", "2", "--numpy"), (
        Row("DIM batch, 48 lanes (6 bridges x 8 speeds), s CPU",
            "numpy stepper", r"numpy stepper dim: " + NUMBER + " s",
            "compiled kernel", r"^dim\s+this " + NUMBER + " s"),
        Row("MLM batch, 48 lanes, s CPU",
            "numpy stepper", r"numpy stepper mlm: " + NUMBER + " s",
            "compiled kernel", r"^mlm\s+this " + NUMBER + " s"))),
    Bench("check", ("bench_check.py", "--every", "48", "--repeat", "1"), (
        Row("EN 1991-2 check, B1, 14 trains x 277 speeds, whole deck, every effect, s CPU",
            "per-speed, per-train RK4 loop (scaled)", r"per-speed per-train RK4 loop:\s+\S+ / +" + NUMBER + " s",
            "whole check (exact envelopes)", r"whole check, whole deck [^:]*:\s+\S+ /\s+" + NUMBER + " s",
            "check <= 3 s"),)),
    Bench("irregularity", ("bench_irregularity.py", "--reps", "2"), (
        Row("DIM batch on a rough track (German high), 48 lanes, s CPU",
            "rough track", r"German high, s1\s+" + NUMBER + " s",
            "smooth track", r"smooth track\s+" + NUMBER + " s", "<= 1.2x", ours="a"),)),
    Bench("spans", ("bench_spans.py",), (
        Row("MLM sweep of a 2 x 15 m continuous deck, 191 speeds, ns per lane-step-mode",
            "2 x 15 m deck", r"^MLM 2x15\s.*?" + NUMBER + " ns per lane-step-mode",
            "one 30 m span", r"^MLM 1x30\s.*?" + NUMBER + " ns per lane-step-mode", "<= 2x", ours="a"),
        Row("DIM sweep of a 2 x 15 m continuous deck (ICE-2), 39 speeds, ns per lane-step-mode",
            "2 x 15 m deck", r"^DIM 2x15\s.*?" + NUMBER + " ns per lane-step-mode",
            "one 30 m span", r"^DIM 1x30\s.*?" + NUMBER + " ns per lane-step-mode", "<= 2x", ours="a"))),
    Bench("ros", ("bench_ros.py", "--models", "mlm,dim"), (
        Row("MLM sweep over ROS 2 (bridge and train nodes), 191 lanes, s",
            "co-simulated", r"^MLM\s+\S+s\s+" + NUMBER + "s",
            "in-process", r"^MLM\s+" + NUMBER + "s", "<= 3x", ours="a"),
        Row("DIM sweep over ROS 2 (one round trip per RK4 stage), 191 lanes, s",
            "co-simulated", r"^DIM\s+\S+s\s+" + NUMBER + "s",
            "in-process", r"^DIM\s+" + NUMBER + "s", "<= 10x", ours="a"))),
    Bench("study", ("bench_study.py", "--sample-spans", "15", "--worker-spans", "39,40"), (
        Row("study cases of L = 15 m (ICE-2), cases/s",
            "batched (one kernel run per batch of six)", r"^  \(a\) batched[^\n]*?\s" + NUMBER + " case/s",
            "one by one", r"^  \(a\) one by one[^\n]*?\s" + NUMBER + " case/s", ">= 10x", ours="a"),
        Row("study cases of L = 39 + 40 m on a local dask cluster, s",
            "1 worker", r"^  \(b\) run_study, 1 worker[^\n]*?\s" + NUMBER + " s",
            "2 workers", r"^  \(b\) run_study, 2 workers\s+" + NUMBER + " s", ">= 1.8x", ours="b")), default=False),
)


def number(text):
    return float(text.replace(",", ""))


def read_rows(bench, out):
    """``[(row, a, b)]`` from a bench's output; a figure that is missing is ``None`` (said in the table)."""
    found = []
    for row in bench.rows:
        a, b = (re.search(rx, out, flags=re.M) for rx in (row.a_re, row.b_re))
        found.append((row, number(a.group(1)) if a else None, number(b.group(1)) if b else None))
    return found


def run(bench, log_dir=None, tree=None):
    """Run one bench script of this checkout, or of ``tree`` (a baseline unpacked by
    :func:`baseline_tree`, its ``src`` first on the path); returns ``(output, seconds)``."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "ADM_SIM_QUIET_COMPILE": "1",
           "FASTDDS_BUILTIN_TRANSPORTS": "SHM", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    root = ROOT if tree is None else Path(tree)
    if tree is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(root / "src"), *filter(None, [env.get("PYTHONPATH")])])
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, str(root / "bench" / bench.argv[0]), *bench.argv[1:]], cwd=root,
                          env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    out = done.stdout + done.stderr
    if log_dir is not None:
        path = Path(log_dir) / f"{bench.name}{'' if tree is None else '.baseline'}.out"
        with open(path, "x", encoding="utf-8") as f:  # never replaces an earlier log
            f.write(out)
    if done.returncode != 0:
        out += f"\n(exit {done.returncode})"
    return out, seconds


#: what a baseline tree needs of the checkout (the benches, the code, the launch scripts and params of bench_ros)
BASELINE_PARTS = ("src", "bench", "launch_scripts", "ros_ws")


def resolve(rev):
    """The full commit of ``rev``, or ``None`` when git does not know it."""
    done = subprocess.run(["git", "rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}"], cwd=ROOT,
                          capture_output=True, text=True)
    return done.stdout.strip() or None


def baseline_tree(sha):
    """``src``, ``bench``, ``launch_scripts`` and ``ros_ws`` of commit ``sha`` unpacked once into a folder
    of the temporary directory that later runs reuse (its numba cache included)."""
    import tempfile

    tree = Path(tempfile.gettempdir()) / f"adm-sim-bench-{sha[:12]}"
    if not (tree / ".complete").exists():
        tree.mkdir(exist_ok=True)
        archive = subprocess.run(["git", "archive", sha, *BASELINE_PARTS], cwd=ROOT, capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive.stdout, check=True)
        (tree / ".complete").write_text(sha + "\n", encoding="utf-8")
    return tree


def compare_table(results, base_results, rev):
    """This tree against the baseline tree, row by row: the project's own figure of each row and the
    A / B ratio of each tree."""
    lines = [f"Against `{rev}` (each bench run on both trees, one after the other, in this run):", "",
             "| measure | ours, this tree | ours, baseline tree | this / baseline | A / B this | A / B baseline |",
             "|---|---|---|---|---|---|"]
    for (_, rows), (_, base_rows) in zip(results, base_results, strict=True):
        for (row, a, b), (_, a0, b0) in zip(rows, base_rows, strict=True):
            mine, theirs = (a, a0) if row.ours == "a" else (b, b0)
            lines.append(f"| {row.measure} | {getattr(row, row.ours)}: {fmt(mine)} | {fmt(theirs)} | "
                         f"{f'**{mine / theirs:.3f}**' if mine and theirs else 'n/a'} | "
                         f"{fmt_ratio(a, b) + 'x' if a and b else 'n/a'} | {fmt_ratio(a0, b0) + 'x' if a0 and b0 else 'n/a'} |")
    return "\n".join(lines)


def commit():
    def git(*a):
        return subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    return git("rev-parse", "--short", "HEAD") + ("+changes" if git("status", "--porcelain", "--", "src", "bench") else "")


def fmt(x):
    if x is None:
        return "missing"
    return f"{x:.3g}" if x < 100 else f"{x:,.0f}"


def fmt_ratio(a, b):
    r = a / b
    return f"{r:.2f}" if r < 10 else f"{r:.3g}"


def table(results, load):
    lines = [f"Measured at commit `{commit()}` on {os.cpu_count()} cores, load average {load[0]:.1f} before and "
             f"{load[1]:.1f} after (`bench/run_all.py --table`).", "",
             "| measure | A | B, the baseline in the same run | A / B | target | bench |", "|---|---|---|---|---|---|"]
    for bench, rows in results:
        for row, a, b in rows:
            ratio = f"**{fmt_ratio(a, b)}x**" if a and b else "n/a"
            lines.append(f"| {row.measure} | {row.a}: {fmt(a)} | {row.b}: {fmt(b)} | {ratio} | {row.target} | "
                         f"`bench/{bench.argv[0]}` |")
    return "\n".join(lines)


def write_table(path, text):
    page = Path(path).read_text(encoding="utf-8")
    parts = page.split(MARK)
    if len(parts) != 3:
        raise SystemExit(f"error: --write: {path} needs exactly two '{MARK}' markers; found {len(parts) - 1}")
    Path(path).write_text(parts[0] + MARK + "\n" + text + "\n" + MARK + parts[2], encoding="utf-8")


def check_outputs(args, chosen):
    """Why the outputs cannot be written (one line), before any bench runs; ``None`` when they can."""
    if args.write:
        page = Path(args.write)
        if not page.is_file():
            return f"--write: {args.write} is not a file"
        if page.read_text(encoding="utf-8").count(MARK) != 2:
            return f"--write: {args.write} needs exactly two '{MARK}' markers"
    if args.log:
        names = [f"{b.name}{suffix}.out" for b in chosen for suffix in ("", ".baseline")]
        taken = [str(Path(args.log) / n) for n in names if (Path(args.log) / n).exists()]
        if taken:
            return f"--log: {', '.join(taken)} exists (an earlier log is never replaced)"
    return None


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", action="store_true", help="print the Markdown table of docs/benchmarks.md")
    ap.add_argument("--only", action="append", choices=[b.name for b in BENCHES], help="run only these benches")
    ap.add_argument("--all", action="store_true", help="also the benches left out of the default run (the study)")
    ap.add_argument("--write", metavar="FILE", help="replace the table between the bench-table markers of FILE")
    ap.add_argument("--log", metavar="DIR", help="keep each bench's output in DIR/<name>.out")
    ap.add_argument("--baseline", metavar="REV", help="also run every bench on the code of git revision REV and "
                                                      "compare (its tree unpacked once into the temporary directory)")
    args = ap.parse_args(argv)
    chosen = [b for b in BENCHES if (b.name in args.only if args.only else (b.default or args.all))]
    refusal = check_outputs(args, chosen)
    sha = None
    if not refusal and args.baseline is not None:
        sha = resolve(args.baseline)
        refusal = None if sha else f"--baseline: {args.baseline!r} is not a revision of this repository"
    if refusal:
        print(f"error: {refusal}", file=sys.stderr)
        return 2
    if args.log:
        Path(args.log).mkdir(parents=True, exist_ok=True)
    tree = None if sha is None else baseline_tree(sha)
    load0 = os.getloadavg()[0]
    results, base_results = [], []
    for i, bench in enumerate(chosen):
        print(f"running bench/{bench.argv[0]} {' '.join(bench.argv[1:])} ...", file=sys.stderr, flush=True)
        trees = [None] if tree is None else ([None, tree] if i % 2 == 0 else [tree, None])  # alternate who goes first
        for t in trees:
            out, seconds = run(bench, args.log, t)
            rows = read_rows(bench, out)
            (results if t is None else base_results).append((bench, rows))
            for row, a, b in rows:
                ratio = f"{fmt_ratio(a, b)}x" if a and b else "n/a (figure missing: see --log)"
                print(f"  {'' if t is None else '[baseline] '}{row.measure}: {row.a} {fmt(a)}, {row.b} {fmt(b)}, "
                      f"ratio {ratio}{'; target ' + row.target if row.target else ''}", file=sys.stderr, flush=True)
            print(f"  ({seconds:.0f} s)", file=sys.stderr, flush=True)
    text = table(results, (load0, os.getloadavg()[0]))
    if tree is not None:
        text += "\n\n" + compare_table(results, base_results, f"{args.baseline}` = `{sha[:12]}")
    if args.table or not args.write:
        print(text)
    if args.write:
        write_table(args.write, text)
    return 0 if all(a and b for _, rows in results for _, a, b in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
