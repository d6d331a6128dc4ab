"""Δζ_VBI on continuous decks (paper Section 4 on :mod:`adm_sim.model.spans` decks).

Limiting cases with an independent answer:

* the MLM matched to itself gives Δζ = 0, and to itself at ζ + x gives x (the root finder's xtol);
* a deck of one span is the simply supported span: the same curves and Δζ_VBI to round-off (its
  modes come from bisection to 1e-14 and quadrature, the span's from closed forms);
* the symmetric two-span deck's first mode is the single span's (antisymmetric, each span a sine),
  so the study's deck has the first frequency of its field bridge;
* the deck's governing point is the largest of the maxima at the two midspans, each the compiled
  sweep at that point.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep_compiled
from adm_sim.model.bridge import Bridge, eurocode_damping_pct
from adm_sim.model.parametric import field_frequencies_hz, mass_function_t_m
from adm_sim.inputs.train_files import load_train

from adm_calib.calib_commands import main
from adm_calib.calibrate import calibrate, calibration_step
from adm_calib.calibration_options import CalibrationOptions
from adm_calib.lanes import CompiledLanes, Requests, SteppedLanes, response_points_m
from adm_calib.reference import DECK_NOTE, lower_bound_for
from adm_calib.study import StudySettings, case_identity, make_batches, select_cases

SPEEDS = np.arange(160.0, 351.0)


@pytest.fixture(scope="module")
def ice2():
    return load_train("ICE-2")


@pytest.fixture(scope="module")
def deck():
    """2 x 15 m, the field's fitted n0 and mu2 at 15 m (study case 2x15-f3-mu2)."""
    return select_cases(["ICE-2"], ["mu2"], (15, 15), [3], spans_layout=2)[0].bridge


def _mlm_curve(bridge, train, dz, step):
    req = Requests()
    req.add(0, SPEEDS, dz)
    return req.run(CompiledLanes([bridge], train, step), "mlm", "mlm")[0]


def test_symmetric_two_span_deck_has_the_single_span_frequency(deck):
    n0 = field_frequencies_hz(15.0)[2]
    assert deck.n0_hz == pytest.approx(n0, rel=1e-12)  # Eq. (18) with the span: the antisymmetric first mode
    # the second mode: each span clamped-pinned, (3.9266 / pi)^2 = 1.5622 n0 (Blevins, Table 8-1)
    assert deck.frequencies_hz[1] / n0 == pytest.approx((3.926602312 / math.pi) ** 2, rel=1e-8)
    phi = deck.shapes(np.array([7.5, 22.5]))[0]
    assert phi[:, 0] == pytest.approx([1.0, -1.0], abs=1e-12)  # antisymmetric, max |phi| = 1 at each midspan


def test_governing_points_are_the_midspans(deck):
    assert response_points_m(Bridge.from_frequency(15.0, 8.26, 19042.0, 0.0185)) == (None,)
    assert response_points_m(deck) == (7.5, 22.5)


def test_deck_lanes_take_the_larger_midspan_maximum(deck, ice2):
    """Every lane equals the larger of the compiled sweeps at the two midspans (same grid)."""
    step = calibration_step(deck, ice2, SPEEDS)
    got = _mlm_curve(deck, ice2, 0.0, step)
    each = [run_sweep_compiled(deck, ice2, "mlm", SPEEDS, options=StepOptions(ds_m=step.ds_m), where=x).max_acc_m_s2
            for x in (7.5, 22.5)]
    np.testing.assert_allclose(got, np.maximum(*each), rtol=1e-12)
    assert np.any(each[0] > each[1]) and np.any(each[1] > each[0])  # each midspan governs somewhere
    stepped = SteppedLanes([deck], ice2, step).run("mlm", np.zeros(5, np.int64), SPEEDS[100:105])
    np.testing.assert_allclose(stepped, got[100:105], rtol=1e-10)  # numpy stepper on the same grid


@pytest.mark.parametrize("x", [0.0, 0.003])
def test_mlm_matched_to_itself_gives_its_own_damping(deck, ice2, x):
    """Target: the deck's MLM at ζ + x. Δζ_VBI = x to the root finder's xtol (5e-7)."""
    step = calibration_step(deck, ice2, SPEEDS)
    target = _mlm_curve(deck, ice2, x, step)
    res = calibrate(deck, ice2, SPEEDS, dim_curve=(SPEEDS, target), adapted_curve=False)
    assert res.status == "ok"
    assert res.delta_zeta_vbi == pytest.approx(x, abs=CalibrationOptions().xtol)


def test_one_span_deck_calibrates_as_the_simply_supported_span(ice2):
    ss = Bridge.from_frequency(15.0, 8.26, 19042.0, 0.0185, bridge_type="cfb")
    one = Bridge.continuous((15.0,), ss.EJ_Nm2, ss.mass_per_length_kg_m, 0.0185, n_modes=3, bridge_type="cfb")
    a, b = (calibrate(x, ice2, adapted_curve=False) for x in (ss, one))
    assert a.status == b.status == "ok"
    # curves to 1e-11 (measured 4e-13): the deck's modes by bisection to 1e-14, its modal masses by quadrature
    np.testing.assert_allclose(b.mlm_acc_m_s2, a.mlm_acc_m_s2, rtol=1e-11)
    np.testing.assert_allclose(b.dim_acc_m_s2, a.dim_acc_m_s2, rtol=1e-11)
    assert b.delta_zeta_vbi == pytest.approx(a.delta_zeta_vbi, rel=1e-9)
    # a deck of one span is the span: the simply supported methods apply (its n0 to 1e-14 relative)
    assert b.delta_zeta_lb_pct == pytest.approx(a.delta_zeta_lb_pct, rel=1e-12)
    assert b.delta_zeta_adm_pct == a.delta_zeta_adm_pct


def test_deck_gets_no_simply_supported_method(deck, ice2):
    pct, note = lower_bound_for(deck, ice2)
    assert pct is None and DECK_NOTE in note and "2 spans 15/15 m" in note
    step = calibration_step(deck, ice2, SPEEDS)
    res = calibrate(deck, ice2, SPEEDS, dim_curve=(SPEEDS, _mlm_curve(deck, ice2, 0.0, step)), adapted_curve=False)
    d = res.to_dict(curves=False)
    assert d["delta_zeta_adm_pct"] is None and d["delta_zeta_eada_pct"] is None and d["delta_zeta_lb_pct"] is None
    assert "not evaluated on a continuous deck" in res.summary()


def test_study_decks_follow_the_field():
    cases = select_cases(["ICE-2", "Railjet"], ["mu2", "mu5"], (12, 13), [1, 3], spans_layout=2)
    field = {(c.span_m, c.freq_index, c.mass_function): c.bridge
             for c in select_cases(["ICE-2"], ["mu2", "mu5"], (12, 13), [1, 3])}
    assert len(cases) == 2 * 2 * 2 * 2
    for c in cases:
        b, ss = c.bridge, field[(c.span_m, c.freq_index, c.mass_function)]
        assert b.spans_m == (c.span_m, c.span_m) and b.n_modes == 6 and b.name.startswith(f"2x{c.span_m:g}-")
        assert b.n0_hz == pytest.approx(ss.n0_hz, rel=1e-12)
        assert b.span_mu_kg_m[0] == pytest.approx(1000 * mass_function_t_m(c.mass_function, c.span_m), rel=1e-15)
        assert 100 * b.damping_ratio == pytest.approx(eurocode_damping_pct(c.span_m, b.bridge_type), rel=1e-15)
        rec = case_identity(b, c.train, c.mass_function, c.freq_index)
        assert (rec["span_m"], rec["deck_length_m"], rec["spans_m"], rec["n_modes"]) == (c.span_m, 2 * c.span_m,
                                                                                        [c.span_m] * 2, 6)
    assert all(len(b) == 1 for b in make_batches(cases))  # a compiled batch holds one deck
    assert StudySettings(spans_layout=2).to_dict()["spans_layout"] == 2
    with pytest.raises(Exception, match=r"spans_layout: 7 .*\[1, 6\]"):
        select_cases(["ICE-2"], spans_layout=7)


def test_cli_refusals(call_main, tmp_path):
    r = call_main(main, "recommend", "--train", "ICE-2", "--n0", "8.26", "--mu", "19042", "--type", "cfb",
                  "--deck-spans", "15/15")
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "--deck-spans: '15/15' is a continuous deck of 2 spans" in r.stderr and "simply supported" in r.stderr
    r = call_main(main, "recommend", "--train", "ICE-2", "--n0", "8.26", "--mu", "19042", "--type", "cfb",
                  "--deck-spans", "15/15", "--extrapolate")
    assert r.returncode == 0 and "warning: --deck-spans 15/15" in r.stderr and "dz_LB = 0.3230 %" in r.stdout
    r = call_main(main, "recommend", "--train", "ICE-2", "--n0", "8.26", "--mu", "19042", "--type", "cfb",
                  "--deck-spans", "15/15", "--span", "15")
    assert r.returncode == 2 and "give one of them" in r.stderr
    r = call_main(main, "study", "--out", str(tmp_path / "s"), "--spans-layout", "7")
    assert r.returncode == 2 and "--spans-layout: 7" in r.stderr and "[1, 6]" in r.stderr
    assert not (tmp_path / "s").exists()
    r = call_main(main, "calibrate", "--bridge", "spans=15/15,n0=8.26,mu=19042,zeta_pct=1.85", "--train", "ICE-2",
                  "--measured", str(tmp_path / "m.json"))
    assert r.returncode == 2 and "--measured" in r.stderr and "continuous deck of 2 spans" in r.stderr
    # a span shorter than the train's longest axle group: refused before any run, nothing written
    r = call_main(main, "calibrate", "--bridge", "spans=15/2,n0=8.26,mu=19042,zeta_pct=1.85", "--train", "ICE-2",
                  "--json", str(tmp_path / "c.json"))
    assert r.returncode == 2 and r.stdout == "" and not (tmp_path / "c.json").exists()
    assert r.stderr.splitlines() == ["error: spans[1]: 2 m is shorter than the longest axle group of ICE-2 (bogie "
                                     "wheelbase 3 m); allowed spans >= 3 m"]
    r = call_main(main, "calibrate", "--bridge", "spans=15/15,n0=8.26,mu=19042,zeta_pct=1.85,n_modes=51", "--train",
                  "ICE-2")
    assert r.returncode == 2 and r.stderr.splitlines() == ["error: bridge spec.n_modes: 51 is out of range; allowed "
                                                           "integer in [1, 50]"]


def test_study_fit_refuses_a_deck_study(call_main, tmp_path):
    """study-fit on a study of continuous decks (the shipped 2-span field, 200 of its lines) is refused in
    one line with the reason (the paper's functions are for simply supported spans), exit 2, nothing
    written; the same records as single spans pass the rule."""
    import json
    from pathlib import Path

    src = Path(__file__).resolve().parents[2] / "results" / "continuous" / "study" / "results.jsonl"
    lines = src.read_text().splitlines()[:200]
    res = tmp_path / "results.jsonl"
    res.write_text("\n".join(lines) + "\n")
    out = tmp_path / "fit"
    r = call_main(main, "study-fit", "--results", str(res), "--out", str(out))
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith(f"error: --results: '{res}' is a study of continuous decks (200 of 200 records, 2 "
                               f"spans, e.g. 2x8-f3-mu1): the paper's lower-bound functions (Section 4.2.1) are "
                               f"fitted to simply supported spans")
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["results.jsonl"]
    from adm_calib.cli.study_fit import _refuse_deck_study

    single = [json.loads(x) for x in lines]
    for rec in single:  # the same records as simply supported spans (no spans_m, or one span) pass
        rec["spans_m"] = [rec["span_m"]] if rec["freq_index"] % 2 else None
    _refuse_deck_study(single, "--results", res)


def test_calibrate_prints_and_writes_the_deck_modes(call_main, tmp_path):
    """``adm-calib calibrate --json`` on a deck holds ``spans_m``, ``frequencies_hz`` and
    ``modal_masses_kg``, one entry per mode used, equal to the deck's exact modes (issue 37 item 1:
    with every result and in every JSON); the printed result names them on its ``modes:`` line.
    Two symmetric 15 m spans at n0 = 8.26 Hz: f1 = n0 (each span a sine, to 1e-12) and the first
    modal mass is mu L_deck / 2 (sine shapes scaled to 1: 19042 x 30 / 2 = 285630 kg, to 1e-10)."""
    spec = "spans=15/15,n0=8.26,mu=19042,zeta_pct=1.85"
    out = tmp_path / "c.json"
    r = call_main(main, "calibrate", "--bridge", spec, "--train", "ICE-2", "--speeds", "240:300:3", "--json", str(out))
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    b = Bridge.continuous((15.0, 15.0), 1.0, 19042.0, 0.0185, n_modes=3)  # EJ scales the frequencies alone
    assert d["spans_m"] == [15.0, 15.0] and len(d["frequencies_hz"]) == len(d["modal_masses_kg"]) == 3
    assert d["frequencies_hz"][0] == pytest.approx(8.26, rel=1e-12)
    ratio = np.asarray(d["frequencies_hz"]) / d["frequencies_hz"][0]
    np.testing.assert_allclose(ratio, b.frequencies_hz[:3] / b.frequencies_hz[0], rtol=1e-12)
    assert d["modal_masses_kg"][0] == pytest.approx(19042.0 * 30.0 / 2.0, rel=1e-10)
    np.testing.assert_allclose(d["modal_masses_kg"], b.modal_mass_kg[:3], rtol=1e-10)
    line = next(s for s in r.stdout.splitlines() if s.startswith("modes: "))
    assert line.startswith("modes: 8.26 Hz (285.63 t), 12.9") and line.endswith("(frequency, modal mass)")
