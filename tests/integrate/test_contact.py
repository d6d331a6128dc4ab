"""The DIM checks its own assumption: the wheel-rail contact force of every axle (Eq. 7).

Closed forms: at low speed on a smooth track every contact force is the static axle load; a wheel
entering a cosine dip of depth ``D`` and length ``L`` at speed ``v`` is pulled down by its own
inertia ``m_w v^2 r''`` with ``r'' = D/2 (2 pi / L)^2 cos(2 pi u)``, so its contact force there is
``F_static - m_w v^2 r''`` (the primary spring and damper add ``c_p v r'``, under 1 % at the
entry, and the profile's spline sampled every 1 cm differs from the cosine by < 0.5 %: tolerance 2 %).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from train_files import short_ice2_file

from adm_sim.cli.sim_commands import main
from adm_sim.errors import InputError
from adm_sim.integrate.compiled_batch import BatchRunner
from adm_sim.integrate.contact import CONTACT_LOST, CONTACT_OK
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled
from adm_sim.inputs.track_profile import parse_irregularity
from adm_sim.model import irregularity as ir
from adm_sim.model.bridge import named_bridge
from adm_sim.inputs.train_files import load_train

COARSE = StepOptions(steps_per_period=8.0)
JOINT = "joint:at=7:length=1:depth=0.002"  # a 2 mm dip over 1 m: legal (slope 0.0063, curvature 0.045 1/m)


@pytest.fixture(scope="module")
def b1_ice2():
    return named_bridge("B1"), load_train("ICE-2")


@pytest.fixture(scope="module")
def joint_dim(b1_ice2):
    """``(step, result)``: the numpy stepper's DIM run of B1 x ICE-2 at 100 and 300 km/h over the
    2 mm dip, 8 steps per period, run once for the tests that read it (they only read it)."""
    b, t = b1_ice2
    step = StepOptions(steps_per_period=8.0, irregularity=parse_irregularity(JOINT, b.span_m))
    return step, run_sweep(b, t, "dim", [100.0, 300.0], options=step)


@pytest.mark.slow  # 11195 DIM steps on the numpy stepper: 4.2 s of CPU
def test_contact_force_at_low_speed_is_the_static_axle_load(tmp_path):
    """Limiting case v -> 0: F_i = F_static,i for every axle on the bridge at every step (measured
    within 0.089 % at 20 km/h on B1, the same for the whole ICE-2 and for the short one run here;
    tolerance 0.3 %), and no lift-off (status ok). The train is ICE-2 with 2 of its 12 passenger
    cars (Loc + 2 PC + Loc, both vehicle types, 16 axles): 11195 steps instead of 39463."""
    b = named_bridge("B1")
    t = load_train(str(short_ice2_file(tmp_path)))
    assert t.n_axles == 16 and set(t.axle_loads_n) == {196e3, 112e3}
    res = run_sweep(b, t, "dim", [20.0], options=COARSE, histories=True)
    F = res.contact_force_n[0]  # (n_steps, n_axles), 0 off the bridge
    on = F != 0.0
    ratio = F[on] / np.broadcast_to(t.axle_loads_n, F.shape)[on]
    assert on.sum() > 1000 and on.any(axis=0).all()
    np.testing.assert_allclose(ratio, 1.0, rtol=0, atol=3e-3)
    assert res.status == CONTACT_OK and res.contact.first() is None
    assert res.contact.min_n[0] == pytest.approx(F[on].min(), rel=1e-12)
    assert res.to_dict()["status"] == "ok"


@pytest.mark.slow  # with joint_dim (the numpy DIM over the dip): 5.1 s of CPU
def test_compiled_contact_check_equals_the_numpy_stepper(b1_ice2, joint_dim, tmp_path):
    """The kernels' contact forces are the numpy stepper's: same first tension (step, axle),
    force and smallest force per lane to 1e-9 relative, smooth and rough. Rough: the whole ICE-2
    over the dip (the numpy run shared with the other tests); smooth, where no wheel lifts and the
    smallest force per lane is compared: the ICE-2 with 2 of its 12 passenger cars (both vehicle
    types; the force is computed axle by axle, whatever the train's length)."""
    b, t = b1_ice2
    rough, rough_res = joint_dim
    short = load_train(str(short_ice2_file(tmp_path)))
    for train, profile in ((short, None), (t, rough.irregularity)):
        opts = StepOptions(steps_per_period=8.0, irregularity=profile)
        ref = (rough_res if profile is not None else run_sweep(b, train, "dim", [100.0, 300.0], options=opts)).contact
        got = run_sweep_compiled(b, train, "dim", [100.0, 300.0], options=opts).contact
        np.testing.assert_allclose(got.min_n, ref.min_n, rtol=1e-9)
        np.testing.assert_array_equal(got.first_k, ref.first_k)
        np.testing.assert_array_equal(got.first_axle, ref.first_axle)
        np.testing.assert_allclose(got.first_n, ref.first_n, rtol=1e-9)


def test_a_legal_dip_lifts_the_leading_wheel_where_it_enters(b1_ice2):
    """At 300 km/h the 2 mm, 1 m dip pulls the leading wheel off the rail on entry (closed form:
    F = F_static - m_w v^2 r''(x) < 0 there); the first tension is at the first step whose front
    lies in the dip, axle 1, with that force within 2 %; at 100 km/h the wheel stays on."""
    b, t = b1_ice2
    prof = parse_irregularity(JOINT, b.span_m)
    res = run_sweep_compiled(b, t, "dim", [100.0, 300.0], options=StepOptions(steps_per_period=8.0, irregularity=prof))
    c = res.contact
    assert res.status == CONTACT_LOST and list(c.lost) == [False, True]
    start = 7.0 - 0.5
    k = int(c.first_k[1])
    assert k == math.ceil(start / res.ds_m) and c.first_axle[1] == 0
    x = k * res.ds_m
    v = 300.0 / 3.6
    curv = 0.001 * (2 * math.pi) ** 2 * math.cos(2 * math.pi * (x - start))
    expected = t.axle_loads_n[0] - t.wheel_mass_kg[0] * v * v * curv
    assert expected < 0
    assert c.first_n[1] == pytest.approx(expected, rel=0.02)
    fl = c.first()
    assert fl["speed_kmh"] == pytest.approx(300.0) and fl["axle"] == 1
    assert fl["time_s"] == pytest.approx(k * res.ds_m / v, rel=1e-12)
    d = res.to_dict()
    assert d["status"] == CONTACT_LOST and d["contact"]["first_loss"]["axle"] == 1
    assert c.min_n[0] > 0


def test_sweep_prints_and_writes_contact_lost(tmp_path, capsys):
    out = tmp_path / "s.json"
    assert main(["sweep", "--model", "dim", "--speeds", "100,300", "--steps-per-period", "8",
                 "--irregularity", JOINT, "--json", str(out)]) == 0
    text = capsys.readouterr().out
    line = [s for s in text.splitlines() if s.startswith("status")]
    assert len(line) == 1
    assert line[0].startswith("status contact_lost: contact lost: the wheel of axle 1 would lift off the rail at 300 km/h")
    d = json.loads(out.read_text())
    assert d["status"] == "contact_lost" and d["contact"]["first_loss"]["speed_kmh"] == pytest.approx(300.0)
    assert main(["sweep", "--model", "dim", "--speeds", "100,120", "--steps-per-period", "8"]) == 0
    assert "status ok: every wheel stays on the rail (smallest contact force" in capsys.readouterr().out


# ---------------------------------------------------------------------- the profile's bounds
def _write(tmp_path, name, x, elev):
    p = tmp_path / name
    p.write_text("position_m,elevation_m\n" + "".join(f"{a:.6f},{e:.6f}\n" for a, e in zip(x, elev)))
    return p


def test_absurd_profiles_are_refused_by_slope(tmp_path):
    """The audit's profiles, every row inside |elevation| <= 0.1 m: +-90 mm alternating every
    0.3 mm, a +-99 mm saw-tooth of 2 mm wavelength."""
    x = np.arange(0.0, 15.0, 0.0003)
    alt = _write(tmp_path, "alt.csv", x, 0.09 * np.where(np.arange(x.size) % 2 == 0, 1.0, -1.0))
    x = np.arange(0.0, 15.0, 0.0005)
    saw = _write(tmp_path, "saw.csv", x, 0.099 * (2.0 * ((x / 0.002) % 1.0) - 1.0))
    for p in (alt, saw):
        with pytest.raises(InputError, match=r"^irregularity: file=.* has slope [0-9.e+]+ \(-\) at x = .* m; "
                                             r"allowed \|slope\| <= 0.05 \(the project's"):
            parse_irregularity(f"file={p}", 15.0)


def test_a_kink_too_tight_for_a_wheel_is_refused_by_curvature():
    """A 40 mm rise over 1 m (slope 0.04, legal) has kinks: curvature beyond 1 / 0.46 m."""
    with pytest.raises(InputError, match=r"curvature [0-9.]+ 1/m at x = .*allowed \|curvature\| <= 2.17 1/m"):
        parse_irregularity("ramp:at=2:length=1:height=0.04", 15.0)
    parse_irregularity("ramp:at=2:length=4:height=0.01", 15.0)  # the same shape, gentler: within both bounds


def test_a_wave_shorter_than_two_steps_is_refused(tmp_path, b1_ice2):
    """A 0.2 mm sine of 0.1 m wavelength is within slope and curvature, but a run with ds > 50 mm
    cannot resolve it; a ramp or a single dip has no wave (no refusal at any step)."""
    b, t = b1_ice2
    x = np.arange(0.0, 15.0, 0.005)
    prof = parse_irregularity(f"file={_write(tmp_path, 'w.csv', x, 0.0002 * np.sin(2 * np.pi * x / 0.1))}", b.span_m)
    assert ir.shortest_wavelength_m(prof) == pytest.approx(0.1, rel=0.06)
    with pytest.raises(InputError, match=r"has a wave of 0.1 m .* 1.67 space steps of ds = 0.06 m; allowed >= 2 steps"):
        BatchRunner([b], t, 0.06, irregularity=prof)
    BatchRunner([b], t, 0.04, irregularity=prof)
    for spec in (JOINT, "ramp:at=0:length=3:height=0.002"):
        assert ir.shortest_wavelength_m(parse_irregularity(spec, b.span_m)) == math.inf
    with pytest.raises(InputError, match=r"allowed >= 2 steps per wave"):
        run_sweep(b, t, "dim", [300.0], options=StepOptions(steps_per_period=4.0, irregularity=prof))


# ---------------------------------------------------------------------- calibration and study
def test_a_calibration_whose_dim_peak_lost_contact_is_not_ok(b1_ice2):
    """A 4 mm dip over 1 m (legal) lifts the leading wheel at every speed from 160 km/h (closed form:
    m_w v^2 r'' = 2003 kg (44.4 m/s)^2 0.079 1/m = 312 kN > 196 kN): the DIM peak comes from such a
    run, so the calibration is ``contact_lost`` naming it; both lane backends log the same losses."""
    from adm_calib.calibrate import calibrate
    from adm_calib.calibration_options import CalibrationOptions

    b, t = b1_ice2
    prof = parse_irregularity("joint:at=7:length=1:depth=0.004", b.span_m)
    opts = CalibrationOptions(step=StepOptions(irregularity=prof))
    res = calibrate(b, t, np.arange(200.0, 321.0, 1.0), options=opts, adapted_curve=False)
    assert res.status == "contact_lost"
    pk = res.dim_peak.speed_kmh
    assert res.message.startswith(f"the DIM peak at {pk:g} km/h comes from a run in which the wheel of axle 1 would "
                                  f"lift off the rail (t = ")
    smooth = calibrate(b, t, np.arange(200.0, 321.0, 1.0), adapted_curve=False)
    assert smooth.status == "ok"


@pytest.fixture(scope="module")
def stepped_joint(b1_ice2, joint_dim):
    """``(lanes, maxima)``: adm_calib's numpy-stepper lanes run once over the 2 mm dip (B1 x ICE-2,
    100 and 300 km/h, the joint_dim step with its ds_m made explicit, as the compiled lanes need it),
    for the tests that read its maxima and its contact log (they only read them).

    SteppedLanes' own code runs (grouping, response points, the contact log); its one run_sweep call,
    ``run_sweep(b, t, "dim", [100, 300], delta_zeta=[0, 0], options=<that step>, where="midspan")``,
    is served by the run of ``joint_dim`` (checked by its arguments), not a second integration of the
    same 8296 steps. Measured once with the real run_sweep: that call's result equals joint_dim's bit for
    bit (max acceleration, max deflection, n_steps, ds_m, every field of the contact check), and the ds_m
    make_grid gives (the step this fixture used before) is joint_dim's ds_m."""
    from dataclasses import replace

    import adm_calib.lanes as lanes_mod

    b, t = b1_ice2
    step0, res = joint_dim
    step = replace(step0, ds_m=res.ds_m)
    calls = []

    def the_joint_dim_run(bridge, train, model, v, delta_zeta=0.0, options=None, where="midspan"):
        assert bridge is b and train is t and (model, where, options) == ("dim", "midspan", step)
        assert list(v) == [100.0, 300.0] and np.all(np.asarray(delta_zeta) == 0.0)
        calls.append(model)
        return res

    lanes = lanes_mod.SteppedLanes([b], t, step)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(lanes_mod, "run_sweep", the_joint_dim_run)
        maxima = lanes.run("dim", [0, 0], [100.0, 300.0])
    assert calls == ["dim"]
    return lanes, maxima


@pytest.mark.slow  # with stepped_joint, i.e. joint_dim (the numpy DIM over the dip): 5 s of CPU run alone
def test_the_lane_backends_log_the_same_contact_losses(b1_ice2, stepped_joint):
    from adm_calib.lanes import CompiledLanes, contact_loss_at

    b, t = b1_ice2
    stepped = stepped_joint[0]
    compiled = CompiledLanes([b], t, stepped.step)
    compiled.run("dim", [0, 0], [100.0, 300.0])
    logs = []
    for lanes in (compiled, stepped):
        logs.append(lanes.contact_log)
        assert contact_loss_at(lanes, 0, 100.0) is None
        assert contact_loss_at(lanes, 0, 300.0)["axle"] == 1
    assert logs[0].keys() == logs[1].keys() == {0}
    (a,), (s,) = logs[0][0].values(), logs[1][0].values()
    assert a["time_s"] == s["time_s"] and a["force_n"] == pytest.approx(s["force_n"], rel=1e-9)


def test_study_rows_carry_the_plausibility_warnings():
    """A DIM peak above 50 m/s² (the audit stored 1.285e11 m/s² with no word) is warned in its row,
    as adm-sim sweep warns it; a plausible peak gives none."""
    from types import SimpleNamespace

    from adm_calib.study.store import _KEEP, result_record
    from adm_calib.study import select_cases

    case = select_cases(["ICE-2"], ["mu3"], (15, 15), [3])[0]

    def record(dim_acc):
        d = {k: None for k in _KEEP} | {"mlm_peak": {"acc_m_s2": 4.0}, "dim_peak": {"acc_m_s2": dim_acc}}
        return result_record(case, SimpleNamespace(to_dict=lambda curves=False: d), 1.0)

    assert record(3.5)["warnings"] == []
    (w,) = record(1.285e11)["warnings"]
    assert w.startswith("DIM peak: peak acceleration: 1.285e+11 m/s² is outside the plausible range <= 50 m/s²")



@pytest.mark.slow  # reads joint_dim and stepped_joint (module fixtures: their cost counts here)
def test_a_sweep_hook_hands_its_contact_check_to_the_calibration(joint_dim, stepped_joint):
    """A co-simulated sweep (the ROS calibration node's hook) returns the run's contact check with
    its maxima; :class:`adm_calib.lanes.HookLanes` logs its losses as the in-process lanes do (the
    numpy-stepper lanes of :func:`stepped_joint`, which fold the same run into their log through
    their own code: the ContactCheck itself, where the hook hands over its JSON form)."""
    from adm_calib.lanes import HookLanes, contact_loss_at

    step, shared = joint_dim
    ref, ref_max = stepped_joint

    def hook(model, speeds, dz, step_):
        # the very call run_sweep(b, t, model, speeds, delta_zeta=dz, options=step_): the shared run's
        if not (model == "dim" and list(speeds) == [100.0, 300.0] and dz == 0.0 and step_ is step):
            raise AssertionError(f"hook called with {model}, {speeds}, {dz}")
        res = shared
        return {"max_acc_m_s2": res.max_acc_m_s2, "contact": json.loads(json.dumps(res.contact.to_dict()))}

    lanes = HookLanes(hook, step)
    np.testing.assert_array_equal(lanes.run("dim", [0, 0], [100.0, 300.0]), ref_max)
    assert contact_loss_at(lanes, 0, 100.0) is None
    assert contact_loss_at(lanes, 0, 300.0) == contact_loss_at(ref, 0, 300.0)
