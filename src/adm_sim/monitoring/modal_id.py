"""Passages of trains in a midspan acceleration record: peak, EN 1990 level, first mode from the free decay.

A monitoring record (``/adm/midspan/accel``, a real accelerometer's ``AccelStamped`` or ``Imu``
topic, an MCAP of either, a data logger's CSV) is cut into *passages*; for each one this module reports the peak ``|a|`` and its
time, its level against the deck acceleration limit of EN 1990 A2.4.4.2.1(4)P (3.5 m/s² ballasted,
5 m/s² direct fastening, :mod:`adm_sim.limits`) and the first bending mode's natural frequency
``f1`` and damping ratio ``ζ1`` identified from the free vibration after the train has left.
Numpy and scipy only (no ROS); the monitor node and ``launch_scripts/monitor.py`` feed it.

Passages
--------
*From run records* (:class:`PassageTracker` with ``/adm/run/status``): one passage per run, the
samples whose stamp lies in ``[t0_s, t1_s)`` of the bridge's ``started`` / ``done`` records (each
end :data:`STAMP_TOLERANCE_S` early: a first sample stamped ``t0_s`` rounded to the ns is the run's),
assigned by stamp, not by arrival (a ``done`` may arrive before the last samples). The train has
left at ``t0_s + (train length + deck length) / v`` (the latched descriptions; the deck length is
``span_m`` of one span, the sum of ``spans_m`` of a continuous deck: the last axle leaves after the
last span); the free decay is taken
from ``settle_periods`` (3) periods after that. Stamps are in the monitored lane's time (a
``started`` record naming its ``time_lane``), or rescaled to it from the clock lane's.

*From the signal* (:func:`segment_signal`, no run records): ``e(t)`` is the moving maximum of
``|a - median(a)|`` over ``window_s``; the noise level ``σ_n`` the 10th percentile of the maxima of
``|a - median(a)|`` in consecutive ``window_s`` windows (the envelope of the quiet signal). A
passage is a stretch where ``e`` exceeds the release level ``release_snr σ_n`` that contains a sample above the trigger ``min(trigger_snr σ_n,
trigger_fraction max|a|)`` (or ``threshold_m_s2`` when given); stretches closer than
``merge_gap_s`` are one passage. The free decay starts at the first half-cycle peak after the
largest one from which the logarithms of the half-cycle peak amplitudes lie on a straight line
(weighted RMS scatter at most ``max_log_scatter``, weights the squared amplitudes, plus three times
the scatter the noise gives unfiltered; peaks below 5 % of the largest or 3 noise levels left
out), plus ``settle_periods`` when band-passed.

First mode (:func:`identify_first_mode`)
----------------------------------------
1. Frequency start value: the peak of the Hann-windowed, zero-padded FFT of the free decay in
   ``f_range_hz`` (parabolic interpolation on the log magnitude).
2. Optional band-pass (default on): zero-phase 2nd-order Butterworth (``sosfiltfilt``) over
   ``[f/2, 2 f]`` (``band_ratio``), applied to the whole passage so the decay window does not start
   at a filter edge; one period at the end of the window is dropped, ``settle_periods`` at its
   start (the filter's response to what came before). A decaying sinusoid ``e^{st}`` is an
   eigenfunction of a linear filter, so the filter changes amplitude and phase but neither the
   frequency nor the decay rate; higher modes (a simply supported beam's third mode is at 9 f1)
   no longer bias the fit.
3. Decay-rate start value: the logarithmic decrement, the slope of ``ln`` of the half-cycle peak
   amplitudes against time.
4. Fit, :func:`scipy.optimize.least_squares`, of ``a(t) = e^{-σ t} (B1 cos ω_d t + B2 sin ω_d t) + c``
   (``t`` from the window start) to the free-decay samples; then ``ω1 = sqrt(ω_d² + σ²)``,
   ``f1 = ω1 / 2π`` (the undamped natural frequency, as n0) and ``ζ1 = σ / ω1``. The window ends
   where the fitted envelope falls below ``end_snr`` times the residual RMS (one refit).
5. Standard uncertainties: the covariance ``s² (JᵀJ)⁻¹`` of the fit's Jacobian ``J`` at the
   solution, with ``s²`` the residuals' one-sided power spectral density at ``f_d`` (Welch) times
   ``f_s / 2`` instead of their plain variance: for white noise the two agree; for coloured
   residuals (band-passed noise, unmodelled modes) it counts the noise where the mode is, not the
   noise the filter removed. ``u(f1)`` and ``u(ζ1)`` follow from ``u(σ)``, ``u(ω_d)`` and their
   covariance by first-order propagation. Valid for one dominant mode in the band; two close modes
   beat and are refused by the scatter rule.

Real sensors (:func:`analyse_passage`)
--------------------------------------
* Static offset: the peak and the level are those of the dynamic signal ``a - offset(t)``; the
  offset (gravity, bias, drift) comes from the quiet signal before and after a passage found in
  the signal (:func:`static_offset`: the line through the two medians, one median, or the median
  of the passage's tail), none for the bridge's own topic (run records: the dynamic acceleration)
  or with ``raw``. Segmentation works on ``|a - trend|`` (:func:`_trend`).
* Dropouts: a stamp interval above 1.5 sample intervals (:func:`find_gaps`); non-finite samples
  are excluded, counted and count as dropouts. The fit of step 4 uses the samples present only;
  for the band-pass each dropout is filled with the first mode fitted to the samples within one
  period on either side (:func:`_fill_gaps`), then refilled with the fitted mode and fitted again.
  A dropout longer than ``max_gap_periods`` inside the fit window refuses the passage.
* Plausibility (:func:`sensor_warnings`): a dynamic peak above 50 m/s² or a static offset near
  neither 0 nor g is warned with its likely cause (units).
* A run of a numerical trial (:data:`adm_sim.protocol.TRIAL_PHASES`) has the level
  :data:`LEVEL_TRIAL`, never compared with the limit.

A passage whose free decay is too short (fewer than ``min_cycles`` periods), has a dropout longer
than ``max_gap_periods`` periods inside the fit window, too noisy (amplitude at its start below
``min_snr`` times the residual RMS), not exponential, or whose ζ1 is not positive or more
uncertain than ``max_rel_std`` gets no numbers: ``identified`` false and a one-line ``reason``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from adm_sim import protocol as P
from adm_sim.limits import acc_limit_m_s2

__all__ = ["IdentifySettings", "ModalFit", "Passage", "PassageTracker", "acc_level", "analyse_passage",
           "analyse_record", "find_gaps", "identify_first_mode", "run_topics_for", "segment_signal", "sensor_warnings",
           "static_offset", "uniform_samples"]

#: Level words of a peak against the limit: within (<= warn fraction), near (<= limit), above.
LEVELS = ("within", "near", "above")
#: Level word of a numerical trial's run (phases :data:`adm_sim.protocol.TRIAL_PHASES`): never compared
#: with the limit.
LEVEL_TRIAL = "trial"
#: A stamp this close below a run's ``t0_s`` belongs to that run (a stamp is ``t0`` rounded to the ns).
STAMP_TOLERANCE_S = 1e-9
#: How the free decay was fitted: no dropout in its window, or across dropouts.
FIT_GAP_FREE = "gap-free"
FIT_PRESENT = "least squares on the samples present"
#: Plausibility of a sensor signal (project's choice): a static offset is expected near 0 (a
#: sensor that removes gravity: within 0.5 m/s²) or near g (one that measures it: within 1 m/s², a
#: tilt up to about 25 deg); a sensor in g shows 1 at rest, one in mm/s² about 9807.
G_M_S2 = 9.80665
OFFSET_NEAR_ZERO_M_S2 = 0.5
OFFSET_NEAR_G_M_S2 = 1.0


@dataclass(frozen=True)
class IdentifySettings:
    """Rules of segmentation and identification (see the module docstring).

    Attributes
    ----------
    min_cycles : float
        Periods of free decay needed to identify damping.
    min_snr : float
        Amplitude at the start of the free decay over the residual RMS.
    max_rel_std : float
        Largest relative standard uncertainty of ζ1 that is still reported.
    max_log_scatter : float
        Weighted RMS scatter of ``ln`` of the half-cycle peak amplitudes about their line, on the
        free decay.
    end_snr : float
        The fit window ends where the fitted envelope falls below this times the residual RMS.
    bandpass : bool
        Band-pass around the FFT peak before fitting.
    band_ratio : float
        The band is ``[f / band_ratio, f band_ratio]``.
    f_range_hz : (float, float)
        Where the first mode is looked for.
    min_samples_per_period : float
        Coarser sampling is refused.
    window_s, trigger_snr, trigger_fraction, release_snr, merge_gap_s, threshold_m_s2
        Segmentation from the signal (:func:`segment_signal`).
    settle_periods : float
        Periods skipped after the start of the free decay (run records: after the train has
        left; the signal: after the log-linear start) when band-passing: the filter's response to
        what came before has decayed to below 1e-3 by then (a start 2.5 periods after an edge
        biases ζ1 by +0.2 %, 4 periods by less than 0.01 %, noise-free).
    baseline_s : float
        The static offset is the median of the quiet samples this long before (and after) a passage
        found in the signal (:func:`static_offset`).
    raw : bool
        Keep the raw signal: no static offset removed (the peak then includes gravity and bias).
    max_gap_periods : float
        Longest dropout inside the free decay that the fit bridges, in periods of the first mode.
    trend_s : float
        Segmentation: the signal's slow trend (gravity, bias, drift) is the median of consecutive
        blocks of this length, interpolated between their centres.
    """

    min_cycles: float = 5.0
    min_snr: float = 10.0
    max_rel_std: float = 0.25
    max_log_scatter: float = 0.03
    end_snr: float = 3.0
    bandpass: bool = True
    band_ratio: float = 2.0
    f_range_hz: tuple = (0.5, 100.0)
    min_samples_per_period: float = 8.0
    window_s: float = 0.5
    trigger_snr: float = 10.0
    trigger_fraction: float = 0.5
    release_snr: float = 2.0
    merge_gap_s: float = 2.0
    threshold_m_s2: float | None = None
    settle_periods: float = 3.0
    baseline_s: float = 2.0
    raw: bool = False
    max_gap_periods: float = 1.0
    trend_s: float = 10.0


@dataclass(frozen=True)
class ModalFit:
    """The first mode identified from a free decay.

    ``f1_hz`` the undamped natural frequency, ``zeta1`` the damping ratio (fraction), their
    standard uncertainties, ``fd_hz`` the damped frequency, ``t_start_s``/``t_end_s`` the fitted
    window, ``n_cycles`` its length in periods, ``snr`` the amplitude at its start over the residual
    RMS, ``amplitude_m_s2`` that amplitude, ``n_samples`` the samples fitted, ``filtered`` whether
    they were band-passed, ``log_scatter`` the scatter of the log cycle amplitudes, ``gaps`` the
    dropouts inside the window (``(t_s, duration_s, samples_missing)``) and ``method`` how they
    were bridged (:data:`FIT_GAP_FREE` or :data:`FIT_PRESENT`).
    """

    f1_hz: float
    zeta1: float
    f1_std_hz: float
    zeta1_std: float
    fd_hz: float
    t_start_s: float
    t_end_s: float
    n_cycles: float
    snr: float
    amplitude_m_s2: float
    n_samples: int
    filtered: bool
    log_scatter: float
    gaps: tuple = ()
    method: str = "gap-free"

    @property
    def zeta1_pct(self):
        return 100.0 * self.zeta1

    @property
    def zeta1_std_pct(self):
        return 100.0 * self.zeta1_std

    def __repr__(self):
        return (f"ModalFit(f1={self.f1_hz:.4f} ± {self.f1_std_hz:.4f} Hz, zeta1={self.zeta1_pct:.3f} ± "
                f"{self.zeta1_std_pct:.3f} %, {self.n_cycles:.1f} cycles from {self.t_start_s:.3f} s, "
                f"SNR {self.snr:.3g})")


@dataclass(frozen=True)
class Passage:
    """One passage: its peak, level and (when identified) first mode; see :meth:`to_dict`."""

    index: int
    t_start_s: float
    t_end_s: float
    peak_acc_m_s2: float
    t_peak_s: float
    limit_m_s2: float
    level: str
    n_samples: int
    fit: ModalFit | None
    reason: str | None
    source: str = "signal"
    run_id: int | None = None
    phase: str | None = None
    info: dict = field(default_factory=dict)
    offset_m_s2: float = 0.0
    offset_drift_m_s3: float = 0.0
    offset_baseline: str = "none"
    raw_peak_acc_m_s2: float | None = None
    n_nonfinite: int = 0
    gaps: tuple = ()
    warnings: tuple = ()

    @property
    def identified(self):
        return self.fit is not None

    def to_dict(self):
        """The JSON record of ``monitor.py --json`` (numbers of the fit are null when not identified)."""
        f = self.fit
        d = {"index": self.index, "run_id": self.run_id, "phase": self.phase, "source": self.source,
             "t_start_s": self.t_start_s, "t_end_s": self.t_end_s, "n_samples": self.n_samples,
             "peak_acc_m_s2": self.peak_acc_m_s2, "t_peak_s": self.t_peak_s, "limit_m_s2": self.limit_m_s2,
             "level": self.level, "identified": f is not None, "reason": self.reason,
             "f1_hz": None if f is None else f.f1_hz, "zeta1_pct": None if f is None else f.zeta1_pct,
             "f1_std_hz": None if f is None else f.f1_std_hz,
             "zeta1_std_pct": None if f is None else f.zeta1_std_pct,
             "signal": "raw" if self.offset_baseline == BASELINE_RAW else "dynamic",
             "offset_m_s2": self.offset_m_s2, "offset_drift_m_s3": self.offset_drift_m_s3,
             "offset_baseline": self.offset_baseline, "raw_peak_acc_m_s2": self.raw_peak_acc_m_s2,
             "nonfinite_samples": self.n_nonfinite,
             "nonfinite_handling": ("excluded (dropouts)" if self.n_nonfinite and self.n_samples > self.n_nonfinite
                                    else "passage refused" if self.n_nonfinite else None),
             "gaps": [_gap_dict(g) for g in self.gaps], "warnings": list(self.warnings),
             "free_decay": None if f is None else {
                 "t_start_s": f.t_start_s, "t_end_s": f.t_end_s, "n_cycles": f.n_cycles, "snr": f.snr,
                 "fd_hz": f.fd_hz, "n_samples": f.n_samples, "bandpass": f.filtered, "log_scatter": f.log_scatter,
                 "method": f.method, "gaps": [_gap_dict(g) for g in f.gaps]}}
        d.update(self.info)
        return d

    def line(self):
        """One log line: peak, level, and f1, ζ1 with their standard uncertainties or the reason."""
        head = f"passage {self.index}" + ("" if self.run_id is None else f" (run {self.run_id}"
                                          + ("" if self.phase is None else f", {self.phase}") + ")")
        lost = self.info.get("samples_lost")
        if self.level == LEVEL_TRIAL:
            level = "a numerical trial, not compared with the limit"
        else:
            level = f"{self.level} the {self.limit_m_s2:g} m/s^2 limit (EN 1990 A2.4.4.2.1)"
        kind = "raw" if self.offset_baseline == BASELINE_RAW else "dynamic"
        offset = (f" (static offset {self.offset_m_s2:.4g} m/s^2 removed, {self.offset_baseline})"
                  if kind == "dynamic" and self.offset_m_s2 != 0.0 else "")
        text = (f"{head}: {kind} peak |a| {self.peak_acc_m_s2:.4f} m/s^2 at t={self.t_peak_s:.3f} s{offset}, {level}"
                + (f", {lost} of {self.info['samples_published']} samples lost" if lost else "")
                + (f", {self.n_nonfinite} non-finite samples excluded" if self.n_nonfinite else "")
                + (f", {len(self.gaps)} dropout(s)" if self.gaps else ""))
        f = self.fit
        if f is None:
            return f"{text}; first mode not identified: {self.reason}"
        how = "" if f.method == FIT_GAP_FREE else f" ({f.method}, across {len(f.gaps)} dropout(s))"
        return (f"{text}; f1 {f.f1_hz:.4f} Hz (u {f.f1_std_hz:.2g} Hz), zeta1 {f.zeta1_pct:.3f} % "
                f"(u {f.zeta1_std_pct:.2g} %), {f.n_cycles:.1f} cycles of free decay{how}")


#: ``offset_baseline`` words: where the static offset removed was taken from.
BASELINE_RAW = "none (raw signal kept)"
BASELINE_DYNAMIC = "none (the bridge publishes the dynamic acceleration)"
BASELINE_BEFORE = "median of the quiet signal before the passage"
BASELINE_BOTH = "medians of the quiet signal before and after the passage, a straight line between them"
BASELINE_AFTER = "median of the quiet signal after the passage"
BASELINE_TAIL = "median of the passage's last samples (no quiet signal before or after it)"


def _gap_dict(g):
    return {"t_s": g[0], "duration_s": g[1], "samples_missing": g[2]}


class IdentificationError(Exception):
    """Why a free decay gives no first mode (the passage's ``reason``); internal to this module."""


# ---------------------------------------------------------------------- samples
def acc_level(peak_m_s2, limit_m_s2, warn_fraction=0.8):
    """``within`` (<= ``warn_fraction`` of the limit), ``near`` (<= limit) or ``above`` the limit
    (EN 1990 A2.4.4.2.1(4)P); a non-finite peak is ``above``."""
    if not math.isfinite(peak_m_s2) or peak_m_s2 > limit_m_s2:
        return LEVELS[2]
    return LEVELS[1] if peak_m_s2 > warn_fraction * limit_m_s2 else LEVELS[0]


def uniform_samples(t_s, a_m_s2):
    """Samples sorted by time, duplicates of a stamp dropped, on a uniform grid.

    Stamped samples whose intervals scatter by less than 1 % of the median interval are taken as
    uniform (``t`` is replaced by the ideal grid); otherwise they are interpolated linearly onto a
    grid at the median interval. Returns ``(t, a, dt, max_gap)``, ``max_gap`` the largest interval
    in units of ``dt`` (a lost stretch of samples shows as a gap > 1.5).
    """
    t = np.asarray(t_s, dtype=float)
    a = np.asarray(a_m_s2, dtype=float)
    if t.shape != a.shape or t.ndim != 1:
        raise ValueError(f"t_s and a_m_s2 must be 1-D of one length, got {t.shape} and {a.shape}")
    order = np.argsort(t, kind="stable")
    t, a = t[order], a[order]
    keep = np.concatenate([[True], np.diff(t) > 0]) if t.size else np.zeros(0, bool)
    t, a = t[keep], a[keep]
    if t.size < 2:
        return t, a, float("nan"), 1.0
    d = np.diff(t)
    dt = float(np.median(d))
    max_gap = float(d.max() / dt)
    if np.max(np.abs(d - dt)) <= 0.01 * dt:
        return t[0] + dt * np.arange(t.size), a, dt, max_gap
    if (t[-1] - t[0]) / dt > 4 * t.size:  # mostly gaps: not resampled (refused by the identification)
        return t, a, dt, max_gap
    grid = t[0] + dt * np.arange(int(math.floor((t[-1] - t[0]) / dt)) + 1)
    return grid, np.interp(grid, t, a), dt, max_gap


def _spectral_peak_hz(x, dt, f_lo, f_hi):
    """Frequency of the largest peak of the Hann-windowed, 8x zero-padded spectrum in [f_lo, f_hi]."""
    n = x.size
    nfft = 1 << int(math.ceil(math.log2(8 * n)))
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(n), nfft))
    f = np.fft.rfftfreq(nfft, dt)
    band = np.flatnonzero((f >= f_lo) & (f <= f_hi))
    if band.size < 3:
        raise IdentificationError(f"no frequency in [{f_lo:g}, {f_hi:g}] Hz is resolved by {n} samples at "
                                  f"{1 / dt:g} Hz")
    i = band[np.argmax(spec[band])]
    if 0 < i < spec.size - 1 and spec[i - 1] > 0 and spec[i + 1] > 0 and spec[i] > 0:
        y0, y1, y2 = np.log(spec[i - 1:i + 2])
        den = y0 - 2 * y1 + y2
        shift = 0.5 * (y0 - y2) / den if den < 0 else 0.0
        return float(f[i] + shift * (f[1] - f[0]))
    return float(f[i])


def _bandpass(x, dt, f_hz, ratio):
    from scipy.signal import butter, sosfiltfilt  # noqa: PLC0415  deferred: scipy.signal costs ~1.5 s to import

    nyq = 0.5 / dt
    lo, hi = f_hz / ratio, min(f_hz * ratio, 0.9 * nyq)
    sos = butter(2, [lo / nyq, hi / nyq], btype="bandpass", output="sos")
    return sosfiltfilt(sos, x, padlen=min(x.size - 1, 3 * int(round(1.0 / (f_hz * dt)))))


def _half_cycle_peaks(x, dt, f_hz):
    """Indices of the extrema of ``x`` (maxima and minima, about one per half period)."""
    from scipy.signal import find_peaks  # noqa: PLC0415  deferred: scipy.signal costs ~1.5 s to import

    dist = max(1, int(0.7 / (f_hz * dt)))  # one maximum and one minimum per period
    up, _ = find_peaks(x, distance=dist)
    down, _ = find_peaks(-x, distance=dist)
    return np.sort(np.concatenate([up, down]))


def _line(tp, y, w):
    """Weighted straight line through ``(tp, y)``: ``(slope, intercept, weighted RMS scatter)``."""
    W = w.sum()
    tm, ym = (w * tp).sum() / W, (w * y).sum() / W
    stt = (w * (tp - tm) ** 2).sum()
    slope = (w * (tp - tm) * (y - ym)).sum() / stt if stt > 0 else 0.0
    res = y - (ym + slope * (tp - tm))
    return slope, ym - slope * tm, float(np.sqrt((w * res ** 2).sum() / W))


def _decay_start(tp, ap, min_peaks, max_scatter, noise):
    """Index into the half-cycle peaks where the exponential free decay starts: the first one
    after the largest from which ``ln ap`` lies on a line (weighted scatter <= ``max_scatter``
    plus three times what the noise ``noise`` (m/s²) alone gives, ``noise / rms(ap)``).
    Returns ``(index, scatter)``; the index is None when no such start leaves ``min_peaks``."""
    y = np.log(ap)
    w = ap ** 2
    i_max = int(np.argmax(ap))
    best = (None, float("inf"))
    for i0 in range(i_max, tp.size - min_peaks + 1):
        slope, _, scatter = _line(tp[i0:], y[i0:], w[i0:])
        if slope < 0 and scatter <= max_scatter + 3.0 * noise / math.sqrt(np.mean(w[i0:])):
            return i0, scatter
        if scatter < best[1]:
            best = (None, scatter)
    return best


# ---------------------------------------------------------------------- the fit
def _model(p, t):
    sigma, wd, b1, b2, c = p
    e = np.exp(-sigma * t)
    return e * (b1 * np.cos(wd * t) + b2 * np.sin(wd * t)) + c


def _jac(p, t):
    sigma, wd, b1, b2, _ = p
    e = np.exp(-sigma * t)
    cw, sw = np.cos(wd * t), np.sin(wd * t)
    osc = b1 * cw + b2 * sw
    return np.column_stack([-t * e * osc, e * t * (-b1 * sw + b2 * cw), e * cw, e * sw, np.ones_like(t)])


def _fit(t, x, f0_hz, sigma0):
    """Least-squares fit of the decaying sinusoid; returns ``(params, jacobian, residuals)``."""
    from scipy.optimize import least_squares  # noqa: PLC0415  deferred: scipy.optimize costs ~1 s to import

    wd0 = 2 * math.pi * f0_hz
    E = np.exp(-sigma0 * t)
    A = np.column_stack([E * np.cos(wd0 * t), E * np.sin(wd0 * t), np.ones_like(t)])
    b1, b2, c = np.linalg.lstsq(A, x, rcond=None)[0]
    p0 = np.array([sigma0, wd0, b1, b2, c])
    res = least_squares(lambda p: _model(p, t) - x, p0, jac=lambda p: _jac(p, t), method="lm",
                        x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000)
    if not res.success:
        raise IdentificationError(f"the decaying-sinusoid fit did not converge ({res.message})")
    return res.x, res.jac, res.fun


def _noise_variance(r, dt, fd_hz):
    """``S_r(f_d) f_s / 2``: the residuals' variance as seen at the mode's frequency (Welch PSD,
    one-sided, averaged over ``f_d`` ± 20 %); the plain variance when too few samples."""
    from scipy.signal import welch  # noqa: PLC0415  deferred: scipy.signal costs ~1.5 s to import

    n = r.size
    nper = max(16, min(n, int(round(8.0 / (fd_hz * dt)))))  # about 8 periods per segment
    if n < 2 * nper:
        return float(np.mean(r ** 2))
    f, S = welch(r, fs=1.0 / dt, nperseg=nper, detrend="constant")
    band = (f >= fd_hz / 1.2) & (f <= fd_hz * 1.2)
    if not band.any():
        band = np.zeros_like(f, dtype=bool)
        band[np.argmin(np.abs(f - fd_hz))] = True
    return float(S[band].mean() * 0.5 / dt)


def identify_first_mode(t_s, a_m_s2, t_free_s=None, settings=None):
    """First mode (f1, ζ1 and their standard uncertainties) from the free decay in a record.

    Parameters
    ----------
    t_s, a_m_s2 : array_like (n,)
        Sample times (s; stamps need not be uniform, see :func:`uniform_samples`) and midspan
        acceleration (m/s², either sign convention) of one passage and the free vibration after it.
    t_free_s : float or None
        When known (run records): the time from which the bridge vibrates freely. None: found from
        the signal (the log-linear rule of the module docstring).
    settings : IdentifySettings or None

    Returns
    -------
    (ModalFit or None, str or None)
        The fit, or None and the one-line reason.
    """
    s = settings or IdentifySettings()
    try:
        return _identify(t_s, a_m_s2, t_free_s, s), None
    except IdentificationError as exc:
        return None, str(exc)


def find_gaps(stamps_s, dt_s):
    """Dropouts in sorted stamps: every interval above 1.5 sample intervals, as
    ``(t_s, duration_s, samples_missing)`` (``t_s`` the last stamp before it)."""
    d = np.diff(stamps_s)
    return tuple((float(stamps_s[i]), float(d[i]), max(int(round(d[i] / dt_s)) - 1, 1))
                 for i in np.flatnonzero(d > 1.5 * dt_s))


def _missing_on_grid(t, gaps, dt):
    miss = np.zeros(t.size, bool)
    for t_a, dur, _ in gaps:
        miss |= (t > t_a + 0.5 * dt) & (t < t_a + dur - 0.5 * dt)
    return miss


def _fill_gaps(t, x, miss, gaps, f_hz, sigma):
    """``x`` with its dropouts filled by the first mode fitted to the samples present within one
    period on either side (linear least squares for its two amplitudes and an offset at the damped
    frequency ``f_hz`` and decay rate ``sigma``), so that the band-pass filter does not ring on the
    straight line that linear interpolation draws across a gap. The filled points never enter the
    fit (:func:`_identify` fits the samples present)."""
    x = x.copy()
    w, period = 2 * math.pi * f_hz, 1.0 / f_hz
    for t_a, dur, _ in gaps:
        inside = miss & (t > t_a) & (t < t_a + dur)
        near = ~miss & (t >= t_a - period) & (t <= t_a + dur + period)
        if not inside.any() or near.sum() < 4:
            continue
        tc = t_a + 0.5 * dur
        tt, ti = t[near] - tc, t[inside] - tc
        E = np.exp(-sigma * tt)
        A = np.column_stack([E * np.cos(w * tt), E * np.sin(w * tt), np.ones_like(tt)])
        b1, b2, c = np.linalg.lstsq(A, x[near], rcond=None)[0]
        x[inside] = np.exp(-sigma * ti) * (b1 * np.cos(w * ti) + b2 * np.sin(w * ti)) + c
    return x


@dataclass
class _Record:
    """A passage's record on its uniform grid (internal to :func:`_identify`): times ``t`` (s),
    acceleration ``a`` (m/s²), step ``dt`` (s), the grid points missing (``miss``), the dropouts
    (``gaps``: :func:`find_gaps`) and the band ``[f_lo, f_hi]`` (Hz) a mode is looked for in."""

    t: np.ndarray
    a: np.ndarray
    dt: float
    miss: np.ndarray
    gaps: list
    f_lo: float
    f_hi: float


def _record(t_s, a_m_s2, s):
    """The finite samples of a passage on their uniform grid, refused when too few, mostly gaps or
    too coarse for ``s.min_samples_per_period`` samples per period of any mode of ``s.f_range_hz``."""
    t_in = np.asarray(t_s, dtype=float)
    a_in = np.asarray(a_m_s2, dtype=float)
    ok = np.isfinite(a_in) & np.isfinite(t_in)
    if not ok.all():  # non-finite samples are dropouts (counted by analyse_passage)
        t_in, a_in = t_in[ok], a_in[ok]
    stamps = np.unique(t_in)
    t, a, dt, _ = uniform_samples(t_in, a_in)
    if t.size >= 2 and (t[-1] - t[0]) / dt > 4 * t.size:
        raise IdentificationError(f"{t.size} samples spread over {(t[-1] - t[0]) / dt:.0f} sample intervals: "
                                  f"the record is mostly gaps")
    if t.size < 32:
        raise IdentificationError(f"{t.size} finite samples: too few to identify the first mode")
    gaps_all = find_gaps(stamps, dt)
    miss = _missing_on_grid(t, gaps_all, dt)
    f_lo, f_hi = s.f_range_hz
    f_hi = min(f_hi, 1.0 / (dt * s.min_samples_per_period))  # at least min_samples_per_period per period
    if f_hi <= f_lo:
        raise IdentificationError(f"sampling at {1 / dt:.4g} Hz gives fewer than {s.min_samples_per_period:g} "
                                  f"samples per period of any mode above {f_lo:g} Hz")
    return _Record(t, a, dt, miss, gaps_all, f_lo, f_hi)


def _free_vibration(rec, t_free_s):
    """Step 1, where the free vibration is (run records, else after the largest excursion): the
    index it starts at, its spectral peak ``f0`` (Hz) and the zero-mean record with its dropouts
    filled at ``f0``."""
    t, miss = rec.t, rec.miss
    x = rec.a - np.median(rec.a)
    i_peak = int(np.argmax(np.abs(np.where(miss, 0.0, x))))
    i_from = i_peak if t_free_s is None else int(np.searchsorted(t, t_free_s))
    if i_from >= t.size - 16:
        raise IdentificationError("no free vibration recorded after the train left (the record ends "
                                  f"{(t[-1] - t[min(i_from, t.size - 1)]):.3g} s after it)")
    f0 = _spectral_peak_hz(x[i_from:], rec.dt, rec.f_lo, rec.f_hi)
    if rec.gaps:
        x = _fill_gaps(t, x, miss, rec.gaps, f0, 0.0)
    return i_from, f0, x


def _decay_peaks(rec, xf, *, i_from, i_end, f0, t_free_s, s):
    """Step 3a, the half-cycle peaks of the free decay (indices into the grid; enough of them, over
    ``s.min_cycles`` periods, or :class:`IdentificationError`) and the fewest the start rule needs."""
    t = rec.t
    if t_free_s is not None:
        i_from = int(np.searchsorted(t, t_free_s + s.settle_periods / f0))
    pk = _half_cycle_peaks(xf[:i_end], rec.dt, f0)
    pk = pk[(pk >= i_from) & ~rec.miss[pk]]
    min_peaks = max(4, int(math.ceil(2 * s.min_cycles)))
    n_avail = (t[i_end - 1] - t[min(i_from, i_end - 1)]) * f0
    if pk.size < min_peaks or n_avail < s.min_cycles:
        if t_free_s is not None:
            settle = (s.settle_periods + 1.0) if s.bandpass else 0.0
            raise IdentificationError(
                f"free vibration of {max((t[-1] - t_free_s) * f0, 0.0):.1f} cycles recorded after the train left "
                f"(< {s.min_cycles + settle:g} cycles needed: {s.min_cycles:g} to identify damping"
                + (f", {settle:g} for the band-pass to settle" if settle else "") + ")")
        raise IdentificationError(f"free decay of {max(n_avail, 0.0):.1f} cycles after the passage "
                                  f"(< {s.min_cycles:g} cycles needed to identify damping)")
    return pk, min_peaks


def _decay_onset(rec, x, tp, ap, *, min_peaks, t_free_s, s):
    """Step 3b, the peak the exponential decay starts at (``j0``, into ``tp``) and the scatter of the
    log cycle amplitudes: the first peak with run records, else the log-linear rule over the cycles
    well above the noise (5 % of the largest and 3 noise levels, robust, from the second
    differences of the raw samples present)."""
    if t_free_s is not None:
        return 0, _line(tp, np.log(ap), ap ** 2)[2]
    d2 = np.diff(x[~rec.miss], 2)
    noise = float(np.median(np.abs(d2 - np.median(d2)))) / 0.6745 / math.sqrt(6.0)
    above = np.flatnonzero(ap >= max(0.05 * ap.max(), 3.0 * noise))
    if above.size < min_peaks:
        raise IdentificationError(f"signal-to-noise ratio {ap.max() / max(noise, 1e-300):.3g} of the largest "
                                  f"cycle: too few cycles above 3 noise levels to identify damping")
    n_top = int(above[-1]) + 1
    j0, scatter = _decay_start(tp[:n_top], ap[:n_top], min_peaks, s.max_log_scatter,
                               noise if not s.bandpass else 0.0)
    if j0 is None:
        raise IdentificationError(f"no exponential free decay after the peak (scatter of the log cycle "
                                  f"amplitudes {scatter:.3f} > {s.max_log_scatter:g}; the record may end "
                                  f"before the train has left, or two modes beat)")
    return j0, scatter


def _fit_decay(rec, xf, *, i0, i_end, f0, sigma0, s):
    """Step 4, fit the samples present from ``i0``, cut where the envelope meets the noise
    (``s.end_snr``), refit: ``(p, J, r, tw)`` of the last fit (:func:`_fit`; ``tw`` its times from
    ``t[i0]``)."""
    t, miss = rec.t, rec.miss
    fit = None
    for _ in range(2):
        tw, xw, keep = t[i0:i_end] - t[i0], xf[i0:i_end], ~miss[i0:i_end]
        n_cyc = tw[-1] * f0 if tw.size else 0.0
        if n_cyc < s.min_cycles:
            raise IdentificationError(f"free decay of {n_cyc:.1f} cycles above the noise after the passage "
                                      f"(< {s.min_cycles:g} cycles needed to identify damping)")
        p, J, r = _fit(tw[keep], xw[keep], f0, sigma0)
        fit = (p, J, r, tw)
        sigma, wd = p[0], abs(p[1])
        amp = math.hypot(p[2], p[3])
        rms = float(np.sqrt(np.mean(r ** 2)))
        if sigma <= 0:
            break
        t_cut = math.log(amp / (s.end_snr * rms)) / sigma if rms > 0 and amp > s.end_snr * rms else tw[-1]
        n_keep = int(np.searchsorted(tw, t_cut))
        if n_keep >= 0.9 * tw.size:
            break
        i_end = i0 + max(n_keep, 2)
        f0, sigma0 = wd / (2 * math.pi), sigma
    assert fit is not None
    return fit


def _refit_over_gaps(rec, p, tw, *, i0, s):
    """Step 4b, the dropouts inside the fitted window: none, ``(None, gaps, FIT_GAP_FREE)``; else
    refill them with the fitted mode, band-pass again and refit the samples present,
    ``((p, J, r), gaps, FIT_PRESENT)``; a dropout longer than ``s.max_gap_periods`` is refused."""
    t, miss = rec.t, rec.miss
    t_a, t_b = t[i0], t[i0] + tw[-1]
    gaps = tuple(g for g in rec.gaps if g[0] + g[1] > t_a and g[0] < t_b)
    if not gaps:
        return None, gaps, FIT_GAP_FREE
    fd_fit = abs(float(p[1])) / (2 * math.pi)
    g_long = max(gaps, key=lambda g: g[1])
    if g_long[1] * fd_fit > s.max_gap_periods:
        raise IdentificationError(f"a dropout of {g_long[1]:.3g} s ({g_long[1] * fd_fit:.2g} periods, "
                                  f"{g_long[2]} samples) at t={g_long[0]:.3f} s in the free decay: longer than "
                                  f"the {s.max_gap_periods:g} period the fit bridges")
    x = _fill_gaps(t, rec.a - np.median(rec.a), miss, rec.gaps, fd_fit, max(float(p[0]), 0.0))
    xf = _bandpass(x, rec.dt, fd_fit, s.band_ratio) if s.bandpass else x
    xw, keep = xf[i0:i0 + tw.size], ~miss[i0:i0 + tw.size]
    return _fit(tw[keep], xw[keep], fd_fit, max(float(p[0]), 1e-6 * fd_fit)), gaps, FIT_PRESENT


def _modal_fit(rec, fit, tw, *, i0, scatter, gaps, method, s):
    """Step 5, the fitted mode checked (band, decay, cycles, signal-to-noise) and its standard
    uncertainties, ``s^2 (J^T J)^-1`` with ``s^2`` from the residual spectrum at ``f_d``."""
    p, J, r = fit
    n_fit = int(r.size)
    sigma, wd = float(p[0]), abs(float(p[1]))
    fd = wd / (2 * math.pi)
    amp = math.hypot(p[2], p[3])
    rms = float(np.sqrt(np.mean(r ** 2)))
    n_cyc = float(tw[-1] * fd)
    snr = amp / rms if rms > 0 else float("inf")
    if not rec.f_lo <= fd <= rec.f_hi:
        raise IdentificationError(f"the fitted frequency {fd:.4g} Hz is outside [{rec.f_lo:g}, {rec.f_hi:.4g}] Hz")
    if sigma <= 0:
        raise IdentificationError(f"the fitted decay rate {sigma:.3g} 1/s is not positive: no damping "
                                  f"can be identified from an amplitude that does not decay")
    if n_cyc < s.min_cycles:
        raise IdentificationError(f"free decay of {n_cyc:.1f} cycles above the noise after the passage "
                                  f"(< {s.min_cycles:g} cycles needed to identify damping)")
    if snr < s.min_snr:
        raise IdentificationError(f"signal-to-noise ratio {snr:.3g} at the start of the free decay "
                                  f"(< {s.min_snr:g} needed to identify damping)")
    s2 = _noise_variance(r, rec.dt, fd)
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        raise IdentificationError("the fit's Jacobian is singular: the free decay does not determine "
                                  "frequency and damping") from None
    w1 = math.hypot(wd, sigma)
    zeta = sigma / w1
    g_z = np.array([wd ** 2 / w1 ** 3, -sigma * wd / w1 ** 3])  # d zeta / d(sigma, wd)
    g_w = np.array([sigma / w1, wd / w1])                       # d omega1 / d(sigma, wd)
    c2 = cov[:2, :2]
    zeta_std = float(math.sqrt(max(g_z @ c2 @ g_z, 0.0)))
    f1_std = float(math.sqrt(max(g_w @ c2 @ g_w, 0.0))) / (2 * math.pi)
    if zeta_std > s.max_rel_std * zeta:
        raise IdentificationError(f"relative standard uncertainty of zeta1 {100 * zeta_std / zeta:.0f} % "
                                  f"(> {100 * s.max_rel_std:g} % allowed)")
    t = rec.t
    return ModalFit(f1_hz=w1 / (2 * math.pi), zeta1=zeta, f1_std_hz=f1_std, zeta1_std=zeta_std, fd_hz=fd,
                    t_start_s=float(t[i0]), t_end_s=float(t[i0] + tw[-1]), n_cycles=n_cyc, snr=float(snr),
                    amplitude_m_s2=float(amp), n_samples=n_fit, filtered=bool(s.bandpass),
                    log_scatter=float(scatter), gaps=gaps, method=method)


def _identify(t_s, a_m_s2, t_free_s, s):
    """The steps of :func:`identify_first_mode` (numbered as in the module docstring)."""
    rec = _record(t_s, a_m_s2, s)
    t, dt = rec.t, rec.dt
    i_from, f0, x = _free_vibration(rec, t_free_s)
    # 2. band-pass over the whole record
    xf = _bandpass(x, dt, f0, s.band_ratio) if s.bandpass else x
    i_end = t.size - (int(round(1.0 / (f0 * dt))) if s.bandpass else 0)
    # 3. the exponential free decay and the logarithmic decrement
    pk, min_peaks = _decay_peaks(rec, xf, i_from=i_from, i_end=i_end, f0=f0, t_free_s=t_free_s, s=s)
    tp, ap = t[pk], np.abs(xf[pk])
    j0, scatter = _decay_onset(rec, x, tp, ap, min_peaks=min_peaks, t_free_s=t_free_s, s=s)
    slope = _line(tp[j0:], np.log(ap[j0:]), ap[j0:] ** 2)[0]
    sigma0 = max(-slope, 1e-6 * f0)
    i0 = pk[j0]
    if t_free_s is None and s.bandpass:  # the filter's memory of the forced vibration
        i0 = pk[min(int(np.searchsorted(pk, i0 + s.settle_periods / (f0 * dt))), pk.size - 1)]
    # 4. fit the samples present, cut where the envelope meets the noise, refit
    p, J, r, tw = _fit_decay(rec, xf, i0=i0, i_end=i_end, f0=f0, sigma0=sigma0, s=s)
    refit, gaps, method = _refit_over_gaps(rec, p, tw, i0=i0, s=s)
    # 5. the checks and the uncertainties
    return _modal_fit(rec, refit or (p, J, r), tw, i0=i0, scatter=scatter, gaps=gaps, method=method, s=s)


# ---------------------------------------------------------------------- passages
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
    from adm_sim.model.plausibility import ROWS  # noqa: PLC0415  light, but only needed here

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
    miss = _missing_on_grid(t, find_gaps(np.unique(t_all[fin]), dt), dt)[:n_blocks * n_win]
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


def _signal_analyses(t, a, segs, settings):
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
            for k, (tp, ap, bf, af) in enumerate(_signal_analyses(t, a, segment_signal(t, a, settings), settings))]


# ---------------------------------------------------------------------- incremental: the monitor
@dataclass
class _Run:
    run_id: int
    t0_s: float
    scale: float = 1.0          # stamp interval -> monitored lane's time
    speed_m_s: float | None = None
    t1_s: float | None = None
    phase: str | None = None
    t: list = field(default_factory=list)
    a: list = field(default_factory=list)
    failed: str | None = None
    last_wall_s: float = 0.0
    published: int | None = None  # samples of the acceleration topic the run says it published


class PassageTracker:
    """Passages of a stream of samples and run records, reported as they complete.

    Feed it the latched descriptions (:meth:`bridge_description`, :meth:`train_description`), the
    ``/adm/run/status`` records (:meth:`status`) and the samples (:meth:`sample`, stamp in s and
    acceleration in m/s²) in any order; each completed passage is handed to ``on_passage`` and kept
    in :attr:`passages`. With run records a run's passage completes when a sample stamped at or
    after its ``t1_s`` arrives, when :meth:`poll` finds no sample for ``settle_s`` of wall time after
    its ``done``, or at :meth:`flush`. Without any run record the samples are segmented by the
    signal (:func:`segment_signal`): at :meth:`flush`, or by :meth:`poll` for a passage followed by
    ``quiet_s`` of quiet signal or of no sample at all (wall time).

    Live, records can be missed: a subscriber that matched the publisher after a run's ``started``
    places the run from its ``done`` (which repeats ``t0_s`` and the monitored lane); a ``done``
    lost with a publisher that has gone (its process ended) leaves a run open, which :meth:`poll`
    completes ``settle_s`` after its last sample once :attr:`records_expected` is False. The live
    monitor sets :attr:`records_expected` while the run-record topic has a publisher; while it is
    True, samples without a run wait for their records instead of being segmented by the signal.

    Parameters
    ----------
    track_type : str or None
        Track type of the limit (EN 1990 A2.4.4.2.1); None: the bridge description's, else ballasted.
    warn_fraction : float
        ``near`` above this fraction of the limit.
    """

    def __init__(self, *, track_type=None, warn_fraction=0.8, settings=None, on_passage=None, settle_s=1.0,
                 quiet_s=10.0, max_buffer_s=900.0):
        self.track_type, self.warn_fraction = track_type, float(warn_fraction)
        self.settings = settings or IdentifySettings()
        self.on_passage = on_passage
        self.settle_s, self.quiet_s, self.max_buffer_s = float(settle_s), float(quiet_s), float(max_buffer_s)
        self.passages: list[Passage] = []
        self.runs: list[_Run] = []
        self.phases: dict[int, str] = {}
        self.span_m: float | None = None  # the deck length (m): all spans of a continuous deck
        self.train_length_m: float | None = None
        self.bridge_track: str | None = None
        self.bridge_limit: float | None = None
        self.bridge_name: str | None = None
        self.seen_records = False
        self.loose_t: list[float] = []
        self.loose_a: list[float] = []
        self.dropped = 0  # samples outside every run (with run records)
        self.nonfinite = 0  # NaN or infinite samples received (each passage counts its own)
        self.records_expected = False  # live: a publisher of run records is on the graph
        self.last_sample_wall_s = 0.0
        self.completed: set[int] = set()  # run ids reported (a repeated done is ignored)
        self._reported_until: float | None = None  # signal passages: the last reported one's end stamp
        self._segmented_n = -1  # samples seen at the last live segmentation

    # ------------------------------------------------------------------ inputs
    def bridge_description(self, rec):
        b = rec.get("bridge") or {}
        if b.get("spans_m"):  # a continuous deck: the train leaves after its last span
            self.span_m = float(math.fsum(float(x) for x in b["spans_m"]))
        elif "span_m" in b:
            self.span_m = float(b["span_m"])
        if b.get("name"):
            self.bridge_name = str(b["name"])
        self.bridge_track = rec.get("track_type") or self.bridge_track
        if rec.get("acc_limit_m_s2") is not None:
            self.bridge_limit = float(rec["acc_limit_m_s2"])

    def train_description(self, rec):
        if rec.get("length_m") is not None:
            self.train_length_m = float(rec["length_m"])

    def status(self, rec, wall_s=0.0):
        """A ``/adm/run/status`` record (dict)."""
        state, run_id = rec.get("state"), rec.get("run_id")
        if run_id is None:
            return
        run_id = int(run_id)
        if rec.get("phase") is not None:
            self.phases[run_id] = str(rec["phase"])
        if rec.get("node") != "bridge":
            return
        if state == "started":
            self.seen_records = True
            run = _Run(run_id, float(rec.get("t0_s", 0.0)), scale=_stamp_scale(rec), last_wall_s=wall_s)
            v_kmh = rec.get("monitor_speed_kmh")
            run.speed_m_s = None if v_kmh is None else float(v_kmh) / 3.6
            self.runs.append(run)
            keep_t, keep_a = [], []
            for t, a in zip(self.loose_t, self.loose_a):  # samples that overtook their started record
                if t >= run.t0_s - STAMP_TOLERANCE_S:
                    self._put(run, t, a)
                else:
                    keep_t.append(t)
                    keep_a.append(a)
            self.loose_t, self.loose_a = keep_t, keep_a
        elif state in ("done", "failed"):
            run = self._run(run_id)
            if run is None and run_id not in self.completed and rec.get("t0_s") is not None:
                self.status({**rec, "state": "started"}, wall_s)  # its started record was missed
                run = self._run(run_id)
            if run is None:
                return
            run.last_wall_s = wall_s
            if state == "failed":
                run.failed = str(rec.get("message", "failed"))
            counts = rec.get("samples")
            if isinstance(counts, dict):  # per-topic counts of the run's done record
                n = [v for k, v in counts.items() if str(k).endswith("midspan/accel")]
                run.published = int(n[0]) if len(n) == 1 else None
            run.t1_s = float(rec["t1_s"]) if rec.get("t1_s") is not None else self._last_t1(run)
            self._rehome_beyond_end(run)

    def _rehome_beyond_end(self, run):
        """Samples that reached a run while its end was unknown but are stamped at or after it belong to
        a later run: a replay's (or a loaded graph's) sample and record publishers have no order between
        them, so the next run's samples can arrive before this run's ``done``. They are fed again (the
        first of them completes this run)."""
        raw = [run.t0_s + (s - run.t0_s) / run.scale for s in run.t]  # back to stamps (see _put)
        end = run.t1_s - STAMP_TOLERANCE_S
        cut = next((i for i, t in enumerate(raw) if t >= end), None)
        if cut is None:
            return
        moved = list(zip(raw[cut:], run.a[cut:]))
        del run.t[cut:], run.a[cut:]
        for t, a in moved:
            self.sample(t, a, run.last_wall_s)

    def sample(self, t_s, a_m_s2, wall_s=0.0):
        """One acceleration sample (stamp in s, m/s²)."""
        t, a = float(t_s), float(a_m_s2)
        self.last_sample_wall_s = wall_s
        if not math.isfinite(a):
            self.nonfinite += 1
        # [t0_s, t1_s), a stamp within 1 ns below a boundary on its later side; the latest run first, so a
        # sample of a run whose started record is in does not go to an earlier run whose done is not yet
        for run in sorted(self.runs, key=lambda r: r.t0_s, reverse=True):
            if run.t0_s - STAMP_TOLERANCE_S <= t and (run.t1_s is None or t < run.t1_s - STAMP_TOLERANCE_S):
                self._put(run, t, a)
                run.last_wall_s = wall_s
                break
        else:  # before its run's started record, or outside every run (counted when its run completes)
            self.loose_t.append(t)
            self.loose_a.append(a)
        for run in list(self.runs):  # a sample at or after a run's end completes it
            if run.t1_s is not None and t >= run.t1_s - STAMP_TOLERANCE_S:
                self._complete(run)

    def poll(self, wall_s):
        """Complete what is due by wall time (live): runs ``settle_s`` after their last input, and
        without run records a passage followed by ``quiet_s`` of quiet signal."""
        for run in list(self.runs):
            if wall_s - run.last_wall_s < self.settle_s:
                continue
            if run.t1_s is None and not self.records_expected:  # its done was lost with its publisher
                run.t1_s = self._last_t1(run)
            if run.t1_s is not None:
                self._complete(run)
        if not self.seen_records and self.loose_t and not self.records_expected:
            final = wall_s - self.last_sample_wall_s >= self.quiet_s
            n = len(self.loose_t)
            if final or n != self._segmented_n:  # nothing new: nothing to segment again
                self._segmented_n = n
                self._signal_passages(final=final)

    def flush(self):
        """Complete everything (end of a recording or of the monitor)."""
        for run in list(self.runs):
            if run.t1_s is None:
                run.t1_s = self._last_t1(run)
            self._complete(run)
        if not self.seen_records and self.loose_t:
            self._signal_passages(final=True)

    # ------------------------------------------------------------------ internals
    @staticmethod
    def _last_t1(run):
        """A run's end when its ``done`` never came: its last sample's stamp."""
        return run.t0_s + ((run.t[-1] - run.t0_s) / run.scale if run.t else 0.0)

    def _run(self, run_id):
        return next((r for r in self.runs if r.run_id == run_id), None)

    @staticmethod
    def _put(run, t, a):
        run.t.append(run.t0_s + (t - run.t0_s) * run.scale)
        run.a.append(a)

    def _limit(self):
        track = self.track_type or self.bridge_track or "ballasted"
        if self.track_type is None and self.bridge_limit is not None:
            return self.bridge_limit, track
        return acc_limit_m_s2(track), track

    def _emit(self, t, a, t_free_s, source, run_id=None, phase=None, info=None, before=None, after=None):
        limit, track = self._limit()
        p = analyse_passage(t, a, index=len(self.passages) + 1, limit_m_s2=limit, track_type=track,
                            warn_fraction=self.warn_fraction, t_free_s=t_free_s, settings=self.settings,
                            source=source, run_id=run_id, phase=phase, info={"track_type": track, **(info or {})},
                            before=before, after=after, dynamic=source == "run records")
        self.passages.append(p)
        if self.on_passage is not None:
            self.on_passage(p)
        return p

    def _complete(self, run):
        self.runs.remove(run)
        self.completed.add(run.run_id)
        if self.loose_t:  # samples left before this run's end belong to no run
            t = np.asarray(self.loose_t)
            keep = t >= run.t1_s - STAMP_TOLERANCE_S
            self.dropped += int((~keep).sum())
            self.loose_t = t[keep].tolist()
            self.loose_a = np.asarray(self.loose_a)[keep].tolist()
        if run.failed is not None:
            return
        t_free = None
        if run.speed_m_s and self.span_m is not None and self.train_length_m is not None:
            t_free = run.t0_s + (self.train_length_m + self.span_m) / run.speed_m_s
        info = {"bridge": self.bridge_name, "t_train_left_s": t_free, "samples_published": run.published,
                "samples_lost": None if run.published is None else max(run.published - len(run.t), 0)}
        self._emit(np.asarray(run.t), np.asarray(run.a), t_free, "run records", run.run_id,
                   self.phases.get(run.run_id), info)

    def _signal_passages(self, final):
        """Segment the samples without a run; report the passages followed by ``quiet_s`` of quiet
        signal (all at ``final``). The last reported passage stays in the buffer, so the trigger of
        the next segmentation (``min(trigger_snr σ_n, trigger_fraction max)``) sees it as the
        segmentation of the whole record would, and is not pulled down to its decaying tail."""
        t, a = np.asarray(self.loose_t), np.asarray(self.loose_a)
        segs = segment_signal(t, a, self.settings)
        order = np.argsort(t, kind="stable")
        t, a = t[order], a[order]
        last_b = None
        for (b, e), (tp, ap, bf, af) in zip(segs, _signal_analyses(t, a, segs, self.settings)):
            if self._reported_until is not None and t[b] <= self._reported_until:
                continue  # reported before (its end may move a little as the buffer grows)
            if not final and t[-1] - t[e - 1] < self.quiet_s:
                break  # may go on
            self._emit(tp, ap, None, "signal", before=bf, after=af)
            self._reported_until, last_b = float(t[e - 1]), b
        if final:
            self.loose_t, self.loose_a = [], []
            self._reported_until = None
        elif last_b is not None or (t.size and t[-1] - t[0] > self.max_buffer_s):
            # keep the last reported passage and what follows; drop what is older or too old
            keep = t >= max(t[last_b] if last_b is not None else t[0], t[-1] - self.max_buffer_s)
            self.loose_t, self.loose_a = t[keep].tolist(), a[keep].tolist()


def run_topics_for(topic):
    """The run-record and description topics beside an acceleration topic of ours
    (``/b1/adm/midspan/accel`` -> ``/b1/adm/run/status``, ``/b1/adm/bridge/description``,
    ``/b1/adm/train/description``), or None for another topic (a sensor's: no run records)."""
    if not topic.endswith(P.TOPIC_ACCEL):
        return None
    ns = topic[: len(topic) - len(P.TOPIC_ACCEL)]
    return ns + P.TOPIC_STATUS, ns + P.TOPIC_BRIDGE_DESC, ns + P.TOPIC_TRAIN_DESC


def _stamp_scale(started):
    """Factor from stamp intervals to the monitored lane's time. A ``started`` record that names the
    lane its stamps run in (``time_lane``) has stamps in the monitored lane's own time; an older one
    stamps in the clock lane's (the slowest: ``clock_speed_kmh``), scaled here by its speed over the
    monitored lane's (``monitor_speed_kmh``), so the frequency of a sweep's monitored lane comes out
    right."""
    if started.get("time_lane") is not None:
        return 1.0
    v_mon, v_clock = started.get("monitor_speed_kmh"), started.get("clock_speed_kmh")
    if v_mon and v_clock:
        return float(v_clock) / float(v_mon)
    return 1.0
