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

    Row ``2k`` is step k, row ``2k + 1`` the RK midpoint; shared by all lanes. One span: by
    :func:`span_load_table`, without a (rows x axles) table. A continuous deck still evaluates every
    (row, axle) position at once (:func:`modal_loads_at`, :func:`deck_modal_loads`: one bincount per mode
    over every entry): the numpy stepper is the reference of the compiled kernels, whose table
    (:func:`adm_sim.integrate.compiled_batch.modal_load_table`) builds it axle by axle.
    """
    if bridge.is_continuous:
        x = half_step_positions(grid.ds_m, axle_offsets_m, 0, grid.n_steps)
        return modal_loads_at(bridge, x, np.asarray(axle_loads_n, dtype=float))
    return span_load_table(bridge, 0.5 * grid.ds_m * np.arange(0, 2 * grid.n_steps + 1), axle_offsets_m,
                           axle_loads_n)


def span_load_table(bridge, s, axle_offsets_m, axle_loads_n):
    """Modal loads of Eq. (6) on one simply supported span with the first axle at ``s`` (m, rows,
    increasing), shape (rows, n_modes): bit for bit :func:`modal_loads_at` of the positions
    ``s - offset`` (the same rows on the span, the same sums in the same axle order), without the
    table of every axle's position at every row (rows x n_axles: 47 MB for ICE-2 on a 4 m span, 20
    times the loads themselves), each axle's position computed only on its rows (:func:`axles_on_deck`)."""
    out = np.zeros((s.size, bridge.n_modes))
    span = bridge.span_m
    j = bridge.mode_numbers * math.pi / span
    for load, r0, x in axles_on_deck(s, span, axle_offsets_m, axle_loads_n):
        out[r0:r0 + x.size] += load * np.sin(np.outer(x, j))
    return out


def axles_on_deck(s, span, axle_offsets_m, axle_loads_n):
    """Each axle's rows on the deck, in axle order: ``(load_n, r0, x)`` with ``x = s[r0:r0 + k] - offset``
    the axle's positions on ``[0, span]`` (the rows are contiguous: ``s`` increases); axles never on
    the deck are left out. ``s - off >= 0`` exactly where ``s >= off`` (the sign of a rounded
    difference is exact); the upper end by the test itself on a few rows beyond ``s = off + span``."""
    loads = np.asarray(axle_loads_n, dtype=float)
    for i, off in enumerate(np.asarray(axle_offsets_m, dtype=float)):
        r0 = int(np.searchsorted(s, off, side="left"))
        r1 = min(int(np.searchsorted(s, off + span, side="right")) + 2, s.size)
        if r0 >= r1:
            continue
        x = s[r0:r1] - off
        on = np.flatnonzero((x >= 0.0) & (x <= span))
        if on.size:
            yield loads[i], r0 + on[0], x[on[0]:on[-1] + 1]
