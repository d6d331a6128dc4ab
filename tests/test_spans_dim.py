"""The DIM on continuous decks: the same kernels (numpy stepper and compiled), the mode shapes and
the Eq. (13) modified mass matrix taken from the deck's mode tables."""

import numpy as np
import pytest

from test_core_dim import SOFT, _modified
from test_spans_mlm import DECKS, as_deck
from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled
from adm_sim.model.bridge import Bridge, TABLE3, named_bridge
from adm_sim.model.trains import load_train


def test_one_span_through_the_mode_tables_is_todays_dim():
    """B1-B4 x ICE-2, DIM (compiled kernels): through the mode tables equal to today's sine-mode DIM
    to 1e-10 relative."""
    train = load_train("ICE-2")
    speeds = [180.0, 240.0, 300.0]
    for name in TABLE3:
        b = named_bridge(name)
        ref = run_sweep_compiled(b, train, "dim", speeds)
        new = run_sweep_compiled(as_deck(b), train, "dim", speeds)
        np.testing.assert_allclose(new.max_acc_m_s2, ref.max_acc_m_s2, rtol=1e-10, atol=0)
        np.testing.assert_allclose(new.max_disp_m, ref.max_disp_m, rtol=1e-10, atol=0)


@pytest.mark.parametrize("deck", list(DECKS))
def test_soft_suspension_massless_wheels_give_the_mlm_on_a_deck(deck):
    """k_p, k_s -> 1 N/m, no dampers, m_w = 0: the deck sees the static axle loads only, so the DIM
    equals the MLM on the same deck to 1e-6 (differences ~ k_p w / F ~ 1e-8)."""
    spans, EJ, mu, _ = DECKS[deck]
    b = Bridge.continuous(spans, EJ, mu, 0.02)
    speeds = [200.0, 250.0, 300.0]
    dim = run_sweep_compiled(b, _modified("ICE-2", **SOFT), "dim", speeds).max_acc_m_s2
    mlm = run_sweep_compiled(b, load_train("ICE-2"), "mlm", speeds).max_acc_m_s2
    np.testing.assert_allclose(dim, mlm, rtol=1e-6)


def test_dim_compiled_equals_numpy_on_a_deck():
    """The compiled DIM kernels and the numpy stepper on a three-span deck: equal to 1e-12."""
    spans, EJ, mu, _ = DECKS["12+16+12"]
    b = Bridge.continuous(spans, EJ, mu, 0.02)
    speeds = [220.0, 280.0]
    a = run_sweep_compiled(b, load_train("Eurostar"), "dim", speeds)
    n = run_sweep(b, load_train("Eurostar"), "dim", speeds)
    np.testing.assert_allclose(a.max_acc_m_s2, n.max_acc_m_s2, rtol=1e-12, atol=0)


def test_interaction_lowers_the_peak_on_a_deck():
    """On the two-span deck at its ICE-2 resonance the DIM peak lies below the MLM peak (the vehicles
    take energy out of the deck, as on one span), and within 30 % of it."""
    spans, EJ, mu, _ = DECKS["2x15"]
    b = Bridge.continuous(spans, EJ, mu, 0.01)
    speeds = np.arange(150.0, 350.0 + 1e-9, 5.0)
    mlm = run_sweep_compiled(b, load_train("ICE-2"), "mlm", speeds).max_acc_m_s2.max()
    dim = run_sweep_compiled(b, load_train("ICE-2"), "dim", speeds).max_acc_m_s2.max()
    assert 0.7 * mlm < dim < mlm
