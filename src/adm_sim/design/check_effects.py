"""Every load effect EN 1991-2 6.4.6.5(3) asks for on a simply supported span: the bending moment
and the shear along the span and the support reactions, dynamic (moving loads, modal beam) and
static, their dynamic increment φ'_dyn (Eq. 6.14) and the design comparison with Φ x α x LM71.

Modal truncation. A modal sum converges like ``1/j^2`` for the moment and like ``1/j`` for the
shear and the reactions (the static shear of a point force is a jump, its sine series converges
slowly), so dividing a truncated dynamic maximum by a truncated static one does not remove the
truncation: on B1 HSLM-A9 gives φ'_M = 0.482 with 3 modes, 0.513 with 5, 0.528 with 9. Here every
effect is computed by the **mode-acceleration method** (static correction): the exact static
effect (influence lines, every mode) plus, for the modes kept, the difference between the dynamic
and the quasi-static modal coordinate,

    R(t) = R_stat(s) + sum_j w_j (q_j(t) - q_j^stat(t)),    q_j^stat = F_j(t) / K_j,

``w_j`` the modal weight of the effect: ``EJ (j pi/L)^2 sin(j pi x/L)`` for the moment at x,
``EJ (j pi/L)^3 cos(j pi x/L)`` for the shear at x (positive as the left reaction:
``V(0) = R_A``, ``V(L) = -R_B``). The higher modes then enter by their static part, which is all
they carry below their resonance. The number of dynamic modes is printed; ``docs/check.md``
shows the convergence for 3, 5, 9 and 15 modes.

Time. ``q_j`` is the exact closed form of :mod:`adm_sim.integrate.envelope` (event to event), sampled at
every position of the first axle on a grid of ``L / samples_per_span`` plus every position where an
axle crosses a support or a section (either side of it, where the static effect has its kinks and
jumps), and over 1.25 fundamental periods of the free vibration after the last axle has left. The
static effects are piecewise linear in the load position, so their maxima over these points are
exact; the dynamic part is sampled (``tests/design/test_check_effects.py`` halves the step: 2e-4).

Sections: x/L = 0, 0.1, ..., 1 for the shear (the ends are the support reactions R_A and R_B),
0.1 .. 0.9 for the moment (zero at the supports).

LM71 (EN 1991-2 6.3.2, Fig. 6.2): four 250 kN axles at 1.6 m and 80 kN/m outside their 6.4 m
window, the distributed load only where it is unfavourable (6.3.2(1): on the part of the influence
line of the sign that is being maximised), times α; the exact maximum over the position of the
group (the effect is piecewise quadratic in it: breakpoints plus a fine grid, 1e-6 relative).

numpy only; no ROS.
"""

from __future__ import annotations

import cmath
import functools
import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

from adm_sim.integrate._jit import njit
from adm_sim.integrate.envelope import _events, propagate
from adm_sim.design.design_loads import (CACHE_SIZE, LM71_AXLE_LOAD_N, LM71_AXLES_M, LM71_HALF_WINDOW_M, LM71_UDL_N_M,
                                  array_from_key, array_key, phi_dyn_prime, read_only)

#: Sections of the shear (x/L); the ends are the support reactions.
SHEAR_SECTIONS = tuple(np.round(np.linspace(0.0, 1.0, 11), 10))
#: Sections of the moment (x/L).
MOMENT_SECTIONS = tuple(np.round(np.linspace(0.1, 0.9, 9), 10))
#: Free vibration followed after the last axle, in fundamental periods.
FREE_PERIODS = 1.25
#: Pass 1 (speeds 1 km/h apart): uniform samples per span; pass 2 refines the speeds near those whose
#: pass-1 maximum of any effect is within COARSE_MARGIN of that effect's largest (sampling lowers a maximum by less
#: than 1 % at 20 per span on B1, see tests/design/test_check_effects.py).
COARSE_SAMPLES_PER_SPAN = 20
COARSE_MARGIN = 0.015
#: Pass 1 takes speeds at least this far apart (km/h); pass 2 every speed within it of a candidate.
COARSE_STEP_KMH = 1.0
#: One-sided offset (fraction of L) at a section, where the shear jumps.
_EPS = 1e-9


@dataclass(frozen=True)
class Effect:
    """One load effect at one section: ``kind`` "M" (N m), "V" (N), "RA" or "RB" (N); ``x_m``."""

    kind: str
    x_m: float

    @property
    def label(self):
        return {"RA": "reaction A", "RB": "reaction B"}.get(self.kind, f"{self.kind}({self.x_m:.4g} m)")


def effects_of(span_m):
    """The effects of 6.4.6.5(3) on a simply supported span, in print order."""
    out = [Effect("RA", 0.0), Effect("RB", span_m)]
    out += [Effect("M", f * span_m) for f in MOMENT_SECTIONS]
    out += [Effect("V", f * span_m) for f in SHEAR_SECTIONS if 0.0 < f < 1.0]
    return out


def _line(e, L, u):
    """Influence ordinate of effect ``e`` for a unit force at ``u`` (any shape, m from the left
    support), without the off-span zero. Shear just right of the section for u > x, left for u < x."""
    x = e.x_m
    if e.kind == "RA":
        return (L - u) / L
    if e.kind == "RB":
        return u / L
    if e.kind == "M":
        return np.where(u <= x, u * (L - x) / L, x * (L - u) / L)
    return np.where(u > x, (L - u) / L, -u / L)


def _influence(effects, L, u):
    """Static influence of a unit force at ``u`` (m from the left support), shape (len(u), n_effects);
    zero off the span (:func:`_line`)."""
    u = np.asarray(u, dtype=float)[:, None]
    on = (u >= 0.0) & (u <= L)
    return np.where(on, np.concatenate([_line(e, L, u) for e in effects], axis=1), 0.0)


def modal_weights(effects, L, EJ, jj):
    """Weights w_j (n_modes, n_effects): the effect is ``sum_j w_j q_j``."""
    k = jj * np.pi / L
    cols = []
    for e in effects:
        if e.kind == "M":
            cols.append(EJ * k**2 * np.sin(k * e.x_m))
        elif e.kind == "V":
            cols.append(EJ * k**3 * np.cos(k * e.x_m))
        elif e.kind == "RA":
            cols.append(EJ * k**3)
        else:
            cols.append(-EJ * k**3 * np.cos(k * L))
    return np.stack(cols, axis=1)


#: Effect kinds as the kernel :func:`_static_sum` numbers them.
_KINDS = {"RA": 0, "RB": 1, "M": 2, "V": 3}


def _static(effects, L, s, offsets, loads):
    """Exact static effects of the axles at every front-axle position s, shape (len(s), n_effects):
    the influence ordinates of :func:`_line` summed over the axles on the span (:func:`_static_sum`)."""
    kind = np.array([_KINDS[e.kind] for e in effects], dtype=np.int64)
    xs = np.array([e.x_m for e in effects], dtype=float)
    out = np.zeros((s.size, len(effects)))
    _static_sum(kind, xs, float(L), np.ascontiguousarray(s, dtype=float), np.ascontiguousarray(offsets, dtype=float),
                np.ascontiguousarray(loads, dtype=float), out)
    return out


@njit(cache=True, nogil=True)
def _static_sum(kind, xs, L, s, offsets, loads, out):
    """out[i, e] += sum over the axles a on the span (0 <= u <= L, u = s_i - offset_a) of load_a times
    the ordinate of :func:`_line` (kind 0 R_A, 1 R_B, 2 M at xs[e], 3 V at xs[e])."""
    for i in range(s.size):
        for a in range(offsets.size):
            u = s[i] - offsets[a]
            if u < 0.0 or u > L:
                continue
            P = loads[a]
            for e in range(kind.size):
                k = kind[e]
                x = xs[e]
                if k == 0:
                    y = (L - u) / L
                elif k == 1:
                    y = u / L
                elif k == 2:
                    y = u * (L - x) / L if u <= x else x * (L - u) / L
                else:
                    y = (L - u) / L if u > x else -u / L
                out[i, e] += P * y


@njit(cache=True, nogil=True)
def midspan_modal_sum(s, offsets, loads, L, jj, gain, mgain, w, m):
    """w[i] += F_a sum_j gain_j sin(j pi x / L), m[i] likewise with ``mgain``, x = s_i - offset_a, over
    the axles on the span (0 <= x <= L): the static midspan deflection and moment on the modes
    (:func:`adm_sim.design.check.static_midspan_max`)."""
    for a in range(offsets.size):
        F = loads[a]
        for i in range(s.size):
            x = s[i] - offsets[a]
            if x < 0.0 or x > L:
                continue
            tw = 0.0
            tm = 0.0
            for j in range(jj.size):
                sh = math.sin(x * jj[j] * math.pi / L)
                tw += sh * gain[j]
                tm += sh * mgain[j]
            w[i] += F * tw
            m[i] += F * tm


def _positions(offsets, L, effects, samples_per_span):
    """Front-axle positions s (m) of the samples: a uniform grid plus every kink and jump."""
    end = offsets[-1] + L
    h = L / samples_per_span
    s = [np.arange(0.0, end + 0.5 * h, h)]
    xs = np.unique([e.x_m for e in effects] + [0.0, L])
    eps = _EPS * L
    for x in xs:
        s.append(offsets + x - eps)
        s.append(offsets + x + eps)
    s = np.concatenate(s)
    return np.unique(s[(s >= 0.0) & (s <= end)])


def _sample_statics(effects, L, offs, loads, bps, jj, n_per_span):
    """Per sample of the front-axle position (:func:`_positions`): its interval ``k_of`` between the
    breakpoints ``bps``, its offset ``ds`` in it, ``E1 = e^(i j pi ds / L)`` (samples, modes) and the
    exact static effects (samples, effects). Cached (a check with mass or stiffness bounds samples every
    train once per bound; these do not depend on the bridge's mass or stiffness); the arrays are shared
    and read-only."""
    return _sample_statics_cached(tuple(effects), float(L), array_key(offs), array_key(loads), array_key(bps),
                                  array_key(jj), int(n_per_span))


@functools.lru_cache(maxsize=CACHE_SIZE)
def _sample_statics_cached(effects, L, offs_key, loads_key, bps_key, jj_key, n_per_span):
    """:func:`_sample_statics` of its keys (:func:`adm_sim.design.design_loads.array_key`), read-only arrays."""
    offs, loads, bps, jj = (np.array(array_from_key(k)) for k in (offs_key, loads_key, bps_key, jj_key))
    s = _positions(offs, L, effects, n_per_span)
    infl = _static(effects, L, s, offs, loads)
    k_of = np.clip(np.searchsorted(bps, s, side="right") - 1, 0, bps.size - 2)
    ds = s - bps[k_of]
    E1 = np.exp(1j * np.pi * np.outer(ds, jj) / L)  # speed independent (samples, modes)
    return read_only(k_of, ds, E1, infl)


@dataclass
class EffectsResult:
    """Per effect: the largest static value of the train (exact), the largest dynamic value over the
    speeds and the speed where it occurs; φ'_dyn = dyn / stat - 1 (EN 1991-2 Eq. 6.14)."""

    effects: list
    static_max: np.ndarray  # (n_effects,) N m or N
    dynamic_max: np.ndarray  # (n_effects,)
    at_speed_kmh: np.ndarray  # (n_effects,)
    n_modes: int
    static_correction: bool
    span_m: float = 0.0

    @cached_property
    def phi_dyn(self):
        """φ'_dyn per effect, ``(n_effects,)`` (:func:`adm_sim.design.design_loads.phi_dyn_prime`; computed once)."""
        return np.array([phi_dyn_prime(d, s) for d, s in zip(self.dynamic_max, self.static_max)])


@njit(cache=True, nogil=True)
def _exp_modes(lam, tau, squares, re, im):
    """re + i im = e^(lam_j tau) for every mode j. ``squares``: lam_j = (j + 1)^2 lam_0 (modes 1, 2, ..
    with one ζ: the simply supported beam's omega_j = j^2 omega_1), so one complex exponential and two
    products per further mode, z^(j^2) = z^((j-1)^2) z^(2j-1) (equal to the exponentials to 1e-15
    relative); else one exponential per mode."""
    if squares:
        z = cmath.exp(lam[0] * tau)
        z2 = z * z
        odd = z  # z^(2j - 1)
        p = z
        re[0] = p.real
        im[0] = p.imag
        for j in range(1, lam.size):
            odd = odd * z2
            p = p * odd
            re[j] = p.real
            im[j] = p.imag
    else:
        for j in range(lam.size):
            z = cmath.exp(lam[j] * tau)
            re[j] = z.real
            im[j] = z.imag


def _modes_are_squares(jj, lam):
    """True when the modes are 1, 2, .. n and lam_j = j^2 lam_1 to 1e-12 (one ζ on every mode):
    :func:`_exp_modes` may then raise one exponential to the powers j^2."""
    n = jj.size
    return bool(np.array_equal(jj, np.arange(1, n + 1)) and
                np.all(np.abs(lam - jj**2 * lam[0]) <= 1e-12 * np.abs(lam)))


@njit(cache=True, nogil=True)
def _step_plan(k_of, ds):
    """How :func:`_scan` advances ``e^(lam tau)`` from sample to sample, the same for every lane:
    ``plan[i]`` is -2 where sample ``i`` starts an interval (the exponentials of its offset ``ds_i``
    computed afresh), -1 where the step ``h = ds_i - ds_(i-1)`` repeats the last one taken (within 1e-12
    relative), else the index in ``steps`` of the step the sample takes (``h`` itself). ``steps`` holds the
    distinct steps taken, bit for bit: a train's samples step by a few lengths (its axle spacings and
    sections; 47-82 distinct steps of about 1450 taken on B1 at 20 samples a span), so each lane computes
    the exponentials of each once, the same function of the same value as at every sample before."""
    ns = k_of.size
    plan = np.empty(ns, np.int64)
    hs = np.empty(ns)
    n = 0
    last_k = -1
    last_ds = 0.0
    last_h = -1.0
    for i in range(ns):
        k = k_of[i]
        d = ds[i]
        if k != last_k:
            plan[i] = -2
            last_h = -1.0
        else:
            h = d - last_ds
            if abs(h - last_h) > 1e-12 * (1.0 + abs(h)):
                hs[n] = h
                plan[i] = n
                n += 1
                last_h = h
            else:
                plan[i] = -1
        last_k = k
        last_ds = d
    # distinct by their bits, not by value, in the order first taken: a linear search among the few
    # found so far (np.unique and np.searchsorted give the same steps sorted, and cost 3-6 s of the first
    # compile; the order of ``steps`` changes no number)
    taken = hs[:n].view(np.int64)
    bits = np.empty(n, np.int64)
    where = np.empty(n, np.int64)
    nu = 0
    for a in range(n):
        u = 0
        while u < nu and bits[u] != taken[a]:
            u += 1
        if u == nu:
            bits[nu] = taken[a]
            nu += 1
        where[a] = u
    for i in range(ns):
        if plan[i] >= 0:
            plan[i] = where[plan[i]]
    return plan, bits[:nu].view(np.float64)


@njit(cache=True, nogil=True)
def _scan(k_of, ds, E1, P, H, lam, v, WT, base, best, squares):
    """best[l, e] = max over samples i of |base[i, e] + sum_j WT[j, e] q_j(i, l)|, with
    q_j = Im[P[k, l, j] E1[i, j]] + Im[H[k, l, j] e^(lam_j ds_i / v_l)], k = k_of[i]. Along the
    samples of one interval e^(lam tau) is advanced by multiplication where the step repeats
    (``squares``: :func:`_exp_modes`); the exponentials of every distinct step are computed once per
    lane (:func:`_step_plan`). The sum over the modes runs for all effects at once (a loop over
    the effects innermost, contiguous in ``WT`` (modes, effects), which the compiler vectorises); every
    effect's sum is still ``base + w_1 q_1 + w_2 q_2 + ...`` in that order."""
    ns = k_of.size
    nm = lam.size
    ne = WT.shape[1]
    plan, steps = _step_plan(k_of, ds)
    sr = np.empty((steps.size, nm))
    si = np.empty((steps.size, nm))
    eLr = np.empty(nm)
    eLi = np.empty(nm)
    qd = np.empty(nm)
    y = np.empty(ne)
    top = np.empty(ne)
    for l in range(v.size):
        inv_v = 1.0 / v[l]
        for u in range(steps.size):
            _exp_modes(lam, steps[u] * inv_v, squares, sr[u], si[u])
        u = 0
        for e in range(ne):
            top[e] = best[l, e]
        for i in range(ns):
            k = k_of[i]
            if plan[i] == -2:
                _exp_modes(lam, ds[i] * inv_v, squares, eLr, eLi)
            else:
                if plan[i] >= 0:
                    u = plan[i]
                for j in range(nm):
                    r = eLr[j] * sr[u, j] - eLi[j] * si[u, j]
                    eLi[j] = eLr[j] * si[u, j] + eLi[j] * sr[u, j]
                    eLr[j] = r
            for j in range(nm):
                p = P[k, l, j]
                e1 = E1[i, j]
                hh = H[k, l, j]
                qd[j] = p.real * e1.imag + p.imag * e1.real + hh.real * eLi[j] + hh.imag * eLr[j]
            for e in range(ne):
                y[e] = base[i, e]
            for j in range(nm):
                w = qd[j]
                for e in range(ne):
                    y[e] += WT[j, e] * w
            for e in range(ne):
                a = abs(y[e])
                top[e] = a if a > top[e] else top[e]
        for e in range(ne):
            best[l, e] = top[e]


def train_effects(bridge, axle_offsets_m, axle_loads_n, speeds_kmh, delta_zeta=0.0, effects=None,
                  static_correction=True, samples_per_span=100, intervals=None):
    """Largest static and dynamic value of every effect of ``effects`` (default :func:`effects_of`).

    Parameters
    ----------
    bridge : adm_sim.model.bridge.Bridge
        Its modes and ``modal_damping_ratios(delta_zeta)``.
    axle_offsets_m, axle_loads_n : array_like (n_axles,)
    speeds_kmh : array_like (n_speeds,)
    static_correction : bool
        The mode-acceleration method (default); ``False`` sums the modes alone (to show the
        truncation).
    samples_per_span : int
        Uniform samples of the front-axle position per span length (kinks and jumps added).
    intervals : adm_sim.integrate.envelope.LaneIntervals, optional
        The coefficients of these lanes from :func:`adm_sim.integrate.envelope.moving_load_envelope`
        (``keep_intervals=True``, the same bridge, axles and speeds in this order), used instead of
        propagating the lanes again when they were computed with the same damping ratio of every mode
        (the same numbers: the same operations on the same values).

    Returns
    -------
    EffectsResult
    """
    L = bridge.span_m
    effects = effects_of(L) if effects is None else list(effects)
    lanes = _lanes(bridge, axle_offsets_m, axle_loads_n, speeds_kmh, delta_zeta, effects, intervals)
    WT = np.ascontiguousarray(lanes.W)  # (modes, effects)
    # free vibration after the last exit: q = Im[H_K e^(lam t)], static part zero (every speed, cheap)
    T1 = 2.0 * np.pi / lanes.om[0]
    t_free = np.linspace(0.0, FREE_PERIODS * T1, 64)
    qf = (lanes.H[-1][None] * np.exp(lanes.lam[None, None, :] * t_free[:, None, None])).imag  # (t, lanes, modes)
    free = np.abs(qf @ lanes.W).max(0)  # (lanes, effects)
    # pass 1: speeds at least COARSE_STEP_KMH apart, coarse positions; pass 2: fine positions at every
    # speed within COARSE_STEP_KMH of a pass-1 speed whose value of some effect is within COARSE_MARGIN
    # of that effect's largest
    kmh = 3.6 * lanes.v
    sel = _coarse_speeds(kmh)
    coarse, _ = _scan_lanes(lanes, sel, WT, COARSE_SAMPLES_PER_SPAN, static_correction)
    coarse = np.maximum(coarse, free[sel])
    cand = sel[(coarse >= (1.0 - COARSE_MARGIN) * coarse.max(0)[None, :]).any(1)]
    keep = np.nonzero((np.abs(kmh[:, None] - kmh[cand][None, :]) <= COARSE_STEP_KMH + 1e-9).any(1))[0]
    fine, static_max = _scan_lanes(lanes, keep, WT, samples_per_span, static_correction)
    best = free.copy()
    best[sel] = np.maximum(best[sel], coarse)
    best[keep] = np.maximum(best[keep], fine)
    i = best.argmax(0)
    dyn_max = best[i, np.arange(len(effects))]
    at = 3.6 * lanes.v[i]
    return EffectsResult(effects=effects, static_max=static_max, dynamic_max=dyn_max, at_speed_kmh=at,
                         n_modes=int(lanes.jj.size), static_correction=bool(static_correction), span_m=float(L))


class _Lanes(NamedTuple):
    """What :func:`train_effects` samples: the bridge's modes, the axles, every lane's closed-form
    coefficients ``P``, ``H`` (K, lanes, modes) and the modal weights ``W`` (modes, effects)."""

    L: float
    effects: list
    offs: np.ndarray
    loads: np.ndarray
    v: np.ndarray  #: (lanes,) m/s
    jj: np.ndarray
    om: np.ndarray
    lam: np.ndarray
    W: np.ndarray
    squares: bool
    bps: np.ndarray
    Gk: np.ndarray  #: (K, modes) modal force per mass at each interval start
    P: np.ndarray
    H: np.ndarray


def _lanes(bridge, axle_offsets_m, axle_loads_n, speeds_kmh, delta_zeta, effects, intervals):
    """The modes, axles, weights and every lane's coefficients (:class:`_Lanes`): ``intervals`` when
    they were computed with the same damping ratio of every mode, else propagated from event to event."""
    L, EJ = bridge.span_m, bridge.EJ_Nm2
    offs = np.asarray(axle_offsets_m, dtype=float)
    loads = np.asarray(axle_loads_n, dtype=float)
    v = np.atleast_1d(np.asarray(speeds_kmh, dtype=float)) / 3.6
    jj = bridge.mode_numbers.astype(float)
    om = bridge.omega_rad_s
    zeta = np.asarray(bridge.modal_damping_ratios(delta_zeta))
    mass = bridge.modal_mass_kg
    lam = -zeta * om + 1j * om * np.sqrt(1.0 - zeta**2)
    W = modal_weights(effects, L, EJ, jj)  # (modes, effects)
    squares = _modes_are_squares(jj, lam)
    bps, G = _events(offs, loads, L, jj, mass[0])
    G = G * (mass[0] / mass)
    Gk = G * np.exp(1j * np.pi * np.outer(bps, jj) / L)  # modal force per mass at each interval start
    if (intervals is not None and tuple(float(z) for z in zeta) == tuple(intervals.zeta)
            and intervals.P.shape == (bps.size, v.size, jj.size)):
        P, H = intervals.P, intervals.H
    else:
        P, H = _propagate(Gk, bps, v, jj, om, zeta, lam, L)
    return _Lanes(L=L, effects=effects, offs=offs, loads=loads, v=v, jj=jj, om=om, lam=lam, W=W, squares=squares,
                  bps=bps, Gk=Gk, P=P, H=H)


def _propagate(Gk, bps, v, jj, om, zeta, lam, L):
    """``P``, ``H`` (K, lanes, modes) of every lane, from event to event (the closed form of
    :mod:`adm_sim.integrate.envelope`, its :func:`~adm_sim.integrate.envelope.propagate`)."""
    Om = jj[None, :] * np.pi * v[:, None] / L  # (lanes, modes)
    dyn = 1.0 / (om**2 - Om**2 + 2j * zeta * om * Om)
    P = Gk[:, None, :] * dyn[None]  # (K, lanes, modes)
    lengths = np.diff(bps)
    return P, propagate(P, Om, lam, lengths[:, None] / v[None, :], lengths)


def _coarse_speeds(kmh):
    """Indices (sorted) of the speeds of pass 1: in increasing speed, each at least COARSE_STEP_KMH above
    the last one taken."""
    sel, last = [], -np.inf
    for i in np.argsort(kmh, kind="stable"):
        if kmh[i] >= last + COARSE_STEP_KMH - 1e-9:
            sel.append(i)
            last = kmh[i]
    return np.sort(np.asarray(sel, dtype=np.int64))


def _scan_lanes(lanes, idx, WT, n_per_span, static_correction):
    """Largest |effect| (len(idx), effects) over the samples of ``n_per_span`` per span (:func:`_positions`)
    of the lanes ``idx``, and the largest static value of every effect over the same samples."""
    k_of, ds, E1, infl = _sample_statics(lanes.effects, lanes.L, lanes.offs, lanes.loads, lanes.bps, lanes.jj,
                                         n_per_span)
    k_of, ds, E1 = np.array(k_of), np.array(ds), np.array(E1)  # writable: the kernel's compiled types
    q_stat = (lanes.Gk[k_of] * E1).imag / lanes.om**2  # q_j^stat at every sample
    base = infl - q_stat @ lanes.W if static_correction else np.zeros_like(infl)
    out = np.zeros((idx.size, len(lanes.effects)))
    _scan(k_of, ds, E1, np.ascontiguousarray(lanes.P[:, idx]), np.ascontiguousarray(lanes.H[:, idx]), lanes.lam,
          lanes.v[idx], WT, np.ascontiguousarray(base), out, lanes.squares)
    return out, np.abs(infl).max(0)


# ---------------------------------------------------------------------- LM71 per effect
def _integral(effects_one, L, u0, u1):
    """Integral over [u0, u1] (clipped to the span) of the influence line of one effect, split into its
    positive and negative parts: returns (pos, neg) arrays for vectorised u0, u1."""
    e = effects_one
    # breakpoints of the piecewise linear line: 0, x, L
    x = e.x_m
    pieces = [(0.0, x), (x, L)] if e.kind in ("M", "V") else [(0.0, L)]
    pos = np.zeros(np.shape(u0))
    neg = np.zeros(np.shape(u0))
    for p0, p1 in pieces:
        a = np.clip(u0, p0, p1)
        b = np.clip(u1, p0, p1)
        # a line on the piece: value at its ends (one-sided), integrate exactly (trapezoid of a line)
        f0 = _influence([e], L, [p0 + (_EPS * L if p0 == x else 0.0)])[0, 0]
        f1 = _influence([e], L, [p1 - (_EPS * L if p1 == x else 0.0)])[0, 0]
        slope = (f1 - f0) / (p1 - p0) if p1 > p0 else 0.0
        fa = f0 + slope * (a - p0)
        fb = f0 + slope * (b - p0)
        val = 0.5 * (fa + fb) * (b - a)
        # a piece of a line changes sign at most once; the lines here keep one sign on each piece
        pos += np.where(val > 0.0, val, 0.0)
        neg += np.where(val < 0.0, val, 0.0)
    return pos, neg


def lm71_effect_max(effect, span_m, alpha=1.0, n_grid=4000):
    """Largest |effect| of α x LM71 (N m or N), the distributed load on the unfavourable part of the
    influence line only (EN 1991-2 6.3.2(1)): max over the group position of both signs."""
    L = span_m
    c = np.asarray(LM71_AXLES_M)
    hw = LM71_HALF_WINDOW_M
    x = effect.x_m
    bps = np.array([0.0, x - _EPS * L, x + _EPS * L, L])
    d = np.concatenate([np.linspace(-hw, L + hw, n_grid), (bps[:, None] - c[None, :]).ravel(),
                        bps - hw, bps + hw])
    d = np.unique(d)
    pts = LM71_AXLE_LOAD_N * _influence([effect], L, (d[:, None] + c[None, :]).ravel())[:, 0].reshape(d.size, c.size)
    # distributed load: the whole span minus the window, the favourable part left off
    pos_all, neg_all = _integral(effect, L, np.full(d.shape, 0.0), np.full(d.shape, L))
    pos_w, neg_w = _integral(effect, L, d - hw, d + hw)
    up = pts.sum(1) + LM71_UDL_N_M * (pos_all - pos_w)
    down = pts.sum(1) + LM71_UDL_N_M * (neg_all - neg_w)
    return float(alpha * max(up.max(), -down.min()))


@dataclass(frozen=True)
class EffectComparison:
    """EN 1991-2 6.4.6.5(3) for one effect: ``(1 + φ'_dyn + r φ'') x train`` vs ``Φ x α x LM71``."""

    effect: Effect
    phi_dyn: float
    phi_dd_factor: float  # r: 1/2 careful, 1 standard maintenance (Annex C: 1 + φ' + φ''/2, 1 + φ' + φ'')
    phi_dd: float
    Phi: float
    train_static: float
    lm71_static: float  # α included

    @property
    def train_design(self):
        return (1.0 + self.phi_dyn + self.phi_dd_factor * self.phi_dd) * self.train_static

    @property
    def lm71_design(self):
        return self.Phi * self.lm71_static

    @property
    def ratio(self):
        return self.train_design / self.lm71_design


def lm71_effects(span_m, alpha, effects=None):
    """α x LM71 static maximum of every effect, ``(n_effects,)`` (cached per span, α and effects; the
    array is shared and read-only)."""
    effects = tuple(effects_of(span_m) if effects is None else effects)
    return _lm71_effects_cached(float(span_m), float(alpha), effects)


@functools.lru_cache(maxsize=CACHE_SIZE)
def _lm71_effects_cached(span_m, alpha, effects):
    """:func:`lm71_effects`, read-only (shared by every caller)."""
    return read_only(np.array([lm71_effect_max(e, span_m, alpha) for e in effects]))
