"""Speed of the exact moving-load envelope (:func:`adm_sim.integrate.envelope.moving_load_envelope`), and
the same numbers against another source tree in the same run.

B1 with HSLM-A1..A10 and ICE-2, 144 to 420 km/h at 1 km/h: midspan, whole deck and x = 5 m.
Each tree runs in its own interpreter (warmed up: the numba kernels compiled and cached first),
alternately, ``--rounds`` times; the best CPU time per tree is printed with the ratio, and every
envelope array of the two trees is compared bit for bit. Asserts nothing about time.
Run: .venv/bin/python bench/bench_envelope.py [--base OTHER_CHECKOUT] [--rounds 3]
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import pathlib  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
FIELDS = ("max_acc_m_s2", "max_disp_m", "t_acc_s", "t_disp_s", "x_acc_m", "x_disp_m", "max_moment_Nm",
          "t_moment_s", "max_disp_midspan_m")
WHERE = ("midspan", "deck", 5.0)


def child(out, repeat):
    """In this interpreter: warm up, time ``repeat`` passes over every train and position, keep the arrays."""
    from adm_sim.model.bridge import named_bridge
    from adm_sim.design.check import resolve_trains
    from adm_sim.integrate.envelope import moving_load_envelope

    bridge = named_bridge("B1")
    trains = resolve_trains("hslm,ICE-2")
    speeds = np.arange(144.0, 421.0, 1.0)

    def one_pass():
        return {(t.name, str(w)): moving_load_envelope(bridge, t.axle_offsets_m, t.axle_loads_n, speeds, where=w)
                for t in trains for w in WHERE}

    one_pass()  # warm-up: compile (or load the cache)
    cpu = []
    for _ in range(repeat):
        c0 = time.process_time()
        envs = one_pass()
        cpu.append(time.process_time() - c0)
    arrays = {f"{name}|{w}|{f}": np.asarray(getattr(e, f)) for (name, w), e in envs.items() for f in FIELDS}
    arrays.update({f"{name}|{w}|refined": np.asarray(e.refined) for (name, w), e in envs.items()})
    np.savez(out, **arrays)
    print(json.dumps({"cpu_s": min(cpu)}))


def run_tree(src, out, repeat):
    env = dict(os.environ, PYTHONPATH=str(src))
    cmd = [sys.executable, __file__, "--child", str(out), "--repeat", str(repeat)]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])["cpu_s"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=pathlib.Path, help="another checkout (its src/ is timed beside this one)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--child", type=pathlib.Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child, args.repeat)
        return
    trees = {"this": ROOT / "src"}
    if args.base:
        trees["base"] = args.base.resolve() / "src"
    best = {k: float("inf") for k in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.rounds):
            for name, src in trees.items():
                best[name] = min(best[name], run_tree(src, pathlib.Path(tmp) / f"{name}.npz", args.repeat))
        print(f"B1 x HSLM-A1..A10 + ICE-2, 277 speeds, midspan + deck + x = 5 m: "
              f"this tree {best['this']:.3f} s CPU (best of {args.rounds} x {args.repeat})")
        if "base" in trees:
            print(f"base tree {best['base']:.3f} s CPU; this / base = {best['this'] / best['base']:.3f}")
            a, b = np.load(pathlib.Path(tmp) / "this.npz"), np.load(pathlib.Path(tmp) / "base.npz")
            assert sorted(a.files) == sorted(b.files)
            diff = [k for k in a.files if not np.array_equal(a[k], b[k])]
            print(f"{len(a.files)} arrays compared bit for bit: {len(diff)} differ" + (f": {diff[:5]}" if diff else ""))


if __name__ == "__main__":
    main()
