"""Cost of the parametric study: per-case time, the dask overhead and the full-study estimate.

    .venv/bin/python bench/bench_study.py [--overhead-only]

Timings are wall-clock on a shared 2-core box: run it when nothing else is busy.

1. Per-case time of ``run_case`` in this process (one BLAS thread) on ICE-2 bridges spread over
   n0; the cost of a case grows about linearly with n0 (the time step follows the highest
   retained mode, 9 n0), so ``t = c0 + c1 n0`` is fitted and summed over the 1110 bridges.
   One case per other train scales the estimate to the four trains (their lengths differ).
2. The dask overhead: 4 cheap cases in a plain loop vs the study on a 1- and a 2-worker
   loopback LocalCluster (cluster start and close included).
"""

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from adm_calib import study as st  # noqa: E402


def timed_case(case):
    t0 = time.perf_counter()
    rec = st.run_case(case)
    return time.perf_counter() - t0, rec


def per_case():
    field = {c.key: c for c in st.select_cases()}
    sample = ["L4-f5-mu2", "L4-f3-mu2", "L8-f3-mu2", "L15-f3-mu2", "L25-f3-mu2", "L40-f3-mu2", "L40-f1-mu5"]
    print("1. per-case time (one process, one BLAS thread), ICE-2:")
    n0, t = [], []
    for name in sample:
        c = field[(name, "ICE-2")]
        dt, rec = timed_case(c)
        n0.append(c.bridge.n0_hz)
        t.append(dt)
        print(f"   {name:12} n0={c.bridge.n0_hz:6.2f} Hz  {dt:6.2f} s  {rec['status']}")
    c1, c0 = np.polyfit(n0, t, 1)
    print(f"   fit t = {c0:.3f} s + {c1:.3f} s/Hz * n0")
    ref_case = "L15-f3-mu2"
    t_ice2 = t[sample.index(ref_case)]
    factors = {"ICE-2": 1.0}
    for train in ("Eurostar", "Railjet", "ICE-4"):
        dt, rec = timed_case(field[(ref_case, train)])
        factors[train] = dt / t_ice2
        print(f"   {ref_case} x {train:8} {dt:6.2f} s  ({factors[train]:.2f} x ICE-2)  {rec['status']}")
    bridges_n0 = np.array([c.bridge.n0_hz for (name, train), c in field.items() if train == "ICE-2"])
    per_train = (c0 + c1 * bridges_n0).sum()
    total = per_train * sum(factors.values())
    print(f"   estimate: {len(field)} cases = {total / 3600:.2f} h of CPU, mean {total / len(field):.2f} s/case; "
          f"on 2 workers ~{total / 2 / 3600:.2f} h")


def overhead():
    print("2. dask overhead on 4 cheap cases (L39/L40, LB frequency, mu1/mu2, ICE-2):")
    cases = st.select_cases(["ICE-2"], ["mu1", "mu2"], (39, 40), [1])
    t0 = time.perf_counter()
    for c in cases:
        st.run_case(c)
    loop = time.perf_counter() - t0
    print(f"   plain loop            {loop:6.2f} s")
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            run = st.run_study(d, cases, workers=workers, progress=False)
            wall = time.perf_counter() - t0
        print(f"   study, {workers} worker(s)    {wall:6.2f} s  (cases {run.wall_s:.2f} s incl. cluster start/close; "
              f"overhead vs loop/{workers}: {wall - loop / workers:+.2f} s)")


if __name__ == "__main__":
    if "--overhead-only" not in sys.argv:
        per_case()
    overhead()
