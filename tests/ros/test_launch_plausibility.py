"""The launchers warn as the command lines do: about the bridge node's start-up values before
anything starts, and about the result they print (once per run), one ``warning: ...`` line each."""

import importlib
import sys
import warnings
from pathlib import Path

import pytest

from adm_sim.errors import PlausibilityWarning
from train_files import two_car_train_file

SCRIPTS = Path(__file__).resolve().parents[2] / "launch_scripts"


@pytest.fixture(scope="module")
def scripts():
    sys.path.insert(0, str(SCRIPTS))
    try:
        yield {name: importlib.import_module(name) for name in ("_supervisor", "crossing", "calibrate")}
    finally:
        sys.path.remove(str(SCRIPTS))


def _said(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    return [str(w.message) for w in caught if issubclass(w.category, PlausibilityWarning)]


def test_bridge_node_values_warned_before_start(scripts, tmp_path):
    params = tmp_path / "p.yaml"
    params.write_text("bridge:\n  ros__parameters:\n    bridge: B3\n    zeta_pct: 0.0185\n")
    said = _said(lambda: scripts["_supervisor"].check_inputs(params_file=str(params)))
    assert said == ["bridge node: zeta_pct: 0.0185 % is outside the plausible range >= 0.1 % (if 0.0185 is a "
                    "fraction, write zeta_pct=1.85); EN 1991-2 Table 6.6 lower limits are 0.5 .. 4 %, so a value "
                    "below 0.1 % looks like a fraction typed into the % key"]
    # a spec that carries the damping itself: its own warning once, not again for the node's parameter
    said = _said(lambda: scripts["_supervisor"].check_inputs(bridge="L=15,n0=8.26,mu=19042,zeta_pct=0.0185"))
    assert len(said) == 1 and said[0].startswith("bridge spec.zeta_pct: 0.0185 % is outside"), said


def test_train_file_warned_once_before_start(scripts, tmp_path):
    """``--train FILE.toml`` with 400 kN axles: the launcher loads it to refuse it early and again
    as the train node will; the warning comes once."""
    train = two_car_train_file(tmp_path, axle_kn=400.0)
    said = _said(lambda: scripts["_supervisor"].check_inputs(train=str(train)))
    assert len(said) == 1 and said[0].startswith("train file t.toml: largest axle load: 400 kN is outside"), said


def test_crossing_summary_warned(scripts):
    s = {"run_id": 1, "model": "dim", "span_m": 4.0, "speeds_kmh": [250.0, 300.0], "max_acc_m_s2": [12.0, 4173.5],
         "max_disp_m": [0.001, 0.07]}
    said = _said(lambda: scripts["crossing"].warn_implausible(s))
    assert [t.split(" is outside")[0] for t in said] == [
        "run 1 (DIM) at 300 km/h: peak acceleration: 4174 m/s²", "run 1 (DIM) at 300 km/h: peak deflection: 0.07 m"]
    assert "the plausible range <= 50 m/s²" in said[0] and "<= 0.04 m for L = 4 m" in said[1]
    s.update(max_acc_m_s2=[1.0, 2.6], max_disp_m=[0.001, 0.003])
    assert _said(lambda: scripts["crossing"].warn_implausible(s)) == []


def test_calibrate_summary_warned(scripts):
    s = {"bridge": "L=4,n0=11,mu=1400,zeta_pct=0.5", "train": "ICE-2",
         "mlm_peak": {"speed_kmh": 180.0, "acc_m_s2": 653.0}, "dim_peak": {"speed_kmh": 185.0, "acc_m_s2": 1926.0}}
    said = _said(lambda: scripts["calibrate"].warn_implausible(s))
    assert [t.split(" is outside")[0] for t in said] == [
        "L=4,n0=11,mu=1400,zeta_pct=0.5 x ICE-2: MLM at 180 km/h: peak acceleration: 653 m/s²",
        "L=4,n0=11,mu=1400,zeta_pct=0.5 x ICE-2: DIM at 185 km/h: peak acceleration: 1926 m/s²"]
    s["dim_peak"] = None
    s["mlm_peak"]["acc_m_s2"] = 7.09
    assert _said(lambda: scripts["calibrate"].warn_implausible(s)) == []
