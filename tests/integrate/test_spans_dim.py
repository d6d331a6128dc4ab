"""The DIM on continuous decks: the same kernels (numpy stepper and compiled), the mode shapes and
the Eq. (13) modified mass matrix taken from the deck's mode tables."""

import tomllib
from importlib import resources

import numpy as np
import pytest

from fe_beam import FEBeam, fe_moving_masses
from test_core_dim import SOFT, _modified
from test_spans_mlm import DECKS, as_deck
from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled
from adm_sim.model.bridge import Bridge, TABLE3, named_bridge
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.inputs.train_files import load_train, train_from_mapping


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
    """The compiled DIM kernels and the numpy stepper on a three-span deck: equal to 1e-12. Both on 4
    steps per period of the highest mode (a quarter of the default, as test_sweep_backends.py compares
    them on one span): the two paths are compared on one ds, which need not be accurate for them to
    agree (RK4 is stable up to h omega = 2.8, here pi / 2)."""
    spans, EJ, mu, _ = DECKS["12+16+12"]
    b = Bridge.continuous(spans, EJ, mu, 0.02)
    speeds = [220.0, 280.0]
    step = StepOptions(steps_per_period=4.0)
    a = run_sweep_compiled(b, load_train("Eurostar"), "dim", speeds, options=step)
    n = run_sweep(b, load_train("Eurostar"), "dim", speeds, options=step)
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


def _short_moving_masses():
    """ICE-2's locomotive and one car whose bogies, car bodies and suspensions are negligible (1 kg,
    1 N/m, no dampers) and whose wheelsets carry m_w + m_b / 2: masses in permanent contact with their
    static axle loads (the DIM reduced to moving masses)."""
    data = tomllib.loads(resources.files("adm_sim").joinpath("data/trains/ice2.toml").read_text())
    data["composition"] = [{"vehicle": "Loc"}, {"vehicle": "PC", "count": 1}]
    for vt in data["vehicle_types"].values():
        vt.update(m_w_kg=vt["m_w_kg"] + vt["m_b_kg"] / 2, m_b_kg=1.0, J_b_kgm2=1.0, k_p_N_m=1.0, c_p_Ns_m=0.0,
                  m_c_kg=1.0, J_c_kgm2=1.0, k_s_N_m=1.0, c_s_Ns_m=0.0)
    data["loads_differ_from_masses"] = True
    return train_from_mapping(data, source="moving masses")


@pytest.mark.slow  # the monolithic reference: 5.5 s of CPU
def test_dim_against_a_direct_fe_integration_with_moving_masses():
    """The DIM (numpy stepper, exact modes, 8 RK4 steps per period of the highest) of 8 moving masses
    of 3.7-4.8 t with their static loads (the locomotive and a car of ICE-2 reduced to their wheelsets)
    at 250 km/h over 2 x 15 m, against an independent FE deck (Hermite cubic, 16 elements per span)
    with the masses coupled in it (mass, Coriolis and centripetal terms of each mass's path assembled
    at every step) integrated directly by Newmark (4 steps per RK4 step), response at 7.5 m, on one
    time grid. Measured (whole history, relative to the FE peak): deflection 1.3e-3 / 6.3e-4 / 6.2e-5
    and acceleration 0.14 / 0.050 / 0.014 with 6 / 12 / 24 modes (the modal truncation converges to
    the FE deck); the MLM of the same loads differs by 0.30. On this grid, 12 modes: 6.30e-4 and
    0.0475, 6 modes: 1.29e-3 and 0.137, MLM 0.297; at 16 steps per period (twice the steps) 6.31e-4,
    0.0484, 1.29e-3, 0.137, 0.296: the time step's share is small beside the truncation's, so the
    coarser grid tests the same property. Asserted with 12 modes: deflection within 2e-3,
    acceleration within 6e-2, both below the 6-mode errors, and the MLM more than twice as far: the
    coupled masses are what is checked."""
    spans, EJ, mu, x = DECKS["2x15"]
    b = Bridge.continuous(spans, EJ, mu, 0.02, n_modes=12)
    train = _short_moving_masses()
    opts = StepOptions(steps_per_period=8.0, free_vibration_periods=1.0)
    r = run_sweep(b, train, "dim", [250.0], histories=True, where=x, options=opts)
    t = r.time_s[0]
    sub = 4
    w3, w1 = b.omega_rad_s[2], b.omega_rad_s[0]
    ab = (2 * 0.02 * w1 * w3 / (w1 + w3), 2 * 0.02 / (w1 + w3))
    _, wf, af = fe_moving_masses(FEBeam(spans, EJ, mu, 16), train.axle_offsets_m, train.axle_loads_n,
                                 train.wheel_mass_kg, 250.0 / 3.6, t[1] / sub, t[-1], ab, x)
    wf, af = wf[::sub][:t.size], af[::sub][:t.size]

    def errors(res):
        return (np.abs(res.midspan_disp_m[0] - wf).max() / np.abs(wf).max(),
                np.abs(res.midspan_acc_m_s2[0] - af).max() / np.abs(af).max())

    same_grid = StepOptions(ds_m=r.ds_m, free_vibration_periods=1.0)
    err12 = errors(r)
    err6 = errors(run_sweep(Bridge.continuous(spans, EJ, mu, 0.02, n_modes=6), train, "dim", [250.0],
                            histories=True, where=x, options=same_grid))
    err_mlm = errors(run_sweep(b, train, "mlm", [250.0], histories=True, where=x, options=same_grid))[1]
    print(f"DIM vs FE moving masses: 12 modes {err12}, 6 modes {err6}; MLM vs FE {err_mlm:.2e}")
    assert err12[0] < 2e-3 and err12[1] < 6e-2
    assert err12[0] < err6[0] and err12[1] < err6[1]
    assert err_mlm > 2 * err12[1]
