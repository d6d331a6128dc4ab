"""Exact moving-load envelopes: max acceleration and deflection per speed, at midspan, at a given
point or anywhere on the deck, and the max midspan bending moment, to round-off.

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
At a point x: ``w = sum_j q_j sin(j pi x / L)`` (Eq. 4), ``a = sum_j q_j'' sin(j pi x / L)``; the
midspan bending moment is ``M = EJ sum_j q_j (j pi / L)^2 sin(j pi / 2)`` (= -EJ w'').

Where (``where=``):

* ``"midspan"``: x = L/2; even modes do not move midspan and are skipped.
* a number x (m, 0 < x < L): every mode.
* ``"deck"``: the largest |a| (and |w|) over every x in [0, L] and every time, with its position,
  every mode included. Since ``sin(j pi (L - x) / L) = (-1)^(j+1) sin(j pi x / L)``, the pair
  {x, L - x} is searched at once: ``max(|a(x)|, |a(L - x)|) = |a_odd(x)| + |a_even(x)|`` (odd- and
  even-mode parts), on a grid of positions x_p = p L / (2 n_x), p = 1 .. n_x, with
  ``n_x = max(2, ceil(samples_per_period * j_max / 4))``, i.e. at least ``samples_per_period``
  positions per wavelength 2 L / j_max of the highest mode. All positions share one pruning bound
  per quantity (``|sin| <= 1``); every sampled (t, x) local maximum (not below its neighbours in
  t and in x) that can still hold the maximum (its value plus ``max|a_tt| h^2 / 4`` over the
  interval plus ``h_x^2 / 8 sum_j (j pi / L)^2 |a_j(t)|`` at the sample reaches the best) is kept;
  after every interval has been sampled the candidates are refined, the largest sample first, each
  only if it can still reach the best, jointly in (t, x) by Newton's method on ``grad a = 0`` with
  the analytic derivatives (box ``t +- h`` inside the interval, ``x +- 2 h_x`` inside [0, L]; at a time bound that the step pushes
  against, e.g. an event instant, Newton continues in x alone; a step that lowers |a| is halved).
  Convergence rule: the iteration stops when both steps are below 1e-12 (relative to the
  interval length and to L) or after :data:`NEWTON_ITERATIONS_2D`; the value is then exact to
  round-off and the position to about 1e-6 L (the maximum is flat in x: a position error d costs
  only ``|a_xx| d^2 / 2``). ``tests/integrate/test_envelope.py`` checks both against an independent brute
  force (closed form per axle, dense t and x grids, zooming grids): values to 1e-9, positions to
  1e-4 L (B1, B4; 3 and 5 modes); 4 and 16 samples per period agree to 1e-10 and 1e-6 L.

Maximum between samples (one-position quantities: midspan, a point, the midspan moment): every interval is sampled at ``samples_per_period``
points per period of the fastest component; each sampled local maximum of ``|a|`` (``|w|``,
``|M|``) that can still hold the maximum (its value plus the curvature bound ``max|a''| h^2 / 4``
reaches the best sample) is refined by Newton's method on ``a'(tau) = 0`` inside its two-sample
bracket, with the analytic derivatives. Event instants, where ``a'`` has kinks, are candidates
too. Intervals whose amplitude bound ``sum |coefficients|`` cannot reach the largest value at the
event instants are not sampled at all, and every interval is pruned again against the maximum
found so far before it is sampled (largest bounds first). The free vibration is followed until
its decaying bound drops below the largest value found at an event instant (at most
:data:`MAX_FREE_PERIODS` fundamental periods). The search loop is compiled with numba (the same
search in numpy, per-interval array operations, cost 2.6-5 s for the 14-train bench case instead
of 0.4 s CPU).

Memory: the lanes (speeds) are independent, so they are computed in chunks of :func:`chunk_lanes`
speeds (:data:`CHUNK_BYTES` of coefficients, bounds and search lists), the same numbers bit for bit
whatever the chunk (``tests/integrate/test_envelope_chunks.py``); :func:`envelope_bytes` (one chunk, the
results, the coefficients kept for the effects) is checked against the memory available first.

Modes: EN 1990 A2.4.4.2.1 asks for every mode up to the larger of 30 Hz, 1.5 n0 and the third
mode's frequency (:func:`check_mode_count`). Damping per mode: ``bridge.modal_damping_ratios``
(Rayleigh anchored at modes 1 and 3, or equal ``"modal"`` damping, see :mod:`adm_sim.model.bridge`).
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from adm_sim.integrate._jit import njit  # numba compiles the search loop; without it the same source runs as plain Python
from adm_sim.errors import InputError
from adm_sim.fields import check_delta_zeta_fraction, check_range
from adm_sim.limits import check_memory
from adm_sim.integrate.step_grid import speeds_to_m_s
from adm_sim.integrate.where import WHERE_KEYWORDS, parse_where, where_text  # noqa: F401  re-exported: the envelope's positions

#: Longest free vibration followed after the last axle has left, in fundamental periods.
MAX_FREE_PERIODS = 30.0
#: Newton iterations of the refinement (quadratic convergence from within a quarter period).
NEWTON_ITERATIONS = 8
#: Largest number of joint (t, x) Newton iterations of the whole-deck refinement.
NEWTON_ITERATIONS_2D = 16
#: Memory budget of one chunk of speeds (bytes, :func:`chunk_lanes`): the exact envelope's coefficients
#: grow as speeds x events x modes (ICE-2 on B1, whole deck, 20000 speeds: 774 MiB at once, 65 MiB in
#: chunks, tracemalloc), so the speeds are taken a chunk at a time. 64 MiB (about 1100 speeds of that
#: case) keeps every bench and check case of today (277 speeds) in one chunk, and a chunk's fixed cost
#: (a few dozen numpy calls) is then far below its search (the 20000 speeds took 3.6 s CPU in chunks
#: against 5.0 s at once).
CHUNK_BYTES = 64 * 2**20
#: Deck candidates of the search per event and deck position, for the memory estimate (measured: at
#: most 0.19 on B1 and B4, 3 and 8 modes, HSLM-A1..A10 and ICE-2, 277 speeds; :func:`lane_bytes`).
CANDIDATES_PER_EVENT = 0.25


def check_frequency_limit_hz(bridge):
    """Highest frequency to include (Hz): max(30 Hz, 1.5 n0, n3), EN 1990 A2.4.4.2.1."""
    return max(30.0, 1.5 * bridge.n0_hz, 9.0 * bridge.n0_hz)


def check_mode_count(bridge, f_limit_hz=None):
    """Number of modes with ``n_j = j^2 n0 <= f_limit`` (default: :func:`check_frequency_limit_hz`)."""
    f = check_frequency_limit_hz(bridge) if f_limit_hz is None else float(f_limit_hz)
    return max(1, int(math.floor(math.sqrt(f / bridge.n0_hz) + 1e-9)))


class LaneIntervals(NamedTuple):
    """Per interval ``k``, lane and mode ``j`` the modal coordinate ``q_j = Im[P e^(i Om tau) + H e^(lam tau)]``
    (the module doc), and the damping ratio of every mode they were computed with; every mode of the bridge.
    :func:`adm_sim.design.check_effects.train_effects` takes them instead of propagating the same lanes again."""

    P: np.ndarray  #: (K, lanes, modes) complex
    H: np.ndarray  #: (K, lanes, modes) complex
    zeta: tuple  #: damping ratio of every mode (fractions)


@dataclass(frozen=True)
class Envelope:
    """Exact MLM maxima per speed.

    Attributes
    ----------
    speeds_kmh, max_acc_m_s2, max_disp_m : ndarray (n_lanes,)
        Max |acceleration| and |deflection| at ``where`` (over the whole deck for ``"deck"``).
    t_acc_s, t_disp_s : ndarray (n_lanes,)
        Time of the maxima, from the first axle's entry.
    x_acc_m, x_disp_m : ndarray (n_lanes,)
        Position of the maxima along the span (m; L/2 at midspan, x for a given position).
    max_moment_Nm, t_moment_s : ndarray (n_lanes,)
        Max |midspan bending moment| ``EJ sum_j q_j (j pi/L)^2 sin(j pi/2)`` (N m) and its time,
        whatever ``where`` (EN 1991-2 6.4.6.5).
    max_disp_midspan_m : ndarray (n_lanes,)
        Max |midspan deflection| (equals ``max_disp_m`` for ``where="midspan"``).
    where : str or float
        ``"midspan"``, ``"deck"`` or the position x (m).
    modes : tuple of int
        Modes in the calculation (all of ``bridge.n_modes``; at midspan even modes do not move).
    zeta : tuple of float
        Damping ratio of every mode used (fractions, ``bridge.modal_damping_ratios`` with Δζ).
    refined : int
        Number of candidate maxima refined by Newton's method.
    intervals : LaneIntervals or None
        The closed-form coefficients of every lane and interval, kept only when asked for
        (``keep_intervals=True``) and every mode was used (not ``"midspan"``).
    """

    speeds_kmh: np.ndarray
    max_acc_m_s2: np.ndarray
    max_disp_m: np.ndarray
    t_acc_s: np.ndarray
    t_disp_s: np.ndarray
    x_acc_m: np.ndarray
    x_disp_m: np.ndarray
    max_moment_Nm: np.ndarray
    t_moment_s: np.ndarray
    max_disp_midspan_m: np.ndarray
    where: object
    modes: tuple
    zeta: tuple
    refined: int
    intervals: LaneIntervals | None = field(default=None, repr=False, compare=False)


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


def deck_positions_m(span_m, n_modes, samples_per_period=4.0):
    """The positions x_p = p L / (2 n_x), p = 1 .. n_x, of the whole-deck search (each stands for
    x_p and L - x_p); ``n_x = max(2, ceil(samples_per_period * n_modes / 4))``."""
    n = max(2, int(math.ceil(samples_per_period * n_modes / 4.0 - 1e-9)))
    return span_m * np.arange(1, n + 1) / (2.0 * n)


def moving_load_envelope(bridge, axle_offsets_m, axle_loads_n, speeds_kmh, *, delta_zeta=0.0,
                         samples_per_period=4.0, where="midspan", keep_intervals=False, delta_zeta_name="delta_zeta",
                         positive_for="the exact envelope", remedy=""):
    """Exact max |acceleration|, |deflection| (at ``where``) and |midspan moment| at every speed.

    The speeds are computed in chunks of :func:`chunk_lanes` lanes (:data:`CHUNK_BYTES`), each lane
    as if alone, so the result is the same bit for bit whatever the chunk; the memory of the whole
    run (:func:`envelope_bytes`) is checked against this machine's before anything is allocated.

    Parameters
    ----------
    bridge : adm_sim.model.bridge.Bridge
        Modal beam; all ``bridge.n_modes`` modes are used with ``bridge.modal_damping_ratios``.
    axle_offsets_m, axle_loads_n : array_like (n_axles,)
        Axles behind the first one (m) and their loads (N).
    speeds_kmh : array_like (n_lanes,)
    delta_zeta : float
        Additional damping (fraction).
    samples_per_period : float
        Samples per period of the fastest component (and, for ``"deck"``, positions per
        wavelength of the highest mode) before refinement (4..64).
    where : {"midspan", "deck"} or float
        Midspan (default), anywhere on the deck (EN 1990 A2.4.4.2.1 limits the peak deck
        acceleration), or a position x in metres, 0 < x < L; text ``"x=<m>"`` is accepted.
    keep_intervals : bool
        Keep the coefficients of every lane and interval in ``Envelope.intervals`` (every mode used:
        not at midspan), for :func:`adm_sim.design.check_effects.train_effects` on the same lanes.
    delta_zeta_name, positive_for, remedy : str
        The refusal of ``delta_zeta`` (the closed form needs ζ + Δζ > 0): the caller's name of it
        (``delta_zeta``, a fraction; ``--delta-zeta-pct``, in %; None: the caller checked it), what
        needs the damping, a hint (:func:`adm_sim.fields.check_delta_zeta`).

    Returns
    -------
    Envelope
    """
    L, where, v_all, ppp, dz, offs, loads = _checked_inputs(bridge, axle_offsets_m, axle_loads_n, speeds_kmh,
                                                           delta_zeta, samples_per_period, where, delta_zeta_name,
                                                           positive_for, remedy)
    md = _modes(bridge, where, dz)
    bps, G = _events(offs, loads, L, md.jj, md.mass[0])  # equal modal masses mu L / 2
    G = G * (md.mass[0] / md.mass)
    quants = _quantities(bridge, where, md, ppp)
    keep = keep_intervals and md.keep.all()
    nq, pmax = len(quants), max(len(x) for _, _, x, _ in quants)
    check_memory(envelope_bytes(v_all.size, bps.size, md.jj.size, nq, pmax, keep),
                 f"the exact envelope of {v_all.size} speeds{' with its coefficients kept' if keep else ''}",
                 f"large because {v_all.size} speeds x {bps.size} axle events x {md.jj.size} modes; "
                 f"fewer speeds{' or no kept coefficients' if keep else ''} make it smaller")
    res = _chunked_lanes(v_all, L, md, bps, G, ppp, quants, keep)
    q_mid = 1 if where == "midspan" else 3
    zeta_used = tuple(float(z) for z in np.ravel(md.zeta_all))
    kept = LaneIntervals(P=res["P"], H=res["H"], zeta=zeta_used) if keep else None
    return Envelope(speeds_kmh=np.atleast_1d(np.asarray(speeds_kmh, dtype=float)).copy(),
                    max_acc_m_s2=res["best"][0], max_disp_m=res["best"][1], t_acc_s=res["when"][0],
                    t_disp_s=res["when"][1], x_acc_m=res["xat"][0], x_disp_m=res["xat"][1],
                    max_moment_Nm=res["best"][2], t_moment_s=res["when"][2],
                    max_disp_midspan_m=res["best"][q_mid].copy(), where=where,
                    modes=tuple(int(j) for j in bridge.mode_numbers), zeta=zeta_used, refined=res["refined"],
                    intervals=kept)


def _checked_inputs(bridge, axle_offsets_m, axle_loads_n, speeds_kmh, delta_zeta, samples_per_period, where,
                    delta_zeta_name, positive_for, remedy):
    """The inputs of :func:`moving_load_envelope` checked (one-line :class:`InputError` otherwise):
    ``(L, where, speeds in m/s, samples per period, Δζ, axle offsets, axle loads)``."""
    if bridge.is_continuous:
        raise InputError(f"method: the exact MLM envelope is written for the sine modes of one simply supported "
                         f"span; a continuous deck ({len(bridge.spans_m)} spans) runs RK4 (allowed --method rk4)", field="method")
    L = bridge.span_m
    where = parse_where(where, L, field="where")
    v_all = speeds_to_m_s(speeds_kmh)
    ppp = check_range("samples_per_period", samples_per_period, "-", 4.0, 64.0)
    # the closed form divides by the damping at resonance: zeta + delta_zeta > 0
    if delta_zeta_name is not None:  # None: the caller checked it (adm_sim.integrate.sweep.lane_damping)
        check_delta_zeta_fraction(delta_zeta_name, float(delta_zeta), bridge.damping_ratio,
                                  positive_for=positive_for, remedy=remedy)
    dz = (100.0 * float(delta_zeta)) / 100.0  # through % as before: the envelope's numbers bit for bit
    offs = np.asarray(axle_offsets_m, dtype=float)
    loads = np.asarray(axle_loads_n, dtype=float)
    if offs.ndim != 1 or offs.shape != loads.shape or offs.size == 0:
        raise InputError("axles: offsets (m) and loads (N) need the same non-zero length")
    return L, where, v_all, ppp, dz, offs, loads


class _Modes(NamedTuple):
    """The modes of the search (every mode, or the odd ones at midspan) and their constants."""

    keep: np.ndarray  #: (all modes,) bool: the mode is searched
    jj: np.ndarray  #: (modes,) mode numbers
    s: np.ndarray  #: (modes,) sin(j pi / 2)
    s_mid: np.ndarray  #: (modes,) sin(j pi / 2), exactly 0 for even modes
    om: np.ndarray  #: (modes,) natural circular frequencies (rad/s)
    zeta_all: np.ndarray  #: (all modes,) damping ratios with Δζ (fractions)
    zeta: np.ndarray  #: (modes,)
    mass: np.ndarray  #: (modes,) modal masses (kg)
    lam: np.ndarray  #: (modes,) complex eigenvalues (1/s)


def _modes(bridge, where, dz):
    """:class:`_Modes` of ``bridge`` at ``where`` with the additional damping ``dz`` (fraction)."""
    jall = bridge.mode_numbers
    s_all = np.sin(jall * np.pi / 2.0)
    keep = np.abs(s_all) > 0.5 if where == "midspan" else np.ones(jall.size, dtype=bool)
    jj, s = jall[keep], s_all[keep]
    om = bridge.omega_rad_s[keep]
    zeta_all = np.asarray(bridge.modal_damping_ratios(dz))
    zeta = zeta_all[keep]
    lam = -zeta * om + 1j * om * np.sqrt(1.0 - zeta**2)
    return _Modes(keep=keep, jj=jj, s=s, s_mid=np.where(np.abs(s) > 0.5, s, 0.0), om=om, zeta_all=zeta_all,
                  zeta=zeta, mass=bridge.modal_mass_kg[keep], lam=lam)


def _quantities(bridge, where, md, ppp):
    """The searched quantities: ``(family 0 = acceleration / 1 = deflection, weights (positions, modes),
    positions, deck?)``; the moment and (but at midspan) the midspan deflection third and fourth."""
    L = bridge.span_m
    jj, s, s_mid = md.jj, md.s, md.s_mid
    kw = jj * np.pi / L
    moment_w = bridge.EJ_Nm2 * kw**2 * s_mid
    if where == "midspan":
        return [(0, s[None, :], [0.5 * L], False), (1, s[None, :], [0.5 * L], False),
                (1, moment_w[None, :], [0.5 * L], False)]
    if where == "deck":
        xg = deck_positions_m(L, int(jj.max()), ppp)
        shapes = np.sin(np.outer(xg, kw))
        return [(0, shapes, xg, True), (1, shapes, xg, True), (1, moment_w[None, :], [0.5 * L], False),
                (1, s_mid[None, :], [0.5 * L], False)]
    sx = np.sin(kw * where)
    return [(0, sx[None, :], [where], False), (1, sx[None, :], [where], False),
            (1, moment_w[None, :], [0.5 * L], False), (1, s_mid[None, :], [0.5 * L], False)]


def lane_bytes(n_events, n_modes, n_quantities, n_positions):
    """Peak memory of one lane (speed) in a chunk of :func:`_all_lanes` (bytes): the four coefficient
    arrays (acceleration and deflection, forced and free) ``4 x 16 K n_modes``, the bounds of the
    value and of the curvature ``2 x 8 K n_quantities``, the interval starts and lengths ``2 x 8 K``,
    the largest temporaries (the ratio of the bounds ``8 K n_quantities``, the pair lists and their
    order, at most ``8 x 8 K``), the per-mode rows (``24 x 16 n_modes``), and the search's deck
    candidates (:data:`CANDIDATES_PER_EVENT` per event and position, 72 bytes each, up to three times
    over while their list doubles); ``K = n_events``."""
    K, nm, nq = float(n_events), float(n_modes), float(n_quantities)
    candidates = CANDIDATES_PER_EVENT * K * float(n_positions) * 72.0 * 3.0
    return 64.0 * K * nm + 16.0 * K * nq + 16.0 * K + 8.0 * K * nq + 64.0 * K + 24.0 * 16.0 * nm + candidates


def chunk_lanes(n_events, n_modes, n_quantities, n_positions):
    """Lanes per chunk: as many as fit :data:`CHUNK_BYTES` (:func:`lane_bytes` each), at least one."""
    return max(1, int(CHUNK_BYTES // lane_bytes(n_events, n_modes, n_quantities, n_positions)))


def envelope_bytes(n_lanes, n_events, n_modes, n_quantities, n_positions, keep_intervals=False):
    """Peak memory of :func:`moving_load_envelope` on ``n_lanes`` speeds (bytes): one chunk
    (:func:`chunk_lanes` lanes of :func:`lane_bytes`), the results of every lane (best, time,
    position of each quantity), and with ``keep_intervals`` the kept coefficients of every lane
    (``2 x 16 K n_modes`` each, :class:`LaneIntervals`)."""
    chunk = min(int(n_lanes), chunk_lanes(n_events, n_modes, n_quantities, n_positions))
    out = float(n_lanes) * 8.0 * (3.0 * n_quantities + 2.0)
    kept = float(n_lanes) * 32.0 * float(n_events) * float(n_modes) if keep_intervals else 0.0
    return chunk * lane_bytes(n_events, n_modes, n_quantities, n_positions) + out + kept


def _chunked_lanes(v_all, L, md, bps, G, ppp, quants, keep):
    """:func:`_all_lanes` on chunks of :func:`chunk_lanes` speeds, the results put together: the same
    as on every lane at once, bit for bit (every lane's propagation, bounds and search are its own)."""
    nl, nm, nq = v_all.size, md.jj.size, len(quants)
    width = chunk_lanes(bps.size, nm, nq, max(len(x) for _, _, x, _ in quants))
    if width >= nl:
        return _all_lanes(v_all, L, md.jj, md.om, md.zeta, md.lam, bps, G, ppp, quants)
    res = {"best": np.empty((nq, nl)), "when": np.empty((nq, nl)), "xat": np.empty((nq, nl)), "refined": 0, "candidates": 0,
           "P": np.empty((bps.size, nl, nm), dtype=complex) if keep else None,
           "H": np.empty((bps.size, nl, nm), dtype=complex) if keep else None}
    for a in range(0, nl, width):
        b = min(nl, a + width)
        part = _all_lanes(v_all[a:b], L, md.jj, md.om, md.zeta, md.lam, bps, G, ppp, quants)
        for key in ("best", "when", "xat"):
            res[key][:, a:b] = part[key]
        res["refined"] += part["refined"]
        res["candidates"] = max(res["candidates"], part["candidates"])
        if keep:
            res["P"][:, a:b] = part["P"]
            res["H"][:, a:b] = part["H"]
        del part  # before the next chunk is allocated
    return res


class Intervals(NamedTuple):
    """Every lane's response between the breakpoints (interval ``k = 0 .. K-2``; ``K-1`` is the free
    vibration after the last exit): per mode ``j`` the acceleration is
    ``Im[acc_c1 e^(i Om tau) + acc_c2 e^(lam tau)]``, the deflection the same with ``disp_c1``,
    ``disp_c2``, ``tau`` the time since the interval's start."""

    acc_c1: np.ndarray  #: (K, lanes, modes) complex
    acc_c2: np.ndarray  #: (K, lanes, modes) complex
    disp_c1: np.ndarray  #: (K, lanes, modes) complex
    disp_c2: np.ndarray  #: (K, lanes, modes) complex
    Om: np.ndarray  #: (lanes, modes) load frequencies j pi v / L (rad/s)
    lam: np.ndarray  #: (modes,) complex eigenvalues -zeta om + i om sqrt(1 - zeta^2) (1/s)
    lam2: np.ndarray  #: (modes,) |lam|^2 (1/s^2)
    t0: np.ndarray  #: (K, lanes) start time of every interval (s)
    T: np.ndarray  #: (K, lanes) length of every interval (s); the free vibration's is set after the first pass


class Quantities(NamedTuple):
    """What is searched: quantity ``q`` of family ``fam[q]`` (0 acceleration, 1 deflection), the sum over
    modes weighted ``W[q, p, j]`` at positions ``xp[q, p]``, ``p < npos[q]``; on the deck
    (``deck[q]``) each position stands for ``x_p`` and ``L - x_p`` (odd and even modes apart)."""

    fam: np.ndarray  #: (quantities,) int
    deck: np.ndarray  #: (quantities,) bool
    npos: np.ndarray  #: (quantities,) int
    W: np.ndarray  #: (quantities, positions, modes)
    xp: np.ndarray  #: (quantities, positions) (m)
    odd: np.ndarray  #: (modes,) bool: odd mode number
    kw: np.ndarray  #: (modes,) wave numbers j pi / L (1/m)
    span_m: float
    hx_m: float  #: half the spacing of the deck positions (m)


class Maxima(NamedTuple):
    """Per quantity and lane: the largest value found (``best``), its time (``when``, s) and position
    (``xat``, m), updated in place by the search; per interval the bounds of the value (``bound``)
    and of its curvature in time (``curv``)."""

    best: np.ndarray  #: (quantities, lanes)
    when: np.ndarray  #: (quantities, lanes)
    xat: np.ndarray  #: (quantities, lanes)
    bound: np.ndarray  #: (quantities, K, lanes)
    curv: np.ndarray  #: (quantities, K, lanes)


class Pairs(NamedTuple):
    """The (interval ``k``, lane ``l``) pairs to sample, largest bound first, with ``m`` samples each."""

    k: np.ndarray
    l: np.ndarray  # noqa: E741  the lane index, as in the equations
    m: np.ndarray


def interval_exponentials(Om, lam, T, lengths):
    """``(e^(i Om T_k), e^(lam T_k))``, each (lanes, modes), of every interval ``k`` of ``lengths`` (m), in order,
    ``T`` (intervals, lanes) the intervals' durations ``lengths[k] / v``. The exponentials are most of the
    propagation's cost and a train's intervals have few lengths (its axle spacings and the span: 14 to 28 of
    71 to 127 on B1 for HSLM-A1..A10 and the four real trains), so an interval as long as one before it, the
    same bits of ``lengths[k]`` and hence of ``T[k]``, takes the exponentials computed for that one: the
    same function of the same values, the same bits. Each is kept until the last interval of its length
    (no more than the coefficients the propagation fills)."""
    left = dict(zip(*np.unique(lengths, return_counts=True)))
    seen = {}
    for k, d in enumerate(lengths):
        ex = seen.pop(d, None)
        if ex is None:
            ex = (np.exp(1j * Om * T[k][:, None]), np.exp(lam * T[k][:, None]))
        left[d] -= 1
        if left[d]:
            seen[d] = ex
        yield ex


def propagate(P, Om, lam, T, lengths):
    """``H`` (K, lanes, modes), the free part of every interval from event to event (see the module doc):
    at the start of interval ``k`` the free part takes what the forced part ``Im[P_k e^(i Om tau)]``
    leaves of q and q', both zero before the first event, and both are carried to the next event over
    ``T[k]`` (s, (intervals, lanes)) with :func:`interval_exponentials` of ``lengths`` (m). One loop for
    the envelope and the effects (:mod:`adm_sim.design.check_effects`): the same operations, the same bits."""
    H = np.empty_like(P)
    q = np.zeros(P.shape[1:])
    dq = np.zeros(P.shape[1:])
    steps = interval_exponentials(Om, lam, T, lengths)
    for k in range(P.shape[0]):
        p = P[k]
        hi = q - p.imag
        H[k] = (dq - Om * p.real - lam.real * hi) / lam.imag + 1j * hi
        if k < P.shape[0] - 1:
            eW, eL = next(steps)
            q = (p * eW).imag + (H[k] * eL).imag
            dq = (1j * Om * p * eW).imag + (lam * H[k] * eL).imag
    return H


def _all_lanes(v, L, jj, om, zeta, lam, bps, G, ppp, quants):
    """Propagate every lane from event to event, then search the maxima (see the module doc)."""
    nl = v.size
    nm = jj.size
    Om = jj[None, :] * np.pi * v[:, None] / L  # (lanes, modes)
    dyn = 1.0 / (om**2 - Om**2 + 2j * zeta * om * Om)
    K = bps.size  # intervals k = 0..K-2 between breakpoints, K-1 = free vibration
    P = G[:, None, :] * np.exp(1j * np.pi * np.outer(bps, jj) / L)[:, None, :] * dyn[None]  # (K, lanes, modes)
    T = np.empty((K, nl))
    lengths = np.diff(bps)
    T[:-1] = lengths[:, None] / v[None, :]
    t0 = bps[:, None] / v[None, :]  # (K, lanes) start time of every interval
    H = propagate(P, Om, lam, T, lengths)
    # acceleration (2nd derivative) and deflection of every mode as Im[c1 e^(i Om tau) + c2 e^(lam tau)]
    fams = ((P * (1j * Om) ** 2, H * lam**2), (P, H))
    nq = len(quants)
    pmax = max(len(x) for _, _, x, _ in quants)
    W = np.zeros((nq, pmax, nm))
    xp = np.zeros((nq, pmax))
    npos = np.zeros(nq, dtype=np.int64)
    fam = np.zeros(nq, dtype=np.int64)
    deck = np.zeros(nq, dtype=np.bool_)
    odd = (np.round(jj).astype(np.int64) % 2) == 1
    kw = jj * np.pi / L
    for i_q, (f, w, x, is_deck) in enumerate(quants):
        x = np.asarray(x, dtype=float)
        W[i_q, :x.size] = w
        xp[i_q, :x.size] = x
        npos[i_q], fam[i_q], deck[i_q] = x.size, f, is_deck
    hx = L / (2.0 * max(1, int(npos[deck].max()) if deck.any() else 1))
    iv = Intervals(acc_c1=fams[0][0], acc_c2=fams[0][1], disp_c1=fams[1][0], disp_c2=fams[1][1], Om=Om, lam=lam,
                   lam2=np.abs(lam) ** 2, t0=t0, T=T)
    qs = Quantities(fam=fam, deck=deck, npos=npos, W=W, xp=xp, odd=odd, kw=kw, span_m=float(L), hx_m=float(hx))
    best, when, xat, bound, curv, b_free = _prepare(iv, qs)
    mx = Maxima(best=best, when=when, xat=xat, bound=bound, curv=curv)
    with np.errstate(divide="ignore"):
        # free vibration: follow it until its decaying bound falls below the best event value
        t_free = (np.log(np.maximum(b_free, 1e-300) / np.maximum(best, 1e-300)) / (-lam.real).min()).max(0)
    T[-1] = np.clip(t_free, 0.0, MAX_FREE_PERIODS * 2.0 * np.pi / om[0])
    # intervals that can hold a larger value than the event instants, largest bound first
    ratio = (bound / np.maximum(best, 1e-300)[:, None, :]).max(0)
    kk, ll = np.nonzero((ratio > 1.0) & (T > 0.0))
    order = np.argsort(-ratio[kk, ll], kind="stable")
    f_lane = np.maximum(np.abs(lam).max(), Om.max(1)) / (2.0 * np.pi)  # fastest component per lane
    m = np.ceil(T[kk[order], ll[order]] * f_lane[ll[order]] * ppp).astype(np.int64) + 1
    refined, candidates = _search_kernel(Pairs(k=kk[order], l=ll[order], m=m), iv, qs, mx)
    return {"best": best, "when": when, "xat": xat, "refined": int(refined), "candidates": int(candidates),
            "P": P, "H": H}


@njit(cache=True, nogil=True)
def _prepare(iv, qs):
    """Per quantity and lane: the largest value at the event instants (and its time and position),
    the amplitude bound ``sum_j w_j (|c1_j| + |c2_j|)`` and curvature bound
    ``sum_j w_j (|c1_j| Om_j^2 + |c2_j| |lam_j|^2)`` of every interval (w_j = max |weight|, 1 on the
    deck), and the amplitude bound of the free vibration. ``iv``: :class:`Intervals`, ``qs``:
    :class:`Quantities`; returns the fields of :class:`Maxima` and the free-vibration bound. The moduli
    of the coefficients are taken once per family (acceleration, deflection) and shared by its
    quantities; intervals outermost, lanes inside (the coefficients' memory order)."""
    ca1, ca2, cd1, cd2, Om, lam2, t0 = iv.acc_c1, iv.acc_c2, iv.disp_c1, iv.disp_c2, iv.Om, iv.lam2, iv.t0
    W, xp, npos, fam, deck, odd, span = qs.W, qs.xp, qs.npos, qs.fam, qs.deck, qs.odd, qs.span_m
    K, nl, nm = ca1.shape
    nq = fam.size
    best = np.zeros((nq, nl))
    when = np.zeros((nq, nl))
    xat = np.zeros((nq, nl))
    bound = np.empty((nq, K, nl))
    curv = np.empty((nq, K, nl))
    b_free = np.zeros((nq, nl))
    top = np.full((nq, nl), -1.0)
    g = np.empty((2, nm))
    amp = np.empty((2, nm))
    cur = np.empty((2, nm))
    a2s = np.empty((2, nm))
    wmax = np.empty((nq, nm))
    used = np.zeros(2, dtype=np.bool_)
    for q in range(nq):
        used[fam[q]] = True
        for j in range(nm):
            wmax[q, j] = 1.0 if deck[q] else abs(W[q, 0, j])
    for k in range(K):
        for l in range(nl):
            for f in range(2):
                if not used[f]:
                    continue
                for j in range(nm):
                    c1 = ca1[k, l, j] if f == 0 else cd1[k, l, j]
                    c2 = ca2[k, l, j] if f == 0 else cd2[k, l, j]
                    g[f, j] = (c1 + c2).imag
                    a1, a2 = abs(c1), abs(c2)
                    amp[f, j] = a1 + a2
                    cur[f, j] = a1 * Om[l, j] ** 2 + a2 * lam2[j]
                    a2s[f, j] = a2
            for q in range(nq):
                f = fam[q]
                b = 0.0
                c = 0.0
                for j in range(nm):
                    b += amp[f, j] * wmax[q, j]
                    c += cur[f, j] * wmax[q, j]
                bound[q, k, l] = b
                curv[q, k, l] = c
                if k == K - 1:
                    bf = 0.0
                    for j in range(nm):
                        bf += a2s[f, j] * wmax[q, j]
                    b_free[q, l] = bf
                for pp in range(npos[q]):
                    o = 0.0
                    e = 0.0
                    y = 0.0
                    for j in range(nm):
                        if deck[q] and not odd[j]:
                            e += g[f, j] * W[q, pp, j]
                        else:
                            o += g[f, j] * W[q, pp, j]
                    y = abs(o) + abs(e) if deck[q] else abs(o)
                    if y > top[q, l]:
                        top[q, l] = y
                        best[q, l] = y
                        when[q, l] = t0[k, l]
                        xat[q, l] = span - xp[q, pp] if deck[q] and abs(o + e) < abs(o - e) else xp[q, pp]
    return best, when, xat, bound, curv, b_free


@njit(cache=True, nogil=True)
def _eval(c1, c2, w, om, lam, tau, n):
    """sum_j w_j Im[c1_j (i om_j)^n e^(i om_j tau) + c2_j lam_j^n e^(lam_j tau)] (n-th derivative)."""
    y = 0.0
    for j in range(c1.size):
        z = 1j * om[j]
        y += w[j] * (c1[j] * z**n * cmath.exp(z * tau) + c2[j] * lam[j] ** n * cmath.exp(lam[j] * tau)).imag
    return y


@njit(cache=True, nogil=True)
def _derivative_coefficients(c1, c2, om, lam, n, a, b):
    """``a_j = c1_j (i om_j)^n``, ``b_j = c2_j lam_j^n``: the coefficients of the n-th derivative, formed as
    :func:`_eval` forms them (the same complex powers, so the same bits)."""
    for j in range(c1.size):
        z = 1j * om[j]
        a[j] = c1[j] * z**n
        b[j] = c2[j] * lam[j] ** n


@njit(cache=True, nogil=True)
def _newton(c1, c2, w, om, lam, x, lo, hi, work):
    """Local extremum of the function of (c1, c2, w) near x inside [lo, hi] (Newton on its derivative).

    The same numbers as Newton on :func:`_eval` (n = 2, then 1, at each x), bit for bit: the derivative
    coefficients are formed once (``work`` (4, modes) complex, overwritten) instead of at every
    iteration, and the two derivatives share their exponentials; each term is still
    ``w_j Im[(c1_j (i om_j)^n) e^(i om_j x) + (c2_j lam_j^n) e^(lam_j x)]``, summed in mode order."""
    a1, b1, a2, b2 = work[0], work[1], work[2], work[3]
    _derivative_coefficients(c1, c2, om, lam, 1, a1, b1)
    _derivative_coefficients(c1, c2, om, lam, 2, a2, b2)
    for _ in range(NEWTON_ITERATIONS):
        g1 = 0.0
        g2 = 0.0
        for j in range(c1.size):
            e1 = cmath.exp(1j * om[j] * x)
            e2 = cmath.exp(lam[j] * x)
            g2 += w[j] * (a2[j] * e1 + b2[j] * e2).imag
            g1 += w[j] * (a1[j] * e1 + b1[j] * e2).imag
        if g2 == 0.0:
            break
        x = min(hi, max(lo, x - g1 / g2))
    return x, abs(_eval(c1, c2, w, om, lam, x, 0))


@njit(cache=True, nogil=True, inline="always")
def _cis(om, t):
    """``cmath.exp(1j * om * t)``, bit for bit, without its real exponential: the argument is the product
    ``(0 + i om)(t + 0 i) = (0 t - om 0) + i (0 0 + om t)``, so ``cmath.exp`` returns ``e^(+-0) cos(0 + om t)``
    and ``e^(+-0) sin(0 + om t)`` with ``e^(+-0) = 1`` exactly; ``0.0 + om t`` keeps the sign of a zero
    as the product's imaginary part does (om, t finite)."""
    y = 0.0 + om * t
    return complex(math.cos(y), math.sin(y))


@njit(cache=True, nogil=True)
def _field(c1, c2, om, lam, kw, t, x):
    """F = sum_j sin(k_j x) g_j(t) and its derivatives (F, F_t, F_x, F_tt, F_tx, F_xx), with
    g_j(t) = Im[c1_j e^(i om_j t) + c2_j e^(lam_j t)] (``e^(i om_j t)``: :func:`_cis`)."""
    F = Ft = Fx = Ftt = Ftx = Fxx = 0.0
    for j in range(c1.size):
        z = 1j * om[j]
        z1 = c1[j] * _cis(om[j], t)
        z2 = c2[j] * cmath.exp(lam[j] * t)
        g0 = (z1 + z2).imag
        g1 = (z1 * z + z2 * lam[j]).imag
        g2 = (z1 * z * z + z2 * lam[j] * lam[j]).imag
        k = kw[j]
        s = math.sin(k * x)
        c = math.cos(k * x)
        F += s * g0
        Ft += s * g1
        Ftt += s * g2
        Fx += k * c * g0
        Ftx += k * c * g1
        Fxx -= k * k * s * g0
    return F, Ft, Fx, Ftt, Ftx, Fxx


@njit(cache=True, nogil=True)
def _newton2(c1, c2, om, lam, kw, t, x, start, tlo, thi, xlo, xhi, t_scale, x_scale):
    """Joint (t, x) Newton on grad F = 0 towards the local maximum of |F| inside the box (see the
    module doc), from ``start`` = :func:`_field` at (t, x); returns (t, x, |F|), never lower than the start."""
    F, Ft, Fx, Ftt, Ftx, Fxx = start
    for _ in range(NEWTON_ITERATIONS_2D):
        sg = 1.0 if F >= 0.0 else -1.0  # maximise sg F: its Hessian must be negative definite
        gt, gx, a, b, c = sg * Ft, sg * Fx, sg * Ftt, sg * Ftx, sg * Fxx
        t_stuck = (t <= tlo and gt < 0.0) or (t >= thi and gt > 0.0)
        det = a * c - b * b
        if not t_stuck and a < 0.0 and det > 0.0:
            dt = -(c * gt - b * gx) / det
            dx = -(a * gx - b * gt) / det
        else:
            dt = -gt / a if (not t_stuck and a < 0.0) else 0.0
            dx = -gx / c if c < 0.0 else 0.0
        if dt == 0.0 and dx == 0.0:
            break
        y0 = abs(F)
        ok = False
        tn, xn = t, x
        Fn = Ftn = Fxn = Fttn = Ftxn = Fxxn = 0.0
        for _h in range(6):  # a step that lowers |F| is halved
            tn = min(thi, max(tlo, t + dt))
            xn = min(xhi, max(xlo, x + dx))
            Fn, Ftn, Fxn, Fttn, Ftxn, Fxxn = _field(c1, c2, om, lam, kw, tn, xn)
            if abs(Fn) >= y0:
                ok = True
                break
            dt *= 0.5
            dx *= 0.5
        if not ok:
            break
        step_t, step_x = abs(tn - t), abs(xn - x)
        t, x = tn, xn
        F, Ft, Fx, Ftt, Ftx, Fxx = Fn, Ftn, Fxn, Fttn, Ftxn, Fxxn
        if step_t <= 1e-12 * t_scale and step_x <= 1e-12 * x_scale:
            break
    return t, x, abs(F)


@njit(cache=True, nogil=True)
def _search_kernel(pairs, iv, qs, mx):
    """Sample every (interval, lane) pair of ``pairs`` (:class:`Pairs`) that can still hold a maximum (pruned
    again against the risen best before each pair, :func:`_start_pair`), refine every sampled local maximum
    of every quantity that can reach its best by Newton (in t at once; jointly in (t, x) on the deck, deferred
    to :func:`_refine_candidates`); ``mx.best``, ``mx.when`` and ``mx.xat`` (quantities, lanes) in place.
    Returns the number of refinements and of deck candidates. The per-sample body stays in this loop; the
    steps per pair are ``inline="always"`` helpers (as plain calls 1.10x the CPU, inlined 0.99-1.01x)."""
    ca1, ca2, cd1, cd2, T, t0 = iv.acc_c1, iv.acc_c2, iv.disp_c1, iv.disp_c2, iv.T, iv.t0
    fam, deck, npos, W, xp, odd, kw, span, hx = qs.fam, qs.deck, qs.npos, qs.W, qs.xp, qs.odd, qs.kw, qs.span_m, qs.hx_m
    best, when, xat, nm, nq, refined = mx.best, mx.when, mx.xat, iv.lam.size, qs.fam.size, 0
    ya, va, vd, active, slack = np.zeros((nq, 3, W.shape[1])), np.empty(nm), np.empty(nm), np.zeros(nq, np.bool_), np.zeros(nq)
    r1, r2, e1, e2, work = (np.empty(nm, np.complex128), np.empty(nm, np.complex128), np.empty(nm, np.complex128),
                            np.empty(nm, np.complex128), np.empty((4, nm), np.complex128))
    sx = np.zeros((2, 3))  # x-curvature slack hx^2/8 sum_j k_j^2 |v_j| of the last three samples (per family)
    cf, ci, nc = np.empty((1024, 5)), np.empty((1024, 4), dtype=np.int64), 0
    for p in range(pairs.k.size):
        k, l, m = pairs.k[p], pairs.l[p], pairs.m[p]
        need_a, need_d = _start_pair(k, l, m, iv, qs, mx, active, slack, r1, r2, e1, e2)
        if not (need_a or need_d):
            continue
        T_ = T[k, l]
        h = T_ / m
        for i in range(m + 1):
            sx[0, 0], sx[0, 1], sx[1, 0], sx[1, 1] = sx[0, 1], sx[0, 2], sx[1, 1], sx[1, 2]
            sx[0, 2] = 0.0
            sx[1, 2] = 0.0
            for j in range(nm):
                if need_a:
                    va[j] = (ca1[k, l, j] * e1[j] + ca2[k, l, j] * e2[j]).imag
                    sx[0, 2] += kw[j] * kw[j] * abs(va[j])
                if need_d:
                    vd[j] = (cd1[k, l, j] * e1[j] + cd2[k, l, j] * e2[j]).imag
                    sx[1, 2] += kw[j] * kw[j] * abs(vd[j])
                e1[j] *= r1[j]
                e2[j] *= r2[j]
            sx[0, 2] *= hx * hx / 8.0
            sx[1, 2] *= hx * hx / 8.0
            for q in range(nq):
                if not active[q]:
                    continue
                v = va if fam[q] == 0 else vd
                for pp in range(npos[q]):
                    o = 0.0
                    e = 0.0
                    if deck[q]:
                        for j in range(nm):
                            if odd[j]:
                                o += W[q, pp, j] * v[j]
                            else:
                                e += W[q, pp, j] * v[j]
                        y = abs(o) + abs(e)
                    else:
                        y = 0.0
                        for j in range(nm):
                            y += W[q, pp, j] * v[j]
                        y = abs(y)
                    ya[q, 0, pp], ya[q, 1, pp], ya[q, 2, pp] = ya[q, 1, pp], ya[q, 2, pp], y
                    if y > best[q, l]:
                        best[q, l] = y
                        when[q, l] = t0[k, l] + i * h
                        xat[q, l] = span - xp[q, pp] if deck[q] and abs(o + e) < abs(o - e) else xp[q, pp]
                if i == 0:
                    continue
                # sample i-1 is a local maximum (the first sample compares with its right side only)
                for pp in range(npos[q]):
                    y1 = ya[q, 1, pp]
                    s1 = slack[q] + (sx[fam[q], 1] if deck[q] else 0.0)
                    if y1 >= ya[q, 2, pp] and (i == 1 or y1 >= ya[q, 0, pp]) and y1 + s1 >= best[q, l]:
                        if deck[q]:
                            if _x_local(ya, q, 1, pp, npos[q]):
                                cf, ci, nc = _push(cf, ci, nc, y1, y1 + s1, (i - 1) * h, h, T_, q, pp, k, l)
                        else:
                            refined += _refine_t(q, pp, (i - 1) * h, h, T_, k, l, iv, qs, mx, work)
        r, cf, ci, nc = _last_sample(k, l, m, h, iv, qs, mx, ya, sx, active, slack, work, cf, ci, nc)
        refined += r
    return refined + _refine_candidates(cf, ci, nc, iv, qs, mx), nc


@njit(cache=True, nogil=True, inline="always")
def _start_pair(k, l, m, iv, qs, mx, active, slack, r1, r2, e1, e2):
    """The quantities whose bound over interval ``k`` of lane ``l`` still reaches their best (``active``)
    and whether the acceleration and the deflection are needed; when one is, the slack of each quantity
    over a step ``h = T / m`` and the exponentials of the first sample and of one step (in ``slack``, ``e1``, ``e2``, ``r1``, ``r2``)."""
    need_a = False
    need_d = False
    for q in range(qs.fam.size):
        active[q] = mx.bound[q, k, l] > mx.best[q, l]
        if active[q]:
            if qs.fam[q] == 0:
                need_a = True
            else:
                need_d = True
    if not (need_a or need_d):
        return need_a, need_d
    h = iv.T[k, l] / m
    om, lam = iv.Om[l], iv.lam
    for q in range(qs.fam.size):
        slack[q] = mx.curv[q, k, l] * h * h / 4.0
    for j in range(lam.size):
        r1[j] = cmath.exp(1j * om[j] * h)
        r2[j] = cmath.exp(lam[j] * h)
        e1[j] = 1.0
        e2[j] = 1.0
    return need_a, need_d


@njit(cache=True, nogil=True)
def _refine_candidates(cf, ci, nc, iv, qs, mx):
    """Refine the deck candidates (:func:`_push`), deferred until every pair is sampled (the best is then
    near the maximum), the largest sample first, each only if its bound still reaches the best; returns
    the number refined."""
    refined = 0
    for c in np.argsort(-cf[:nc, 0]):
        q, pp, k, l = ci[c, 0], ci[c, 1], ci[c, 2], ci[c, 3]
        if cf[c, 1] < mx.best[q, l]:
            continue
        refined += _refine_deck(q, pp, cf[c, 2], cf[c, 3], cf[c, 4], k, l, iv, qs, mx)
    return refined


@njit(cache=True, nogil=True, inline="always")
def _last_sample(k, l, m, h, iv, qs, mx, ya, sx, active, slack, work, cf, ci, nc):
    """The last sample ``m`` of the pair (interval ``k``, lane ``l``, step ``h``) judged as a local maximum
    (its left side only) as :func:`_search_kernel` judges the others; returns the refinements and the deck
    candidates ``cf, ci, nc`` (:func:`_push`)."""
    best, fam, deck, npos, T_ = mx.best, qs.fam, qs.deck, qs.npos, iv.T[k, l]
    refined = 0
    for q in range(fam.size):
        if not active[q]:
            continue
        for pp in range(npos[q]):
            s2 = slack[q] + (sx[fam[q], 2] if deck[q] else 0.0)
            if ya[q, 2, pp] >= ya[q, 1, pp] and ya[q, 2, pp] + s2 >= best[q, l]:
                if deck[q]:
                    if _x_local(ya, q, 2, pp, npos[q]):
                        cf, ci, nc = _push(cf, ci, nc, ya[q, 2, pp], ya[q, 2, pp] + s2, m * h, h, T_, q, pp, k, l)
                else:
                    refined += _refine_t(q, pp, m * h, h, T_, k, l, iv, qs, mx, work)
    return refined, cf, ci, nc


@njit(cache=True, nogil=True)
def _x_local(ya, q, row, pp, n):
    """Is the sample at position ``pp`` of history row ``row`` not below its neighbours in x?"""
    y = ya[q, row, pp]
    return not ((pp > 0 and y < ya[q, row, pp - 1]) or (pp < n - 1 and y < ya[q, row, pp + 1]))


@njit(cache=True, nogil=True)
def _push(cf, ci, nc, y, bound, t, h, T_, q, pp, k, l):
    """Append a deck candidate (sample, value bound, time in the interval, step, interval length;
    quantity, position index, interval, lane), doubling the storage when full (copied element by element:
    a slice assignment would compile numba's shape-mismatch error, about 5 s of the first compile)."""
    if nc == cf.shape[0]:
        cf2 = np.empty((2 * nc, 5))
        ci2 = np.empty((2 * nc, 4), dtype=np.int64)
        for r in range(nc):
            for c in range(5):
                cf2[r, c] = cf[r, c]
            for c in range(4):
                ci2[r, c] = ci[r, c]
        cf, ci = cf2, ci2
    cf[nc, 0], cf[nc, 1], cf[nc, 2], cf[nc, 3], cf[nc, 4] = y, bound, t, h, T_
    ci[nc, 0], ci[nc, 1], ci[nc, 2], ci[nc, 3] = q, pp, k, l
    return cf, ci, nc + 1


@njit(cache=True, nogil=True)
def _refine_t(q, pp, x, h, T_, k, l, iv, qs, mx, work):
    """Refine a candidate of quantity ``q`` at position ``pp`` (one position, not the deck) at time ``x``
    of interval ``k``, lane ``l`` (step ``h``, length ``T_``) by Newton in t; into ``mx`` in place
    (``work``: :func:`_newton`'s)."""
    c1 = iv.acc_c1[k, l] if qs.fam[q] == 0 else iv.disp_c1[k, l]
    c2 = iv.acc_c2[k, l] if qs.fam[q] == 0 else iv.disp_c2[k, l]
    x, y = _newton(c1, c2, qs.W[q, pp], iv.Om[l], iv.lam, x, max(0.0, x - h), min(T_, x + h), work)
    if y > mx.best[q, l]:
        mx.best[q, l] = y
        mx.when[q, l] = iv.t0[k, l] + x
        mx.xat[q, l] = qs.xp[q, pp]
    return 1


@njit(cache=True, nogil=True)
def _refine_deck(q, pp, t, h, T_, k, l, iv, qs, mx):
    """Refine a deck candidate of quantity ``q`` at time ``t`` of interval ``k``, lane ``l`` (step ``h``,
    length ``T_``) and position x_p or L - x_p (the larger) jointly in (t, x); into ``mx`` in place."""
    c1 = iv.acc_c1[k, l] if qs.fam[q] == 0 else iv.disp_c1[k, l]
    c2 = iv.acc_c2[k, l] if qs.fam[q] == 0 else iv.disp_c2[k, l]
    om, lam, kw, span, hx = iv.Om[l], iv.lam, qs.kw, qs.span_m, qs.hx_m
    best, when, xat, t0 = mx.best, mx.when, mx.xat, iv.t0
    xs = qs.xp[q, pp]
    start = _field(c1, c2, om, lam, kw, t, xs)  # the field at the side taken is Newton's start, not computed twice
    mirror = _field(c1, c2, om, lam, kw, t, span - xs)
    if abs(mirror[0]) > abs(start[0]):
        xs = span - xs
        start = mirror
    t, xs, y = _newton2(c1, c2, om, lam, kw, t, xs, start, max(0.0, t - h), min(T_, t + h), max(0.0, xs - 2.0 * hx),
                        min(span, xs + 2.0 * hx), max(T_, 1e-300), span)
    if y > best[q, l]:
        best[q, l] = y
        when[q, l] = t0[k, l] + t
        xat[q, l] = xs
    return 1


__all__ = ["Envelope", "LaneIntervals", "moving_load_envelope", "check_mode_count", "check_frequency_limit_hz",
           "parse_where", "where_text", "deck_positions_m", "MAX_FREE_PERIODS", "WHERE_KEYWORDS", "CHUNK_BYTES",
           "lane_bytes", "chunk_lanes", "envelope_bytes"]
