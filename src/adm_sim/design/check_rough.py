"""Beyond the standard: the DIM of the real trains on a rough track beside the smooth check.

EN 1990 A2.4.4.2.1 and EN 1991-2 6.4.6 check the deck acceleration with moving loads on a smooth
track; the shipped rough-track runs (results/irregularity/README.md) show the DIM on a rough
profile exceeding that MLM in 27-40 % of the cases above 3.5 m/s². ``check --irregularity SPEC
--seeds N`` therefore runs, for every train with vehicles, the DIM (paper Eqs. 7-17, midspan
acceleration, compiled lanes) over the check's speeds on N random profiles of one spectrum (seeds
1..N, :func:`adm_sim.inputs.track_profile.parse_irregularity`; pinned to zero at both supports, the approach track
smooth) and reports the largest midspan acceleration per seed and over the seeds beside the smooth
check. It is the project's addition, labelled as beyond the standard, and never changes the verdict.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError
from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s
from adm_sim.inputs.track_profile import parse_irregularity

#: Most seeds one check runs.
MAX_SEEDS = 20
BEYOND = ("beyond the standard: EN 1991-2 checks the moving loads on a smooth track; this DIM on a rough "
          "profile is the project's addition and does not enter the verdict")


def check_spec(spec, seeds, span_m, field="--irregularity"):
    """The spectrum spec (``german-high`` or ``german-high:band=2:80``, no seed) and the seed count,
    checked by building the first profile; one-line InputError otherwise."""
    text = str(spec).strip()
    if "seed=" in text.lower():
        raise InputError(f"{field}: {text!r} names a seed; give the spectrum alone and --seeds N (seeds 1..N)")
    if "+" in text or text.lower().startswith(("file=", "ramp", "joint")) or not text:
        raise InputError(f"{field}: {text!r} is not one random spectrum; allowed german-low, german-high, fra-1..fra-6, "
                         f"iso-a..iso-h, optionally :band=LO:HI (m)")
    try:
        n = int(str(seeds))
    except ValueError:
        raise InputError(f"--seeds: {seeds!r} is not a whole number; allowed 1..{MAX_SEEDS}") from None
    if not 1 <= n <= MAX_SEEDS:
        raise InputError(f"--seeds: {n} is out of range; allowed 1..{MAX_SEEDS}")
    try:
        parse_irregularity(f"{text}:seed=1", span_m)  # an unknown spectrum or band
    except InputError as exc:
        raise InputError(f"{field}: {text!r}: {str(exc).removeprefix('irregularity: ')}") from None
    return text, n


@dataclass(frozen=True)
class RoughDim:
    """One train on N profiles: per seed the largest midspan DIM acceleration and its speed."""

    train: str
    spec: str
    seeds: tuple
    max_acc_m_s2: tuple
    at_speed_kmh: tuple
    smooth_check_m_s2: float  # the train's largest acceleration of the (smooth, MLM) check

    @property
    def worst(self):
        i = int(np.argmax(self.max_acc_m_s2))
        return self.seeds[i], self.max_acc_m_s2[i], self.at_speed_kmh[i]

    def to_dict(self):
        s, a, v = self.worst
        return {"train": self.train, "spectrum": self.spec, "seeds": list(self.seeds),
                "max_midspan_acc_m_s2": list(self.max_acc_m_s2), "at_speed_kmh": list(self.at_speed_kmh),
                "max_over_seeds_m_s2": a, "worst_seed": s, "smooth_check_m_s2": self.smooth_check_m_s2,
                "note": BEYOND}

    def line(self, limit_m_s2):
        per = ", ".join(f"seed {s}: {a:.4f} at {v:g} km/h" for s, a, v in
                        zip(self.seeds, self.max_acc_m_s2, self.at_speed_kmh))
        s, a, v = self.worst
        return (f"rough track {self.spec} ({len(self.seeds)} seeds), DIM midspan, {self.train}: {per}; max {a:.4f} "
                f"m/s2 (seed {s}) beside the smooth check's {self.smooth_check_m_s2:.4f} m/s2 "
                f"({'above' if a > limit_m_s2 else 'within'} the {limit_m_s2:g} m/s2 limit) [{BEYOND}]")


def rough_dim(bridge, train, speeds_kmh, spec, seeds, smooth_check_m_s2, options=None):
    """:class:`RoughDim` of ``train`` (with vehicles) on ``bridge`` over ``speeds_kmh`` for seeds 1..``seeds``."""
    from adm_sim.integrate.compiled_batch import BatchRunner  # noqa: PLC0415  numba, only with --irregularity

    options = options or StepOptions()
    v_kmh = np.asarray(speeds_kmh, dtype=float)
    grid = make_grid(bridge, train.length_m, speeds_to_m_s(v_kmh), options)
    acc, at = [], []
    for s in range(1, seeds + 1):
        prof = parse_irregularity(f"{spec}:seed={s}", bridge.span_m)
        runner = BatchRunner([bridge], train, grid.ds_m, options.free_vibration_periods, options.dense_maxima,
                             irregularity=prof)
        a = np.asarray(runner.run("dim", np.zeros(v_kmh.size, dtype=np.int64), v_kmh, 0.0)[0])
        i = int(np.argmax(a))
        acc.append(float(a[i]))
        at.append(float(v_kmh[i]))
    return RoughDim(train=train.name, spec=spec, seeds=tuple(range(1, seeds + 1)), max_acc_m_s2=tuple(acc),
                    at_speed_kmh=tuple(at), smooth_check_m_s2=float(smooth_check_m_s2))
