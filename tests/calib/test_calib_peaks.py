"""Peak identification, DIM peak association and the Δζ root finder on closed-form curves.

Synthetic curve: the steady-state dynamic amplification of a damped single-degree-of-freedom
oscillator, ``A(v) = 1 / sqrt((1 - s^2)^2 + (2 zeta s)^2)`` with ``s = v / v_res``; its peak over
``s`` is ``1 / (2 zeta sqrt(1 - zeta^2))`` at ``s = sqrt(1 - 2 zeta^2)``.
"""

import numpy as np
import pytest

from adm_calib import peaks as pk
from adm_calib.calibration_options import CalibrationOptions
from adm_calib.damping_root import solve_delta_zeta


def sdof(v, v_res, zeta):
    s = np.asarray(v, float) / v_res
    return 1.0 / np.sqrt((1 - s**2) ** 2 + (2 * zeta * s) ** 2)


V = np.arange(160.0, 351.0, 1.0)


def test_peak_of_resonance_curve():
    a = sdof(V, 263.3, 0.02)
    p = pk.find_peak(V, a)
    assert p.found and p.is_local_max and not p.max_at_range_end
    assert p.speed_kmh == 263.0                                    # nearest sample to 263.3*sqrt(1-8e-4)
    assert p.acc_m_s2 == pytest.approx(a.max(), rel=0)


def test_monotone_curve_has_no_reasonable_peak():
    a = sdof(V, 400.0, 0.02)                                          # resonance above the range
    p = pk.find_peak(V, a)
    assert not p.found and p.max_at_range_end
    assert "no reasonable peak" in p.reason
    assert p.to_dict() is None


def test_largest_value_at_range_end_gives_lesser_interior_peak():
    a = sdof(V, 200.0, 0.03) + 10.0 * sdof(V, 380.0, 0.02)            # rising towards 350 km/h
    assert np.argmax(a) == V.size - 1
    p = pk.find_peak(V, a)
    assert p.found and p.max_at_range_end
    assert abs(p.speed_kmh - 200.0) <= 1.0


def test_plateau_counts_once_and_ripple_is_not_a_peak():
    a = np.array([1.0, 2.0, 3.0, 3.0, 3.0, 2.0, 1.0])
    assert list(pk.local_maxima(a)) == [3]
    ripple = np.ones(50)
    ripple[20] += 1e-5                                               # below 0.1 % prominence
    assert pk.local_maxima(ripple).size == 0
    assert pk.local_maxima(ripple, min_prominence_rel=0.0).size == 1


def test_association_picks_shifted_dim_peak():
    mlm = sdof(V, 263.0, 0.0185)
    dim = 0.8 * sdof(V, 256.0, 0.0185)                               # VBI: lower, 7 km/h slower
    pm = pk.find_peak(V, mlm)
    pd = pk.associate_peak(V, dim, pm.speed_kmh)
    assert pd.found and pd.is_local_max
    assert pd.speed_kmh == pk.find_peak(V, dim).speed_kmh
    assert pd.acc_m_s2 == pytest.approx(dim.max(), rel=0)


def test_association_ignores_peaks_outside_window_and_flags_non_maxima():
    # DIM peak 40 km/h below the MLM peak, and only a slope inside the window
    dim = sdof(V, 220.0, 0.02)
    pd = pk.associate_peak(V, dim, 300.0)
    assert pd.found and not pd.is_local_max
    win = (V >= 280) & (V <= 310)
    assert pd.acc_m_s2 == pytest.approx(dim[win].max(), rel=0)
    assert pd.speed_kmh == 280.0
    # two DIM peaks in the window: the higher one wins
    two = sdof(V, 285.0, 0.02) + 1.5 * sdof(V, 305.0, 0.02)
    assert abs(pk.associate_peak(V, two, 300.0).speed_kmh - 305.0) <= 1.0
    # no samples in the window
    assert not pk.associate_peak(V[:10], dim[:10], 300.0).found


def test_bad_curves_are_rejected():
    with pytest.raises(ValueError, match="strictly increasing"):
        pk.find_peak([1.0, 1.0, 2.0], [1.0, 2.0, 1.0])
    with pytest.raises(ValueError, match="equal length"):
        pk.find_peak([1.0, 2.0, 3.0], [1.0, 2.0])


# ---------------------------------------------------------------------- root finder on closed form

def mlm_eval(v_res, zeta):
    def f(speeds, dz):
        return sdof(speeds, v_res, zeta + np.asarray(dz))
    return f


@pytest.mark.parametrize("x", [0.0063, 0.0005, -0.004, 0.031])
def test_default_tolerance_gives_the_printed_digits(x):
    """The default root tolerance (5e-7, half a unit of the fourth decimal of Δζ in percent): the root
    lies within 0.00005 % of the closed form's, so it prints as the exact value does."""
    zeta, v_res = 0.0185, 263.4
    target = pk.find_peak(V, sdof(V, v_res, zeta + x))
    p = pk.find_peak(V, sdof(V, v_res, zeta))
    w = V[np.abs(V - p.speed_kmh) <= 5]
    s = solve_delta_zeta(mlm_eval(v_res, zeta), p.speed_kmh, w, target.acc_m_s2, zeta)
    assert s.status == "ok" and CalibrationOptions().xtol == 5e-7
    assert abs(s.delta_zeta - x) < 5e-7
    assert f"{100 * s.delta_zeta:.4f}" == f"{100 * x:.4f}"


@pytest.mark.parametrize("x", [0.0063, 0.0005, -0.004, 0.031])
def test_solver_recovers_closed_form_damping(x):
    zeta, v_res = 0.0185, 263.4
    target = pk.find_peak(V, sdof(V, v_res, zeta + x))
    p = pk.find_peak(V, sdof(V, v_res, zeta))
    w = V[np.abs(V - p.speed_kmh) <= 5]
    # the solver to 1e-8 (the study's tolerance; a calibration's default stops at 5e-7, its printed digits)
    s = solve_delta_zeta(mlm_eval(v_res, zeta), p.speed_kmh, w, target.acc_m_s2, zeta,
                         options=CalibrationOptions(xtol=1e-8))
    assert s.status == "ok"
    assert s.delta_zeta == pytest.approx(x, abs=1e-7)                  # xtol 1e-8, 0.00001 %
    assert abs(s.residual_rel) <= 1e-3
    assert s.iterations >= 1
    assert s.adapted_peak.acc_m_s2 == pytest.approx(target.acc_m_s2, rel=1e-6)


def test_solver_reports_unreachable_target():
    zeta, v_res = 0.0185, 263.4
    p = pk.find_peak(V, sdof(V, v_res, zeta))
    w = V[np.abs(V - p.speed_kmh) <= 5]
    high = solve_delta_zeta(mlm_eval(v_res, zeta), p.speed_kmh, w, 1e4, zeta)
    assert high.status == "not_bracketed" and high.delta_zeta is None
    assert "stays below the DIM peak" in high.message
    low = solve_delta_zeta(mlm_eval(v_res, zeta), p.speed_kmh, w, 1e-3, zeta)
    assert low.status == "not_bracketed" and "stays above" in low.message


def test_options_are_validated():
    from adm_sim.errors import InputError

    with pytest.raises(InputError, match="dim_grid: 'coarse' is not allowed"):
        CalibrationOptions(dim_grid="coarse")
    with pytest.raises(InputError, match=r"xtol: 0.1 - \(fraction\) is out of range"):
        CalibrationOptions(xtol=0.1)
