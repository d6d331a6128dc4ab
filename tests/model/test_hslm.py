"""HSLM-A1 .. A10 (EN 1991-2 6.4.6.1.1, Table 6.3, Fig. 6.12) as generated load trains."""

import subprocess
import sys

import numpy as np
import pytest

from adm_sim.model.bridge import named_bridge
from adm_sim.integrate.envelope import moving_load_envelope
from adm_sim.errors import InputError
from adm_sim.model.bridge import Bridge
from adm_sim.design.check import resolve_trains, run_check
from adm_sim.model.hslm import HSLM_A_TABLE, hslm_b_axles, hslm_b_spec, hslm_name
from adm_sim.inputs.train_files import load_train

CLI = [sys.executable, "-m", "adm_sim.cli.sim_commands"]

#: Table 6.3 as printed: (N, D m, d m, P kN).
TABLE_6_3 = {
    "HSLM-A1": (18, 18.0, 2.0, 170.0),
    "HSLM-A2": (17, 19.0, 3.5, 200.0),
    "HSLM-A3": (16, 20.0, 2.0, 180.0),
    "HSLM-A4": (15, 21.0, 3.0, 190.0),
    "HSLM-A5": (14, 22.0, 2.0, 170.0),
    "HSLM-A6": (13, 23.0, 2.0, 180.0),
    "HSLM-A7": (13, 24.0, 2.0, 190.0),
    "HSLM-A8": (12, 25.0, 2.5, 190.0),
    "HSLM-A9": (11, 26.0, 2.0, 210.0),
    "HSLM-A10": (11, 27.0, 2.0, 210.0),
}

#: Every axle position (m behind the first axle), as tabulated by independent public implementations
#: of Fig. 6.12 that agree with each other (SincBridgeDynamics.jl ``A_1 .. A_10``; Karoumi's KTH
#: ``HSLMA.m``; caldintav's UPM ``a01 .. a10.def``). Typed out here, not computed by adm-sim.
AXLES_M = {
    "HSLM-A1": [
        0, 3, 14, 17, 20.525, 22.525, 35.7625, 37.7625, 53.7625, 55.7625, 71.7625, 73.7625, 89.7625,
        91.7625, 107.7625, 109.7625, 125.7625, 127.7625, 143.7625, 145.7625, 161.7625, 163.7625, 179.7625,
        181.7625, 197.7625, 199.7625, 215.7625, 217.7625, 233.7625, 235.7625, 251.7625, 253.7625, 269.7625,
        271.7625, 287.7625, 289.7625, 305.7625, 307.7625, 323.7625, 325.7625, 341.7625, 343.7625, 359.7625,
        361.7625, 375, 377, 380.525, 383.525, 394.525, 397.525],
    "HSLM-A2": [
        0, 3, 14, 17, 20.525, 24.025, 36.0125, 39.5125, 55.0125, 58.5125, 74.0125, 77.5125, 93.0125,
        96.5125, 112.0125, 115.5125, 131.0125, 134.5125, 150.0125, 153.5125, 169.0125, 172.5125, 188.0125,
        191.5125, 207.0125, 210.5125, 226.0125, 229.5125, 245.0125, 248.5125, 264.0125, 267.5125, 283.0125,
        286.5125, 302.0125, 305.5125, 321.0125, 324.5125, 340.0125, 343.5125, 359.0125, 362.5125, 374.5,
        378, 381.525, 384.525, 395.525, 398.525],
    "HSLM-A3": [
        0, 3, 14, 17, 20.525, 22.525, 37.7625, 39.7625, 57.7625, 59.7625, 77.7625, 79.7625, 97.7625,
        99.7625, 117.7625, 119.7625, 137.7625, 139.7625, 157.7625, 159.7625, 177.7625, 179.7625, 197.7625,
        199.7625, 217.7625, 219.7625, 237.7625, 239.7625, 257.7625, 259.7625, 277.7625, 279.7625, 297.7625,
        299.7625, 317.7625, 319.7625, 337.7625, 339.7625, 357.7625, 359.7625, 375, 377, 380.525, 383.525,
        394.525, 397.525],
    "HSLM-A4": [
        0, 3, 14, 17, 20.525, 23.525, 38.2625, 41.2625, 59.2625, 62.2625, 80.2625, 83.2625, 101.2625,
        104.2625, 122.2625, 125.2625, 143.2625, 146.2625, 164.2625, 167.2625, 185.2625, 188.2625, 206.2625,
        209.2625, 227.2625, 230.2625, 248.2625, 251.2625, 269.2625, 272.2625, 290.2625, 293.2625, 311.2625,
        314.2625, 332.2625, 335.2625, 353.2625, 356.2625, 371, 374, 377.525, 380.525, 391.525, 394.525],
    "HSLM-A5": [
        0, 3, 14, 17, 20.525, 22.525, 39.7625, 41.7625, 61.7625, 63.7625, 83.7625, 85.7625, 105.7625,
        107.7625, 127.7625, 129.7625, 149.7625, 151.7625, 171.7625, 173.7625, 193.7625, 195.7625, 215.7625,
        217.7625, 237.7625, 239.7625, 259.7625, 261.7625, 281.7625, 283.7625, 303.7625, 305.7625, 325.7625,
        327.7625, 347.7625, 349.7625, 367, 369, 372.525, 375.525, 386.525, 389.525],
    "HSLM-A6": [
        0, 3, 14, 17, 20.525, 22.525, 40.7625, 42.7625, 63.7625, 65.7625, 86.7625, 88.7625, 109.7625,
        111.7625, 132.7625, 134.7625, 155.7625, 157.7625, 178.7625, 180.7625, 201.7625, 203.7625, 224.7625,
        226.7625, 247.7625, 249.7625, 270.7625, 272.7625, 293.7625, 295.7625, 316.7625, 318.7625, 339.7625,
        341.7625, 360, 362, 365.525, 368.525, 379.525, 382.525],
    "HSLM-A7": [
        0, 3, 14, 17, 20.525, 22.525, 41.7625, 43.7625, 65.7625, 67.7625, 89.7625, 91.7625, 113.7625,
        115.7625, 137.7625, 139.7625, 161.7625, 163.7625, 185.7625, 187.7625, 209.7625, 211.7625, 233.7625,
        235.7625, 257.7625, 259.7625, 281.7625, 283.7625, 305.7625, 307.7625, 329.7625, 331.7625, 353.7625,
        355.7625, 375, 377, 380.525, 383.525, 394.525, 397.525],
    "HSLM-A8": [
        0, 3, 14, 17, 20.525, 23.025, 42.5125, 45.0125, 67.5125, 70.0125, 92.5125, 95.0125, 117.5125,
        120.0125, 142.5125, 145.0125, 167.5125, 170.0125, 192.5125, 195.0125, 217.5125, 220.0125, 242.5125,
        245.0125, 267.5125, 270.0125, 292.5125, 295.0125, 317.5125, 320.0125, 342.5125, 345.0125, 364.5,
        367, 370.525, 373.525, 384.525, 387.525],
    "HSLM-A9": [
        0, 3, 14, 17, 20.525, 22.525, 43.7625, 45.7625, 69.7625, 71.7625, 95.7625, 97.7625, 121.7625,
        123.7625, 147.7625, 149.7625, 173.7625, 175.7625, 199.7625, 201.7625, 225.7625, 227.7625, 251.7625,
        253.7625, 277.7625, 279.7625, 303.7625, 305.7625, 329.7625, 331.7625, 353, 355, 358.525, 361.525,
        372.525, 375.525],
    "HSLM-A10": [
        0, 3, 14, 17, 20.525, 22.525, 44.7625, 46.7625, 71.7625, 73.7625, 98.7625, 100.7625, 125.7625,
        127.7625, 152.7625, 154.7625, 179.7625, 181.7625, 206.7625, 208.7625, 233.7625, 235.7625, 260.7625,
        262.7625, 287.7625, 289.7625, 314.7625, 316.7625, 341.7625, 343.7625, 366, 368, 371.525, 374.525,
        385.525, 388.525],
}


@pytest.mark.parametrize("name", list(TABLE_6_3))
def test_every_axle_against_the_independent_table(name):
    N, D, d, P = TABLE_6_3[name]
    assert HSLM_A_TABLE[name] == (N, D, d, P)
    t = load_train(name)
    expected = np.array(AXLES_M[name])
    assert t.n_axles == expected.size == 2 * N + 14
    np.testing.assert_allclose(t.axle_offsets_m, expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(t.axle_loads_n, 1000.0 * P)
    assert not t.units  # a load train: no vehicles


def test_lengths_within_annex_e():
    """First-to-last axle 37.525 + (N + 2) D: 375.5 .. 398.5 m, every train within Annex E's 400 m."""
    lengths = {n: load_train(n).length_m for n in TABLE_6_3}
    assert lengths["HSLM-A9"] == pytest.approx(375.525, abs=1e-9)
    assert lengths["HSLM-A2"] == pytest.approx(398.525, abs=1e-9)
    assert max(lengths.values()) <= 400.0
    for n, (N, D, _, _) in TABLE_6_3.items():
        assert lengths[n] == pytest.approx(2 * (17 + 3.525 / 2) + (N + 2) * D, abs=1e-9)


def test_names():
    assert hslm_name("hslm-a4") == "HSLM-A4" == hslm_name("HSLM A4") == hslm_name("HSLMA4")
    assert hslm_name("ICE-2") is None
    with pytest.raises(InputError, match=r"'HSLM-A11' is not an HSLM-A universal train; allowed HSLM-A1 \.\. HSLM-A10"):
        load_train("HSLM-A11")


@pytest.mark.parametrize("name", list(TABLE_6_3))
def test_resonance_speeds_on_b1(name):
    """Peaks of the exact envelope on B1 at v = n0 D / i (i = 2, 3 inside 150..420 km/h) within 1 %.

    A resonance whose free vibrations cancel (the single load's free amplitude goes as
    cos(pi n0 L / v) = cos(pi i L / D), zero at i L / D = k + 1/2, e.g. A1 with i = 3) is skipped.
    """
    bridge = named_bridge("B1")
    t = load_train(name)
    D = HSLM_A_TABLE[name][1]
    found = 0
    for i in (2, 3):
        v_pred = 3.6 * bridge.n0_hz * D / i
        if not 150.0 <= v_pred <= 420.0 or abs(np.cos(np.pi * i * bridge.span_m / D)) < 0.3:
            continue
        v = np.arange(0.96 * v_pred, 1.04 * v_pred, 0.1)
        env = moving_load_envelope(bridge, t.axle_offsets_m, t.axle_loads_n, v)
        y = env.max_acc_m_s2
        peaks = v[np.flatnonzero((y[1:-1] > y[:-2]) & (y[1:-1] >= y[2:])) + 1]
        assert peaks.size, f"{name} i={i}: no local maximum near {v_pred:.1f} km/h"
        assert np.abs(peaks / v_pred - 1).min() <= 0.01, f"{name} i={i}: peaks {peaks} vs {v_pred:.1f} km/h"
        found += 1
    assert found >= 1


@pytest.mark.slow
def test_sweep_cli_accepts_hslm_for_mlm_and_dim_refuses(tmp_path):
    r = subprocess.run(CLI + ["sweep", "--bridge", "B1", "--train", "HSLM-A4", "--model", "mlm", "--speeds", "250:260:5"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "HSLM-A4: 0 vehicles, 44 axles, 394.52 m" in r.stdout
    r = subprocess.run(CLI + ["sweep", "--bridge", "B1", "--train", "HSLM-A4", "--model", "dim", "--speeds", "250"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert r.stderr == ("error: model: 'dim' needs a train with vehicles; 'HSLM-A4' is a load train (MLM only)\n")


# ---------------------------------------------------------------------------------------- HSLM-B
# EN 1991-2 6.4.6.1.1: HSLM-B is N point forces of 170 kN at a uniform spacing d, N and d read off the
# standard's figure for spans below 7 m. No public copy or implementation of that figure was found, so
# N and d are the user's (HSLM-B:N=<n>:d=<m>) and these tests check the train, not the figure.

def test_hslm_b_layout():
    assert hslm_b_spec("HSLM-B:N=12:d=4.5") == (12, 4.5) == hslm_b_spec("hslm-b : d=4.5 : n=12")
    assert hslm_b_spec("HSLM-A4") is None and hslm_b_spec("ICE-2") is None
    offs, loads = hslm_b_axles(12, 4.5)
    assert offs.tolist() == [4.5 * k for k in range(12)] and loads.tolist() == [170e3] * 12
    (t,) = resolve_trains("HSLM-B:N=12:d=4.5")
    assert t.name == "HSLM-B:N=12:d=4.5" and not t.units and t.axle_offsets_m[-1] == 49.5


@pytest.mark.parametrize("text,msg", [
    ("HSLM-B", r"^train: 'HSLM-B' gives no N and d; give HSLM-B:N=<forces>:d=<spacing m>, N and d read off"),
    ("HSLM-B:N=10", r"^train: 'HSLM-B:N=10' needs both N and d; give HSLM-B:N=<forces>:d=<spacing m>"),
    ("HSLM-B:N=10:N=3", r"^train: 'HSLM-B:N=10:N=3': 'n=3' is not N=<forces> or d=<spacing m> \(each once\)"),
    ("HSLM-B:N=10.5:d=3", r"^train: HSLM-B N = '10.5' is not a whole number of forces in \[2, 100\]"),
    ("HSLM-B:N=1:d=3", r"^train: HSLM-B N = '1' is not a whole number of forces in \[2, 100\]"),
    ("HSLM-B:N=10:d=0.1", r"^train: HSLM-B d = 0.1 m is out of range; allowed \[0.5, 30\] m"),
    ("HSLM-B:N=10:d=x", r"^train: HSLM-B d = 'x' is not a number; allowed \[0.5, 30\] m"),
])
def test_hslm_b_bad_input(text, msg):
    with pytest.raises(InputError, match=msg):
        hslm_b_spec(text)


def test_hslm_b_span_rules():
    """EN 1991-2 6.4.6.1.1(5): HSLM-A for L >= 7 m, HSLM-B below; each refused on the other side."""
    short = Bridge.from_frequency(5.0, 20.0, 10000.0, 0.02)
    with pytest.raises(InputError, match=r"^trains: HSLM-A applies to spans >= 7 m; this bridge spans 5 m, where "
                                         r"EN 1991-2 6.4.6.1.1\(5\) asks for HSLM-B: give HSLM-B:N=<forces>:d=<spacing m>"):
        run_check(short, 300.0, resolve_trains("hslm"))
    with pytest.raises(InputError, match=r"^trains: HSLM-B:N=12:d=4.5: HSLM-B applies to simply supported spans < 7 m "
                                         r"\(EN 1991-2 6.4.6.1.1\(5\)\); this bridge spans 15 m"):
        run_check(named_bridge("B1"), 300.0, resolve_trains("HSLM-B:N=12:d=4.5"))


def test_hslm_b_resonance_at_n0_d():
    """The regular spacing d drives the resonance v = n0 d / i: a 5 m span with n0 = 20 Hz, 10 t/m,
    zeta 2 %, under 12 forces at 4.5 m peaks at n0 d = 324 km/h (found at 324.6 km/h; the check refines
    there at 0.1 km/h); the governing value is the exact envelope at that speed (1e-12)."""
    short = Bridge.from_frequency(5.0, 20.0, 10000.0, 0.02)
    res = run_check(short, 300.0, resolve_trains("HSLM-B:N=12:d=4.5"))
    t, v, a = res.governing
    assert t.kind == "hslm" and v == pytest.approx(324.0, abs=3.3)  # within 1 % of n0 d
    env = moving_load_envelope(res.bridge, *hslm_b_axles(12, 4.5), np.array([v]), where="deck")
    assert a == pytest.approx(float(env.max_acc_m_s2[0]), rel=1e-12)
    # the resonance builds up force by force: 2 forces 16.2, 6 forces between, 12 forces 47.7 m/s2
    two, six = (float(moving_load_envelope(res.bridge, *hslm_b_axles(n, 4.5), res.speeds_kmh, where="deck")
                      .max_acc_m_s2.max()) for n in (2, 6))
    assert two == pytest.approx(16.2228, rel=1e-3) and 1.3 * two < six < a / 1.3
    assert a == pytest.approx(47.7148, rel=1e-3)


@pytest.mark.slow
def test_hslm_b_cli_refusals(tmp_path):
    short = tmp_path / "short.toml"
    short.write_text('name = "short"\nL = 5.0\nn0 = 20.0\nmu = 10000.0\nzeta_pct = 2.0\n')
    js = tmp_path / "c.json"
    base = CLI + ["check", "--bridge", str(short), "--max-line-speed", "300", "--json", str(js)]
    r = subprocess.run(base, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.startswith("error: --trains: HSLM-A applies to spans >= 7 m; this bridge "
                                                     "spans 5 m") and r.stderr.count("\n") == 1 and not js.exists()
    r = subprocess.run(base + ["--trains", "HSLM-B:N=12:d=abc"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.startswith("error: --trains: HSLM-B d = 'abc' is not a number")
    assert not js.exists()
