"""A ``--spawn`` viewer is never left open by a run that does not start: a refused output folder
spawns none, a viewer that fails leaves no folder, an interrupt while the viewer is checked ends
it, and ``replay.py`` ends the viewer it spawned when the run is refused after it.

The viewer is a fake ``rerun`` (a small script put where :func:`adm_sim.recording.viewer_process.rerun_cli`
is looked up): it notes its pid, listens on the ``--port`` it is given and answers every connection
with the first words of a gRPC server (an empty HTTP/2 SETTINGS frame), or says ``Error: no
DISPLAY`` and exits 1. It gives up by itself after 120 s, so a failing test leaves nothing for long.
An answering fake never exits, so the time a spawned viewer must stay alive after its answer
(:data:`~adm_sim.recording.viewer_process.SPAWN_SETTLE_S`, 1.5 s) is 0.2 s here: the settle loop
runs, it only waits less for an exit that cannot come.
"""

from __future__ import annotations

import importlib
import os
import struct
import sys
import time
from pathlib import Path

import pytest

from adm_sim.errors import InputError, RunError
from adm_sim.recording import viewer_process as vp

pytestmark = pytest.mark.slow  # every test here starts processes

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "launch_scripts"

FAKE = r'''#!{python} -S
import os, socket, sys, time
with open({pids!r}, "a") as f:
    f.write(f"{{os.getpid()}}\n")
if {mode!r} == "no-display":
    print("Error: no DISPLAY", file=sys.stderr, flush=True)
    sys.exit(1)
port = int(sys.argv[sys.argv.index("--port") + 1])
srv = socket.socket()
srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
srv.bind(("127.0.0.1", port))
srv.listen(16)
srv.settimeout(0.5)
t_end = time.monotonic() + 120.0
while time.monotonic() < t_end:
    try:
        c, _ = srv.accept()
    except socket.timeout:
        continue
    with c:
        c.settimeout(2.0)
        try:
            c.recv(64)
            c.sendall(b"\x00\x00\x00\x04\x00\x00\x00\x00\x00")
        except OSError:
            pass
'''


def _alive(pid):
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


@pytest.fixture
def fake_viewer(tmp_path, monkeypatch):
    """``make(mode)`` puts a fake viewer in place (``"viewer"`` answers, ``"no-display"`` exits 1);
    ``pids()`` lists the pids of the fakes started. Whatever is left alive is killed at the end."""
    pid_file = tmp_path / "viewer_pids"

    def make(mode="viewer"):
        exe = tmp_path / f"rerun_{mode}"
        exe.write_text(FAKE.format(python=sys.executable, pids=str(pid_file), mode=mode))
        exe.chmod(0o755)
        monkeypatch.setattr(vp, "rerun_cli", lambda: str(exe))
        monkeypatch.setattr(vp, "SPAWN_SETTLE_S", 0.2)

    def pids():
        return [int(x) for x in pid_file.read_text().split()] if pid_file.exists() else []

    make.pids = pids
    yield make
    for pid in pids():
        if _alive(pid):
            os.kill(pid, 9)
    for proc in list(vp._VIEWERS):  # held until exit by spawn_viewer
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        vp._VIEWERS.remove(proc)


@pytest.fixture
def scripts():
    sys.path.insert(0, str(SCRIPTS))
    try:
        yield {name: importlib.import_module(name) for name in ("_supervisor", "replay")}
    finally:
        sys.path.remove(str(SCRIPTS))


def _launch_args(out, **kw):
    from types import SimpleNamespace

    base = dict(domain_id=None, spawn=True, connect=None, out=str(out), bridge=None, train=None, speeds=None,
                params_file=str(ROOT / "ros_ws" / "params" / "crossing_b3_300.yaml"), overwrite=False,
                wait_clients="0", namespace="/", max_work=None)
    return SimpleNamespace(**(base | kw))


def _tree(folder):
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*"))


def test_a_refused_folder_spawns_no_viewer(tmp_path, fake_viewer, scripts):
    """An earlier run in ``--out`` (no ``--overwrite``) is refused before the viewer is spawned:
    no viewer process at all, the folder as it was."""
    fake_viewer("viewer")
    out = tmp_path / "out"
    out.mkdir()
    (out / "run.mcap").write_bytes(b"earlier run")
    before = _tree(out)
    with pytest.raises(InputError, match=r"^--out: '.*' holds an earlier run \(run.mcap\); choose another folder "
                                         r"or pass --overwrite$"):
        scripts["_supervisor"].preflight(_launch_args(out), tmp_path / "default")
    assert fake_viewer.pids() == []  # never started (it was left running before the folder came first)
    assert _tree(out) == before and (out / "run.mcap").read_bytes() == b"earlier run"


def test_a_viewer_that_dies_leaves_no_folder(tmp_path, fake_viewer, scripts):
    """The folder is claimed before the viewer now: a viewer that exits at once is one line with its
    own last word, and the folder created for the run (and its lock) is gone again."""
    fake_viewer("no-display")
    out = tmp_path / "new" / "out"
    with pytest.raises(RunError, match=r"^--spawn: the rerun viewer exited at once \(exit status 1: Error: no "
                                       r"DISPLAY\); is there a display\?$"):
        scripts["_supervisor"].preflight(_launch_args(out), tmp_path / "default")
    (pid,) = fake_viewer.pids()
    assert not _alive(pid)
    assert not out.exists()
    from adm_sim.files import release_all

    release_all()  # the runner's end: the parents created for the folder go too
    assert _tree(tmp_path) == ["rerun_no-display", "viewer_pids"]


def test_a_spawned_viewer_is_handed_to_the_run(tmp_path, fake_viewer, scripts):
    """The viewer answers: the launch streams to it as to ``--connect``, in the folder it claimed."""
    fake_viewer("viewer")
    out = tmp_path / "out"
    args = _launch_args(out)
    sup = scripts["_supervisor"]
    got, env, created, old = sup.preflight(args, tmp_path / "default")
    try:
        (pid,) = fake_viewer.pids()
        assert _alive(pid)
        assert args.spawn is False and args.connect.startswith("rerun+http://127.0.0.1:")
        assert vp.handshake(args.connect) == args.connect
        assert got == out and created and old == set() and (out / ".launch.lock").exists()
    finally:
        sup.release_out(out)
        env.release()
        vp.stop_viewer(vp._VIEWERS[-1])
    assert not _alive(pid)


def test_an_interrupt_while_the_viewer_is_checked_ends_it(fake_viewer, monkeypatch):
    """Ctrl-C during the handshake: the viewer (its own session, so the terminal's SIGINT does not
    reach it) is ended, not left behind."""
    fake_viewer("viewer")

    def interrupted(url, what="", timeout_s=0.0):
        raise KeyboardInterrupt

    monkeypatch.setattr(vp, "handshake", interrupted)
    with pytest.raises(KeyboardInterrupt):
        vp.spawn_viewer(what="--spawn", timeout_s=60.0)
    (pid,) = fake_viewer.pids()
    assert not _alive(pid)
    assert vp._VIEWERS == []


def _tiny_mcap(path):
    """One ``std_msgs/msg/Float64`` on ``/x``: a recording ``replay.py`` accepts."""
    from mcap.writer import Writer

    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        sid = w.register_schema(name="std_msgs/msg/Float64", encoding="ros2msg", data=b"float64 data")
        cid = w.register_channel(topic="/x", message_encoding="cdr", schema_id=sid)
        w.add_message(channel_id=cid, log_time=1_000, publish_time=1_000,
                      data=b"\x00\x01\x00\x00" + struct.pack("<d", 1.5))
        w.finish()
    return path


def test_replay_ends_its_viewer_when_refused_after_the_spawn(tmp_path, fake_viewer, scripts, monkeypatch):
    """``replay.py --spawn --republish``: the viewer comes from
    :func:`~adm_sim.recording.viewer_process.spawn_viewer`; a refusal after it (no ROS domain id to
    be had) ends it, as nothing was shown in it yet."""
    pytest.importorskip("mcap")
    fake_viewer("viewer")
    replay = scripts["replay"]
    rec = _tiny_mcap(tmp_path / "in.mcap")

    def no_domain(domain_id=None):
        raise RunError("ROS_DOMAIN_ID: no free domain id in [1, 101]")

    monkeypatch.setattr(replay, "apply_local_ros_env", no_domain)
    args = replay.parse_args([str(rec), "--spawn", "--republish"])
    t0 = time.monotonic()
    with pytest.raises(RunError, match=r"^ROS_DOMAIN_ID: no free domain id"):
        replay._run(args)
    (pid,) = fake_viewer.pids()
    assert not _alive(pid)
    assert time.monotonic() - t0 < 60.0  # bounded (the viewer settles 0.2 s here)
