"""The continuous deck's LM71 search against its former form, kept here verbatim.

:func:`adm_sim.design.deck_statics.lm71_max` evaluates both signs on the grid in one call and zooms in on
its eight best grid points (four per sign) in lockstep, one evaluation per zoom level for all of them
(:func:`adm_sim.design.deck_statics.zoom_max_many`), and :func:`adm_sim.design.deck_statics._partial_integral`
evaluates the line at the points of every partly covered piece in one call; each value is still formed
by the same operations in the same order. The former search (one zoom per best point and sign, one
evaluation per piece) must give the same maximum, sign and position bit for bit, for every kind of effect
(moment, shear, deflection, reaction, end rotation) on a deck of three unequal spans of unequal stiffness,
and the same values of ``lm71_value`` for either sign on a grid over the deck and beyond its ends.
``bench/check_bits.py --only deck`` proves the whole check's outputs byte for byte.
"""

import numpy as np
import pytest

from adm_sim.design import deck_statics as ds
from adm_sim.design.deck_statics import LM71_AXLE_LOAD_N, LM71_AXLES_M, LM71_HALF_WINDOW_M, LM71_UDL_N_M


def _partial_integral_before(beam, effect, pieces, lo, hi, sign):
    """Integral of the influence line over [lo, hi] (arrays) restricted to the pieces of ``sign``."""
    ends, integ, sgn = pieces
    lo = np.clip(np.asarray(lo, dtype=float), ends[0], ends[-1])
    hi = np.clip(np.asarray(hi, dtype=float), ends[0], ends[-1])
    out = np.zeros(lo.shape)
    g, w = ds._GAUSS
    for p in np.flatnonzero(sgn == sign):
        a, b = ends[p], ends[p + 1]
        c0, c1 = np.maximum(lo, a), np.minimum(hi, b)
        full = (c0 <= a) & (c1 >= b)
        out += np.where(full, integ[p], 0.0)
        part = (c1 > c0) & ~full
        if part.any():
            m = 0.5 * (c0[part] + c1[part])
            h = 0.5 * (c1[part] - c0[part])
            pts = m[:, None] + h[:, None] * g[None, :]
            vals = beam.line(effect, pts.ravel()).reshape(pts.shape)
            out[part] += (vals * w[None, :]).sum(1) * h
    return out


def _lm71_value_before(beam, effect, centre_m, sign, pieces=None):
    pieces = ds.signed_pieces(beam, effect) if pieces is None else pieces
    d = np.atleast_1d(np.asarray(centre_m, dtype=float))
    c = np.asarray(LM71_AXLES_M)
    pts = LM71_AXLE_LOAD_N * beam.line(effect, (d[:, None] + c[None, :]).ravel()).reshape(d.size, c.size).sum(1)
    total = float(pieces[1][pieces[2] == sign].sum())
    gap = _partial_integral_before(beam, effect, pieces, d - LM71_HALF_WINDOW_M, d + LM71_HALF_WINDOW_M, sign)
    return sign * (pts + LM71_UDL_N_M * (total - gap))


def _lm71_max_before(beam, effect, alpha):
    pieces = ds.signed_pieces(beam, effect)
    c = np.asarray(LM71_AXLES_M)
    hw = LM71_HALF_WINDOW_M
    lo, hi = -hw, beam.length + hw
    grid = np.arange(lo, hi + ds.LM71_GRID_M, ds.LM71_GRID_M)
    ends = pieces[0]
    cand = np.concatenate([grid, (ends[:, None] - c[None, :]).ravel(), ends - hw, ends + hw])
    cand = np.unique(np.clip(cand, lo, hi))
    best = None
    for sign in (1, -1):
        vals = _lm71_value_before(beam, effect, cand, sign, pieces)
        for i in np.argsort(vals)[-4:]:  # zoom in around the best grid points
            a = cand[max(i - 1, 0)]
            b = cand[min(i + 1, cand.size - 1)]
            x, fx = ds.zoom_max(lambda t: _lm71_value_before(beam, effect, t, sign, pieces), a, b)
            if fx < vals[i]:
                x, fx = float(cand[i]), float(vals[i])
            if best is None or fx > best.value:
                best = ds.LM71Max(value=fx, sign=sign, centre_m=float(x))
    return ds.LM71Max(value=alpha * best.value, sign=best.sign, centre_m=best.centre_m)


#: Three unequal spans of unequal stiffness: lines of both signs with several roots per span.
BEAM = ds.ContinuousBeam((7.5, 31.2, 18.3), (9e9, 2.2e10, 1.4e10))
EFFECTS = [ds.DeckEffect("M", 12.4), ds.DeckEffect("M", 7.5), ds.DeckEffect("V", 38.6), ds.DeckEffect("V", 0.0),
           ds.DeckEffect("w", 23.1), ds.DeckEffect("R", 7.5, 1), ds.DeckEffect("R", 57.0, 3),
           ds.DeckEffect("theta", 0.0, 0), ds.DeckEffect("theta", 57.0, 3)]


@pytest.mark.parametrize("effect", EFFECTS, ids=lambda e: f"{e.kind}-{e.x_m:g}")
def test_lm71_max_equals_its_former_form(effect):
    before = _lm71_max_before(BEAM, effect, 1.33)
    now = ds._lm71_max.__wrapped__(BEAM, effect, 1.33)  # computed here, not taken from another test's cache
    assert (now.value, now.sign, now.centre_m) == (before.value, before.sign, before.centre_m)
    assert now.value > 0.0 and now.sign in (1, -1)
    d = np.linspace(-5.0, BEAM.length + 5.0, 397)
    for sign in (1, -1):
        assert np.array_equal(ds.lm71_value(BEAM, effect, d, sign), _lm71_value_before(BEAM, effect, d, sign))
    # both signs in one call: each centre's value is the one of its sign alone
    both = ds.lm71_value(BEAM, effect, np.concatenate([d, d]), np.repeat([1, -1], d.size))
    assert np.array_equal(both, np.concatenate([_lm71_value_before(BEAM, effect, d, s) for s in (1, -1)]))


def test_zoom_many_follows_each_zoom():
    """Each interval of :func:`zoom_max_many` ends where :func:`zoom_max` ends on it alone, with its
    value, whatever the others do (they end at other levels: intervals of other widths)."""
    def f(x, tag):
        return -(x - 0.3 * tag) ** 2 + np.sin(7.0 * x * tag)

    intervals = [(-1.0, 1.0), (0.0, 0.5), (-3.0, 2.0), (0.2, 0.2 + 1e-8)]
    tags = [1.0, 2.0, -1.5, 1.0]
    many = ds.zoom_max_many(f, intervals, tags)
    alone = [ds.zoom_max(lambda x, t=t: f(x, t), a, b) for (a, b), t in zip(intervals, tags)]
    assert many == alone
