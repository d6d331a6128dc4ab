"""Peaks of a maximum-acceleration curve over speed: the one rule of the project.

Paper Section 4, step 2: "We considered only peaks that are also local maxima", so a **peak** is
an *interior local maximum* of the curve ``a(v)`` of maximum midspan accelerations:

* higher than its neighbours on both sides; a plateau of equal samples counts once, at its middle
  sample (the left one of two): the rule of :func:`scipy.signal.find_peaks`, written here in a few
  lines of Python (:func:`_local_maxima_1d`, :func:`_prominences`) that give the same indices and
  prominences bit for bit (``tests/integrate/test_core_peaks.py`` compares them), because importing
  ``scipy.signal`` costs about 1 s at the start of every command;
* never the first or the last speed of the range (its true maximum may lie outside the range);
* not a ripple: its prominence is at least ``min_prominence_rel`` times its value (default
  0.1 %, the calibration's acceptance of a peak match).

The **peak of a curve** is its highest interior local maximum (:func:`find_peak`). When the
curve's largest value lies at an end of the range (or an end value ties with it within 0.1 %,
:data:`RANGE_END_RTOL`) the peak is a lesser interior maximum, and ``max_at_range_end`` says so. ``adm-sim sweep`` (:meth:`adm_sim.integrate.sweep.SweepResult.peak`) and
``adm-calib calibrate`` (:mod:`adm_calib.peaks`) both use this module, so they name the same peak
of one curve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Default smallest prominence of a peak relative to its value (0.1 %).
MIN_PROMINENCE_REL = 1e-3
#: Relative tolerance of "largest value at an end of the speed range" (:func:`max_at_range_end`).
RANGE_END_RTOL = 1e-3


@dataclass(frozen=True)
class Peak:
    """A point of a maximum-acceleration curve.

    Attributes
    ----------
    found : bool
        False means "no reasonable peak"; the other fields are then NaN/-1.
    index : int
        Index into the curve's speed array.
    speed_kmh, acc_m_s2 : float
        Speed (km/h) and maximum midspan acceleration (m/s^2).
    is_local_max : bool
        Whether the point is an interior local maximum of its curve.
    max_at_range_end : bool
        Whether the curve's largest value lies at the first or last speed of the range.
    reason : str
        Why no peak was found, or how it was chosen.
    """

    found: bool
    index: int = -1
    speed_kmh: float = float("nan")
    acc_m_s2: float = float("nan")
    is_local_max: bool = False
    max_at_range_end: bool = False
    reason: str = ""

    def to_dict(self):
        if not self.found:
            return None
        return {"speed_kmh": float(self.speed_kmh), "acc_m_s2": float(self.acc_m_s2)}

    def __repr__(self):
        if not self.found:
            return f"Peak(not found: {self.reason})"
        return (f"Peak({self.speed_kmh:g} km/h, {self.acc_m_s2:.5g} m/s^2, local_max={self.is_local_max}, "
                f"max_at_range_end={self.max_at_range_end})")


def check_curve(speeds_kmh, acc_m_s2):
    """Speeds (increasing) and values as float arrays of one shape; ``ValueError`` otherwise."""
    v = np.asarray(speeds_kmh, dtype=float)
    a = np.asarray(acc_m_s2, dtype=float)
    if v.ndim != 1 or v.shape != a.shape:
        raise ValueError(f"speeds {v.shape} and accelerations {a.shape} must be 1-D of equal length")
    if v.size > 1 and np.any(np.diff(v) <= 0):
        raise ValueError("speeds must be strictly increasing")
    return v, a


def local_maxima(values, min_prominence_rel=MIN_PROMINENCE_REL):
    """Indices of the interior local maxima of a curve, shape (n_peaks,), in increasing order.

    End points are never maxima; plateaus count once (middle sample); a maximum whose prominence
    is below ``min_prominence_rel`` times its value is dropped (numerical ripple; pass 0 to keep
    every maximum).
    """
    a = np.asarray(values, dtype=float)
    if a.ndim != 1:
        raise ValueError(f"values {a.shape} must be 1-D")
    if a.size < 3:
        return np.zeros(0, dtype=int)
    idx = _local_maxima_1d(a)
    keep = _prominences(a, idx) >= min_prominence_rel * np.abs(a[idx])
    return idx[keep]


def _local_maxima_1d(a):
    """Indices of the interior local maxima of ``a`` (1-D float64), plateaus at their middle sample.

    The rule of scipy's ``_local_maxima_1d`` (``scipy/signal/_peak_finding_utils.pyx``), which
    :func:`scipy.signal.find_peaks` applies, on runs of equal samples: a run is a maximum when it
    is neither the first nor the last run, and the runs before and after it are lower; its peak is
    its middle sample ``(first + last) // 2``. NaN is a run of its own and every comparison with
    it is false, as in scipy's loop.
    """
    n = a.size
    if n < 3:
        return np.zeros(0, dtype=np.intp)
    start = np.flatnonzero(np.r_[True, a[1:] != a[:-1]])  # first sample of every run
    end = np.r_[start[1:] - 1, n - 1]
    v = a[start]
    inner = np.flatnonzero((v[1:-1] > v[:-2]) & (v[1:-1] > v[2:])) + 1
    return ((start[inner] + end[inner]) // 2).astype(np.intp)


def _prominences(a, peaks):
    """Topographic prominence of every peak, shape (n_peaks,): the peak's value minus the higher
    of the lowest values between it and the nearest sample on either side that is not lower or
    equal (higher, or NaN), or the end of the curve.

    The loop of scipy's ``_peak_prominences`` with no window: the same stopping rule, the same
    comparisons and the same subtraction.
    """
    x = a.tolist()
    n_x = len(x)
    out = np.empty(len(peaks))
    for n, p in enumerate(peaks.tolist()):
        top = left = right = x[p]
        i = p
        while i >= 0 and x[i] <= top:
            if x[i] < left:
                left = x[i]
            i -= 1
        i = p
        while i < n_x and x[i] <= top:
            if x[i] < right:
                right = x[i]
            i += 1
        out[n] = top - max(left, right)
    return out


def largest_interior_peak(values, min_prominence_rel=MIN_PROMINENCE_REL):
    """Index of the highest interior local maximum (:func:`local_maxima`), or ``None``."""
    a = np.asarray(values, dtype=float)
    idx = local_maxima(a, min_prominence_rel)
    return None if idx.size == 0 else int(idx[np.argmax(a[idx])])


def max_at_range_end(values, rtol=None):
    """Whether the largest value of the curve lies at an end of the speed range, ties included.

    True when the value at the first or the last sample is at least ``(1 - rtol)`` times the
    curve's largest value (accelerations are >= 0). Default ``rtol`` = :data:`RANGE_END_RTOL`
    (0.1 %), the calibration's matching tolerance (Section 4, Step 3) and the prominence an
    interior maximum needs to count as a peak: an interior maximum less than 0.1 % above an end
    value is not told apart from that end. Example (shipped study, ICE-2): on L12-f2-mu1 the largest
    value lies at 349 km/h, 0.002 % (8e-5 m/s^2) above the 350 km/h value: flagged (it was not with
    the strict definition); on L12-f2-mu4 the maximum at 347 km/h is 0.23 % above the 350 km/h
    value: not flagged. ``rtol=0`` is the strict definition (largest value exactly at an end).
    """
    a = np.asarray(values, dtype=float)
    floor = (1.0 - (RANGE_END_RTOL if rtol is None else rtol)) * a.max()
    return bool(a[0] >= floor or a[-1] >= floor)


def find_peak(speeds_kmh, acc_m_s2, min_prominence_rel=MIN_PROMINENCE_REL):
    """The highest interior local maximum of a curve (paper Section 4, step 2).

    Parameters
    ----------
    speeds_kmh, acc_m_s2 : array_like, shape (n_speeds,)
        Speeds (km/h, increasing) and maximum midspan accelerations (m/s^2).

    Returns
    -------
    Peak
        ``found=False`` with a reason when the curve has no interior local maximum.
    """
    v, a = check_curve(speeds_kmh, acc_m_s2)
    at_end = bool(a.size and max_at_range_end(a))
    i = largest_interior_peak(a, min_prominence_rel)
    if i is None:
        where = "at an end of the speed range" if at_end else "nowhere"
        return Peak(found=False, max_at_range_end=at_end,
                    reason=f"no reasonable peak: no interior local maximum (largest value {where})")
    reason = ("highest interior local maximum; the curve's largest value lies at an end of the speed range"
              if at_end else "highest interior local maximum (also the largest value)")
    return Peak(found=True, index=i, speed_kmh=float(v[i]), acc_m_s2=float(a[i]), is_local_max=True,
                max_at_range_end=at_end, reason=reason)
