"""``replay.py --connect/--spawn`` check the viewer before the run and never hang on it.

Loopback peers only: a closed port, a plain HTTP server, a socket that accepts and never answers,
a spawned viewer that exits at once (no display), a real rerun gRPC server (``rr.serve_grpc`` in a
child process), and that server stopped with SIGSTOP mid-run.
"""

import http.server
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("rerun")
pytest.importorskip("mcap")

from adm_sim.errors import RunError  # noqa: E402
from adm_sim.recording.viewer_feed import check_viewer  # noqa: E402

pytestmark = pytest.mark.slow  # every test here starts processes

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
REPLAY = ROOT / "launch_scripts" / "replay.py"
SERVER = """
import sys, time
import rerun as rr
rr.init("viewer_stub")
print(rr.serve_grpc(grpc_port=int(sys.argv[1])), flush=True)
time.sleep(300)
"""


def _port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def http_server():
    srv = http.server.HTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    srv.RequestHandlerClass.log_message = lambda *a: None
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    yield f"rerun+http://127.0.0.1:{srv.server_port}/proxy"
    srv.shutdown()


@pytest.fixture
def silent_socket():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen()
    yield f"rerun+http://127.0.0.1:{s.getsockname()[1]}/proxy"
    s.close()


@pytest.fixture
def rerun_server():
    port = _port()
    p = subprocess.Popen([PY, "-c", SERVER, str(port)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                         text=True, env=dict(os.environ, RUST_LOG="off"))
    try:
        url = p.stdout.readline().strip()
        assert url == f"rerun+http://127.0.0.1:{port}/proxy"
        yield p, url
    finally:
        p.send_signal(signal.SIGCONT)
        p.kill()
        p.wait(timeout=10)


def _replay(recording, *args, timeout=120):
    t0 = time.monotonic()
    r = subprocess.run([PY, str(REPLAY), str(recording), *args], capture_output=True, text=True, timeout=timeout,
                       env=dict(os.environ, RUST_LOG="off"))
    return r, time.monotonic() - t0


def test_check_viewer_against_every_peer(http_server, silent_socket, rerun_server):
    _, url = rerun_server
    assert check_viewer(url) == url
    with pytest.raises(RunError, match=r"^--connect: no viewer at rerun\+http://127.0.0.1:1/proxy \(Connection refused\)"):
        check_viewer("rerun+http://127.0.0.1:1/proxy")
    with pytest.raises(RunError, match=r"is not a rerun viewer \(it answered b'"):
        check_viewer(http_server)
    t0 = time.monotonic()
    with pytest.raises(RunError, match=r"does not answer \(no HTTP/2 answer within 0.3 s\)"):
        check_viewer(silent_socket, timeout_s=0.3)
    assert 0.25 < time.monotonic() - t0 < 5.0


def test_replay_refuses_a_viewer_that_is_not_there(recording, http_server):
    """Two replays at once (each its own process and peer): a closed port and a server that is not a
    rerun viewer, each refused with its one line, exit 1, nothing on stdout. A silent peer goes
    through the same check (``viewer_process.check_viewer``, called by ``replay.py --connect`` before
    anything is read) with nothing specific to the replay: its refusal is tested in
    :func:`test_check_viewer_against_every_peer` (0.3 s) and, with a launcher's shipped 5 s, in
    tests/inputs/test_hostile_inputs.py (``viewer:crossing-connect-silent-server``); waiting those
    5 s out here as well would idle a test worker for nothing new."""
    cases = (("rerun+http://127.0.0.1:1/proxy", "no viewer at"), (http_server, "is not a rerun viewer"))
    procs = [subprocess.Popen([PY, str(REPLAY), str(recording), "--connect", url], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, env=dict(os.environ, RUST_LOG="off"))
             for url, _why in cases]
    try:
        results = [p.communicate(timeout=120) for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    for (url, why), p, (out, err) in zip(cases, procs, results, strict=True):
        assert p.returncode == 1, (url, err)
        assert err.splitlines() == [err.strip()] and why in err and err.startswith("error: --connect: ")
        assert out == ""


@pytest.mark.skipif(bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")), reason="a display is there")
def test_spawn_without_display_is_an_error(recording):
    r, took = _replay(recording, "--spawn")
    assert r.returncode == 1
    (line,) = r.stderr.splitlines()
    assert line.startswith("error: --spawn: the rerun viewer exited at once (exit status 1: ") and "DISPLAY" in line
    assert r.stdout == "" and took < 60


def test_replay_to_a_real_viewer_logs_every_message(recording, rerun_server):
    _, url = rerun_server
    r, _ = _replay(recording, "--connect", url)
    assert r.returncode == 0 and r.stderr == ""
    # every message of the recording, counted by the independent reader
    from adm_sim.recording.mcap_log import read_messages

    msgs = [topic for topic, _, _ in read_messages(recording)]
    assert r.stdout.strip() == f"logged {len(msgs)} messages on {len(set(msgs))} topics to {url}"
