"""Exact moving-load envelopes: max midspan acceleration and deflection per speed, to round-off.

The Moving Load Model on the modal beam (paper Eqs. 5, 6, 12) is, mode by mode, a damped
oscillator driven by ``(1/M_j) sum_i F_i sin(j pi (v t - a_i) / L)`` over the axles ``i`` on the
span (a_i: axle offset behind the first axle). Between two events (an axle entering at front
position ``s = a_i`` or leaving at ``s = a_i + L``) the load of mode j is one sinusoid,
``Im[G_jk e^(i Omega_j t)]`` with ``Omega_j = j pi v / L`` and the speed-independent complex
amplitude ``G_jk = (1/M_j) sum_(on) F_i e^(-i j pi a_i / L)``, so the solution is exactly

    q_j(t_k + tau) = Im[P_jk e^(i Omega_j tau)] + Im[H_jk e^(lambda_j tau)],
    P_jk = G_jk e^(i j pi s_k / L) / (omega_j^2 - Omega_j^2 + 2 i zeta_j omega_j Omega_j),
    lambda_j = -zeta_j omega_j + i omega_j sqrt(1 - zeta_j^2),

with ``H_jk`` fixed by continuity of q and q' at the event (Fryba's closed form of a moving
force, propagated from event to event). After the last axle has left, ``P = 0`` (free vibration).
Midspan: ``w = sum_j q_j sin(j pi / 2)``, ``a = sum_j q_j'' sin(j pi / 2)`` (even modes do not
move midspan and are skipped).

Maximum between samples: every interval is sampled at ``samples_per_period`` points per period
of the fastest component; each sampled local maximum of ``|a|`` (``|w|``) that can still hold the
maximum (its value plus the curvature bound ``max|a''| h^2 / 4`` reaches the best sample) is
refined by Newton's method on ``a'(tau) = 0`` inside its two-sample bracket, with the analytic
derivatives. Event instants, where ``a'`` has kinks, are candidates too. Intervals whose
amplitude bound ``sum |coefficients|`` cannot reach the largest value at the event instants are
not sampled at all, and every interval is pruned again against the maximum found so far before
it is sampled (largest bounds first). The free vibration is followed until its decaying bound drops
below the largest value found at an event instant (at most :data:`MAX_FREE_PERIODS` fundamental
periods). The search loop is compiled with numba (the same search in numpy, per-interval array
operations, cost 2.6-5 s for the 14-train bench case instead of 0.4 s CPU).

Modes: EN 1990 A2.4.4.2.1 asks for every mode up to the larger of 30 Hz, 1.5 n0 and the third
mode's frequency (:func:`check_mode_count`).
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError, check_range

try:  # numba compiles the search loop; without it the same source runs as plain Python (slow)
    from numba import njit
except ImportError:  # pragma: no cover - numba is in requirements.txt
    def njit(*args, **kwargs):
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

#: Longest free vibration followed after the last axle has left, in fundamental periods.
MAX_FREE_PERIODS = 30.0
#: Newton iterations of the refinement (quadratic convergence from within a quarter period).
NEWTON_ITERATIONS = 8


def check_frequency_limit_hz(bridge):
    """Highest frequency to include (Hz): max(30 Hz, 1.5 n0, n3), EN 1990 A2.4.4.2.1."""
    return max(30.0, 1.5 * bridge.n0_hz, 9.0 * bridge.n0_hz)


def check_mode_count(bridge, f_limit_hz=None):
    """Number of modes with ``n_j = j^2 n0 <= f_limit`` (default: :func:`check_frequency_limit_hz`)."""
    f = check_frequency_limit_hz(bridge) if f_limit_hz is None else float(f_limit_hz)
    return max(1, int(math.floor(math.sqrt(f / bridge.n0_hz) + 1e-9)))


@dataclass(frozen=True)
class Envelope:
    """Exact MLM maxima per speed.

    Attributes
    ----------
    speeds_kmh, max_acc_m_s2, max_disp_m : ndarray (n_lanes,)
    t_acc_s, t_disp_s : ndarray (n_lanes,)
        Time of the maxima, from the first axle's entry.
    modes : tuple of int
        Modes in the calculation (all of ``bridge.n_modes``; even modes have no midspan motion).
    refined : int
        Number of candidate maxima refined by Newton's method.
    """

    speeds_kmh: np.ndarray
    max_acc_m_s2: np.ndarray
    max_disp_m: np.ndarray
    t_acc_s: np.ndarray
    t_disp_s: np.ndarray
    modes: tuple
    refined: int


def _events(offsets, loads, span, jj, mass):
    """Breakpoints s_k (m) and the speed-independent load amplitudes G (K+1, modes)."""
    bps = np.unique(np.concatenate([offsets, offsets + span]))
    phase = np.exp(-1j * np.pi * np.outer(offsets, jj) / span) * (loads / mass)[:, None]  # (axles, modes)
    delta = np.zeros((bps.size, jj.size), dtype=complex)
    np.add.at(delta, np.searchsorted(bps, offsets), phase)
    np.add.at(delta, np.searchsorted(bps, offsets + span), -phase)
    G = np.cumsum(delta, axis=0)
    G[-1] = 0.0  # free vibration after the last exit (exactly zero, not round-off)
    return bps, G


def moving_load_envelope(bridge, axle_offsets_m, axle_loads_n, speeds_kmh, delta_zeta=0.0,
                         samples_per_period=4.0):
    """Exact max |midspan acceleration| and |deflection| of the MLM at every speed.

    Parameters
    ----------
    bridge : adm_sim.bridge.Bridge
        Modal beam; all ``bridge.n_modes`` modes are used with ``bridge.modal_damping_ratios``.
    axle_offsets_m, axle_loads_n : array_like (n_axles,)
        Axles behind the first one (m) and their loads (N).
    speeds_kmh : array_like (n_lanes,)
    delta_zeta : float
        Additional damping (fraction).
    samples_per_period : float
        Samples per period of the fastest component before refinement (4..64).

    Returns
    -------
    Envelope
    """
    from adm_sim.stepping import speeds_to_m_s

    v_all = speeds_to_m_s(speeds_kmh)
    ppp = check_range("samples_per_period", samples_per_period, "-", 4.0, 64.0)
    dz = check_range("delta_zeta_pct", 100.0 * float(delta_zeta), "%", -100 * bridge.damping_ratio, 20.0) / 100.0
    offs = np.asarray(axle_offsets_m, dtype=float)
    loads = np.asarray(axle_loads_n, dtype=float)
    if offs.ndim != 1 or offs.shape != loads.shape or offs.size == 0:
        raise InputError("axles: offsets (m) and loads (N) need the same non-zero length")
    L = bridge.span_m
    jall = bridge.mode_numbers
    s_all = np.sin(jall * np.pi / 2.0)
    keep = np.abs(s_all) > 0.5
    jj, s = jall[keep], s_all[keep]
    om = bridge.omega_rad_s[keep]
    zeta = np.asarray(bridge.modal_damping_ratios(dz))[keep]
    if np.any(zeta <= 0.0):  # the closed form divides by the damping at resonance
        raise InputError(f"damping: zeta + delta_zeta = {100 * (bridge.damping_ratio + dz):g} %; the exact envelope "
                         f"needs damping > 0 % (allowed (0, 40] %)")
    mass = bridge.modal_mass_kg[keep]
    lam = -zeta * om + 1j * om * np.sqrt(1.0 - zeta**2)
    bps, G = _events(offs, loads, L, jj, mass[0])  # equal modal masses mu L / 2
    G = G * (mass[0] / mass)

    res = _all_lanes(v_all, L, jj, s, om, zeta, lam, bps, G, ppp)
    return Envelope(speeds_kmh=np.atleast_1d(np.asarray(speeds_kmh, dtype=float)).copy(),
                    max_acc_m_s2=res["acc"], max_disp_m=res["disp"], t_acc_s=res["tacc"],
                    t_disp_s=res["tdisp"], modes=tuple(int(j) for j in jall), refined=res["refined"])


def _all_lanes(v, L, jj, s, om, zeta, lam, bps, G, ppp):
    """Propagate every lane from event to event, then search the maxima (see the module doc)."""
    nl = v.size
    Om = jj[None, :] * np.pi * v[:, None] / L  # (lanes, modes)
    dyn = 1.0 / (om**2 - Om**2 + 2j * zeta * om * Om)
    K = bps.size  # intervals k = 0..K-2 between breakpoints, K-1 = free vibration
    P = G[:, None, :] * np.exp(1j * np.pi * np.outer(bps, jj) / L)[:, None, :] * dyn[None]  # (K, lanes, modes)
    H = np.empty_like(P)
    T = np.empty((K, nl))
    T[:-1] = np.diff(bps)[:, None] / v[None, :]
    t0 = bps[:, None] / v[None, :]  # (K, lanes) start time of every interval
    q = np.zeros((nl, jj.size))
    dq = np.zeros((nl, jj.size))
    for k in range(K):
        p = P[k]
        hi = q - p.imag
        H[k] = (dq - Om * p.real - lam.real * hi) / lam.imag + 1j * hi
        if k < K - 1:
            eW = np.exp(1j * Om * T[k][:, None])
            eL = np.exp(lam * T[k][:, None])
            q = (p * eW).imag + (H[k] * eL).imag
            dq = (1j * Om * p * eW).imag + (lam * H[k] * eL).imag
    # midspan acceleration (2nd derivative) and deflection as sum_j Im[c1 e^(i Om tau) + c2 e^(lam tau)]
    coef_a1, coef_a2 = s * P * (1j * Om) ** 2, s * H * lam**2
    coef_d1, coef_d2 = s * P, s * H
    best2 = np.empty((2, nl))
    when2 = np.empty((2, nl))
    for q_, (c1, c2) in enumerate(((coef_a1, coef_a2), (coef_d1, coef_d2))):  # exact values at the events
        at_event = np.abs((c1 + c2).imag.sum(-1))  # (K, lanes)
        i = at_event.argmax(0)
        best2[q_] = at_event[i, np.arange(nl)]
        when2[q_] = t0[i, np.arange(nl)]
    # free vibration: follow it until its decaying bound falls below the best event value
    t_free = np.zeros(nl)
    for q_, c2 in enumerate((coef_a2, coef_d2)):
        b = np.abs(c2[-1]).sum(-1)
        with np.errstate(divide="ignore"):
            t_free = np.maximum(t_free, np.log(np.maximum(b, 1e-300) / np.maximum(best2[q_], 1e-300)) / (-lam.real).min())
    T[-1] = np.clip(t_free, 0.0, MAX_FREE_PERIODS * 2.0 * np.pi / om[0])
    # intervals that can hold a larger value than the event instants, largest bound first
    bound = np.stack([(np.abs(coef_a1) + np.abs(coef_a2)).sum(-1), (np.abs(coef_d1) + np.abs(coef_d2)).sum(-1)])
    curv = np.stack([(np.abs(coef_a1) * Om**2 + np.abs(coef_a2) * np.abs(lam) ** 2).sum(-1),
                     (np.abs(coef_d1) * Om**2 + np.abs(coef_d2) * np.abs(lam) ** 2).sum(-1)])
    ratio = (bound / np.maximum(best2, 1e-300)[:, None, :]).max(0)
    kk, ll = np.nonzero((ratio > 1.0) & (T > 0.0))
    order = np.argsort(-ratio[kk, ll], kind="stable")
    f_lane = np.maximum(np.abs(lam).max(), Om.max(1)) / (2.0 * np.pi)  # fastest component per lane
    m = np.ceil(T[kk[order], ll[order]] * f_lane[ll[order]] * ppp).astype(np.int64) + 1
    refined = _search_kernel(kk[order], ll[order], m, coef_a1, coef_a2, coef_d1, coef_d2, Om, lam, T, t0,
                             bound, curv, best2, when2)
    return {"acc": best2[0], "disp": best2[1], "tacc": when2[0], "tdisp": when2[1], "refined": int(refined)}


@njit(cache=True, nogil=True)
def _eval(c1, c2, om, lam, tau, n):
    """sum_j Im[c1_j (i om_j)^n e^(i om_j tau) + c2_j lam_j^n e^(lam_j tau)] (n-th derivative)."""
    y = 0.0
    for j in range(c1.size):
        w = 1j * om[j]
        y += (c1[j] * w**n * cmath.exp(w * tau) + c2[j] * lam[j] ** n * cmath.exp(lam[j] * tau)).imag
    return y


@njit(cache=True, nogil=True)
def _newton(c1, c2, om, lam, x, lo, hi):
    """Local extremum of the function of (c1, c2) near x inside [lo, hi] (Newton on its derivative)."""
    for _ in range(NEWTON_ITERATIONS):
        g2 = _eval(c1, c2, om, lam, x, 2)
        if g2 == 0.0:
            break
        x = min(hi, max(lo, x - _eval(c1, c2, om, lam, x, 1) / g2))
    return x, abs(_eval(c1, c2, om, lam, x, 0))


@njit(cache=True, nogil=True)
def _search_kernel(kk, ll, m, ca1, ca2, cd1, cd2, Om, lam, T, t0, bound, curv, best, when):
    """Sample every (interval, lane) pair that can still hold a maximum (pruned again against the
    risen best before each pair), refine every sampled local maximum of |a| and |w| that can reach
    the best by Newton inside its two-sample bracket; ``best`` and ``when`` (2, lanes) in place."""
    nm = lam.size
    refined = 0
    ya = np.empty(3)
    for p in range(kk.size):
        k, l = kk[p], ll[p]
        if bound[0, k, l] <= best[0, l] and bound[1, k, l] <= best[1, l]:
            continue
        T_ = T[k, l]
        h = T_ / m[p]
        om = Om[l]
        for q in range(2):  # 0: acceleration, 1: deflection
            if bound[q, k, l] <= best[q, l]:
                continue
            c1 = ca1[k, l] if q == 0 else cd1[k, l]
            c2 = ca2[k, l] if q == 0 else cd2[k, l]
            slack = curv[q, k, l] * h * h / 4.0
            r1 = np.empty(nm, dtype=np.complex128)
            r2 = np.empty(nm, dtype=np.complex128)
            e1 = np.ones(nm, dtype=np.complex128)
            e2 = np.ones(nm, dtype=np.complex128)
            for j in range(nm):
                r1[j] = cmath.exp(1j * om[j] * h)
                r2[j] = cmath.exp(lam[j] * h)
            for i in range(m[p] + 1):
                y = 0.0
                for j in range(nm):
                    y += (c1[j] * e1[j] + c2[j] * e2[j]).imag
                    e1[j] *= r1[j]
                    e2[j] *= r2[j]
                y = abs(y)
                ya[0], ya[1], ya[2] = ya[1], ya[2], y
                if y > best[q, l]:
                    best[q, l] = y
                    when[q, l] = t0[k, l] + i * h
                # sample i-1 is a local maximum (the first sample compares with its right side only)
                if i >= 1 and ya[1] >= ya[2] and (i == 1 or ya[1] >= ya[0]) and ya[1] + slack >= best[q, l]:
                    refined += _refine_at(c1, c2, om, lam, (i - 1) * h, h, T_, t0[k, l], best, when, q, l)
            if ya[2] >= ya[1] and ya[2] + slack >= best[q, l]:  # the last sample
                refined += _refine_at(c1, c2, om, lam, m[p] * h, h, T_, t0[k, l], best, when, q, l)
    return refined


@njit(cache=True, nogil=True)
def _refine_at(c1, c2, om, lam, x, h, T_, t_start, best, when, q, l):
    x, y = _newton(c1, c2, om, lam, x, max(0.0, x - h), min(T_, x + h))
    if y > best[q, l]:
        best[q, l] = y
        when[q, l] = t_start + x
    return 1


__all__ = ["Envelope", "moving_load_envelope", "check_mode_count", "check_frequency_limit_hz",
           "MAX_FREE_PERIODS"]
