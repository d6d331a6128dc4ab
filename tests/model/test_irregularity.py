"""Track irregularity in the DIM (adm_sim.model.irregularity): spectra, generated profiles, defects,
files, the wheel terms of Eq. (9) in the numpy stepper and the compiled kernels, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from adm_sim.inputs.track_profile import parse_irregularity
from adm_sim.model import irregularity as irr
from adm_sim.model.bridge import Bridge
from adm_sim.integrate.compiled_batch import BatchRunner
from adm_sim.errors import InputError
from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s
from adm_sim.integrate.sweep import run_sweep
from adm_sim.inputs.train_files import load_train, train_from_mapping
from train_files import short_ice2_file


# ---------------------------------------------------------------------- coefficients (sources: docs/irregularities.md)
def test_coefficients_pinned():
    g_lo, g_hi = irr.SPECTRA["german-low"], irr.SPECTRA["german-high"]
    assert (g_lo.a_v, g_lo.omega_c, g_lo.omega_r) == (4.032e-7, 0.8246, 0.0206)
    assert (g_hi.a_v, g_hi.omega_c, g_hi.omega_r) == (1.080e-6, 0.8246, 0.0206)
    assert g_lo.band_m == g_hi.band_m == (0.5, 80.0)
    av_cm2 = {1: 1.2107, 2: 1.0181, 3: 0.6816, 4: 0.5376, 5: 0.2095, 6: 0.0339}
    for c, av in av_cm2.items():
        s = irr.SPECTRA[f"fra-{c}"]
        assert s.a_v == pytest.approx(av * 1e-4, rel=1e-15)
        assert (s.omega_c, s.k, s.band_m) == (0.8245, 0.25, (1.524, 304.8))
    # the formulas at one point, by hand: German high at Omega = 1 rad/m, FRA 6 at Omega = 0.5 rad/m
    assert g_hi.psd(1.0) == pytest.approx(1.080e-6 * 0.8246**2 / ((1 + 0.0206**2) * (1 + 0.8246**2)), rel=1e-14)
    assert irr.SPECTRA["fra-6"].psd(0.5) == pytest.approx(
        0.25 * 0.0339e-4 * 0.8245**2 / (0.25 * (0.25 + 0.8245**2)), rel=1e-14)


def test_iso8608_coefficients_pinned():
    """ISO 8608 classes A..H: G_d(n0) the geometric mean of the class limits 2^(3:2:17) 1e-6 m^3
    (VBI-2D B07_OptionsProcessing.m), i.e. 16, 64, ..., 262144 1e-6 m^3; n0 = 0.1 cycle/m, w = 2;
    band 0.01..10 cycle/m. S(Omega) = G_d(n) / (2 pi), n = Omega / (2 pi)."""
    limits = [2.0 ** e for e in range(3, 18, 2)]
    assert list(irr.ISO_LIMITS_UM3) == limits
    gd = {"a": 16, "b": 64, "c": 256, "d": 1024, "e": 4096, "f": 16384, "g": 65536, "h": 262144}
    for i, (c, g) in enumerate(gd.items()):
        s = irr.SPECTRA[f"iso-{c}"]
        assert s.a_v == pytest.approx(g * 1e-6, rel=1e-15)
        if i < 7:
            assert g == pytest.approx(np.sqrt(limits[i] * limits[i + 1]), rel=1e-15)
        assert (s.kind, s.n0_cyc_m, s.waviness, s.band_m) == ("iso", 0.1, 2.0, (0.1, 100.0))
    c = irr.SPECTRA["iso-c"]
    # at n0 the PSD is G_d(n0) per cycle/m, i.e. G_d(n0) / (2 pi) per rad/m; at 2 n0 a quarter of it
    assert c.psd(2 * np.pi * 0.1) == pytest.approx(256e-6 / (2 * np.pi), rel=1e-14)
    assert c.psd(2 * np.pi * 0.2) == pytest.approx(256e-6 / 4 / (2 * np.pi), rel=1e-14)
    # variance over the band 2..80 m, closed form G_d(n0) n0^2 (1/n1 - 1/n2) = 1.95e-4 m^2, against a
    # generated profile over one full period (2000 m: its variance is the sum of the harmonics' a^2/2)
    x = np.arange(0.0, 2000.0, 0.4)
    var = np.var(irr.harmonic_sum(c, (2.0, 80.0), 1, x, length_m=2000.0))
    assert var == pytest.approx(256e-6 * 0.01 * (80.0 - 2.0), rel=0.002)  # measured 1.6e-4


@pytest.mark.parametrize("name", ["german-high", "fra-6", "iso-c"])  # the three forms (German low: German high scaled)
def test_generated_psd_matches_target(name):
    """Welch PSD of 5 generated 2 km profiles (seeds 1..5, band 2..80 m), averaged, against
    S(Omega): each of 6 bands of equal log width between 2.5 m and 40 m wavelength within 12 %
    (measured: 7.7 % at worst, in the longest band; the longest wavelengths of the 2..80 m band
    are left out: with 410 m Welch segments the Hann window leaks the steep spectrum there, 15 %
    between 40 and 60 m)."""
    spec = irr.spectrum(name)
    dx = 0.4
    x = np.arange(0.0, 2000.0, dx)
    S = []
    for seed in range(1, 6):
        r = irr.harmonic_sum(spec, (2.0, 80.0), seed, x, length_m=2000.0)
        w, s = irr.welch_psd(r, dx, nperseg=1024)
        S.append(s)
    S = np.mean(S, axis=0)
    edges = 2.0 * np.pi / np.geomspace(40.0, 2.5, 7)
    off = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (w >= lo) & (w < hi)
        assert sel.sum() >= 2
        off.append(S[sel].mean() / spec.psd(w[sel]).mean() - 1.0)
    assert max(abs(o) for o in off) < 0.12, f"{name}: bands off by {np.round(off, 3)}"


def test_random_profile_pinned_seeded():
    a = irr.random_profile("german-high", 3, 20.0)
    b = irr.random_profile("german-high", 3, 20.0)
    c = irr.random_profile("german-high", 4, 20.0)
    assert np.array_equal(a.r_m, b.r_m) and not np.array_equal(a.r_m, c.r_m)
    assert a.r_m[0] == 0.0 and abs(a.r_m[-1]) < 1e-18  # pinned at both supports
    assert 3e-4 < a.rms_m() < 1e-2  # mm scale for a German high disturbance track


def test_defects_closed_form():
    x = np.linspace(0.0, 10.0, 1001)
    p = parse_irregularity("ramp:at=2:length=4:height=0.01", 10.0)
    r, s = p.evaluate(np.array([1.0, 4.0, 7.0]))
    # a rising ramp lifts the wheel: r is the downward displacement, r = -elevation
    np.testing.assert_allclose(r, [0.0, -0.005, -0.01], atol=1e-12)
    assert s[1] == pytest.approx(-0.01 / 4, rel=1e-9)
    rj = parse_irregularity("joint:at=5:length=2:depth=0.003", 10.0).evaluate(np.array([5.0]))[0]
    assert rj[0] == pytest.approx(0.003, rel=1e-9)  # a dip lowers it
    j = irr.joint(x, 5.0, 2.0, 0.003)
    assert j.min() == pytest.approx(-0.003, rel=1e-12) and j[0] == 0.0 and j[-1] == 0.0


def test_profile_files(tmp_path):
    x = np.linspace(0.0, 15.0, 31)
    r = 1e-3 * np.sin(2 * np.pi * x / 5.0)
    csvf = tmp_path / "p.csv"
    csvf.write_text("position_m,elevation_m\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(x, r)))
    tomlf = tmp_path / "p.toml"
    tomlf.write_text(f"position_m = {x.tolist()!r}\nelevation_m = {r.tolist()!r}\n")
    a, b = parse_irregularity(f"file={csvf}", 15.0), parse_irregularity(f"file={tomlf}", 15.0)
    np.testing.assert_array_equal(a.r_m, b.r_m)
    assert a.evaluate(np.array([-1.0, 16.0]))[0].tolist() == [0.0, 0.0]  # zero off the file
    np.testing.assert_array_equal(a.r_m, -r)  # elevations up in the file, r = -elevation


# ---------------------------------------------------------------------- bad input: one line, key, value, range
@pytest.mark.parametrize("spec, match", [
    ("fra-7:seed=1", r"spectrum = 'fra-7' .*allowed german-low, german-high, fra-1"),
    ("iso-i:seed=1", r"spectrum = 'iso-i' .*allowed .*iso-a, iso-b, .*iso-h$"),
    ("iso-c:band=0.05:80", r"band = 0.05:80 m is outside the iso-c spectrum; allowed lo < hi within \[0.1, 100\] m"),
    ("german-high:band=0.2:80", r"band = 0.2:80 m is outside the german-high spectrum; allowed lo < hi within \[0.5, 80\] m"),
    ("fra-6:band=2:400", r"band = 2:400 m .*\[1.524, 304.8\] m"),
    ("german-low:seed=-1", r"seed = '-1' .*allowed an integer >= 0"),
    ("ramp:at=0:length=2:height=0.5", r"ramp height = '0.5' .*\[-0.05, 0.05\] m"),
])
def test_bad_specs(spec, match):
    with pytest.raises(InputError, match=match):
        parse_irregularity(spec, 15.0)


def test_bad_files(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("0,0\n1,0.001\n0.5,0\n2,0\n3,0\n")
    with pytest.raises(InputError, match=r"position_m = 0.5 m at row 3 does not increase \(previous 1 m\)"):
        parse_irregularity(f"file={f}", 15.0)
    f.write_text("0,0\n1,nan\n2,0\n3,0\n")
    with pytest.raises(InputError, match=r"row 2 has position 1.0 m, elevation nan m; allowed finite numbers"):
        parse_irregularity(f"file={f}", 15.0)


@pytest.mark.parametrize("bad", ["fra-9", "iso-z"])
def test_cli_bad_input_exit_2(tmp_path, capsys, bad):
    from adm_calib.calib_commands import main

    out = tmp_path / "s"
    code = None
    try:
        code = main(["study", "--out", str(out), "--trains", "ICE-2", "--irregularity", f"{bad}:seed=1"])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith(f"error: irregularity: spectrum = '{bad}'")
    assert not out.exists()


# ---------------------------------------------------------------------- the wheel terms in both steppers
def _bridge():
    from adm_calib.study import select_cases

    return select_cases(trains=["ICE-2"], mass_functions=["mu2"], spans_m=(15, 15), freq_indices=(3,))[0].bridge


def _ds(bridge, train, v):
    # 4 steps per period of the highest mode (the core's default is 16; RK4 is stable up to h omega =
    # 2.8, here pi / 2), as in test_batch.py: the numpy stepper's cost is its number of steps, and the
    # paths compared below (bit for bit, or to 1e-12) run on this one ds, which need not be accurate
    # for them to agree. What a coarser ds gives up: the responses compared are RK4 at 4 steps per
    # period, not the converged ones (step convergence is test_core_dim.py's and test_vehicles.py's)
    return make_grid(bridge, train.length_m, speeds_to_m_s(v), StepOptions(steps_per_period=4.0)).ds_m


@pytest.mark.slow
def test_zero_profile_is_smooth_bit_for_bit(tmp_path):
    """A profile of zeros gives the smooth track's maxima bit for bit, on the numpy stepper and on the
    compiled lanes. The ICE-2 with 2 of its 12 passenger cars (both vehicle types): the profile
    enters wheel by wheel, so the equality does not depend on the number of cars."""
    b, tr = _bridge(), load_train(str(short_ice2_file(tmp_path)))
    v = np.array([230.0, 290.0])
    ds = _ds(b, tr, v)
    zero = irr.Profile(np.linspace(0.0, 15.0, 301), np.zeros(301), "zero")
    for p in (None, zero):
        st = StepOptions(ds_m=ds, irregularity=p)
        a = run_sweep(b, tr, "dim", v, options=st).max_acc_m_s2
        c = BatchRunner([b], tr, ds, irregularity=p).run("dim", np.zeros(2, int), v)[0]
        if p is None:
            a0, c0 = a, c
    np.testing.assert_array_equal(a, a0)
    np.testing.assert_array_equal(c, c0)


@pytest.mark.slow
def test_numpy_and_compiled_agree_with_profile():
    b, tr = _bridge(), load_train("Railjet")
    v = np.array([180.0, 260.0, 340.0])
    ds = _ds(b, tr, v)
    p = parse_irregularity("german-high:seed=2+joint:at=7:length=1:depth=0.002", 15.0)
    a = run_sweep(b, tr, "dim", v, options=StepOptions(ds_m=ds, irregularity=p)).max_acc_m_s2
    c = BatchRunner([b], tr, ds, irregularity=p).run("dim", np.zeros(3, int), v)[0]
    smooth = BatchRunner([b], tr, ds).run("dim", np.zeros(3, int), v)[0]
    np.testing.assert_allclose(c, a, rtol=1e-12, atol=0)
    assert np.max(np.abs(c / smooth - 1.0)) > 0.01  # the profile does change the response


def test_mlm_ignores_profile():
    b, tr = _bridge(), load_train("ICE-2")
    v = np.array([250.0])
    ds = _ds(b, tr, v)
    p = parse_irregularity("fra-6:seed=1", 15.0)
    a = BatchRunner([b], tr, ds, irregularity=p).run("mlm", np.zeros(1, int), v)[0]
    c = BatchRunner([b], tr, ds).run("mlm", np.zeros(1, int), v)[0]
    np.testing.assert_array_equal(a, c)


# ---------------------------------------------------------------------- closed form: harmonic under a sprung mass
def _bounce_vehicle():
    """One conventional vehicle whose four axles sit 0, 2.5, 20, 22.5 m behind the first: on a
    profile of wavelength 2.5 m every wheel sees the same elevation, so the vehicle only bounces
    (body on two bogies: a 2-DOF system with a closed-form steady state)."""
    vt = {"m_c_kg": 20000.0, "J_c_kgm2": 1.0e6, "m_b_kg": 2000.0, "J_b_kgm2": 1500.0, "m_w_kg": 1500.0,
          "k_s_N_m": 5.0e7, "c_s_Ns_m": 3.0e5, "k_p_N_m": 2.0e8, "c_p_Ns_m": 4.0e5,
          "d_m": 26.0, "r_m": 20.0, "b_m": 2.5}
    vt["axle_load_kN"] = (vt["m_c_kg"] + 2 * vt["m_b_kg"] + 4 * vt["m_w_kg"]) * 9.81 / 4 / 1000
    return train_from_mapping({"name": "bounce", "vehicle_types": {"V": vt}, "composition": [{"vehicle": "V"}]},
                              source="test"), vt


@pytest.mark.slow
def test_harmonic_profile_sprung_mass_steady_state():
    """Contact force of a wheel on a very stiff bridge (n0 = 40 Hz, 60 m) rolling over
    r(x) = a cos(2 pi x / 2.5 m) at 100 km/h against the closed-form steady state of the bounce
    system: body ``m_c``, two bogies ``m_b`` on ``k_s, c_s`` each, four wheels on ``k_p, c_p``;
    contact force amplitude ``-(k_p + i w c_p)(a - Z_b) + m_w w^2 a``. Agreement within 2 % in
    amplitude and 0.02 rad in phase (the bridge's own quasi-static deflection, ~1e-5 m against
    a = 1 mm, and the RK4 error are far smaller)."""
    pytest.importorskip("scipy")
    tr, vt = _bounce_vehicle()
    L = 60.0
    br = Bridge(span_m=L, EJ_Nm2=10000.0 * (2 * L * L * 40.0 / np.pi) ** 2, mass_per_length_kg_m=10000.0,
                damping_ratio=0.02, n_modes=3)
    a, lam, v_kmh = 1e-3, 2.5, 100.0
    x = np.linspace(0.0, L, 6001)
    prof = irr.Profile(x, a * np.cos(2 * np.pi * x / lam), "harmonic")
    ds = 0.02
    res = run_sweep(br, tr, "dim", [v_kmh], options=StepOptions(ds_m=ds, irregularity=prof), histories=True)
    F = res.contact_force_n[0, :, 0]  # first axle
    k = np.arange(F.size)
    xa = k * ds  # position of the first axle at step k
    sel = (xa > 35.0) & (xa < 57.5)  # every axle on the deck, transients (>0.7 s) decayed
    xs, Fs = xa[sel], F[sel] - tr.axle_loads_n[0]
    Om = 2 * np.pi / lam
    A = np.stack([np.cos(Om * xs), -np.sin(Om * xs)], axis=1)
    (re, im), *_ = np.linalg.lstsq(A, Fs, rcond=None)
    sim = re + 1j * im
    w = Om * v_kmh / 3.6
    ks, kp = vt["k_s_N_m"] + 1j * w * vt["c_s_Ns_m"], vt["k_p_N_m"] + 1j * w * vt["c_p_Ns_m"]
    M = np.array([[-w**2 * vt["m_c_kg"] + 2 * ks, -2 * ks],
                  [-ks, -w**2 * vt["m_b_kg"] + ks + 2 * kp]])
    zc, zb = np.linalg.solve(M, np.array([0.0, 2 * kp * a]))
    exact = -kp * (a - zb) + vt["m_w_kg"] * w**2 * a
    assert abs(sim) == pytest.approx(abs(exact), rel=0.02)
    assert abs(np.angle(sim / exact)) < 0.02
    assert abs(exact) > 0.05 * tr.axle_loads_n[0]  # a real dynamic force, not noise
