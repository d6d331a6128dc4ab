"""The MLM on continuous decks: the mode tables in the in-process sweeps (numpy stepper and compiled
kernels), against today's sine path on one span and against an independent finite-element beam
integrated directly (tests/fe_beam.py) on two- and three-span decks."""

import numpy as np
import pytest

from fe_beam import FEBeam, fe_moving_loads
from adm_sim.errors import InputError
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled, sweep_exact
from adm_sim.model.bridge import Bridge, TABLE3, named_bridge
from adm_sim.model.trains import moving_loads
from adm_sim.inputs.train_files import load_train

TRAINS = ("ICE-2", "Eurostar", "Railjet", "ICE-4")


def as_deck(b):
    """The same single span given by its spans: the exact-mode tables of adm_sim.model.spans."""
    return Bridge(span_m=b.span_m, EJ_Nm2=b.EJ_Nm2, mass_per_length_kg_m=b.mass_per_length_kg_m,
                  damping_ratio=b.damping_ratio, n_modes=b.n_modes, name=b.name, bridge_type=b.bridge_type,
                  spans_m=(b.span_m,), span_EJ_Nm2=(b.EJ_Nm2,), span_mu_kg_m=(b.mass_per_length_kg_m,))


@pytest.mark.parametrize("train_name", TRAINS)
def test_one_span_through_the_mode_tables_is_todays_sweep(train_name):
    """B1-B4 x the four trains, MLM RK4 (compiled kernels): the sweep through the mode tables equals
    today's sine-mode sweep to 1e-10 relative (max acceleration and deflection, every speed)."""
    train = load_train(train_name)
    speeds = np.arange(150.0, 350.0 + 1e-9, 10.0)
    for name in TABLE3:
        b = named_bridge(name)
        d = as_deck(b)
        assert d.is_continuous and not b.is_continuous
        ref = run_sweep_compiled(b, train, "mlm", speeds)
        new = run_sweep_compiled(d, train, "mlm", speeds)
        assert new.n_steps == ref.n_steps
        np.testing.assert_allclose(new.max_acc_m_s2, ref.max_acc_m_s2, rtol=1e-10, atol=0)
        np.testing.assert_allclose(new.max_disp_m, ref.max_disp_m, rtol=1e-10, atol=0)


def test_one_span_numpy_stepper_and_a_point_off_midspan():
    """The numpy stepper too, and --where x=<m>: the sine path at x = L/3 (sin(j pi / 3)) equals the
    table path there to 1e-10 relative; the table path at midspan equals today's midspan run. The sine
    runs at midspan and L/3 are then compared with each other (they are what a separate run at each
    point gives, bit for bit: where="midspan" is run_sweep's default)."""
    b, train = named_bridge("B3"), load_train("ICE-2")
    speeds = [200.0, 260.0, 300.0]
    d = as_deck(b)
    sine = {}
    for where in ("midspan", b.span_m / 3.0):
        ref = sine[where] = run_sweep(b, train, "mlm", speeds, where=where)
        new = run_sweep(d, train, "mlm", speeds, where=where)
        np.testing.assert_allclose(new.max_acc_m_s2, ref.max_acc_m_s2, rtol=1e-10, atol=0)
    at_mid, at_third = sine["midspan"], sine[b.span_m / 3.0]
    assert np.all(np.abs(at_third.max_acc_m_s2 / at_mid.max_acc_m_s2 - 1) > 1e-3)  # another point, other numbers


def _rayleigh_ab(bridge):
    """Rayleigh coefficients ``C = a M + b K`` of the bridge's damping (anchored at modes 1 and 3)."""
    w1, w3 = bridge.omega_rad_s[0], bridge.omega_rad_s[2]
    z = bridge.damping_ratio
    return 2 * z * w1 * w3 / (w1 + w3), 2 * z / (w1 + w3)


DECKS = {
    "2x15": ((15.0, 15.0), (2.0e10, 2.0e10), (1.5e4, 1.5e4), 7.5),
    "12+16+12": ((12.0, 16.0, 12.0), (1.6e10, 2.4e10, 1.6e10), (1.4e4, 1.7e4, 1.4e4), 20.0),
}
AXLES = moving_loads([0.0, 2.5, 17.0, 19.5], [170e3] * 4, "two bogies")


def _modal(deck, n_modes, speed_kmh, ds_m=None, steps_per_period=16.0):
    spans, EJ, mu, x = DECKS[deck]
    b = Bridge.continuous(spans, EJ, mu, 0.02, n_modes=n_modes)
    opts = StepOptions(steps_per_period=steps_per_period, ds_m=ds_m, free_vibration_periods=1.0)
    return run_sweep(b, AXLES, "mlm", [speed_kmh], histories=True, where=x, options=opts)


def _fe(deck, speed_kmh, t, sub=4):
    """The FE beam's deflection and acceleration at the deck's response point at the times ``t``
    (``sub`` Newmark steps per interval of ``t``)."""
    spans, EJ, mu, x = DECKS[deck]
    beam = FEBeam(spans, EJ, mu, 24)
    # C = a M + b K with the modal model's Rayleigh coefficients (its modes 1 and 3)
    ab = _rayleigh_ab(Bridge.continuous(spans, EJ, mu, 0.02, n_modes=3))
    _, wf, af = fe_moving_loads(beam, AXLES.axle_offsets_m, AXLES.axle_loads_n, speed_kmh / 3.6, t[1] / sub, t[-1],
                                ab, x)
    return wf[::sub][:t.size], af[::sub][:t.size]


@pytest.mark.slow  # the direct FE references: 3.0-3.9 s of CPU a deck
@pytest.mark.parametrize("deck", list(DECKS))
def test_mlm_against_a_direct_fe_integration(deck):
    """Four axles of 170 kN at 250 km/h over a two-span and a three-span deck (2 % Rayleigh damping
    anchored at modes 1 and 3 in both models), response in the middle of a span, the crossing and one
    fundamental period after it. The modal MLM (RK4 on the exact modes, 8 steps per period of mode 32)
    against a Hermite-cubic FE beam of 24 elements per span integrated directly by Newmark (average
    acceleration, 4 steps per RK4 step, no modal truncation), on one time grid. Measured (whole
    history, relative to the FE peak): deflection 1e-2 (4 modes), 3e-4..5e-4 (16), 2e-5..8e-5 (32);
    acceleration 0.19..0.22 (4), 0.019..0.020 (16), 0.004..0.007 (32): the modal truncation converges
    to the FE beam. At 16 steps per period (twice the steps) every one of these errors is the same
    to 2 digits (the time step's share lies far below the truncation's), so the coarser grid tests
    the same property. Asserted: 32 modes within 2e-4 (deflection) and 1e-2 (acceleration), 16
    modes within 1e-3 and 3e-2, and the error falls from 4 to 16 to 32 modes."""
    r32 = _modal(deck, 32, 250.0, steps_per_period=8.0)
    wf, af = _fe(deck, 250.0, r32.time_s[0])
    assert np.abs(wf).max() > 1e-4  # a real deflection (m)
    err = {}
    for n in (4, 16, 32):
        r = r32 if n == 32 else _modal(deck, n, 250.0, ds_m=r32.ds_m)  # the same grid, n modes
        assert r.n_steps == r32.n_steps
        err[n] = (np.abs(r.midspan_disp_m[0] - wf).max() / np.abs(wf).max(),
                  np.abs(r.midspan_acc_m_s2[0] - af).max() / np.abs(af).max())
    print(deck, err)
    assert err[32][0] < 2e-4 and err[32][1] < 1e-2
    assert err[16][0] < 1e-3 and err[16][1] < 3e-2
    assert err[4][1] > err[16][1] > err[32][1] and err[4][0] > err[16][0] > err[32][0]


def test_step_convergence_on_a_continuous_deck():
    """The three-span deck (3 modes by the rule) under the four axles, 200..300 km/h, maxima between
    the steps too (dense maxima): the peak acceleration moves 0.05 % from 16 to 32 steps per period of
    the highest mode and 0.005 % from 32 to 64 (measured); asserted < 0.1 % and < 0.02 %."""
    spans, EJ, mu, x = DECKS["12+16+12"]
    b = Bridge.continuous(spans, EJ, mu, 0.02)
    speeds = np.arange(200.0, 300.0 + 1e-9, 5.0)
    peak = {spp: run_sweep_compiled(b, AXLES, "mlm", speeds, options=StepOptions(steps_per_period=spp,
                                                                              dense_maxima=True)).max_acc_m_s2.max()
            for spp in (16, 32, 64)}
    assert abs(peak[16] / peak[32] - 1) < 1e-3
    assert abs(peak[32] / peak[64] - 1) < 2e-4


def test_compiled_equals_numpy_on_a_continuous_deck():
    """The compiled kernels and the numpy stepper take the same tables: equal to 1e-12 relative."""
    spans, EJ, mu, x = DECKS["12+16+12"]
    b = Bridge.continuous(spans, EJ, mu, 0.02)
    speeds = [210.0, 250.0, 290.0]
    for where in ("midspan", 5.0):
        a = run_sweep_compiled(b, AXLES, "mlm", speeds, where=where)
        n = run_sweep(b, AXLES, "mlm", speeds, where=where)
        np.testing.assert_allclose(a.max_acc_m_s2, n.max_acc_m_s2, rtol=1e-12, atol=0)


def test_what_is_not_wired_is_refused():
    """The exact envelope refuses a continuous deck with one line naming the allowed choice; an RK4 run
    records one point (no --where deck)."""
    b = Bridge.continuous((15.0, 15.0), 2.0e10, 1.5e4, 0.02)
    with pytest.raises(InputError, match="exact MLM envelope is written for the sine modes.*allowed --method rk4"):
        sweep_exact(b, AXLES, [200.0])
    with pytest.raises(InputError, match="where: 'deck' is not allowed for an RK4 run"):
        run_sweep(b, AXLES, "mlm", [200.0], where="deck")
