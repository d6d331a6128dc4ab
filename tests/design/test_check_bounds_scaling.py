"""The mass and stiffness bounds of EN 1991-2 6.4.6.3.2/3 against the scaling of the modal beam.

With ζ per mode independent of the mass and stiffness (EN 1991-2 6.4.6.3.1: ζ from the span only;
Rayleigh 1-3 keeps its per-mode ratios because every frequency scales alike), the mass x kappa
moves every frequency by 1/sqrt(kappa): substituting t = sqrt(kappa) s in
kappa m q'' + 2 zeta sqrt(k kappa m) q' + k q = P phi(v t) gives q_kappa(t; v) = q_1(t / sqrt(kappa);
v sqrt(kappa)). So at speed v under the bound the deflections, moments, shears and reactions equal
the nominal ones at v sqrt(kappa), the accelerations are the nominal ones / kappa, positions are the
same and times x sqrt(kappa). Stiffness x kappa: the nominal bridge at v / sqrt(kappa), accelerations,
moments, shears and reactions unchanged, deflections / kappa, times / sqrt(kappa).

The check runs every bound directly (its own bridge, its own speeds); these tests rebuild each bound's
curves at the check's own speeds (the 1 km/h grid and the 0.1 km/h refinements) from the nominal
bridge at the mapped speeds and require agreement to 1e-9 relative on every maximum and speed the
check reports (positions 1e-8 L), for HSLM-A7 and ICE-2 and both damping models.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from adm_sim.design import check_effects as ce
from adm_sim.model.bridge import named_bridge
from adm_sim.design.check import resolve_trains, run_check
from adm_sim.integrate.envelope import moving_load_envelope

REL = 1e-9


@pytest.fixture(scope="module", params=["modal", "rayleigh13"])
def checked(request):
    b = named_bridge("B1")
    res = run_check(b, 250.0, resolve_trains("HSLM-A7,ICE-2"), damping_model=request.param,
                    mass_bounds="standard:4000,2000", stiffness_bounds=(-0.1, 0.1))
    return res


def _kappa(res, r):
    """("mass" | "stiffness", kappa) of the bound result ``r`` against the nominal ``res``."""
    km = r.bridge.mass_per_length_kg_m / res.bridge.mass_per_length_kg_m
    ks = r.bridge.EJ_Nm2 / res.bridge.EJ_Nm2
    assert (km == 1.0) != (ks == 1.0)
    return ("mass", km) if km != 1.0 else ("stiffness", ks)


@pytest.mark.slow  # with the module fixture checked (two checks with four bounds): 2.1-2.6 s of CPU a damping model
def test_every_bound_is_the_nominal_bridge_at_mapped_speeds(checked):
    res = checked
    assert [label.split(" (")[0] for label, _ in res.bounds] == [
        "mass lower bound -3.15 %", "mass upper bound +7.67 %", "stiffness lower bound -10 %",
        "stiffness upper bound +10 %"]
    zeta_nominal = res.bridge.modal_damping_ratios(0.0)
    for label, r in res.bounds:
        what, k = _kappa(res, r)
        # the damping ratio of every mode is the nominal one (Rayleigh 1-3 included)
        np.testing.assert_allclose(r.bridge.modal_damping_ratios(0.0), zeta_nominal, rtol=1e-12)
        assert r.modes == res.modes
        speed_factor = math.sqrt(k) if what == "mass" else 1.0 / math.sqrt(k)
        acc_factor = 1.0 / k if what == "mass" else 1.0
        disp_factor = 1.0 if what == "mass" else 1.0 / k
        for c, t in zip(r.trains, resolve_trains("HSLM-A7,ICE-2")):
            env = moving_load_envelope(res.bridge, t.axle_offsets_m, t.axle_loads_n, c.speeds_kmh * speed_factor,
                                       where="deck")
            np.testing.assert_allclose(c.max_acc_m_s2, env.max_acc_m_s2 * acc_factor, rtol=REL, err_msg=label)
            np.testing.assert_allclose(c.max_disp_m, env.max_disp_m * disp_factor, rtol=REL, err_msg=label)
            np.testing.assert_allclose(c.max_disp_midspan_m, env.max_disp_midspan_m * disp_factor, rtol=REL,
                                       err_msg=label)
            np.testing.assert_allclose(c.max_moment_Nm, env.max_moment_Nm, rtol=REL, err_msg=label)
            # the position of the largest acceleration at every speed: 1e-8 L (Newton stops on the value, which
            # is flat in x at the maximum; measured 2.6e-9 L at most; printed to the mm)
            np.testing.assert_allclose(c.x_acc_m, env.x_acc_m, rtol=0, atol=1e-8 * res.bridge.span_m, err_msg=label)
            # the governing value and speed of the bound
            i = c.i_max
            assert int(np.argmax(env.max_acc_m_s2)) == i
            assert c.speeds_kmh[i] * speed_factor == pytest.approx(env.speeds_kmh[i], rel=1e-15)


@pytest.mark.slow  # reads the module fixture checked (its cost counts here)
def test_every_effect_of_every_bound_is_the_nominal_one_at_mapped_speeds(checked, monkeypatch):
    """φ'_dyn of the moment and shear at every section and the reactions (EN 1991-2 6.4.6.5(3)): the
    forces do not scale (mass or stiffness), so the largest dynamic value of every effect is the nominal
    one at the mapped speeds; the two passes of :func:`adm_sim.design.check_effects.train_effects` keep their
    speed steps in the bound's own km/h (the coarse step maps to sqrt(kappa) km/h)."""
    res = checked
    for label, r in res.bounds:
        what, k = _kappa(res, r)
        speed_factor = math.sqrt(k) if what == "mass" else 1.0 / math.sqrt(k)
        monkeypatch.setattr(ce, "COARSE_STEP_KMH", 1.0 * speed_factor)
        for c, t in zip(r.trains, resolve_trains("HSLM-A7,ICE-2")):
            eff = ce.train_effects(res.bridge, t.axle_offsets_m, t.axle_loads_n, c.speeds_kmh * speed_factor)
            np.testing.assert_allclose(c.effects.static_max, eff.static_max, rtol=1e-12, err_msg=label)
            np.testing.assert_allclose(c.effects.dynamic_max, eff.dynamic_max, rtol=REL, err_msg=label)
            np.testing.assert_allclose(c.effects.at_speed_kmh * speed_factor, eff.at_speed_kmh, rtol=1e-12,
                                       err_msg=label)
            np.testing.assert_allclose(c.effects.phi_dyn, eff.phi_dyn, rtol=0, atol=REL, err_msg=label)
        monkeypatch.undo()


def test_the_bounds_with_the_closed_form_of_one_force():
    """The scaling on its own, away from the check: one 100 kN force over a 12 m beam, 5 modes, mass x
    0.8 at 200 km/h against the nominal beam at 200 sqrt(0.8) km/h; stiffness x 1.3 at 200 km/h against
    the nominal at 200 / sqrt(1.3); midspan and deck, every quantity."""
    b = dataclasses.replace(named_bridge("B1"), span_m=12.0, n_modes=5, damping_model="modal")
    offs, loads = np.array([0.0]), np.array([1e5])
    for key, k in (("mass_per_length_kg_m", 0.8), ("EJ_Nm2", 1.3)):
        bb = dataclasses.replace(b, **{key: getattr(b, key) * k})
        f = math.sqrt(k) if key.startswith("mass") else 1.0 / math.sqrt(k)
        for where in ("midspan", "deck"):
            d = moving_load_envelope(bb, offs, loads, [200.0], where=where)
            n = moving_load_envelope(b, offs, loads, [200.0 * f], where=where)
            acc, disp = (1.0 / k, 1.0) if key.startswith("mass") else (1.0, 1.0 / k)
            assert d.max_acc_m_s2[0] == pytest.approx(n.max_acc_m_s2[0] * acc, rel=REL)
            assert d.max_disp_m[0] == pytest.approx(n.max_disp_m[0] * disp, rel=REL)
            assert d.max_moment_Nm[0] == pytest.approx(n.max_moment_Nm[0], rel=REL)
            assert d.t_acc_s[0] == pytest.approx(n.t_acc_s[0] * (math.sqrt(k) if key.startswith("mass")
                                                                   else 1.0 / math.sqrt(k)), rel=1e-8)


def _clear_static_caches():
    """Empty every cache of static results (the check's, the effects' and design_loads')."""
    import adm_sim.design.check as chk
    from adm_sim.design import design_loads

    for f in (chk._static_midspan_max_cached, ce._sample_statics_cached, ce._lm71_effects_cached,
              design_loads._train_midspan_max_cached, design_loads._lm71_midspan):
        f.cache_clear()


def test_threads_and_caches_change_no_number(monkeypatch):
    """The trains run in threads and the static effects are cached: one thread and empty caches give
    the same result, bit for bit (B1, HSLM-A7 and ICE-2, V = 200 km/h, a mass bound)."""
    import adm_sim.design.check as chk

    trains = resolve_trains("HSLM-A7,ICE-2")
    b = named_bridge("B1")
    two = run_check(b, 200.0, trains, mass_bounds=(-0.1, 0.0))
    monkeypatch.setattr(chk, "CHECK_THREADS", 1)
    _clear_static_caches()
    one = run_check(b, 200.0, trains, mass_bounds=(-0.1, 0.0))
    for r2, r1 in [(two, one), (two.bounds[0][1], one.bounds[0][1])]:
        for c2, c1 in zip(r2.trains, r1.trains):
            for name in ("speeds_kmh", "max_acc_m_s2", "x_acc_m", "max_disp_m", "max_moment_Nm"):
                assert np.array_equal(getattr(c2, name), getattr(c1, name)), name
            assert np.array_equal(c2.effects.dynamic_max, c1.effects.dynamic_max)
            assert np.array_equal(c2.effects.static_max, c1.effects.static_max)
            assert c2.static_disp_m == c1.static_disp_m and c2.design == c1.design
    # a mass bound takes the nominal bridge's cached static midspan maxima: they are computed without the
    # mass, so a fresh computation for the bound's own bridge is the same number
    bb = dict(two.bounds)[two.bounds[0][0]].bridge
    t = trains[0]
    fresh = chk._static_midspan_max(bb.span_m, bb.EJ_Nm2, bb.mode_numbers, t.axle_offsets_m, t.axle_loads_n, 2000)
    assert chk.static_midspan_max(bb, t.axle_offsets_m, t.axle_loads_n) == fresh


def test_static_midspan_max_against_the_bridge_modal_stiffness():
    """The static midspan maxima take K_j = (L/2) (j pi/L)^4 EJ, without the mass; the former computation took
    the bridge's M_j omega_j^2 (the same value up to round-off): every train on B1 and B2, 3 and 5 modes,
    agree to 2e-15 relative (measured 6.7e-16)."""
    import adm_sim.design.check as chk
    from adm_sim.design.check_effects import midspan_modal_sum

    for name in ("B1", "B2"):
        for n in (3, 5):
            b = dataclasses.replace(named_bridge(name), n_modes=n)
            L, j = b.span_m, b.mode_numbers
            for t in resolve_trains("hslm,ICE-2,Eurostar,Railjet,ICE-4"):
                offs, loads = np.asarray(t.axle_offsets_m, dtype=float), np.asarray(t.axle_loads_n, dtype=float)
                s = np.arange(0.0, offs[-1] + L, L / 2000)
                gain = np.sin(j * np.pi / 2) / b.modal_stiffness_N_m
                mgain = gain * b.EJ_Nm2 * (j * np.pi / L) ** 2
                w, m = np.zeros_like(s), np.zeros_like(s)
                midspan_modal_sum(s, offs, loads, float(L), j, gain, mgain, w, m)
                np.testing.assert_allclose(chk.static_midspan_max(b, offs, loads), (np.abs(w).max(), np.abs(m).max()),
                                           rtol=2e-15, atol=0)


def test_cached_arrays_are_read_only():
    """A cached static array is shared by every caller: writing into it raises instead of changing it."""
    b = named_bridge("B1")
    lm = ce.lm71_effects(b.span_m, 1.0)
    with pytest.raises(ValueError, match="read-only"):
        lm[0] = 0.0
    assert ce.lm71_effects(b.span_m, 1.0) is lm  # the same object, not a copy
    t = resolve_trains("HSLM-A7")[0]
    effects = ce.effects_of(b.span_m)
    offs, loads = np.asarray(t.axle_offsets_m, dtype=float), np.asarray(t.axle_loads_n, dtype=float)
    bps = np.unique(np.concatenate([offs, offs + b.span_m]))
    arrays = ce._sample_statics(effects, b.span_m, offs, loads, bps, b.mode_numbers, 20)
    for a in arrays:
        with pytest.raises(ValueError, match="read-only"):
            a[0] = a[0]
    again = ce._sample_statics(effects, b.span_m, offs.copy(), loads.copy(), bps.copy(), b.mode_numbers, 20)
    assert all(x is y for x, y in zip(arrays, again))  # cached by value, not by identity
