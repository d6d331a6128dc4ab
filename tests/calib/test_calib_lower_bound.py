"""Eq. (20) with the rules of Section 4.2.2 in one home (adm_calib.lower_bound), and its callers."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from adm_sim.errors import InputError

from adm_calib.lower_bound import first_root_hz, lower_bound_pct, zero_from_hz
from adm_calib.reference import lower_bound_table
from adm_calib.study.fit import fit_cubic


def _cubic(r1, r2, r3, k):
    """Coefficients (a, b, c, d) of k (n0 - r1)(n0 - r2)(n0 - r3), expanded by hand."""
    return (k, -k * (r1 + r2 + r3), k * (r1 * r2 + r1 * r3 + r2 * r3), -k * r1 * r2 * r3)


def test_zero_from_the_first_root_above_2_1_hz():
    # roots -1, 5 and 12 Hz, negative k: positive on (-1, 5), negative on (5, 12), positive above 12
    coef = _cubic(-1.0, 5.0, 12.0, -0.01)
    assert first_root_hz(coef) == pytest.approx(5.0, abs=1e-12)
    n0 = np.array([2.1, 3.0, 4.999, 5.0, 8.0, 13.0, 20.0])
    want = [-0.01 * (x + 1) * (x - 5) * (x - 12) if x < 5.0 else 0.0 for x in n0]
    assert lower_bound_pct(coef, n0) == pytest.approx(want, abs=1e-14)
    assert lower_bound_pct(coef, 13.0) == 0.0  # positive again above 12 Hz: still 0 (first root only)
    assert isinstance(lower_bound_pct(coef, 3.0), float)


def test_a_root_below_2_1_hz_does_not_count():
    coef = _cubic(1.0, 9.0, 30.0, 0.001)  # roots 1, 9, 30 Hz; the first above 2.1 Hz is 9
    assert first_root_hz(coef) == pytest.approx(9.0, abs=1e-12)
    assert lower_bound_pct(coef, 8.0) == pytest.approx(0.001 * 7 * -1 * -22, rel=1e-13)


def test_no_root_zero_above_the_fitted_range_only():
    coef = (0.0, 0.001, 0.0, 0.1)  # 0.1 + 0.001 n0^2 > 0 everywhere: no root
    assert first_root_hz(coef) == math.inf
    assert zero_from_hz(coef, fit_range_max_hz=21.0) == 21.0
    assert lower_bound_pct(coef, 20.9, fit_range_max_hz=21.0) == pytest.approx(0.1 + 0.001 * 20.9**2, rel=1e-14)
    assert lower_bound_pct(coef, 21.5, fit_range_max_hz=21.0) == 0.0
    assert lower_bound_pct(coef, 15.0, fit_range_max_hz=13.0) == 0.0
    assert lower_bound_pct(coef, 30.0) == pytest.approx(1.0, rel=1e-14)  # published functions: no range end


@pytest.mark.parametrize("n0", [2.0, float("nan"), [3.0, 1.5]])
def test_below_the_lower_limit_is_refused(n0):
    with pytest.raises(InputError, match=r"n0_hz: .* Hz is outside the validity of Eq. \(20\); allowed >= 2.1 Hz"):
        lower_bound_pct((0.0, 0.0, -0.1, 1.0), n0)


def test_published_functions_against_an_independent_root():
    """Every Table B1-B4 function through LowerBound (the recommend path), its vectorised form (the
    figures and the comparison) and a root bracketed by brentq on a 0.01 Hz scan (independent of
    numpy.roots)."""
    grid = np.arange(2.1, 40.0, 0.01)
    for t, tab in lower_bound_table("paper").items():
        for m, lb in tab.items():
            p = np.polyval(lb.coefficients, grid)
            k = int(np.flatnonzero(np.sign(p[1:]) != np.sign(p[:-1]))[0])
            root = brentq(lambda x: np.polyval(lb.coefficients, x), grid[k], grid[k + 1], xtol=1e-13)
            assert lb.first_root_hz == pytest.approx(root, abs=1e-9), (t, m)
            n0 = np.array([2.1, 0.5 * (2.1 + root), root - 1e-6, root + 1e-6, 25.0])
            want = np.where(n0 < root, np.polyval(lb.coefficients, n0), 0.0)
            assert lb.value_pct(n0) == pytest.approx(want, abs=1e-12), (t, m)
            assert [lb.delta_zeta_pct(x) for x in n0] == pytest.approx(list(want), abs=1e-12), (t, m)


def test_fitted_cubic_obeys_its_fit_range():
    """A fit over 2-16 Hz is 0 above 16 Hz where its cubic has no root there (no extrapolation)."""
    x = np.linspace(2.5, 15.5, 18)
    y = 0.2 + 0.01 * x  # a rising line: no root above 2.1 Hz
    f = fit_cubic(x, y, fit_range_max_hz=16.0)
    assert f.upper_limit_hz > 1e6  # the fitted cubic's rounding-level n0^3 term: no root in the field
    assert f.value_pct([10.0, 16.0 - 1e-9, 16.5]) == pytest.approx([0.3, 0.2 + 0.16, 0.0], abs=1e-9)
