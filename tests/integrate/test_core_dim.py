"""DIM solver: limiting cases (soft and rigid suspensions, conventional and Jacobs trains),
step convergence and contact-force balance.

The limiting cases and the convergence run on the compiled kernels (``run_sweep_compiled``: the
numpy stepper's grid and maxima to ~1e-13 relative, held to 1e-12 by ``tests/integrate/test_sweep_backends.py``
and ``tests/integrate/test_batch.py``), at a sixth of the numpy stepper's CPU; the contact forces need the
histories only the numpy stepper keeps."""

import tomllib
from importlib import resources

import numpy as np
import pytest

from adm_sim.model.bridge import named_bridge
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled
from adm_sim.inputs.train_files import load_train, train_from_mapping


def _modified(name, **changes):
    """A packaged train with every vehicle type's fields replaced (callables get the old value)."""
    fname = {"ICE-2": "ice2.toml", "Eurostar": "eurostar.toml"}[name]
    data = tomllib.loads(resources.files("adm_sim").joinpath("data/trains", fname).read_text())
    for vt in data["vehicle_types"].values():
        for key, val in changes.items():
            vt[key] = val(vt) if callable(val) else val
    data["loads_differ_from_masses"] = True  # limit cases: the table's static loads, other masses, on purpose
    return train_from_mapping(data, source=f"modified {name}")


SOFT = dict(k_p_N_m=1.0, c_p_Ns_m=0.0, k_s_N_m=1.0, c_s_Ns_m=0.0, m_w_kg=0.0)


@pytest.mark.parametrize("train_name", ["ICE-2", "Eurostar"])
def test_soft_suspension_massless_wheels_give_the_mlm(train_name):
    # k_p, k_s -> 1 N/m, no dampers, m_w = 0: the bridge sees the static axle loads only,
    # so the DIM must reproduce the MLM (differences ~ k_p w / F ~ 1e-8).
    b = named_bridge("B3")
    speeds = [200.0, 265.0, 300.0]
    dim = run_sweep_compiled(b, _modified(train_name, **SOFT), "dim", speeds).max_acc_m_s2
    mlm = run_sweep_compiled(b, load_train(train_name), "mlm", speeds).max_acc_m_s2
    np.testing.assert_allclose(dim, mlm, rtol=1e-6)


@pytest.mark.parametrize("train_name", ["ICE-2", "Eurostar"])
def test_rigid_primary_stage_equals_masses_carried_by_the_wheels(train_name):
    # Rigid primary stage and J_b = m_b b^2 / 4: each bogie acts as two point masses m_b / 2
    # riding on its axles. Car bodies made negligible. Reference: the same train whose
    # wheelsets carry m_w + m_b / 2 (handled by the bridge's modified mass matrix, Eq. 13)
    # with soft, massless bogies. Agreement to 0.3 % (the primary stage at 1e10 N/m still
    # deflects by (omega_bridge / omega_primary)^2 ~ 3e-4).
    b = named_bridge("B3")
    speeds = [250.0, 268.0, 290.0]
    body = dict(m_c_kg=1.0, J_c_kgm2=1.0, k_s_N_m=1.0, c_s_Ns_m=0.0)
    # c_p damps the stiff bogie mode (~2900 rad/s) at 70 % of critical: the rail's kink at the
    # support makes the wheel velocity jump on entry, which rings an undamped stiff spring.
    rigid = _modified(train_name, k_p_N_m=1e10, c_p_Ns_m=lambda vt: 1.4 * np.sqrt(1e10 * vt["m_b_kg"] / 2),
                      J_b_kgm2=lambda vt: vt["m_b_kg"] * vt["b_m"] ** 2 / 4, **body)
    lumped = _modified(train_name, m_w_kg=lambda vt: vt["m_w_kg"] + vt["m_b_kg"] / 2,
                       m_b_kg=1.0, J_b_kgm2=1.0, k_p_N_m=1.0, c_p_Ns_m=0.0, **body)
    opts = StepOptions(steps_per_period=32)
    a_rigid = run_sweep_compiled(b, rigid, "dim", speeds, options=opts).max_acc_m_s2
    a_lumped = run_sweep_compiled(b, lumped, "dim", speeds, options=opts).max_acc_m_s2
    a_mlm = run_sweep_compiled(b, load_train(train_name), "mlm", speeds, options=opts).max_acc_m_s2
    np.testing.assert_allclose(a_rigid, a_lumped, rtol=3e-3)
    # the carried masses matter: the check above is not a trivial MLM = MLM
    assert np.max(np.abs(a_lumped / a_mlm - 1)) > 0.01


@pytest.mark.parametrize("bridge_name,train_name,lo,hi", [("B1", "ICE-2", 250.0, 276.0),
                                                         ("B3", "Eurostar", 258.0, 284.0)])
def test_dim_step_convergence(bridge_name, train_name, lo, hi):
    # Halving the step moves the DIM peak by < 0.1 % (speeds around the resonance);
    # conventional and Jacobs trains.
    b, t = named_bridge(bridge_name), load_train(train_name)
    speeds = np.arange(lo, hi, 1.0)
    opts = StepOptions()
    p1 = run_sweep_compiled(b, t, "dim", speeds, options=opts).peak()
    p2 = run_sweep_compiled(b, t, "dim", speeds, options=opts.halved()).peak()
    assert p1["speed_kmh"] == p2["speed_kmh"]
    assert abs(p1["acc_m_s2"] / p2["acc_m_s2"] - 1) < 1e-3


def test_interaction_lowers_the_resonance_peak_b1_ice2():
    # Section 1: vehicle-bridge interaction reduces the resonant response (Fig. 15).
    b, t = named_bridge("B1"), load_train("ICE-2")
    speeds = np.arange(250.0, 276.0, 1.0)
    mlm = run_sweep_compiled(b, t, "mlm", speeds).peak()
    dim = run_sweep_compiled(b, t, "dim", speeds).peak()
    assert dim["acc_m_s2"] < 0.95 * mlm["acc_m_s2"]
    assert abs(dim["speed_kmh"] - mlm["speed_kmh"]) <= 5.0


@pytest.mark.slow
@pytest.mark.parametrize("train_name", ["ICE-2", "Eurostar"])
def test_contact_forces_balance_the_static_loads(train_name):
    # Eq. (7): averaged over an axle's passage the contact force equals its static load
    # (the suspension and inertia forces oscillate about zero); at 160 km/h within 3 %. On 8 steps per
    # period (half the default: 175 samples per passage) the means are the default step's to 1e-5 of
    # the load (measured +0.03 .. +0.19 % for ICE-2, +0.05 .. +0.06 % for the Eurostar on both), the
    # smallest forces 0.988-0.998 of it against 0.989-0.998.
    b, t = named_bridge("B2"), load_train(train_name)
    r = run_sweep(b, t, "dim", [160.0], histories=True, options=StepOptions(steps_per_period=8.0))
    f = r.contact_force_n[0]  # (n_steps, n_axles)
    for i in (0, 5, t.n_axles // 2, t.n_axles - 1):
        on = f[:, i] != 0.0
        assert on.sum() > 100
        assert f[on, i].mean() == pytest.approx(t.axle_loads_n[i], rel=0.03)
        assert np.all(f[on, i] > 0.0)  # the wheel stays pressed on the rail


def test_dim_rejects_load_trains():
    from adm_sim.errors import InputError
    from adm_sim.model.trains import moving_loads

    with pytest.raises(InputError, match="model: 'dim' needs a train with vehicles"):
        run_sweep(named_bridge("B1"), moving_loads([0.0], [1e5]), "dim", [200.0])
