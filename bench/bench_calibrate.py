"""Wall time of one ``calibrate`` for B1 x ICE-2, all sweeps included (target: <= 8 s on 2 cores).

Run: ``.venv/bin/python bench/bench_calibrate.py [--repeat N]``. Prints the time of each phase
(MLM sweep, DIM sweep on the Section 3.3 grid, root finding with the adapted-curve sweep) and the
result, so a regression in speed or in the number can be seen at once.
"""

import argparse
import time

from adm_sim.bridge import named_bridge
from adm_sim.trains import load_train

from adm_calib.calibrate import calibrate


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="number of timed runs (default 1)")
    args = ap.parse_args()
    bridge, train = named_bridge("B1"), load_train("ICE-2")
    best = float("inf")
    for k in range(args.repeat):
        t0 = time.perf_counter()
        res = calibrate(bridge, train)
        wall = time.perf_counter() - t0
        best = min(best, wall)
        phases = ", ".join(f"{name} {t:.2f} s" for name, t in res.timings_s.items())
        print(f"run {k + 1}: calibrate B1 x ICE-2 {wall:.2f} s ({phases}); "
              f"DIM speeds {res.dim_speeds_kmh.size}, brentq iterations {res.solve.iterations}")
    print(f"dz_VBI = {res.delta_zeta_vbi_pct:.4f} %; MLM peak {res.mlm_peak.acc_m_s2:.4f} m/s^2 at "
          f"{res.mlm_peak.speed_kmh:g} km/h; DIM peak {res.dim_peak.acc_m_s2:.4f} m/s^2 at "
          f"{res.dim_peak.speed_kmh:g} km/h")
    print(f"best wall time {best:.2f} s (target <= 8 s)")


if __name__ == "__main__":
    main()
