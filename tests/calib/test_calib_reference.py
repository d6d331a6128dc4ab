"""Reference methods: Eurocode ADM, EADA (Eq. 3) and the lower-bound functions (Eq. 20, Tables B1-B4)."""

import types

import pytest

from adm_sim.model.bridge import named_bridge
from adm_sim.errors import InputError
from adm_sim.inputs.train_files import load_train
from adm_calib import reference as ref

# ---------------------------------------------------------------------- ADM


def test_adm_15m_is_065_pct():
    # EN 1991-2 Fig. 6.15: about 0.65 % at 15 m; hand value 0.1365 / 0.209125.
    assert ref.adm_delta_zeta_pct(15.0) == pytest.approx(0.65, abs=0.01)
    assert ref.adm_delta_zeta_pct(15.0) == pytest.approx(0.1365 / 0.209125, rel=1e-12)


@pytest.mark.parametrize("span", [30.0, 30.5, 40.0, 100.0])
def test_adm_zero_from_30m(span):
    assert ref.adm_delta_zeta_pct(span) == 0.0


def test_adm_never_negative_just_below_30m():
    # the rational function itself is -0.0024 % at 29.8 m; the ADM gives no negative damping
    L = 29.8
    raw = (0.0187 * L - 0.00064 * L**2) / (1 - 0.0441 * L - 0.0044 * L**2 + 0.000255 * L**3)
    assert raw < 0.0
    assert ref.adm_delta_zeta_pct(L) == 0.0


def test_adm_positive_below_30m_and_rejects_bad_span():
    for L in (2.0, 5.0, 10.0, 20.0, 25.0, 29.0):
        assert ref.adm_delta_zeta_pct(L) > 0.0
    with pytest.raises(InputError, match=r"span_m: -5 m is out of range"):
        ref.adm_delta_zeta_pct(-5.0)


# ---------------------------------------------------------------------- lower bounds

# A few rows retyped from the paper (a, b, c, d, upper limit), independent of the data file.
PRINTED = {
    ("ICE-2", "mu3"): (7.282e-4, -0.02644, 0.2478, -0.236, 14.81),
    ("Eurostar", "mu5"): (-0.002322, 0.01912, -0.05523, 0.4709, 8.31),
    ("Railjet", "mu6"): (-0.01547, 0.2867, -1.598, 3.844, 11.37),
    ("ICE-4", "mu1"): (-0.003214, 0.07749, -0.6049, 1.604, 11.58),
}


@pytest.mark.parametrize("key", sorted(PRINTED))
def test_lower_bound_data_match_printed_rows(key):
    lb = ref.lower_bound(*key)
    a, b, c, d, ul = PRINTED[key]
    assert (lb.a, lb.b, lb.c, lb.d, lb.upper_limit_hz) == (a, b, c, d, ul)


def test_every_first_root_matches_printed_upper_limit():
    # The printed upper limits have two decimals: the computed first root must round to them.
    table = ref.lower_bound_table()
    assert sorted(table) == sorted(ref.STUDY_TRAINS)
    n = 0
    for train, rows in table.items():
        assert sorted(rows) == ["mu1", "mu2", "mu3", "mu4", "mu5", "mu6"]
        for mf, lb in rows.items():
            assert lb.first_root_hz == pytest.approx(lb.upper_limit_hz, abs=0.01), (train, mf)
            assert lb.polynomial_pct(lb.first_root_hz) == pytest.approx(0.0, abs=1e-9)
            n += 1
    assert n == 24


def test_lower_bound_values_by_hand():
    # ICE-2 / mu3 at 7.24 Hz (the point named in Section 4.2.1), Eq. (20) by hand:
    n0 = 7.24
    hand = 7.282e-4 * n0**3 - 0.02644 * n0**2 + 0.2478 * n0 - 0.236
    assert ref.lower_bound("ICE-2", "mu3").delta_zeta_pct(n0) == pytest.approx(hand, rel=1e-12)
    assert hand == pytest.approx(0.4485, abs=1e-4)
    # Railjet / mu1 at the lower limit 2.1 Hz
    hand = -5.631e-4 * 2.1**3 + 0.007015 * 2.1**2 - 0.02098 * 2.1 + 0.2931
    assert ref.lower_bound("railjet", "mu1").delta_zeta_pct(2.1) == pytest.approx(hand, rel=1e-12)


def test_lower_bound_zero_beyond_root_and_refused_below_21hz():
    lb = ref.lower_bound("Eurostar", "mu2")
    assert lb.delta_zeta_pct(lb.first_root_hz + 0.01) == 0.0
    assert lb.delta_zeta_pct(20.0) == 0.0
    assert lb.delta_zeta_pct(lb.first_root_hz - 0.5) > 0.0
    with pytest.raises(InputError, match=r"n0_hz: 2 Hz is out of range; allowed >= 2.1 Hz"):
        lb.delta_zeta_pct(2.0)


# ---------------------------------------------------------------------- Section 4.3 rules

def test_recommend_on_a_mass_function_uses_it():
    # B1 lies on mu2 (CFB, 0.7002 * 15 + 8.539 = 19.042 t/m), Table 3.
    rec = ref.recommend("ICE-2", 8.26, 19.042, "cfb", span_m=15.0)
    assert rec.mass_functions == ("mu2",)
    assert rec.delta_zeta_pct == pytest.approx(ref.lower_bound("ICE-2", "mu2").delta_zeta_pct(8.26), rel=1e-12)


def test_recommend_inside_takes_next_heavier_or_interpolates():
    L, n0 = 20.0, 5.0
    mu1, mu2 = 0.843 * L + 10.45, 0.7002 * L + 8.539   # 27.31 and 22.543 t/m
    mu = 0.25 * mu1 + 0.75 * mu2
    safe = ref.recommend("Railjet", n0, mu, "cfb", span_m=L)
    assert safe.mass_functions == ("mu1",) and "safe side" in safe.rule
    v1 = ref.lower_bound("Railjet", "mu1").delta_zeta_pct(n0)
    v2 = ref.lower_bound("Railjet", "mu2").delta_zeta_pct(n0)
    assert safe.delta_zeta_pct == pytest.approx(v1, rel=1e-12)
    interp = ref.recommend("Railjet", n0, mu, "cfb", span_m=L, interpolate=True)
    assert interp.mass_functions == ("mu1", "mu2")
    assert interp.delta_zeta_pct == pytest.approx(0.25 * v1 + 0.75 * v2, rel=1e-9)


def test_recommend_outside_takes_nearest():
    L, n0 = 20.0, 5.0
    heavy = ref.recommend("ICE-4", n0, 40.0, "sc", span_m=L)       # above mu4 = 11.945 t/m
    light = ref.recommend("ICE-4", n0, 1.0, "sc", span_m=L)        # below mu6 = 4.597 t/m
    assert heavy.mass_functions == ("mu4",) and "nearest" in heavy.rule
    assert light.mass_functions == ("mu6",) and "nearest" in light.rule
    assert light.delta_zeta_pct == pytest.approx(ref.lower_bound("ICE-4", "mu6").delta_zeta_pct(n0), rel=1e-12)


def test_recommend_estimates_span_from_n0():
    rec = ref.recommend("ICE-2", 5.0, 20.0, "cfb")
    assert rec.span_estimated
    assert 97.76 * rec.span_m ** -0.9124 == pytest.approx(5.0, rel=1e-9)


@pytest.mark.parametrize("kwargs, match", [
    (dict(train="TGV"), r"train: 'TGV' was not studied by the paper"),
    (dict(n0_hz=1.9), r"n0_hz: 1.9 Hz is out of range.*validity of the lower-bound functions"),
    (dict(n0_hz=40.0), r"n0_hz: 40 Hz is out of range"),
    (dict(bridge_type="steel"), r"bridge_type: 'steel' is not allowed"),
    (dict(span_m=-3.0), r"span_m: -3 m is out of range; allowed \[4, 40\] m"),
    (dict(mu_t_m=-1.0), r"mu: -1 t/m is out of range"),
])
def test_recommend_refuses(kwargs, match):
    args = dict(train="ICE-2", n0_hz=5.0, mu_t_m=20.0, bridge_type="cfb", span_m=20.0)
    args.update(kwargs)
    with pytest.raises(InputError, match=match):
        ref.recommend(**args)


def test_train_names_are_case_insensitive():
    assert ref.canonical_train_name("ice2") == "ICE-2"
    assert ref.canonical_train_name("Ice-4") == "ICE-4"
    assert ref.canonical_train_name("EUROSTAR") == "Eurostar"


def test_lower_bound_for_bridge_eurostar_b1_is_zero():
    # Paper Section 4.4: B1 (8.26 Hz) lies beyond the Eurostar functions (root 7.78 Hz): 0.
    dz, note = ref.lower_bound_for(named_bridge("B1"), load_train("Eurostar"))
    assert dz == 0.0 and "beyond the first root" in note


# ---------------------------------------------------------------------- EADA

def test_half_coach_by_hand_ice2_pc():
    """ICE-2 passenger car (paper Table A1) and EADA on B1 (Table 3, Eq. 3), values computed by hand.

    Table A1, PC: m_c = 33930 kg, m_b = 2373 kg, k_s = 3e5 N/m, c_s = 6e3 Ns/m (per bogie),
    k_p = 1.6e6 N/m, c_p = 2e4 Ns/m (per axle) -> per bogie K = 2 k_p = 3.2e6, C = 2 c_p = 4e4.

    Mass:  a = k_s / (k_s + K) = 3e5 / 3.5e6 = 3/35;  a^2 m_b = 9 * 2373 / 1225 = 17.434286 kg
           m_1 = 33930 / 2 + 17.434286 = 16982.434286 kg
    Series Kelvin stages, x = w^2:  K* = (k_s + i w c_s)(K + i w C) / ((k_s + K) + i w (c_s + C))
      Re K* = [k_s K (k_s + K) + x ((k_s C + K c_s)(c_s + C) - c_s C (k_s + K))] / [(k_s + K)^2 + x (c_s + C)^2]
            = [9.6e11 * 3.5e6 + x (3.12e10 * 4.6e4 - 2.4e8 * 3.5e6)] / [1.225e13 + 2.116e9 x]
            = [3.36e18 + 5.952e14 x] / [1.225e13 + 2.116e9 x]
      Im K* / w = [(k_s C + K c_s)(k_s + K) - (k_s K - x c_s C)(c_s + C)] / [same]
            = [1.092e17 - 4.416e16 + 1.104e13 x] / [1.225e13 + 2.116e9 x] = [6.504e16 + 1.104e13 x] / [...]
    Tuning frequency w_1^2 = Re K*(w_1) / m_1 (Eq. 2) is the quadratic
      m_1 2.116e9 x^2 + (m_1 1.225e13 - 5.952e14) x - 3.36e18 = 0
      3.5934831e13 x^2 + 2.0743962e17 x - 3.36e18 = 0  ->  x = 16.152289 s^-2, w_1 = 4.0189911 rad/s (0.63964 Hz)
    Denominator 1.225e13 + 2.116e9 * 16.152289 = 1.2284178e13:
      k_1 = (3.36e18 + 5.952e14 * 16.152289) / 1.2284178e13 = 274305.19 N/m  (= m_1 x)
      c_1 = (6.504e16 + 1.104e13 * 16.152289) / 1.2284178e13 = 5309.1318 Ns/m
      zeta_1 = c_1 / (2 m_1 w_1) = 5309.1318 / (2 * 16982.434 * 4.0189911) = 0.038893455
    Eq. (3) on B1 (Table 3: mu = 19.042 t/m, L = 15 m, n0 = 8.26 Hz):
      M_1 = 19042 * 15 / 2 = 142815 kg,  Omega_1 = 2 pi 8.26 = 51.899111 rad/s
      mu_1 = 16982.434 / 142815 = 0.11891212,  r_1 = 4.0189911 / 51.899111 = 0.077438534
      dz = 100 * 0.11891212 * 0.077438534 * sqrt(0.077438534^2 + (2 * 0.038893455)^2) = 0.10107232 %
    """
    coach = ref.half_coach(load_train("ICE-2").vehicle_types["PC"], "PC")
    # the hand values carry 8 significant digits: 1e-7 relative
    assert coach.m_1_kg == pytest.approx(16982.434286, rel=1e-9)
    assert coach.omega_1_rad_s == pytest.approx(4.0189911, rel=1e-7)
    assert coach.k_1_N_m == pytest.approx(274305.19, rel=1e-7)
    assert coach.c_1_Ns_m == pytest.approx(5309.1318, rel=1e-7)
    assert coach.zeta_1 == pytest.approx(0.038893455, rel=1e-7)
    assert ref.eada_delta_zeta_pct(coach, 19042.0, 15.0, 8.26) == pytest.approx(0.10107232, rel=1e-7)
    # B1 as built has n0 = 8.262 Hz from EJ and mu (Eq. 18), a little above Table 3's rounded 8.26 Hz:
    # dz scales between r_1^1 and r_1^2 with r_1 ~ 1/n0, so it is 0.03-0.05 % lower
    b1 = named_bridge("B1")
    assert 0.10107232 * (8.26 / b1.n0_hz) ** 2 <= ref.eada_delta_zeta_pct(
        coach, b1.mass_per_length_kg_m, b1.span_m, b1.n0_hz) <= 0.10107232 * (8.26 / b1.n0_hz)


def test_half_coach_undamped_is_series_spring():
    v = types.SimpleNamespace(m_c_kg=40000.0, m_b_kg=3000.0, k_s_N_m=4e5, c_s_Ns_m=0.0, k_p_N_m=1e6, c_p_Ns_m=None)
    coach = ref.half_coach(v)
    k_series = 4e5 * 2e6 / 2.4e6
    assert coach.k_1_N_m == pytest.approx(k_series, rel=1e-12)
    assert coach.c_1_Ns_m == pytest.approx(0.0, abs=1e-9)
    assert coach.m_1_kg == pytest.approx(20000.0 + (4e5 / 2.4e6) ** 2 * 3000.0, rel=1e-12)


def test_eada_vehicle_choice():
    assert ref.eada_vehicle(load_train("ICE-4"))[0] == "unpowered PC"
    assert ref.eada_vehicle(load_train("ICE-2"))[0] == "PC"
    assert ref.eada_vehicle(load_train("Railjet"))[0] == "PC"
    dz, note = ref.eada_for(named_bridge("B1"), load_train("Eurostar"))
    assert dz is None and "Jacobs" in note
