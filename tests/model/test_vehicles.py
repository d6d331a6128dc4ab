"""Vehicle files (bodies, wheelsets, stages): the paper's trains unchanged, the sprung-mass
benchmarks of vehicle-bridge interaction, the closed-form limits, and bad input.

References
----------
* VBI-2D (D. Cantero, NTNU; GPL-3.0), its analytical verification set of a 1-DOF sprung mass on a
  simply supported beam (script "Generation of Validation examples based on the analytical
  formulation"): L = 25 m, E = 3.5e10 N/m^2, I = 1.3901 m^4, m = 18358 kg/m, no beam damping;
  m_V = 5750 kg, k_V = 1595e3 N/m, c_V = 0 or 4e5 N s/m; v = 25 m/s; smooth, or a 10 mm ramp
  rising linearly from L/3 to L/2. :func:`sprung_mass_reference` solves that formulation here --
  modal beam, coupled to the oscillator through the contact point, with the convective term of the
  damper and the profile's ``r``, ``v r'`` -- by scipy's DOP853 at rtol 1e-8 (1e-10 with a ramp,
  integrated piecewise between its kinks). The set also ships its own output
  (``Verification/Verification_Analytical_{SprungVeh,RampOn,DampOn}.mat``: midspan displacement
  every 1 ms, from Newmark-beta at dt = 1 ms on 100 modes); :data:`VBI2D_SHIPPED` holds its peak
  and every 100th sample, against which the reference is compared too.
* Yang & Yau (1997), "Vehicle-bridge interaction element for dynamic analysis", J. Struct. Eng.
  123(11), example after Biggs (1964): L = 25 m, E = 2.87e9 N/m^2, I = 2.9 m^4, m = 2303 kg/m,
  m_V = 5750 kg, k_V = 1595 kN/m, v = 100 km/h (the same vehicle as VBI-2D's set).
"""

from __future__ import annotations

import functools
import subprocess
import sys
import tomllib
from importlib import resources

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from adm_sim.model.bridge import Bridge, named_bridge
from adm_sim.errors import InputError
from adm_sim.fields import AXLE_LOAD_REL_TOL
from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled
from adm_sim.inputs.train_files import load_train, train_from_mapping, vehicle_file_mapping
from adm_sim.model.vehicles import to_toml

PAPER = {"ICE-2": "ice2", "Eurostar": "eurostar", "Railjet": "railjet", "ICE-4": "ice4"}


def _shipped(key):
    return resources.files("adm_sim").joinpath("data/vehicles", f"{key}_vehicles.toml")


def _vehicle_train(key):
    return train_from_mapping(tomllib.loads(_shipped(key).read_text()), source=f"{key}_vehicles.toml")


# ---------------------------------------------------------------------- the paper's trains
@pytest.mark.parametrize("name", list(PAPER))
def test_paper_train_as_vehicle_file_has_the_same_matrices(name):
    """Every unit's M, K_s, C_s, Lw, k_p, c_p to 1e-12 relative (measured <= 5e-15: the positions
    differ by the rounding of ``front + x``); axle loads and wheelset masses bit for bit."""
    t, v = load_train(name), _vehicle_train(PAPER[name])
    assert v.n_axles == t.n_axles and v.n_dof == t.n_dof and len(v.units) == len(t.units)
    np.testing.assert_allclose(v.axle_offsets_m, t.axle_offsets_m, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(v.axle_loads_n, t.axle_loads_n)
    np.testing.assert_array_equal(v.wheel_mass_kg, t.wheel_mass_kg)
    np.testing.assert_array_equal(v.unit_of_axle, t.unit_of_axle)
    for i in range(len(t.units)):
        a, b = t.unit_matrices(i), v.unit_matrices(i)
        for f in ("M", "K_s", "C_s", "Lw", "k_p", "c_p"):
            x, y = getattr(a, f), getattr(b, f)
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-12 * np.abs(x).max(), err_msg=f"{name} unit {i} {f}")
    np.testing.assert_allclose([c[1] for u in v.units for c in u.cars], [c[1] for u in t.units for c in u.cars],
                               rtol=0, atol=1e-12)  # car bodies' end points (where comfort b_v is read)


@pytest.mark.parametrize("name", list(PAPER))
def test_shipped_vehicle_files_are_the_generated_ones(name):
    """The shipped files are what :func:`vehicle_file_mapping` writes from the train files (no hand edits)."""
    t = load_train(name)
    body = to_toml(vehicle_file_mapping(t))
    text = _shipped(PAPER[name]).read_text()
    assert text.split("\nname = ", 1)[1] == body.split("name = ", 1)[1]


@pytest.mark.parametrize("name", list(PAPER))
def test_dim_maxima_of_table4_bridges_equal_on_the_compiled_kernels(name):
    """Table 4's bridges B1-B4, a DIM sweep on the numba kernels (the compiled batch): maxima of the
    vehicle file equal the train file's to 1e-12 relative (measured <= 2e-14), so Table 4 (Δζ
    calibrated on these maxima) is unchanged."""
    t, v = load_train(name), _vehicle_train(PAPER[name])
    speeds = [160.0, 220.0, 300.0]
    for b in ("B1", "B2", "B3", "B4"):
        br = named_bridge(b)
        a = run_sweep_compiled(br, t, "dim", speeds)
        c = run_sweep_compiled(br, v, "dim", speeds)
        np.testing.assert_allclose(c.max_acc_m_s2, a.max_acc_m_s2, rtol=1e-12, err_msg=f"{name} {b}")
        np.testing.assert_allclose(c.max_disp_m, a.max_disp_m, rtol=1e-12, err_msg=f"{name} {b}")


def test_table4_delta_zeta_vbi_unchanged_on_b1():
    """Table 4's VBI row is a calibration on these maxima: ICE-4 on B1 (speeds 250-300 km/h),
    dz_VBI of the vehicle file equals the train file's (0.379 %) to 1e-9 (as fractions)."""
    from adm_calib.calibrate import calibrate

    speeds = np.arange(250.0, 301.0, 2.0)
    a = calibrate(named_bridge("B1"), load_train("ICE-4"), speeds_kmh=speeds, adapted_curve=False)
    b = calibrate(named_bridge("B1"), _vehicle_train("ice4"), speeds_kmh=speeds, adapted_curve=False)
    assert a.delta_zeta_vbi == pytest.approx(0.00379, abs=5e-6)
    assert b.delta_zeta_vbi == pytest.approx(a.delta_zeta_vbi, abs=1e-9)
    assert b.eada_note.startswith("EADA is not defined for ICE-4: its vehicles are bodies and stages")


def test_vehicle_file_runs_through_load_train_and_the_checks(tmp_path):
    """``--train file.toml`` takes a vehicle file (load_train -> train_from_mapping); consistency_rows
    skips its units (their loads are checked against statics when loaded)."""
    p = tmp_path / "my_vehicle_train.toml"
    p.write_text(_shipped("railjet").read_text())
    t = load_train(str(p))
    assert t.n_axles == load_train("Railjet").n_axles
    from adm_sim.model.trains import consistency_rows

    assert all(r.item.startswith("n_p") for r in consistency_rows(t, rel_tol=AXLE_LOAD_REL_TOL))


# ---------------------------------------------------------------------- sprung mass benchmarks
def sprung_mass_reference(L, EI, m, m_v, k_v, c_v, v, n_modes, rigid=False, ramp=None):
    """Midspan deflection (m, downwards) of a simply supported modal beam under a sprung mass
    entering at t = 0 in static equilibrium (VBI-2D's analytical formulation), while it is on the
    beam: ``(t_s, w_mid_m)``. ``rigid``: the moving mass (contact held, no spring). ``ramp``:
    ``(at_m, length_m, height_m)``, a rise of the rail (elevation up) under the wheel, which then
    follows ``u = w - e(x)``, ``u_dot = w_dot - v e'(x)`` (w and u downwards)."""
    i = np.arange(1, n_modes + 1)
    w = (i * np.pi / L) ** 2 * np.sqrt(EI / m)
    g = 9.81
    c0 = np.sqrt(2.0 / L)

    def rhs(t, s):
        x = v * t
        p = c0 * np.sin(i * np.pi * x / L)
        dp = c0 * (i * np.pi / L) * np.cos(i * np.pi * x / L)
        q, qd = s[:n_modes], s[n_modes:2 * n_modes]
        if rigid:  # (m I + m_v p p^T) qdd = p (m_v g - m_v (2 v dp.qd + v^2 ddp.q)) - m w^2 q
            ddp = -c0 * (i * np.pi / L) ** 2 * np.sin(i * np.pi * x / L)
            A = m * np.eye(n_modes) + m_v * np.outer(p, p)
            f = p * m_v * (g - 2.0 * v * (dp @ qd) - v * v * (ddp @ q)) - m * w**2 * q
            return np.concatenate([qd, np.linalg.solve(A, f)])
        y, yd = s[2 * n_modes], s[2 * n_modes + 1]
        e, de = 0.0, 0.0
        if ramp is not None:
            at, ln, h = ramp
            e = h * min(max((x - at) / ln, 0.0), 1.0)
            de = h / ln if at <= x < at + ln else 0.0
        u, ud = p @ q - e, p @ qd + v * (dp @ q - de)
        F = k_v * (y - u) + c_v * (yd - ud)
        return np.concatenate([qd, -w**2 * q + p * (m_v * g + F) / m, [yd, -F / m_v]])

    T = L / v
    ts = np.linspace(0.0, T, 1001)
    n = 2 * n_modes + (0 if rigid else 2)
    mid = c0 * np.sin(i * np.pi / 2.0)
    if ramp is None:
        sol = solve_ivp(rhs, (0.0, T), np.zeros(n), method="DOP853", rtol=1e-8, atol=1e-13, t_eval=ts)
        return ts, mid @ sol.y[:n_modes]
    cuts = [0.0, ramp[0] / v, (ramp[0] + ramp[1]) / v, T]  # piecewise between the kinks of the ramp
    s0, out = np.zeros(n), []
    for a, b in zip(cuts[:-1], cuts[1:]):
        te = np.append(ts[(ts >= a) & (ts < b)], b)
        sol = solve_ivp(rhs, (a, b), s0, method="DOP853", rtol=1e-10, atol=1e-14, t_eval=te)
        s0 = sol.y[:, -1]
        out.append(sol.y[:n_modes, :-1])
    out.append(s0[:n_modes, None])
    return ts, mid @ np.concatenate(out, axis=1)


def sprung_mass_train(m_v, k_v, c_v, m_w=0.0):
    return train_from_mapping({"name": "sprung mass", "vehicles": {"SM": {
        "length_m": 0.0, "bodies": [{"name": "mass", "mass_kg": m_v, "x_m": 0.0}],
        "wheelsets": [{"name": "wheel", "mass_kg": m_w, "x_m": 0.0}],
        "stages": [{"upper": "mass", "lower": "wheel", "x_m": 0.0, "k_N_m": k_v, "c_Ns_m": c_v}]}},
        "composition": [{"vehicle": "SM"}]}, source="sprung mass")


def _dim_on_bridge(bridge, train, v_m_s):
    r = run_sweep(bridge, train, "dim", [3.6 * v_m_s], histories=True)
    on = r.time_s[0] <= bridge.span_m / v_m_s
    return r.time_s[0][on], r.midspan_disp_m[0][on]


N_MODES = 6  # both sides (the same truncation); modes 7+ add < 1e-4 of the first to the midspan deflection


@functools.cache
def vbi2d_smooth_reference(c_v):
    """:func:`sprung_mass_reference` of VBI-2D's smooth case (6 modes, k_V 1595 kN/m, damper ``c_v``),
    solved once per process and shared by the tests that compare with it (read only)."""
    L, EI, m, v = 25.0, 3.5e10 * 1.3901, 18358.0, 25.0
    ts, ref = sprung_mass_reference(L, EI, m, 5750.0, 1595e3, c_v, v, N_MODES)
    ts.flags.writeable = False
    ref.flags.writeable = False
    return ts, ref


@pytest.mark.slow
@pytest.mark.parametrize("c_v, peak_mm", [(0.0, 0.41866), (4.0e5, 0.41890)], ids=["undamped", "damped"])
def test_sprung_mass_vbi2d_verification_set(c_v, peak_mm):
    """VBI-2D's set (smooth profile): the DIM's midspan deflection history equals the analytical
    formulation's within 5e-5 of its peak (measured 1.4e-5 undamped, 1.3e-5 damped: RK4 at 16 steps
    per period of mode 6 against DOP853), the peak (0.41866 mm undamped, 0.41890 mm damped) within
    2e-5 relative (measured 1.5e-6). The vehicle file compiles the 1-DOF oscillator: one body
    without pitch, one massless wheelset, one stage."""
    L, EI, m, v = 25.0, 3.5e10 * 1.3901, 18358.0, 25.0
    br = Bridge(span_m=L, EJ_Nm2=EI, mass_per_length_kg_m=m, damping_ratio=0.0, n_modes=N_MODES,
                damping_model="modal")
    tr = sprung_mass_train(5750.0, 1595e3, c_v)
    assert tr.axle_loads_n[0] == pytest.approx(5750.0 * 9.81, rel=1e-12)
    ts, ref = vbi2d_smooth_reference(c_v)
    t, d = _dim_on_bridge(br, tr, v)
    assert 1e3 * ref.max() == pytest.approx(peak_mm, abs=1e-5)
    assert d.max() == pytest.approx(ref.max(), rel=2e-5)
    assert np.abs(d - np.interp(t, ts, ref)).max() <= 5e-5 * ref.max()


#: VBI-2D's shipped analytical output (github.com/DanielCanteroNTNU/VBI-2D, Verification/
#: Verification_Analytical_<case>.mat, written by V01_Analytical_Verification_Examples.m): peak midspan
#: deflection (mm, downwards), its time (s), and the deflection at t = 0, 0.1, ..., 1.0 s (mm).
VBI2D_SHIPPED = {
    "SprungVeh": (0.418545, 0.436, [0.0, 0.088332, 0.259246, 0.258323, 0.39784, 0.367328, 0.352633, 0.335139,
                                    0.173337, 0.157226, -0.029732]),
    "RampOn": (0.467210, 0.454, [0.0, 0.088332, 0.259246, 0.258323, 0.413236, 0.427814, 0.229403, 0.304589,
                                 0.326292, 0.039154, 0.031764]),
    "DampOn": (0.462597, 0.424, [0.0, 0.08827, 0.259614, 0.258524, 0.44363, 0.340171, 0.303837, 0.41795, 0.085285,
                                 0.22064, -0.049793]),
}


@pytest.mark.slow
@pytest.mark.parametrize("case, c_v, peak_mm, hist_tol", [("RampOn", 0.0, 0.46703, 5e-5), ("DampOn", 4.0e5, 0.46198, 2e-4)],
                         ids=["ramp-undamped", "ramp-damped"])
def test_sprung_mass_vbi2d_ramp(case, c_v, peak_mm, hist_tol):
    """VBI-2D's cases with the 10 mm ramp (rising from L/3 to L/2, then level), without and with the
    suspension damper: the DIM on the profile ``ramp:at=L/3:length=L/6:height=0.01`` against the
    formulation solved here (6 modes both): peak 0.46703 mm undamped, 0.46198 mm damped (11.6 % and
    10.3 % above the smooth track's), the DIM's within 2e-5 (measured 4.8e-6, 4.1e-6), its history
    within 5e-5 / 2e-4 of the peak (measured 1.8e-5 undamped; 9.4e-5 damped, where the damper
    force jumps at the ramp's kinks and the RK4 step straddles them). Against VBI-2D's shipped
    output (Newmark at 1 ms, 100 modes): peak within 2e-3 (measured 3.9e-4, 1.3e-3) and the samples
    every 0.1 s within 1 % of the peak (measured 0.17 %, 0.50 %): the shipped solution's own time
    step, as its Newmark scheme at 0.1 ms moves onto this reference (docs/vehicles.md)."""
    from adm_sim.inputs.track_profile import parse_irregularity
    from adm_sim.integrate.step_grid import StepOptions

    L, EI, m, v = 25.0, 3.5e10 * 1.3901, 18358.0, 25.0
    br = Bridge(span_m=L, EJ_Nm2=EI, mass_per_length_kg_m=m, damping_ratio=0.0, n_modes=N_MODES,
                damping_model="modal")
    tr = sprung_mass_train(5750.0, 1595e3, c_v)
    prof = parse_irregularity(f"ramp:at={L / 3!r}:length={L / 6!r}:height=0.01", L)
    ts, ref = sprung_mass_reference(L, EI, m, 5750.0, 1595e3, c_v, v, N_MODES, ramp=(L / 3, L / 6, 0.01))
    r = run_sweep(br, tr, "dim", [3.6 * v], histories=True, options=StepOptions(irregularity=prof))
    on = r.time_s[0] <= L / v
    t, d = r.time_s[0][on], r.midspan_disp_m[0][on]
    assert 1e3 * ref.max() == pytest.approx(peak_mm, abs=1e-5)
    assert d.max() == pytest.approx(ref.max(), rel=2e-5)
    assert np.abs(d - np.interp(t, ts, ref)).max() <= hist_tol * ref.max()
    smooth = vbi2d_smooth_reference(c_v)[1]
    assert ref.max() > 1.09 * smooth.max()  # the ramp raises the peak by ~10 %: a real effect
    peak, t_peak, samples = VBI2D_SHIPPED[case]
    assert 1e3 * ref.max() == pytest.approx(peak, rel=2e-3)
    assert ts[ref.argmax()] == pytest.approx(t_peak, abs=2.5e-3)
    assert np.abs(1e3 * ref[::100] - np.array(samples)).max() <= 0.01 * peak


def test_sprung_mass_vbi2d_smooth_against_shipped_output():
    """The smooth case against VBI-2D's shipped output: peak 0.418545 mm there, 0.41866 mm here
    (2.7e-4), samples every 0.1 s within 0.15 % of the peak (measured 0.096 % at 6 modes)."""
    ts, ref = vbi2d_smooth_reference(0.0)
    peak, t_peak, samples = VBI2D_SHIPPED["SprungVeh"]
    assert 1e3 * ref.max() == pytest.approx(peak, rel=5e-4)
    assert ts[ref.argmax()] == pytest.approx(t_peak, abs=1.5e-3)
    assert np.abs(1e3 * ref[::100] - np.array(samples)).max() <= 1.5e-3 * peak


@pytest.mark.slow
def test_sprung_mass_yang_yau_1997():
    """Yang & Yau (1997) / Biggs (1964): beam n1 = 4.78 Hz (omega_1 = 30.02 rad/s), vehicle 2.65 Hz
    (16.66 rad/s), v = 100 km/h. The DIM's peak midspan deflection (2.4083 mm) equals the reference
    formulation's within 2e-5 relative (measured 3e-7), the history within 5e-5 of the peak
    (measured 1.5e-5); the sprung mass deflects the beam 0.45 % more than the moving force (MLM,
    2.3975 mm)."""
    L, EI, m, v = 25.0, 2.87e9 * 2.9, 2303.0, 100.0 / 3.6
    br = Bridge(span_m=L, EJ_Nm2=EI, mass_per_length_kg_m=m, damping_ratio=0.0, n_modes=N_MODES,
                damping_model="modal")
    assert br.omega_rad_s[0] == pytest.approx(30.02, abs=0.01)
    tr = sprung_mass_train(5750.0, 1595e3, 0.0)
    ts, ref = sprung_mass_reference(L, EI, m, 5750.0, 1595e3, 0.0, v, N_MODES)
    t, d = _dim_on_bridge(br, tr, v)
    assert 1e3 * d.max() == pytest.approx(2.4083, abs=1e-4)
    assert d.max() == pytest.approx(ref.max(), rel=2e-5)
    assert np.abs(d - np.interp(t, ts, ref)).max() <= 5e-5 * ref.max()
    mlm = run_sweep(br, tr, "mlm", [3.6 * v], histories=True)
    on = mlm.time_s[0] <= L / v
    assert d.max() / mlm.midspan_disp_m[0][on].max() == pytest.approx(1.0045, abs=5e-4)


@pytest.mark.slow
def test_stiff_suspension_is_a_moving_mass():
    """k_V = 1e9 N/m (the oscillator at 66 Hz, above the modes that matter): the DIM's peak equals
    the moving mass's (contact held, inertia and convective terms; 2.4257 mm, 1.2 % above the moving
    force) within 1e-3 (measured 2.8e-4); the same mass as wheelset mass, within 2e-5 (measured 4.5e-6)."""
    L, EI, m, v = 25.0, 2.87e9 * 2.9, 2303.0, 100.0 / 3.6
    br = Bridge(span_m=L, EJ_Nm2=EI, mass_per_length_kg_m=m, damping_ratio=0.0, n_modes=4, damping_model="modal")
    ts, ref = sprung_mass_reference(L, EI, m, 5750.0, 0.0, 0.0, v, 4, rigid=True)
    t, d = _dim_on_bridge(br, sprung_mass_train(5750.0, 1.0e9, 0.0), v)
    assert d.max() == pytest.approx(ref.max(), rel=1e-3)
    # the same mass carried as wheelset mass (no suspension) is the moving mass by construction
    t2, d2 = _dim_on_bridge(br, sprung_mass_train(1.0, 1.0, 0.0, m_w=5749.0), v)
    assert d2.max() == pytest.approx(ref.max(), rel=2e-5)


def test_soft_suspension_is_the_moving_force_mlm():
    """k_V = 2e3 N/m (0.09 Hz): the body hardly follows the deck, the wheel force stays m_V g, the
    DIM equals the MLM (moving constant force) within 1e-3 in deflection and acceleration (measured
    7.5e-5 and 2.3e-4)."""
    br = Bridge(span_m=25.0, EJ_Nm2=2.87e9 * 2.9, mass_per_length_kg_m=2303.0, damping_ratio=0.02, n_modes=3)
    tr = sprung_mass_train(5750.0, 2.0e3, 0.0)
    speeds = [80.0, 100.0, 160.0]
    d, f = run_sweep(br, tr, "dim", speeds), run_sweep(br, tr, "mlm", speeds)
    np.testing.assert_allclose(d.max_disp_m, f.max_disp_m, rtol=1e-3)
    np.testing.assert_allclose(d.max_acc_m_s2, f.max_acc_m_s2, rtol=1e-3)


def test_sprung_mass_on_the_compiled_kernels_equals_numpy():
    br = Bridge(span_m=25.0, EJ_Nm2=2.87e9 * 2.9, mass_per_length_kg_m=2303.0, damping_ratio=0.02)
    tr = sprung_mass_train(5750.0, 1595e3, 4e4)
    a, b = run_sweep(br, tr, "dim", [100.0, 200.0]), run_sweep_compiled(br, tr, "dim", [100.0, 200.0])
    np.testing.assert_allclose(b.max_acc_m_s2, a.max_acc_m_s2, rtol=1e-12)


def test_reversed_vehicle_mirrors_positions_and_keeps_frequencies():
    """An asymmetric two-axle vehicle and the same reversed: axle offsets mirrored, static loads
    swapped, the undamped frequencies (generalised eigenproblem K x = w^2 M x) equal."""
    veh = {"length_m": 10.0,
           "bodies": [{"name": "body", "mass_kg": 20000.0, "pitch_inertia_kgm2": 1.5e5, "x_m": 4.0}],
           "wheelsets": [{"name": "a", "mass_kg": 1000.0, "x_m": 2.0}, {"name": "b", "mass_kg": 1000.0, "x_m": 9.0}],
           "stages": [{"upper": "body", "lower": "a", "x_m": 2.0, "k_N_m": 2e6, "c_Ns_m": 2e4},
                      {"upper": "body", "lower": "b", "x_m": 9.0, "k_N_m": 1e6, "c_Ns_m": 1e4}]}
    fw = train_from_mapping({"name": "f", "vehicles": {"V": veh}, "composition": [{"vehicle": "V"}]})
    bw = train_from_mapping({"name": "r", "vehicles": {"V": veh}, "composition": [{"vehicle": "V", "reversed": True}]})
    np.testing.assert_allclose(fw.axle_offsets_m, [0.0, 7.0])
    np.testing.assert_allclose(bw.axle_offsets_m, [0.0, 7.0])
    # statics: body 4 m from a, 5 m from b -> a carries 5/7 of the body's weight
    np.testing.assert_allclose(fw.axle_loads_n, [9.81 * (20000 * 5 / 7 + 1000), 9.81 * (20000 * 2 / 7 + 1000)],
                               rtol=1e-12)
    np.testing.assert_allclose(bw.axle_loads_n, fw.axle_loads_n[::-1], rtol=1e-12)

    def freqs(t):
        m = t.unit_matrices(0)
        return np.sort(np.sqrt(np.linalg.eigvals(np.diag(1.0 / m.M) @ m.K).real))

    np.testing.assert_allclose(freqs(bw), freqs(fw), rtol=1e-12)


# ---------------------------------------------------------------------- bad input
def _one(**over):
    veh = {"length_m": 10.0,
           "bodies": [{"name": "body", "mass_kg": 20000.0, "pitch_inertia_kgm2": 1.5e5, "x_m": 5.0}],
           "wheelsets": [{"name": "a", "mass_kg": 1000.0, "x_m": 2.0}, {"name": "b", "mass_kg": 1000.0, "x_m": 8.0}],
           "stages": [{"upper": "body", "lower": "a", "x_m": 2.0, "k_N_m": 2e6, "c_Ns_m": 2e4},
                      {"upper": "body", "lower": "b", "x_m": 8.0, "k_N_m": 2e6, "c_Ns_m": 2e4}]}
    for path, value in over.items():
        keys = path.split("__")
        d = veh
        for k in keys[:-1]:
            d = d[int(k)] if k.isdigit() else d[k]
        if value is None:
            del d[keys[-1]]
        else:
            d[keys[-1]] = value
    return {"name": "bad", "vehicles": {"V": veh}, "composition": [{"vehicle": "V"}]}


@pytest.mark.parametrize("over, match", [
    ({"bodies__0__mass_kg": -5.0}, r"vehicles\.V\.bodies\[0\]\.mass_kg: -5 kg is out of range; allowed \[1, 500000\] kg"),
    ({"stages__0__k_N_m": -1.0}, r"vehicles\.V\.stages\[0\]\.k_N_m: -1 N/m is out of range; allowed \[1, 1e\+10\] N/m"),
    ({"stages__1__c_Ns_m": -3.0}, r"stages\[1\]\.c_Ns_m: -3 N s/m is out of range"),
    ({"bodies__0__masss_kg": 1.0}, r"vehicles\.V\.bodies\[0\]: unknown key\(s\) 'masss_kg'; allowed name, mass_kg"),
    ({"lenght_m": 3.0}, r"vehicles\.V: unknown key\(s\) 'lenght_m'; allowed length_m"),
    ({"bodies__0__x_m": 12.0}, r"wheelset 'a': static wheel load -121 kN .* is not positive .* allowed > 0 kN"),
    ({"stages__1__lower": "nowhere"}, r"stages\[1\]\.lower: 'nowhere' is not a body or wheelset; allowed 'body', 'a', 'b'"),
    ({"bodies__0__mass_kg": "20 t"}, r"bodies\[0\]\.mass_kg: '20 t'"),
    ({"wheelsets__1__x_m": 2.0}, r"wheelsets 'a' and 'b' stand at the same x_m = 2 m"),
    ({"wheelsets__0__static_load_kN": 100.0}, r"static_load_kN given for some wheelsets but not for 'b'"),
    ({"stages__1__lower": "a"}, r"vehicles\.V: wheelset 'a' hangs on 2 stages; allowed exactly 1"),
    ({"wheelsets__1__x_m": 12.0}, r"wheelset 'b' x_m = 12 m lies outside the vehicle; allowed \[0, length_m = 10\] m"),
])
def test_bad_vehicle_files_one_line_naming_key_value_range(over, match):
    with pytest.raises(InputError, match=match) as exc:
        train_from_mapping(_one(**over), source="v.toml")
    assert "\n" not in str(exc.value)


def test_coinciding_axles_of_successive_vehicles_are_refused():
    data = _one(wheelsets__0__x_m=0.0, stages__0__x_m=0.0, wheelsets__1__x_m=10.0, stages__1__x_m=10.0)
    data["composition"] = [{"vehicle": "V", "count": 2}]
    with pytest.raises(InputError, match=r"v\.toml: composition: axles 1 and 2 are 0\.000 m apart \(vehicles 'V', 'V'\); "
                                         r"allowed axles strictly one after another"):
        train_from_mapping(data, source="v.toml")


def test_example_vehicle_file():
    """data/examples/my_vehicle_train.toml: a sprung mass (56.4 kN) and three wagons whose static
    loads come from statics: (36000 / 2 + 1200) x 9.81 N per wheelset."""
    p = resources.files("adm_sim").joinpath("data/examples/my_vehicle_train.toml")
    t = load_train(str(p))
    np.testing.assert_allclose(t.axle_offsets_m, [0.0, 5.5, 14.5, 19.5, 28.5, 33.5, 42.5], atol=1e-12)
    np.testing.assert_allclose(t.axle_loads_n, [5750 * 9.81] + [19200 * 9.81] * 6, rtol=1e-12)
    assert t.describe() == "test car + 3 wagons: 4 vehicles, 7 axles, 42.50 m first to last axle, 1186.5 kN total"


def test_bodies_not_connected_are_refused():
    data = _one()
    data["vehicles"]["V"]["bodies"].append({"name": "loose", "mass_kg": 100.0, "x_m": 5.0})
    with pytest.raises(InputError, match=r"v\.toml: vehicles\.V: bodies/wheelsets 'loose' are not connected to the "
                                         r"rest by stages; allowed one connected vehicle"):
        train_from_mapping(data, source="v.toml")


def test_pitch_without_pitch_stiffness_is_refused():
    data = _one()
    data["vehicles"]["V"]["bodies"].append({"name": "top", "mass_kg": 100.0, "pitch_inertia_kgm2": 10.0, "x_m": 5.0})
    data["vehicles"]["V"]["stages"].append({"upper": "top", "lower": "body", "x_m": 5.0, "k_N_m": 1e5, "c_Ns_m": 0.0})
    with pytest.raises(InputError, match=r"body 'top' has a pitch inertia but no stage that resists pitching"):
        train_from_mapping(data, source="v.toml")


def test_given_static_loads_must_match_the_weight():
    data = _one(wheelsets__0__static_load_kN=150.0, wheelsets__1__static_load_kN=150.0)
    with pytest.raises(InputError, match=r"static loads sum to 300 kN, the masses weigh 215\.8 kN \(allowed within "
                                         r"0\.5 %\)"):
        train_from_mapping(data, source="v.toml")
    data["loads_differ_from_masses"] = True
    assert train_from_mapping(data, source="v.toml").axle_loads_n.tolist() == [150e3, 150e3]


@pytest.mark.slow
def test_bad_vehicle_file_on_the_command_line_exits_2(tmp_path):
    """``adm-sim sweep --train bad.toml``: one line ``error: ...`` naming the key, exit 2, nothing written."""
    p = tmp_path / "bad_vehicle.toml"
    p.write_text(to_toml(_one(bodies__0__mass_kg=-5.0)))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "adm_sim.cli.sim_commands", "sweep", "--bridge", "B1", "--train", str(p),
                        "--model", "dim", "--speeds", "200", "--json", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "bodies[0].mass_kg: -5 kg" in lines[0], r.stderr
    assert not out.exists()
