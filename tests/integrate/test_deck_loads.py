"""The compiled modal-load table of a continuous deck (``kernels.add_deck_loads`` through
``compiled_batch.modal_load_table``) against the numpy one of the stepper
(``mlm_loads.modal_loads_at``: the deck's ``DeckModes.phi`` on every (row, axle) at once).

Same expression in the same order, compiled: the two agree to a few units of round-off
(1e-14 of the largest load, against ~1e-16 measured), and every row sums its axles in axle
order, so a table row with no axle on the deck is exactly zero in both."""

import numpy as np
import pytest

from adm_sim.integrate.compiled_batch import modal_load_table
from adm_sim.integrate.mlm_loads import half_step_positions, modal_loads_at
from adm_sim.model.bridge import Bridge
from adm_sim.inputs.train_files import load_train


@pytest.mark.parametrize("spans", [(15.0, 15.0), (12.0, 20.0, 12.0), (10.0, 10.0, 10.0, 10.0), (30.0,)])
def test_deck_table_equals_the_steppers(spans):
    tr = load_train("ICE-2")
    b = Bridge.continuous(spans, 2.0e10, 1.5e4, 0.02)
    ds, n = 0.0731, 7000
    got = modal_load_table(b, ds, tr.axle_offsets_m, tr.axle_loads_n, n)
    ref = modal_loads_at(b, half_step_positions(ds, tr.axle_offsets_m, 0, n), np.asarray(tr.axle_loads_n, float))
    assert got.shape == ref.shape == (2 * n + 1, b.n_modes)
    assert np.abs(got - ref).max() <= 1e-14 * np.abs(ref).max()
    empty = ~np.any(ref != 0.0, axis=1)
    assert empty.any() and np.all(got[empty] == 0.0)  # rows with no axle on the deck (the free vibration)
