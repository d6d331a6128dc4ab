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
not sampled at all. The free vibration is followed until its decaying bound drops below the
largest value found at an event instant (at most :data:`MAX_FREE_PERIODS` fundamental periods).

Modes: EN 1990 A2.4.4.2.1 asks for every mode up to the larger of 30 Hz, 1.5 n0 and the third
mode's frequency (:func:`check_mode_count`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError, check_range

#: Longest free vibration followed after the last axle has left, in fundamental periods.
MAX_FREE_PERIODS = 30.0
#: Samples evaluated together (the remaining intervals are pruned again after each chunk).
CHUNK_SAMPLES = 200_000
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


def _value(P, H, Om, lam, s, tau, order):
    """sum_j s_j Im[P (i Om)^n e^(i Om tau) + H lam^n e^(lam tau)]; tau broadcasts on axis -2."""
    t = tau[..., None]
    return (s * (P * (1j * Om) ** order * np.exp(1j * Om * t) + H * lam**order * np.exp(lam * t)).imag).sum(-1)


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
    mass = bridge.modal_mass_kg[keep]
    lam = -zeta * om + 1j * om * np.sqrt(1.0 - zeta**2)
    bps, G = _events(offs, loads, L, jj, mass[0])  # equal modal masses mu L / 2
    G = G * (mass[0] / mass)

    res = _all_lanes(v_all, L, jj, s, om, zeta, lam, bps, G, ppp)
    return Envelope(speeds_kmh=np.atleast_1d(np.asarray(speeds_kmh, dtype=float)).copy(),
                    max_acc_m_s2=res["acc"], max_disp_m=res["disp"], t_acc_s=res["tacc"],
                    t_disp_s=res["tdisp"], modes=tuple(int(j) for j in jall), refined=res["refined"])


#: The two searched quantities: name -> derivative order of q (acceleration 2, deflection 0).
_ORDERS = {"acc": 2, "disp": 0}


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
    best = {name: np.zeros(nl) for name in _ORDERS}
    when = {name: np.zeros(nl) for name in _ORDERS}
    for k in range(K):
        p = P[k]
        hi = q - p.imag
        H[k] = (dq - Om * p.real - lam.real * hi) / lam.imag + 1j * hi
        for name, order in _ORDERS.items():  # exact values at the event instants
            val = np.abs(_value(p, H[k], Om, lam, s, np.zeros(nl), order))
            better = val > best[name]
            best[name] = np.where(better, val, best[name])
            when[name] = np.where(better, t0[k], when[name])
        if k < K - 1:
            eW = np.exp(1j * Om * T[k][:, None])
            eL = np.exp(lam * T[k][:, None])
            q = (p * eW).imag + (H[k] * eL).imag
            dq = (1j * Om * p * eW).imag + (lam * H[k] * eL).imag
    # free vibration: follow it until its decaying bound falls below the best event value
    t_free = np.zeros(nl)
    for name, order in _ORDERS.items():
        b = (np.abs(s) * np.abs(lam) ** order * np.abs(H[-1])).sum(-1)
        with np.errstate(divide="ignore"):
            t_free = np.maximum(t_free, np.log(np.maximum(b, 1e-300) / np.maximum(best[name], 1e-300)) / (-lam.real).min())
    T[-1] = np.clip(t_free, 0.0, MAX_FREE_PERIODS * 2.0 * np.pi / om[0])
    # intervals that can hold a larger value than the event instants
    coef = {name: np.abs(s) * (np.abs(P) * Om**o + np.abs(H) * np.abs(lam) ** o) for name, o in _ORDERS.items()}
    curv = {name: (np.abs(s) * (np.abs(P) * Om ** (o + 2) + np.abs(H) * np.abs(lam) ** (o + 2))).sum(-1)
            for name, o in _ORDERS.items()}
    bounds = {name: coef[name].sum(-1) for name in _ORDERS}
    alive = np.zeros((K, nl), dtype=bool)
    ratio = np.zeros((K, nl))
    for name in _ORDERS:
        r = bounds[name] / np.maximum(best[name], 1e-300)[None, :]
        alive |= r > 1.0
        ratio = np.maximum(ratio, r)
    kk, ll = np.nonzero(alive & (T > 0.0))
    order = np.argsort(-ratio[kk, ll], kind="stable")  # largest bound first: the floor rises fast
    kk, ll = kk[order], ll[order]
    f_lane = np.maximum(np.abs(lam).max(), Om.max(1)) / (2.0 * np.pi)  # fastest component per lane
    cands = {name: [] for name in _ORDERS}
    while kk.size:  # chunks of about CHUNK_SAMPLES samples; re-prune against the risen floor
        m = np.ceil(T[kk, ll] * f_lane[ll] * ppp).astype(np.int64) + 1  # steps per interval
        stop = max(1, int(np.searchsorted(np.cumsum(m + 1), CHUNK_SAMPLES)))
        _sample(kk[:stop], ll[:stop], m[:stop], P, H, T, t0, Om, lam, s, curv, best, when, cands)
        kk, ll = kk[stop:], ll[stop:]
        still = np.zeros(kk.size, dtype=bool)
        for name in _ORDERS:
            still |= bounds[name][kk, ll] > best[name][ll]
        kk, ll = kk[still], ll[still]
    refined = 0
    for name, order in _ORDERS.items():
        refined += _refine(name, order, cands[name], P, H, T, t0, Om, lam, s, best, when)
    return {"acc": best["acc"], "disp": best["disp"], "tacc": when["acc"], "tdisp": when["disp"],
            "refined": refined}


def _sample(kk, ll, m, P, H, T, t0, Om, lam, s, curv, best, when, cands):
    """Sample the (interval, lane) pairs ``kk, ll`` at ``m + 1`` points each (flat, no loops)."""
    c = m + 1
    pair = np.repeat(np.arange(kk.size), c)
    first = np.cumsum(c) - c
    i = np.arange(pair.size) - first[pair]
    h = T[kk, ll] / m
    tau = i * h[pair]
    E1 = np.exp(1j * Om[ll][pair] * tau[:, None])
    E2 = np.exp(lam * tau[:, None])
    p, hh, om_p = s * P[kk, ll], s * H[kk, ll], Om[ll]
    is_first = i == 0
    is_last = i == m[pair]
    for name, order in _ORDERS.items():
        c1 = (p * (1j * om_p) ** order)[pair]
        c2 = (hh * lam**order)[pair]
        y = np.abs((c1.real * E1.imag + c1.imag * E1.real + c2.real * E2.imag + c2.imag * E2.real).sum(-1))
        lane = ll[pair]
        _update(best[name], when[name], lane, y, t0[kk[pair], lane] + tau)
        left = np.where(is_first, -np.inf, np.roll(y, 1))
        right = np.where(is_last, -np.inf, np.roll(y, -1))
        loc = np.flatnonzero((y >= left) & (y >= right))
        slack = curv[name][kk[pair[loc]], lane[loc]] * h[pair[loc]] ** 2 / 4.0
        cands[name].append((kk[pair[loc]], lane[loc], tau[loc], h[pair[loc]], y[loc] + slack))


def _refine(name, order, cands, P, H, T, t0, Om, lam, s, best, when):
    """Newton on the derivative inside each candidate's two-sample bracket (in place)."""
    if not cands:
        return 0
    k_c, lane_c, tau_c, h_c, reach = (np.concatenate([c[i] for c in cands]) for i in range(5))
    keep = reach >= best[name][lane_c]
    k_c, lane_c, tau_c, h_c = k_c[keep], lane_c[keep], tau_c[keep], h_c[keep]
    if k_c.size == 0:
        return 0
    p, hh, om_c = P[k_c, lane_c], H[k_c, lane_c], Om[lane_c]
    lo = np.maximum(tau_c - h_c, 0.0)
    hi = np.minimum(tau_c + h_c, T[k_c, lane_c])
    x = tau_c.copy()
    for _ in range(NEWTON_ITERATIONS):
        g1 = _value(p, hh, om_c, lam, s, x, order + 1)
        g2 = _value(p, hh, om_c, lam, s, x, order + 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(g2 != 0.0, g1 / g2, 0.0)
        x = np.clip(x - step, lo, hi)
    val = np.abs(_value(p, hh, om_c, lam, s, x, order))
    _update(best[name], when[name], lane_c, val, t0[k_c, lane_c] + x)
    return int(k_c.size)


def _update(best, when, lane, y, t):
    """In place: ``best[l] = max(best[l], y[lane == l])`` and the time ``t`` of a new maximum."""
    top = np.full(best.size, -np.inf)
    np.maximum.at(top, lane, y)
    better = top > best
    if not better.any():
        return
    hit = np.flatnonzero(better[lane] & (y == top[lane]))
    lanes, first = np.unique(lane[hit], return_index=True)
    best[lanes] = top[lanes]
    when[lanes] = t[hit[first]]


__all__ = ["Envelope", "moving_load_envelope", "check_mode_count", "check_frequency_limit_hz",
           "MAX_FREE_PERIODS"]
