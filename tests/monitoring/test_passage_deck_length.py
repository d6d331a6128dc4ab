"""The monitor's passage of a run on a continuous deck: the train leaves after the last span.

The free decay of a run's passage starts when the last axle has left the deck, at
``t0 + (deck length + train length) / v``; for a continuous deck the deck length is the sum of its
spans (the bridge record's ``spans_m``; its ``span_m`` is that sum too, checked by
:class:`adm_sim.model.bridge.Bridge`), not the longest span nor the first one.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from adm_sim.model.bridge import Bridge
from adm_sim.monitoring.modal_id import PassageTracker

SPANS_M = (20.0, 25.0, 20.0)
TRAIN_M = 200.18  # an ICE-2-like length
V_KMH = 252.0     # 70 m/s: round times
T0_S = 3.25


def _run(bridge_record):
    """One run fed to a tracker (started, 1 kHz samples of a decaying 4 Hz sine, done); its passage."""
    tr = PassageTracker()
    tr.bridge_description({"bridge": bridge_record})
    tr.train_description({"length_m": TRAIN_M})
    tr.status({"node": "bridge", "state": "started", "run_id": 1, "t0_s": T0_S, "monitor_speed_kmh": V_KMH})
    t = T0_S + np.arange(0, 8000) * 1e-3
    a = np.exp(-0.3 * (t - T0_S)) * np.sin(2 * np.pi * 4.0 * (t - T0_S))
    for tk, ak in zip(t, a):
        tr.sample(tk, ak)
    tr.status({"node": "bridge", "state": "done", "run_id": 1, "t0_s": T0_S, "t1_s": float(t[-1]) + 1e-3})
    tr.flush()
    assert len(tr.passages) == 1
    return tr.passages[0]


def test_the_train_leaves_a_continuous_deck_after_its_last_span():
    deck = Bridge.continuous(SPANS_M, EJ_Nm2=1.0e10, mass_per_length_kg_m=12000.0, damping_ratio=0.02, n_modes=3)
    assert deck.span_m == 65.0  # the deck length, as the bridge record carries it
    record = {"span_m": deck.span_m, "spans_m": list(deck.spans_m)}
    p = _run(record)
    # (65 + 200.18) m / 70 m/s = 3.788285714... s after t0
    want = T0_S + (65.0 + TRAIN_M) / 70.0
    assert p.info["t_train_left_s"] == pytest.approx(want, rel=0, abs=1e-12)
    assert math.isclose(want - T0_S, 3.7882857142857143, rel_tol=0, abs_tol=1e-12)
    # a record naming the spans alone (span_m absent or stale) times the passage alike
    p2 = _run({"span_m": 25.0, "spans_m": list(SPANS_M)})
    assert p2.info["t_train_left_s"] == pytest.approx(want, rel=0, abs=1e-12)


def test_one_span_keeps_its_span_length():
    p = _run({"span_m": 25.0})
    assert p.info["t_train_left_s"] == pytest.approx(T0_S + (25.0 + TRAIN_M) / 70.0, rel=0, abs=1e-12)
