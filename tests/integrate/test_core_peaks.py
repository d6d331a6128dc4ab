"""The one peak rule (adm_sim.integrate.peaks): sweep and calibration name the same peak of one curve.

Curves are built so that the answer is known by construction: a resonance bump, a ripple below
0.1 % prominence, a rising plateau (not a maximum), a flat-topped peak (its middle sample).
"""

import numpy as np
import pytest

from adm_sim.integrate import peaks as core
from adm_sim.model.bridge import named_bridge
from adm_sim.integrate.sweep import SweepResult
from adm_calib import peaks as calib

V = np.arange(160.0, 351.0, 1.0)


def bump(v, centre, width, height):
    return height / (1.0 + ((v - centre) / width) ** 2)


def sweep_result(acc):
    return SweepResult(model="mlm", bridge=named_bridge("B1"), train_name="t", speeds_kmh=V,
                       max_acc_m_s2=np.asarray(acc, float), max_disp_m=np.zeros(V.size), delta_zeta=np.zeros(()),
                       ds_m=0.01, n_steps=1)


def test_ripple_on_a_rising_tail_is_not_the_peak():
    # resonance at 230 km/h (1.9 m/s^2); the curve then rises to a flat 2.1 m/s^2 from 330 km/h
    # with a ripple of 0.05 % prominence at 340 km/h, higher than the resonance
    acc = bump(V, 230.0, 4.0, 1.0) + 0.9 + 1.2 * ((V - 300.0) / 30.0).clip(0.0, 1.0)
    acc[V == 340.0] += 0.0005 * acc[V == 340.0]
    assert acc[V == 340.0] > acc[V == 230.0]
    i = core.largest_interior_peak(acc)
    assert V[i] == 230.0
    assert sweep_result(acc).peak()["speed_kmh"] == 230.0
    p = calib.find_peak(V, acc)
    assert p.speed_kmh == 230.0 and p.acc_m_s2 == acc[V == 230.0][0]
    # with no prominence threshold the ripple (a real, if tiny, local maximum) wins
    assert V[core.largest_interior_peak(acc, 0.0)] == 340.0


def test_rising_plateau_is_not_a_maximum_and_a_flat_top_counts_at_its_middle():
    acc = np.array([1.0, 3.0, 3.0, 4.0, 2.0, 5.0, 5.0, 5.0, 1.0])
    assert core.local_maxima(acc, 0.0).tolist() == [3, 6]
    assert core.largest_interior_peak(acc) == 6
    v = np.arange(acc.size, dtype=float)
    assert calib.find_peak(v, acc).index == 6


def test_no_interior_peak_on_a_monotone_curve():
    acc = np.linspace(0.5, 2.0, V.size)
    assert core.largest_interior_peak(acc) is None and sweep_result(acc).peak() is None
    p = calib.find_peak(V, acc)
    assert not p.found and p.max_at_range_end


@pytest.mark.parametrize("seed", range(5))
def test_sweep_and_calibration_name_the_same_peak(seed):
    rng = np.random.default_rng(seed)
    acc = sum(bump(V, c, w, h) for c, w, h in zip(rng.uniform(170, 340, 4), rng.uniform(1, 8, 4),
                                                  rng.uniform(0.5, 2.0, 4)))
    acc = acc * (1.0 + 2e-4 * rng.standard_normal(V.size))  # ripples below the 0.1 % prominence
    p, s = calib.find_peak(V, acc), sweep_result(acc).peak()
    assert (p.found, s is not None) == (True, True)
    assert (s["speed_kmh"], s["acc_m_s2"]) == (p.speed_kmh, p.acc_m_s2)


def _curves():
    """Curves that exercise every branch of the peak loop: smooth resonance curves, quantised ones
    (plateaus, rising plateaus, plateaus at the ends), NaN and infinities, short and constant ones."""
    rng = np.random.default_rng(24)
    for seed in range(40):
        r = np.random.default_rng(seed)
        acc = sum(bump(V, c, w, h) for c, w, h in zip(r.uniform(170, 340, 4), r.uniform(1, 8, 4),
                                                      r.uniform(0.5, 2.0, 4)))
        yield acc * (1.0 + 2e-3 * r.standard_normal(V.size))
    for n in (1, 2, 3, 4, 5, 7, 50, 400):
        for _ in range(30):
            yield np.round(rng.uniform(0.0, 1.0, n) * rng.integers(1, 6))  # many ties
    x = np.round(rng.uniform(0.0, 4.0, 200))
    x[rng.integers(0, 200, 20)] = np.nan
    yield x
    x = rng.uniform(0.0, 1.0, 200)
    x[[5, 50, 51, 120]] = np.inf
    x[[60, 199]] = -np.inf
    yield x
    yield np.zeros(10)
    yield np.array([0.0, 1.0, 1.0, 1.0, 1.0])  # plateau up to the last sample: no peak
    yield np.array([0.0, 2.0, 2.0, 1.0, 2.0, 2.0, 0.0])


def test_peak_rule_equals_scipy_find_peaks_bit_for_bit():
    """The peak loop written here gives scipy.signal.find_peaks' indices and prominences exactly
    (scipy.signal is not imported at run time: ~1 s of every command's start)."""
    from scipy.signal import find_peaks

    n = 0
    for acc in _curves():
        idx, props = find_peaks(acc, prominence=0.0)
        mine = core._local_maxima_1d(acc)
        assert mine.tolist() == idx.tolist()
        assert np.array_equal(core._prominences(acc, mine), props["prominences"])
        for rel in (0.0, 1e-3, 0.05):
            with np.errstate(invalid="ignore"):  # 0 x inf on the curve with infinite peaks, in both
                keep = props["prominences"] >= rel * np.abs(acc[idx])
                assert core.local_maxima(acc, rel).tolist() == idx[keep].tolist()
        n += idx.size
    assert n > 1000  # the comparison saw many peaks


def test_peak_rule_refuses_a_2d_curve():
    with pytest.raises(ValueError, match="must be 1-D"):
        core.local_maxima(np.zeros((3, 4)))
