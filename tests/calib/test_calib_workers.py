"""Worker pools die with the command that started them (``adm_calib.workers``)."""

import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import psutil
import pytest

from adm_calib.workers import die_with_parent

pytestmark = pytest.mark.slow  # every test here starts processes


def _pool_children(proc):
    try:
        return proc.children(recursive=True)
    except psutil.NoSuchProcess:
        return []


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_table4_workers_end_when_the_command_is_killed(tmp_path):
    """``adm-calib table4 --jobs 2`` killed with SIGKILL while its pool computes: both workers are
    gone within 5 s (without the death signal they computed on for minutes)."""
    cmd = [sys.executable, "-m", "adm_calib.calib_commands", "table4", "--jobs", "2", "--out", str(tmp_path / "t4")]
    parent = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    # the ROS wheels' bootstrapper may re-execute python once: the command is the leaf that owns the pool
    p = psutil.Process(parent.pid)
    workers = []
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end and parent.poll() is None:
        kids = _pool_children(p)
        owners = [k for k in [p, *kids] if len(_pool_children(k)) >= 2]
        if owners:
            owner = owners[-1]
            workers = _pool_children(owner)
            break
        time.sleep(0.02)
    assert workers, "the pool's workers never appeared"
    for proc in [p, *p.children(recursive=True)]:
        if proc not in workers:
            os.kill(proc.pid, signal.SIGKILL)
    parent.wait(10)
    gone, alive = psutil.wait_procs(workers, timeout=5)
    for w in alive:
        w.kill()
    assert not alive, f"{len(alive)} pool worker(s) outlived the killed command"


def _parent_pid(_):
    return os.getppid()


def test_die_with_parent_keeps_a_worker_whose_parent_lives():
    """The initializer leaves a worker of a live parent running: the pool computes as before."""
    with ProcessPoolExecutor(max_workers=1, initializer=die_with_parent, initargs=(os.getpid(),)) as ex:
        assert list(ex.map(_parent_pid, range(3))) == [os.getpid()] * 3


def test_die_with_parent_exits_a_worker_whose_parent_is_gone():
    """A worker told of a parent that is not its parent (it died before the signal was armed) exits
    at once with status 1."""
    code = f"from adm_calib.workers import die_with_parent; die_with_parent({os.getpid()} + 999999); print('alive')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 1
    assert "alive" not in out.stdout
