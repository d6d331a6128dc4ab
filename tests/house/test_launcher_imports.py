"""The launch scripts answer ``--help`` and refuse bad input without the heavy libraries of their work.

A launch script imports rerun (~0.9 s), rclpy (~0.2 s) and scipy.signal (~1.5 s) only on the path
that uses them: rerun when a replay draws (``--rrd``, ``--spawn``, ``--connect``), rclpy when it
republishes or a monitor subscribes live, scipy when a passage is analysed. Each case runs the
script's ``main(argv)`` in a fresh process (a forked child of tests/probe_server.py's server, which
imported the standard library and numpy only and none of these) and lists which of those modules
were imported; it also
runs a replay that republishes (refused at ``--topics`` after rclpy loaded, before any participant
is created) and one that draws, so the probe can fail both ways.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from probe_server import ProbeServer

pytestmark = pytest.mark.slow  # every test here starts a process

ROOT = Path(__file__).resolve().parents[2]
WATCHED = ("rerun", "rclpy", "scipy.signal", "scipy.optimize", "scipy.ndimage")

PROBE = """
import contextlib, importlib, io, json, sys
sys.path.insert(0, sys.argv[1])
m = importlib.import_module(sys.argv[2])
err = io.StringIO()
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
    try:
        rc = m.main(json.loads(sys.argv[3]))
    except SystemExit as exc:
        rc = exc.code
print(json.dumps({"rc": rc, "err": err.getvalue(), "loaded": [w for w in json.loads(sys.argv[4]) if w in sys.modules]}))
"""


_SERVER = ProbeServer(WATCHED, ROOT / "src")


@pytest.fixture(scope="module", autouse=True)
def _stop_probe_server():
    yield
    _SERVER.stop()


def run_probe(script, argv, cwd):
    """``(exit code, stderr, watched modules loaded)`` of ``launch_scripts/<script>.py``'s ``main(argv)``."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), FASTDDS_BUILTIN_TRANSPORTS="SHM",
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", RUST_LOG="off")
    p = _SERVER.probe(PROBE, str(ROOT / "launch_scripts"), script, json.dumps(argv), json.dumps(WATCHED), env=env,
                      cwd=cwd, timeout=300)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout.strip().splitlines()[-1])
    return out["rc"], out["err"], set(out["loaded"])


@pytest.fixture
def recording(tmp_path):
    """A small valid MCAP: 20 ``std_msgs/String`` on ``/adm/progress``."""
    from std_msgs.msg import String

    from adm_sim.recording.mcap_log import McapRecorder

    path = tmp_path / "run.mcap"
    with McapRecorder(path, chunk_size=1024) as rec:
        for k in range(20):
            rec.write("/adm/progress", String(data=f'{{"step": {k}}}'), k * 1_000_000)
    return path


@pytest.mark.parametrize("script, argv, code", [
    ("replay", ["--help"], 0),
    ("replay", ["{t}/missing.mcap", "--rrd", "{t}/o.rrd"], 2),
    ("replay", ["{rec}", "--republish", "--rate", "nan"], 2),
    ("monitor", ["--help"], 0),
    ("monitor", ["--mcap", "{t}/missing.mcap"], 2),
    ("crossing", ["--help"], 0),
])
def test_help_and_bad_input_load_none_of_the_heavy_libraries(tmp_path, recording, script, argv, code):
    argv = [a.format(t=tmp_path, rec=recording) for a in argv]
    rc, err, loaded = run_probe(script, argv, tmp_path)
    assert rc == code, err
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), lines
    assert loaded == set(), loaded


def test_a_replay_that_republishes_does_not_load_rerun(tmp_path, recording):
    """``--republish`` loads rclpy (the probe sees it) and never rerun."""
    rc, err, loaded = run_probe("replay", [str(recording), "--republish", "--topics", "/not/recorded"], tmp_path)
    assert rc == 2 and "error: --topics: none of ['/not/recorded'] is in" in err, err
    assert "rclpy" in loaded and "rerun" not in loaded, loaded


def test_a_replay_that_draws_loads_rerun_and_not_rclpy(tmp_path, recording):
    rc, err, loaded = run_probe("replay", [str(recording), "--rrd", str(tmp_path / "o.rrd")], tmp_path)
    assert rc == 0, err
    assert (tmp_path / "o.rrd").stat().st_size > 0
    assert "rerun" in loaded and "rclpy" not in loaded, loaded
