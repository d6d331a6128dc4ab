"""EN 1991-2 6.4.6.5(3) design comparison (adm_sim.design.design_loads) against independent references.

References, none of them the code under test:
* hand calculations written out below (Φ2/Φ3 of 6.4.5.2, φ'' and φ' of Annex C, LM71 on 20 m);
* Φ3(35 m) = 1.1079, a value quoted from a design report ("BG40") in a public repository that
  implements Φ3 on its own; the Annex C formulas as coded in bacadra/bacadra's EN 15528 module
  (K, φ', α, φ'' identical to ours) and φ'_dyn = y_dyn/y_stat - 1 in addeKTH/BeamDyn
  dynamicfactor.js were read, not imported;
* statics: reactions and moments summed from the loads (moment), and the modal (Fourier sine)
  series of the static deflection (deflection), both written here from first principles, with a
  dense scan over positions refined by scipy's bounded scalar minimiser.
"""

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from adm_sim.design import design_loads as dl
from adm_sim.errors import InputError
from adm_sim.model.hslm import hslm_axles

# ---------------------------------------------------------------- independent references


def statics_midspan_moment(L, points, udls):
    """Midspan moment from equilibrium of the left half. points: [(x, P)], udls: [(x1, x2, q)],
    x from the left support; parts off the span are dropped."""
    pts = [(x, P) for x, P in points if 0.0 <= x <= L]
    segs = [(max(0.0, a), min(L, b), q) for a, b, q in udls if min(L, b) > max(0.0, a)]
    # reaction at the left support: moments about the right support
    RA = sum(P * (L - x) for x, P in pts) / L + sum(q * (b - a) * (L - (a + b) / 2) for a, b, q in segs) / L
    M = RA * L / 2
    M -= sum(P * (L / 2 - x) for x, P in pts if x < L / 2)
    for a, b, q in segs:
        b2 = min(b, L / 2)
        if b2 > a:
            M -= q * (b2 - a) * (L / 2 - (a + b2) / 2)
    return M


def modal_midspan_deflection(L, EJ, points, udls, n_modes=4001):
    """Static midspan deflection by the sine series of the simply supported beam:
    w(L/2) = sum_j (2/L) p_j sin(j pi/2) (L / j pi)^4 / EJ, p_j = int p(x) sin(j pi x / L) dx."""
    j = np.arange(1, n_modes + 1, 2, dtype=float)  # even modes vanish at midspan
    pj = np.zeros_like(j)
    for x, P in points:
        if 0.0 <= x <= L:
            pj += P * np.sin(j * np.pi * x / L)
    for a, b, q in udls:
        a, b = max(0.0, a), min(L, b)
        if b > a:
            pj += q * L / (j * np.pi) * (np.cos(j * np.pi * a / L) - np.cos(j * np.pi * b / L))
    return float(np.sum(2.0 / L * pj * np.sin(j * np.pi / 2) * (L / (j * np.pi)) ** 4) / EJ)


def lm71_loads(L, d, alpha=1.0):
    """LM71 of Fig. 6.2 with its point-force group centred d from midspan: points and UDL pieces."""
    c = L / 2 + d
    points = [(c + e, alpha * 250e3) for e in (-2.4, -0.8, 0.8, 2.4)]
    udls = [(-1e3, c - 3.2, alpha * 80e3), (c + 3.2, L + 1e3, alpha * 80e3)]
    return points, udls


def scan_max(f, lo, hi, n):
    """Largest f on a grid of n points, refined by a bounded minimiser around the best point."""
    x = np.linspace(lo, hi, n)
    v = np.array([f(t) for t in x])
    i = int(np.argmax(v))
    h = (hi - lo) / (n - 1)
    r = minimize_scalar(lambda t: -f(t), bounds=(max(lo, x[i] - h), min(hi, x[i] + h)), method="bounded",
                        options={"xatol": 1e-9})
    return max(v[i], -r.fun)


# ---------------------------------------------------------------- Φ2, Φ3 (6.4.5.2)


def test_phi2_phi3_hand_values_and_bounds():
    # L = 20 m: sqrt(20) - 0.2 = 4.2721360; 1.44 / 4.2721360 = 0.3370680; 2.16 / 4.2721360 = 0.5056020
    assert dl.phi2(20.0) == pytest.approx(1.44 / (math.sqrt(20.0) - 0.2) + 0.82, rel=1e-15)
    assert dl.phi2(20.0) == pytest.approx(1.157068, abs=1e-6)
    assert dl.phi3(20.0) == pytest.approx(1.235602, abs=1e-6)
    # L = 4 m: sqrt(4) - 0.2 = 1.8, Φ2 = 0.8 + 0.82 = 1.62 (below the 1.67 cap), Φ3 = 1.2 + 0.73 = 1.93
    assert dl.phi2(4.0) == pytest.approx(1.62, abs=1e-12)
    assert dl.phi3(4.0) == pytest.approx(1.93, abs=1e-12)
    # caps: Φ2 = 1.67 for LΦ <= (0.2 + 1.44/0.85)^2 = 3.588 m, Φ3 = 2.00 for LΦ <= (0.2 + 2.16/1.27)^2 = 3.613 m
    assert dl.phi2(3.0) == 1.67 and dl.phi2(0.5) == 1.67 and dl.phi2(0.01) == 1.67
    assert dl.phi3(3.0) == 2.00 and dl.phi3(0.01) == 2.00
    assert dl.phi2(3.59) == pytest.approx(1.44 / (math.sqrt(3.59) - 0.2) + 0.82) and dl.phi2(3.59) < 1.67
    # floor: both reach 1.00 at sqrt(LΦ) = 8.2, LΦ = 67.24 m, and stay there
    assert dl.phi2(67.24) == pytest.approx(1.0, abs=1e-12) and dl.phi3(67.24) == pytest.approx(1.0, abs=1e-12)
    assert dl.phi2(100.0) == 1.0 and dl.phi3(100.0) == 1.0 and dl.phi2(66.0) > 1.0
    # an independent design report (BG40): Φ3 = 1.1079 for LΦ = 35 m
    assert dl.phi3(35.0) == pytest.approx(1.1079, abs=5e-5)
    assert dl.dynamic_factor(20.0, "careful") == dl.phi2(20.0)
    assert dl.dynamic_factor(20.0, "standard") == dl.phi3(20.0)


# ---------------------------------------------------------------- Annex C


def test_phi_double_prime_hand_values():
    # L n0 = 80: the second term vanishes: φ'' = 0.56 e^-1 (L = 10) and 0.56 e^-4 (L = 20)
    assert dl.phi_double_prime(10.0, 8.0, 40.0) == pytest.approx(0.56 * math.exp(-1.0), rel=1e-14)
    assert dl.phi_double_prime(10.0, 8.0, 40.0) == pytest.approx(0.2060125, abs=1e-7)
    assert dl.phi_double_prime(20.0, 4.0, 83.3) == pytest.approx(0.0102568, abs=1e-7)
    # L = 5, n0 = 10: 56 e^-0.25 = 43.61284; 50 (50/80 - 1) e^-(1/16) = -17.61400; sum / 100 = 0.2599885
    assert dl.phi_double_prime(5.0, 10.0, 40.0) == pytest.approx(0.2599885, abs=1e-6)
    # α = v / 22 below 22 m/s: half the value at 11 m/s, zero at rest; independent of v above 22 m/s
    full = dl.phi_double_prime(5.0, 10.0, 40.0)
    assert dl.phi_double_prime(5.0, 10.0, 11.0) == pytest.approx(0.5 * full, rel=1e-14)
    assert dl.phi_double_prime(5.0, 10.0, 0.0) == 0.0
    assert dl.phi_double_prime(5.0, 10.0, 22.0) == full == dl.phi_double_prime(5.0, 10.0, 100.0)
    # clamp at 0: L = 5, n0 = 1: 43.61 + 50 (5/80 - 1) e^-(1/16) = 43.61 - 44.03 < 0
    assert dl.phi_double_prime(5.0, 1.0, 40.0) == 0.0
    # long spans: both exponentials die, e^-25 50 (100 x 1.5 / 80 - 1) / 100 = 6e-12
    assert dl.phi_double_prime(100.0, 1.5, 83.3) < 1e-10


def test_phi_prime_annex_c():
    # K = v / (2 L n0) = 0.5 -> 0.5 / (0.5 + 0.0625) = 0.888...
    assert dl.phi_prime(20.0, 2.0, 40.0) == pytest.approx(0.5 / (1 - 0.5 + 0.5**4), rel=1e-14)
    assert dl.phi_prime(20.0, 2.0, 40.0) == pytest.approx(8.0 / 9.0, rel=1e-14)
    assert dl.phi_prime(10.0, 1.0, 15.2) == 1.325  # K = 0.76
    below = dl.phi_prime(10.0, 1.0, 15.19999)
    assert below == pytest.approx(1.325, abs=1e-4)  # (C.3) and (C.4) meet at K = 0.76 to 1e-4


def test_phi_dyn_prime_is_the_increment():
    assert dl.phi_dyn_prime(1.644e-3, 1.0e-3) == pytest.approx(0.644, abs=1e-12)
    # per-speed maxima against one static value: the largest ratio, minus one; sign of y ignored
    assert dl.phi_dyn_prime([1.0, 1.3, -1.5, 1.2], 1.2) == pytest.approx(0.25, abs=1e-12)
    assert dl.phi_dyn_prime([2.0, 3.0], [1.0, 2.5]) == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(InputError, match=r"max_stat: .*non-zero"):
        dl.phi_dyn_prime(1.0, 0.0)
    with pytest.raises(InputError, match=r"max_stat: 3 values do not match the 2"):
        dl.phi_dyn_prime([1.0, 2.0], [1.0, 1.0, 1.0])
    with pytest.raises(InputError, match=r"max_dyn"):
        dl.phi_dyn_prime([1.0, float("nan")], 1.0)


# ---------------------------------------------------------------- statics, closed forms


def test_eurocode_adm_in_the_core_hand_values():
    """EN 1991-2 6.4.6.3.1 Eq. (6.13) by hand: L = 15 m gives (0.2805 - 0.144) / (1 - 0.6615 - 0.99
    + 0.860625) = 0.1365 / 0.209125 %; L = 10 m gives 0.123 / (1 - 0.441 - 0.44 + 0.255) = 0.123 / 0.374 %; 0 from 30 m on (and in the
    dip just below, where Fig. 6.15 ends at 0); adm_calib.reference re-exports the same function."""
    assert dl.adm_delta_zeta_pct(15.0) == pytest.approx(0.1365 / 0.209125, rel=1e-12)
    assert dl.adm_delta_zeta_pct(10.0) == pytest.approx(0.123 / 0.374, rel=1e-12)
    assert dl.adm_delta_zeta_pct(30.0) == 0.0 and dl.adm_delta_zeta_pct(29.5) == 0.0
    with pytest.raises(InputError, match=r"^span_m: -5 m is out of range"):
        dl.adm_delta_zeta_pct(-5.0)
    from adm_calib.reference import adm_delta_zeta_pct

    assert adm_delta_zeta_pct is dl.adm_delta_zeta_pct


@pytest.mark.parametrize("a", [0.0, 1.3, 5.0, 10.0, 14.2])
def test_point_load_closed_forms_against_statics_and_modes(a):
    L, EJ, P = 20.0, 3.3e10, 170e3
    M, w = dl.point_load_midspan(L, EJ, a, P)
    assert float(M) == pytest.approx(statics_midspan_moment(L, [(a, P)], []), rel=1e-13, abs=1e-6)
    assert float(w) == pytest.approx(modal_midspan_deflection(L, EJ, [(a, P)], []), rel=1e-11, abs=1e-18)


def test_udl_closed_forms_against_statics_and_modes():
    L, EJ, q = 17.5, 2.1e10, 80e3
    M, w = dl.udl_midspan(L, EJ, q)
    assert M == pytest.approx(q * L * L / 8, rel=1e-14)
    assert w == pytest.approx(5 * q * L**4 / (384 * EJ), rel=1e-14)
    assert w == pytest.approx(modal_midspan_deflection(L, EJ, [], [(0.0, L, q)]), rel=1e-11)
    for a, b in [(0.0, 3.0), (2.0, 8.75), (5.0, 15.0), (12.0, 17.5)]:
        M, w = dl.udl_midspan(L, EJ, q, a, b)
        assert M == pytest.approx(statics_midspan_moment(L, [], [(a, b, q)]), rel=1e-12)
        assert w == pytest.approx(modal_midspan_deflection(L, EJ, [], [(a, b, q)]), rel=1e-10)


# ---------------------------------------------------------------- LM71


def test_lm71_20m_hand_calculation():
    L, EJ = 20.0, 1.0e10
    r = dl.lm71_midspan(L, EJ)
    # Moment, an axle at midspan (group shifted 0.8 m): axles at -1.6, 0, 1.6, 3.2 m from midspan,
    # ordinates L/4 - |x|/2 = 4.2, 5.0, 4.2, 3.4 -> 250 kN x 16.8 m = 4200 kNm; the 6.4 m gap
    # [-2.4, 4.0] takes 5 x 6.4 - (2.4^2 + 4.0^2) / 4 = 26.56 m^2 out of L^2/8 = 50 m^2:
    # 80 kN/m x 23.44 m^2 = 1875.2 kNm. Total 6075.2 kNm.
    assert r.moment_Nm == pytest.approx(6075.2e3, rel=1e-13)
    assert abs(r.moment_position_m) == pytest.approx(0.8, abs=1e-12)
    # The symmetric placement is q 0.8^2 / 2 = 25.6 kNm lower: gap 32 - 2 x 3.2^2 / 4 = 26.88 m^2,
    # 4200 + 80 x 23.12 = 6049.6 kNm.
    assert statics_midspan_moment(L, *lm71_loads(L, 0.0)) == pytest.approx(6049.6e3, rel=1e-13)
    # Deflection, symmetric: a = 9.2 m (x2) and 7.6 m (x2): a (3L^2 - 4a^2) = 7925.248 and 7364.096;
    # 250 kN x 2 x 15289.344 = 7.644672e9. UDL outside a in [6.8, 10] on both sides:
    # 100000 - 2 x [F(10) - F(6.8)], F(a) = 600 a^2 - a^4: 100000 - 2 x (50000 - 25605.8624) = 51211.7248;
    # 80 kN/m x 51211.7248 = 4.096937984e9. w = 1.1741609984e10 / (48 EJ) = 24.4616875 mm.
    assert r.deflection_m == pytest.approx(1.1741609984e10 / (48 * EJ), rel=1e-12)
    assert r.deflection_m == pytest.approx(0.0244616875, rel=1e-8)  # the rounded mm value
    # α scales both effects
    r133 = dl.lm71_midspan(L, EJ, 1.33)
    assert r133.moment_Nm == pytest.approx(1.33 * 6075.2e3, rel=1e-13)
    assert r133.deflection_m == pytest.approx(1.33 * r.deflection_m, rel=1e-13)


@pytest.mark.parametrize("L", [1.0, 3.0, 5.0, 6.4, 7.3, 12.0, 39.0])
def test_lm71_maxima_against_brute_force(L):
    EJ = 2.0e10
    r = dl.lm71_midspan(L, EJ)
    lim = L / 2 + 3.2 + 0.5  # beyond: the UDL alone
    M_ref = scan_max(lambda d: statics_midspan_moment(L, *lm71_loads(L, d)), -lim, lim, 4001)
    w_ref = scan_max(lambda d: modal_midspan_deflection(L, EJ, *lm71_loads(L, d), n_modes=1201), -lim, lim, 801)
    # the moment peaks at a kink, where the refined scan stops ~1e-9 short: exact >= scan, equal to 1e-8
    assert r.moment_Nm >= M_ref * (1 - 1e-14) and r.moment_Nm == pytest.approx(M_ref, rel=1e-8)
    assert r.deflection_m == pytest.approx(w_ref, rel=2e-8)  # series truncated at mode 1201: ~1e-10
    # the position reported reproduces the maximum
    assert statics_midspan_moment(L, *lm71_loads(L, r.moment_position_m)) == pytest.approx(r.moment_Nm, rel=1e-12)


def test_lm71_short_span_only_what_fits():
    # L = 1 m: only one axle fits and the 6.4 m gap covers the span: P L / 4 = 62.5 kNm, P L^3 / (48 EJ)
    EJ = 1.0e9
    r = dl.lm71_midspan(1.0, EJ)
    assert r.moment_Nm == pytest.approx(62.5e3, rel=1e-13)
    assert r.deflection_m == pytest.approx(250e3 / (48 * EJ), rel=1e-13)


# ---------------------------------------------------------------- axle trains


def test_train_moment_is_an_axle_at_midspan_and_deflection_exact():
    L, EJ = 15.0, 1.2e10
    a = np.array([0.0, 2.5, 4.1, 11.0, 13.5, 19.9, 22.4])
    P = np.array([195e3, 195e3, 112e3, 112e3, 140e3, 112e3, 90e3])
    r = dl.train_midspan_max(L, EJ, a, P)
    # independent: every axle at midspan, statics
    M_axle = max(statics_midspan_moment(L, [(L / 2 + ak - ai, p) for ak, p in zip(a, P)], []) for ai in a)
    assert r.moment_Nm == pytest.approx(M_axle, rel=1e-13)
    stop = a[-1] + L
    M_ref = scan_max(lambda s: statics_midspan_moment(L, [(s - ai, p) for ai, p in zip(a, P)], []), 0, stop, 20001)
    assert r.moment_Nm >= M_ref * (1 - 1e-14) and r.moment_Nm == pytest.approx(M_ref, rel=1e-8)
    w_ref = scan_max(lambda s: modal_midspan_deflection(L, EJ, [(s - ai, p) for ai, p in zip(a, P)], []),
                     0, stop, 3001)
    assert r.deflection_m == pytest.approx(w_ref, rel=1e-9)


def test_train_two_axles_hand():
    # two 200 kN axles 3 m apart on 20 m: M = 200 x 5 + 200 x 3.5 = 1700 kNm (one at midspan);
    # w symmetric, a = 8.5 m: 2 x 200e3 x 8.5 x (1200 - 289) / (48 EJ)
    L, EJ = 20.0, 1.0e10
    r = dl.train_midspan_max(L, EJ, [0.0, 3.0], [200e3, 200e3])
    assert r.moment_Nm == pytest.approx(1.7e6, rel=1e-14)
    assert r.deflection_m == pytest.approx(2 * 200e3 * 8.5 * 911 / (48 * EJ), rel=1e-12)


def test_hslm_a1_on_20m_against_brute_force():
    L, EJ = 20.0, 1.0e10
    a, P = hslm_axles("HSLM-A1")
    r = dl.train_midspan_max(L, EJ, a, P)
    stop = a[-1] + L
    M_ref = scan_max(lambda s: statics_midspan_moment(L, [(s - ai, p) for ai, p in zip(a, P)], []), 0, stop, 8001)
    assert r.moment_Nm >= M_ref * (1 - 1e-14) and r.moment_Nm == pytest.approx(M_ref, rel=1e-8)
    # deflection: the series over all axles at 1601 positions, then refined
    w_ref = scan_max(lambda s: modal_midspan_deflection(L, EJ, [(s - ai, p) for ai, p in zip(a, P)], [],
                                                        n_modes=401), 0, stop, 1601)
    assert r.deflection_m == pytest.approx(w_ref, rel=1e-8)


# ---------------------------------------------------------------- 6.4.6.5(3)


def test_design_comparison_hand_case():
    L, EJ = 20.0, 1.0e10
    c = dl.design_comparison("two axles", L, EJ, n0_hz=4.0, axle_offsets_m=[0.0, 3.0],
                             axle_loads_n=[200e3, 200e3], speed_m_s=300 / 3.6,
                             phi_dyn_deflection=0.644, phi_dyn_moment=0.5, maintenance="careful", alpha=1.33)
    phi_dd = 0.56 * math.exp(-4.0)  # L n0 / 80 = 1
    Phi2 = 1.44 / (math.sqrt(20.0) - 0.2) + 0.82
    assert c.phi_dd == pytest.approx(phi_dd, rel=1e-14) and c.Phi == pytest.approx(Phi2, rel=1e-15)
    assert c.train_design_moment_Nm == pytest.approx((1 + 0.5 + phi_dd / 2) * 1.7e6, rel=1e-13)
    w_static = 2 * 200e3 * 8.5 * 911 / (48 * EJ)
    assert c.train_design_deflection_m == pytest.approx((1 + 0.644 + phi_dd / 2) * w_static, rel=1e-12)
    assert c.lm71_design_moment_Nm == pytest.approx(Phi2 * 1.33 * 6075.2e3, rel=1e-13)
    assert c.lm71_design_deflection_m == pytest.approx(Phi2 * 1.33 * 1.1741609984e10 / (48 * EJ), rel=1e-12)
    assert c.governs_moment == "LM71" and c.governs_deflection == "LM71"
    assert c.ratio_moment == pytest.approx((1.5 + phi_dd / 2) * 1.7e6 / (Phi2 * 1.33 * 6075.2e3), rel=1e-12)
    line = c.describe()
    assert "\n" not in line and "two axles" in line and "LM71" in line and "Φ2=1.157" in line
    # standard maintenance uses Φ3; φ'_dyn of the moment defaults to the deflection's
    s = dl.design_comparison("two axles", L, EJ, 4.0, [0.0, 3.0], [200e3, 200e3], 300 / 3.6, 0.644,
                             maintenance="standard")
    assert s.Phi == pytest.approx(2.16 / (math.sqrt(20.0) - 0.2) + 0.73, rel=1e-15)
    assert s.phi_dyn_moment == 0.644 and s.alpha == 1.0


def test_design_comparison_train_can_govern_and_governing_picks_it():
    # 12 axles of 250 kN at 1.6 m (heavier than LM71's 4 + 80 kN/m over 6.4 m), φ'_dyn = 1.0, on 10 m:
    # the train governs; independent numbers: static moment by statics with an axle at midspan.
    L, EJ = 10.0, 5.0e9
    a = np.arange(12) * 1.6
    P = np.full(12, 250e3)
    c = dl.design_comparison("heavy", L, EJ, 8.0, a, P, 40.0, 1.0, maintenance="careful")
    M_axle = max(statics_midspan_moment(L, [(L / 2 + ak - ai, 250e3) for ak in a], []) for ai in a)
    assert c.train_static_moment_Nm == pytest.approx(M_axle, rel=1e-13)
    phi_dd = 0.56 * math.exp(-1.0)
    assert c.train_design_moment_Nm == pytest.approx((2.0 + phi_dd / 2) * M_axle, rel=1e-13)
    assert c.governs_moment == "train" and c.ratio_moment > 1.0
    light = dl.design_comparison("light", L, EJ, 8.0, [0.0], [100e3], 40.0, 0.1)
    assert dl.governing([light, c], "moment") is c
    assert dl.governing([light, c], "deflection") is c
    d = c.to_dict()
    assert d["governs_moment"] == "train" and d["Phi"] == c.Phi


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize("call, match", [
    (lambda: dl.lm71_midspan(0.0, 1e10), r"^span_m: 0 m is out of range; allowed > 0 m$"),
    (lambda: dl.lm71_midspan(-3.0, 1e10), r"^span_m: -3 m is out of range"),
    (lambda: dl.lm71_midspan(10.0, 0.0), r"^EJ_Nm2: 0 N m\^2 is out of range"),
    (lambda: dl.lm71_midspan(10.0, 1e10, 1.2), r"^alpha: 1.2 is not a classification factor of EN 1991-2 "
                                                r"6.3.2\(3\); allowed 0.75, 0.83, 0.91, 1.00, 1.10, 1.21, 1.33, 1.46$"),
    (lambda: dl.dynamic_factor(10.0, "poor"), r"^maintenance: 'poor' is not allowed; allowed 'careful' or 'standard'$"),
    (lambda: dl.phi2(0.0), r"^L_phi_m: 0 m is out of range; allowed > 0 m$"),
    (lambda: dl.phi_double_prime(10.0, 0.0, 40.0), r"^n0_hz: 0 Hz is out of range"),
    (lambda: dl.phi_double_prime(10.0, 5.0, -1.0), r"^v_m_s: -1 m/s is out of range; allowed >= 0 m/s$"),
    (lambda: dl.train_midspan_max(10.0, 1e10, [0.0, 1.0], [1e5]), r"^axle_offsets_m/axle_loads_n: 2 offsets and 1 loads"),
    (lambda: dl.train_midspan_max(10.0, 1e10, [0.0], [-1e5]), r"^axle_loads_n: -100000 N is negative"),
    (lambda: dl.design_comparison("t", 10.0, 1e10, 5.0, [0.0], [1e5], 40.0, -2.0),
     r"^phi_dyn_deflection: -2 - is out of range; allowed >= -1 -$"),
    (lambda: dl.design_comparison("t", 10.0, 1e10, 5.0, [0.0], [1e5], 40.0, 0.5, maintenance="good"),
     r"^maintenance: 'good' is not allowed"),
])
def test_bad_input_one_line(call, match):
    with pytest.raises(InputError, match=match) as exc:
        call()
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("n0,L,v,standard,careful", [
    (8.262, 15.0, 250 / 3.6, 1.6013895031306409, 1.4936572218457267),
    (5.0, 10.0, 20.0, 1.3040349436677368, 1.2767679708358644),
    (3.0, 30.0, 300 / 3.6, 1.8007932717226882, 1.7974649912099858),
    (12.0, 6.0, 160 / 3.6, 1.7856470559107875, 1.6131459642426795),
])
def test_annex_c_pairing_matches_an_independent_implementation(n0, L, v, standard, careful):
    """EN 1991-2 Annex C (cited by content): the dynamic factor of a real train is 1 + φ' + φ''/2 on
    carefully maintained track and 1 + φ' + φ'' with standard maintenance: ``phi_dd_factor`` pairs 1/2 with
    careful and 1 with standard maintenance. Reference values from an independent public
    implementation of the same formulas, bacadra/bacadra ``bacadra/bicad/railb/en155.py`` (class
    ``dfact``, mode 'clea' 1 + φ' + 0.50 φ'', mode 'stan' 1 + φ' + φ''), commit
    0399243f004dadfdd5ce5294cb8c37d1d8373b76, evaluated for these (n0 Hz, LΦ m, v m/s)."""
    for maintenance, ref in (("standard", standard), ("careful", careful)):
        ours = 1.0 + dl.phi_prime(L, n0, v) + dl.phi_dd_factor(maintenance) * dl.phi_double_prime(L, n0, v)
        assert ours == pytest.approx(ref, rel=1e-12)


def test_static_maxima_cached_by_value():
    """train_midspan_max and lm71_midspan are cached by their values (arrays by bytes, shape and dtype): the same
    axles give the same result object; other axles, span or stiffness are computed anew."""
    offs, loads = hslm_axles("HSLM-A7")
    a = dl.train_midspan_max(15.0, 7.694e9, offs, loads)
    assert dl.train_midspan_max(15.0, 7.694e9, np.array(offs, copy=True), list(loads)) is a
    b = dl.train_midspan_max(15.0, 7.694e9, offs[:-1], loads[:-1])
    assert b is not a and b == dl._train_midspan_max(15.0, 7.694e9, np.asarray(offs[:-1], dtype=float),
                                                      np.asarray(loads[:-1], dtype=float))
    assert dl.lm71_midspan(20.0, 1e10, 1.33) is dl.lm71_midspan(20.0, 1e10, 1.33)
    assert dl.lm71_midspan(20.0, 2e10, 1.33).deflection_m == pytest.approx(
        dl.lm71_midspan(20.0, 1e10, 1.33).deflection_m / 2, rel=1e-12)
    key = dl.array_key(np.arange(6.0).reshape(2, 3))
    back = dl.array_from_key(key)
    assert back.shape == (2, 3) and np.array_equal(back, np.arange(6.0).reshape(2, 3)) and not back.flags.writeable
