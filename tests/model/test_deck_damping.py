"""The damping of a continuous deck given by type: EN 1991-2 Table 6.6 (paper Table 2) read with L the
longest span (adm_sim.model.bridge.deck_damping_pct, the project's choice: the standard's wording of L
for continuous decks could not be checked, docs/check.md lists the searches).

The values are the table's formulas written out here: steel and composite 0.5 + 0.125 (20 - L) %,
filler beam and reinforced concrete 1.5 + 0.07 (20 - L) % below 20 m, 0.5 % and 1.5 % from 20 m."""

import itertools

import numpy as np
import pytest

from adm_sim.model.bridge import (DECK_DAMPING_LENGTH_RULE, deck_damping_length_m, deck_damping_pct,
                                  eurocode_damping_pct)


@pytest.mark.parametrize("spans,btype,L,pct", [
    ((12.0, 16.0, 12.0), "cfb", 16.0, 1.5 + 0.07 * 4.0),   # 1.78 %
    ((12.0, 16.0, 12.0), "sc", 16.0, 0.5 + 0.125 * 4.0),   # 1.0 %
    ((8.0, 8.0), "sc", 8.0, 0.5 + 0.125 * 12.0),           # 2.0 %
    ((18.0, 25.0, 18.0), "cfb", 25.0, 1.5),                # the longest span from 20 m: the floor
    ((30.0,), "sc", 30.0, 0.5),                            # one span: the span
])
def test_table_6_6_at_the_longest_span(spans, btype, L, pct):
    """L is the longest span; the damping is the table's at that L, to 1e-12 %."""
    assert deck_damping_length_m(spans) == L
    got, L_used, text = deck_damping_pct(spans, btype)
    assert L_used == L and got == pytest.approx(pct, abs=1e-12)
    assert f"L = {L:g} m" in text and "project's choice" in text and btype.upper() in text


def test_the_longest_span_is_the_conservative_choice():
    """Table 6.6 does not increase with L, so the longest span gives the smallest of the spans' own
    values: the deck's damping equals min_i zeta(L_i) (so never more than the mean span's or the
    shortest span's), on every layout of 2-6 spans from a grid of 4-40 m."""
    grid = (4.0, 7.5, 12.0, 19.9, 20.0, 33.0, 40.0)
    for btype in ("cfb", "sc"):
        vals = [eurocode_damping_pct(L, btype) for L in np.linspace(1.0, 150.0, 2981)]
        assert all(a >= b for a, b in zip(vals[:-1], vals[1:]))  # non-increasing in L
        for n in range(2, 7):
            for spans in itertools.islice(itertools.product(grid, repeat=n), 0, None, 37):
                deck, _, _ = deck_damping_pct(spans, btype)
                own = [eurocode_damping_pct(L, btype) for L in spans]
                assert deck == min(own)
                assert deck <= eurocode_damping_pct(sum(spans) / n, btype)


def test_the_rule_says_it_is_the_projects_choice():
    assert "project's choice" in DECK_DAMPING_LENGTH_RULE and "could not be checked" in DECK_DAMPING_LENGTH_RULE
