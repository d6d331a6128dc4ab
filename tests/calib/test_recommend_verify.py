"""A recommendation that holds (``recommend``: ``conservative`` with its reason; ``--verify``:
min(Δζ_LB, Δζ_VBI) from the engineer's own calibration; ``--speeds``/``--max-line-speed``,
``--zeta-pct``).

Held-out bridges off the study grid (spans 8.6, 18 and 35.8 m, none a study span/frequency pair):
the value ``--verify`` returns makes the MLM peak with ζ + Δζ at least the DIM peak within the
calibration's 0.1 % match rule, checked here by an MLM sweep of its own (``run_sweep``), not by the
calibration's numbers.
"""

import json

import numpy as np
import pytest

from adm_calib import peaks as pk
from adm_calib.calib_commands import main
from adm_calib.calibrate import calibration_step
from adm_calib.recommend_verify import Verdict, study_verdict
from adm_calib.recommend_warnings import StudyCase
from adm_calib.reference import recommend
from adm_sim.integrate.sweep import run_sweep
from adm_sim.inputs.train_files import load_train

MATCH_RTOL = 1e-3  # the paper's acceptance of a peak match (Section 4, Step 3)

#: (train, n0 Hz, mu kg/m, type, span m): Railjet on an 8.6 m steel span (dz_VBI < 0 <= dz_LB), ICE-2 on
#: an 18 m concrete span (dz_VBI above the bound), ICE-4 on a 35.8 m concrete span (0 < dz_LB, dz_VBI < 0)
HELD_OUT = {
    "railjet_8.6m_sc": ("Railjet", "13", "9000", "sc", "8.6"),
    "ice2_18m_cfb": ("ICE-2", "6.5", "15000", "cfb", "18"),
    "ice4_35.8m_cfb": ("ICE-4", "4.4", "25000", "cfb", "35.8"),
}


def _recommend_json(call_main, case, *extra):
    train, n0, mu, typ, span = HELD_OUT[case]
    done = call_main(main, "recommend", "--train", train, "--n0", n0, "--mu", mu, "--type", typ, "--span", span,
                     "--json", *extra)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


# the 8.6 m Railjet case calibrates a short span at small steps (2.5-3.5 s of CPU): slow (docs/testing.md)
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if c == "railjet_8.6m_sc" else c
                                  for c in HELD_OUT])
def test_verified_value_makes_the_mlm_reach_the_dim_peak(call_main, case):
    d = _recommend_json(call_main, case, "--verify")
    v = d["verification"]
    bound, vbi, verified = d["delta_zeta_lb_pct"], v["delta_zeta_vbi_pct"], v["verified_pct"]
    assert verified == min(bound, vbi) and v["bound_pct"] == bound
    assert v["calibration_status"] == "ok" and v["delta_zeta_determined"] is True
    assert d["conservative"] is (bound <= vbi) and d["conservative_source"] == "calibration"
    # an MLM of its own at zeta + verified over the same speeds, on the calibration's space step
    from adm_sim.model.bridge import Bridge

    train = load_train(d["train"])
    bridge = Bridge.from_frequency(d["span_m"], d["n0_hz"], d["mu_kg_m"], d["zeta_pct"] / 100.0)
    v_kmh = np.arange(160.0, 351.0)
    step = calibration_step(bridge, train, v_kmh)
    mlm = run_sweep(bridge, train, "mlm", v_kmh, delta_zeta=verified / 100.0, options=step).max_acc_m_s2
    peak = pk.find_peak(v_kmh, mlm)
    dim_peak = v["dim_peak"]["acc_m_s2"]
    assert peak.acc_m_s2 >= (1.0 - MATCH_RTOL) * dim_peak, (case, peak, dim_peak)
    if not d["conservative"]:
        # the bound itself would not hold: the MLM with zeta + bound peaks more than 0.1 % below the DIM
        at_bound = run_sweep(bridge, train, "mlm", v_kmh, delta_zeta=bound / 100.0, options=step).max_acc_m_s2
        assert pk.find_peak(v_kmh, at_bound).acc_m_s2 < (1.0 - MATCH_RTOL) * dim_peak


def test_negative_dz_vbi_railjet_is_named_on_the_number_line(call_main):
    """Railjet, 8.6 m steel span: the paper's bound is 0, the bridge's own Δζ_VBI is negative."""
    train, n0, mu, typ, span = HELD_OUT["railjet_8.6m_sc"]
    done = call_main(main, "recommend", "--train", train, "--n0", n0, "--mu", mu, "--type", typ, "--span", span,
                     "--verify", "--zeta-pct", "1.925")
    assert done.returncode == 0, done.stderr
    first, second = done.stdout.splitlines()[:2]
    assert first.startswith("dz_LB = 0.0000 %  conservative: false (the bridge's own dz_VBI = -0.1")
    assert second.startswith("dz_verified = -0.1") and "= min(dz_LB 0.0000 %, dz_VBI -0.1" in second
    assert "zeta = 1.925 % (user, --zeta-pct)" in done.stdout


def test_study_verdict_from_nearby_cases():
    rec = recommend("ICE-2", 6.5, 15.0, "cfb", span_m=18.0)
    near = [StudyCase("ICE-2", rec.mass_functions[0], "a", 6.4, rec.delta_zeta_pct + 0.1, ""),
            StudyCase("ICE-2", rec.mass_functions[0], "b", 6.8, rec.delta_zeta_pct + 0.01, "")]
    ok = study_verdict(rec, near)
    assert ok == Verdict(True, ok.reason, "study") and "all 2 study cases" in ok.reason
    low = [*near, StudyCase("ICE-2", rec.mass_functions[0], "c", 6.6, rec.delta_zeta_pct - 0.05, "")]
    bad = study_verdict(rec, low)
    assert not bad.conservative and bad.reason.startswith("1 of the 3 study cases") and "(c, 6.60 Hz)" in bad.reason
    far = [StudyCase("ICE-2", rec.mass_functions[0], "d", 7.2, -1.0, "")]  # 0.7 Hz away: not nearby
    assert not study_verdict(rec, far).conservative and "no study case" in study_verdict(rec, far).reason


def test_recommend_without_verify_carries_conservative_from_the_study(call_main):
    """ICE-4 on a 35.8 m concrete span at 4.4 Hz: the shipped study's nearby ICE-4 cases."""
    d = _recommend_json(call_main, "ice4_35.8m_cfb")
    assert isinstance(d["conservative"], bool) and d["conservative_source"] == "study"
    assert d["conservative_reason"] and d["verification"] is None
    assert d["zeta_source"].startswith("EN 1991-2 Table 6.6") and d["zeta_pct"] == pytest.approx(1.5)


@pytest.mark.parametrize("args, message", [
    (("--speeds", "160:350:1", "--max-line-speed", "300"), "give one design speed range, not both"),
    (("--max-line-speed", "20"), "--max-line-speed: 20"),
    (("--zeta-pct", "25"), "--zeta-pct: 25"),
    (("--zeta-pct", "-1"), "--zeta-pct: -1"),
    (("--verify", "--speeds", "161:163:1"), "--speeds: 161..163 km/h (--speeds 161:163:1) cannot show the resonance"),
])
def test_recommend_bad_design_inputs(call_main, args, message):
    train, n0, mu, typ, span = HELD_OUT["ice2_18m_cfb"]
    done = call_main(main, "recommend", "--train", train, "--n0", n0, "--mu", mu, "--type", typ, "--span", span, *args)
    assert done.returncode == 2 and done.stdout == ""
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], done.stderr


def test_check_damping_lb_uses_min_of_bound_and_own_calibration():
    """adm-calib check --damping lb: B4 (30 m steel) x Railjet, the check's own bridge (modal damping):
    the Δζ the check runs with is min(bound, Δζ_VBI) of an independent calibrate() of that bridge."""
    import dataclasses

    from adm_calib.calibrate import calibrate
    from adm_calib.check import calibrated_damping
    from adm_calib.reference import lower_bound_for
    from adm_sim.model.bridge import named_bridge

    bridge = dataclasses.replace(named_bridge("B4"), damping_model="modal")
    train = load_train("Railjet")
    pct, note = calibrated_damping(bridge, train, "lb")
    bound, _ = lower_bound_for(bridge, train)
    own = calibrate(bridge, train, adapted_curve=False)
    assert pct == min(bound, own.delta_zeta_vbi_pct)
    assert f"min(lower bound {bound:.3f} %, own dz_VBI {own.delta_zeta_vbi_pct:.3f} %, calibration status " \
           f"{own.status}) = {pct:.3f} %" in note
    assert f"bound conservative: {str(own.determined and own.delta_zeta_vbi_pct >= bound).lower()}" in note
