"""The irregularity slice, run as studies (one directory per spectrum and seed), resumable.

Sub-slice of "ICE-2 and Railjet over the mu2 set": the mu2 bridges of spans 4, 8, ..., 40 m at
frequency indices 1, 3, 5 (LB, fit and UB power law of n0): 30 bridges per train, 60 cases per
(spectrum, seed). Seed-major order (seed 1 for German low, German high and FRA 6, then seed 2,
...), so an interrupted run leaves whole seeds. Every study skips the cases already in its
results.jsonl: rerun the same command to resume.

    nohup /work/main/.venv/bin/python results/irregularity/run_slice.py > results/irregularity/run.log 2>&1 &
"""

import sys
import time
from pathlib import Path

from adm_calib.study import StudySettings, run_study, select_cases

HERE = Path(__file__).resolve().parent
SPECTRA = ("german-low", "german-high", "fra-6")
SEEDS = tuple(int(s) for s in (sys.argv[1:] or "1 2 3 4 5".split()))
SPANS_M = tuple(float(s) for s in range(4, 41, 4))
FREQ_INDICES = (1, 3, 5)


def slice_cases():
    cases = select_cases(trains=("ICE-2", "Railjet"), mass_functions=("mu2",), freq_indices=FREQ_INDICES)
    return [c for c in cases if c.span_m in SPANS_M]


def main():
    cases = slice_cases()
    t0 = time.time()
    for seed in SEEDS:
        for spec in SPECTRA:
            out = HERE / "runs" / f"{spec}-s{seed}"
            settings = StudySettings(irregularity=f"{spec}:seed={seed}")
            t = time.time()
            run = run_study(out, cases, settings=settings, workers=2,
                            options={"slice": "mu2, spans 4:40:4 m, freq_index 1,3,5", "trains": ["ICE-2", "Railjet"]})
            print(f"== {time.strftime('%H:%M:%S', time.gmtime())} {spec} seed {seed}: {run.summary()} "
                  f"({time.time() - t:.0f} s, total {time.time() - t0:.0f} s)", flush=True)
            if run.interrupted:
                return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
