"""The adm-calib command: outputs, exit codes and one-line errors; no ROS in the analysis package."""

import csv
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from adm_calib import reference as ref
from adm_calib.calib_commands import main

ROOT = Path(__file__).resolve().parents[2]


def run_cli(*args, cwd=None):
    """The command in its own process (test_bad_input_exit_code_of_the_process)."""
    return subprocess.run([sys.executable, "-m", "adm_calib.calib_commands", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


@pytest.fixture
def call(call_main):
    """``call(*args)``: the command's ``main`` in this process (the process itself:
    test_bad_input_exit_code_of_the_process)."""
    return lambda *args: call_main(main, *args)



def png_size(path):
    """(width, height) in pixels from a PNG's IHDR chunk; fails on anything that is not a PNG."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def test_calibrate_writes_json_and_plot_readme_headline(tmp_path, call):
    """The README's headline numbers (the main job's case, B1 x ICE-2, default speeds 160:350:1 km/h):
    MLM peak 2.2465 m/s² at 263 km/h, DIM peak 1.8108 m/s² at 262 km/h, dz_VBI 0.553 %, each to the
    last printed digit (half a unit: 5e-5 m/s², 5e-4 %)."""
    js, png = tmp_path / "b1.json", tmp_path / "b1.png"
    p = call("calibrate", "--bridge", "B1", "--train", "ice2", "--json", str(js), "--plot", str(png))
    assert p.returncode == 0, p.stderr
    assert "dz_VBI         0.553 %" in p.stdout and "MLM peak       2.2465 m/s^2 at 263 km/h" in p.stdout
    d = json.loads(js.read_text())
    assert d["status"] == "ok" and d["train"] == "ICE-2"
    assert d["mlm_peak"]["speed_kmh"] == 263.0 and d["mlm_peak"]["acc_m_s2"] == pytest.approx(2.2465, abs=5e-5)
    assert d["dim_peak"]["speed_kmh"] == 262.0 and d["dim_peak"]["acc_m_s2"] == pytest.approx(1.8108, abs=5e-5)
    assert d["delta_zeta_vbi_pct"] == pytest.approx(0.553, abs=5e-4)
    # the adapted MLM peak meets the DIM peak (the calibration's root condition, 1e-5 relative)
    assert d["adapted_mlm_peak"]["acc_m_s2"] == pytest.approx(d["dim_peak"]["acc_m_s2"], rel=1e-5)
    # EN 1991-2 6.4.6.3.1 at L = 15 m: (0.0187 L - 0.00064 L^2) / (1 - 0.0441 L - 0.0044 L^2 + 0.000255 L^3)
    L = 15.0
    adm = (0.0187 * L - 0.00064 * L**2) / (1 - 0.0441 * L - 0.0044 * L**2 + 0.000255 * L**3)
    assert d["delta_zeta_adm_pct"] == pytest.approx(adm, rel=1e-9) and adm == pytest.approx(0.6527, abs=1e-4)
    assert d["delta_zeta_lb_pct"] == pytest.approx(ref.lower_bound("ICE-2", "mu2").delta_zeta_pct(8.262), abs=1e-3)
    assert d["delta_zeta_eada_pct"] == pytest.approx(0.1010, abs=5e-5)
    assert png_size(png) == (960, 540)  # 8 x 4.5 in at 120 dpi (plots.plot_calibration)
    # never overwrite silently
    p2 = call("calibrate", "--bridge", "B1", "--train", "ICE-2", "--json", str(js))
    assert p2.returncode == 2
    assert p2.stderr.strip().splitlines() == [f"error: --json: '{js}' exists; use --overwrite to replace it"]


def test_table4_subset_eurostar_has_no_eada(tmp_path, call):
    p = call("table4", "--out", str(tmp_path), "--bridges", "B3", "--trains", "Eurostar", "--speeds", "250:300:1")
    assert p.returncode == 0, p.stderr
    rows = list(csv.reader((tmp_path / "table4.csv").open()))
    assert rows[0] == ["approach", "Eurostar B3"]
    assert [r[0] for r in rows[1:]] == ["VBI", "LB", "ADM", "EADA"]
    assert rows[4][1] == ""                                          # EADA undefined
    assert float(rows[3][1]) == pytest.approx(0.6527, abs=1e-4)      # ADM at 15 m
    assert float(rows[2][1]) == pytest.approx(ref.lower_bound("Eurostar", "mu5").delta_zeta_pct(8.262), abs=1e-3)
    text = (tmp_path / "table4.txt").read_text()
    assert "n/a" in text and "Jacobs" in text
    assert png_size(tmp_path / "fig19_total_damping.png") == (720, 432)  # one train: 6 x 3.6 in at 120 dpi
    assert json.loads((tmp_path / "table4.json").read_text())["Eurostar B3"]["delta_zeta_eada_pct"] is None


def test_recommend_prints_rule_and_functions(capsys):
    assert main(["recommend", "--train", "ICE-2", "--n0", "5", "--mu", "25000", "--type", "cfb", "--span", "20"]) == 0
    out = capsys.readouterr().out
    # mu2(20) = 22.543 < 25 < mu1(20) = 27.31 t/m: safe side = mu1
    assert "next heavier function mu1" in out
    expected = ref.lower_bound("ICE-2", "mu1").delta_zeta_pct(5.0)
    assert f"dz_LB = {expected:.4f} %" in out
    assert main(["recommend", "--train", "ICE-2", "--n0", "5", "--mu", "25000", "--type", "cfb", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["span_estimated"] is True and d["mass_functions"]
    assert d["mu_kg_m"] == 25000.0 and d["mu_t_m"] == 25.0


@pytest.mark.parametrize("argv, match", [
    (["recommend", "--train", "TGV", "--n0", "5", "--mu", "20000", "--type", "cfb"], r"train: 'TGV' was not studied"),
    (["recommend", "--train", "ICE-2", "--n0", "1.5", "--mu", "20000", "--type", "cfb"],
     r"--n0: 1.5 Hz is out of range; allowed \[2.1, 35.\d+\] Hz"),
    (["recommend", "--train", "ICE-2", "--n0", "5", "--mu", "20000", "--type", "cfb", "--span", "-10"],
     r"^error: --span: -10 m is out of range; allowed \[4, 40\] m$"),
    (["recommend", "--train", "ICE-2", "--n0", "5", "--mu", "20000", "--type", "concrete"], r"argument --type: invalid choice"),
    (["recommend", "--train", "ICE-2", "--n0", "five", "--mu", "20000", "--type", "cfb"], r"--n0: 'five' is not a number"),
    (["recommend", "--train", "ICE-2", "--n0", "5", "--mu", "20", "--type", "cfb"],
     r"^error: --mu: 20 kg/m is out of range; allowed \[500, 100000\] kg/m \(--mu is in kg/m like the bridge "
     r"specs: 20 t/m = 20000 kg/m\)$"),
    (["calibrate", "--bridge", "B1", "--train", "TGV"], r"train: 'TGV' is unknown"),
    (["calibrate", "--bridge", "L=-15,n0=8,mu=19000,zeta_pct=1.8", "--train", "ICE-2"], r"L: -15 m is out of range"),
    (["calibrate", "--bridge", "B1", "--train", "ICE-2", "--speeds", "350:160:1"], r"speeds: '350:160:1' needs start <= stop"),
    (["calibrate", "--bridge", "B1", "--train", "ICE-2", "--plot", "out.jpg"], r"must end in .png"),
    (["table4", "--trains", "TGV"], r"^error: --trains: 'TGV' was not studied"),
    (["table4", "--bridges", "B7"], r"^error: --bridges: 'B7' is not a named bridge"),
    (["frobnicate"], r"invalid choice"),
])
def test_bad_input_one_line_exit_2(argv, match, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")
    assert re.search(match, err[0]), err[0]


@pytest.mark.slow
def test_bad_input_exit_code_of_the_process():
    p = run_cli("recommend", "--train", "ICE-2", "--n0", "1.0", "--mu", "20000", "--type", "sc")
    assert p.returncode == 2
    assert p.stderr.startswith("error: --n0: 1 Hz is out of range") and "Traceback" not in p.stderr
    p = run_cli("calibrate", "--bridge", "B1", "--train", "unknown-train")
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "unknown-train" in p.stderr


@pytest.mark.slow
def test_console_script_installed():
    exe = Path(sys.executable).with_name("adm-calib")
    if not exe.exists():
        pytest.skip("console script not installed in this environment")
    p = subprocess.run([str(exe), "recommend", "--train", "Railjet", "--n0", "3.6", "--mu", "9560", "--type", "sc",
                        "--span", "30"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "mu lies on mass function mu5" in p.stdout
