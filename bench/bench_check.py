"""Speed of the EN 1991-2 dynamic check: B1 with HSLM-A1..A10 and the four real trains, 144 to 420
km/h at 1 km/h, 3 modes, whole deck (the default; midspan timed beside it), every effect of
6.4.6.5(3) (moment and shear along the span, reactions, by the mode-acceleration method) and the
serviceability checks; with mass and stiffness bounds timed beside it; against a per-speed,
per-train loop (the way a user would script a peer tool: one time integration per train and speed,
here the core's RK4 MLM run lane by lane).

Prints times and ratios measured in this run; asserts nothing about time. The loop baseline runs on
every ``--every``-th speed for all trains and is scaled to all speeds (said in the output).
Run: .venv/bin/python bench/bench_check.py [--every 12] [--baseline ROOT [--repeat 3]]

``--baseline ROOT`` sets this tree beside a baseline tree (another checkout, e.g. a worktree of the main
branch at the branch point: ``git worktree add --detach /tmp/base <commit>``; its ``src`` or ROOT itself
when it is a ``src`` directory), in one run, the trees alternating, best of ``--repeat``, with the ratios
this / baseline:

* the command a user types, as a whole process (interpreter start, imports, numba's cached kernels, the
  check, the report written): ``adm-sim check --bridge B1 --max-line-speed 350 --trains
  hslm,ICE-2,Eurostar,Railjet,ICE-4 --mass-bounds=standard:4000,2000 --report X.html`` (the target:
  3 s), and the same without the bounds; one untimed run of each per tree first (numba's cache, the
  bytecode: the runs write ``__pycache__`` as a user's install does, whatever
  ``PYTHONDONTWRITEBYTECODE`` says);
* in process, warmed up (each tree in its own process): the whole check, with the bounds and the HTML
  report, the bounds alone, the report alone, and the check's own phase timers.

CPU time (user + system, with the threads and children) is the measure on a shared machine; wall time is
what the user waits, and holds only on a quiet one (NaN where only wall time exists).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import pathlib  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from adm_sim.design.check import resolve_trains, run_check  # noqa: E402
from adm_sim.model.bridge import named_bridge  # noqa: E402
from adm_sim.integrate.envelope import moving_load_envelope  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402

TRAINS = "hslm,ICE-2,Eurostar,Railjet,ICE-4"
V_LINE_KMH = 350.0  # 1.2 x 350 = 420 km/h


def timed(fn, repeat=1):
    """Best wall time and best CPU time of this process (the machine is shared: CPU time is what the
    work costs, wall time what the user waits) over ``repeat`` runs."""
    best, cpu, out = math.inf, math.inf, None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        best = min(best, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return best, cpu, out


#: The bounds of the target: EN 1991-2 6.4.6.3.2's from 4000 kg/m of ballast at 2000 kg/m3.
STANDARD_BOUNDS = "standard:4000,2000"


def worker(repeat):
    """One tree's times (JSON on stdout): the whole check; with the standard's mass bounds and the HTML
    report; best wall and CPU of ``repeat`` after a warm-up."""
    from adm_sim.design.check_report import report_html

    bridge = named_bridge("B1")
    trains = resolve_trains(TRAINS)
    res = run_check(bridge, V_LINE_KMH, trains, mass_bounds=STANDARD_BOUNDS)  # warm-up (numba cache, imports)
    report_html(res)
    out = {}
    out["check"] = timed(lambda: run_check(bridge, V_LINE_KMH, trains), repeat)[:2]
    w, c, html = timed(lambda: report_html(run_check(bridge, V_LINE_KMH, trains, mass_bounds=STANDARD_BOUNDS)), repeat)
    out["bounds_report"] = (w, c)
    w, c, res = timed(lambda: run_check(bridge, V_LINE_KMH, trains, mass_bounds=STANDARD_BOUNDS), repeat)
    out["bounds"] = (w, c)
    out["report"] = timed(lambda: report_html(res), repeat)[:2]
    # the phases of the check (wall, from the result's own timers): the nominal bridge and the two bounds
    out["phase_nominal"] = (res.timings_s["damping"] + res.timings_s["envelopes"], math.nan)
    out["phase_bounds"] = (res.timings_s["bounds"], math.nan)
    lab, gt, gv, ga = res.envelope_governing()
    out["envelope"] = f"{gt.name} {ga:.4f} m/s2 at {gv:g} km/h, governed by {lab}"
    out["report_kib"] = len(html) / 1024
    print(json.dumps(out))


#: The command of the target (issue 36), its options after ``adm-sim check``; ``{report}`` a temporary file.
COMMAND = ["--bridge", "B1", "--max-line-speed", f"{V_LINE_KMH:g}", "--trains", TRAINS,
           f"--mass-bounds={STANDARD_BOUNDS}", "--report", "{report}", "--overwrite"]


def src_of(root):
    """The ``src`` directory of a checkout ``root`` (or ``root`` itself when it holds ``adm_sim``)."""
    root = pathlib.Path(root).resolve()
    return root if (root / "adm_sim").is_dir() else root / "src"


def whole_process(src, argv, report):
    """Wall and CPU time (s; user + system of the process and its threads) of ``adm-sim check argv`` as a
    user runs it, importing ``src``; one line of error and exit on a failure."""
    env = dict(os.environ, PYTHONPATH=str(src), OPENBLAS_NUM_THREADS="1")
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # a user's install keeps its bytecode
    argv = ["check"] + [a.replace("{report}", str(report)) for a in argv]
    script = pathlib.Path(sys.executable).with_name("adm-sim")
    cmd = [str(script)] if script.exists() else [sys.executable, "-m", "adm_sim.cli.sim_commands"]
    r0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    p = subprocess.run(cmd + argv, env=env, capture_output=True, text=True)
    wall, r1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise SystemExit(f"error: adm-sim {' '.join(argv)} with {src} exited {p.returncode}: {p.stderr.strip()[-300:]}")
    return [wall, (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)]


def _keep_best(best, key, v):
    old = best.get(key, [math.inf, math.inf])
    best[key] = [min(old[0], v[0]), v[1] if math.isnan(v[1]) else min(old[1], v[1])]


def compare(baseline, repeat, in_process=True):
    """This tree beside ``baseline`` (a checkout or its src), the trees alternating ``repeat`` times."""
    trees = {"baseline": src_of(baseline), "this": src_of(pathlib.Path(__file__).resolve().parents[1])}
    commands = {"cli_bounds": COMMAND, "cli": [a for a in COMMAND if not a.startswith("--mass-bounds")]}
    best = {k: {} for k in trees}
    with tempfile.TemporaryDirectory(prefix="bench-check-") as tmp:
        report = pathlib.Path(tmp) / "report.html"
        for src in trees.values():  # warm-up: numba's cache, the bytecode
            for argv in commands.values():
                whole_process(src, argv, report)
        for _ in range(repeat):
            for name, src in trees.items():
                for key, argv in commands.items():
                    _keep_best(best[name], key, whole_process(src, argv, report))
                if not in_process:
                    continue
                env = dict(os.environ, PYTHONPATH=str(src))
                r = subprocess.run([sys.executable, __file__, "--worker", "--repeat", "1"], env=env,
                                   capture_output=True, text=True, check=True)
                for k, v in json.loads(r.stdout.strip().splitlines()[-1]).items():
                    if isinstance(v, list):
                        _keep_best(best[name], k, v)
                    else:
                        best[name][k] = v
    print(f"B1, {TRAINS}, V = {V_LINE_KMH:g} km/h (144 .. 420 km/h), every effect and the SLS; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; wall / CPU s, best of {repeat}, trees alternating; "
          f"baseline = {trees['baseline']}, this = {trees['this']}")
    print(f"{'':62s} {'baseline':>17s} {'this':>17s} {'this / baseline':>17s}")
    for k, what in (("cli_bounds", f"adm-sim check ... --mass-bounds={STANDARD_BOUNDS} --report X.html"),
                    ("cli", "adm-sim check ... --report X.html (no bounds)"),
                    ("check", "in process, warm: whole check"),
                    ("bounds_report", "  whole check, mass bounds, HTML report"),
                    ("bounds", "  the check with the mass bounds alone"),
                    ("phase_nominal", "    of which the nominal bridge (wall)"),
                    ("phase_bounds", "    of which the two bounds (wall)"),
                    ("report", "  the HTML report alone")):
        if k not in best["baseline"] or k not in best["this"]:
            continue
        b, a = best["baseline"][k], best["this"][k]
        target = "  (target <= 3 s)" if k == "cli_bounds" else ""
        print(f"{what:62s} {b[0]:7.3f} / {b[1]:7.3f} {a[0]:7.3f} / {a[1]:7.3f} {a[0] / b[0]:7.3f} / "
              f"{a[1] / b[1]:7.3f}{target}")
    for name in trees:
        if "envelope" in best[name]:
            print(f"{name}: envelope {best[name]['envelope']}; report {best[name]['report_kib']:.0f} KiB")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=int, default=12, help="loop baseline on every n-th speed (scaled to all)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--baseline", "--compare", metavar="ROOT", dest="baseline",
                    help="this tree beside another checkout (or its src directory), whole process and in process")
    ap.add_argument("--no-in-process", action="store_true", help="with --baseline: the whole process alone")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        return worker(args.repeat)
    if args.baseline:
        return compare(args.baseline, args.repeat, in_process=not args.no_in_process)
    bridge = named_bridge("B1")
    trains = resolve_trains(TRAINS)
    speeds = np.arange(144.0, 421.0, 1.0)
    moving_load_envelope(bridge, trains[0].axle_offsets_m, trains[0].axle_loads_n, speeds[:3])  # warm-up

    t_env, c_env, envs = timed(lambda: [moving_load_envelope(bridge, t.axle_offsets_m, t.axle_loads_n, speeds)
                                 for t in trains], args.repeat)
    t_deck, c_deck, _ = timed(lambda: [moving_load_envelope(bridge, t.axle_offsets_m, t.axle_loads_n, speeds,
                                                            where="deck") for t in trains], args.repeat)
    t_check, c_check, res = timed(lambda: run_check(bridge, V_LINE_KMH, trains), args.repeat)
    t_mid, c_mid, res_mid = timed(lambda: run_check(bridge, V_LINE_KMH, trains, where="midspan"), args.repeat)
    import adm_sim.design.check_effects as ce

    t_eff, c_eff, _ = timed(lambda: [ce.train_effects(bridge, t.axle_offsets_m, t.axle_loads_n, c.speeds_kmh)
                                     for t, c in zip(trains, res.trains)], args.repeat)
    t_bnd, c_bnd, _ = timed(lambda: run_check(bridge, V_LINE_KMH, trains, mass_bounds=(-0.1, 0.15)), 1)
    # EN 1991-2 6.4.6.3.2's bounds from the ballast (4000 kg/m at 2000 kg/m3) and the HTML report
    from adm_sim.design.check_report import report_html

    t_std, c_std, res_std = timed(lambda: run_check(bridge, V_LINE_KMH, trains, mass_bounds="standard:4000,2000"), 1)
    t_rep, c_rep, html = timed(lambda: report_html(res_std), 1)
    n_fine = sum(c.speeds_kmh.size for c in res.trains) - len(trains) * res.speeds_kmh.size

    sub = speeds[:: args.every]
    t_loop_sub, c_loop_sub, loop = timed(
        lambda: {t.name: [run_sweep(bridge, t, "mlm", [v]).max_acc_m_s2[0] for v in sub] for t in trains})
    t_loop = t_loop_sub * speeds.size / sub.size
    c_loop = c_loop_sub * speeds.size / sub.size

    rel = np.concatenate([np.asarray(loop[t.name]) / e.max_acc_m_s2[:: args.every] - 1 for t, e in zip(trains, envs)])
    g, v, acc = res.governing
    print(f"B1, {len(trains)} trains ({TRAINS}), {speeds.size} speeds 144..420 km/h, modes {res.modes}")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; times: wall / CPU of this process")
    print(f"exact envelopes, 14 trains x {speeds.size} speeds, midspan:    {t_env:7.3f} / {c_env:7.3f} s (best of {args.repeat})")
    print(f"exact envelopes, 14 trains x {speeds.size} speeds, whole deck: {t_deck:7.3f} / {c_deck:7.3f} s")
    print(f"whole check, whole deck (+ {n_fine} refinement speeds, every effect, SLS): {t_check:7.3f} / "
          f"{c_check:7.3f} s (target <= 3 s)")
    print(f"  of which the effects of 6.4.6.5(3) (mode-acceleration, 20 effects):   {t_eff:7.3f} / {c_eff:7.3f} s")
    print(f"whole check with mass bounds -10 %/+15 % (three bridges):      {t_bnd:7.3f} / {c_bnd:7.3f} s")
    print(f"whole check with the standard's mass bounds (standard:4000,2000): {t_std:7.3f} / {c_std:7.3f} s; "
          f"its HTML report: {t_rep:.3f} / {c_rep:.3f} s ({len(html) / 1024:.0f} KiB)")
    lab, gt, gv, ga = res_std.envelope_governing()
    print(f"  envelope: {gt.name} {ga:.4f} m/s2 at {gv:g} km/h, governed by {lab}")
    print(f"whole check, midspan only (--where midspan):          {t_mid:7.3f} / {c_mid:7.3f} s")
    print(f"per-speed per-train RK4 loop:                         {t_loop:7.1f} / {c_loop:7.1f} s "
          f"({sub.size * len(trains)} runs measured, {t_loop_sub:.1f} s wall, scaled to {speeds.size * len(trains)} runs)")
    print(f"ratio loop / envelopes: {t_loop / t_env:.0f}x wall, {c_loop / c_env:.0f}x CPU; "
          f"loop / whole check: {t_loop / t_check:.0f}x wall, {c_loop / c_check:.0f}x CPU")
    print(f"loop (RK4, 16 steps per period) vs exact envelope: {100 * rel.min():+.3f} % .. {100 * rel.max():+.4f} %")
    zeta = ", ".join(f"{100 * z:.4g} %" for z in g.zeta)
    print(f"governing (whole deck, damping model {res.damping_model}: zeta per mode {zeta}): {g.name} {acc:.4f} m/s2 "
          f"at {v:g} km/h, x = {g.x_max_m:.3f} m ({g.x_max_m / bridge.span_m:.3f} L); "
          f"{'PASS' if res.passed else 'FAIL'} vs 3.5 m/s2")
    gm, vm, am = res_mid.governing
    print(f"midspan only: {gm.name} {am:.4f} m/s2 at {vm:g} km/h; {'PASS' if res_mid.passed else 'FAIL'}")


if __name__ == "__main__":
    main()
