"""Moving-load sweeps of a continuous deck read at every span: the dynamic part of the deck check.

The moving-load model of :mod:`adm_sim.integrate` on the deck's exact modes (:mod:`adm_sim.model.spans`):
the modal loads of Eq. (6) on the shared space grid (:func:`adm_sim.integrate.mlm_loads.mlm_modal_load_table`)
and the exact RK4 recurrence of every lane-mode oscillator (:func:`adm_sim.integrate.rk4_sides.mlm_rk4_coefficients`),
the same numbers as ``adm-sim sweep --model mlm`` on the deck. At every step, for every speed:

* the acceleration at a grid of points in every span (``points_per_span`` equal intervals, the
  midspan among them): the largest |a| per span over the points and the time, and where;
* the deflection at every span's midspan;
* every static effect of EN 1991-2 6.4.6.5(3) by the **mode-acceleration method**: the exact static
  effect of the axles (:class:`adm_sim.design.deck_statics.ContinuousBeam`, every mode) plus the
  dynamic correction of the modes kept, ``R = R_stat + sum_j w_j (q_j - F_j / K_j)``, with the modal
  weight ``w_j = omega_j^2 int mu phi_j eta`` (the effect, by the influence line eta, of mode j's
  elastic forces ``mu omega_j^2 phi_j``; for the moment at x it equals ``-EJ phi_j''(x)``, for the
  deflection ``phi_j(x)``); the integral by Gauss-Legendre between the supports and the section.

The maxima are taken at the steps (sampled in time; ``steps_per_period`` steps per period of the
highest mode at the slowest speed, the RK4 sweep's own rule), over the crossing and two fundamental
periods of free vibration. The static effects are taken at the same step positions (so that
φ'_dyn = dyn / stat - 1 compares like with like): on a 15 m span under ICE-2 the static midspan
moment sampled so lies 2.6e-4 below the exact one (tests/design/test_check_deck.py).

numpy only; no ROS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adm_sim.integrate.mlm_loads import half_step_positions, mlm_modal_load_table
from adm_sim.integrate.rk4_sides import mlm_rk4_coefficients
from adm_sim.integrate.step_grid import StepOptions, make_grid

#: Equal intervals per span of the acceleration grid (the points between them, the midspan included).
POINTS_PER_SPAN = 20
#: RK4 steps per period of the highest mode at the slowest speed (the sweep's default is 16).
STEPS_PER_PERIOD = 24.0


@dataclass
class DeckSweep:
    """Maxima per speed of one train on a continuous deck.

    Attributes
    ----------
    speeds_kmh : ndarray (n_speeds,)
    max_acc_m_s2 : ndarray (n_speeds, n_spans)
        Largest |acceleration| over the points of each span.
    x_acc_m : ndarray (n_speeds, n_spans)
        Where (m from the left abutment).
    max_acc_midspan_m_s2, max_disp_midspan_m : ndarray (n_speeds, n_spans)
        At every span's midspan.
    effects_max : ndarray (n_speeds, n_effects)
        Largest |effect| (mode-acceleration method).
    static_max : ndarray (n_effects,)
        Largest |static effect| of the axles (exact), over the same positions.
    n_steps : int
    ds_m : float
    """

    speeds_kmh: np.ndarray
    max_acc_m_s2: np.ndarray
    x_acc_m: np.ndarray
    max_acc_midspan_m_s2: np.ndarray
    max_disp_midspan_m: np.ndarray
    effects_max: np.ndarray
    static_max: np.ndarray
    n_steps: int
    ds_m: float


def acceleration_points(bridge, points_per_span=POINTS_PER_SPAN):
    """The points of the acceleration grid (m) and the span of each, ``points_per_span - 1`` per span."""
    xs, span = [], []
    for i, (a, L) in enumerate(zip(bridge.supports_m[:-1], bridge.spans_m)):
        x = a + L * np.arange(1, points_per_span) / points_per_span
        xs.append(x)
        span.append(np.full(x.size, i))
    return np.concatenate(xs), np.concatenate(span)


def modal_weights(bridge, beam, effects):
    """``w_j`` of every effect, shape (n_modes, n_effects): ``omega_j^2 int mu phi_j eta`` by
    Gauss-Legendre on the pieces between the supports and the section (see the module doc)."""
    om2 = bridge.omega_rad_s**2
    deck = bridge.deck
    out = np.empty((bridge.n_modes, len(effects)))
    n_gauss = int(40 + 2 * float(deck.beta_1_m.max()) * float(max(bridge.spans_m)))
    g, w = np.polynomial.legendre.leggauss(n_gauss)
    for c, e in enumerate(effects):
        ends = beam.breakpoints(e)
        mid = 0.5 * (ends[1:] + ends[:-1])
        half = 0.5 * (ends[1:] - ends[:-1])
        x = (mid[:, None] + half[:, None] * g[None, :]).ravel()
        wt = (half[:, None] * w[None, :]).ravel()
        mu = np.asarray(bridge.span_mu_kg_m)[beam.locate(x)[0]]
        phi = deck.phi(x)  # (n_x, n_modes)
        out[:, c] = om2 * ((wt * mu * beam.line(e, x))[:, None] * phi).sum(0)
    return out


def static_table(beam, effects, ds_m, axle_offsets_m, axle_loads_n, n_steps):
    """Exact static effects of the axles at every step position, shape (n_steps + 1, n_effects)."""
    u = half_step_positions(ds_m, axle_offsets_m, 0, n_steps)[::2]  # (n_steps + 1, n_axles)
    on = (u >= 0.0) & (u <= beam.length)
    rows, axle = np.nonzero(on)
    vals = beam.lines(effects, u[rows, axle]) * np.asarray(axle_loads_n, dtype=float)[axle][:, None]
    out = np.zeros((u.shape[0], len(effects)))
    for c in range(len(effects)):
        out[:, c] = np.bincount(rows, weights=vals[:, c], minlength=u.shape[0])
    return out


def deck_sweep(bridge, beam, effects, axle_offsets_m, axle_loads_n, speeds_kmh, *, delta_zeta=0.0,
               points_per_span=POINTS_PER_SPAN, steps_per_period=STEPS_PER_PERIOD):
    """:class:`DeckSweep` of the axles over the deck at ``speeds_kmh`` (see the module doc).

    Parameters
    ----------
    bridge : adm_sim.model.bridge.Bridge
        A continuous deck (its modes, ``modal_damping_ratios(delta_zeta)``).
    beam : adm_sim.design.deck_statics.ContinuousBeam
        Its statics (the same spans and EJ).
    effects : sequence of adm_sim.design.deck_statics.DeckEffect
    axle_offsets_m, axle_loads_n : array_like (n_axles,)
    speeds_kmh : array_like (n_speeds,)
    delta_zeta : float
        Additional damping (fraction).
    """
    offs = np.asarray(axle_offsets_m, dtype=float)
    loads = np.asarray(axle_loads_n, dtype=float)
    v_kmh = np.atleast_1d(np.asarray(speeds_kmh, dtype=float))
    grid = make_grid(bridge, float(offs[-1]), v_kmh / 3.6, StepOptions(steps_per_period=steps_per_period))
    P = mlm_modal_load_table(bridge, grid, offs, loads)  # (2 n + 1, n_modes)
    M, K = bridge.modal_mass_kg, bridge.modal_stiffness_N_m
    Z = np.broadcast_to(bridge.modal_damping_Ns_m(delta_zeta), (v_kmh.size, bridge.n_modes))
    h = grid.dt_s[:, None]
    (ax, axd), (bx, bxd), (c0, c0d), (ch, chd), (c1, c1d) = mlm_rk4_coefficients(h, M, Z, K)
    xp, span_of = acceleration_points(bridge, points_per_span)
    mids = bridge.supports_m[:-1] + 0.5 * np.asarray(bridge.spans_m)
    phi_pts = bridge.deck.phi(xp).T  # (n_modes, n_points)
    phi_mid = bridge.deck.phi(mids).T  # (n_modes, n_spans)
    W = modal_weights(bridge, beam, effects)
    S = static_table(beam, effects, grid.ds_m, offs, loads, grid.n_steps)
    nl, nm = v_kmh.size, bridge.n_modes
    q = np.zeros((nl, nm))
    qd = np.zeros((nl, nm))
    top_acc = np.zeros((nl, xp.size))
    top_mid = np.zeros((nl, mids.size))
    top_eff = np.zeros((nl, len(effects)))
    Q = np.hstack([phi_mid, W])  # displacement-proportional outputs
    nmid = mids.size
    for k in range(grid.n_steps + 1):
        p0 = P[2 * k]
        qdd = (p0 - Z * qd - K * q) / M
        np.maximum(top_acc, np.abs(qdd @ phi_pts), out=top_acc)
        y = q @ Q
        y[:, nmid:] += S[k] - (p0 / K) @ W
        np.maximum(top_mid, np.abs(y[:, :nmid]), out=top_mid)
        np.maximum(top_eff, np.abs(y[:, nmid:]), out=top_eff)
        if k == grid.n_steps:
            break
        ph, p1 = P[2 * k + 1], P[2 * k + 2]
        q, qd = (ax * q + bx * qd + c0 * p0 + ch * ph + c1 * p1,
                 axd * q + bxd * qd + c0d * p0 + chd * ph + c1d * p1)
    n_sp = len(bridge.spans_m)
    acc = np.empty((nl, n_sp))
    xacc = np.empty((nl, n_sp))
    acc_mid = np.empty((nl, n_sp))
    for i in range(n_sp):
        sel = np.flatnonzero(span_of == i)
        j = top_acc[:, sel].argmax(1)
        acc[:, i] = top_acc[np.arange(nl), sel[j]]
        xacc[:, i] = xp[sel[j]]
        acc_mid[:, i] = top_acc[:, sel[np.argmin(np.abs(xp[sel] - mids[i]))]]
    return DeckSweep(speeds_kmh=v_kmh, max_acc_m_s2=acc, x_acc_m=xacc, max_acc_midspan_m_s2=acc_mid,
                     max_disp_midspan_m=top_mid, effects_max=top_eff, static_max=np.abs(S).max(0),
                     n_steps=grid.n_steps, ds_m=grid.ds_m)
