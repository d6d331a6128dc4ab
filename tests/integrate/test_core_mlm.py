"""MLM solver against closed-form solutions, limiting cases and step convergence."""


import numpy as np
import pytest

from analytic import (moving_force_midspan_deflection, static_midspan_deflection,
                      static_midspan_deflection_modal)
from adm_sim.model.bridge import named_bridge
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep
from adm_sim.model.trains import moving_loads
from adm_sim.inputs.train_files import load_train

ONE_FORCE = moving_loads([0.0], [100e3], "one force")


@pytest.mark.parametrize("bridge_name", ["B1", "B4"])
@pytest.mark.parametrize("speed_kmh", [100.0, 250.0, 350.0])
def test_single_moving_force_matches_closed_form(bridge_name, speed_kmh):
    # Fryba's modal solution, mode by mode in closed form, incl. free vibration after exit.
    # Tolerance from the issue: relative error <= 1e-4 on midspan deflection (default step).
    b = named_bridge(bridge_name)
    r = run_sweep(b, ONE_FORCE, "mlm", [speed_kmh], histories=True)
    t, w = r.time_s[0], r.midspan_disp_m[0]
    ref = moving_force_midspan_deflection(b, 100e3, speed_kmh / 3.6, t)
    assert np.abs(ref).max() > 1e-4  # a real deflection (m), not a trivially zero signal
    assert np.abs(w - ref).max() / np.abs(ref).max() <= 1e-4


def test_slow_crossing_follows_static_influence_line():
    # 5 km/h over B1: the dynamic part is negligible; the midspan deflection follows the
    # static influence line of the 3-mode beam (to 0.5 %) and the exact beam formula to the
    # modal truncation error (3 modes: < 1 %).
    b = named_bridge("B1")
    r = run_sweep(b, ONE_FORCE, "mlm", [5.0], histories=True, options=StepOptions(free_vibration_periods=0))
    x = r.time_s[0] * 5.0 / 3.6
    on = (x > 0.05 * b.span_m) & (x < 0.95 * b.span_m)
    w = r.midspan_disp_m[0][on]
    modal = static_midspan_deflection_modal(b, 100e3, x[on])
    exact = static_midspan_deflection(b, 100e3, x[on])
    peak = exact.max()
    assert np.abs(w - modal).max() <= 5e-3 * peak
    assert np.abs(w - exact).max() <= 1e-2 * peak
    # at midspan the 3-mode series is within 0.3 % of F L^3 / (48 EJ)
    assert w.max() == pytest.approx(100e3 * b.span_m**3 / (48 * b.EJ_Nm2), rel=3e-3)


def test_resonance_speeds_of_a_regular_train():
    # 20 equal axles every d = 17 m: resonance at v_i = n0 d / i (i = 2, 3 in 150..350 km/h);
    # d is chosen away from the cancellation spans L = (i - 1/2) v / n0.
    d = 17.0
    train = moving_loads(np.arange(20) * d, np.full(20, 150e3), "regular")
    b = named_bridge("B1")
    speeds = np.arange(150.0, 350.0 + 1e-9, 0.5)
    r = run_sweep(b, train, "mlm", speeds, options=StepOptions(steps_per_period=10))
    acc = r.max_acc_m_s2
    for i in (2, 3):
        v_res = b.n0_hz * d / i * 3.6
        win = np.flatnonzero(np.abs(speeds - v_res) <= 0.05 * v_res)
        j = win[np.argmax(acc[win])]
        assert win[0] < j < win[-1], f"no resonance peak near {v_res:.1f} km/h"
        assert speeds[j] == pytest.approx(v_res, rel=0.01)
        assert acc[j] > 1.5 * acc[win].min()  # a real resonance, well above its surroundings


def test_zero_damping_and_no_load_limits():
    b = named_bridge("B3")
    nothing = moving_loads([0.0, 5.0], [0.0, 0.0])
    r = run_sweep(b, nothing, "mlm", [200.0, 300.0])
    assert np.all(r.max_acc_m_s2 == 0.0)
    # more damping never raises the response of a resonant crossing
    t = load_train("ICE-2")
    lo = run_sweep(b, t, "mlm", [270.0], delta_zeta=0.0).max_acc_m_s2[0]
    hi = run_sweep(b, t, "mlm", [270.0], delta_zeta=0.01).max_acc_m_s2[0]
    assert hi < lo


def test_response_is_linear_in_the_loads():
    b = named_bridge("B2")
    one = moving_loads([0.0, 3.0], [100e3, 50e3])
    two = moving_loads([0.0, 3.0], [200e3, 100e3])
    a1 = run_sweep(b, one, "mlm", [200.0, 260.0]).max_acc_m_s2
    a2 = run_sweep(b, two, "mlm", [200.0, 260.0]).max_acc_m_s2
    np.testing.assert_allclose(a2, 2 * a1, rtol=1e-12)


def test_lanes_are_independent():
    # One lane of a batched sweep equals the same speed run alone (shared grid, same ds).
    b, t = named_bridge("B1"), load_train("Railjet")
    opts = StepOptions(ds_m=0.05)
    batch = run_sweep(b, t, "mlm", [200.0, 263.0, 300.0], options=opts).max_acc_m_s2
    alone = run_sweep(b, t, "mlm", [263.0], options=opts).max_acc_m_s2
    assert batch[1] == pytest.approx(alone[0], rel=1e-12)


@pytest.fixture(scope="module")
def b1_ice2_sweep():
    """The MLM sweep of B1 x ICE-2 over 160..350 km/h every 1 km/h on the default step, run once for
    test_b1_ice2_resonance_peak and the default-step side of test_mlm_step_convergence[B1-ICE-2]
    (bit for bit the run each made on its own, measured)."""
    return run_sweep(named_bridge("B1"), load_train("ICE-2"), "mlm", np.arange(160.0, 351.0, 1.0),
                     options=StepOptions())


@pytest.mark.slow
@pytest.mark.parametrize("bridge_name,train_name", [("B1", "ICE-2"), ("B4", "ICE-4")])
def test_mlm_step_convergence(bridge_name, train_name, request):
    # Halving the step moves the sweep's peak by < 0.1 %.
    b, t = named_bridge(bridge_name), load_train(train_name)
    speeds = np.arange(160.0, 351.0, 1.0)
    opts = StepOptions()
    if (bridge_name, train_name) == ("B1", "ICE-2"):  # the default-step run is the module's shared one
        p1 = request.getfixturevalue("b1_ice2_sweep").peak()
    else:
        p1 = run_sweep(b, t, "mlm", speeds, options=opts).peak()
    p2 = run_sweep(b, t, "mlm", speeds, options=opts.halved()).peak()
    assert p1 is not None and p2 is not None
    assert p1["speed_kmh"] == p2["speed_kmh"]
    assert abs(p1["acc_m_s2"] / p2["acc_m_s2"] - 1) < 1e-3


def test_b1_ice2_resonance_peak(b1_ice2_sweep):
    # ICE-2 coaches (d = 26.4 m) drive B1 (n0 = 8.262 Hz) at v = n0 d / 3 = 261.8 km/h.
    b = named_bridge("B1")
    pk = b1_ice2_sweep.peak()
    assert pk["speed_kmh"] == pytest.approx(b.n0_hz * 26.4 / 3 * 3.6, abs=2.0)
    # the README's headline MLM peak (2.2465 m/s² at 263 km/h), to half the last printed digit
    assert pk["speed_kmh"] == 263.0 and pk["acc_m_s2"] == pytest.approx(2.2465, abs=5e-5)
