"""Speeds as the user types them: ``start:stop:step`` (stop included) or a comma list, in km/h.

One reader for the command lines (``--speeds``), the ROS parameters (``speeds_kmh``), the launch
scripts and the study; the speed range and the bounded work are the field registry's
(:mod:`adm_sim.fields`: ``speeds_kmh``, ``n_speeds``, ``n_lanes``).
"""

from __future__ import annotations

import math

import numpy as np

from adm_sim.errors import InputError
from adm_sim.fields import FIELDS, check_count


def parse_speeds(text, ordered=True, field="speeds_kmh"):
    """Speeds (km/h) from ``"160:350:1"`` (start:stop:step, stop included) or ``"200,250"``.

    Every number must be finite; each speed lies in [1, 600] km/h. With ``ordered`` (every user
    input) a comma list must increase strictly, because a peak over speed is only meaningful on an
    ordered grid; lanes of a run (the train node's ``speeds_kmh``, e.g. a damping ladder that
    repeats its speeds) take ``ordered=False``. ``field`` names the input in messages (the ROS
    nodes pass their parameter name ``speeds_kmh``).
    """
    text = str(text).strip()
    if ":" in text and "," in text:
        raise InputError(f"{field}: {text!r} mixes ':' and ','; give start:stop:step or a comma list (km/h)", field=field)
    try:
        parts = [float(p) for p in text.replace(":", ",").split(",") if p.strip()]
    except ValueError:
        parts = None
    if not parts or (":" in text and len(parts) not in (2, 3)):
        raise InputError(f"{field}: {text!r} is not start:stop:step or a comma list (km/h)", field=field)
    bad = [p for p in parts if not math.isfinite(p)]
    if bad:
        raise InputError(f"{field}: {text!r} holds {bad[0]!r}; every speed and step must be a finite number (km/h)", field=field)
    if ":" in text:
        a, b, st = parts if len(parts) == 3 else parts + [1.0]
        if st <= 0 or b < a:
            raise InputError(f"{field}: {text!r} needs start <= stop and step > 0 (km/h)", field=field)
        n = int(math.floor((b - a) / st + 1e-9)) + 1
        check_count("n_speeds" if ordered else "n_lanes", n, field, repr(text))  # before any array
        v = a + st * np.arange(n)
    else:
        check_count("n_speeds" if ordered else "n_lanes", len(parts), field, repr(text))
        v = np.array(parts)
        if ordered and np.any(np.diff(v) <= 0):
            raise InputError(f"{field}: {text!r} must increase strictly (km/h), e.g. 200,250,263", field=field)
    lo, hi = FIELDS["speeds_kmh"].range
    out = v[(v < lo) | (v > hi)]
    if out.size:
        raise InputError(f"{field}: {text!r} gives {out[0]:g} km/h; allowed speeds in [{lo:g}, {hi:g}] km/h", field=field)
    return v
