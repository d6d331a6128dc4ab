"""CPU of the study's batches by phase, on a subset of every train and several spans.

    .venv/bin/python bench/bench_study_phases.py [--out dz.json] [--against other.json]

Eight batches of the study's window grid (48 cases: ICE-2 15 m and 4 m, Railjet 30 m and 6 m,
Eurostar 8 m and 40 m, ICE-4 25 m and 10 m, five frequency indices) through
:func:`adm_calib.study.run_batch`, after one warm-up batch that loads the kernels. Printed: the
process CPU time (``time.process_time``: on a shared machine wall time measures the other jobs) of
each batch and of the whole subset, and per model and phase of the lane runner the CPU and the
lanes run; ``axle_rows`` is the DIM's table of the axles on the bridge and the Eq. (13) inverses
(inside the first DIM request of each batch). ``--out`` writes every case's status and Δζ_VBI;
``--against`` compares them with such a file written by another tree (the largest |Δζ change|
in %, and whether any status changed). Run it in two trees one after the other, e.g. a
``git worktree`` of the older commit, each with its own numba cache.
"""

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import collections
import json
import time

import numpy as np

from adm_calib import lanes as L
from adm_calib import study as st
from adm_calib.study.execution import run_batch
from adm_sim.integrate import compiled_batch, tables

#: (span m, frequency index, train): every train, short spans (many steps, costly DIM tables) and long.
BATCHES = ((15, 3, "ICE-2"), (4, 5, "ICE-2"), (30, 1, "Railjet"), (8, 2, "Eurostar"), (25, 4, "ICE-4"),
           (6, 3, "Railjet"), (40, 5, "Eurostar"), (10, 1, "ICE-4"))


def _instrument(cpu, lanes):
    run = L.CompiledLanes.run

    def counted(self, model, case, speeds_kmh, delta_zeta=0.0, sweep=None, phase=""):
        t = time.process_time()
        out = run(self, model, case, speeds_kmh, delta_zeta, sweep, phase)
        cpu[(model, phase)] += time.process_time() - t
        lanes[(model, phase)] += np.size(case)
        return out

    L.CompiledLanes.run = counted
    rows = tables.axle_rows

    def timed_rows(*a, **k):
        t = time.process_time()
        out = rows(*a, **k)
        cpu["axle_rows"] += time.process_time() - t
        return out

    compiled_batch.axle_rows = timed_rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="write every case's status and Δζ_VBI (JSON)")
    ap.add_argument("--against", help="compare with a file written by --out")
    args = ap.parse_args(argv)
    cpu, lanes = collections.Counter(), collections.Counter()
    _instrument(cpu, lanes)
    run_batch(st.select_cases(["ICE-2"], ["mu1"], (40, 40), [1]))  # warm-up: load or compile the kernels
    cpu.clear()
    lanes.clear()
    recs = []
    t0 = time.process_time()
    for span, fi, train in BATCHES:
        t1 = time.process_time()
        recs += run_batch(st.select_cases([train], st.MASS_FUNCTION_NAMES, (span, span), [fi]), st.StudySettings())
        print(f"{train:8s} L = {span:2d} m, f{fi}: {time.process_time() - t1:6.2f} s CPU")
    total = time.process_time() - t0
    print(f"total: {total:.2f} s CPU, {len(recs)} cases")
    for k, v in sorted(cpu.items(), key=lambda kv: -kv[1]):
        name = k if isinstance(k, str) else f"{k[0]} {k[1]}"
        extra = f", {lanes[k]} lanes" if k in lanes else " (inside the DIM requests)"
        print(f"  {name:16s} {v:6.2f} s ({100 * v / total:3.0f} %){extra}")
    rows = [[r["bridge"], r["train"], r["status"], r.get("delta_zeta_vbi_pct")] for r in recs]
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(rows, fh)
    if args.against:
        with open(args.against) as fh:
            other = {(b, t): (s, dz) for b, t, s, dz in json.load(fh)}
        changed = [(b, t) for b, t, s, _ in rows if other[(b, t)][0] != s]
        dz = [abs(d - other[(b, t)][1]) for b, t, _, d in rows if d is not None and other[(b, t)][1] is not None]
        print(f"against {args.against}: statuses changed {len(changed)}; largest |Δζ_VBI change| "
              f"{max(dz) if dz else 0.0:.2e} % over {len(dz)} cases")


if __name__ == "__main__":
    main()
