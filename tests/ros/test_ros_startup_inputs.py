"""Bad input at ROS start-up: a params YAML is checked before any node starts (launch scripts),
and a node started by hand with a bad parameter prints one line and exits 2 (never a traceback).
"""

import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
from adm_sim.processes.dds_env import local_ros_env  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "launch_scripts"


@pytest.mark.slow
@pytest.mark.parametrize("yaml_text, line", [
    ("bridge:\n  ros__parameters:\n    span: 20.0\n",
     "bridge.ros__parameters.span: unknown parameter; allowed EJ_Nm2, beam_every_steps, beam_points, bridge, "
     "damping_model, delta_zeta, delta_zeta_lanes, ds_m, free_vibration_periods, monitor_every_steps, "
     "monitor_speed_kmh, mu_kg_m, n0_hz, n_modes, partner_timeout_s, response_m, span_EJ_Nm2, span_m, span_mu_kg_m, "
     "spans_m, start_type_description_service, "
     "steps_per_period, track_type, use_sim_time, warn_fraction, zeta_pct"),
    ("bridge:\n  ros__parameters:\n    span_m: -5.0\n",
     "bridge: span_m: -5 m is out of range; allowed [1, 150] m"),
    ("bridge:\n  ros__parameters:\n    span_m: 20\n",
     "bridge.ros__parameters.span_m: 20 is a int; expected a float (write 15.0, not 15) in m"),
    ("brige:\n  ros__parameters:\n    bridge: B1\n",
     "'brige' is not a node of this launch; allowed bridge, calibration, driver, train or '/**'"),
    ("train:\n  parameters:\n    train: ICE-2\n",
     "train: expected exactly one key 'ros__parameters' holding 'name: value' entries, "
     "got {'parameters': {'train': 'ICE-2'}}"),
    ("train:\n  ros__parameters:\n    speeds_kmh: 280\n",
     "train.ros__parameters.speeds_kmh: 280 is a int; expected a str (quote text values) in km/h"),
    ("train:\n  ros__parameters:\n    model: fem\n",
     "train: model: 'fem' is not allowed; allowed 'mlm' or 'dim'"),
    ("train:\n  ros__parameters:\n    mlm_block_steps: 0\n",
     "train: mlm_block_steps: 0 steps is out of range; allowed integer in [1, 10000000] steps"),
    ("bridge:\n  ros__parameters:\n    bridge: B1\n   span_m: 1\n",
     "not valid YAML at line 4, column 4"),
    ("/**:\n  ros__parameters:\n    partner_timeout_s: 0.1\n",
     "/**: partner_timeout_s: 0.1 s is out of range; allowed [0.5, 600] s"),
])
def test_launch_checks_params_file_before_start(yaml_text, line, tmp_path, launcher):
    check_launch("calibrate.py", yaml_text, line, tmp_path, launcher)


@pytest.mark.slow
def test_crossing_checks_params_file_too(tmp_path):
    """The launch script's own process (the cases above call ``calibrate.py``'s ``main`` in this one)."""
    def process(script, argv):
        r = subprocess.run([sys.executable, str(SCRIPTS / script)] + argv, capture_output=True, text=True, timeout=60)
        return r.returncode, r.stdout, r.stderr

    check_launch("crossing.py", "bridge:\n  ros__parameters:\n    span_m: -5.0\n",
                 "bridge: span_m: -5 m is out of range; allowed [1, 150] m", tmp_path, process)


def check_launch(script, yaml_text, line, tmp_path, run):
    params = tmp_path / "case.yaml"
    params.write_text(yaml_text)
    code, out, err = run(script, ["--out", str(tmp_path / "o"), "--params-file", str(params)])
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    head = f"error: --params-file {str(params)!r}: "
    if "not valid YAML" in line:
        assert lines[0].startswith(head + line)
    else:
        assert lines[0] == head + line
    assert "ROS_DOMAIN_ID" not in out  # nothing was started
    assert not (tmp_path / "o").exists()


def test_shipped_params_files_pass_the_check():
    sys.path.insert(0, str(SCRIPTS))
    try:
        from _supervisor import check_inputs
    finally:
        sys.path.remove(str(SCRIPTS))
    for path in sorted((ROOT / "ros_ws" / "params").glob("*.yaml")):
        check_inputs(params_file=path)


@pytest.mark.slow
@pytest.mark.parametrize("module, args, line", [
    ("adm_sim.nodes.bridge_node", ["-p", "span_m:=-5.0"],
     "error: bridge: span_m: -5 m is out of range; allowed [1, 150] m"),
    ("adm_sim.nodes.bridge_node", ["-p", "zeta_pct:=25.0"],
     "error: bridge: zeta_pct: 25 % is out of range; allowed [0, 20] %"),
    ("adm_sim.nodes.bridge_node", ["-p", "n_modes:=0"],
     "error: bridge: n_modes: 0 is out of range; allowed integer in [1, 50]"),
    ("adm_sim.nodes.bridge_node", ["-p", "n_modes:=21"],  # B1, one simply supported span: 20 at most
     "error: bridge: n_modes: 21 is out of range; allowed integer in [1, 20]"),
    ("adm_sim.nodes.bridge_node", ["-p", "bridge:=B9"],
     None),  # the preset's own message (checked below)
    ("adm_sim.nodes.train_node", ["-p", "mlm_block_steps:=0"],
     "error: train: mlm_block_steps: 0 steps is out of range; allowed integer in [1, 10000000] steps"),
    ("adm_sim.nodes.driver", ["-p", "run_timeout_s:=0.5"],
     "error: driver: run_timeout_s: 0.5 s is out of range; allowed [1, 86400] s"),
])
def test_node_started_by_hand_with_bad_parameter(module, args, line):
    with local_ros_env() as env:
        r = subprocess.run([sys.executable, "-m", module, "--ros-args"] + args, capture_output=True, text=True,
                           timeout=60, env=env)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    if line is None:
        (only,) = r.stderr.splitlines()
        assert only.startswith("error: bridge: ") and "B9" in only
    else:
        assert r.stderr.splitlines() == [line]


@pytest.mark.slow
def test_node_warns_in_one_line_and_runs_on(tmp_path):
    """A bridge node started with an implausible but allowed bridge (a damping typed as a fraction
    into the % key, docs/plausibility.md) prints the CLIs' one-line warning with its name, as its
    errors (``error: bridge: ...``), never Python's ``file:line: Category:`` + source line; and it runs on."""
    import time

    doc = (ROOT / "docs" / "plausibility.md").read_text().splitlines()
    cli_line = next(line for line in doc if line.startswith("warning: bridge spec.zeta_pct: 0.0185 %"))
    err = tmp_path / "bridge.err"
    with local_ros_env() as env, open(err, "w") as f:
        p = subprocess.Popen([sys.executable, "-m", "adm_sim.nodes.bridge_node", "--ros-args", "-p",
                              "bridge:=L=15,n0=8.26,mu=19042,zeta_pct=0.0185"], stdout=subprocess.DEVNULL, stderr=f,
                             env=env, cwd=ROOT)
        try:
            t_end = time.monotonic() + 60
            while "warning:" not in err.read_text() and time.monotonic() < t_end and p.poll() is None:
                time.sleep(0.1)
            time.sleep(0.5)
            assert p.poll() is None, err.read_text()  # a warning, not an error: the node runs on
        finally:
            p.send_signal(signal.SIGINT)
            p.wait(30)
    lines = err.read_text().splitlines()
    assert [line for line in lines if "warning" in line.lower()] == [
        "warning: bridge: " + cli_line.removeprefix("warning: ")], lines
    assert not any("PlausibilityWarning" in line or ".py:" in line for line in lines), lines


@pytest.mark.slow
def test_node_started_by_hand_with_malformed_params_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("train:\n  ros__parameters:\n    model: [\n")
    with local_ros_env() as env:
        r = subprocess.run([sys.executable, "-m", "adm_sim.nodes.train_node", "--ros-args", "--params-file", str(bad)],
                           capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2
    assert r.stderr.splitlines() == [f"error: train: --params-file '{bad}': not valid YAML at line 4, column 1 "
                                     "(expected the node content, but found '<stream end>')"]
