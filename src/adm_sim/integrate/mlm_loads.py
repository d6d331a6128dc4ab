"""The moving-load model's loads: axle positions at the RK4 stage points and their modal loads (Eq. 6).

The MLM's loads do not depend on the bridge motion, so they are tabulated once per run on the
half-step grid of train positions (:mod:`adm_sim.integrate.step_grid`), shared by all lanes: row ``2k`` is
step ``k``, row ``2k + 1`` its RK midpoint.
"""

from __future__ import annotations

import math

import numpy as np


def half_step_positions(ds_m, axle_offsets_m, k0, n_steps):
    """Axle positions (m from the left support) at the RK4 stage points of steps ``k0..k0+n``.

    Row ``r`` is the first axle at ``s = r ds / 2``, ``r = 2 k0 .. 2 (k0 + n)``; shape
    ``(2 n + 1, n_axles)``. Rows ``2k`` are steps, rows ``2k + 1`` the RK midpoints.
    """
    s = 0.5 * ds_m * np.arange(2 * k0, 2 * (k0 + n_steps) + 1)
    return s[:, None] - np.asarray(axle_offsets_m, dtype=float)[None, :]


def deck_modal_loads(bridge, rows, x_m, loads_n, n_rows):
    """Modal loads of Eq. (6) on a continuous deck, shape (n_rows, n_modes): the load ``loads_n[e]``
    at ``x_m[e]`` (m from the left abutment, on the deck) added to row ``rows[e]``, with the deck's
    mode shapes evaluated in one call for every entry."""
    phi = bridge.deck.phi(np.asarray(x_m, dtype=float)) * np.asarray(loads_n, dtype=float)[:, None]
    out = np.empty((n_rows, bridge.n_modes))
    for j in range(bridge.n_modes):
        out[:, j] = np.bincount(rows, weights=phi[:, j], minlength=n_rows)
    return out


def modal_loads_at(bridge, x_m, loads_n):
    """Modal loads of Eq. (6) for axle positions ``x_m`` (rows, n_axles), shape (rows, n_modes).

    One pass per axle over the rows with that axle on the bridge (positions increase along the
    rows); the rectangle function Gamma is the closed span ``[0, L]`` (a continuous deck: its
    whole length, its exact mode shapes).
    """
    if bridge.is_continuous:
        rows, axle = np.nonzero((x_m >= 0.0) & (x_m <= bridge.span_m))
        return deck_modal_loads(bridge, rows, x_m[rows, axle], np.asarray(loads_n, dtype=float)[axle], x_m.shape[0])
    out = np.zeros((x_m.shape[0], bridge.n_modes))
    j = bridge.mode_numbers * math.pi / bridge.span_m
    for i in range(x_m.shape[1]):
        x = x_m[:, i]
        on = np.flatnonzero((x >= 0.0) & (x <= bridge.span_m))
        if on.size:
            lo, hi = on[0], on[-1] + 1
            out[lo:hi] += loads_n[i] * np.sin(np.outer(x[lo:hi], j))
    return out


def mlm_modal_load_table(bridge, grid, axle_offsets_m, axle_loads_n):
    """Modal loads of Eq. (6) on the half-step grid, shape (2 n_steps + 1, n_modes).

    Row ``2k`` is step k, row ``2k + 1`` the RK midpoint; shared by all lanes.
    """
    x = half_step_positions(grid.ds_m, axle_offsets_m, 0, grid.n_steps)
    return modal_loads_at(bridge, x, np.asarray(axle_loads_n, dtype=float))
