"""check --irregularity SPEC --seeds N: the DIM of the real trains on rough profiles beside the smooth
check, beyond the standard (never in the verdict).

Reference: the numpy stepper (``run_sweep`` with ``StepOptions(irregularity=profile)``), an independent
path from the compiled lanes ``check_rough`` uses, on the same profile and speed grid: equal to 1e-9."""

import dataclasses
import json

import numpy as np
import pytest

from adm_sim.cli.sim_commands import main
from adm_sim.design import check as ck
from adm_sim.design.check_rough import BEYOND, rough_dim
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled
from adm_sim.inputs.track_profile import parse_irregularity
from adm_sim.model.bridge import named_bridge
from adm_sim.inputs.train_files import load_train
from train_files import short_ice2_file


@pytest.mark.slow  # the numpy DIM on rough profiles: 2.2 s of CPU
def test_rough_dim_equals_the_numpy_stepper_on_the_same_profiles(tmp_path):
    """The ICE-2 with 2 of its 12 passenger cars (both locomotives, both car types): the equality of
    the compiled lanes and the numpy stepper on one profile holds vehicle by vehicle and step by step,
    not through the train's length, and the short train takes about a fifth of the steps and vehicles."""
    b = dataclasses.replace(named_bridge("B3"), damping_model="modal")
    t = load_train(str(short_ice2_file(tmp_path)))
    v = np.array([230.0, 250.0, 270.0])
    r = rough_dim(b, t, v, "german-high", 2, 1.0)
    assert r.seeds == (1, 2)
    for s, a, at in zip(r.seeds, r.max_acc_m_s2, r.at_speed_kmh):
        prof = parse_irregularity(f"german-high:seed={s}", b.span_m)
        ref = run_sweep(b, t, "dim", v, options=StepOptions(irregularity=prof)).max_acc_m_s2
        assert a == pytest.approx(ref.max(), rel=1e-9) and at == v[int(np.argmax(ref))]
    # the profile changes the response (the smooth run compiled: the numpy stepper's to 3e-15 here,
    # tests/integrate: the kernels against the stepper)
    smooth = run_sweep_compiled(b, t, "dim", v).max_acc_m_s2.max()
    assert max(r.max_acc_m_s2) != pytest.approx(smooth, rel=1e-6)


def test_check_reports_rough_track_beside_the_smooth_verdict(tmp_path, call_main):
    out = tmp_path / "c.json"
    done = call_main(main, "check", "--bridge", "B3", "--max-line-speed", "250", "--trains", "HSLM-A7,Railjet",
                     "--irregularity", "fra-6", "--seeds", "2", "--json", str(out))
    assert done.returncode == 0, done.stderr
    line = next(x for x in done.stdout.splitlines() if x.startswith("rough track fra-6 (2 seeds), DIM midspan, Railjet"))
    assert BEYOND in line
    d = json.loads(out.read_text())
    (rough,) = d["rough_track"]
    assert rough["train"] == "Railjet" and rough["seeds"] == [1, 2]
    assert rough["max_over_seeds_m_s2"] == max(rough["max_midspan_acc_m_s2"])
    plain = ck.run_check(named_bridge("B3"), 250.0, ck.resolve_trains("HSLM-A7,Railjet"))
    assert d["verdict"] == ("pass" if plain.passed else "fail")
    assert d["governing"]["acc_m_s2"] == pytest.approx(plain.governing[2], rel=1e-12)


@pytest.mark.parametrize("args, message", [
    (["--trains", "HSLM-A7", "--irregularity", "german-high"], "error: --irregularity: the trains checked (HSLM-A7) have no vehicles"),
    (["--trains", "ICE-2", "--irregularity", "german-high:seed=3"], "error: --irregularity: 'german-high:seed=3' names a seed"),
    (["--trains", "ICE-2", "--irregularity", "german-high", "--seeds", "0"], "error: --seeds: 0 is out of range; allowed 1..20"),
    (["--trains", "ICE-2", "--irregularity", "bumpy"], "error: --irregularity: 'bumpy': spectrum = 'bumpy' is not allowed"),
])
def test_bad_rough_inputs(tmp_path, call_main, args, message):
    out = tmp_path / "c.json"
    done = call_main(main, "check", "--bridge", "B1", "--max-line-speed", "250", "--json", str(out), *args)
    assert done.returncode == 2 and done.stdout == "" and not out.exists()
    assert len(done.stderr.strip().splitlines()) == 1 and done.stderr.startswith(message), done.stderr
