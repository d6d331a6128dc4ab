"""Cost of the parametric study: batched vs one-by-one cases, 1 vs 2 workers, the full-study projection.

    .venv/bin/python bench/bench_study.py [--span 15] [--train ICE-2] [--sample-spans 4,8,15,25,40]
                                          [--worker-spans 4,5] [--measured results/study/study.json] [--quick]

Wall-clock timings on a shared 2-core box: run it when nothing else is busy (the full run takes
several minutes; ``--quick`` is a smoke run of a few cheap cases, L = 39-40 m at the lowest
frequency, whose numbers mean nothing). One BLAS thread everywhere. The numba kernels are warmed
up (compiled, or loaded from the cache) on a tiny case before anything is timed. Nothing is
asserted; the targets are printed next to the numbers.

(a) Batching, in this process. The 30 cases of one span for one train (5 frequency indices x 6
    mass functions) through :func:`adm_calib.study.run_batch`, one call per batch key as the
    study does (5 batches of 6), against the same 30 cases one by one through today's path
    ``adm_calib.calibrate.calibrate(bridge, train, options=..., adapted_curve=False)``. Printed
    as cases per second and their ratio (target >= 10x), with the largest difference of
    Δζ_VBI between the two paths. ``--quick``: L = 40 m, one frequency index (one batch of 6
    cases) against 2 cases one by one.

(b) Workers. A 2-span subset (all frequency indices and mass functions of the two spans of
    ``--worker-spans``, default 4 and 5 m, the costliest spans, where the study spends its time;
    one train: 60 cases, 10 batches) through :func:`adm_calib.study.run_study` on a local cluster
    of 1 and of 2 workers, wall times including the cluster start and each worker's first kernel
    load; their ratio (target >= 1.8x). The fixed start-up (a cluster of that many workers
    started and every worker's kernels loaded, no case run) is measured separately and printed,
    with the ratio of the wall times net of it, and the machine's own ceiling: one batch
    computed three times alone, then in two processes at once (throughput ratio
    ``2 t_alone / t_both``). ``--quick``: 39 + 40 m.

(c) Projection of the full study (4440 cases = 740 batches: 185 (span, frequency index) pairs x
    4 trains) on 2 workers. Per-batch costs ``t(L, i)`` for the train of (b) are measured in
    this process at every frequency index i of the sample spans (``--sample-spans``); the cost
    of every other span is interpolated per frequency index, linearly in ``log t`` over
    ``log L`` (held constant outside the sample). The other trains are scaled by one factor each,
    ``r_train = t_train(L*, i*) / t_ref(L*, i*)``, measured on one batch (L* = ``--span``,
    i* = 3; quick: i* = 1). The batches are then dealt in the study's order (highest n0 first)
    to whichever of the 2 workers is free first (a greedy list schedule, as dask does with one
    thread per worker), giving the makespan ``M``; the projection is

        T_2 = M + o_2,   o_2 = W_2 - M_b

    where ``W_2`` is the measured 2-worker wall time of (b) and ``M_b`` the same schedule
    computed from the in-process costs of (b)'s own batches (so ``o_2`` is the cluster start,
    the per-worker kernel load and the dask overhead, taken as independent of the study's size).
    The projected CPU total ``sum t`` and the 1-worker overhead ``o_1 = W_1 - sum t_b`` are
    printed too.
    With ``--measured study.json``, the wall time actually measured is read from that file's
    ``runs`` entries (sum of ``wall_s`` of the runs, cases completed, workers of each run).
"""

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import heapq
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from adm_calib import study as st

FULL_CASES = 4440


def _train(name):
    from adm_sim.inputs.train_files import load_train

    return load_train(name)


def _batch(train, span, fi, mass_functions=st.MASS_FUNCTION_NAMES):
    cases = st.select_cases([train], mass_functions, (span, span), [fi])
    if not cases:
        raise SystemExit(f"no field case for {train} at L = {span:g} m, frequency index {fi}")
    return cases


def timed_batch(cases, settings):
    t0 = time.perf_counter()
    recs = st.run_batch(cases, settings)
    return time.perf_counter() - t0, recs


def warm_up(settings, train):
    """First calls compile (or load from the numba cache): one cheap case through both paths."""
    from adm_calib.calibrate import calibrate

    t0 = time.perf_counter()
    case = _batch(train, 40, 1, ["mu1"])
    st.run_batch(case, settings)
    calibrate(case[0].bridge, _train(train), speeds_kmh=settings.speeds_kmh(),
              options=settings.calibration_options(), adapted_curve=False)
    return time.perf_counter() - t0


def schedule(costs, workers):
    """Makespan of dealing ``costs`` in order to whichever worker is free first."""
    free = [0.0] * workers
    for c in costs:
        heapq.heappush(free, heapq.heappop(free) + c)
    return max(free)


def study_order(batches):
    """The study's submission order: highest n0 first (stable)."""
    return sorted(batches, key=lambda b: -b[0].bridge.n0_hz)


# ---------------------------------------------------------------------- (a)
def part_a(settings, train, span, fis, n_single, sample):
    from adm_calib.calibrate import calibrate

    tr = _train(train)
    batched, recs = 0.0, {}
    for fi in fis:
        cases = _batch(train, span, fi)
        dt, rs = timed_batch(cases, settings)
        sample[(span, fi)] = dt
        batched += dt
        recs.update({(r["bridge"], r["train"]): r for r in rs})
    n_batched = len(recs)
    singles = [c for fi in fis for c in _batch(train, span, fi)][:n_single]
    t0 = time.perf_counter()
    dz_diff = 0.0
    for c in singles:
        res = calibrate(c.bridge, tr, speeds_kmh=settings.speeds_kmh(), options=settings.calibration_options(),
                        adapted_curve=False)
        a, b = res.delta_zeta_vbi_pct, recs[c.key]["delta_zeta_vbi_pct"]
        if a is not None and b is not None:
            dz_diff = max(dz_diff, abs(a - b))
        elif (a is None) != (b is None):
            dz_diff = float("inf")
    single = time.perf_counter() - t0
    return {"n_batched": n_batched, "batched_s": batched, "n_single": len(singles), "single_s": single,
            "dz_diff": dz_diff}


# ---------------------------------------------------------------------- (c) sample
def measure_sample(settings, train, spans, fis, sample):
    for L in spans:
        for fi in fis:
            if (L, fi) not in sample:
                sample[(L, fi)] = timed_batch(_batch(train, L, fi), settings)[0]


def train_factors(settings, ref_train, span, fi, sample):
    out = {}
    for t in st.STUDY_TRAINS:
        if t == ref_train:
            out[t] = 1.0
        else:
            out[t] = timed_batch(_batch(t, span, fi), settings)[0] / sample[(span, fi)]
    return out


def predict(sample, factors, ref_train):
    """Predicted cost of every batch of the full study, in the study's order."""
    spans = sorted({L for L, _ in sample})
    fis = sorted({fi for _, fi in sample})
    costs = []
    for b in study_order(st.make_batches(st.select_cases())):
        L, fi = b[0].span_m, b[0].freq_index
        near = min(fis, key=lambda f: (abs(f - fi), f))       # quick: only some indices measured
        y = np.log([sample[(s, near)] for s in spans])
        t = float(np.exp(np.interp(np.log(L), np.log(spans), y)))
        costs.append(t * factors[b[0].train] * len(b) / 6.0)
    return costs


# ---------------------------------------------------------------------- (b)
def _load_kernels():
    """What a worker does before its first case: import the study and load the compiled kernels."""
    from adm_calib import study

    study.run_batch(study.select_cases(["ICE-2"], ["mu1"], (40, 40), [1]), study.StudySettings())
    return os.getpid()


def start_up(workers):
    """Wall time to start a local cluster of ``workers`` and load every worker's kernels."""
    from distributed import Client

    t0 = time.perf_counter()
    cluster = st.local_cluster(workers)
    with Client(cluster, set_as_default=False) as client:
        client.run(_load_kernels)
        dt = time.perf_counter() - t0
    cluster.close()
    return dt


def _timed_repeats(cases, settings, repeats, start_at=None):
    """Warm up, wait until ``start_at`` (a shared wall-clock instant), then time ``repeats`` batches."""
    st.run_batch(cases, settings)
    if start_at is not None:
        time.sleep(max(0.0, start_at - time.time()))
    t0 = time.perf_counter()
    for _ in range(repeats):
        st.run_batch(cases, settings)
    return time.perf_counter() - t0


def machine_ceiling(settings, cases, repeats=3):
    """Throughput of two processes computing at once against one alone (the same batch each).

    The ceiling any 2-worker run can reach on this machine: ``2 t_alone / max(t_1, t_2)``.
    """
    from concurrent.futures import ProcessPoolExecutor
    import multiprocessing

    alone = _timed_repeats(cases, settings, repeats)
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        start_at = time.time() + 15.0  # both processes warmed up by then
        both = list(pool.map(_timed_repeats, [cases] * 2, [settings] * 2, [repeats] * 2, [start_at] * 2))
    return alone, both


def part_b(settings, cases):
    walls, starts = {}, {}
    for workers in (1, 2):
        starts[workers] = start_up(workers)
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            run = st.run_study(d, cases, settings=settings, workers=workers)
            walls[workers] = time.perf_counter() - t0
            if run.completed != len(cases) or run.errors:
                print(f"   note: {workers}-worker run finished {run.completed} of {len(cases)} cases, "
                      f"{run.errors} errors")
    return walls, starts


def measured(path):
    meta = json.loads(Path(path).read_text())
    runs = meta.get("runs", [])
    wall = sum(float(r.get("wall_s") or 0.0) for r in runs)
    done = sum(int(r.get("completed") or 0) for r in runs)
    unfinished = sum(1 for r in runs if r.get("finished") is None)
    workers = sorted({len((r.get("cluster") or {}).get("workers") or {}) for r in runs if r.get("cluster")})
    return {"runs": len(runs), "wall_s": wall, "completed": done, "unfinished": unfinished, "workers": workers}


def print_measured(path):
    m = measured(path)
    workers = ",".join(map(str, m["workers"])) or "?"
    unfinished = f", {m['unfinished']} unfinished" if m["unfinished"] else ""
    note = f"({m['completed']} cases in {m['runs']} run(s), workers {workers}{unfinished})"
    _row("(c) measured wall (study.json runs)", f"{m['wall_s'] / 3600:.2f} h", note)


def _row(label, value, target=""):
    print(f"  {label:<46} {value:>16}  {target}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--span", type=float, default=None, help="span of (a) in m (default 15; quick: 40)")
    ap.add_argument("--train", default="ICE-2", help="train of (a), (b) and the sample (default ICE-2)")
    ap.add_argument("--sample-spans", default=None, help="spans whose batches are timed for (c) "
                    "(default 4,8,15,25,40; quick: 39,40)")
    ap.add_argument("--worker-spans", default=None, help="the two spans of (b) in m (default 4,5; quick: 39,40)")
    ap.add_argument("--measured", default=None, help="study.json of a finished study: print its measured wall time")
    ap.add_argument("--quick", action="store_true", help="smoke run on a few cheap cases (numbers not meaningful)")
    args = ap.parse_args()

    settings = st.StudySettings()
    train = st.canonical_trains([args.train], "--train")[0]
    if args.quick:
        span = 40.0 if args.span is None else args.span
        fis, n_single = (1,), 2
        spans = [39.0, 40.0] if args.sample_spans is None else [float(s) for s in args.sample_spans.split(",")]
        fi_ref = 1
    else:
        span = 15.0 if args.span is None else args.span
        fis, n_single = st.FREQ_INDICES, 30
        spans = [4.0, 8.0, 15.0, 25.0, 40.0] if args.sample_spans is None else [
            float(s) for s in args.sample_spans.split(",")]
        fi_ref = 3
    spans = sorted(set(spans) | {span})

    print(f"bench_study: train {train}, span {span:g} m, sample spans {','.join(f'{s:g}' for s in spans)}, "
          f"frequency indices {','.join(map(str, fis))}{' (quick)' if args.quick else ''}")
    print(f"  warm-up (kernels compiled or loaded from the cache): {warm_up(settings, train):.2f} s")

    sample = {}
    a = part_a(settings, train, span, fis, n_single, sample)
    measure_sample(settings, train, spans, fis, sample)
    factors = train_factors(settings, train, span, fi_ref, sample)

    if args.worker_spans is not None:
        pair = tuple(float(s) for s in args.worker_spans.split(","))
    else:
        pair = (39.0, 40.0) if args.quick else (4.0, 5.0)
    cases_b = [c for c in st.select_cases([train], spans_m=(min(pair), max(pair)), freq_indices=fis)
               if c.span_m in pair]
    measure_sample(settings, train, pair, fis, sample)  # per-batch costs of (b)'s own batches, in this process
    walls, starts = part_b(settings, cases_b)
    alone, both = machine_ceiling(settings, _batch(train, span, fi_ref))
    costs_b = [sample[(b[0].span_m, b[0].freq_index)] * len(b) / 6.0 for b in study_order(st.make_batches(cases_b))]
    m_b = schedule(costs_b, 2)
    o1, o2 = walls[1] - sum(costs_b), walls[2] - m_b

    costs = predict(sample, factors, train)
    m_full = schedule(costs, 2)

    print("  per-batch cost in this process (s), 6 cases each:")
    print("    L (m) " + "".join(f"   i={fi}" for fi in fis))
    for L in spans:
        print(f"    {L:5g} " + "".join(f"{sample[(L, fi)]:7.2f}" for fi in fis))
    print("  train factors at L = {:g} m, i = {}: {}".format(
        span, fi_ref, ", ".join(f"{t} {f:.2f}" for t, f in factors.items())))
    print()
    rate_b, rate_s = a["n_batched"] / a["batched_s"], a["n_single"] / a["single_s"]
    _row(f"(a) batched, {a['n_batched']} cases of L = {span:g} m", f"{rate_b:.3f} case/s",
         f"({a['batched_s']:.1f} s)")
    _row(f"(a) one by one (calibrate), {a['n_single']} cases", f"{rate_s:.3f} case/s", f"({a['single_s']:.1f} s)")
    _row("(a) speed-up", f"{rate_b / rate_s:.1f} x", "target >= 10 x")
    _row("(a) max |dz_VBI batched - one by one|", f"{a['dz_diff']:.2e} %")
    label = f"{len(cases_b)} cases, L = {'+'.join(f'{s:g}' for s in pair)} m"
    _row(f"(b) run_study, 1 worker, {label}", f"{walls[1]:.1f} s", f"(overhead o_1 {o1:+.1f} s)")
    _row("(b) run_study, 2 workers", f"{walls[2]:.1f} s", f"(overhead o_2 {o2:+.1f} s)")
    _row("(b) speed-up", f"{walls[1] / walls[2]:.2f} x", "target >= 1.8 x")
    _row("(b) start-up alone, 1 / 2 workers", f"{starts[1]:.1f} / {starts[2]:.1f} s",
         "(cluster start + kernel load, no case)")
    _row("(b) speed-up net of start-up", f"{(walls[1] - starts[1]) / (walls[2] - starts[2]):.2f} x")
    _row("(b) machine ceiling: 1 batch x3, alone / 2 at once", f"{alone:.1f} / {max(both):.1f} s",
         f"(2 processes give {2 * alone / max(both):.2f} x the throughput of one)")
    _row(f"(c) projected CPU, {len(costs)} batches", f"{sum(costs) / 3600:.2f} h",
         f"(mean {sum(costs) / FULL_CASES:.2f} s/case)")
    _row(f"(c) projected wall, {FULL_CASES} cases, 2 workers", f"{(m_full + o2) / 3600:.2f} h",
         f"(makespan {m_full / 3600:.2f} h + o_2)")
    if args.measured:
        print_measured(args.measured)
    if args.quick:
        print("  quick: few cheap cases; the numbers, and the projection above all, are not meaningful")


if __name__ == "__main__":
    main()
