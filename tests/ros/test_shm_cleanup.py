"""No Fast DDS shared-memory file is left in /dev/shm after SIGKILL of one of our processes.

``replay.py --republish`` and a supervised node are killed with SIGKILL mid-run; the files each
used (read here from /proc independently of the code under test) must be gone after the next
start (replay) and after the launcher's end (supervisor), while those of a live participant of
the same domain stay.
"""

import fcntl
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mcap")

from adm_sim.processes import dds_env  # noqa: E402
from adm_sim.processes.supervisor import Supervisor  # noqa: E402

pytestmark = pytest.mark.slow  # every test here starts processes

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
REPLAY = ROOT / "launch_scripts" / "replay.py"


@pytest.fixture(autouse=True)
def one_probe_at_a_time(tmp_path_factory):
    """The tests of this file one at a time across xdist workers: Fast DDS's port semaphores (e.g.
    ``sem.fastrtps_port7000_mutex``) are shared by participants of every domain, so a probe of a test
    running on the other worker can hold one at this test's clean and die before its check, which
    then sees a file that is stale but was rightly kept (seen in a fresh-clone suite under
    ``--dist worksteal``)."""
    lock = tmp_path_factory.getbasetemp().parent / "adm_sim_test_shm_cleanup.lock"  # shared by the workers
    with open(lock, "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        yield

_PROBE = """
import rclpy, sys, time
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node("shm_probe")
pub = node.create_publisher(Float64, "/probe", 10)
sub = node.create_subscription(Float64, "/probe", lambda m: None, 10)
for _ in range(20):
    pub.publish(Float64(data=1.0))
    rclpy.spin_once(node, timeout_sec=0.02)
print("ready", flush=True)
time.sleep(120)
"""


def _files_of(pid):
    """Fast DDS files (with their lock and mutex files) that ``pid`` maps or holds open, from /proc."""
    names = set()
    for line in Path(f"/proc/{pid}/maps").read_text().splitlines():
        parts = line.split(maxsplit=5)
        if len(parts) == 6 and parts[5].startswith("/dev/shm/fastrtps_"):
            names.add(parts[5][9:])
    for fd in os.scandir(f"/proc/{pid}/fd"):
        try:
            t = os.readlink(fd.path)
        except OSError:
            continue
        if t.startswith("/dev/shm/fastrtps_"):
            names.add(t[9:])
    out = set()
    for n in names:
        base = n.removesuffix("_el").removesuffix("_sl")
        out |= {base, f"{base}_el", f"{base}_sl", f"sem.{base}_mutex"}
    return {n for n in out if os.path.exists(f"/dev/shm/{n}")}


def _own_files(pid):
    """The Fast DDS files whose ``_el`` lock ``pid`` holds (its own segment and ports, per /proc/locks)."""
    inodes = set()
    with open("/proc/locks") as f:
        for line in f:
            parts = line.split()
            if "->" not in parts and len(parts) > 5 and parts[4] == str(pid):
                inodes.add(int(parts[5].rsplit(":", 1)[1]))
    return {e.name for e in os.scandir("/dev/shm") if e.name.startswith("fastrtps_") and e.inode() in inodes}


def _data_segments(names):
    """Of ``names``, the data segments (``fastrtps_`` and 16 hex digits): each one process's own, on its
    domain alone, unlike the port files every domain's participants share."""
    return {n for n in names if n.startswith("fastrtps_") and len(n) == 25}


def _data_segments_gone(names):
    """``names`` hold a data segment (:func:`_data_segments`), and none of them is left in /dev/shm."""
    segments = _data_segments(names)
    return bool(segments) and not any(os.path.exists(f"/dev/shm/{n}") for n in segments)


def _wait(pred, timeout=60.0, what="condition"):
    t_end = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < t_end, f"no {what} within {timeout} s"
        time.sleep(0.1)


def _stale(names):
    """Of ``names``, the files still in /dev/shm that no live process maps or holds."""
    live = set()
    for e in os.scandir("/proc"):
        if e.name.isdigit():
            try:
                live |= _files_of(int(e.name))
            except OSError:
                pass
    return {n for n in names if os.path.exists(f"/dev/shm/{n}") and n not in live}


def _forgotten(names, pid):
    """Of ``names``, the stale files (:func:`_stale`) a clean should have removed: every one but a port
    file that the ledger of the dead process ``pid`` notes for a later clean. A clean keeps, and notes, a
    file that a live process maps at that moment; the port files (``fastrtps_port<n>`` with their lock
    and mutex) are shared by the participants of every domain, so that process may be one of a test on
    another xdist worker, which can end between the clean and this check (seen under ``-n 3``): the file
    is then stale but noted, and the next clean removes it. A data segment is its domain's alone, so
    none of it is excused. Reading the ledger after :func:`_stale` keeps the check free of that race."""
    stale = _stale(names)
    noted = set()
    for ledger in dds_env.SHM_LEDGER_DIR.glob(f"{pid}-*.txt"):
        for base in ledger.read_text().split():
            if base.startswith("fastrtps_port"):
                noted |= {base, f"{base}_el", f"{base}_sl", f"sem.{base}_mutex"}
    return stale - noted


def test_sigkill_of_replay_republish_leaves_nothing_after_the_next_start(recording, tmp_path):
    with dds_env.local_ros_env() as env:
        live = subprocess.Popen([PY, "-c", _PROBE], env=env, stdout=subprocess.PIPE, text=True)
        victim = subprocess.Popen([PY, str(REPLAY), str(recording), "--republish", "--rate", "0.05"], env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            assert live.stdout.readline().strip() == "ready"
            _wait(lambda: any(n.startswith("fastrtps_port") for n in _files_of(victim.pid)) and
                  len(list(dds_env.SHM_LEDGER_DIR.glob(f"{victim.pid}-*.txt"))) == 1, what="replay participant")
            kept = _own_files(live.pid)
            # mid-run: the replay has found the live participant (it maps the live one's files)
            _wait(lambda: _files_of(victim.pid) & kept, what="replay mapping the live participant's files")
            theirs = _files_of(victim.pid)
            assert kept
            victim.send_signal(signal.SIGKILL)
            victim.wait(timeout=10)
            # its data segment is left behind (a live peer may still map it until it notices the death:
            # then it is not stale yet, and its note is kept for a later clean)
            assert any(os.path.exists(f"/dev/shm/{n}") for n in _data_segments(theirs))
            # the next start of a replay cleans what the killed one left
            # (no subscriber: no wait for one; the clean comes first, at the start)
            r = subprocess.run([PY, str(REPLAY), str(recording), "--republish", "--rate", "0", "--topics",
                                "/adm/midspan/accel", "--wait-subscribers", "0"], env=env, capture_output=True,
                               text=True, timeout=120)
            assert r.returncode == 0, r.stderr
            assert _forgotten(theirs, victim.pid) == set()
            assert all(os.path.exists(f"/dev/shm/{n}") for n in kept)   # the live participant's files stay
            assert _own_files(live.pid) >= kept
            # what stays noted of the killed process is what a live process still used at the clean: a
            # later clean removes it once unused, and keeps noting what is still used
            dds_env.clean_dead_shm()
            assert _forgotten(theirs, victim.pid) == set()
        finally:
            for p in (live, victim):
                if p.poll() is None:
                    p.kill()
                p.communicate(timeout=10)


def test_sigkill_of_a_supervised_node_is_cleaned_at_the_launcher_end(tmp_path):
    with Supervisor(tmp_path / "logs") as sup:
        p = sup.start_command("probe", [PY, "-c", _PROBE], capture=True)
        _wait(lambda: not sup.lines.empty(), what="probe ready")
        assert sup.lines.get() == ("probe", "ready")
        _wait(lambda: sup.dead() is None and len(list(dds_env.SHM_LEDGER_DIR.glob(f"{p.pid}-*.txt"))) == 1,
              what="ledger of the node")
        theirs = _files_of(p.pid)
        assert theirs
        sup.kill("probe", signal.SIGKILL)
        assert p.returncode == -signal.SIGKILL
        assert _stale(theirs)                    # SIGKILL leaves them ...
    assert _forgotten(theirs, p.pid) == set()    # ... the supervisor's end removes them
    # (its own data segment at least: the probe was alone on its domain, so nothing else mapped it)
    assert _data_segments_gone(theirs)
    # its note is closed, or keeps only what a live process still used at the clean (a port file of
    # its domain that a participant of a parallel test maps, seen once in a CI run), for a later clean
    dds_env.clean_dead_shm()
    assert _forgotten(theirs, p.pid) == set()


def test_clean_dead_shm_keeps_files_of_live_processes(tmp_path):
    with dds_env.local_ros_env() as env:
        p = subprocess.Popen([PY, "-c", _PROBE], env=env, stdout=subprocess.PIPE, text=True)
        try:
            assert p.stdout.readline().strip() == "ready"
            assert dds_env.record_shm([p.pid]) >= 2
            mine = _files_of(p.pid)
            dds_env.clean_dead_shm()             # alive: ledger and files kept
            assert all(os.path.exists(f"/dev/shm/{n}") for n in mine)
            assert len(list(dds_env.SHM_LEDGER_DIR.glob(f"{p.pid}-*.txt"))) == 1
        finally:
            p.kill()
            p.communicate(timeout=10)
        dds_env.clean_dead_shm()
        # dead: its data segment is gone and nothing stale is left. The effect is checked, not this call's
        # count of removed files: a launcher on another xdist worker cleans first thing at its start, and
        # can remove the probe's files between the kill and this call (seen under ``-n 3``: 0 removed here)
        assert _data_segments_gone(mine)
        assert _forgotten(mine, p.pid) == set()
