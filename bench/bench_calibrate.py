"""Compute time of ``adm-calib calibrate`` B1 x ICE-2 and of the whole ``adm-calib table4``.

Run: ``.venv/bin/python bench/bench_calibrate.py [--repeat N] [--no-table4] [--numpy]``. Both use the
compiled lane runner (:class:`adm_calib.lanes.CompiledLanes`); the kernels are compiled (or loaded
from numba's cache) by a warm-up calibration that is not timed. Prints the time of each phase
(MLM sweep, DIM sweep on the Section 3.3 grid, root finding with the adapted-curve sweep) and the
result, so a regression in speed or in the number can be seen at once. Targets: calibrate <= 1 s,
table4 <= 15 s (16 calibrations, one process). ``--numpy`` also times the same calibration on the
numpy stepper (``backend="numpy"``, the reference the kernels are tested against) in this run and
prints the ratio.
"""

import argparse
import time

from adm_sim.model.bridge import named_bridge
from adm_sim.inputs.train_files import load_train

from adm_calib.calibrate import calibrate
from adm_calib.table4 import run_table4


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="number of timed runs (default 1)")
    ap.add_argument("--no-table4", action="store_true", help="skip the table4 timing")
    ap.add_argument("--numpy", action="store_true", help="also time the calibration on the numpy stepper (baseline)")
    args = ap.parse_args()
    bridge, train = named_bridge("B1"), load_train("ICE-2")
    t0 = time.perf_counter()
    calibrate(bridge, train, speeds_kmh=[250.0, 263.0, 270.0], adapted_curve=False)
    print(f"warm-up (numba compile or cache load) {time.perf_counter() - t0:.2f} s")
    best = float("inf")
    for k in range(args.repeat):
        t0 = time.perf_counter()
        res = calibrate(bridge, train)
        wall = time.perf_counter() - t0
        best = min(best, wall)
        phases = ", ".join(f"{name} {t:.3f} s" for name, t in res.timings_s.items())
        print(f"run {k + 1}: calibrate B1 x ICE-2 {wall:.3f} s ({phases}); "
              f"DIM speeds {res.dim_speeds_kmh.size}, root iterations {res.solve.iterations}")
    print(f"dz_VBI = {res.delta_zeta_vbi_pct:.4f} %; MLM peak {res.mlm_peak.acc_m_s2:.4f} m/s^2 at "
          f"{res.mlm_peak.speed_kmh:g} km/h; DIM peak {res.dim_peak.acc_m_s2:.4f} m/s^2 at "
          f"{res.dim_peak.speed_kmh:g} km/h")
    print(f"calibrate B1 x ICE-2: best {best:.3f} s of compute (target <= 1 s)")
    if args.numpy:
        t0 = time.perf_counter()
        ref = calibrate(bridge, train, backend="numpy")
        wall = time.perf_counter() - t0
        print(f"calibrate B1 x ICE-2 on the numpy stepper: {wall:.3f} s (numpy / compiled {wall / best:.1f}x); "
              f"dz_VBI {ref.delta_zeta_vbi_pct:.4f} %")
    if not args.no_table4:
        t0 = time.perf_counter()
        table = run_table4()
        wall = time.perf_counter() - t0
        vbi = " ".join(f"{table.value('VBI', t, b):.3f}" if table.value("VBI", t, b) is not None else "n/a"
                       for t, b in table.columns())
        print(f"table4 (16 calibrations, one process): {wall:.2f} s (target <= 15 s); VBI row: {vbi}")


if __name__ == "__main__":
    main()
