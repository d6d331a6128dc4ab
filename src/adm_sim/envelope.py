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
#: Newton iterations of the refinement (quadratic convergence from within a quarter period).
NEWTON_ITERATIONS = 8
#: Lanes processed together (sorted by speed, so a block samples for its own slowest lane).
LANE_BLOCK = 48


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
                         samples_per_period=6.0):
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

    n = v_all.size
    out = {k: np.zeros(n) for k in ("acc", "disp", "tacc", "tdisp")}
    refined = 0
    order = np.argsort(v_all, kind="stable")
    for b0 in range(0, n, LANE_BLOCK):
        lanes = order[b0:b0 + LANE_BLOCK]
        res, nref = _block(v_all[lanes], L, jj, s, om, zeta, lam, bps, G, ppp)
        refined += nref
        for k in out:
            out[k][lanes] = res[k]
    return Envelope(speeds_kmh=np.atleast_1d(np.asarray(speeds_kmh, dtype=float)).copy(),
                    max_acc_m_s2=out["acc"], max_disp_m=out["disp"], t_acc_s=out["tacc"],
                    t_disp_s=out["tdisp"], modes=tuple(int(j) for j in jall), refined=refined)


def _block(v, L, jj, s, om, zeta, lam, bps, G, ppp):
    """Envelope of one block of lanes (speeds ``v`` in m/s)."""
    nl = v.size
    Om = jj[None, :] * np.pi * v[:, None] / L  # (lanes, modes)
    dyn = 1.0 / (om**2 - Om**2 + 2j * zeta * om * Om)
    K = bps.size  # intervals k = 0..K-2 between breakpoints, K-1 = free vibration
    P = G[:, None, :] * np.exp(1j * np.pi * np.outer(bps, jj) / L)[:, None, :] * dyn[None]  # (K, lanes, modes)
    H = np.empty_like(P)
    T = np.empty((K, nl))
    T[:-1] = np.diff(bps)[:, None] / v[None, :]
    q = np.zeros((nl, jj.size))
    dq = np.zeros((nl, jj.size))
    best = {"acc": np.zeros(nl), "disp": np.zeros(nl)}
    when = {"acc": np.zeros(nl), "disp": np.zeros(nl)}
    t0 = bps[:, None] / v[None, :]  # (K, lanes) start time of every interval
    for k in range(K):
        p = P[k]
        hi = q - p.imag
        hr = (dq - Om * p.real - lam.real * hi) / lam.imag
        H[k] = hr + 1j * hi
        for name, order in (("acc", 2), ("disp", 0)):
            val = np.abs(_value(p, H[k], Om, lam, s, np.zeros(nl), order))
            better = val > best[name]
            best[name] = np.where(better, val, best[name])
            when[name] = np.where(better, t0[k], when[name])
        if k == K - 1:
            break
        eW = np.exp(1j * Om * T[k][:, None])
        eL = np.exp(lam * T[k][:, None])
        q = (p * eW).imag + (H[k] * eL).imag
        dq = (1j * Om * p * eW).imag + (lam * H[k] * eL).imag
    # free vibration: follow it until its bound falls below the best event value
    sigma = -lam.real
    bound_acc = (np.abs(s) * np.abs(lam) ** 2 * np.abs(H[-1])).sum(-1)
    bound_disp = (np.abs(s) * np.abs(H[-1])).sum(-1)
    with np.errstate(divide="ignore"):
        t_free = np.maximum(np.log(np.maximum(bound_acc, 1e-300) / np.maximum(best["acc"], 1e-300)),
                            np.log(np.maximum(bound_disp, 1e-300) / np.maximum(best["disp"], 1e-300))) / sigma.min()
    T[-1] = np.clip(t_free, 0.0, MAX_FREE_PERIODS * 2.0 * np.pi / om[0])
    f_max = max(np.abs(lam).max(), Om.max()) / (2.0 * np.pi)
    nref = 0
    for name, order in (("acc", 2), ("disp", 0)):
        nref += _search(name, order, P, H, T, t0, Om, lam, s, best, when, f_max, ppp)
    return {"acc": best["acc"], "disp": best["disp"], "tacc": when["acc"], "tdisp": when["disp"]}, nref


def _search(name, order, P, H, T, t0, Om, lam, s, best, when, f_max, ppp):
    """Sample the intervals that can hold the maximum, then refine the candidates (in place)."""
    K, nl = T.shape
    coef = np.abs(s) * (np.abs(P) * Om ** order + np.abs(H) * np.abs(lam) ** order)  # (K, lanes, modes)
    bound = coef.sum(-1)
    curv = (np.abs(s) * (np.abs(P) * Om ** (order + 2) + np.abs(H) * np.abs(lam) ** (order + 2))).sum(-1)
    floor = best[name].copy()  # exact values at event instants: a lower bound of the maximum
    cands = []  # (k, lane index array, tau array, h array, value array)
    for k in range(K):
        lanes = np.flatnonzero((bound[k] > floor) & (T[k] > 0.0))
        if lanes.size == 0:
            continue
        m = int(math.ceil(T[k, lanes].max() * f_max * ppp)) + 1
        u = np.linspace(0.0, 1.0, m + 1)
        tau = u[None, :] * T[k, lanes][:, None]  # (A, m+1)
        y = np.abs(_value(P[k, lanes][:, None, :], H[k, lanes][:, None, :], Om[lanes][:, None, :],
                          lam, s, tau, order))
        i_best = y.argmax(1)
        top = y[np.arange(lanes.size), i_best]
        better = top > best[name][lanes]
        best[name][lanes[better]] = top[better]
        when[name][lanes[better]] = t0[k, lanes[better]] + tau[better, i_best[better]]
        # sampled local maxima (ends compare with their single neighbour)
        left = np.concatenate([np.full((lanes.size, 1), -np.inf), y[:, :-1]], 1)
        right = np.concatenate([y[:, 1:], np.full((lanes.size, 1), -np.inf)], 1)
        loc = (y >= left) & (y >= right)
        h = T[k, lanes] / m
        li, ii = np.nonzero(loc)
        if li.size:
            cands.append((k, lanes[li], tau[li, ii], h[li], y[li, ii], curv[k, lanes[li]] * h[li] ** 2 / 4.0))
    if not cands:
        return 0
    k_c = np.concatenate([np.full(c[1].size, c[0]) for c in cands])
    lane_c, tau_c, h_c, y_c, slack = (np.concatenate([c[i] for c in cands]) for i in range(1, 6))
    keep = y_c + slack >= best[name][lane_c]
    k_c, lane_c, tau_c, h_c = k_c[keep], lane_c[keep], tau_c[keep], h_c[keep]
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
    top = np.full(best[name].size, -np.inf)
    np.maximum.at(top, lane_c, val)
    better = top > best[name]
    for ln in np.flatnonzero(better):
        i = np.flatnonzero((lane_c == ln) & (val == top[ln]))[0]
        when[name][ln] = t0[k_c[i], ln] + x[i]
    best[name] = np.where(better, top, best[name])
    return int(k_c.size)


__all__ = ["Envelope", "moving_load_envelope", "check_mode_count", "check_frequency_limit_hz",
           "MAX_FREE_PERIODS"]
