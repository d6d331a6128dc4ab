"""Association of the DIM peak with the MLM peak (paper Section 4, step 2).

The peak rule itself (interior local maxima with 0.1 % prominence, the highest one, the
``max_at_range_end`` flag, :class:`Peak`) lives in :mod:`adm_sim.integrate.peaks`, the one home of the rule,
and is re-exported here. This module adds the calibration's rules on top of it:

* the **MLM peak** is the highest peak of the MLM curve (:func:`find_peak`). If the curve's
  largest value lies at an end of the speed range (ties within 0.1 % included), the chosen peak is a lesser interior maximum
  and the flag ``max_at_range_end`` says so. If there is no peak, the outcome is "no reasonable
  peak".
* **association rule**: the DIM peak associated with the MLM peak at speed ``v_m`` is the highest
  DIM peak (interior local maximum of the whole DIM curve) whose speed lies in the window
  ``[v_m - 20, v_m + 10]`` km/h. Interaction adds the wheelset mass to the bridge and lowers its
  frequency, so the DIM resonance moves to lower speeds; the paper refines its DIM sweeps on
  ``[v_m - 20, v_m + 5]`` for this reason (Section 3.3), and the window adds 5 km/h upwards for
  margin. If the window holds no DIM peak, the largest DIM value in the window is used and
  ``is_local_max`` is False: such a case is the one the paper settled by looking at the curves,
  and a study may filter on the flag.
"""

from __future__ import annotations

import numpy as np

from adm_sim.integrate.peaks import MIN_PROMINENCE_REL, RANGE_END_RTOL, Peak, find_peak, largest_interior_peak, local_maxima, max_at_range_end
from adm_sim.integrate.peaks import check_curve as _check_curve

__all__ = ["ASSOCIATION_WINDOW_KMH", "MIN_PROMINENCE_REL", "RANGE_END_RTOL", "STATUSES", "UNDETERMINED_STATUSES",
           "Peak", "associate_peak", "association_decided", "determination", "extend_advice", "find_peak",
           "has_delta_zeta", "record_status",
           "largest_interior_peak", "local_maxima", "max_at_range_end", "window_max"]

#: Association window around the MLM peak speed (km/h): (below, above).
ASSOCIATION_WINDOW_KMH = (20.0, 10.0)


def associate_peak(speeds_kmh, acc_m_s2, ref_speed_kmh, window_kmh=ASSOCIATION_WINDOW_KMH, *,
                   min_prominence_rel=MIN_PROMINENCE_REL):
    """The point of a (DIM) curve associated with a reference (MLM) peak speed.

    Rule (module docstring): the highest interior local maximum with speed in
    ``[ref - window[0], ref + window[1]]``; if none, the largest value in that window, flagged
    ``is_local_max=False``.

    Returns
    -------
    Peak
        ``found=False`` if the curve has no sample in the window.
    """
    v, a = _check_curve(speeds_kmh, acc_m_s2)
    lo, hi = ref_speed_kmh - window_kmh[0], ref_speed_kmh + window_kmh[1]
    in_win = (v >= lo - 1e-9) & (v <= hi + 1e-9)
    at_end = bool(a.size and max_at_range_end(a))
    if not np.any(in_win):
        return Peak(found=False, max_at_range_end=at_end,
                    reason=f"no sample in the association window [{lo:g}, {hi:g}] km/h")
    idx = local_maxima(a, min_prominence_rel)
    idx = idx[in_win[idx]]
    if idx.size:
        i = int(idx[np.argmax(a[idx])])
        return Peak(found=True, index=i, speed_kmh=float(v[i]), acc_m_s2=float(a[i]), is_local_max=True,
                    max_at_range_end=at_end,
                    reason=f"highest local maximum in the window [{lo:g}, {hi:g}] km/h")
    w = np.flatnonzero(in_win)
    i = int(w[np.argmax(a[w])])
    return Peak(found=True, index=i, speed_kmh=float(v[i]), acc_m_s2=float(a[i]), is_local_max=False,
                max_at_range_end=at_end,
                reason=f"no local maximum in the window [{lo:g}, {hi:g}] km/h: largest value in it")


def association_decided(speeds_kmh, acc_m_s2, ref_speed_kmh, window_kmh=ASSOCIATION_WINDOW_KMH, *,
                        min_prominence_rel=MIN_PROMINENCE_REL):
    """Whether :func:`associate_peak` on this part of a curve gives what it gives on the whole curve.

    The part is a contiguous run of the whole curve's samples that holds every sample of the window
    and at least one more beyond each end of the window (or the curve's own end). Then a sample of
    the window is a local maximum of the part exactly when it is one of the whole curve, and its
    prominence on the part is at most its prominence on the whole curve (the part ends the search
    for the lowest value sooner), so a maximum kept on the part is kept on the whole curve, and only
    a maximum dropped on the part for its prominence might be kept on the whole curve. The result is
    the same when no such maximum can win: each is lower than the highest maximum kept on the part.
    Runs of equal samples (plateaus) are not decided here.

    Returns
    -------
    bool
        False: run the whole curve before associating.
    """
    v, a = _check_curve(speeds_kmh, acc_m_s2)
    lo, hi = ref_speed_kmh - window_kmh[0], ref_speed_kmh + window_kmh[1]
    in_win = (v >= lo - 1e-9) & (v <= hi + 1e-9)
    if a.size and np.any(a[1:] == a[:-1]):
        return False
    every = local_maxima(a, 0.0)
    every = every[in_win[every]]
    kept = local_maxima(a, min_prominence_rel)
    kept = kept[in_win[kept]]
    dropped = np.setdiff1d(every, kept)
    if dropped.size == 0:
        return True
    return bool(kept.size) and bool(a[dropped].max() < a[kept].max())


def window_max(speeds_kmh, acc_m_s2, ref_speed_kmh, window_kmh=ASSOCIATION_WINDOW_KMH):
    """Largest value of a curve in the window around ``ref_speed_kmh`` (the re-located peak).

    Used at each trial damping of the calibration: a max over a fixed window is continuous in the
    damping, which a bracketing root finder needs. Returns ``(index, value)``.
    """
    v = np.asarray(speeds_kmh, dtype=float)
    a = np.asarray(acc_m_s2, dtype=float)
    lo, hi = ref_speed_kmh - window_kmh[0], ref_speed_kmh + window_kmh[1]
    w = np.flatnonzero((v >= lo - 1e-9) & (v <= hi + 1e-9))
    i = int(w[np.argmax(a[w])])
    return i, float(a[i])


# ---------------------------------------------------------------------- is the Δζ_VBI determined?
#: Statuses of a calibration whose Δζ_VBI is computed but not determined (Section 4, Step 2): the
#: value is still printed, marked "not determined", and the advice says what to change.
UNDETERMINED_STATUSES = {
    "range_end": "the MLM curve's largest value, or the DIM value associated with the MLM peak, lies at an "
                 "end of the speed range: the resonance lies at or beyond it",
    "not_associated": "the association window holds no DIM local maximum: the DIM value taken is the window's "
                      "largest, so it depends on where the window ends, not on a resonance",
}
#: Every status a calibration reports, in the order the rules apply (docs/cli.md lists them).
STATUSES = {
    "ok": "Δζ_VBI determined: interior MLM peak, its DIM peak a local maximum, peaks matched within 0.1 %",
    "no_mlm_peak": "the MLM curve has no interior local maximum",
    "no_dim_peak": "no DIM sample in the association window",
    "not_bracketed": "the MLM peak stays on one side of the DIM peak over the whole damping ladder",
    "no_match": "the root does not match the peaks within 0.1 %",
    "grid_too_coarse": "the speed grid misses the resonance (exact MLM envelope)",
    "no_resonance_in_range": "the speed range holds no resonance (exact MLM envelope)",
    **UNDETERMINED_STATUSES,
    "contact_lost": "a wheel's contact force turns tensile in the DIM run of the peak: the DIM's assumption "
                    "that the wheels never leave the rail is broken, so its peak is no reference",
}
#: Headroom (km/h) the advice adds beyond the end of the range where the resonance lies.
EXTEND_BY_KMH = 70.0
#: The paper's speed range (km/h) of the shipped study's records (Section 3.3).
STUDY_RANGE_KMH = (160.0, 350.0)


def _end_of(values):
    """``"top"``, ``"bottom"`` or ``None``: the end of a curve whose value is within
    :data:`RANGE_END_RTOL` of its largest (the top wins a tie: the resonance above the range is the
    one a calibration misses)."""
    a = np.asarray(values, dtype=float)
    if not a.size:
        return None
    floor = (1.0 - RANGE_END_RTOL) * a.max()
    return "top" if a[-1] >= floor else "bottom" if a[0] >= floor else None


def extend_advice(end, range_kmh):
    """One line: which way to extend the speed range (``end`` "top" or "bottom")."""
    lo, hi = float(range_kmh[0]), float(range_kmh[1])
    if end == "bottom":
        new = f"{max(lo - EXTEND_BY_KMH, 10.0):g}:{hi:g}:1"
        where = f"below {lo:g} km/h"
    else:
        new = f"{lo:g}:{hi + EXTEND_BY_KMH:g}:1"
        where = f"above {hi:g} km/h"
    return f"extend --speeds {where} (e.g. --speeds {new}; ROS parameter speeds_kmh) and calibrate again"


def determination(speeds_kmh, mlm_acc_m_s2, mlm_peak, dim_peak):
    """Whether a matched Δζ_VBI is determined (Section 4, Step 2): ``None`` or ``(status, message)``.

    Rules, first match wins (the status names: :data:`UNDETERMINED_STATUSES`):

    * ``range_end``: the MLM curve's largest value lies at an end of the speed range (within
      :data:`RANGE_END_RTOL`, ``mlm_peak.max_at_range_end``: the peak taken is a lesser interior
      maximum and the resonance lies at or beyond the end), or the DIM value associated with the MLM
      peak is the first or last speed of the range. Paper Section 4, Step 2: "maximum accelerations
      at 350 km/h were excluded from the further investigations".
    * ``not_associated``: the DIM value is not a local maximum (no DIM peak in the association
      window, so the window's edge picks the value). Step 2: "We considered only peaks that are also
      local maxima".

    Parameters
    ----------
    speeds_kmh, mlm_acc_m_s2 : ndarray (n_speeds,)
        The MLM speed range (km/h) and curve (m/s^2).
    mlm_peak, dim_peak : Peak
        Both found.
    """
    v = np.asarray(speeds_kmh, dtype=float)
    lo, hi = float(v[0]), float(v[-1])
    if mlm_peak.max_at_range_end:
        end = _end_of(mlm_acc_m_s2) or "top"
        at = hi if end == "top" else lo
        return ("range_end", f"the MLM curve's largest value lies at the {end} of the speed range ({at:g} km/h), "
                             f"above the peak taken at {mlm_peak.speed_kmh:g} km/h: the resonance lies at or beyond "
                             f"{at:g} km/h; Δζ_VBI not determined: {extend_advice(end, (lo, hi))}")
    if dim_peak.speed_kmh <= lo + 1e-9 or dim_peak.speed_kmh >= hi - 1e-9:
        end = "top" if dim_peak.speed_kmh >= hi - 1e-9 else "bottom"
        return ("range_end", f"the DIM value associated with the MLM peak ({mlm_peak.speed_kmh:g} km/h) lies at the "
                             f"{end} of the speed range ({dim_peak.speed_kmh:g} km/h): the DIM resonance lies at or "
                             f"beyond it; Δζ_VBI not determined: {extend_advice(end, (lo, hi))}")
    if not dim_peak.is_local_max:
        return ("not_associated", f"{dim_peak.reason} (MLM peak {mlm_peak.speed_kmh:g} km/h, DIM value at "
                                  f"{dim_peak.speed_kmh:g} km/h): no DIM peak to associate; Δζ_VBI not determined: "
                                  f"plot the curves (--plot) and, if a DIM peak lies beyond the range, "
                                  f"{extend_advice('top', (lo, hi))}")
    return None


def record_status(rec, range_kmh=STUDY_RANGE_KMH, mlm_max_at_range_end=None):
    """The status :func:`determination` gives a study's result line (no curves): its own status
    unless that is ``ok``, then ``range_end`` / ``not_associated`` / ``ok`` from its flags and peaks.

    ``mlm_max_at_range_end`` overrides the line's flag (the shipped lines carry the strict flag;
    ``results/study/fit/mlm_range_end_recheck.csv`` holds today's, :data:`RANGE_END_RTOL`).
    """
    status = rec.get("status")
    if status != "ok" or rec.get("delta_zeta_vbi_pct") is None:
        return status
    flag = rec.get("mlm_max_at_range_end") if mlm_max_at_range_end is None else mlm_max_at_range_end
    dim = rec.get("dim_peak") or {}
    v = dim.get("speed_kmh")
    if flag or (v is not None and (v <= range_kmh[0] + 1e-9 or v >= range_kmh[1] - 1e-9)):
        return "range_end"
    if rec.get("dim_is_local_max") is False:
        return "not_associated"
    return "ok"


def has_delta_zeta(status):
    """Whether a status carries a Δζ_VBI (``ok`` or one of :data:`UNDETERMINED_STATUSES`): the
    study's fit applies its own exclusion rules to these (``step2``, ``strict``), as before."""
    return status == "ok" or status in UNDETERMINED_STATUSES
