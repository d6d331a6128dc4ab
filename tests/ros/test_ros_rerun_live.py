"""A live rerun viewer on 127.0.0.1 receives a crossing streamed with ``--connect``.

The "viewer" is rerun's own headless receiver (``rerun --bind 127.0.0.1 --port P --save F``), which
writes whatever a connected SDK sends; its file must hold the default blueprint and the data of
its Runs and Speed sweep views.

The receiver is rerun's native binary, started directly (the venv's ``bin/rerun`` is a Python
wrapper that keeps its child on SIGKILL) with SIGINT at its default action: a test run in the
background of a non-interactive shell inherits SIGINT ignored, and the receiver then ignored the
SIGINT that ends it (20 s of waiting, then a native receiver left running).
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import rerun_cli
from rrd_views import check_recording, view_entities

from adm_sim.recording.viewer_process import free_port, wait_for_port
import pytest

pytestmark = pytest.mark.slow  # every test here starts processes

ROOT = Path(__file__).resolve().parents[2]
RECEIVER = Path(rerun_cli.__file__).with_name("rerun")


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def wait_until_written(path, timeout_s=10.0, still_s=0.3):
    """Wait (at most ``timeout_s``) until ``path`` exists and its size has not changed for ``still_s``:
    the receiver writes what the SDK flushed to it before the crossing exited."""
    t_end = time.monotonic() + timeout_s
    last, since = None, time.monotonic()
    while time.monotonic() < t_end:
        size = path.stat().st_size if path.exists() else None
        if size != last:
            last, since = size, time.monotonic()
        elif size and time.monotonic() - since >= still_s:
            return
        time.sleep(0.05)


#: The launch's default file (crossing_b3_300.yaml: B3 x ICE-2) with the coarse steps of the other
#: co-simulation tests (4 per period of mode 3, one period of free vibration): the stream to the
#: viewer and what its views hold are under test, not the numbers' accuracy (about 1 s of CPU less).
COARSE = "    steps_per_period: 4.0\n    free_vibration_periods: 1.0\n"


def test_crossing_streams_to_a_live_viewer(tmp_path):
    text = (ROOT / "ros_ws" / "params" / "crossing_b3_300.yaml").read_text()
    assert text.count("train:\n") == 1 and text.index("bridge:") < text.index("train:")
    params = tmp_path / "crossing_b3_300_coarse.yaml"
    params.write_text(text.replace("train:\n", COARSE + "train:\n"))  # the end of the bridge section
    port = free_port()
    recv = tmp_path / "received.rrd"
    env = dict(os.environ, CI="1")  # no analytics from the receiver
    viewer = subprocess.Popen([str(RECEIVER), "--bind", "127.0.0.1", "--port", str(port), "--save", str(recv)],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              preexec_fn=_default_sigint)
    try:
        assert wait_for_port(port, 20.0), "rerun receiver did not start"
        r = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "crossing.py"), "--model", "mlm",
                            "--speeds", "280", "--out", str(tmp_path / "run"), "--params-file", str(params),
                            "--connect", f"rerun+http://127.0.0.1:{port}/proxy"],
                           capture_output=True, text=True, timeout=180, cwd=ROOT)
        assert r.returncode == 0, r.stderr
        wait_until_written(recv)
    finally:
        viewer.send_signal(signal.SIGINT)
        try:
            viewer.wait(20)
        except subprocess.TimeoutExpired:
            viewer.kill()
            viewer.wait()
    ents, blue = check_recording(recv)  # blueprint, run_time from 0, units in titles
    assert "/runs/beam/run_01/deflection" in ents and "/runs/beam/run_01/peak_shape" in ents
    assert ents["/sweep/curves/MLM_zeta"]["times"]["speed_kmh"] == [280]
    for view in blue["views"]:
        if view["space_origin"].startswith(("runs", "sweep/curves")):
            assert view_entities(view, ents), view["display_name"]
