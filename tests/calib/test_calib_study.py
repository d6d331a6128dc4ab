"""The parametric study on dask (Section 3.3) and the lower-bound fit (Section 4.2.1).

The cases used here are the cheapest of the field (L = 39-40 m at the LB frequency, n0 ~ 2.1 Hz,
about 1.5 s each); the full study (4440 cases) takes hours and is not run.
"""

import json
import os
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import psutil
import pytest
from scipy.optimize import brentq

from adm_calib import study as st
from adm_calib.study.store import _exclusive
from adm_calib.calib_commands import main
from adm_calib.reference import lower_bound_table, span_from_frequency_m
from adm_sim.errors import InputError

# one mass function over 12 spans: 12 batches of one case, so a kill lands mid-run
STUDY_ARGS = ["--trains", "ICE-2", "--spans", "29:40", "--freq-index", "1", "--mass-functions", "mu1"]
STUDY_KEYS = {(f"L{L}-f1-mu1", "ICE-2") for L in range(29, 41)}
N_STUDY = len(STUDY_KEYS)


def _study_argv(out, *extra):
    """One worker process: a kill or Ctrl-C still lands mid-run (12 batches), one process fewer to start."""
    return ["study", "--out", str(out), *STUDY_ARGS, "--workers", "1", *extra]


def _study_cmd(out, *extra):
    return [sys.executable, "-m", "adm_calib.calib_commands", *_study_argv(out, *extra)]


def _complete_lines(path):
    if not path.exists():
        return []
    data = path.read_bytes()
    return data[: data.rfind(b"\n") + 1].splitlines()


def _wait_for_lines(proc, path, n=1, timeout=90.0):
    t_end = time.monotonic() + timeout
    while len(_complete_lines(path)) < n:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < t_end, "no result line in time"
        time.sleep(0.05)


def _listening_addresses(pids):
    out = set()
    for c in psutil.net_connections(kind="inet"):
        if c.status == psutil.CONN_LISTEN and c.pid in pids:
            out.add(c.laddr.ip)
    return out


def _assert_processes_end(procs, timeout=20.0):
    """The worker processes end by themselves once their parent is gone (none left behind)."""
    t_end = time.monotonic() + timeout
    alive = procs
    while time.monotonic() < t_end:
        alive = [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        if not alive:
            return
        time.sleep(0.2)
    for p in alive:                      # clean up what this test started, then fail
        p.kill()
    pytest.fail(f"processes left running: {[p.pid for p in alive]}")


# ---------------------------------------------------------------------- study on dask
@pytest.mark.slow
def test_tiny_study_equals_in_process_calibrate(tmp_path):
    from adm_sim.inputs.train_files import load_train

    from adm_calib.calibrate import CalibrationOptions, calibrate
    from adm_calib.calibration_options import XTOL_STUDY

    cases = st.select_cases(["ice2"], ["mu1", "mu2", "mu3"], (40, 40), [1])
    assert [c.key for c in cases] == [(f"L40-f1-mu{m}", "ICE-2") for m in (1, 2, 3)]
    t_start = time.perf_counter()
    run = st.run_study(tmp_path, cases, workers=2)
    elapsed_s = time.perf_counter() - t_start
    assert (run.completed, run.submitted, run.interrupted, run.errors) == (3, 3, False, 0)
    lines = (tmp_path / "results.jsonl").read_text().splitlines()
    assert len(lines) == 3
    recs = {r["bridge"]: r for r in map(json.loads, lines)}
    train = load_train("ICE-2")
    for c in cases:
        ref = calibrate(c.bridge, train, adapted_curve=False, options=CalibrationOptions(xtol=XTOL_STUDY))
        r = recs[c.bridge.name]
        assert r["status"] == ref.status == "ok"
        # batched (compiled lanes, find_root) vs one case alone (numpy stepper, brentq), same ds:
        # peaks to 1e-9 relative, dz to 1e-5 % (both roots are within xtol = 1e-6 % of the true one)
        assert abs(r["delta_zeta_vbi_pct"] - ref.delta_zeta_vbi_pct) <= 1e-5
        assert r["mlm_peak"]["acc_m_s2"] == pytest.approx(ref.mlm_peak.acc_m_s2, rel=1e-9)
        assert r["dim_peak_acc_m_s2"] == pytest.approx(ref.dim_peak.acc_m_s2, rel=1e-9)
        assert (r["span_m"], r["mass_function"], r["freq_index"], r["bridge_type"]) == (40.0, c.mass_function, 1, "cfb")
        assert r["n0_hz"] == pytest.approx(c.bridge.n0_hz, rel=1e-12)
        assert r["mu_t_m"] == pytest.approx(c.bridge.mass_per_length_kg_m / 1000, rel=1e-12)
        assert r["zeta_pct"] == pytest.approx(1.5) and r["delta_zeta_adm_pct"] == 0.0   # L >= 30 m
        # the flags from the in-process curves (numpy stepper), by plain argmax and neighbours
        mlm, dim = ref.mlm_acc_m_s2, ref.dim_acc_m_s2
        assert r["mlm_max_at_range_end"] is (int(np.argmax(mlm)) in (0, mlm.size - 1))
        # the study's default DIM grid is the window (the paper's speeds near the MLM peak): its curve
        # does not reach the ends of the range, so that flag is unknown (null)
        assert r["dim_grid"] == "window" and r["dim_max_at_range_end"] is None
        i = int(np.flatnonzero(ref.dim_speeds_kmh == r["dim_peak"]["speed_kmh"])[0])
        assert r["dim_is_local_max"] is bool(0 < i < dim.size - 1 and dim[i - 1] < dim[i] > dim[i + 1])
        # a case's wall time (its batch's wall time / cases in the batch) lies within the study's
        # elapsed time, measured around run_study
        assert 0.0 < r["wall_s"] <= elapsed_s
    # two workers: the cases' wall times add up to at most twice the elapsed time (0.91 s of 8.2 s measured)
    assert sum(r["wall_s"] for r in recs.values()) <= 2 * elapsed_s
    meta = json.loads((tmp_path / "study.json").read_text())
    cl = meta["runs"][-1]["cluster"]
    assert cl["scheduler"].startswith("tcp://127.0.0.1:")
    assert len(cl["workers"]) == 2
    for addr, w in cl["workers"].items():
        assert addr.startswith("tcp://127.0.0.1:") and w["nanny"].startswith("tcp://127.0.0.1:")
        assert w["nthreads"] == 1
    assert all(env == dict(st.WORKER_ENV) for env in cl["worker_env"].values())
    assert meta["settings"] == st.StudySettings().to_dict() and meta["runs"][-1]["versions"]["dask"]


@pytest.mark.slow
def test_resume_after_sigkill_with_truncated_line(tmp_path, capsys):
    """The killed study is a process of its own; the two runs after it (their messages, exit code
    and files are what is checked) call the command's ``main`` in this process."""
    res = tmp_path / "results.jsonl"
    p = subprocess.Popen(_study_cmd(tmp_path), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         start_new_session=True)
    try:
        _wait_for_lines(p, res, 1)
        tree = [psutil.Process(p.pid)] + psutil.Process(p.pid).children(recursive=True)
        # nothing of the study listens on anything but the loopback interface
        assert _listening_addresses({q.pid for q in tree}) <= {"127.0.0.1"}
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
        p.communicate()
    _assert_processes_end(tree[1:])
    first = _complete_lines(res)
    assert 1 <= len(first) < N_STUDY
    # one flipped byte in the first line (a digit of its wall time: still valid JSON) and a write
    # cut short (the last line has no newline): both named, dropped, and those cases computed again
    size = res.stat().st_size
    data = bytearray(res.read_bytes())
    at = data.index(b'"wall_s":') + len(b'"wall_s":')
    data[at] = ord("9") if data[at] != ord("9") else ord("8")
    res.write_bytes(bytes(data))
    with open(res, "ab") as f:
        f.write(json.dumps({"bridge": "L40-f1-mu1", "train": "ICE-2", "status": "ok"}).encode()[:40])
    with pytest.raises(InputError, match=r"damaged line 1 \(byte 0, \d+ bytes\): checksum mismatch"):
        st.read_results(res)
    capsys.readouterr()
    rc2 = main(_study_argv(tmp_path))
    out2, err2 = capsys.readouterr()
    assert rc2 == 0, err2
    assert (f"study: dropped results.jsonl line 1 (byte 0, {len(first[0]) + 1} bytes): checksum mismatch; "
            f"that case runs again") in out2
    assert (f"study: dropped a truncated last line {len(first) + 1} (byte {size}, 40 bytes, no newline) of "
            f"results.jsonl; that case runs again") in out2
    first = first[1:]
    final = res.read_bytes()
    assert final.endswith(b"\n")
    lines = final.splitlines()
    keys = [(r["bridge"], r["train"]) for r in map(json.loads, lines)]
    assert len(lines) == N_STUDY and set(keys) == STUDY_KEYS       # every case once
    assert lines[: len(first)] == first                       # the killed run's results kept as written
    run2 = json.loads((tmp_path / "study.json").read_text())["runs"][-1]
    assert (run2["already_done"], run2["submitted"], run2["completed"]) == (len(first), N_STUDY - len(first), N_STUDY - len(first))
    # a third run computes nothing
    rc3 = main(_study_argv(tmp_path))
    assert rc3 == 0 and "0 of 0 submitted" in capsys.readouterr().out
    assert res.read_bytes() == final


@pytest.mark.slow
def test_ctrl_c_stops_cleanly_and_keeps_results(tmp_path):
    res = tmp_path / "results.jsonl"
    p = subprocess.Popen(_study_cmd(tmp_path), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    try:
        _wait_for_lines(p, res, 1)
        kids = psutil.Process(p.pid).children(recursive=True)
        os.killpg(p.pid, signal.SIGINT)          # as Ctrl-C on a terminal: the whole process group
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert p.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert "interrupted; rerun the same command to resume" in out
    _assert_processes_end(kids)
    lines = _complete_lines(res)
    assert 1 <= len(lines) <= N_STUDY and res.read_bytes().endswith(b"\n")
    run = json.loads((tmp_path / "study.json").read_text())["runs"][-1]
    assert run["interrupted"] is True and run["completed"] == len(lines)


def test_error_case_is_recorded_not_raised():
    case = st.select_cases(["ICE-2"], ["mu6"], (40, 40), [1])[0]
    bad = st.StudyCase(bridge=case.bridge, train="no-such-train", mass_function="mu6", freq_index=1)
    rec = st.run_case(bad)
    assert rec["status"] == "error" and rec["delta_zeta_vbi_pct"] is None
    assert rec["message"].startswith("InputError: train: 'no-such-train' is unknown") and "\n" not in rec["message"]
    assert (rec["bridge"], rec["train"], rec["mass_function"]) == ("L40-f1-mu6", "no-such-train", "mu6")


@pytest.mark.slow
def test_results_reader_and_guards(tmp_path):
    res = tmp_path / "results.jsonl"
    res.write_text('{"bridge": "a", "train": "ICE-2"}\nnot json\n{"bridge": "b", "train": "ICE-2"}\n')
    with pytest.raises(InputError, match=r"damaged line 2 \(byte 34, 9 bytes\): not valid JSON; a study resumed"):
        st.read_results(res)
    res.write_text('{"bridge": "a", "train": "ICE-2"}\n{"bridge": "b", "tr')
    c = st.read_results(res)
    assert [r["bridge"] for r in c.records] == ["a"] and c.truncated_tail == b'{"bridge": "b", "tr'
    # another study's settings: refused before any cluster starts
    cases = st.select_cases(["ICE-2"], ["mu1"], (40, 40), [1])
    (tmp_path / "study.json").write_text(json.dumps({"format": st.META_FORMAT, "runs": [],
                                                     "settings": st.StudySettings(speeds="200:300:1").to_dict()}))
    with pytest.raises(InputError, match=r"other settings \(speeds '200:300:1' -> '160:350:1'\); use another --out"):
        st.run_study(tmp_path, cases)
    # two studies never append to one file
    with _exclusive(tmp_path):
        with pytest.raises(InputError, match="is in use by another running study"):
            st.run_study(tmp_path, cases, settings=st.StudySettings(speeds="200:300:1"))


def test_select_cases_counts():
    every = st.select_cases()
    assert len(every) == 4440 and len({c.key for c in every}) == 4440
    sub = st.select_cases(["Railjet", "ICE-4"], ["mu4", "mu5"], (10, 12), [2, 5])
    assert len(sub) == 2 * 2 * 3 * 2
    assert {c.train for c in sub} == {"Railjet", "ICE-4"}
    assert {c.bridge.bridge_type for c in sub} == {"sc"}


@pytest.mark.slow
def test_study_imports_neither_dask_nor_matplotlib():
    """The study's module leaves the cluster and the figures to the commands that use them (rclpy:
    tests/house/test_layers.py's ``test_nothing_below_the_nodes_loads_rclpy``)."""
    code = ("import sys, adm_calib.study; "
            "print(sorted(m for m in ('dask', 'distributed', 'matplotlib') if m in sys.modules))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and p.stdout.strip() == "[]", p.stderr


# ---------------------------------------------------------------------- bad input
@pytest.mark.parametrize("args, message", [
    (["--trains", "TGV"], "error: --trains: 'TGV' is not a study train; allowed ICE-2, Eurostar, Railjet, ICE-4 or the variant Eurostar-table"),
    (["--spans", "50:60"], "error: --spans: 50 m is out of range; allowed [4, 40] m"),
    (["--workers", "0"], "error: --workers: 0 processes is out of range; allowed integer in [1, 64] processes"),
    (["--freq-index", "1,6"], "error: --freq-index: 6 is out of range; allowed integer in [1, 5]"),
    (["--mass-functions", "mu7"], "error: --mass-functions: 'mu7' is unknown; allowed mu1, mu2, mu3, mu4, mu5, mu6"),
    (["--scheduler", "0.0.0.0"], "error: --scheduler: '0.0.0.0' is not an address like tcp://127.0.0.1:8786"),
])
def test_study_bad_input_exit_2_one_line(tmp_path, capsys, args, message):
    out = tmp_path / "s"
    assert main(["study", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [message]
    assert not out.exists()


def test_study_fit_bad_input(tmp_path, capsys):
    assert main(["study-fit", "--results", str(tmp_path / "none.jsonl")]) == 2
    assert capsys.readouterr().err.splitlines() == [f"error: --results: '{tmp_path / 'none.jsonl'}' is not a file"]


# ---------------------------------------------------------------------- lower-bound fit
def _synthetic(coef, train="ICE-2", mf="mu3", per_interval=8, seed=1):
    """Records whose interval minima lie exactly on the cubic ``coef``; all other points lie above
    the cubic's maximum over their interval (positive scatter), so the minima are known."""
    rng = np.random.default_rng(seed)
    edges = st.INTERVAL_EDGES_HZ
    recs, minima = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        x = np.sort(rng.uniform(lo, hi, per_interval))
        top = np.polyval(coef, np.linspace(lo, hi, 401)).max()
        y = top + 0.005 + rng.uniform(0.0, 0.3, per_interval)
        k = int(rng.integers(per_interval))
        y[k] = np.polyval(coef, x[k])
        minima.append((x[k], y[k]))
        for xi, yi in zip(x, y):
            recs.append({"bridge": f"S{len(recs)}", "train": train, "mass_function": mf, "n0_hz": float(xi),
                         "span_m": float(span_from_frequency_m(xi)), "status": "ok",
                         "delta_zeta_vbi_pct": float(yi), "mlm_max_at_range_end": False, "dim_is_local_max": True})
    return recs, minima


def test_fit_recovers_known_cubic_from_interval_minima():
    coef = (7.0e-4, -2.6e-2, 0.25, -0.24)
    recs, minima = _synthetic(coef)
    # cases above 21 Hz are not used (Section 4.2.1)
    recs.append(dict(recs[0], bridge="high", n0_hz=25.0, delta_zeta_vbi_pct=-5.0))
    fit = st.fit_study(recs)
    f = fit.fits[("ICE-2", "mu3")]
    assert len(f.minima) == len(st.INTERVAL_EDGES_HZ) - 1 == 18
    assert [(p.n0_hz, p.delta_zeta_pct) for p in f.minima] == minima
    assert all(p.n_cases == 8 for p in f.minima[:-1]) and f.minima[-1].n_cases == 8
    assert fit.excluded["above_21hz"] == 1
    # exact data: least squares returns the cubic to round-off (1e-8 relative on 18 well spread points)
    np.testing.assert_allclose(f.fit.coefficients, coef, rtol=1e-8)
    assert f.fit.r2 == pytest.approx(1.0, abs=1e-12)
    assert max(abs(f.fit.max_res_pct), abs(f.fit.min_res_pct)) < 1e-10
    # independently: a bracketing solver between the first sign change of the cubic on a 0.01 Hz grid
    grid = np.arange(2.1, 40.0, 0.01)
    p = np.polyval(coef, grid)
    k = int(np.flatnonzero(np.sign(p[:-1]) != np.sign(p[1:]))[0])
    root = brentq(lambda x: np.polyval(coef, x), grid[k], grid[k + 1], xtol=1e-14, rtol=4 * np.finfo(float).eps)
    assert f.fit.upper_limit_hz == pytest.approx(root, abs=1e-8)
    # independently: the smallest real root of the cubic above 2.1 Hz (numpy's companion-matrix roots)
    roots = np.roots(coef)
    real = sorted(r.real for r in roots if abs(r.imag) < 1e-12 and r.real > 2.1)
    assert f.fit.upper_limit_hz == pytest.approx(real[0], abs=1e-8)
    assert f.fit.value_pct(f.fit.upper_limit_hz + 1) == 0.0


def test_fit_of_table_b1_reproduces_published_upper_limits():
    """The published Table B1 cubics evaluated at points of every interval are fitted back to
    themselves; their first root above 2.1 Hz is the printed upper limit to 0.01 Hz."""
    recs = []
    for mf, lb in lower_bound_table()["ICE-2"].items():
        edges = st.INTERVAL_EDGES_HZ
        for lo, hi in zip(edges[:-1], edges[1:]):
            x = 0.5 * (lo + hi)
            recs.append({"bridge": f"{mf}-{x}", "train": "ICE-2", "mass_function": mf, "n0_hz": x, "status": "ok",
                         "delta_zeta_vbi_pct": float(lb.polynomial_pct(x))})
    fit = st.fit_study(recs)
    for mf, lb in lower_bound_table()["ICE-2"].items():
        f = fit.fits[("ICE-2", mf)].fit
        np.testing.assert_allclose(f.coefficients, lb.coefficients, rtol=1e-7)
        assert abs(f.upper_limit_hz - lb.upper_limit_hz) <= 0.01, (mf, f.upper_limit_hz, lb.upper_limit_hz)


def test_interval_minima_edges_and_ties():
    x = [1.9, 2.0, 2.49, 2.5, 2.5, 20.9, 21.0, 21.5]
    y = [-9.0, 0.3, 0.1, 0.2, 0.2, 0.5, 0.4, -9.0]
    m = st.interval_minima(x, y, names="abcdefgh")
    assert [(p.lo_hz, p.hi_hz, p.n_cases, p.bridge) for p in m] == [
        (2.0, 2.5, 2, "c"), (2.5, 3.0, 2, "d"), (16.0, 21.0, 2, "g")]


def _no_figures(monkeypatch):
    """study-fit without the conservative bound's linear programmes and with empty figure files.

    ``conservative_study`` is replaced where the command looks it up, in ``adm_calib.cli.study_fit``
    (which imports the name): replaced in ``adm_calib.study.conservative`` it took effect only when
    the command module was first imported after the patch, and then stayed for the rest of the run."""
    from adm_calib import plots
    from adm_calib.cli import study_fit

    def empty_png(*args, **kwargs):
        next(a for a in args if isinstance(a, Path)).write_bytes(b"")

    monkeypatch.setattr(study_fit, "conservative_study", lambda fit: [])
    for name in ("plot_dz_vs_span", "plot_lower_bounds", "plot_lower_bound_set", "plot_lower_bounds_train"):
        monkeypatch.setattr(plots, name, empty_png)


@pytest.mark.slow
def test_study_fit_cli_end_to_end(tmp_path, capsys, monkeypatch):
    lbs = lower_bound_table()
    recs = []
    for t in ("ICE-2", "Eurostar"):
        for mf in ("mu2", "mu5"):
            r, _ = _synthetic(lbs[t][mf].coefficients, train=t, mf=mf, per_interval=4, seed=len(recs))
            recs += [dict(x, bridge=f"{t}-{mf}-{x['bridge']}") for x in r]
    base = dict(recs[0])
    recs += [dict(base, bridge="E1", status="error", delta_zeta_vbi_pct=None, message="RuntimeError: boom"),
             dict(base, bridge="N1", status="no_mlm_peak", delta_zeta_vbi_pct=None),
             dict(base, bridge="F1", mlm_max_at_range_end=True, delta_zeta_vbi_pct=-3.0),
             dict(base, bridge="F2", dim_is_local_max=False, delta_zeta_vbi_pct=-3.0)]
    res = tmp_path / "results.jsonl"
    res.write_text("".join(json.dumps(r) + "\n" for r in recs) + '{"bridge": "cut')
    out = tmp_path / "fit"
    # the conservative bound's linear programmes (about 990 linprog calls for these four sets, 5 s of
    # CPU per fit) run in the default-rule fit below, whose conservative files are checked; in the
    # fits with rules none and strict they are left out (no set), their files still written.
    # Likewise the figures (matplotlib: ~3 s of CPU per fit) are drawn and checked in the default-rule
    # fit; with rules none and strict their files are written empty (not proven here: that drawing
    # works on a fit of rule none or strict; the plotting code does not depend on the rule)
    _no_figures(monkeypatch)
    assert main(["study-fit", "--results", str(res), "--out", str(out), "--exclude", "none"]) == 0
    text = capsys.readouterr().out
    assert "excluded     1: status error" in text and "excluded     1: no dz_VBI" in text
    assert "associated DIM value" not in text
    assert f"a truncated last line {len(recs) + 1} (byte {len(res.read_bytes()) - 15}, 15 bytes, no newline) of the results file was ignored" in text
    rows = (out / "lower_bounds_fit_none.csv").read_text().splitlines()
    assert rows[0].startswith("train,mass_function,n_cases,n_points,a,b,c,d,upper_limit_hz,r2")
    assert [r.split(",")[:2] for r in rows[1:]] == [["ICE-2", "mu2"], ["ICE-2", "mu5"], ["Eurostar", "mu2"],
                                                    ["Eurostar", "mu5"]]
    # with rule none the flagged cases (dz = -3 %) are used: they pull the ICE-2 mu2 minimum down
    assert float(rows[1].split(",")[11]) < -1.0                    # min residual
    # default rule step2: the DIM value that is not a local maximum is dropped, the MLM-end case stays
    monkeypatch.undo()
    assert main(["study-fit", "--results", str(res), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "excluded     1: associated DIM value" in text and "largest MLM value at an end" not in text
    rows = (out / "lower_bounds_fit.csv").read_text().splitlines()
    assert float(rows[1].split(",")[11]) < -1.0
    for png in ["fig16_dz_vs_span.png", "fig18_lower_bounds.png", "fig17_lower_bound_ICE-2.png"]:
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len((out / "interval_minima.csv").read_text().splitlines()) == 1 + 4 * 18
    # the comparison counts the flags per set; only rule strict takes the fit back to the paper's cubic
    row = next(r for r in (out / "appendix_b_comparison.md").read_text().splitlines() if r.startswith("| ICE-2 mu2 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1:5] == ["76", "2", "1", "1"] and float(cells[5]) > 1.0 and cells[7] == "0.000"
    # the conservative bound of every set, as a table and as a lower-bound file
    sets = [r.split("|")[1].strip() for r in (out / "conservative_lower_bounds.md").read_text().splitlines()
            if r.startswith("| ") and not r.startswith("| set ")]
    assert sets == ["ICE-2 mu2", "ICE-2 mu5", "Eurostar mu2", "Eurostar mu5"]
    toml = tomllib.loads((out / "lower_bounds_conservative.toml").read_text())
    assert {t: sorted(m for m in tab if m.startswith("mu")) for t, tab in toml["tables"].items()} == {
        "ICE-2": ["mu2", "mu5"], "Eurostar": ["mu2", "mu5"]}
    # never overwrite silently
    assert main(["study-fit", "--results", str(res), "--out", str(out)]) == 2
    assert f"--out: {str(out / 'lower_bounds_fit.csv')!r} exists; use --overwrite to replace it" in capsys.readouterr().err
    # --exclude-flagged (= strict): both flagged cases are dropped and counted; the fit is exact again
    _no_figures(monkeypatch)
    assert main(["study-fit", "--results", str(res), "--out", str(out), "--exclude-flagged"]) == 0
    text = capsys.readouterr().out
    assert "excluded     1: largest MLM value at an end" in text and "excluded     1: associated DIM value" in text
    rows = (out / "lower_bounds_fit_strict.csv").read_text().splitlines()
    cols = rows[0].split(",")
    for row in rows[1:]:
        d = dict(zip(cols, row.split(",")))
        assert float(d["r2"]) == pytest.approx(1.0, abs=1e-6)
        assert float(d["upper_limit_hz"]) == pytest.approx(float(d["paper_upper_limit_hz"]), abs=0.01)


@pytest.mark.parametrize("dz, zeta, message", [
    (1e308, 1.5, "delta_zeta_vbi_pct: 1e+308 % is out of range; allowed (-1.5, 20] %"),
    (-1.6, 1.5, "delta_zeta_vbi_pct: -1.6 % is out of range; allowed (-1.5, 20] %"),
    (-25.0, None, "delta_zeta_vbi_pct: -25 % is out of range; allowed [-20, 20] %"),
])
def test_study_fit_refuses_a_dz_no_calibration_gives(tmp_path, capsys, dz, zeta, message):
    """A Δζ_VBI beyond what a calibration can return (zeta + dz > 0, the ladder's top of 20 %) is a
    damaged or edited results file: one line, exit 2, nothing written."""
    lbs = lower_bound_table()
    recs, _ = _synthetic(lbs["ICE-2"]["mu2"].coefficients, train="ICE-2", mf="mu2", per_interval=2, seed=1)
    recs[0] = dict(recs[0], delta_zeta_vbi_pct=dz, zeta_pct=zeta)
    res = tmp_path / "results.jsonl"
    res.write_text("".join(json.dumps(r) + "\n" for r in recs))
    assert main(["study-fit", "--results", str(res), "--out", str(tmp_path / "fit")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "fit").exists()
