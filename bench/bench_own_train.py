"""One train's study from its file timed beside the built-in ICE-2's, in one run (docs/own_train.md).

    .venv/bin/python bench/bench_own_train.py [--train FILE] [--workers 2] [--spans 4:40] [--freq-index 1,2,3,4,5]
                                              [--quick]

Both studies run as ``adm-calib study`` runs them (:func:`adm_calib.study.run_study` on a loopback
local cluster, ``--workers`` processes of one thread, default 2), each into a fresh temporary
folder, the train file first (default: the example vehicle train, src/adm_sim/data/examples/
my_vehicle_train.toml), then the built-in ICE-2 on the same cases (default: the whole field, 1110
cases each). Printed: each wall time (cluster start included), cases per second, the ratio file
train / ICE-2, the 1-minute load average before and after each run (the machine is shared: a
load above the worker count slows both), and the target (one train's 1110 cases within 90 s on
a quiet machine, two workers). The numba kernels are loaded once before anything is timed.
``--quick``: L = 39-40 m at the lowest frequency (12 cases each), a smoke run whose numbers mean
little. Nothing is asserted.
"""

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import tempfile
import time
from pathlib import Path

from adm_calib import study as st
from adm_calib.study.own_train import study_trains

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 90.0


def _load():
    return float(Path("/proc/loadavg").read_text().split()[0])


def timed_study(trains, files, selection, workers):
    cases = st.select_cases(trains, own=files, **selection)
    with tempfile.TemporaryDirectory(prefix="bench_own_train_") as tmp:
        l0 = _load()
        t0 = time.perf_counter()
        run = st.run_study(Path(tmp) / "study", cases, workers=workers, train_files=files)
        wall = time.perf_counter() - t0
        l1 = _load()
    return len(cases), wall, run, (l0, l1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train", default=str(ROOT / "src" / "adm_sim" / "data" / "examples" / "my_vehicle_train.toml"),
                    help="train or vehicle file (default: the example vehicle train)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--spans", default="4:40", help="span range lo:hi in m (default the field's 4:40)")
    ap.add_argument("--freq-index", default="1,2,3,4,5")
    ap.add_argument("--quick", action="store_true", help="L = 39-40 m, lowest frequency: a smoke run")
    a = ap.parse_args(argv)
    lo, hi = ((39, 40) if a.quick else tuple(float(x) for x in a.spans.split(":")))
    selection = {"spans_m": (lo, hi), "freq_indices": [1] if a.quick else [int(x) for x in a.freq_index.split(",")]}
    names, files = study_trains([a.train])
    # the kernels (compiled or loaded from numba's cache) before anything is timed
    st.run_batch(st.select_cases(["ICE-2"], ["mu1"], (40, 40), [1]))
    n_f, wall_f, run_f, load_f = timed_study(names, files, selection, a.workers)
    n_i, wall_i, run_i, load_i = timed_study(["ICE-2"], {}, selection, a.workers)
    print(f"own train study: {names[0]!r} from {a.train} against the built-in ICE-2, {a.workers} workers, "
          f"spans {lo:g}-{hi:g} m, frequency indices {selection['freq_indices']}")
    for label, n, wall, run, (l0, l1) in ((names[0], n_f, wall_f, run_f, load_f), ("ICE-2", n_i, wall_i, run_i, load_i)):
        st_text = ", ".join(f"{k} {v}" for k, v in sorted(run.statuses.items()))
        print(f"  {label:24} {n:5d} cases {wall:8.1f} s {n / wall:7.2f} cases/s  ({st_text}; load {l0:.2f} -> {l1:.2f})")
    print(f"  ratio {names[0]!r} / ICE-2 wall time: {wall_f / wall_i:.3f}")
    if n_f == 1110:
        print(f"  target: one train's 1110 cases within {TARGET_S:g} s on a quiet machine with 2 workers: "
              f"{wall_f:.1f} s ({'met' if wall_f <= TARGET_S else 'not met'}; load {load_f[0]:.2f} at the start)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
