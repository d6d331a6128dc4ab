"""Continuous decks of 3 to 6 spans through the check (adm_sim.design.check_deck) and its sweep
(adm_sim.design.deck_dynamics.deck_sweep), each against a reference computed here:

* one LM71 effect per layout (the hogging moment over the first intermediate support) against the
  stiffness-method reference of tests/design/test_check_deck.py (fe_lm71), to 1e-6;
* on the dynamic layouts (3, 5 and 6 spans, ``DYNAMIC_LAYOUTS``), the sweep's midspan accelerations
  against the same moving loads on the same modes integrated by scipy's DOP853 (rtol 1e-10) and read
  on a time grid 8 times finer than the sweep's steps: the sweep reads its maxima at its RK4 steps
  (24 per period of the top mode), so it may lie a little below the dense maximum (2 % allowed,
  0.97 % measured) and above it only by RK4's own error and the dense grid's (0.1 % allowed, 0.072 %
  measured);
* on the same layouts, ``adm-sim sweep``'s compiled RK4 at the middle of the longest span against the
  same reference;
* the check's set-up on every layout: the rule's modes and their frequencies, L_Phi of Table 6.2 as
  quoted (k = 1.3, 1.4, 1.5, 1.5), the effects named, the damping of Table 6.6 at the longest span;
* the whole check on the largest layout (six spans, 84 effects): finite results, and that set-up is
  what it reports.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from test_check_deck import fe_lm71

from adm_sim.design.check_deck import deck_effects, deck_modes_for, determinant_length_m, run_deck_check
from adm_sim.design.deck_dynamics import deck_sweep
from adm_sim.design.deck_statics import ContinuousBeam, DeckEffect, beam_of, lm71_max
from adm_sim.inputs.bridges import parse_bridge_spec
from adm_sim.inputs.train_files import load_train
from adm_sim.model.bridge import Bridge, eurocode_damping_pct
from adm_sim.model.spans import deck_modes, rule_mode_count

LAYOUTS = {3: (11.0, 15.0, 12.0), 4: (10.0, 13.0, 13.0, 10.0), 5: (9.0, 12.0, 14.0, 12.0, 9.0),
           6: (10.0, 11.0, 12.0, 12.0, 11.0, 10.0)}
K_TABLE_6_2 = {3: 1.3, 4: 1.4, 5: 1.5, 6: 1.5}
#: The layouts of the two dynamic tests (the static ones take every layout). deck_sweep and the
#: compiled deck loads loop over spans and modes alike, with no branch on the number of spans. 4 spans
#: (4 modes, symmetric, two equal longest spans) is left out: 6 spans is symmetric with 4 modes too,
#: and 4 spans' sweep errors against the dense reference (-0.51 .. -0.01 %) lay inside those of the
#: layouts kept: 5 spans -0.52 .. +0.072 % (nearest the upper bound), 6 spans -0.97 % (nearest the
#: lower bound) .. +0.02 %, 3 spans -0.13 .. +0.05 %.
DYNAMIC_LAYOUTS = (3, 5, 6)
#: a short train of two bogie pairs (m, N): cheap for the dense reference
OFFSETS = np.array([0.0, 2.5, 17.5, 20.0, 24.0, 26.5, 41.5, 44.0])
LOADS = np.full(OFFSETS.size, 170e3)


@pytest.mark.parametrize("n", sorted(LAYOUTS))
def test_hogging_lm71_against_the_stiffness_method(n):
    spans = LAYOUTS[n]
    EJ = tuple(2.0e10 + 1e9 * i for i in range(n))
    beam = ContinuousBeam(spans, EJ)
    e = DeckEffect("M", float(spans[0]), -1, "hogging M support 1")
    m = lm71_max(beam, e)
    assert m.value == pytest.approx(fe_lm71(spans, EJ, e, m.centre_m, m.sign), rel=1e-6)
    assert m.sign == -1  # hogging


def _modal_loads(deck, n_modes, v_m_s, t_s):
    """The modal loads of the train at the times ``t_s`` (n_t,), shape (n_modes, n_t): per time, the
    sum over the axles on the deck of load x mode shape (the right-hand sides' ``load(t)`` at every
    time at once; equal to it up to the order of the sum over axles)."""
    x = v_m_s * np.asarray(t_s)[:, None] - OFFSETS  # (n_t, n_axles)
    on = (x >= 0.0) & (x <= deck.length_m)
    rows, axles = np.nonzero(on)
    P = np.zeros((x.shape[0], n_modes))
    np.add.at(P, rows, LOADS[axles][:, None] * deck.phi(x[on]))
    return P.T


def _dense_midspan_acc(bridge, v_m_s, t_end_s):
    """Largest |acceleration| at every midspan, the modal equations integrated by DOP853."""
    d = bridge.deck
    M, K = bridge.modal_mass_kg, bridge.modal_stiffness_N_m
    Z = bridge.modal_damping_Ns_m(0.0)
    L = d.length_m
    mids = bridge.supports_m[:-1] + 0.5 * np.asarray(bridge.spans_m)
    phi_mid = d.phi(mids)  # (n_spans, n_modes)

    def load(t):
        x = v_m_s * t - OFFSETS
        on = (x >= 0.0) & (x <= L)
        if not on.any():
            return np.zeros(bridge.n_modes)
        return LOADS[on] @ d.phi(x[on])

    def rhs(t, y):
        q, qd = y[:bridge.n_modes], y[bridge.n_modes:]
        return np.concatenate([qd, (load(t) - Z * qd - K * q) / M])

    top_T = 2 * math.pi / bridge.omega_rad_s[-1]
    t = np.arange(0.0, t_end_s, top_T / (24 * 8))
    sol = solve_ivp(rhs, (0.0, t[-1]), np.zeros(2 * bridge.n_modes), method="DOP853", rtol=1e-10, atol=1e-14,
                    t_eval=t, max_step=top_T / 8)
    q, qd = sol.y[:bridge.n_modes], sol.y[bridge.n_modes:]
    P = _modal_loads(d, bridge.n_modes, v_m_s, t)
    qdd = (P - Z[:, None] * qd - K[:, None] * q) / M[:, None]
    return np.abs(phi_mid @ qdd).max(1)


@pytest.mark.parametrize("n", [pytest.param(n, marks=[] if n == 5 else [pytest.mark.slow]) for n in DYNAMIC_LAYOUTS])
def test_sweep_midspans_against_a_dense_integration(n):
    """Measured (sweep / dense - 1 per midspan, 180 and 270 km/h): -0.97 % .. +0.072 %; about 4 s per
    layout, so one layout (5 spans) runs in the developer loop, the rest of ``DYNAMIC_LAYOUTS`` in
    the slow tier."""
    spans = LAYOUTS[n]
    deck = Bridge.continuous(spans, 2.2e10, 14000.0, 0.02, damping_model="modal")
    beam = ContinuousBeam(spans, (2.2e10,) * n)
    v_kmh = np.array([180.0, 270.0])
    sw = deck_sweep(deck, beam, [DeckEffect("M", float(spans[0]))], OFFSETS, LOADS, v_kmh)
    assert np.all(np.isfinite(sw.max_acc_m_s2)) and np.all(sw.max_acc_m_s2 > 0)
    t_end = sw.n_steps * sw.ds_m / (v_kmh / 3.6)  # the sweep's own time span at each speed
    for i, v in enumerate(v_kmh):
        ref = _dense_midspan_acc(deck, v / 3.6, t_end[i])
        rel = sw.max_acc_midspan_m_s2[i] / ref - 1.0
        assert rel.max() <= 1e-3 and rel.min() >= -0.02, (n, v, rel)


@pytest.mark.slow
@pytest.mark.parametrize("n", DYNAMIC_LAYOUTS)
def test_adm_sim_sweep_on_the_dynamic_layouts(n):
    """``adm-sim sweep``'s compiled RK4 (adm_sim.integrate.sweep.run_sweep_compiled) on the dynamic
    layouts (``DYNAMIC_LAYOUTS``: 4 spans left out, as there), read at the middle of the longest span
    with its dense maxima (the cubic between steps): finite, and equal to the DOP853 reference at that
    point to 0.2 % (RK4 at 16 steps per period; measured -0.18 %, -0.18 %, -0.09 % for 3, 5, 6 spans
    at 250 km/h; -0.14 % on 4 spans when it ran)."""
    from adm_sim.integrate.step_grid import StepOptions
    from adm_sim.integrate.sweep import run_sweep_compiled
    from adm_sim.model.trains import moving_loads

    spans = LAYOUTS[n]
    deck = Bridge.continuous(spans, 2.2e10, 14000.0, 0.02, damping_model="modal")
    i = int(np.argmax(spans))
    x = float(deck.supports_m[i] + 0.5 * spans[i])
    train = moving_loads(OFFSETS, LOADS, "two bogie pairs")
    res = run_sweep_compiled(deck, train, "mlm", [250.0], where=x, options=StepOptions(dense_maxima=True))
    got = float(res.max_acc_m_s2[0])
    assert math.isfinite(got) and got > 0
    t_end = res.n_steps * res.ds_m / (250.0 / 3.6)
    ref = _dense_point_acc(deck, 250.0 / 3.6, t_end, x)
    assert got == pytest.approx(ref, rel=2e-3), (got, ref)


def _dense_point_acc(bridge, v_m_s, t_end_s, x_m):
    """As :func:`_dense_midspan_acc` at one point."""
    d = bridge.deck
    M, K, Z = bridge.modal_mass_kg, bridge.modal_stiffness_N_m, bridge.modal_damping_Ns_m(0.0)
    phi_x = d.phi(np.array([x_m]))[0]

    def load(t):
        xs = v_m_s * t - OFFSETS
        on = (xs >= 0.0) & (xs <= d.length_m)
        return LOADS[on] @ d.phi(xs[on]) if on.any() else np.zeros(bridge.n_modes)

    def rhs(t, y):
        q, qd = y[:bridge.n_modes], y[bridge.n_modes:]
        return np.concatenate([qd, (load(t) - Z * qd - K * q) / M])

    top_T = 2 * math.pi / bridge.omega_rad_s[-1]
    t = np.arange(0.0, t_end_s, top_T / 192)
    sol = solve_ivp(rhs, (0.0, t[-1]), np.zeros(2 * bridge.n_modes), method="DOP853", rtol=1e-10, atol=1e-14,
                    t_eval=t, max_step=top_T / 8)
    q, qd = sol.y[:bridge.n_modes], sol.y[bridge.n_modes:]
    P = _modal_loads(d, bridge.n_modes, v_m_s, t)
    return float(np.abs(phi_x @ ((P - Z[:, None] * qd - K[:, None] * q) / M[:, None])).max())


def _deck(n):
    spans = LAYOUTS[n]
    return parse_bridge_spec(f"spans={'/'.join(f'{s:g}' for s in spans)},EJ=2.2e10,mu=14000,type=sc")


@pytest.mark.parametrize("n", sorted(LAYOUTS))
def test_check_set_up_on_every_layout(n):
    """What the check takes from the layout before its sweeps, by the functions run_deck_check calls:
    the rule's modes with the model's frequencies, L_Phi of Table 6.2 as quoted (k = 1.3, 1.4, 1.5,
    1.5), the effects of 6.4.6.5(3) named per span and support, Table 6.6's damping at the longest
    span. The whole check (its LM71 search over every effect, the sweep, the serviceability limits)
    runs on the largest layout below: about 3-6 s of CPU per layout, mostly the LM71 search."""
    spans = LAYOUTS[n]
    deck = _deck(n)
    assert deck.damping_ratio == pytest.approx(eurocode_damping_pct(max(spans), "sc") / 100.0, rel=1e-15)
    assert deck.damping_source.startswith(f"EN 1991-2 Table 6.6 lower limit for SC (paper Table 2) with "
                                          f"L = {max(spans):g} m")
    b, need = deck_modes_for(deck, None)
    assert need == rule_mode_count(spans, (2.2e10,) * n, (14000.0,) * n) and b.n_modes == need
    ref = deck_modes(spans, (2.2e10,) * n, (14000.0,) * n, need).frequencies_hz
    np.testing.assert_allclose(b.frequencies_hz, ref, rtol=1e-14)
    assert determinant_length_m(spans) == pytest.approx(max(K_TABLE_6_2[n] * sum(spans) / n, max(spans)), rel=1e-15)
    labels = [e.label for e in deck_effects(beam_of(b))]
    assert len(labels) == (n + 1) + (n - 1) + 9 * n + 2 * n + n == len(set(labels))
    assert f"hogging M support {n - 1}" in labels and f"w midspan {n}" in labels and f"reaction support {n}" in labels


@pytest.mark.slow
def test_whole_check_on_the_largest_layout():
    """The whole check (run_deck_check) on six spans, 84 effects: finite results, and the set-up of
    :func:`test_check_set_up_on_every_layout` is what it reports."""
    n = 6
    spans = LAYOUTS[n]
    res = run_deck_check(_deck(n), 160, [load_train("HSLM-A1")])
    d = res.to_dict()
    assert d["spans_m"] == list(spans) and len(d["per_span_governing"]) == n
    need = rule_mode_count(spans, (2.2e10,) * n, (14000.0,) * n)
    assert d["rule_modes"] == need and d["modes"] == list(range(1, need + 1))
    ref = deck_modes(spans, (2.2e10,) * n, (14000.0,) * n, need).frequencies_hz
    assert d["frequencies_hz"] == pytest.approx(ref.tolist(), rel=1e-14)
    assert d["L_phi_m"] == pytest.approx(max(K_TABLE_6_2[n] * sum(spans) / n, max(spans)), rel=1e-15)
    effects = d["en1991_2_6_4_6_5_effects"]
    assert len(effects) == len(deck_effects(ContinuousBeam(spans, (2.2e10,) * n))) == 84
    assert all(math.isfinite(e["ratio"]) and e["ratio"] > 0 for e in effects)
    tr = d["trains"][0]
    assert all(math.isfinite(p["max_acc_m_s2"]) and p["max_acc_m_s2"] > 0 for p in tr["per_span"])
    assert d["damping_source"].startswith(f"EN 1991-2 Table 6.6 lower limit for SC (paper Table 2) with "
                                          f"L = {max(spans):g} m")
