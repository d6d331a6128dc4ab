"""A live viewer has a handshake and a deadline: one that is not there is one line before the run,
one that stops answering at the end of a run is one warning, never a hang (loopback peers only)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from adm_sim.errors import RunError
from adm_sim.recording import viewer_process as vp

ROOT = Path(__file__).resolve().parents[2]
SETTINGS = b"\x00\x00\x00\x04\x00\x00\x00\x00\x00"  # an empty HTTP/2 SETTINGS frame: a gRPC server's first words


def _peer(answers):
    """A loopback server whose k-th connection gets ``answers[k]`` (None: accepted and never
    answered; past the list: never answered). Returns (port, server socket)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(16)
    held = []

    def run():
        k = 0
        while True:
            try:
                c, _ = srv.accept()
            except OSError:
                return
            held.append(c)
            reply = answers[k] if k < len(answers) else None
            k += 1
            if reply is not None:
                c.sendall(reply)

    threading.Thread(target=run, daemon=True).start()
    return srv.getsockname()[1], srv


def test_handshake_refuses_what_is_not_a_viewer():
    port, srv = _peer([])  # accepts, never speaks
    with srv:
        t0 = time.monotonic()
        with pytest.raises(RunError, match=rf"^--connect: the viewer at rerun\+http://127.0.0.1:{port}/proxy does "
                                           r"not answer \(no HTTP/2 answer within 0.25 s\)$"):
            vp.handshake(f"rerun+http://127.0.0.1:{port}/proxy", what="--connect", timeout_s=0.25)
        assert time.monotonic() - t0 < 30.0  # bounded (0.25 s asked; generous for a loaded machine)
    port, srv = _peer([b"HTTP/1.1 400 Bad Request\r\n\r\n"])
    with srv, pytest.raises(RunError, match=r"is not a rerun viewer \(it answered b'HTTP/1.1 '"):
        vp.handshake(f"rerun+http://127.0.0.1:{port}/proxy")
    port, srv = _peer([SETTINGS])
    with srv:
        assert vp.handshake(f"rerun+http://127.0.0.1:{port}/proxy") == f"rerun+http://127.0.0.1:{port}/proxy"


def test_init_rerun_refuses_a_closed_port():
    from adm_sim.recording.rerun_log import init_rerun

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    with pytest.raises(RunError, match=rf"^connect_url: no viewer at rerun\+http://127.0.0.1:{port}/proxy "
                                       r"\(Connection refused\)"):
        init_rerun("adm_sim_test", connect_url=f"rerun+http://127.0.0.1:{port}/proxy")


@pytest.mark.slow
@pytest.mark.skipif(bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")),
                    reason="a display is there: the viewer would start")
def test_spawn_without_display_is_one_line():
    with pytest.raises(RunError, match=r"^spawn: the rerun viewer exited at once \(exit status \d+: .*\); is there "
                                       r"a display\?$"):
        vp.spawn_viewer(timeout_s=30.0)


_CLOSE = """
import sys, time
from adm_sim.recording import rerun_log as rl, viewer_process as vp
import rerun as rr
vp.WATCH_EVERY_S = float(sys.argv[3])  # the watch's period (2 s in a run)
rl.init_rerun("adm_sim_test", connect_url=sys.argv[1])
for i in range(500):
    rr.set_time("sim_time", duration=i * 0.01)
    rr.log("a", rr.Scalars(float(i)))
t0 = time.monotonic()
ok = rl.close_rerun(watch_viewer=(sys.argv[2] == "watch"))
print(f"closed ok={ok} in {time.monotonic() - t0:.1f} s", flush=True)
vp.exit_if_abandoned(0)
"""


@pytest.mark.slow
def test_viewer_that_stops_answering_is_given_up(tmp_path):
    """The peer answers the handshake before the run (a viewer), then never again (stopped): the
    flush at the end of the run (``rr.disconnect``, which waits for the viewer for ever) is given
    up after the next handshake fails, one ``warning:`` line, exit 0, no hang. The viewer is asked
    every 0.3 s here (``WATCH_EVERY_S``, 2 s in a run: the peer never answers again, so only the
    wait for its silence is shorter), its handshake then allowed 1.3 s (``every_s + 1``)."""
    port, srv = _peer([SETTINGS])
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), CI="1")
    with srv:
        r = subprocess.run([sys.executable, "-c", _CLOSE, f"rerun+http://127.0.0.1:{port}/proxy", "watch", "0.3"],
                           capture_output=True, text=True, timeout=120, env=env)
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode == 0, r.stderr
    assert "closed ok=False" in r.stdout, r.stdout
    warn = [ln for ln in r.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warn) == 1, r.stderr
    assert warn[0].startswith(f"warning: connect_url: the rerun viewer at rerun+http://127.0.0.1:{port}/proxy stopped "
                              "answering (the viewer at"), warn[0]
    assert "does not answer (no HTTP/2 answer within 1.3 s)" in warn[0] and warn[0].endswith("it was given up and may miss the end of the run")
