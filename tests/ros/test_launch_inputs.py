"""launch_scripts/calibrate.py refuses bad input before starting any process (exit 2, one line)."""

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # every test here starts processes

SCRIPTS = Path(__file__).resolve().parents[2] / "launch_scripts"


@pytest.mark.parametrize("script", ["calibrate.py", "crossing.py"])
@pytest.mark.parametrize("args,match", [
    (["--train", "TGV"], "train: 'TGV' is unknown; allowed ICE-2"),
    (["--bridge", "L=-3,n0=8,mu=1000,zeta_pct=1"], "L: -3 m is out of range; allowed [1, 150] m"),
    (["--speeds", "100:50"], "needs start <= stop"),
    (["--params-file", "nope.yaml"], "--params-file: 'nope.yaml' does not exist"),
])
def test_bad_input_exit_2(script, args, match, tmp_path, launcher):
    code, out, err = launcher(script, ["--out", str(tmp_path / "o")] + args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and match in lines[0], err
    assert "Traceback" not in err
    assert "ROS_DOMAIN_ID" not in out  # nothing was started
    assert list(tmp_path.iterdir()) == []  # no output folder


@pytest.mark.parametrize("script", ["calibrate.py", "crossing.py"])
def test_refuses_to_overwrite_an_earlier_run(script, tmp_path):
    (tmp_path / "summary.json").write_text("{}")
    r = subprocess.run([sys.executable, str(SCRIPTS / script), "--out", str(tmp_path)], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2 and "holds an earlier run (summary.json)" in r.stderr
    assert (tmp_path / "summary.json").read_text() == "{}"


def test_node_rejects_a_wrongly_typed_startup_parameter():
    # -p speeds_kmh:=280 is a YAML integer; the node names the parameter and exits 2, no traceback
    from adm_sim.processes.dds_env import local_ros_env

    with local_ros_env() as env:
        r = subprocess.run([sys.executable, "-m", "adm_sim.nodes.train_node", "--ros-args", "-p", "speeds_kmh:=280"],
                           capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "error: train: speeds_kmh: the given value has the wrong type" in r.stderr
    assert "expected a str (km/h)" in r.stderr


def test_calibrate_dim_grid_reaches_the_calibration_node(tmp_path, launcher):
    """``--dim-grid`` sets the calibration node's ``dim_grid`` (default: the params file's, window);
    a value not in the registry is refused before anything starts."""
    code, out, err = launcher("calibrate.py", ["--out", str(tmp_path / "o"), "--dim-grid", "coarse"])
    assert code == 2 and "ROS_DOMAIN_ID" not in out
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "--dim-grid" in lines[0] and "'coarse'" in lines[0] and "window" in lines[0]
    import calibrate  # on sys.path while the launcher fixture is
    for given, expected in ((["--dim-grid", "paper"], "paper"), ([], None)):
        _, _, cal = calibrate.node_params(calibrate.parse_args(given), tmp_path)
        assert cal.get("dim_grid") == expected
    import yaml

    doc = yaml.safe_load((SCRIPTS.parent / "ros_ws" / "params" / "b1_ice2.yaml").read_text())
    assert doc["calibration"]["ros__parameters"]["dim_grid"] == "window"
