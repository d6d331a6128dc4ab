"""HSLM-A1 .. A10 (EN 1991-2 6.4.6.1.1, Table 6.3, Fig. 6.12) as generated load trains."""

import subprocess
import sys

import numpy as np
import pytest

from adm_sim.bridge import named_bridge
from adm_sim.envelope import moving_load_envelope
from adm_sim.errors import InputError
from adm_sim.hslm import HSLM_A_TABLE, hslm_name
from adm_sim.trains import load_train

CLI = [sys.executable, "-m", "adm_sim.cli"]

#: Table 6.3 as printed (N, D m, d m, P kN) and, by hand from Fig. 6.12 as read, the distance from
#: the first to the last axle: 2 (17 + 3.525 + 1.5) + (N + 2) D = 44.05 + (N + 2) D.
EXPECTED = {
    "HSLM-A1": (18, 18.0, 2.0, 170.0, 404.05),
    "HSLM-A2": (17, 19.0, 3.5, 200.0, 405.05),
    "HSLM-A3": (16, 20.0, 2.0, 180.0, 404.05),
    "HSLM-A4": (15, 21.0, 3.0, 190.0, 401.05),
    "HSLM-A5": (14, 22.0, 2.0, 170.0, 396.05),
    "HSLM-A6": (13, 23.0, 2.0, 180.0, 389.05),
    "HSLM-A7": (13, 24.0, 2.0, 190.0, 404.05),
    "HSLM-A8": (12, 25.0, 2.5, 190.0, 394.05),
    "HSLM-A9": (11, 26.0, 2.0, 210.0, 382.05),
    "HSLM-A10": (11, 27.0, 2.0, 210.0, 395.05),
}


@pytest.mark.parametrize("name", list(EXPECTED))
def test_axles_lengths_and_positions(name):
    N, D, d, P, length = EXPECTED[name]
    assert HSLM_A_TABLE[name] == (N, D, d, P)
    t = load_train(name)
    x = t.axle_offsets_m
    assert t.n_axles == 2 * N + 14
    assert t.length_m == pytest.approx(length, abs=1e-9)
    assert x[0] == 0.0 and x[-1] == pytest.approx(length, abs=1e-9)
    np.testing.assert_allclose(x[:6], [0.0, 3.0, 14.0, 17.0, 20.525, 23.525], atol=1e-12)  # power car, end-coach bogie
    np.testing.assert_allclose(x[-6:], length - np.array([23.525, 20.525, 17.0, 14.0, 3.0, 0.0]), atol=1e-9)
    np.testing.assert_allclose(x, length - x[::-1], atol=1e-9)  # symmetric train
    jac = x[6:-6].reshape(-1, 2)  # N + 1 Jacobs bogies of wheelbase d, D apart
    assert jac.shape == (N + 1, 2)
    np.testing.assert_allclose(jac[:, 1] - jac[:, 0], d, atol=1e-12)
    np.testing.assert_allclose(np.diff(jac.mean(1)), D, atol=1e-9)
    assert jac.mean(1)[0] - 22.025 == pytest.approx(D)  # end coach: bogie centre to first Jacobs centre
    np.testing.assert_array_equal(t.axle_loads_n, 1000.0 * P)
    assert not t.units  # a load train: no vehicles


def test_names():
    assert hslm_name("hslm-a4") == "HSLM-A4" == hslm_name("HSLM A4") == hslm_name("HSLMA4")
    assert hslm_name("ICE-2") is None
    with pytest.raises(InputError, match=r"'HSLM-A11' is not an HSLM-A universal train; allowed HSLM-A1 \.\. HSLM-A10"):
        load_train("HSLM-A11")


@pytest.mark.parametrize("name", list(EXPECTED))
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


def test_sweep_cli_accepts_hslm_for_mlm_and_dim_refuses(tmp_path):
    r = subprocess.run(CLI + ["sweep", "--bridge", "B1", "--train", "HSLM-A4", "--model", "mlm", "--speeds", "250:260:5"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "HSLM-A4: 0 vehicles, 44 axles, 401.05 m" in r.stdout
    r = subprocess.run(CLI + ["sweep", "--bridge", "B1", "--train", "HSLM-A4", "--model", "dim", "--speeds", "250"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert r.stderr == ("error: model: 'dim' needs a train with vehicles; 'HSLM-A4' is a load train (MLM only)\n")
