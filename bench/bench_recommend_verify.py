"""Cost of ``adm-calib recommend --verify`` beside the calibration it runs.

The target (issue "numbers an engineer acts on"): ``recommend --verify`` takes the calibration's own
time plus at most 0.5 s. Both are timed in this process, warmed up (kernels compiled, modules
imported), alternating, best of ``--repeat``: the calibration alone
(:func:`adm_calib.calibrate.calibrate` of the same bridge and train, ``adapted_curve=False``) and the
whole command (``main(["recommend", ..., "--verify", "--json"])``, its output discarded). Prints both,
their difference and their ratio, in wall time and in CPU time of this process (on a shared machine the
CPU time is the steadier measure); asserts nothing about time.

Run: .venv/bin/python bench/bench_recommend_verify.py [--repeat 3]
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import io  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

from adm_calib.calib_commands import main  # noqa: E402
from adm_calib.calibrate import calibrate  # noqa: E402
from adm_sim.model.bridge import Bridge, eurocode_damping_pct  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402

#: Railjet on an 8.6 m steel span (a held-out bridge of tests/calib/test_recommend_verify.py).
CASE = {"train": "Railjet", "n0": 13.0, "mu": 9000.0, "type": "sc", "span": 8.6}


def command():
    argv = ["recommend", "--train", CASE["train"], "--n0", str(CASE["n0"]), "--mu", str(CASE["mu"]),
            "--type", CASE["type"], "--span", str(CASE["span"]), "--verify", "--json"]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()), \
            warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(argv) == 0


def calibration():
    zeta = eurocode_damping_pct(CASE["span"], CASE["type"]) / 100.0
    bridge = Bridge.from_frequency(CASE["span"], CASE["n0"], CASE["mu"], zeta, bridge_type=CASE["type"])
    return calibrate(bridge, load_train(CASE["train"]), adapted_curve=False)


def main_bench():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    calibration()  # warm-up: kernels, modules
    command()
    best = {k: [math.inf, math.inf] for k in ("calibration", "recommend --verify")}
    for _ in range(args.repeat):
        for name, fn in (("calibration", calibration), ("recommend --verify", command)):
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            best[name] = [min(best[name][0], time.perf_counter() - t0), min(best[name][1], time.process_time() - c0)]
    cal, cmd = best["calibration"], best["recommend --verify"]
    print(f"case: {CASE['train']} on L = {CASE['span']:g} m, n0 = {CASE['n0']:g} Hz, mu = {CASE['mu']:g} kg/m "
          f"({CASE['type']}), 160..350 km/h; best of {args.repeat}, this process; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'':24s} {'wall':>8s} {'CPU':>8s}")
    print(f"calibration alone       {cal[0]:7.3f} s {cal[1]:7.3f} s")
    print(f"recommend --verify      {cmd[0]:7.3f} s {cmd[1]:7.3f} s")
    print(f"difference              {cmd[0] - cal[0]:7.3f} s {cmd[1] - cal[1]:7.3f} s   (target <= 0.5 s)")
    print(f"ratio                   {cmd[0] / cal[0]:7.3f}   {cmd[1] / cal[1]:7.3f}")


if __name__ == "__main__":
    main_bench()
