"""``--measured PASSAGES.json`` (src/adm_sim/inputs/measured.py): the monitored bridge's n0 and ζ
from the monitor's JSON, on ``adm-sim check``, ``adm-calib calibrate`` and ``adm-calib recommend``.

The reader's rules on hand-made files (median, lower quartile, Eq. (18), every refusal); then the
way back end to end: a simulated bridge whose true n0 is 4 % above the design value (B1) and whose
ζ is 2.4 % (design 1.85 %), five noisy passages (a z-up sensor: gravity, noise) through
``monitor.py --csv``, then the check of B1 ``--measured`` against the check of the true bridge:
the governing acceleration within 2 % (measured: see the test).
"""

from __future__ import annotations

import contextlib
import importlib
import io
import json
import math
import signal

import numpy as np
import pytest

from ros_fixtures import ROOT

from adm_sim.errors import InputError
from adm_sim.inputs.measured import MIN_PASSAGES, apply_measured, read_measured
from adm_sim.model.bridge import named_bridge


def passage(f1, zeta_pct, **kw):
    return {"index": 1, "identified": True, "f1_hz": f1, "zeta1_pct": zeta_pct, "peak_acc_m_s2": 1.0,
            "level": "within", "phase": None, "bridge": None, **kw}


def write(tmp_path, passages, name="p.json"):
    p = tmp_path / name
    p.write_text(json.dumps({"passages": passages, "topic": "/sensor/accel", "source": "x"}))
    return p


def test_median_quartile_and_eq18(tmp_path):
    """n0 = median f1, ζ = the 25 % quantile (linear) of ζ1, EJ = μ (2 L² n0 / π)² (Eq. 18);
    unidentified passages and runs with an added Δζ left out and counted."""
    f1 = [8.60, 8.58, 8.61, 8.59, 8.62]
    z = [2.50, 2.30, 2.45, 2.40, 2.35]
    ps = [passage(f, zz) for f, zz in zip(f1, z)]
    ps += [passage(9.9, 5.0, phase="bracketing"), {**passage(None, None), "identified": False, "reason": "x"}]
    path = write(tmp_path, ps)
    m = read_measured(str(path))
    assert m.f1_hz == 8.60 and m.n_used == 5 and m.n_passages == 7 and m.n_excluded_dz == 1
    assert m.zeta1_pct == pytest.approx(2.35, rel=1e-12)  # sorted 2.30 2.35 2.40 ...: q25 at index 1
    assert m.zeta1_pct <= m.zeta1_median_pct == 2.40
    assert m.f1_spread == pytest.approx(0.04 / 8.60) and m.zeta1_spread == pytest.approx(0.20 / 2.40)
    design = named_bridge("B1")
    b, _ = apply_measured(str(path), design)
    assert b.n0_hz == pytest.approx(8.60, rel=1e-12)
    assert b.EJ_Nm2 == pytest.approx(design.mass_per_length_kg_m * (2 * 15.0 ** 2 * 8.60 / math.pi) ** 2, rel=1e-12)
    assert b.damping_ratio == pytest.approx(0.0235, rel=1e-12)
    assert (b.span_m, b.mass_per_length_kg_m, b.n_modes) == (design.span_m, design.mass_per_length_kg_m, design.n_modes)
    text = "\n".join(m.lines(design, b))
    assert "5 identified passages of 7 (1 runs with an added dz left out)" in text
    assert "n0   = 8.6000 Hz, median of f1" in text and "given 8.2621 Hz" in text
    assert "25 % quantile of zeta1 (project's choice" in text and "Eq. (18)" in text


def test_quartile_never_above_the_median(tmp_path):
    """Three passages, two equal low values: q25 = median = the low value (never above it)."""
    m = read_measured(str(write(tmp_path, [passage(8.6, 1.0), passage(8.6, 1.0), passage(8.6, 1.5)])))
    assert m.zeta1_pct == 1.0 == m.zeta1_median_pct


@pytest.mark.parametrize("doc, words", [
    ("{not json", "is not JSON (Expecting property name"),
    ('{"runs": []}', "is not the monitor's JSON: no 'passages' list"),
    ('[1, 2]', "is not the monitor's JSON: no 'passages' list"),
    ('{"passages": [{"f1_hz": 8.0}]}', "is not the monitor's JSON: passage 1 has no 'identified', 'zeta1_pct', 'peak_acc_m_s2', 'level'"),
])
def test_not_the_monitors_json(doc, words, tmp_path):
    p = tmp_path / "p.json"
    p.write_text(doc)
    with pytest.raises(InputError, match=r"--measured: '.*p\.json' " + words.replace("(", r"\(").replace(")", r"\)")):
        read_measured(str(p))


@pytest.mark.parametrize("passages, words", [
    ([passage(8.6, 2.0), passage(8.6, 2.1)], f"has 2 identified passage(s) of 2; at least {MIN_PASSAGES} are needed"),
    ([passage(8.6, 2.0)] * 2 + [passage(8.6, 2.0, phase="root_search")] * 2,
     "has 2 identified passage(s) of 4 (2 with an added dz left out)"),
    ([passage(8.6, 2.0, bridge="B1"), passage(8.6, 2.0, bridge="B3"), passage(8.6, 2.0, bridge="B1")],
     "mixes the passages of bridges B1, B3"),
    ([passage(8.0, 2.0), passage(8.6, 2.0), passage(8.3, 2.0)], "the identified f1 spread by 7.23 % ((max - min) / "
                                                                  "median, 8 .. 8.6); allowed at most 5 %"),
    ([passage(8.6, 1.0), passage(8.6, 3.5), passage(8.6, 2.0)], "the identified zeta1 spread by 125 %"),
])
def test_refused(passages, words, tmp_path):
    path = write(tmp_path, passages)
    with pytest.raises(InputError) as exc:
        read_measured(str(path))
    assert str(exc.value).startswith(f"--measured: {str(path)!r}") and words in str(exc.value), str(exc.value)


# ---------------------------------------------------------------------- end to end
TRUE_N0 = 1.04 * named_bridge("B1").n0_hz
TRUE_ZETA_PCT = 2.4
SPEEDS_KMH = (266.0, 272.0, 278.0, 288.0, 295.0)  # about the third sub-resonance, 272 km/h


def true_bridge():
    from adm_sim.model.bridge import Bridge

    b1 = named_bridge("B1")
    return Bridge.from_frequency(b1.span_m, TRUE_N0, b1.mass_per_length_kg_m, TRUE_ZETA_PCT / 100, name="true")


@pytest.fixture(scope="module")
def passages_json(tmp_path_factory):
    """Five passages of ICE-2 over the true bridge (MLM, 30 periods of free vibration), as a z-up
    sensor at 500 Hz would log them (gravity, white noise 5 mm/s^2, 20 s of quiet after each, then
    the logger pauses 20 s: no sample), through ``monitor.py --csv ... --json`` (its ``main``)."""
    from adm_sim.integrate.step_grid import StepOptions
    from adm_sim.integrate.sweep import run_sweep
    from adm_sim.inputs.train_files import load_train

    out = tmp_path_factory.mktemp("measured")
    r = run_sweep(true_bridge(), load_train("ICE-2"), "mlm", list(SPEEDS_KMH),
                  options=StepOptions(free_vibration_periods=30), histories=True)
    fs, t_all, a_all, t0 = 500.0, [], [], 0.0
    rng = np.random.default_rng(3)
    for k in range(len(SPEEDS_KMH)):
        th, ah = np.asarray(r.time_s[k]), np.asarray(r.midspan_acc_m_s2[k])
        t = np.arange(0.0, th[-1] + 20.0, 1 / fs)
        a = np.interp(t, th, ah, right=0.0)
        quiet = np.arange(-20.0, 0.0, 1 / fs) if k == 0 else np.zeros(0)
        t = np.concatenate([quiet, t]) + t0 + 20.0
        a = np.concatenate([np.zeros(quiet.size), a])
        t_all.append(t)
        a_all.append(a)
        t0 = t[-1] + 1 / fs
    t, a = np.concatenate(t_all), np.concatenate(a_all)
    a = 9.80665 + a + 0.005 * rng.standard_normal(t.size)
    csv = out / "logger.csv"
    csv.write_text("t,a\n" + "\n".join(f"{ti:.4f},{ai:.6f}" for ti, ai in zip(t.tolist(), a.tolist())) + "\n")
    js = out / "passages.json"
    # monitor.py's main in this process, as ``python launch_scripts/monitor.py`` calls it: the passages
    # and their identification are under test here, not the process (its start-up and imports were
    # ~0.8 s of the ~1.8 s of CPU of the identification's process); its SIGINT and SIGTERM handlers
    # are put back after it (this fixture is built before tests/conftest.py's signal_handlers, which
    # does that for a test)
    out, err = io.StringIO(), io.StringIO()
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            mp.syspath_prepend(str(ROOT / "launch_scripts"))
            mp.chdir(ROOT)
            code = importlib.import_module("monitor").main(["--csv", str(csv), "--json", str(js)])
    finally:
        for s, h in handlers.items():
            signal.signal(s, h)
    assert code == 0, err.getvalue()
    return js


@pytest.mark.slow
def test_monitored_bridge_to_its_check(passages_json, call_main, tmp_path):
    """The check of B1 --measured: its governing acceleration within 2 % of the check of the true
    bridge (the design B1 differs by far more), the measured values said in the text and the JSON."""
    from adm_sim.cli.sim_commands import main

    doc = json.loads(passages_json.read_text())
    assert [p["identified"] for p in doc["passages"]] == [True] * 5, [p["reason"] for p in doc["passages"]]
    common = ["--max-line-speed", "200", "--trains", "ICE-2", "--speed-step", "1"]
    gov = {}
    for name, bridge in (("true", f"L=15,n0={TRUE_N0!r},mu=19042,zeta_pct={TRUE_ZETA_PCT}"),
                         ("measured", "B1"), ("design", "B1")):
        extra = ["--measured", str(passages_json)] if name == "measured" else []
        js = tmp_path / f"{name}.json"
        res = call_main(main, "check", "--bridge", bridge, *extra, *common, "--json", str(js))
        assert res.returncode == 0, res.stderr
        d = json.loads(js.read_text())
        gov[name] = d["governing"]["acc_m_s2"]
        if name == "measured":
            m = d["measured"]
            assert m["n_passages_used"] == 5 and m["n0_hz"] == pytest.approx(TRUE_N0, rel=0.005)
            assert m["zeta_pct"] == pytest.approx(TRUE_ZETA_PCT, rel=0.05) and m["zeta_pct"] <= m["zeta1_median_pct"]
            assert "measured bridge from" in res.stdout and "median of f1" in res.stdout
    assert gov["measured"] == pytest.approx(gov["true"], rel=0.02)
    assert abs(gov["design"] / gov["true"] - 1) > 0.05  # the measurement matters


# ---------------------------------------------------------------------- the other commands' hooks
def test_recommend_takes_n0_from_the_passages(tmp_path, call_main):
    """``adm-calib recommend --measured``: the answer of ``--n0 <median f1>``, and the measured values said."""
    from adm_calib.calib_commands import main

    path = write(tmp_path, [passage(f, 2.0) for f in (6.48, 6.50, 6.53)])
    common = ["recommend", "--train", "ICE-2", "--type", "cfb", "--mu", "15000", "--json"]
    by_file = call_main(main, *common, "--measured", str(path))
    by_value = call_main(main, *common, "--n0", "6.5")
    assert by_file.returncode == by_value.returncode == 0, by_file.stderr
    a, b = json.loads(by_file.stdout), json.loads(by_value.stdout)
    assert a["delta_zeta_lb_pct"] == b["delta_zeta_lb_pct"] and a["measured"]["n0_hz"] == 6.5
    assert a["measured"]["n_passages_used"] == 3 and "measured" not in b


@pytest.mark.parametrize("args, words", [
    (["--n0", "6.5", "--measured", "M"], "--n0: '6.5' given with --measured"),
    ([], "--n0: not given; give the first natural frequency (Hz) or --measured PASSAGES.json"),
    (["--measured", "missing.json"], "--measured: 'missing.json' is not a file"),
])
def test_recommend_bad_measured(args, words, tmp_path, call_main):
    from adm_calib.calib_commands import main

    path = write(tmp_path, [passage(6.5, 2.0)] * 3)
    args = [str(path) if a == "M" else a for a in args]
    res = call_main(main, "recommend", "--train", "ICE-2", "--type", "cfb", "--mu", "15000", *args)
    assert res.returncode == 2 and res.stderr.startswith("error: ") and words in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("command", [["calibrate", "--train", "ICE-2"], ["check", "--max-line-speed", "200"]])
def test_calibrate_and_check_refuse_a_bad_file_before_any_work(command, tmp_path, call_main):
    """Two identified passages: one line, exit 2, no --json written (adm-calib calibrate and check)."""
    from adm_calib.calib_commands import main

    path = write(tmp_path, [passage(8.6, 2.0)] * 2)
    out = tmp_path / "out.json"
    res = call_main(main, *command, "--bridge", "B1", "--measured", str(path), "--json", str(out))
    assert res.returncode == 2, res.stderr
    assert res.stderr.strip().splitlines() == [f"error: --measured: {str(path)!r} has 2 identified passage(s) of 2; "
                                               f"at least 3 are needed for a measured n0 and zeta"]
    assert not out.exists()


@pytest.mark.slow
def test_calibrate_the_measured_bridge(passages_json, call_main, tmp_path):
    """``adm-calib calibrate --measured``: the calibration of the bridge spec with the measured n0
    and ζ, to the last digit, and the measured values in its JSON."""
    from adm_calib.calib_commands import main

    m = read_measured(str(passages_json))
    common = ["calibrate", "--train", "ICE-2", "--speeds", "262:282:1"]
    spec = f"L=15,n0={m.f1_hz!r},mu=19042,zeta_pct={m.zeta1_pct!r}"
    res = {}
    for name, bridge in (("measured", ["--bridge", "B1", "--measured", str(passages_json)]),
                         ("spec", ["--bridge", spec])):
        out = tmp_path / f"{name}.json"
        done = call_main(main, *common, *bridge, "--json", str(out))
        assert done.returncode == 0, done.stderr
        res[name] = json.loads(out.read_text())
    assert res["measured"]["delta_zeta_vbi_pct"] == res["spec"]["delta_zeta_vbi_pct"]
    assert res["measured"]["mlm_peak"] == res["spec"]["mlm_peak"]
    assert res["measured"]["measured"]["n0_hz"] == m.f1_hz and "measured" not in res["spec"]
    assert res["measured"]["zeta_pct"] == pytest.approx(m.zeta1_pct, rel=1e-12)
