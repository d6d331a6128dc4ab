"""The EN 1991-2 check of a continuous deck (adm_sim.design.check_deck, deck_statics, deck_dynamics).

The static influence lines and the LM71 effects are held against an independent stiffness-method
calculation written here: Hermite beam elements (exact for point forces at the nodes) with a node at
every support, the section and the force, the distributed load integrated by scipy's adaptive
quadrature between the roots (scipy's brentq) of the reference's own influence line.
"""

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize

from adm_sim.design.check import run_check
from adm_sim.design.check_text import summary
from adm_sim.design.check_deck import axle_group_m, deck_effects, determinant_length_m, run_deck_check
from adm_sim.design.check_effects import Effect, lm71_effect_max
from adm_sim.design.deck_dynamics import deck_sweep, modal_weights
from adm_sim.design.deck_statics import ContinuousBeam, DeckEffect, lm71_max, lm71_value
from adm_sim.design.design_loads import LM71_AXLE_LOAD_N, LM71_AXLES_M, LM71_HALF_WINDOW_M, LM71_UDL_N_M
from adm_sim.errors import InputError
from adm_sim.model.bridge import Bridge, named_bridge
from adm_sim.model.trains import moving_loads
from adm_sim.inputs.train_files import load_train

SPANS = (12.0, 16.0, 13.0)
EJ = (2.0e10, 3.0e10, 2.5e10)


# ---------------------------------------------------------------------- the stiffness-method reference
def _stiffness(EJ_, h):
    return EJ_ / h**3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                  [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])


def fe_effect(spans, EJs, kind, x, u, support=-1):
    """The effect of a unit downward force at u by the stiffness method (w up-positive inside)."""
    sup = np.concatenate([[0.0], np.cumsum(spans)])
    if kind == "V" and np.min(np.abs(sup - x)) < 1e-6:  # just right of a support: that support's node
        x = float(sup[np.argmin(np.abs(sup - x))])
    nodes = np.unique(np.concatenate([sup, [x], [u] if 0.0 <= u <= sup[-1] else []]))
    n = nodes.size
    K = np.zeros((2 * n, 2 * n))
    els = []
    for e in range(n - 1):
        a, b = nodes[e], nodes[e + 1]
        s = min(np.searchsorted(sup, 0.5 * (a + b)) - 1, len(spans) - 1)
        k = _stiffness(EJs[s], b - a)
        idx = [2 * e, 2 * e + 1, 2 * e + 2, 2 * e + 3]
        K[np.ix_(idx, idx)] += k
        els.append((idx, k))
    F = np.zeros(2 * n)
    if 0.0 <= u <= sup[-1]:
        F[2 * int(np.argmin(np.abs(nodes - u)))] = -1.0
    fixed = [2 * int(np.argmin(np.abs(nodes - s))) for s in sup]
    free = [i for i in range(2 * n) if i not in fixed]
    d = np.zeros(2 * n)
    d[free] = np.linalg.solve(K[np.ix_(free, free)], F[free])
    i = int(np.argmin(np.abs(nodes - x)))
    if kind == "R":
        return float((K @ d - F)[fixed[support]])
    if kind == "w":
        return float(-d[2 * i])
    if kind == "theta":
        return float(-d[1] if support == 0 else d[-1])
    if kind == "M":  # internal moment at the section, sagging positive: the element right of the node
        if i < n - 1:
            idx, k = els[i]
            return float(-(k @ d[idx])[1])
        idx, k = els[i - 1]
        return float((k @ d[idx])[3])
    idx, k = els[i]  # "V": the shear just right of the node, dM/dx
    return float((k @ d[idx])[0])


def fe_lm71(spans, EJs, e, centre, sign):
    """LM71 with the group centred at ``centre``, the distributed load where the reference's own line has
    ``sign``, outside the 6.4 m window (reference: quad between brentq roots)."""
    L = float(np.sum(spans))
    eta = lambda u: fe_effect(spans, EJs, e.kind, e.x_m, u, e.support)  # noqa: E731
    pts = sum(LM71_AXLE_LOAD_N * eta(centre + c) for c in LM71_AXLES_M if 0.0 <= centre + c <= L)
    sup = list(np.concatenate([[0.0], np.cumsum(spans)]))
    bps = sorted(set(sup + ([e.x_m] if e.kind in ("M", "V", "w") else [])
                     + [min(max(centre + s * LM71_HALF_WINDOW_M, 0.0), L) for s in (-1, 1)]))
    ends = []
    for a, b in zip(bps[:-1], bps[1:]):
        # The grid that brackets the roots keeps 1 cm inside each piece. Nearer a node of the reference
        # (a support, the section), the force's node makes an element of length |u - node| and the
        # ordinate is lost to round-off (M at 4.8 m: up to 8 off within 1e-5 m, 1e-7 at 1 cm); sampled
        # 1e-9 m inside, an M or w line at a section in a span changed sign there: two spurious roots
        # ~3e-5 m either side of the section, whose sub-interval of noise was integrated (the reference
        # up to 1.3e-5 relative too low) or drove quad to its subdivision limit (IntegrationWarning, 1 s).
        # Every kink (supports, section) is a breakpoint already, so none lies inside a quad interval.
        # A genuine root within 1 cm of a breakpoint would go unbracketed: none in these tests' decks.
        d = min(1e-2, 0.25 * (b - a))
        g = np.linspace(a + d, b - d, 41)
        y = [eta(t) for t in g]
        ends.append(a)
        ends += [scipy.optimize.brentq(eta, g[k], g[k + 1], xtol=1e-14) for k in range(40) if y[k] * y[k + 1] < 0.0]
    ends.append(L)
    udl = 0.0
    for a, b in zip(ends[:-1], ends[1:]):
        m = 0.5 * (a + b)
        if b - a < 1e-12 or abs(m - centre) < LM71_HALF_WINDOW_M or np.sign(eta(m)) != sign:
            continue
        udl += scipy.integrate.quad(eta, a, b, epsabs=1e-14, epsrel=1e-10, limit=200)[0]
    return sign * (pts + LM71_UDL_N_M * udl)


EFFECTS = (DeckEffect("M", 12.0, -1, "hogging M support 1"), DeckEffect("M", 20.0, -1, "M span 2 midspan"),
           DeckEffect("M", 4.8, -1, "M span 1 0.4 L"), DeckEffect("R", 12.0, 1, "reaction support 1"),
           DeckEffect("R", 0.0, 0, "reaction support 0"), DeckEffect("V", 12.0 + 1e-9 * 16, -1, "V right of support 1"),
           DeckEffect("w", 20.0, -1, "w midspan 2"), DeckEffect("theta", 0.0, 0, "rotation left abutment"))


@pytest.mark.parametrize("e", EFFECTS, ids=lambda e: e.label)
def test_influence_lines_match_the_stiffness_method(e):
    """Every ordinate of the three-moment influence lines equals the stiffness method's to 1e-9 of the
    line's largest ordinate (both exact for point forces; the difference is round-off)."""
    beam = ContinuousBeam(SPANS, EJ)
    u = np.concatenate([np.linspace(0.0, 41.0, 83), np.random.default_rng(1).uniform(0.0, 41.0, 40)])
    u = u[np.abs(u - e.x_m) > 1e-6]  # not on the section itself (the shear's jump)
    got = beam.line(e, u)
    ref = np.array([fe_effect(SPANS, EJ, e.kind, e.x_m, t, e.support) for t in u])
    assert np.max(np.abs(got - ref)) <= 1e-9 * np.max(np.abs(ref))


@pytest.mark.parametrize("e", EFFECTS, ids=lambda e: e.label)
def test_lm71_effects_match_the_stiffness_method(e):
    """The largest α x LM71 effect (the distributed load on the unfavourable parts) equals the stiffness
    method's at the same group position to 1e-6, and no position of a 0.1 m grid gives more by the
    reference (its grid maximum lies within 1e-6 above and 2 % below)."""
    beam = ContinuousBeam(SPANS, EJ)
    m = lm71_max(beam, e)
    ref = fe_lm71(SPANS, EJ, e, m.centre_m, m.sign)
    assert m.value == pytest.approx(ref, rel=1e-6)
    grid = np.arange(-3.2, 44.2, 0.5)
    ours = max(float(lm71_value(beam, e, grid, s).max()) for s in (1, -1))
    assert ours <= m.value * (1 + 1e-9)
    some = [fe_lm71(SPANS, EJ, e, c, m.sign) for c in grid[:: 16]]
    assert max(some) <= m.value * (1 + 1e-6)


def test_one_span_lm71_equals_the_simply_supported_check():
    """A deck of one span: the LM71 moment at 0.3 L and the reaction equal check_effects' own to 1e-6."""
    beam = ContinuousBeam([15.0], [1e10])
    assert lm71_max(beam, DeckEffect("M", 4.5)).value == pytest.approx(lm71_effect_max(Effect("M", 4.5), 15.0),
                                                                       rel=1e-6)
    assert lm71_max(beam, DeckEffect("R", 0.0, 0)).value == pytest.approx(lm71_effect_max(Effect("RA", 0.0), 15.0),
                                                                          rel=1e-6)


def test_reactions_balance_the_force():
    """Equilibrium: the reactions sum to the force and their moment about the left abutment is u (1e-12)."""
    beam = ContinuousBeam(SPANS, EJ)
    u = np.linspace(0.0, 41.0, 97)
    R = np.array([beam.reaction(k, u) for k in range(4)])
    assert np.allclose(R.sum(0), 1.0, atol=1e-12)
    assert np.allclose((R * beam.supports[:, None]).sum(0), u, atol=1e-11)


@pytest.mark.parametrize("spans,expected", [((10.0, 10.0), 12.0), ((12.0, 16.0, 12.0), 1.3 * 40 / 3),
                                            ((10.0,) * 4, 14.0), ((10.0,) * 5, 15.0), ((10.0,) * 6, 15.0),
                                            ((5.0, 30.0), 30.0), ((25.0,), 25.0)])
def test_determinant_length_of_table_6_2(spans, expected):
    """L_Φ = k L_m, k = 1.2 .. 1.5 for 2 .. 5+ spans, not less than the longest span; one span: L."""
    assert determinant_length_m(spans) == pytest.approx(expected, rel=1e-15)


def test_modal_weights_are_the_curvature_and_the_shape():
    """w_j of the moment at x equals -EJ φ_j''(x) and of the deflection φ_j(x) (1e-9 of the largest)."""
    b = Bridge.continuous(SPANS, EJ, 15000.0, 0.02, n_modes=6)
    beam = ContinuousBeam(SPANS, EJ)
    x = np.array([5.0, 20.0, 33.0])
    effs = [DeckEffect("M", float(t)) for t in x] + [DeckEffect("w", float(t)) for t in x]
    W = modal_weights(b, beam, effs)
    phi, _, pxx = b.shapes(x)
    ej = np.array([EJ[0], EJ[1], EJ[2]])
    for c in range(3):
        ref = -ej[c] * pxx[c]
        assert np.max(np.abs(W[:, c] - ref)) <= 1e-9 * np.max(np.abs(ref))
        assert np.max(np.abs(W[:, 3 + c] - phi[c])) <= 1e-9


def test_one_span_deck_sweep_matches_the_exact_envelope():
    """A deck of one span swept at midspan: the acceleration sampled at 24 steps per period of the top
    mode lies within 1.5 % below the exact envelope (adm_sim.integrate.envelope) and at most 0.1 % above
    it (RK4's own error: 2e-4 measured); the static midspan moment, sampled at the same steps, lies
    within 1e-3 below the exact one."""
    from adm_sim.integrate.envelope import moving_load_envelope

    L, n0, mu = 15.0, 8.26, 19042.0
    EJ1 = mu * (2 * L**2 * n0 / np.pi) ** 2
    deck = Bridge.continuous([L], EJ1, mu, 0.0185, n_modes=3, damping_model="modal")
    single = Bridge(span_m=L, EJ_Nm2=EJ1, mass_per_length_kg_m=mu, damping_ratio=0.0185, n_modes=3,
                    damping_model="modal")
    t = load_train("ICE-2")
    v = np.arange(250.0, 320.0, 5.0)
    sw = deck_sweep(deck, ContinuousBeam([L], [EJ1]), [DeckEffect("M", 7.5)], t.axle_offsets_m, t.axle_loads_n, v)
    env = moving_load_envelope(single, t.axle_offsets_m, t.axle_loads_n, v, where="midspan")
    rel = sw.max_acc_midspan_m_s2[:, 0] / env.max_acc_m_s2 - 1
    assert rel.max() <= 1e-3 and rel.min() >= -0.015
    from adm_sim.design.design_loads import train_midspan_max
    exact = train_midspan_max(L, EJ1, t.axle_offsets_m, t.axle_loads_n).moment_Nm
    assert exact * (1 - 1e-3) <= sw.static_max[0] <= exact * (1 + 1e-12)  # sampled at the steps (2.6e-4 below)


def test_axle_groups_and_refusals():
    """The longest axle group (HSLM-A: max(bogie spacing, 3 m)); a span shorter than it, HSLM-B, additional
    damping and a mode count above 50 are refused in one line naming the value."""
    assert axle_group_m(load_train("HSLM-A2")) == 3.5
    deck = Bridge.continuous([2.5, 10.0], 2e10, 15000.0, 0.02)
    with pytest.raises(InputError, match=r"spans\[0\]: 2.5 m is shorter than the longest axle group of HSLM-A1 \(3 m\)"):
        run_deck_check(deck, 300, [load_train("HSLM-A1")])
    deck = Bridge.continuous([12.0, 16.0], 2e10, 15000.0, 0.02)
    with pytest.raises(InputError, match=r"damping adm: .*allowed --damping none"):
        run_deck_check(deck, 300, [load_train("HSLM-A1")], damping="adm")
    with pytest.raises(InputError, match=r"n_modes: 51 is out of range; allowed an integer in \[1, 50\]"):
        run_deck_check(deck, 300, [load_train("HSLM-A1")], n_modes=51)


@pytest.mark.slow
def test_deck_check_names_spans_modes_and_every_effect():
    """The whole check on two spans: text and JSON name the spans and the modes; every effect has a
    ratio; the supports' effects are there; the screening is stated as not applicable."""
    deck = Bridge.continuous([12.0, 16.0], 2.5e10, 15000.0, 0.02, name="D2")
    res = run_deck_check(deck, 250, [load_train("HSLM-A1")])
    text = res.summary()
    f, m = deck.frequencies_hz, deck.modal_mass_kg
    assert f"modes: 1 ({f[0]:.3f} Hz, {m[0] / 1000:.5g} t), 2 ({f[1]:.3f} Hz, {m[1] / 1000:.5g} t)" in text
    assert d_modes_equal(res.to_dict(), deck)
    assert "spans 1..2 = 12+16 m" in text and "modes: 1 (" in text
    assert "hogging M support 1" in text and "reaction support 2" in text
    assert "Figs. 6.9/6.10): not applicable" in text
    d = res.to_dict()
    assert d["spans_m"] == [12.0, 16.0] and d["modes"] == list(range(1, deck.n_modes + 1))
    assert len(d["en1991_2_6_4_6_5_effects"]) == len(deck_effects(ContinuousBeam([12.0, 16.0], 2.5e10)))
    assert d["L_phi_m"] == pytest.approx(max(1.2 * 14.0, 16.0))
    assert all(e["ratio"] > 0 for e in d["en1991_2_6_4_6_5_effects"])


def d_modes_equal(d, bridge):
    """The JSON's frequencies and modal masses are the bridge's, one per mode used (exact: tolist)."""
    return (d["frequencies_hz"] == bridge.frequencies_hz.tolist() and d["modal_masses_kg"] == bridge.modal_mass_kg.tolist()
            and len(d["frequencies_hz"]) == len(d["modes"]))


def test_one_span_check_names_every_mode_and_its_modal_mass():
    """Issue 37 item 1 on the single-span check: the text's ``modes:`` line and the JSON carry each
    mode's frequency and modal mass. B1 (L = 15 m, n0 = 8.262 Hz, mu = 19042 kg/m): f_j = j^2 n0,
    modal mass mu L / 2 = 142815 kg for every sine mode (closed forms, to 1e-12)."""
    b1 = named_bridge("B1")
    res = run_check(b1, 250.0, [moving_loads([0.0], [100e3], name="one axle")])
    d = res.to_dict()
    assert d["spans_m"] == [15.0] and d_modes_equal(d, b1)
    np.testing.assert_allclose(d["frequencies_hz"], [b1.n0_hz * j * j for j in (1, 2, 3)], rtol=1e-12)
    np.testing.assert_allclose(d["modal_masses_kg"], [19042.0 * 15.0 / 2.0] * 3, rtol=1e-12)
    line = next(s for s in summary(res).splitlines() if s.startswith("modes: "))
    assert line.startswith("modes: 1 (8.262 Hz, 142.81 t), 2 (33.049 Hz, 142.81 t), 3 (74.359 Hz, 142.81 t) "
                           "(frequency, modal mass; EN 1990 A2.4.4.2.1")
