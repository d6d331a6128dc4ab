"""Lanes and CPU of the study's batches on the paper's DIM grid and on the window grid.

    .venv/bin/python bench/bench_study_grid.py

Five batches of ICE-2 (30 cases: L = 15, 4, 30, 8, 25 m at frequency indices 3, 5, 1, 2, 4) through
:func:`adm_calib.study.run_batch`, once with the paper's grid and the one-request damping ladder
(the shipped study's settings) and once with the study's defaults (window grid, two-stage ladder).
Printed per setting: the process CPU time (``time.process_time``, robust on a shared machine where
wall time is not) and the lanes run per model and phase (each lane one speed of one case at one
damping; a DIM lane costs about 8 MLM lanes, fitted from these two runs). The Δζ_VBI of both are
compared (they must be equal bit for bit). The kernels are warmed up on one batch first.
"""

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import collections
import time

import numpy as np

from adm_calib import lanes as L
from adm_calib import study as st
from adm_calib.study import cases as study_cases
from adm_calib.study.execution import run_batch

BATCHES = ((15, 3), (4, 5), (30, 1), (8, 2), (25, 4))


def main():
    count = collections.Counter()
    run = L.CompiledLanes.run

    def counted(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase=""):
        count[(model, phase)] += np.size(case)
        return run(self, model, case, speeds_kmh, delta_zeta, sweep, phase)

    L.CompiledLanes.run = counted
    run_batch(st.select_cases(["ICE-2"], ["mu1"], (40, 40), [1]))  # warm-up: load or compile the kernels
    dz = {}
    for grid, stage in (("paper", None), ("window", study_cases.LADDER_FIRST_STAGE)):
        study_cases.LADDER_FIRST_STAGE = stage
        count.clear()
        t0 = time.process_time()
        recs = []
        for span, fi in BATCHES:
            recs += run_batch(st.select_cases(["ICE-2"], st.MASS_FUNCTION_NAMES, (span, span), [fi]),
                              st.StudySettings(dim_grid=grid))
        cpu = time.process_time() - t0
        dz[grid] = [r["delta_zeta_vbi_pct"] for r in recs]
        lanes = ", ".join(f"{m} {p} {n}" for (m, p), n in sorted(count.items()))
        print(f"{grid:7s} ladder first stage {stage}: {len(recs)} cases, {cpu:.1f} s CPU; lanes: {lanes}")
    same = dz["paper"] == dz["window"]
    print(f"Δζ_VBI equal bit for bit: {same}")


if __name__ == "__main__":
    main()
