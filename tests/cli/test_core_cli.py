"""The adm-sim command line: outputs, JSON keys and one-line errors with exit code 2."""

import json
import subprocess
import sys

import pytest

from adm_sim.cli.sim_commands import main

CLI = [sys.executable, "-m", "adm_sim.cli.sim_commands"]


def run(*args):
    """The command in its own process (test_bad_input_exit_code_of_the_process)."""
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=300)


@pytest.fixture
def call(call_main):
    """``call(*args)``: the command's ``main`` in this process (the process itself:
    test_bad_input_exit_code_of_the_process)."""
    return lambda *args: call_main(main, *args)



def test_sweep_json_and_plot(tmp_path, call):
    js, png = tmp_path / "s.json", tmp_path / "s.png"
    # default speeds 160:350:1 km/h; the MLM sweep is the exact envelope (adm_sim.integrate.envelope), so its
    # peak is the true maximum at 263 km/h, which tests/integrate/test_envelope.py checks against the closed
    # form of every axle (2.24716 m/s²); the RK4 run (--method rk4, 16 steps per period) samples it
    # at its steps and sits just below (the README's 2.2465 m/s²)
    r = call("sweep", "--bridge", "B1", "--train", "ICE-2", "--model", "mlm", "--json", str(js), "--plot", str(png))
    assert r.returncode == 0, r.stderr
    assert "peak:" in r.stdout and "exact envelope" in r.stdout
    assert "damping per mode (rayleigh): zeta_1 = 1.85 %, zeta_2 = 1.156 %, zeta_3 = 1.85 %" in r.stdout
    d = json.loads(js.read_text())
    assert len(d["speeds_kmh"]) == 191 == len(d["max_acc_m_s2"])
    assert d["method"] == "exact" and d["where"] == "midspan"
    pk = d["peak"]
    assert pk["speed_kmh"] == 263.0 and pk["acc_m_s2"] == pytest.approx(2.24716, abs=5e-6)
    rk = tmp_path / "rk4.json"
    r = call("sweep", "--bridge", "B1", "--train", "ICE-2", "--model", "mlm", "--method", "rk4", "--json", str(rk))
    d4 = json.loads(rk.read_text())
    assert d4["method"] == "rk4" and d4["peak"]["acc_m_s2"] == pytest.approx(2.2465, abs=5e-5)
    assert d4["peak"]["acc_m_s2"] < pk["acc_m_s2"]
    i = d["speeds_kmh"].index(pk["speed_kmh"])
    assert pk["acc_m_s2"] == d["max_acc_m_s2"][i] == max(d["max_acc_m_s2"])
    data = png.read_bytes()  # a PNG of 7 x 4 in at 120 dpi (cli._plot_sweep)
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and (int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")) == (840, 480)


def test_sweep_reports_missing_interior_peak(tmp_path, call):
    js = tmp_path / "s.json"
    # 250..260 km/h climbs towards the 263 km/h resonance of B1 x ICE-2: no interior maximum
    r = call("sweep", "--bridge", "B1", "--speeds", "250:260:2", "--json", str(js))
    assert r.returncode == 0
    d = json.loads(js.read_text())
    assert d["peak"] is None
    assert "no interior peak" in r.stdout and "260 km/h" in r.stdout


@pytest.mark.parametrize("args,match", [
    (["sweep", "--bridge", "L=-3,n0=8,mu=1000,zeta_pct=1"], "L: -3 m is out of range; allowed [1, 150] m"),
    (["sweep", "--train", "TGV"], "train: 'TGV' is unknown"),
    (["sweep", "--model", "fem"], "invalid choice: 'fem'"),
    (["sweep", "--speeds", "100:50"], "needs start <= stop"),
    (["sweep", "--speeds", "100:900:10"], "speeds: '100:900:10' gives 610 km/h; allowed speeds in [1, 600] km/h"),
    (["sweep", "--delta-zeta-pct", "-5"], "--delta-zeta-pct: -5 % is out of range"),
    (["sweep", "--steps-per-period", "1"], "--steps-per-period: 1 steps is out of range; allowed [4, 10000] steps"),
    (["sweep", "--where", "x=15"], "--where: 15 m is out of range; allowed (0, 15) m"),
    (["sweep", "--where", "span"], "--where: 'span' is not allowed; allowed deck, midspan or x=<position in m>"),
    (["sweep", "--where", "deck", "--method", "rk4"], "--where: 'deck' needs the exact MLM envelope"),
    (["sweep", "--model", "dim", "--method", "exact"], "--method: 'exact' is the closed-form MLM envelope"),
    (["sweep", "--bridge", "L=15,n0=8,mu=10000,zeta_pct=0"], "the exact MLM envelope needs damping > 0 %"),
])
def test_bad_input_is_one_line_exit_2(args, match, capsys):
    # in this process (the command's main, as the console script calls it); the process itself:
    # test_bad_input_exit_code_of_the_process below
    assert main(list(args)) == 2
    out, err = capsys.readouterr()
    # plausibility warnings (docs/plausibility.md) may precede the error: an undamped light deck warns
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("warning: ")]
    assert len(lines) == 1 and lines[0].startswith("error:")
    assert match in lines[0]
    assert "Traceback" not in err and out == ""


@pytest.mark.slow
@pytest.mark.parametrize("args,match", [
    (["sweep", "--model", "fem"], "invalid choice: 'fem'"),                                   # the parser's
    (["sweep", "--bridge", "L=15,n0=8,mu=10000,zeta_pct=0"], "the exact MLM envelope needs damping > 0 %"),  # a check's
])
def test_bad_input_exit_code_of_the_process(args, match):
    """The process exits 2 with one error line (after any warning), no traceback."""
    r = run(*args)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.strip().splitlines() if not ln.startswith("warning: ")]
    assert len(lines) == 1 and lines[0].startswith("error:") and match in lines[0]
    assert "Traceback" not in r.stderr and r.stdout == ""


def test_trains_check_prints_the_checks(call):
    r = call("trains", "--check")
    assert r.returncode == 0
    assert "n_p PC 2-8 (Eq. 1)" in r.stdout and "MISMATCH" in r.stdout  # Eurostar-table
    assert r.stdout.count("ok ") >= 12


def test_sweep_outputs_checked_before_the_run(tmp_path, capsys):
    from adm_sim.cli.sim_commands import main

    base = ["sweep", "--bridge", "B4", "--model", "mlm", "--speeds", "200,260"]
    j = tmp_path / "r.json"
    cases = [
        (["--json", str(tmp_path / "no" / "r.json")], f"error: --json: '{tmp_path}/no/r.json': the directory '{tmp_path}/no' does not exist"),
        (["--json", str(tmp_path)], f"error: --json: '{tmp_path}' is a directory; give a file name"),
        (["--plot", str(tmp_path / "p.jpg")], f"error: --plot: '{tmp_path}/p.jpg' must end in .png"),
        (["--json", str(tmp_path / "same.png"), "--plot", str(tmp_path / "same.png")],
         f"error: --plot: '{tmp_path}/same.png' is the --json file; give two different files"),
    ]
    for extra, line in cases:
        assert main(base + extra) == 2
        out = capsys.readouterr()
        assert out.err == line + "\n" and "MLM sweep" not in out.out  # refused before any computation
    assert main(base + ["--json", str(j)]) == 0
    first = j.read_text()
    assert main(base + ["--json", str(j), "--speeds", "200,300"]) == 2
    assert capsys.readouterr().err == f"error: --json: '{j}' exists; use --overwrite to replace it\n"
    assert j.read_text() == first                       # untouched
    assert main(base + ["--json", str(j), "--overwrite", "--speeds", "200,300"]) == 0
    assert json.loads(j.read_text())["speeds_kmh"] == [200.0, 300.0]
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]   # no temporary files left


def test_bridges_field_is_pure_csv(capsys):
    from adm_sim.cli.sim_commands import main

    assert main(["bridges", "--field"]) == 0
    out = capsys.readouterr()
    rows = out.out.splitlines()
    assert rows[0] == "name,span_m,n0_hz,mu_kg_m,mu_t_m,EJ_Nm2,zeta_pct,type" and len(rows) == 1111
    # mu1 at 4 m: 0.843 * 4 + 10.45 = 13.822 t/m (Eq. 19, Table 1), shown in kg/m and t/m
    assert rows[1].startswith("L4-f1-mu1,4,20.7883,13822.0,13.8220,") and "1110 bridges" in out.err
