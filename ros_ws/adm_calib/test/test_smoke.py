"""Smoke test of the installed adm_calib package (run by ``colcon test``): closed forms."""

import numpy as np
from adm_calib.peaks import window_max
from adm_calib.reference import adm_delta_zeta_pct


def test_eurocode_additional_damping():
    """EN 1991-2 Eq. (6.13) at L = 15 m: (0.0187 L - 0.00064 L^2) / (1 - 0.0441 L - 0.0044 L^2
    + 0.000255 L^3) = 0.1365 / 0.209125 = 0.652720 %; 0 from 30 m on."""
    assert abs(adm_delta_zeta_pct(15.0) - 0.1365 / 0.209125) < 1e-12
    assert abs(adm_delta_zeta_pct(15.0) - 0.652720) < 5e-7
    assert adm_delta_zeta_pct(30.0) == 0.0


def test_window_max_of_a_resonance_curve():
    """The largest value of a curve with its maximum at 250 km/h is found in a window around it."""
    v = np.arange(160.0, 351.0, 1.0)
    a = 1.0 / (1.0 + ((v - 250.0) / 10.0) ** 2)
    i, peak = window_max(v, a, 248.0)
    assert v[i] == 250.0 and peak == 1.0
