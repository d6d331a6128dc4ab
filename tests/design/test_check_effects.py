"""EN 1991-2 6.4.6.5(3) for every effect along the span (adm_sim.design.check_effects): statics by hand, LM71 by
hand, the mode-acceleration method against the closed form of one moving force, modal convergence
(3, 5, 9, 15 modes), the two-pass speed search against one fine pass, and the φ'' share per maintenance."""

import dataclasses
import math

import numpy as np
import pytest

from adm_sim.design import check_effects as ce
from adm_sim.model.bridge import named_bridge
from adm_sim.design.check import check_speeds_kmh
from adm_sim.design.design_loads import lm71_midspan, phi_dd_factor
from adm_sim.inputs.train_files import load_train
from analytic import moving_force_modal

B1 = dataclasses.replace(named_bridge("B1"), damping_model="modal")


def by_label(res):
    return {e.label: i for i, e in enumerate(res.effects)}


def test_static_effects_of_one_axle_by_hand():
    """One axle F: R_A = R_B = F, M(x) = F x (L - x) / L, |V(x)| = F max(x, L - x) / L (load just beside x)."""
    F, L = 1e5, B1.span_m
    r = ce.train_effects(B1, [0.0], [F], [100.0])
    for e, st in zip(r.effects, r.static_max):
        if e.kind in ("RA", "RB"):
            assert st == pytest.approx(F, rel=1e-12)
        elif e.kind == "M":
            assert st == pytest.approx(F * e.x_m * (L - e.x_m) / L, rel=1e-12)
        else:
            assert st == pytest.approx(F * max(e.x_m, L - e.x_m) / L, rel=1e-8)


def test_lm71_effects_by_hand():
    """LM71 on 15 m: the midspan moment equals design_loads.lm71_midspan (3715.2 kNm); the reaction, first
    axle on the support: 250 (15 + 13.4 + 11.8 + 10.2) / 15 + 80 x 9.4^2 / 2 / 15 = 1075.627 kN; the shear at
    midspan, axles on the right half and 80 kN/m on the rest of it: 250 (7.5 + 5.9 + 4.3 + 2.7) / 15 +
    80 x 1.9^2 / 2 / 15 = 349.627 kN."""
    L = 15.0
    assert ce.lm71_effect_max(ce.Effect("M", 7.5), L) == pytest.approx(lm71_midspan(L, 1e10).moment_Nm, rel=1e-8)
    ra = 250e3 * (15 + 13.4 + 11.8 + 10.2) / 15 + 80e3 * 9.4**2 / 2 / 15
    assert ce.lm71_effect_max(ce.Effect("RA", 0.0), L) == pytest.approx(ra, rel=1e-8)
    assert ce.lm71_effect_max(ce.Effect("RB", L), L) == pytest.approx(ra, rel=1e-8)
    v_mid = 250e3 * (7.5 + 5.9 + 4.3 + 2.7) / 15 + 80e3 * 1.9**2 / 2 / 15
    assert ce.lm71_effect_max(ce.Effect("V", 7.5), L) == pytest.approx(v_mid, rel=1e-7)
    assert ce.lm71_effect_max(ce.Effect("RA", 0.0), L, alpha=1.33) == pytest.approx(1.33 * ra, rel=1e-8)


@pytest.mark.parametrize("kmh", [120.0, 300.0])
def test_mode_acceleration_against_the_closed_form(kmh):
    """One force F on B1 (3 modes): R_A(t) = F (1 - v t / L) + sum_j EJ k_j^3 (q_j - F_j / K_j) and
    M(L/2, t) = F a / 2 + sum_j EJ k_j^2 sin(j pi / 2) (q_j - F_j / K_j), q_j by the closed form of
    tests/analytic.py on a grid of 0.5 mm of travel, plus the free vibration: the largest values agree
    with the sampled ones of train_effects within 1e-3 (the sampling lowers a maximum only)."""
    F, L, EJ = 1e5, B1.span_m, B1.EJ_Nm2
    v = kmh / 3.6
    t = np.arange(0.0, L / v + 1.3 / B1.n0_hz, 5e-4 / v)
    q, _, f = moving_force_modal(B1, F, v, t)
    k = B1.mode_numbers * np.pi / L
    qs = f / B1.omega_rad_s[:, None] ** 2  # F_j / K_j (f is F_j / M_j)
    a = np.clip(v * t, 0.0, None)
    on = a <= L
    ra = np.where(on, F * (1 - a / L), 0.0) + (EJ * k**3) @ (q - qs)
    mm = np.where(on, F * np.minimum(a, L - a) / 2, 0.0) + (EJ * k**2 * np.sin(k * L / 2)) @ (q - qs)
    r = ce.train_effects(B1, [0.0], [F], [kmh], samples_per_span=400)
    i = by_label(r)
    for ref, lab in ((np.abs(ra).max(), "reaction A"), (np.abs(mm).max(), "M(7.5 m)")):
        got = r.dynamic_max[i[lab]]
        assert got == pytest.approx(ref, rel=1e-3), lab


def test_modal_convergence_table_hslm_a9_b1():
    """HSLM-A9 on B1, V = 250 km/h (144 .. 300 km/h), ζ 1.85 % on every mode. With the static correction
    φ'_dyn of every effect moves by less than 0.007 from 3 to 15 modes, 0.003 from 5 (midspan moment 0.5231, 0.5238,
    0.5238, 0.5237); the modal sum alone, divided by the exact static effect, gives the reaction 0.02
    with 3 modes and 0.26 with 15 (against 0.338): the shear needs the correction."""
    t = load_train("HSLM-A9")
    sp = check_speeds_kmh(250.0)
    rows = {}
    for n in (3, 5, 9, 15):
        b = dataclasses.replace(B1, n_modes=n)
        rows[n] = (ce.train_effects(b, t.axle_offsets_m, t.axle_loads_n, sp),
                   ce.train_effects(b, t.axle_offsets_m, t.axle_loads_n, sp, static_correction=False))
    i = by_label(rows[3][0])
    mid = [rows[n][0].phi_dyn[i["M(7.5 m)"]] for n in (3, 5, 9, 15)]
    np.testing.assert_allclose(mid, [0.5231, 0.5238, 0.5238, 0.5237], atol=6e-4)
    diff = [np.abs(rows[n][0].phi_dyn - rows[15][0].phi_dyn).max() for n in (3, 5, 9)]
    assert diff[0] < 7e-3 and diff[1] < 3e-3 and diff[2] < 2e-3
    assert rows[3][0].phi_dyn[i["reaction A"]] == pytest.approx(0.338, abs=3e-3)
    assert rows[3][1].phi_dyn[i["reaction A"]] < 0.05 and rows[15][1].phi_dyn[i["reaction A"]] < 0.3


def test_two_passes_equal_one_fine_pass(monkeypatch):
    """The coarse pass only chooses the speeds of the fine one: with every speed refined (margin 1, step 0)
    the results are the same to round-off for HSLM-A9 and ICE-2 on B1, V = 350 km/h, at the check's own
    speeds (1 km/h and the 0.1 km/h refinement around every acceleration peak)."""
    from adm_sim.design.check import run_check

    res = run_check(named_bridge("B1"), 350.0, [load_train("HSLM-A9"), load_train("ICE-2")])
    for c in res.trains:
        t = load_train(c.name)
        assert c.speeds_kmh.size > 300
        two = ce.train_effects(B1, t.axle_offsets_m, t.axle_loads_n, c.speeds_kmh)
        monkeypatch.setattr(ce, "COARSE_MARGIN", 1.0)
        monkeypatch.setattr(ce, "COARSE_STEP_KMH", 0.0)
        one = ce.train_effects(B1, t.axle_offsets_m, t.axle_loads_n, c.speeds_kmh)
        monkeypatch.undo()
        np.testing.assert_allclose(two.dynamic_max, one.dynamic_max, rtol=1e-12)
        np.testing.assert_array_equal(two.at_speed_kmh, one.at_speed_kmh)


def test_sampling_step_halved_twice():
    """100 samples per span (the default) against 400: every dynamic maximum within 1e-3 (from below)."""
    sp = check_speeds_kmh(250.0)
    for name in ("HSLM-A1", "ICE-2"):
        t = load_train(name)
        r = ce.train_effects(B1, t.axle_offsets_m, t.axle_loads_n, sp)
        f = ce.train_effects(B1, t.axle_offsets_m, t.axle_loads_n, sp, samples_per_span=400)
        rel = 1 - r.dynamic_max / f.dynamic_max
        assert rel.max() < 1e-3 and rel.min() > -1e-12


def test_phi_dd_share_by_maintenance():
    """Annex C (cited by content): 1 + φ' + φ''/2 on carefully maintained track, 1 + φ' + φ'' with standard maintenance."""
    assert phi_dd_factor("careful") == 0.5 and phi_dd_factor("standard") == 1.0
    c = ce.EffectComparison(effect=ce.Effect("M", 7.5), phi_dyn=0.5, phi_dd_factor=1.0, phi_dd=0.2, Phi=1.3,
                            train_static=1e6, lm71_static=2e6)
    assert c.train_design == pytest.approx(1.7e6) and c.ratio == pytest.approx(1.7 / 2.6)
    assert math.isclose(dataclasses.replace(c, phi_dd_factor=0.5).train_design, 1.6e6)


# ---------------------------------------------------------------------- EN 1990 A2.4.4 serviceability
def test_lm71_deflection_and_end_rotation_by_hand():
    """The largest deflection of LM71 on a span is at midspan for a symmetric group: equal to the exact
    midspan maximum of design_loads (3e-7, the trapezoid rule of the distributed load); on B1
    Φ2 x LM71 = 1.212 x 3.171 = 3.843 mm < L/600 = 25 mm. End rotation: a point force P at a gives
    P a (L - a)(2L - a) / (6 EJ L), checked against its sine series sum_j 2 P sin(j pi a / L) / (L EJ k_j^3)
    (1/j^3, 400 terms); the distributed load alone q L^3 / (24 EJ); LM71 on 15 m: the maximum over the
    group position, brute force on a 0.5 mm grid with the distributed load integrated by the same
    formula's antiderivative checked against scipy's quad."""
    from scipy.integrate import quad

    from adm_sim.design import check_sls as sls

    L, EJ = 15.0, 1e10
    w, x = sls.lm71_max_deflection(L, EJ)
    assert w == pytest.approx(lm71_midspan(L, EJ).deflection_m, rel=1e-6) and x == 7.5
    b1 = named_bridge("B1")
    res = sls.serviceability(b1, 1.44 / (math.sqrt(15.0) - 0.2) + 0.82, 1.0, "ballasted", 2.0)
    assert res.deflection_m == pytest.approx(3.843e-3, abs=1e-6) and res.deflection_ok and res.lateral_ok
    P, a = 1e5, 4.0
    k = np.arange(1, 401) * np.pi / L
    series = (2 * P * np.sin(k * a) / (L * EJ * k**3)).sum()
    closed = P * a * (L - a) * (2 * L - a) / (6 * EJ * L)
    assert closed == pytest.approx(series, rel=1e-6)
    point = lambda u: u * (L - u) * (2 * L - u) / (6 * EJ * L)  # noqa: E731
    assert quad(point, 0, L)[0] * 80e3 == pytest.approx(80e3 * L**3 / (24 * EJ), rel=1e-12)
    from scipy.optimize import minimize_scalar

    c = np.array([-2.4, -0.8, 0.8, 2.4])

    def theta(d):
        u = d + c
        u = u[(u >= 0) & (u <= L)]
        lo, hi = min(max(d - 3.2, 0.0), L), min(max(d + 3.2, 0.0), L)
        return 250e3 * point(u).sum() + 80e3 * (quad(point, 0, lo)[0] + quad(point, hi, L)[0])

    grid = np.arange(-3.2, L + 3.2, 0.01)
    d0 = grid[np.argmax([theta(d) for d in grid])]
    opt = minimize_scalar(lambda d: -theta(d), bounds=(d0 - 0.02, d0 + 0.02), method="bounded",
                          options={"xatol": 1e-9})
    best = max(-opt.fun, theta(d0))
    got = sls.lm71_end_rotation(L, EJ)
    assert got == pytest.approx(best, rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("value,line", [
    ("abc", "error: --lateral-frequency: 'abc' is not a frequency; give the first lateral natural frequency of "
            "the span in Hz, > 0\n"),
    ("-1", "error: --lateral-frequency: '-1' Hz is not the frequency of a span; allowed (0, 100] Hz (the upper bound "
           "is the project's choice: no railway span sways above it; EN 1990 A2.4.4.2.4(3) asks for at least 1.2 Hz)\n"),
    ("1e9", "error: --lateral-frequency: '1e9' Hz is not the frequency of a span; allowed (0, 100] Hz (the upper bound "
            "is the project's choice: no railway span sways above it; EN 1990 A2.4.4.2.4(3) asks for at least 1.2 Hz)\n"),
])
def test_lateral_frequency_bad_input(tmp_path, value, line):
    import subprocess
    import sys

    js = tmp_path / "c.json"
    r = subprocess.run([sys.executable, "-m", "adm_sim.cli.sim_commands", "check", "--max-line-speed", "250",
                        "--trains", "HSLM-A1", "--lateral-frequency", value, "--json", str(js)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr == line and not js.exists()
