"""The comparison of paper Section 4.4: Table 4 (Δζ of four approaches) for B1-B4 x four trains.

Rows: ``VBI`` (Δζ_VBI calibrated here), ``LB`` (lower-bound functions, Tables B1-B4), ``ADM``
(EN 1991-2 6.4.6.3.1) and ``EADA`` (Eq. 3; undefined for the Eurostar). Columns train-major, as the
paper prints them. Undefined values are empty in the CSV and ``n/a`` in the text table.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

from adm_sim.model.bridge import named_bridge
from adm_sim.inputs.train_files import load_train

from adm_calib.calibrate import calibrate
from adm_calib.reference import STUDY_TRAINS
from adm_calib.workers import die_with_parent

BRIDGES = ("B1", "B2", "B3", "B4")
ROWS = ("VBI", "LB", "ADM", "EADA")


def _calibrate_one(args):
    bridge_name, train_name, speeds, options = args
    return calibrate(named_bridge(bridge_name), load_train(train_name), speeds_kmh=speeds, options=options,
                     adapted_curve=False)


@dataclass
class Table4:
    """Calibrations of every (train, bridge) pair; ``results[(train, bridge)]``."""

    trains: tuple
    bridges: tuple
    results: dict = field(default_factory=dict)

    @property
    def zeta_pct(self):
        out = {}
        for (_, b), r in self.results.items():
            out[b] = r.zeta_pct
        return out

    def value(self, row, train, bridge):
        """Δζ (%) of approach ``row`` or ``None`` where undefined."""
        r = self.results[(train, bridge)]
        return {"VBI": r.delta_zeta_vbi_pct, "LB": r.delta_zeta_lb_pct, "ADM": r.delta_zeta_adm_pct,
                "EADA": r.delta_zeta_eada_pct}[row]

    def columns(self):
        return [(t, b) for t in self.trains for b in self.bridges]

    def to_csv(self):
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["approach"] + [f"{t} {b}" for t, b in self.columns()])
        for row in ROWS:
            vals = [self.value(row, t, b) for t, b in self.columns()]
            w.writerow([row] + ["" if v is None else f"{v:.4f}" for v in vals])
        return buf.getvalue()

    def to_text(self):
        """Readable table in the paper's layout (Δζ in %), with the flags below it."""
        cols = self.columns()
        lines = ["Additional damping dz (%) for different approaches (paper Table 4 layout)"]
        head1 = f"{'':6}" + "".join(f"{t:<{8 * len(self.bridges)}}" for t in self.trains)
        head2 = f"{'':6}" + "".join(f"{b:>8}" for _, b in cols)
        lines += [head1, head2]
        for row in ROWS:
            vals = [self.value(row, t, b) for t, b in cols]
            lines.append(f"{row:6}" + "".join(f"{'n/a':>8}" if v is None else f"{v:8.3f}" for v in vals))
        notes = []
        for (t, b) in cols:
            r = self.results[(t, b)]
            flags = []
            if r.status != "ok":
                flags.append(f"status {r.status}: {r.message}")
            if r.mlm_peak.max_at_range_end:
                flags.append("largest MLM value at an end of the speed range")
            if r.dim_peak.found and not r.dim_peak.is_local_max:
                flags.append("associated DIM value is not a local maximum")
            if flags:
                notes.append(f"  {t} {b}: " + "; ".join(flags))
        if notes:
            lines += ["Cases to check on the curves:"] + notes
        if any(r.delta_zeta_eada_pct is None for r in self.results.values()):
            lines.append("EADA n/a: not defined for trains with Jacobs bogies (Eurostar), paper Section 4.4.")
        return "\n".join(lines)

    def to_json(self):
        return json.dumps({f"{t} {b}": self.results[(t, b)].to_dict(curves=False) for t, b in self.columns()},
                          indent=2)


def run_table4(bridges=BRIDGES, trains=STUDY_TRAINS, speeds_kmh=None, *, options=None, jobs=1, progress=None):
    """Calibrate every (train, bridge) pair; ``jobs`` > 1 runs them in worker processes.

    ``progress(done, total, note)`` (optional) is called after every pair with the pair's name.
    """
    pairs = [(t, b) for t in trains for b in bridges]
    args = [(b, t, speeds_kmh, options) for t, b in pairs]
    table = Table4(trains=tuple(trains), bridges=tuple(bridges))
    pool = (ProcessPoolExecutor(max_workers=jobs, initializer=die_with_parent, initargs=(os.getpid(),))
            if jobs > 1 else contextlib.nullcontext())
    with pool as ex:
        results = (ex.map if ex is not None else map)(_calibrate_one, args)
        for i, (pair, res) in enumerate(zip(pairs, results), start=1):
            table.results[pair] = res
            if progress is not None:
                progress(i, len(pairs), " x ".join(pair))
    return table
