"""The first bending mode (f1, ζ1 and their standard uncertainties) from a passage's free decay.

:func:`identify_first_mode` follows the steps of the method in :mod:`adm_sim.monitoring.modal_id`
("First mode"), one function each, numbered as there: the record on its uniform grid
(:func:`uniform_samples`, dropouts :func:`find_gaps`), 1. where the free vibration is and its
spectral peak, 2. the band-pass, 3. the half-cycle peaks and the start of the exponential decay
(the logarithmic decrement), 4. the least-squares fit of a decaying sinusoid (across dropouts:
:func:`_refit_over_gaps`), 5. the checks and the standard uncertainties. A passage that gives no
mode raises :class:`IdentificationError` inside this module; :func:`identify_first_mode` returns its
one-line reason instead. The steps that call scipy (the band-pass, the peaks, the least-squares fit,
the noise variance) are :mod:`adm_sim.monitoring.decay_signal`'s, loaded with the first analysis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from adm_sim.monitoring.modal_records import FIT_GAP_FREE, FIT_PRESENT, IdentifySettings, ModalFit

__all__ = ["IdentificationError", "find_gaps", "identify_first_mode", "missing_on_grid", "uniform_samples"]


class IdentificationError(Exception):
    """Why a free decay gives no first mode (the passage's ``reason``); internal to this module."""


# ---------------------------------------------------------------------- samples
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
    """Frequency of the largest peak of the Hann-windowed, 8x zero-padded spectrum in [f_lo, f_hi]
    (within half a bin of the band); refused when the band's largest value is at its edge on the flank
    of a larger peak outside it (there the parabola's vertex lay bins away, even below 0 Hz)."""
    n = x.size
    nfft = 1 << int(math.ceil(math.log2(8 * n)))
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(n), nfft))
    f = np.fft.rfftfreq(nfft, dt)
    band = np.flatnonzero((f >= f_lo) & (f <= f_hi))
    if band.size < 3:
        raise IdentificationError(f"no frequency in [{f_lo:g}, {f_hi:g}] Hz is resolved by {n} samples at "
                                  f"{1 / dt:g} Hz")
    i = band[np.argmax(spec[band])]
    if 0 < i < spec.size - 1 and max(spec[i - 1], spec[i + 1]) > spec[i]:  # on the flank of a peak outside
        raise IdentificationError(f"no spectral peak in [{f_lo:g}, {f_hi:.4g}] Hz: the spectrum rises beyond the "
                                  f"band's edge at {f[i]:.4g} Hz (a mode or a swing outside the band)")
    if 0 < i < spec.size - 1 and spec[i - 1] > 0 and spec[i + 1] > 0 and spec[i] > 0:
        # a local maximum: the parabola's vertex is within half a bin of it
        y0, y1, y2 = np.log(spec[i - 1:i + 2])
        den = y0 - 2 * y1 + y2
        shift = 0.5 * (y0 - y2) / den if den < 0 else 0.0
        return float(f[i] + shift * (f[1] - f[0]))
    return float(f[i])


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
def _fit(t, x, f0_hz, sigma0):
    """Least-squares fit of the decaying sinusoid (:func:`adm_sim.monitoring.decay_signal.fit_decay`);
    returns ``(params, jacobian, residuals)``."""
    res = _signal().fit_decay(t, x, f0_hz, sigma0)
    if not res.success:
        raise IdentificationError(f"the decaying-sinusoid fit did not converge ({res.message})")
    return res.x, res.jac, res.fun


def _signal():
    """:mod:`adm_sim.monitoring.decay_signal`, the steps that call scipy.signal and scipy.optimize."""
    from adm_sim.monitoring import decay_signal  # noqa: PLC0415  scipy.signal (~1.5 s) and scipy.optimize (~1 s) when a free decay is analysed, not when a monitor starts

    return decay_signal


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


def missing_on_grid(t, gaps, dt):
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
    miss = missing_on_grid(t, gaps_all, dt)
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
    pk = _signal().half_cycle_peaks(xf[:i_end], rec.dt, f0)
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
    if not 0.0 < fd_fit < 0.45 * s.band_ratio / rec.dt:  # no gap filling nor band-pass can be made around it
        raise IdentificationError(f"the fitted frequency {fd_fit:.4g} Hz is outside [{rec.f_lo:g}, {rec.f_hi:.4g}] Hz")
    g_long = max(gaps, key=lambda g: g[1])
    if g_long[1] * fd_fit > s.max_gap_periods:
        raise IdentificationError(f"a dropout of {g_long[1]:.3g} s ({g_long[1] * fd_fit:.2g} periods, "
                                  f"{g_long[2]} samples) at t={g_long[0]:.3f} s in the free decay: longer than "
                                  f"the {s.max_gap_periods:g} period the fit bridges")
    x = _fill_gaps(t, rec.a - np.median(rec.a), miss, rec.gaps, fd_fit, max(float(p[0]), 0.0))
    xf = _signal().bandpass(x, rec.dt, fd_fit, s.band_ratio) if s.bandpass else x
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
    s2 = _signal().noise_variance(r, rec.dt, fd)
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
    xf = _signal().bandpass(x, dt, f0, s.band_ratio) if s.bandpass else x
    # the band-pass's last period is left out; a record shorter than that period has no free decay to
    # read (at least one sample kept, so that the count of cycles below is 0, not an index from the end)
    i_end = max(1, t.size - (int(round(1.0 / (f0 * dt))) if s.bandpass else 0))
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

