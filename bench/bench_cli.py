"""The commands as a user meets them: whole process from the shell, this tree against a baseline tree.

Times ``adm-sim sweep --model mlm``, ``adm-sim sweep --model dim`` (B1 x ICE-2, 160..350 km/h at
1 km/h) and ``adm-sim check --bridge B1 --max-line-speed 300`` as whole processes (interpreter
start, imports, loading the compiled kernels from numba's cache, the work, the output), warm: one
untimed run of each command per tree first (it also fills a tree's numba cache), then ``--repeat``
timed runs, the two trees alternating so that both meet the same load of the shared machine.
Prints the median and the best wall time and CPU time (user + system of the process and its
children: less swayed by the load of a shared machine) per command and tree, and the ratios
baseline / this.

``--first-run``: copies this tree's ``src`` (no ``__pycache__``, so no numba cache) to a temporary
folder and times ``adm-sim compile`` (the set-up step that compiles the kernels once), then the
first ``check`` and the first DIM sweep after it, against warm runs of the same copy; and, in a
second fresh copy, the first ``check`` without the compile step (it compiles on first use and
says so on stderr).

``--startup``: the start of both programs instead, where no work is done: ``--help``, a refusal of bad
input (exit 2) and a subcommand's ``--help`` (:data:`STARTUP`), best of ``--repeat`` per tree, the trees
alternating; each program imports only the module of the subcommand it runs.

A baseline tree is any checkout of the project, e.g. ``git archive 4810c5f | tar -x -C /tmp/base``.
Asserts nothing about time.

Run: .venv/bin/python bench/bench_cli.py --baseline /tmp/base [--repeat 5] [--first-run | --startup]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = {
    "sweep mlm": ["sweep", "--bridge", "B1", "--train", "ICE-2", "--model", "mlm"],
    "sweep dim": ["sweep", "--bridge", "B1", "--train", "ICE-2", "--model", "dim"],
    "check B1": ["check", "--bridge", "B1", "--max-line-speed", "300"],
}

#: The start of a command where it does no work: (program, argv, exit code).
STARTUP = {
    "adm-sim --help": ("adm-sim", ["--help"], 0),
    "adm-sim sweep --speeds x": ("adm-sim", ["sweep", "--speeds", "x"], 2),
    "adm-calib --help": ("adm-calib", ["--help"], 0),
    "adm-sim sweep --help": ("adm-sim", ["sweep", "--help"], 0),
    "adm-sim check --help": ("adm-sim", ["check", "--help"], 0),
    "adm-calib calibrate --help": ("adm-calib", ["calibrate", "--help"], 0),
    "adm-calib recommend --n0 x": ("adm-calib", ["recommend", "--train", "ICE-2", "--n0", "x", "--mu", "15000",
                                                 "--type", "cfb"], 2),
}
#: The entry module of each program (what its console script imports).
ENTRY = {"adm-sim": "adm_sim.cli.sim_commands", "adm-calib": "adm_calib.calib_commands"}


def adm_sim_script(python, program="adm-sim"):
    """The console script of ``program`` beside the interpreter (what the user types), else ``-m``."""
    script = Path(python).with_name(program)
    return [str(script)] if script.exists() else [python, "-m", ENTRY[program]]


def _children_cpu_s():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(tree, argv, python, check=True, cpu=None):
    """Wall time (s) of one whole process of ``adm-sim argv`` importing ``tree/src``, and its stderr;
    its CPU time (user + system, s) is appended to the list ``cpu`` if given."""
    env = dict(os.environ, PYTHONPATH=str(Path(tree) / "src"), OPENBLAS_NUM_THREADS="1")
    c0, t0 = _children_cpu_s(), time.perf_counter()
    p = subprocess.run(adm_sim_script(python) + argv, env=env, cwd=tree, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if cpu is not None:
        cpu.append(_children_cpu_s() - c0)
    if check and p.returncode != 0:
        raise SystemExit(f"error: adm-sim {' '.join(argv)} in {tree} exited {p.returncode}: {p.stderr.strip()[-400:]}")
    return wall, p.stderr


def side_by_side(trees, python, repeat, names):
    """Wall and CPU times per (command, tree), trees alternating run by run."""
    times = {(c, t): [] for c in names for t in trees}
    cpu = {(c, t): [] for c in names for t in trees}
    for c in names:
        for t in trees:
            run(t, COMMANDS[c], python)  # warm-up (and compile into the tree's cache if it has none)
        for _ in range(repeat):
            for t in trees:
                times[c, t].append(run(t, COMMANDS[c], python, cpu=cpu[c, t])[0])
    return times, cpu


def copy_src(dst):
    """This tree's ``src`` in ``dst`` without any ``__pycache__`` (no numba cache: a fresh clone)."""
    shutil.copytree(ROOT / "src", Path(dst) / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    return Path(dst)


def startup(trees, python, repeat):
    """Best wall time and best CPU time (user + system, s) per (start-up case, tree), the trees alternating
    run by run; the exit code of each run checked."""
    best, best_cpu = {}, {}
    for name, (program, argv, code) in STARTUP.items():
        for _ in range(repeat):
            for t in trees:
                env = dict(os.environ, PYTHONPATH=str(Path(t) / "src"))
                c0, t0 = _children_cpu_s(), time.perf_counter()
                p = subprocess.run(adm_sim_script(python, program) + argv, env=env, cwd=t, capture_output=True)
                wall, cpu = time.perf_counter() - t0, _children_cpu_s() - c0
                if p.returncode != code:
                    raise SystemExit(f"error: {program} {' '.join(argv)} in {t} exited {p.returncode}, not {code}")
                best[name, t] = min(best.get((name, t), wall), wall)
                best_cpu[name, t] = min(best_cpu.get((name, t), cpu), cpu)
    return best, best_cpu


def first_run(python, repeat):
    with tempfile.TemporaryDirectory(prefix="adm-first-") as d1, tempfile.TemporaryDirectory(prefix="adm-first-") as d2:
        fresh = copy_src(d1)
        t_compile, err = run(fresh, ["compile"], python)
        line = next((s for s in err.splitlines() if s.startswith("compiling kernels (once)")), "(no line)")
        print(f"adm-sim compile (fresh copy, no cache): {t_compile:.2f} s; stderr: {line}")
        for name in ("check B1", "sweep dim"):
            t_first, err = run(fresh, COMMANDS[name], python)
            said = any(s.startswith("compiling kernels (once)") for s in err.splitlines())
            warm = [run(fresh, COMMANDS[name], python)[0] for _ in range(repeat)]
            med = statistics.median(warm)
            print(f"{name}: first after compile {t_first:.2f} s, warm median {med:.2f} s (best {min(warm):.2f}) "
                  f"-> first / warm = {t_first / med:.2f}; compiled again: {'yes' if said else 'no'}")
        fresh2 = copy_src(d2)
        t_first, err = run(fresh2, COMMANDS["check B1"], python)
        line = next((s for s in err.splitlines() if s.startswith("compiling kernels (once)")), "(no line)")
        print(f"check B1, fresh copy without the compile step: {t_first:.2f} s; stderr: {line}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="root of a baseline tree (a checkout with src/); none: this tree alone")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per command and tree (default 5)")
    ap.add_argument("--python", default=sys.executable, help="interpreter of the environment (default: this one)")
    ap.add_argument("--only", choices=tuple(COMMANDS), action="append", help="time only these commands")
    ap.add_argument("--first-run", action="store_true", help="time the first run from a fresh copy instead")
    ap.add_argument("--startup", action="store_true", help="time the start of both programs (--help, a refusal)")
    args = ap.parse_args()
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load {os.getloadavg()[0]:.2f}, "
          f"{os.cpu_count()} CPUs, {args.python}")
    if args.first_run:
        first_run(args.python, args.repeat)
        return 0
    trees = [ROOT] + ([Path(args.baseline).resolve()] if args.baseline else [])
    if args.startup:
        best, best_cpu = startup(trees, args.python, args.repeat)
        print(f"start-up, whole process, best of {args.repeat} (s); this = {ROOT}, baseline = {args.baseline}")
        for what, table in (("wall time", best), ("CPU time (user + system)", best_cpu)):
            print(f"{what:28s} {'this':>8s}" + (f" {'baseline':>9s} {'baseline / this':>16s}" if args.baseline else ""))
            for name in STARTUP:
                line = f"{name:28s} {table[name, ROOT]:8.3f}"
                if args.baseline:
                    b = table[name, trees[1]]
                    line += f" {b:9.3f} {b / table[name, ROOT]:15.2f}x"
                print(line)
        print(f"load after: {os.getloadavg()[0]:.2f}")
        return 0
    names = args.only or list(COMMANDS)
    times, cpu = side_by_side(trees, args.python, args.repeat, names)
    print(f"whole process, warm, {args.repeat} runs each (s); this = {ROOT}, baseline = {args.baseline}")
    for what, table in (("wall time", times), ("CPU time (user + system)", cpu)):
        head = f"{what:26s} {'this: median (best)':>22s}"
        if args.baseline:
            head += f" {'baseline: median (best)':>26s} {'baseline / this':>16s}"
        print(head)
        for c in names:
            a = table[c, ROOT]
            line = f"{c:26s} {statistics.median(a):14.3f} ({min(a):.3f})"
            if args.baseline:
                b = table[c, trees[1]]
                line += (f" {statistics.median(b):18.3f} ({min(b):.3f}) "
                         f"{statistics.median(b) / statistics.median(a):10.2f}x (best {min(b) / min(a):.2f}x)")
            print(line)
    print(f"load after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
