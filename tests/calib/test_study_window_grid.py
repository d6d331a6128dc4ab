"""The study's fast paths give the paper grid's results: the ``window`` DIM grid and the two-stage
damping ladder.

* :func:`adm_calib.peaks.association_decided`: on a contiguous part of a curve it says True only
  when the association equals the whole curve's (a maximum dropped for its prominence on the
  part but kept on the whole curve, a plateau: False);
* :func:`adm_calib.speed_grids.dim_speeds_window`: a contiguous part of the paper grid holding
  the association window with 5 km/h and one speed to spare, plus the fastest paper speed;
* a calibration on the window grid equals the paper grid's bit for bit (peaks, Δζ_VBI, solver),
  also when the rest of the paper grid has to be run (forced here);
* the two-stage ladder gives the one-request ladder's bracket and root bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from adm_calib import calibrate as cal
from adm_calib import peaks as pk
from adm_calib.calibration_options import CalibrationOptions
from adm_calib.speed_grids import dim_speeds_paper, dim_speeds_window
from adm_sim.inputs.bridges import resolve_bridge
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.inputs.train_files import load_train

COARSE = StepOptions(steps_per_period=6.0, free_vibration_periods=1.0)  # small and fast; the same for both grids


def _bump_curve():
    """Speeds 100..130 km/h: a bump of 1.0 at 105 km/h (0.04 % above the samples just left of it,
    50 % above the curve's left end), a fall to 0.5 at 110 km/h, a higher peak (2.0) at 125 km/h."""
    v = np.arange(100.0, 131.0)
    a = np.interp(v, [100, 102, 103, 104, 105, 110, 125, 130], [0.5, 0.6, 0.9996, 0.9998, 1.0, 0.5, 2.0, 1.0])
    return v, a


def test_association_decided_on_parts_of_a_curve():
    ref, win = 110.0, (20.0, 10.0)  # window [90, 120] km/h: the bump is its only local maximum
    v, a = _bump_curve()
    assert pk.association_decided(v, a, ref, win)  # the whole curve decides itself
    assert pk.associate_peak(v, a, ref, win).speed_kmh == 105.0
    # the part from 103 km/h: the bump's prominence there is 0.02 % (< 0.1 %), so the part drops it
    # and would take the largest value of the window instead: not decided
    part = slice(3, None)
    assert 2 not in pk.local_maxima(a[part]) and 5 in pk.local_maxima(a)
    assert pk.associate_peak(v[part], a[part], ref, win).speed_kmh != 105.0
    assert not pk.association_decided(v[part], a[part], ref, win)
    # a kept peak of the window higher than the dropped bump: both curves take it, decided
    b = a.copy()
    b[12] = 1.5  # 112 km/h
    assert pk.association_decided(v[part], b[part], ref, win)
    assert pk.associate_peak(v[part], b[part], ref, win).speed_kmh == pk.associate_peak(v, b, ref, win).speed_kmh == 112.0
    # a plateau is never decided here
    c = b.copy()
    c[13] = c[12]
    assert not pk.association_decided(v, c, ref, win)


def test_window_grid_is_a_contiguous_part_of_the_paper_grid():
    opt = CalibrationOptions()
    v = np.arange(160.0, 351.0)
    for peak in (170.0, 263.0, 346.0):
        paper = dim_speeds_paper(v, peak, opt)
        curve, run = dim_speeds_window(paper, peak, opt)
        i0 = int(np.flatnonzero(paper == curve[0])[0])
        np.testing.assert_array_equal(curve, paper[i0:i0 + curve.size])
        lo, hi = peak - 20.0 - 5.0, peak + 10.0 + 5.0
        assert set(paper[(paper >= lo) & (paper <= hi)]) <= set(curve)
        assert curve[0] < max(lo, 160.0) + 1e-9 or curve[0] == 160.0
        assert curve[-1] > min(hi, 350.0) - 1e-9 or curve[-1] == 350.0
        assert run[-1] == paper[-1] == 350.0 and set(run) == set(curve) | {350.0}
        assert curve.size <= 34 < paper.size  # about half of the paper's 60-odd speeds


@pytest.fixture(scope="module")
def b1_paper_and_window():
    bridge, train = resolve_bridge("B1"), load_train("ICE-2")
    out = {}
    for grid in ("paper", "window"):
        out[grid] = cal.calibrate(bridge, train, options=CalibrationOptions(dim_grid=grid, step=COARSE),
                                  adapted_curve=False)
    return out


def test_window_grid_gives_the_paper_grids_calibration(b1_paper_and_window):
    p, w = b1_paper_and_window["paper"], b1_paper_and_window["window"]
    assert p.status == w.status == "ok"
    assert w.dim_speeds_kmh.size < p.dim_speeds_kmh.size / 2 + 5
    assert w.delta_zeta_vbi_pct == p.delta_zeta_vbi_pct  # bit for bit: the same lanes
    for a, b in ((w.mlm_peak, p.mlm_peak), (w.dim_peak, p.dim_peak)):
        assert (a.speed_kmh, a.acc_m_s2, a.is_local_max) == (b.speed_kmh, b.acc_m_s2, b.is_local_max)
    # every DIM value of the window curve is the paper curve's value at that speed
    on = np.isin(p.dim_speeds_kmh, w.dim_speeds_kmh)
    np.testing.assert_array_equal(p.dim_acc_m_s2[on], w.dim_acc_m_s2)
    assert (w.solve.iterations, w.solve.bracket) == (p.solve.iterations, p.solve.bracket)
    d = w.to_dict(curves=False)
    assert d["dim_grid"] == "window" and d["dim_max_at_range_end"] is None
    assert p.to_dict(curves=False)["dim_max_at_range_end"] in (True, False)


def test_window_grid_runs_the_rest_of_the_paper_grid_when_undecided(b1_paper_and_window, monkeypatch):
    monkeypatch.setattr(pk, "association_decided", lambda *a, **k: False)
    bridge, train = resolve_bridge("B1"), load_train("ICE-2")
    w = cal.calibrate(bridge, train, options=CalibrationOptions(dim_grid="window", step=COARSE), adapted_curve=False)
    p = b1_paper_and_window["paper"]
    np.testing.assert_array_equal(w.dim_speeds_kmh, p.dim_speeds_kmh)
    np.testing.assert_array_equal(w.dim_acc_m_s2, p.dim_acc_m_s2)
    assert w.delta_zeta_vbi_pct == p.delta_zeta_vbi_pct
    assert w.to_dict(curves=False)["dim_max_at_range_end"] == p.to_dict(curves=False)["dim_max_at_range_end"]


def test_two_stage_ladder_gives_the_same_bracket_and_root(b1_paper_and_window):
    p = b1_paper_and_window["paper"]
    bridge, train = resolve_bridge("B1"), load_train("ICE-2")
    calls = []
    s = cal.calibrate(bridge, train, options=CalibrationOptions(step=COARSE, ladder_first_stage=0.01),
                      adapted_curve=False, on_trial=lambda dz, peak, target: calls.append(dz))
    assert s.delta_zeta_vbi_pct == p.delta_zeta_vbi_pct
    assert (s.solve.bracket, s.solve.iterations, s.solve.function_calls) == \
        (p.solve.bracket, p.solve.iterations, p.solve.function_calls)
    assert p.delta_zeta_vbi_pct < 1.0 and max(calls[:10]) == pytest.approx(0.01)  # the first stage was enough
    # a root above the first stage: the rest of the ladder runs, the bracket is still the first sign change
    t = cal.calibrate(bridge, train, options=CalibrationOptions(step=COARSE, ladder_first_stage=0.002),
                      adapted_curve=False)
    assert t.delta_zeta_vbi_pct == p.delta_zeta_vbi_pct and t.solve.bracket == p.solve.bracket
