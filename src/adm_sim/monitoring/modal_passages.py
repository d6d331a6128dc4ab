"""Passages in a record: the static offset removed, peak and level, segmentation by the signal.

:func:`analyse_passage` makes one :class:`~adm_sim.monitoring.modal_records.Passage` from its
samples (the static offset of :func:`static_offset`, the dynamic peak, the level, the first mode of
:func:`adm_sim.monitoring.modal_fit.identify_first_mode`, the plausibility warnings of
:func:`sensor_warnings`); :func:`segment_signal` cuts a record without run records into passages by
the envelope rule of :mod:`adm_sim.monitoring.modal_id` ("Passages"), and :func:`analyse_record`
does both.
"""

from __future__ import annotations

import math

import numpy as np

from adm_sim import protocol as P
from adm_sim.limits import acc_limit_m_s2
from adm_sim.model.plausibility import ROWS
from adm_sim.monitoring.modal_fit import find_gaps, identify_first_mode, missing_on_grid, uniform_samples
from adm_sim.monitoring.modal_records import (BASELINE_AFTER, BASELINE_BEFORE, BASELINE_BOTH, BASELINE_DYNAMIC,
                                              BASELINE_RAW, BASELINE_TAIL, LEVEL_TRIAL, IdentifySettings, Passage,
                                              acc_level)

__all__ = ["G_M_S2", "OFFSET_NEAR_G_M_S2", "OFFSET_NEAR_ZERO_M_S2", "analyse_passage", "analyse_record",
           "segment_signal", "sensor_warnings", "signal_analyses", "static_offset"]

#: Plausibility of a sensor signal (project's choice): a static offset is expected near 0 (a
#: sensor that removes gravity: within 0.5 m/s²) or near g (one that measures it: within 1 m/s², a
#: tilt up to about 25 deg); a sensor in g shows 1 at rest, one in mm/s² about 9807.
G_M_S2 = 9.80665
OFFSET_NEAR_ZERO_M_S2 = 0.5
OFFSET_NEAR_G_M_S2 = 1.0



def static_offset(t_s, a_m_s2, before=None, after=None, settings=None):
    """The static part of a passage's signal (gravity, sensor bias, slow drift), to be removed.

    ``before`` and ``after`` are ``(t_s, a_m_s2)`` of the quiet signal on either side of the
    passage (finite samples; the last / first ``settings.baseline_s`` are used). With at least 16
    samples on both sides the offset is the straight line through ``(median t, median a)`` of each
    (a drifting sensor); with one side the median of that side; with neither the median of the
    passage's last ``baseline_s`` (the end of its free decay, which oscillates about the offset).

    Returns ``(offset_at(t) callable, drift in m/s³, baseline word)``.
    """
    s = settings or IdentifySettings()
    sides = []
    for side, last in ((before, True), (after, False)):
        if side is None:
            sides.append(None)
            continue
        ts, xs = (np.asarray(v, dtype=float) for v in side)
        ok = np.isfinite(xs)
        ts, xs = ts[ok], xs[ok]
        if ts.size:
            sel = ts >= ts.max() - s.baseline_s if last else ts <= ts.min() + s.baseline_s
            ts, xs = ts[sel], xs[sel]
        sides.append((float(np.median(ts)), float(np.median(xs))) if ts.size >= 16 else None)
    b, e = sides
    if b is not None and e is not None and e[0] > b[0]:
        slope = (e[1] - b[1]) / (e[0] - b[0])
        return (lambda t: b[1] + slope * (np.asarray(t, dtype=float) - b[0])), slope, BASELINE_BOTH
    if b is not None or e is not None:
        m = (b or e)[1]
        return (lambda t: np.full(np.shape(t), m)), 0.0, BASELINE_BEFORE if b is not None else BASELINE_AFTER
    t, a = np.asarray(t_s, dtype=float), np.asarray(a_m_s2, dtype=float)
    ok = np.isfinite(a)
    tail = ok & (t >= t[ok].max() - s.baseline_s) if ok.any() else ok
    m = float(np.median(a[tail])) if tail.any() else 0.0
    return (lambda t: np.full(np.shape(t), m)), 0.0, BASELINE_TAIL


def sensor_warnings(peak_m_s2, offset_m_s2, baseline, label="passage"):
    """Plausibility of a sensor's passage: a dynamic peak above the bound of
    :mod:`adm_sim.model.plausibility` (50 m/s²), a static offset near neither 0 nor g; each with
    the likely cause (units). Returns the warning texts."""
    out = []
    bound = ROWS["acceleration"].limits({})[1]
    if math.isfinite(peak_m_s2) and peak_m_s2 > bound:
        out.append(f"{label}: dynamic peak {peak_m_s2:.4g} m/s^2 above the {bound:g} m/s^2 no bridge deck reaches: "
                   f"are the samples in m/s^2 (mm/s^2 are 1000 times larger, cm/s^2 100 times)?")
    if baseline not in (BASELINE_RAW, BASELINE_DYNAMIC) and math.isfinite(offset_m_s2):
        off = abs(offset_m_s2)
        if off > OFFSET_NEAR_ZERO_M_S2 and abs(off - G_M_S2) > OFFSET_NEAR_G_M_S2:
            out.append(f"{label}: static offset {offset_m_s2:.4g} m/s^2 is near neither 0 (+-{OFFSET_NEAR_ZERO_M_S2:g}) "
                       f"nor g ({G_M_S2:g} +-{OFFSET_NEAR_G_M_S2:g} m/s^2; the project's bounds): are the samples in "
                       f"m/s^2 (a sensor in g shows 1 at rest, one in mm/s^2 about 9807)?")
    return tuple(out)


def analyse_passage(t_s, a_m_s2, *, index=1, limit_m_s2=None, track_type="ballasted", warn_fraction=0.8,
                    t_free_s=None, settings=None, source="signal", run_id=None, phase=None, info=None,
                    before=None, after=None, dynamic=False):
    """One :class:`Passage` from its samples: the static offset removed (:func:`static_offset`:
    from the quiet signal ``before`` / ``after`` it, none when ``dynamic`` (the bridge's own
    acceleration) or ``settings.raw``), the dynamic peak ``|a - offset|`` and its time, the level
    against the limit (``limit_m_s2``, else the one of ``track_type``; a numerical trial's phase:
    :data:`LEVEL_TRIAL`), the first mode of its free decay. Non-finite samples are excluded and
    counted (they are dropouts); a passage without enough finite samples gets no numbers."""
    s = settings or IdentifySettings()
    t = np.asarray(t_s, dtype=float)
    a = np.asarray(a_m_s2, dtype=float)
    limit = acc_limit_m_s2(track_type) if limit_m_s2 is None else float(limit_m_s2)
    trial = phase in P.TRIAL_PHASES
    fin = np.isfinite(a) & np.isfinite(t)
    n_bad = int(t.size - fin.sum())
    common = dict(index=index, limit_m_s2=limit, source=source, run_id=run_id, phase=phase, info=dict(info or {}),
                  n_nonfinite=n_bad)
    if not fin.any():
        nan = float("nan")
        tt = t[np.isfinite(t)]
        reason = "no samples" if t.size == 0 else f"all {t.size} samples are non-finite (NaN or inf)"
        return Passage(t_start_s=float(tt.min()) if tt.size else nan, t_end_s=float(tt.max()) if tt.size else nan,
                       peak_acc_m_s2=nan, t_peak_s=nan, level=LEVEL_TRIAL if trial else acc_level(nan, limit),
                       n_samples=int(t.size), fit=None, reason=reason,
                       warnings=(f"passage {index}: {reason}; passage refused",) if t.size else (), **common)
    tf, af = t[fin], a[fin]
    order = np.argsort(tf, kind="stable")
    tf, af = tf[order], af[order]
    if s.raw:
        off_fn, drift, baseline = (lambda x: np.zeros(np.shape(x))), 0.0, BASELINE_RAW
    elif dynamic:
        off_fn, drift, baseline = (lambda x: np.zeros(np.shape(x))), 0.0, BASELINE_DYNAMIC
    else:
        off_fn, drift, baseline = static_offset(tf, af, before, after, s)
    x = af - off_fn(tf)
    absx = np.abs(x)
    i = int(np.argmax(absx))
    peak = float(absx[i])
    offset = float(off_fn(tf[i]))
    stamps = np.unique(tf)
    gaps = find_gaps(stamps, float(np.median(np.diff(stamps)))) if stamps.size > 1 else ()
    fit, reason = identify_first_mode(tf, x, t_free_s, s)
    warns = list(sensor_warnings(peak, offset, baseline, f"passage {index}"))
    if n_bad:
        warns.append(f"passage {index}: {n_bad} non-finite samples (NaN or inf) excluded; they count as dropouts")
    return Passage(t_start_s=float(tf[0]), t_end_s=float(tf[-1]), peak_acc_m_s2=peak, t_peak_s=float(tf[i]),
                   level=LEVEL_TRIAL if trial else acc_level(peak, limit, warn_fraction), n_samples=int(t.size),
                   fit=fit, reason=reason, offset_m_s2=offset, offset_drift_m_s3=float(drift),
                   offset_baseline=baseline, raw_peak_acc_m_s2=float(np.max(np.abs(af))), gaps=gaps,
                   warnings=tuple(warns), **common)


def _moving_max(x, n):
    from scipy.ndimage import maximum_filter1d  # noqa: PLC0415  deferred: scipy.ndimage is a heavy import

    return maximum_filter1d(x, size=max(1, n), mode="nearest")


def _trend(t, a, block_s):
    """The slow part of a signal: medians of consecutive ``block_s`` blocks, linear between their
    centres (constant beyond the first and last); a passage's oscillation has its median near the
    offset, so gravity, bias and drift are followed and the vibration is not."""
    n = t.size
    dt = (t[-1] - t[0]) / max(n - 1, 1)
    nb = max(1, int(round(block_s / dt))) if dt > 0 else n
    if n < 2 * nb:
        return np.full(n, np.median(a))
    k = n // nb
    blocks = a[:k * nb].reshape(k, nb)
    tc = t[:k * nb].reshape(k, nb).mean(axis=1)
    return np.interp(t, tc, np.median(blocks, axis=1))


def segment_signal(t_s, a_m_s2, settings=None):
    """Passages in a record without run records: ``[(i_start, i_end), ...]`` (``i_end`` exclusive)
    into the sorted samples, by the envelope rule of the module docstring (of ``|a - trend|``,
    :func:`_trend`; non-finite samples are left out of the rule)."""
    s = settings or IdentifySettings()
    t_all = np.sort(np.asarray(t_s, dtype=float))
    a_in = np.asarray(a_m_s2, dtype=float)[np.argsort(np.asarray(t_s, dtype=float), kind="stable")]
    fin = np.isfinite(a_in)
    t, a, dt, _ = uniform_samples(t_all[fin], a_in[fin])
    if t.size < 4:
        return []
    x = np.abs(a - _trend(t, a, s.trend_s))
    n_win = max(2, int(round(s.window_s / dt)))
    env = _moving_max(x, n_win)
    n_blocks = max(1, x.size // n_win)
    blocks = x[:n_blocks * n_win].reshape(n_blocks, -1).max(axis=1)
    # the noise level from blocks of samples present: a dropout's interpolated line has no noise
    miss = missing_on_grid(t, find_gaps(np.unique(t_all[fin]), dt), dt)[:n_blocks * n_win]
    whole = ~miss.reshape(n_blocks, -1).any(axis=1)
    noise = float(np.percentile(blocks[whole] if whole.any() else blocks, 10))
    trigger = s.threshold_m_s2 if s.threshold_m_s2 is not None else min(s.trigger_snr * noise,
                                                                         s.trigger_fraction * float(x.max()))
    release = min(s.release_snr * noise, trigger)
    above = env > release
    edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(np.int8), [0]])))
    runs = [[int(b), int(e)] for b, e in zip(edges[::2], edges[1::2]) if x[b:e].max() > trigger]
    merged: list[list[int]] = []
    for b, e in runs:
        if merged and t[b] - t[merged[-1][1] - 1] < s.merge_gap_s:
            merged[-1][1] = e
        else:
            merged.append([b, e])
    # map back to the caller's samples (uniform_samples may have resampled)
    return [(int(np.searchsorted(t_all, t[b])), int(np.searchsorted(t_all, t[e - 1], side="right")))
            for b, e in merged]


def signal_analyses(t, a, segs, settings):
    """``(t, a, before, after)`` of each segment of sorted samples: the quiet samples on either side
    (up to the neighbouring passages) for the static offset."""
    out = []
    for k, (b, e) in enumerate(segs):
        lo = segs[k - 1][1] if k else 0
        hi = segs[k + 1][0] if k + 1 < len(segs) else t.size
        out.append((t[b:e], a[b:e], (t[lo:b], a[lo:b]), (t[e:hi], a[e:hi])))
    return out


def analyse_record(t_s, a_m_s2, *, limit_m_s2=None, track_type="ballasted", warn_fraction=0.8, settings=None):
    """Every passage of a record without run records (:func:`segment_signal`), as :class:`Passage`."""
    t = np.asarray(t_s, dtype=float)
    a = np.asarray(a_m_s2, dtype=float)
    order = np.argsort(t, kind="stable")
    t, a = t[order], a[order]
    return [analyse_passage(tp, ap, index=k + 1, limit_m_s2=limit_m_s2, track_type=track_type,
                            warn_fraction=warn_fraction, settings=settings, before=bf, after=af)
            for k, (tp, ap, bf, af) in enumerate(signal_analyses(t, a, segment_signal(t, a, settings), settings))]
