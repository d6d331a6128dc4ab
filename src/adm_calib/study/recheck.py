"""Re-derive the "MLM maximum at range end" flag of study results from their MLM curves.

The result lines hold no curves, so a change of the flag's definition
(:func:`adm_calib.peaks.max_at_range_end`, now with a relative tolerance) cannot be applied to
them by reading alone. :func:`range_end_recheck` recomputes the MLM curve at the bridge's own
damping (Section 4, Step 1; the same batched compiled run and the same space step as the study,
:func:`adm_calib.calibrate.batch_step`) of every case, checks that its peak is the shipped one, and
returns the flag under both definitions with the end-to-maximum ratio.

    python -m adm_calib.study.recheck results/study/results.jsonl.gz OUT.csv
"""

from __future__ import annotations

import csv
import sys
import time
from dataclasses import dataclass

import numpy as np

from adm_calib import peaks as pk
from adm_calib.calibrate import batch_step
from adm_calib.study.cases import StudySettings, _train, select_cases
from adm_calib.study.store import read_results, record_key


@dataclass(frozen=True)
class RangeEndRow:
    """One case: ``end_ratio`` = larger end value / largest value of the MLM curve (<= 1)."""

    bridge: str
    train: str
    max_speed_kmh: float
    max_acc_m_s2: float
    end_ratio: float
    flag_strict: bool
    flag_tolerant: bool
    shipped_flag: bool
    peak_matches: bool


def range_end_recheck(records, settings=StudySettings(), rtol=pk.RANGE_END_RTOL, progress=None):
    """The range-end flag of every record with a MLM peak, strict (``rtol=0``) and with ``rtol``.

    Returns
    -------
    list of RangeEndRow
        ``peak_matches``: the recomputed MLM peak equals the shipped one (speed, and value to 1e-9).
    """
    from adm_sim.integrate.compiled_batch import BatchRunner  # noqa: PLC0415  numba kernels, only for the re-check

    by_key = {record_key(r): r for r in records}
    groups = {}
    for c in select_cases(sorted({r["train"] for r in by_key.values()})):
        if c.key in by_key:
            groups.setdefault(c.batch_key, []).append(c)
    v = settings.speeds_kmh()
    opt = settings.calibration_options()
    out = []
    for i, cases in enumerate(groups.values()):
        train = _train(cases[0].train)
        bridges = [c.bridge for c in cases]
        step = batch_step(bridges, train, v, opt)
        runner = BatchRunner(bridges, train, step.ds_m, step.free_vibration_periods)
        n = len(cases)
        acc = runner.run("mlm", np.repeat(np.arange(n), v.size), np.tile(v, n))[0].reshape(n, v.size)
        for c, a in zip(cases, acc):
            rec = by_key[c.key]
            peak = pk.find_peak(v, a, opt.min_prominence_rel)
            shipped = rec.get("mlm_peak") or {}
            same = (peak.found == bool(shipped)) and (not peak.found or (
                peak.speed_kmh == shipped["speed_kmh"] and abs(peak.acc_m_s2 / shipped["acc_m_s2"] - 1) <= 1e-9))
            j = int(np.argmax(a))
            out.append(RangeEndRow(bridge=c.bridge.name, train=c.train, max_speed_kmh=float(v[j]),
                                   max_acc_m_s2=float(a[j]), end_ratio=float(max(a[0], a[-1]) / a[j]),
                                   flag_strict=pk.max_at_range_end(a, 0.0), flag_tolerant=pk.max_at_range_end(a, rtol),
                                   shipped_flag=bool(rec.get("mlm_max_at_range_end")), peak_matches=bool(same)))
        if progress:
            progress(i + 1, len(groups))
    return out


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    src, dst = argv
    t0 = time.perf_counter()
    rows = range_end_recheck(read_results(src).records,
                             progress=lambda i, n: print(f"{i}/{n} batches", file=sys.stderr, flush=True)
                             if i % 50 == 0 or i == n else None)
    with open(dst, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["bridge", "train", "max_speed_kmh", "max_acc_m_s2", "end_ratio", "flag_strict",
                    f"flag_rtol_{pk.RANGE_END_RTOL:g}", "shipped_flag", "peak_matches"])
        for r in rows:
            w.writerow([r.bridge, r.train, f"{r.max_speed_kmh:g}", f"{r.max_acc_m_s2:.9g}", f"{r.end_ratio:.9f}",
                        int(r.flag_strict), int(r.flag_tolerant), int(r.shipped_flag), int(r.peak_matches)])
    changed = sum(r.flag_tolerant != r.shipped_flag for r in rows)
    print(f"{len(rows)} cases in {time.perf_counter() - t0:.0f} s; flag changed for {changed}; "
          f"strict flag = shipped for {sum(r.flag_strict == r.shipped_flag for r in rows)}; "
          f"peaks match for {sum(r.peak_matches for r in rows)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
