"""Exact modes of continuous decks (src/adm_sim/model/spans.py) against closed forms and an
independent finite-element beam (tests/fe_beam.py)."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from fe_beam import FEBeam
from adm_sim.model.spans import (clamped_count, deck_modes, gauss_points, rule_mode_count,
                                 span_rotation_stiffness)

EJ, MU = 2.0e10, 1.5e4  # N m^2, kg/m (a concrete deck of ~15 m spans)


def lam(modes, span=0):
    """Frequency parameters beta L of every mode in span ``span``."""
    return modes.beta_1_m[:, span] * modes.spans_m[span]


def test_single_span_is_the_sine_series():
    """One span: phi_j = sin(j pi x / L) to 1e-10, omega_j = (j pi / L)^2 sqrt(EJ / mu) (Eq. 4, 18)
    to 1e-13, modal mass mu L / 2 to 1e-12."""
    L, n = 17.5, 8
    m = deck_modes([L], [EJ], [MU], n)
    j = np.arange(1, n + 1)
    assert np.allclose(m.omega_rad_s, (j * math.pi / L) ** 2 * math.sqrt(EJ / MU), rtol=1e-13, atol=0)
    x = np.linspace(0.0, L, 1001)
    phi, phx, phxx = m.shapes(x)
    k = j * math.pi / L
    assert np.abs(phi - np.sin(np.outer(x, k))).max() < 1e-10
    assert np.abs(phx / k - np.cos(np.outer(x, k))).max() < 1e-10
    assert np.abs(phxx / k**2 + np.sin(np.outer(x, k))).max() < 1e-10
    assert np.allclose(m.modal_mass_kg, MU * L / 2, rtol=1e-12, atol=0)


def test_span_stiffness_against_the_span_solved_directly():
    """The closed-form dynamic stiffness (k_ii, k_ij) equals the end moments of the span's exact
    solution solved as a 4x4 system in cosh/sinh (another basis), to 1e-9 relative; static limit
    4 EJ / L, 2 EJ / L."""
    L = 12.0
    for lam_ in (0.7, 2.0, 3.9, 5.5, 9.1):
        beta = lam_ / L
        omega = beta**2 * math.sqrt(EJ / MU)
        b = beta
        # w = A cosh + B sinh + C cos + D sin; w(0)=0, w'(0)=1, w(L)=0, w'(L)=0 -> m_a = k_ii, m_b = k_ij
        ch, sh, c, s = math.cosh(lam_), math.sinh(lam_), math.cos(lam_), math.sin(lam_)
        A = np.array([[1, 0, 1, 0], [0, b, 0, b], [ch, sh, c, s], [b * sh, b * ch, -b * s, b * c]])
        A_, B_, C_, D_ = np.linalg.solve(A, [0, 1, 0, 0])
        w2_0 = b * b * (A_ - C_)
        w2_L = b * b * (A_ * ch + B_ * sh - C_ * c - D_ * s)
        kii, kij = span_rotation_stiffness(EJ, MU, L, omega)
        assert kii == pytest.approx(-EJ * w2_0, rel=1e-9)
        assert kij == pytest.approx(EJ * w2_L, rel=1e-9)
    kii, kij = span_rotation_stiffness(EJ, MU, L, 1e-9)
    assert (kii, kij) == pytest.approx((4 * EJ / L, 2 * EJ / L), rel=1e-9)


def test_clamped_count_against_the_clamped_roots():
    """J0 counts the roots of cos l cosh l = 1 (4.7300, 7.8532, 10.9956, ...) below l."""
    roots = [brentq(lambda x: math.cos(x) * math.cosh(x) - 1.0, (k + 0.5) * math.pi - 0.3, (k + 0.5) * math.pi + 0.3)
             for k in range(1, 8)]
    assert roots[0] == pytest.approx(4.7300, abs=1e-4)
    for lam_ in np.linspace(0.1, 25.0, 997):
        assert clamped_count(lam_) == sum(r < lam_ for r in roots)


def test_two_equal_spans_against_a_printed_table():
    """Two equal spans: the symmetric modes are the clamped-hinged span's. W. T. Thomson, Theory of
    Vibration with Applications (Taylor & Francis, 2010), Table 9.5-1, row "Clamped-hinged", prints
    (beta l)^2 = 15.4, 50.0 (and 104.0 for the third: the exact 104.25 rounds to 104.2, so the
    table's third entry is not held to its printed digits here), and row "Simply supported" 9.87 and
    39.5 for the antisymmetric modes; the deck's modes 1-4 match them to the printed digits."""
    m = deck_modes([15.0, 15.0], [EJ, EJ], [MU, MU], 4)
    bl2 = lam(m) ** 2
    assert round(bl2[0], 2) == 9.87 and round(bl2[2], 1) == 39.5  # simply supported row
    assert round(bl2[1], 1) == 15.4 and round(bl2[3], 1) == 50.0  # clamped-hinged row


def test_two_equal_spans_closed_form():
    """Two equal spans: the antisymmetric modes are the single span's (beta L = k pi), the
    symmetric ones the pinned-clamped span's, tan l = tanh l (beta L = 3.9266, 7.0686), to 1e-12."""
    m = deck_modes([15.0, 15.0], [EJ, EJ], [MU, MU], 4)
    pc = [brentq(lambda x: math.tan(x) - math.tanh(x), a, a + 1.0, xtol=1e-15) for a in (3.5, 6.6)]
    assert pc[0] == pytest.approx(3.9266, abs=1e-4)
    assert lam(m) == pytest.approx([math.pi, pc[0], 2 * math.pi, pc[1]], rel=1e-12)
    assert m.omega_rad_s[0] == pytest.approx(deck_modes([15.0], [EJ], [MU], 1).omega_rad_s[0], rel=1e-13)


@pytest.mark.parametrize("n_spans", [3, 4, 5, 6])
def test_equal_spans_periodic_closed_form(n_spans):
    """N equal spans: with theta_n = cos(eps (n + 1/2)) the support equations hold for
    cos(eps) = -k_ii / k_ij, eps = k pi / N (k = 0 .. N-1): in every cluster one mode per k, found
    here by brentq on that scalar equation (three spans: 3.1416, 3.5564, 4.2975; four: 3.1416,
    3.3932, 3.9266, 4.4633), to 1e-11."""
    m = deck_modes([12.0] * n_spans, [EJ] * n_spans, [MU] * n_spans, 2 * n_spans)

    def ratio(x):
        s, c, t = math.sin(x), math.cos(x), math.tanh(x)
        return -(s - c * t) / (t - s / math.cosh(x))

    ref = []
    for cluster in (0, 1):
        lo, hi = (cluster + 1) * math.pi, (cluster + 1.5) * math.pi + 0.12  # a cluster: k pi .. clamped root
        ref.append((cluster + 1) * math.pi)
        for k in range(1, n_spans):
            target = math.cos(k * math.pi / n_spans)
            xs = np.linspace(lo + 1e-9, hi, 4001)
            v = np.array([ratio(x) - target for x in xs])
            i = np.flatnonzero((np.sign(v[:-1]) != np.sign(v[1:])) & (np.abs(v[:-1]) < 2) & (np.abs(v[1:]) < 2))
            assert i.size == 1
            ref.append(brentq(lambda x: ratio(x) - target, xs[i[0]], xs[i[0] + 1], xtol=1e-15))
    ref = np.sort(ref)
    if n_spans == 3:
        assert ref[1:3] == pytest.approx([3.5564, 4.2975], abs=1e-4)
    if n_spans == 4:
        assert ref[1:4] == pytest.approx([3.3932, 3.9266, 4.4633], abs=1e-4)
    assert lam(m) == pytest.approx(ref, rel=1e-11)


def test_unequal_spans_against_finite_elements():
    """Three unequal spans with their own EJ and mu: the first 9 frequencies against an independent
    Hermite-cubic finite-element beam (consistent mass, so its frequencies lie above the exact ones
    and converge as h^4). With 10 and 20 elements per span the FE error relative to the exact modes
    is positive, below 1e-4 at 20, and falls 2^4 = 16 times (14..17) when the mesh is halved: the
    exact modes are the FE limit, not another approximation (an error of 1e-7 in them would show
    as a ratio off 16 on the first modes, whose FE error at 20 elements is ~5e-7)."""
    spans, EJs, mus = [11.0, 16.0, 9.5], [1.2e10, 3.1e10, 0.9e10], [1.1e4, 1.6e4, 0.95e4]
    m = deck_modes(spans, EJs, mus, 9)
    e10 = FEBeam(spans, EJs, mus, 10).frequencies_rad_s(9) / m.omega_rad_s - 1
    e20 = FEBeam(spans, EJs, mus, 20).frequencies_rad_s(9) / m.omega_rad_s - 1
    assert np.all(e20 > 0) and np.all(e20 < 1e-4)
    assert np.all((e10 / e20 > 14.0) & (e10 / e20 < 17.0))


def test_modes_are_orthogonal_and_satisfy_their_rayleigh_quotient():
    """Unequal spans, EJ and mu per span: sum_i mu_i int phi_j phi_k = delta_jk M_j to 1e-8 of
    sqrt(M_j M_k), and sum_i EJ_i int phi_j'' phi_k'' = delta_jk omega_j^2 M_j to 1e-8."""
    spans, EJs, mus = [8.0, 13.0, 13.0, 21.0, 7.0], [0.8e10, 2.0e10, 2.4e10, 6.0e10, 0.7e10], \
        [0.9e4, 1.3e4, 1.4e4, 2.2e4, 0.8e4]
    m = deck_modes(spans, EJs, mus, 24)
    x, w = gauss_points(m)
    phi, _, phxx = m.shapes(x)
    G = (w[:, None] * phi).T @ phi
    assert np.allclose(np.diag(G), m.modal_mass_kg, rtol=1e-12)
    norm = np.sqrt(np.outer(m.modal_mass_kg, m.modal_mass_kg))
    assert np.abs(G / norm - np.eye(24)).max() < 1e-8
    span_of = np.searchsorted(m.supports_m, x, side="right") - 1
    ej_over_mu = (m.EJ_Nm2 / m.mu_kg_m)[span_of]
    Kmat = (w[:, None] * ej_over_mu[:, None] * phxx).T @ phxx
    assert np.abs(Kmat / (norm * np.sqrt(np.outer(m.omega_rad_s**2, m.omega_rad_s**2))) - np.eye(24)).max() < 1e-8


def test_shapes_continuous_at_the_supports_and_normalised():
    """phi = 0 at every support, phi' and EJ phi'' continuous across the intermediate supports
    (1e-9 of their scale), max |phi| = 1 and phi'(0) > 0 for every mode."""
    spans, EJs, mus = [10.0, 14.0, 12.0], [1.0e10, 2.0e10, 1.5e10], [1.0e4, 1.4e4, 1.2e4]
    m = deck_modes(spans, EJs, mus, 12)
    phi_s = m.shapes(m.supports_m)[0]
    assert np.abs(phi_s).max() < 1e-10
    for k in (1, 2):
        xs = m.supports_m[k]
        left, right = (m.shapes(np.array([xs - d]))for d in (1e-9, -1e-9))
        scale1 = np.abs(m.beta_1_m).max()
        assert np.abs(left[1] - right[1]).max() < 1e-6 * scale1
        assert np.abs(m.EJ_Nm2[k - 1] * left[2] - m.EJ_Nm2[k] * right[2]).max() < 1e-6 * EJ * scale1**2
    x, phi = m.table(400)[:2]
    assert np.abs(phi).max() <= 1.0 + 1e-12
    for j in range(12):  # the true maximum, refined independently of the module's Newton step
        k = int(np.argmax(np.abs(phi[:, j])))
        r = minimize_scalar(lambda z: -abs(m.shapes(np.array([z]))[0][0, j]), bounds=(x[k - 1], x[k + 1]),
                            method="bounded", options={"xatol": 1e-10})
        assert -r.fun == pytest.approx(1.0, abs=1e-10)
    assert np.all(m.shapes(np.array([0.0]))[1] > 0)


def test_tables_equal_the_shapes():
    """The space-grid tables are the shapes at the grid's abscissae (bit for bit), supports included."""
    m = deck_modes([10.0, 12.0], [EJ, EJ], [MU, MU], 6)
    x, phi, phx, phxx = m.table(50)
    assert x.size == 101 and x[50] == 10.0 and x[-1] == 22.0
    for a, b in zip((phi, phx, phxx), m.shapes(x)):
        assert np.array_equal(a, b)


def test_rule_mode_count():
    """Every mode up to max(30 Hz, 1.5 n0), at least three: counted from the frequencies."""
    # two spans of 25 m (n0 = 2.9 Hz): the five modes up to 30 Hz
    f = deck_modes([25.0, 25.0], [EJ, EJ], [MU, MU], 12).frequencies_hz
    assert int(np.sum(f <= 30.0)) == 5
    assert rule_mode_count([25.0, 25.0], [EJ, EJ], [MU, MU]) == 5
    # two spans of 15 m (n0 = 8.1 Hz): two modes below 30 Hz, the third mode kept
    f = deck_modes([15.0, 15.0], [EJ, EJ], [MU, MU], 12).frequencies_hz
    assert int(np.sum(f <= 30.0)) == 2
    assert rule_mode_count([15.0, 15.0], [EJ, EJ], [MU, MU]) == 3
    # a stiff short deck (n0 > 20 Hz): 1.5 n0 rules
    m2 = deck_modes([5.0, 5.0], [EJ, EJ], [MU, MU], 6)
    n0 = m2.frequencies_hz[0]
    assert rule_mode_count([5.0, 5.0], [EJ, EJ], [MU, MU]) == max(3, int(np.sum(m2.frequencies_hz <= max(30, 1.5 * n0))))


def test_phi_alone_equals_the_shapes():
    """``DeckModes.phi`` (the MLM's loads) equals the first array of ``shapes`` to 1e-14 at random
    points of a three-span deck, supports included."""
    m = deck_modes([10.0, 14.0, 12.0], [1.0e10, 2.0e10, 1.5e10], [1.0e4, 1.4e4, 1.2e4], 10)
    x = np.concatenate([np.random.default_rng(1).uniform(0.0, 36.0, 500), m.supports_m])
    assert np.abs(m.phi(x) - m.shapes(x)[0]).max() < 1e-14
