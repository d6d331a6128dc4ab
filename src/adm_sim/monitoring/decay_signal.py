"""The steps of the free-decay fit that call scipy (:mod:`adm_sim.monitoring.modal_fit`, steps 2-5).

The band-pass (step 2), the half-cycle peaks (step 3), the least-squares fit of a decaying sinusoid
(step 4) and the residuals' noise variance at the mode's frequency (step 5). scipy.signal (~1.5 s to
import, it pulls scipy.stats) and scipy.optimize (~1 s) load with this module, which
:mod:`adm_sim.monitoring.modal_fit` imports only when a passage's free decay is analysed: a monitor,
``monitor.py --help`` and bad input start without them.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import butter, find_peaks, sosfiltfilt, welch

__all__ = ["bandpass", "fit_decay", "half_cycle_peaks", "noise_variance"]


def bandpass(x, dt, f_hz, ratio):
    """Zero-phase second-order Butterworth band-pass of ``x`` (sampled every ``dt`` s) from
    ``f_hz / ratio`` to ``f_hz * ratio`` (at most 0.9 Nyquist)."""
    nyq = 0.5 / dt
    lo, hi = f_hz / ratio, min(f_hz * ratio, 0.9 * nyq)
    sos = butter(2, [lo / nyq, hi / nyq], btype="bandpass", output="sos")
    return sosfiltfilt(sos, x, padlen=min(x.size - 1, 3 * int(round(1.0 / (f_hz * dt)))))


def half_cycle_peaks(x, dt, f_hz):
    """Indices of the extrema of ``x`` (maxima and minima, about one per half period)."""
    dist = max(1, int(0.7 / (f_hz * dt)))  # one maximum and one minimum per period
    up, _ = find_peaks(x, distance=dist)
    down, _ = find_peaks(-x, distance=dist)
    return np.sort(np.concatenate([up, down]))


def _model(p, t):
    """``e^(-sigma t) (b1 cos(wd t) + b2 sin(wd t)) + c`` of ``p = (sigma, wd, b1, b2, c)``."""
    sigma, wd, b1, b2, c = p
    e = np.exp(-sigma * t)
    return e * (b1 * np.cos(wd * t) + b2 * np.sin(wd * t)) + c


def _jac(p, t):
    """Jacobian of :func:`_model` with respect to ``p`` (n, 5)."""
    sigma, wd, b1, b2, _ = p
    e = np.exp(-sigma * t)
    cw, sw = np.cos(wd * t), np.sin(wd * t)
    osc = b1 * cw + b2 * sw
    return np.column_stack([-t * e * osc, e * t * (-b1 * sw + b2 * cw), e * cw, e * sw, np.ones_like(t)])


def fit_decay(t, x, f0_hz, sigma0):
    """Least-squares fit (Levenberg-Marquardt) of the decaying sinusoid :func:`_model` to ``x(t)``
    from the linear fit at frequency ``f0_hz`` and decay rate ``sigma0`` (1/s); scipy's
    ``OptimizeResult`` (``success``, ``message``, ``x``, ``jac``, ``fun``)."""
    wd0 = 2 * math.pi * f0_hz
    E = np.exp(-sigma0 * t)
    A = np.column_stack([E * np.cos(wd0 * t), E * np.sin(wd0 * t), np.ones_like(t)])
    b1, b2, c = np.linalg.lstsq(A, x, rcond=None)[0]
    p0 = np.array([sigma0, wd0, b1, b2, c])
    return least_squares(lambda p: _model(p, t) - x, p0, jac=lambda p: _jac(p, t), method="lm",
                         x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000)


def noise_variance(r, dt, fd_hz):
    """``S_r(f_d) f_s / 2``: the residuals' variance as seen at the mode's frequency (Welch PSD,
    one-sided, averaged over ``f_d`` ± 20 %); the plain variance when too few samples."""
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
