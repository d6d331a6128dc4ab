"""The irregularity slice, run as studies (one directory per spectrum and seed), resumable.

Sub-slice of "ICE-2 and Railjet over the mu2 set": the mu2 bridges of spans 4, 8, ..., 40 m at
frequency indices 1, 3, 5 (LB, fit and UB power law of n0): 30 bridges per train, 60 cases per
(spectrum, seed). Seed-major order (seed 1 for German low, German high and FRA 6, then seed 2,
...), so an interrupted run leaves whole seeds. Every study skips the cases already in its
results.jsonl: rerun the same command to resume. Settings of the shipped runs: the paper's DIM grid
(Section 3.3), 160..350 km/h at 1 km/h.

    nohup .venv/bin/python results/irregularity/run_slice.py [--seeds 1,2,3,4,5] [--out DIR] [--workers 2] \\
        > results/irregularity/run.log 2>&1 &

The arguments are read in :func:`main` only, so importing this module (``analyse.py`` does, for
:func:`slice_cases`) never reads the importer's command line.
"""

import argparse
import sys
import time
from pathlib import Path

from adm_calib.study import StudySettings, run_study, select_cases

HERE = Path(__file__).resolve().parent
SPECTRA = ("german-low", "german-high", "fra-6")
SEEDS = (1, 2, 3, 4, 5)
SPANS_M = tuple(float(s) for s in range(4, 41, 4))
FREQ_INDICES = (1, 3, 5)
#: The DIM grid of the shipped runs (the study's default became ``window`` later).
DIM_GRID = "paper"


def slice_cases():
    cases = select_cases(trains=("ICE-2", "Railjet"), mass_functions=("mu2",), freq_indices=FREQ_INDICES)
    return [c for c in cases if c.span_m in SPANS_M]


def _seeds(text):
    """``1,2,5`` or ``1 2 5``: the seeds, each an integer >= 0 (as ``--irregularity SPEC:seed=N``)."""
    out = []
    for s in text.replace(",", " ").split():
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{s!r} is not an integer (allowed: integers >= 0, a comma list)") from None
        if v < 0:
            raise argparse.ArgumentTypeError(f"{v} is negative (allowed: integers >= 0, a comma list)")
        out.append(v)
    if not out:
        raise argparse.ArgumentTypeError(f"{text!r} holds no seed (allowed: integers >= 0, a comma list)")
    return tuple(out)


def _workers(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer (allowed: integers in [1, 64] processes)") from None
    if not 1 <= v <= 64:
        raise argparse.ArgumentTypeError(f"{v} processes is outside [1, 64]")
    return v


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        """Bad arguments: one line on stderr, exit 2 (no usage block)."""
        self.exit(2, f"error: {message}\n")


def parse_args(argv=None):
    p = _Parser(prog="run_slice.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=_seeds, default=SEEDS, help="comma list of profile seeds (default 1,2,3,4,5)")
    p.add_argument("--out", type=Path, default=HERE / "runs",
                   help="root of the study directories <spectrum>-s<seed> (default results/irregularity/runs)")
    p.add_argument("--workers", type=_workers, default=2, metavar="N",
                   help="worker processes of the local cluster (integer in [1, 64], default 2)")
    return p.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    cases = slice_cases()
    t0 = time.time()
    for seed in args.seeds:
        for spec in SPECTRA:
            out = args.out / f"{spec}-s{seed}"
            settings = StudySettings(irregularity=f"{spec}:seed={seed}", dim_grid=DIM_GRID)
            t = time.time()
            run = run_study(out, cases, settings=settings, workers=args.workers,
                            options={"slice": "mu2, spans 4:40:4 m, freq_index 1,3,5", "trains": ["ICE-2", "Railjet"]})
            print(f"== {time.strftime('%H:%M:%S', time.gmtime())} {spec} seed {seed}: {run.summary()} "
                  f"({time.time() - t:.0f} s, total {time.time() - t0:.0f} s)", flush=True)
            if run.interrupted:
                return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
