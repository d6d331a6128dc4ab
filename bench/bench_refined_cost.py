"""CPU cost of the refined-speed study against the default one, on a sample of study batches.

Run: ``.venv/bin/python bench/bench_refined_cost.py [--every 31]``. Takes every N-th batch of the
whole study (batches in the study's own order: highest n0 first), runs each with the default
settings and with ``refine_speed`` one after the other in this process, and prints the ratio of
their process (CPU) times: unlike wall times on a shared machine, it does not depend on what else
runs. The kernels are compiled (or loaded from numba's cache) by an untimed warm-up.
"""

import argparse
import time

from adm_calib import study as st


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=int, default=31, help="take every N-th batch (default 31)")
    args = ap.parse_args()
    batches = sorted(st.make_batches(st.select_cases()), key=lambda b: -b[0].bridge.n0_hz)[::args.every]
    default, refined = st.StudySettings(), st.StudySettings(refine_speed=True)
    st.run_batch(batches[-1][:1], default)
    st.run_batch(batches[-1][:1], refined)
    tot = [0.0, 0.0]
    for b in batches:
        cpu = []
        for s in (default, refined):
            t0 = time.process_time()
            st.run_batch(b, s)
            cpu.append(time.process_time() - t0)
        tot[0] += cpu[0]
        tot[1] += cpu[1]
        c = b[0]
        print(f"{c.train:9} L{c.bridge.span_m:g} f{c.freq_index} ({len(b)} cases): default {cpu[0]:.2f} s, "
              f"refined {cpu[1]:.2f} s CPU, x{cpu[1] / cpu[0]:.2f}", flush=True)
    print(f"{len(batches)} batches: default {tot[0]:.1f} s, refined {tot[1]:.1f} s CPU: refined/default "
          f"x{tot[1] / tot[0]:.2f} (target <= 1.5)")


if __name__ == "__main__":
    main()
