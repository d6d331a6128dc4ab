"""Wheel-rail contact on rough track at every DIM speed of the paper's grid, not only at the DIM peak.

The study's line of a case says ``contact_lost`` only when its DIM peak comes from a run in which a
wheel would lift off (the speed the calibration uses). This script runs, per case, the DIM over the
paper's DIM grid (Section 3.3: 160..350 km/h every 5 km/h, 39 speeds; the study adds 1 km/h speeds
around the peak) on the case's profile, with the contact check of every axle at every step
(:mod:`adm_sim.integrate.contact`), and writes one CSV row per case: the smallest contact force over
the speeds (kN) and, where a wheel would lift off, the lowest such speed, its axle (from the leading
one), time and force, and how many of the 39 speeds lost contact.

    PYTHONPATH=src .venv/bin/python results/irregularity/contact_any_speed.py OUT.csv [--slice] [--seeds 1,2]

``--slice``: the 60 cases of ``run_slice.slice_cases`` instead of every μ2 case (370).
"""

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

from adm_calib.study import StudySettings, select_cases
from adm_calib.study.cases import _train
from adm_sim.integrate.sweep import run_sweep_compiled

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from run_slice import DIM_GRID, SPECTRA, slice_cases  # noqa: E402

SPEEDS_KMH = np.arange(160.0, 351.0, 5.0)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path)
    p.add_argument("--slice", action="store_true")
    p.add_argument("--seeds", default="1,2")
    a = p.parse_args(argv)
    seeds = [int(s) for s in a.seeds.split(",")]
    cases = slice_cases() if a.slice else select_cases(trains=("ICE-2", "Railjet"), mass_functions=("mu2",))
    cols = ["spectrum", "seed", "bridge", "train", "span_m", "n0_hz", "min_contact_kn", "lost_speeds",
            "first_speed_kmh", "axle", "time_s", "force_kn"]
    t0 = time.time()
    with open(a.out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for seed in seeds:
            for spec in SPECTRA:
                settings = StudySettings(irregularity=f"{spec}:seed={seed}", dim_grid=DIM_GRID)
                for c in cases:
                    opt = settings.calibration_options(c.bridge.span_m).step
                    res = run_sweep_compiled(c.bridge, _train(c.train), "dim", SPEEDS_KMH, options=opt)
                    ck = res.contact
                    fl = ck.first()
                    row = [spec, seed, c.bridge.name, c.train, c.span_m, f"{c.bridge.n0_hz:.6f}",
                           f"{float(np.min(ck.min_n)) / 1e3:.3f}", int(np.sum(ck.lost))]
                    row += ([f"{fl['speed_kmh']:g}", fl["axle"], f"{fl['time_s']:.4g}", f"{fl['force_n'] / 1e3:.4g}"]
                            if fl else ["", "", "", ""])
                    w.writerow(row)
                fh.flush()
                print(f"{time.strftime('%H:%M:%S', time.gmtime())} {spec} seed {seed}: {len(cases)} cases "
                      f"({time.time() - t0:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
