"""The trains of the nominal bridge and of every bound run in one pool of threads
(:func:`adm_sim.design.check._run_cases`): each bound's result is, number for number, the check of that
bound's bridge run on its own, and the order the trains finish in changes nothing."""

import json

import numpy as np
import pytest

import adm_sim.design.check as chk
from adm_sim.design.check import resolve_trains, run_check
from adm_sim.model.bridge import named_bridge

#: each test runs several checks with bounds (2.0 s of CPU each): slow (docs/testing.md)
pytestmark = pytest.mark.slow


def _numbers(res):
    """Every number and text of a check's JSON but its timings (bit for bit: JSON writes floats exactly)."""
    d = res.to_dict()
    d.pop("timings_s")
    return json.dumps(d, sort_keys=True, default=lambda o: o.tolist() if isinstance(o, np.ndarray) else repr(o))


def test_bounds_equal_their_own_checks():
    """B1, HSLM-A7 and ICE-2 at V = 200 km/h, mass bounds -10 %/+15 % and a stiffness bound -10 %: every
    bound's result equals run_check of its bridge (with the options a bound is checked with: the
    maintenance named, no further bounds), bit for bit; the nominal equals the check without bounds."""
    trains = resolve_trains("HSLM-A7,ICE-2")
    res = run_check(named_bridge("B1"), 200.0, trains, mass_bounds=(-0.1, 0.15), stiffness_bounds=(-0.1, 0.0))
    assert [label.split(" (")[0] for label, _ in res.bounds] == [
        "mass lower bound -10 %", "mass upper bound +15 %", "stiffness lower bound -10 %"]
    for label, got in res.bounds:
        alone = run_check(got.bridge, 200.0, trains, track_maintenance=res.track_maintenance, alpha=res.alpha,
                          where=res.where, damping_model="modal")
        assert _numbers(got) == _numbers(alone), label
    # the bounds move the answer (the test would not see a bound computed on the nominal bridge)
    acc = [float(r.trains[0].max_acc_m_s2.max()) for _, r in res.bounds]
    assert len(set(acc)) == 3 and float(res.trains[0].max_acc_m_s2.max()) not in acc
    nominal = run_check(named_bridge("B1"), 200.0, trains)
    d, n = json.loads(_numbers(res)), json.loads(_numbers(nominal))
    assert d["trains"] == n["trains"] and d["governing"] == n["governing"]


def test_each_bridge_starts_its_longest_trains_first(monkeypatch):
    """HSLM-A7 (40 axles), ICE-2 (56), HSLM-A1 (50) at V = 200 km/h with mass bounds, on one thread (the
    order the pool starts them in): each bridge runs ICE-2, HSLM-A1, HSLM-A7, the nominal first; the
    results stay in the order of the trains given, the progress counts 1 .. 3, the same numbers as on two
    threads. (An interrupt in the first train started ends the check before the others start:
    tests/design/test_check.py::test_interrupted_check_runs_no_train_not_yet_started.)"""
    trains = resolve_trains("HSLM-A7,ICE-2,HSLM-A1")
    assert [np.size(t.axle_offsets_m) for t in trains] == [40, 56, 50]
    two = run_check(named_bridge("B1"), 200.0, trains, mass_bounds=(-0.1, 0.15))
    started, progress = [], []
    train_check = chk._train_check

    def spy(ctx, t, dz_pct, note):
        started.append((ctx.bridge.mass_per_length_kg_m, t.name))
        return train_check(ctx, t, dz_pct, note)

    monkeypatch.setattr(chk, "CHECK_THREADS", 1)
    monkeypatch.setattr(chk, "_train_check", spy)
    one = run_check(named_bridge("B1"), 200.0, trains, mass_bounds=(-0.1, 0.15),
                    progress=lambda done, total: progress.append((done, total)))
    assert [name for _, name in started] == ["ICE-2", "HSLM-A1", "HSLM-A7"] * 3
    masses = [m for m, _ in started]
    assert masses[0] == named_bridge("B1").mass_per_length_kg_m and len(set(masses)) == 3
    assert masses[:3] == masses[0:1] * 3 and masses[3:6] == masses[3:4] * 3
    assert progress == [(1, 3), (2, 3), (3, 3)]
    assert [t.name for t in one.trains] == ["HSLM-A7", "ICE-2", "HSLM-A1"]
    assert _numbers(one) == _numbers(two)
