"""A calibration over a speed grid that cannot show the resonance says so in its status
(``adm_calib.speed_grids.speed_grid_finding``), instead of "ok" beside a number from a quasi-static
or missed peak."""

import numpy as np
import pytest

from adm_sim.model.bridge import named_bridge
from adm_sim.integrate.sweep import sweep_exact
from adm_sim.inputs.train_files import load_train

from adm_calib.calibrate import calibrate
from adm_calib.speed_grids import GRID_RTOL, NO_RESONANCE_FRACTION, speed_grid_finding


@pytest.fixture(scope="module")
def b1_ice2():
    return named_bridge("B1"), load_train("ICE-2")


def test_default_grid_and_finer_grids_need_no_check(b1_ice2):
    """The paper's grid holds every reference speed: no finding, nothing computed."""
    b, t = b1_ice2
    assert speed_grid_finding(b, t, np.arange(160.0, 351.0)) is None
    assert speed_grid_finding(b, t, np.arange(150.0, 360.5, 0.5)) is None


def test_a_narrow_grid_around_the_resonance_is_fine(b1_ice2):
    b, t = b1_ice2
    assert speed_grid_finding(b, t, np.arange(250.0, 276.0)) is None


def test_a_50_kmh_grid_misses_the_resonance(b1_ice2):
    """B1 x ICE-2 resonates at 263 km/h (exact MLM 2.2472 m/s^2); the grid 160, 210, 260, 310 km/h
    sees 1.9994 m/s^2 at 260 km/h, 12.4 % lower: far beyond GRID_RTOL."""
    b, t = b1_ice2
    v = np.arange(160.0, 351.0, 50.0)
    status, message = speed_grid_finding(b, t, v)
    assert status == "grid_too_coarse"
    exact = sweep_exact(b, t, np.arange(160.0, 311.0))[0].max_acc_m_s2
    on_grid = sweep_exact(b, t, v)[0].max_acc_m_s2
    assert exact.max() / on_grid.max() - 1 > GRID_RTOL
    assert "263 km/h" in message and f"{100 * (exact.max() / on_grid.max() - 1):.1f} %" in message


def test_a_quasi_static_range_holds_no_resonance(b1_ice2):
    """1..10 km/h: the MLM maximum (0.025 m/s^2) is about 1 % of the resonance's 2.247 m/s^2."""
    b, t = b1_ice2
    status, message = speed_grid_finding(b, t, np.arange(1.0, 11.0))
    assert status == "no_resonance_in_range"
    low = sweep_exact(b, t, np.arange(1.0, 11.0))[0].max_acc_m_s2.max()
    high = sweep_exact(b, t, np.arange(1.0, 351.0))[0].max_acc_m_s2.max()
    assert low < NO_RESONANCE_FRACTION * high
    assert f"{100 * low / high:.1f} %" in message


def test_calibration_status_carries_the_finding(b1_ice2):
    """The calibration still reports its numbers, but its status is not "ok".

    80..100 km/h holds the third sub-resonance (88 km/h, 28.8 % of the 2.2472 m/s^2 at 263 km/h), so
    every phase of the calibration finds its peak and the finding alone sets the status. The
    quasi-static 1..10 km/h range gives the same finding (test above) but needs a step ten times
    finer (the step follows the highest speed): 41 s of CPU for this calibration instead of 0.4 s."""
    b, t = b1_ice2
    res = calibrate(b, t, speeds_kmh=np.arange(80.0, 101.0), adapted_curve=False)
    assert res.status == "no_resonance_in_range"
    assert res.to_dict(curves=False)["status"] == "no_resonance_in_range"
    ok = calibrate(b, t, speeds_kmh=np.arange(250.0, 276.0), adapted_curve=False)
    assert ok.status == "ok"
