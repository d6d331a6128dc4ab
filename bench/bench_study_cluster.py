"""What the study's local dask cluster costs beside its tasks: CPU of every process against the tasks' own.

    .venv/bin/python bench/bench_study_cluster.py [--trains ICE-2] [--spans 20:25] [--rounds 2]

Runs the batches of a subset of the study (default: ICE-2, spans 20-25 m, every frequency index
and mass function: 30 batches, 180 cases) as tasks on :func:`adm_calib.study.local_cluster` (two
workers), twice per round: with the study's cluster settings (:data:`~adm_calib.study.execution.CLUSTER_CONFIG`,
glibc's malloc defaults) and with dask's defaults (the task profiler, 20 ms ticks, and
``MALLOC_TRIM_THRESHOLD_=65536`` from the nanny), alternating. Printed per run: cluster start,
run and close (wall), the tasks' own CPU (``time.thread_time`` of the thread that runs them), the
CPU of their worker processes while they ran (``time.process_time``: the task plus the worker's
other threads), the CPU of every process (client and scheduler, nannies, workers:
``getrusage`` of this process and its children) and the minor page faults. CPU, not wall: on a
shared machine wall time measures the other jobs. Kernels compiled ahead (``adm-sim compile``),
or the first run pays for the compilation.
"""

import argparse
import os
import resource
import time

from adm_calib import study as st
from adm_calib.study import execution
from adm_calib.study.execution import local_cluster, make_batches, run_batch


def _task(batch):
    t, p = time.thread_time(), time.process_time()
    run_batch(batch)
    return time.thread_time() - t, time.process_time() - p


def _usage():
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime, s.ru_stime + c.ru_stime, s.ru_minflt + c.ru_minflt


def one_run(batches, dask_defaults):
    """Start a cluster, run every batch, close it; the figures of one run (dict)."""
    from distributed import Client, as_completed  # noqa: PLC0415  only the study needs dask

    saved = execution.CLUSTER_CONFIG, execution.UNSET_WORKER_ENV
    environ = dict(os.environ)  # dask's nanny writes its pre-spawn environment into this process's
    if dask_defaults:
        execution.CLUSTER_CONFIG, execution.UNSET_WORKER_ENV = {}, ()
    try:
        cpu0, sys0, flt0 = _usage()
        t0 = time.perf_counter()
        cluster = local_cluster(2)
        client = Client(cluster, set_as_default=False)
        t1 = time.perf_counter()
        futs = [client.submit(_task, b, pure=False) for b in batches]
        thread = proc = 0.0
        for f in as_completed(futs, loop=client.loop):
            a, b = f.result()
            thread, proc = thread + a, proc + b
        t2 = time.perf_counter()
        client.close()
        cluster.close()
        t3 = time.perf_counter()
    finally:
        execution.CLUSTER_CONFIG, execution.UNSET_WORKER_ENV = saved
        os.environ.clear()  # so that the next cluster does not inherit MALLOC_TRIM_THRESHOLD_ from this one
        os.environ.update(environ)
    cpu1, sys1, flt1 = _usage()
    return {"start": t1 - t0, "run": t2 - t1, "close": t3 - t2, "thread": thread, "proc": proc,
            "cpu": cpu1 - cpu0, "sys": sys1 - sys0, "faults": flt1 - flt0}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trains", default="ICE-2")
    ap.add_argument("--spans", default="20:25", help="lo:hi (m)")
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args(argv)
    lo, hi = (float(x) for x in args.spans.split(":"))
    batches = make_batches(st.select_cases(args.trains.split(","), st.MASS_FUNCTION_NAMES, (lo, hi), list(st.FREQ_INDICES)))
    print(f"{len(batches)} batches; CPU in s (all processes), wall in s")
    print(f"{'settings':14s} {'start':>6s} {'run':>6s} {'close':>6s} {'tasks':>7s} {'workers':>8s} {'all CPU':>8s} "
          f"{'of which sys':>12s} {'faults':>9s}")
    for _ in range(args.rounds):
        for name, defaults in (("study", False), ("dask defaults", True)):
            r = one_run(batches, defaults)
            print(f"{name:14s} {r['start']:6.1f} {r['run']:6.1f} {r['close']:6.1f} {r['thread']:7.2f} {r['proc']:8.2f} "
                  f"{r['cpu']:8.2f} {r['sys']:12.2f} {r['faults']:9d}", flush=True)


if __name__ == "__main__":
    main()
