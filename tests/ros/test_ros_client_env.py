"""A client set up as docs/ros.md says sees a launch's graph and every sample of its run.

The launcher prints one ``export`` line; the client runs in a process whose environment is that
line on top of what any shell has (``HOME``, ``PATH``; rclpy needs a home for its log directory)
and nothing else (none of the test's own variables), and its code is the
minimal client of docs/ros.md ("Integrating a monitoring system") as it stands there. The client
opts into the flow control and the launcher waits for it (``--wait-clients 1``), so it must
receive every acceleration sample of the run: its count equals the bridge's own (the ``done``
record) and the recorder's (summary.json), with nothing lost.
"""

import json
import re
import shlex
import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

ROOT = Path(__file__).resolve().parents[2]


def docs_client():
    """The minimal client's code block of docs/ros.md."""
    text = (ROOT / "docs" / "ros.md").read_text()
    m = re.search(r'```python\n("""minimal_client\.py.*?)```', text, re.S)
    assert m, "docs/ros.md has no minimal_client.py block"
    return m.group(1)


def export_env(line):
    """The variables of a shell ``export A=1 B=2  # comment`` line."""
    words = shlex.split(line, comments=True)
    assert words[0] == "export", line
    return dict(w.split("=", 1) for w in words[1:])


@pytest.mark.slow
def test_docs_client_with_the_printed_environment_alone_gets_every_sample(tmp_path):
    client_py = tmp_path / "minimal_client.py"
    client_py.write_text(docs_client())
    out = tmp_path / "out"
    # the sweep's file, with a bounded wait for the client and the coarse steps of the other
    # co-simulation tests (4 per period of mode 3, one period of free vibration: 1,612 samples in
    # place of 3,302, still over three flow-control windows of counted messages; about 1 s of
    # CPU less): the client's view of the run, not the numbers' accuracy, is under test
    params = tmp_path / "params.yaml"
    sweep = (ROOT / "ros_ws" / "params" / "sweep_b1_mlm.yaml").read_text()
    anchor = "    monitor_speed_kmh: 263.0\n"
    assert sweep.count(anchor) == 1
    params.write_text(sweep.replace(anchor, anchor + "    steps_per_period: 4.0\n    free_vibration_periods: 1.0\n")
                      + "driver:\n  ros__parameters:\n    run_timeout_s: 120.0\n")
    launcher = subprocess.Popen(
        [sys.executable, str(ROOT / "launch_scripts" / "crossing.py"), "--speeds", "250:270:10", "--out", str(out),
         "--wait-clients", "1", "--params-file", str(params)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    client = None
    try:
        first = launcher.stdout.readline()
        assert first.startswith("ROS_DOMAIN_ID="), (first, launcher.stderr.read() if launcher.poll() else "")
        line = launcher.stdout.readline()
        env = export_env(line)
        assert sorted(env) == ["FASTDDS_BUILTIN_TRANSPORTS", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID"], line
        assert env["ROS_DOMAIN_ID"] == first.split()[0].split("=")[1]
        # exactly the documented environment: a shell's HOME and PATH, then the export line
        env = {"HOME": str(tmp_path), "PATH": "/usr/bin:/bin", **env}
        client = subprocess.Popen([sys.executable, str(client_py)], env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, cwd=tmp_path)
        rest, err = launcher.communicate(timeout=300)
        assert launcher.returncode == 0, err
        assert "clients opted in: /minimal_client" in rest, rest
        summary = json.loads((out / "summary.json").read_text())
        recorded = summary["samples"]["/adm/midspan/accel"]
        # the client prints its line 1 s after the done record; then it is stopped with Ctrl-C
        line = client.stdout.readline()
        client.send_signal(signal.SIGINT)
        client_out, client_err = client.communicate(timeout=60)
    finally:
        for p in (launcher, client):
            if p is not None and p.poll() is None:
                p.kill()
    m = re.fullmatch(r"run (\d+) \((\w+)\): (\d+) of (\d+) samples, (-?\d+) lost\n", line)
    assert m, (line, client_err)
    run_id, phase, got, sent, lost = m.groups()
    assert (int(run_id), phase) == (summary["run_id"], summary["phase"])
    assert int(sent) == recorded > 100  # the bridge's count of the run is the recorder's
    assert int(got) == int(sent) and int(lost) == 0, line
    assert client.returncode == 0 and "Traceback" not in client_err, client_err
