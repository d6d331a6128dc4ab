"""Limits and defaults that several commands, nodes and the study share, each written once.

* The deck acceleration limits of EN 1990 A2.4.4.2.1(4)P, one track vocabulary:
  ``ballasted`` (γ_bt = 3.5 m/s²) and ``direct_fastening`` (γ_df = 5 m/s², "direct fastened
  tracks with track and structural elements designed for high speed traffic"). ``direct`` is
  accepted as an alias of ``direct_fastening`` only where it was documented
  (``adm-sim check --track direct``, docs/check.md).
* The default speed range of the paper, Section 3.3: 160 to 350 km/h every 1 km/h.
* The range of the additional damping Δζ: from ``-ζ`` (no negative total damping) to 20 %.

Numpy only; no ROS, no CLI (messages name the field the caller gives). The Δζ checks are the field
registry's (:func:`adm_sim.fields.check_delta_zeta`, field ``delta_zeta``), whose bounds are the
numbers written here.
"""

from __future__ import annotations

import numpy as np

from adm_sim.errors import InputError

# ---------------------------------------------------------------------- EN 1990 A2.4.4.2.1
#: Peak deck acceleration limits (m/s²) by track type, EN 1990 A2.4.4.2.1(4)P.
ACC_LIMITS_M_S2 = {"ballasted": 3.5, "direct_fastening": 5.0}
#: Track types, in the order of the table.
TRACK_TYPES = tuple(ACC_LIMITS_M_S2)
#: Other spellings accepted by the check's ``--track`` (documented interface) -> the track type.
TRACK_ALIASES = {"direct": "direct_fastening"}


def check_track_type(field, value, aliases=False):
    """The track type ``value`` (one of :data:`TRACK_TYPES`; with ``aliases`` also a key of
    :data:`TRACK_ALIASES`, returned as its track type); :class:`InputError` naming ``field``
    otherwise (``track_type: 'gravel' is not allowed; allowed ballasted or direct_fastening``)."""
    if aliases and value in TRACK_ALIASES:
        return TRACK_ALIASES[value]
    if value not in ACC_LIMITS_M_S2:
        raise InputError(f"{field}: {value!r} is not allowed; allowed {' or '.join(TRACK_TYPES)}")
    return value


def acc_limit_m_s2(track_type):
    """Peak deck acceleration limit (m/s²) of a track type (or alias), EN 1990 A2.4.4.2.1(4)P."""
    return ACC_LIMITS_M_S2[TRACK_ALIASES.get(track_type, track_type)]


# ---------------------------------------------------------------------- speeds, Section 3.3
#: Default speed range (km/h), the paper's Section 3.3: ``start:stop:step``, stop included.
DEFAULT_SPEEDS = "160:350:1"


def default_speeds_kmh():
    """The default speeds (km/h), ``(191,)``: :data:`DEFAULT_SPEEDS` parsed (a new array each call)."""
    start, stop, step = (float(x) for x in DEFAULT_SPEEDS.split(":"))
    return np.arange(start, stop + 0.5 * step, step)


# ---------------------------------------------------------------------- additional damping
#: Largest additional damping Δζ (%); the smallest is ``-ζ`` (total damping ``ζ + Δζ >= 0``).
MAX_DELTA_ZETA_PCT = 20.0
#: The same as a fraction (0.2; the calibration's ladder ends here).
MAX_DELTA_ZETA = MAX_DELTA_ZETA_PCT / 100.0


__all__ = ["ACC_LIMITS_M_S2", "TRACK_TYPES", "TRACK_ALIASES", "check_track_type", "acc_limit_m_s2",
           "DEFAULT_SPEEDS", "default_speeds_kmh", "MAX_DELTA_ZETA_PCT", "MAX_DELTA_ZETA"]
