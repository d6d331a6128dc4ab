"""A signal that lands while the supervisor polls or waits on a process leaves that process
waitable.

``Popen.poll`` and ``Popen.wait`` take the process's wait lock before their ``try``; an interrupt
raised between the two leaves the lock taken, and every later ``wait`` of the process times out,
even after SIGKILL. A launcher signalled at that moment ended in a traceback (``TimeoutExpired``
from its stop), once in a fresh-clone suite. The supervisor polls and waits with SIGINT and
SIGTERM held, and raises the interrupt afterwards.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading

import pytest

from adm_sim.processes.supervisor import Supervisor

pytestmark = pytest.mark.slow  # every test here starts processes


class _SignalledInsidePoll:
    """A process whose ``poll`` takes a lock, receives SIGTERM, and only then releases the lock,
    as ``Popen._internal_poll`` does around its ``waitpid``."""

    def __init__(self, proc):
        self.proc, self.lock, self.signalled = proc, threading.Lock(), False
        self.pid = proc.pid

    def poll(self):
        if not self.lock.acquire(False):
            return None
        if not self.signalled:
            self.signalled = True
            os.kill(os.getpid(), signal.SIGTERM)  # its handler runs at this frame's next line
        x = 0
        for _ in range(1000):
            x += 1
        self.lock.release()
        return self.proc.poll()

    def wait(self, timeout=None):
        return self.proc.wait(timeout)

    @property
    def returncode(self):
        return self.proc.returncode


def test_sigterm_inside_a_poll_is_raised_after_it_with_the_lock_free(tmp_path):
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], start_new_session=True)
    try:
        sup = Supervisor(tmp_path, env={"ROS_DOMAIN_ID": "0"})
        fake = _SignalledInsidePoll(sleeper)
        sup.procs["node"] = fake
        with pytest.raises(KeyboardInterrupt):
            with sup:
                for _ in range(100):
                    sup.dead()
        assert fake.signalled
        assert fake.lock.acquire(False), "the interrupt was raised inside the poll: its lock is still taken"
        fake.lock.release()
        assert sleeper.poll() is not None  # stopped by the supervisor's exit (SIGTERM)
        assert signal.getsignal(signal.SIGTERM) is not None
    finally:
        if sleeper.poll() is None:
            sleeper.kill()
            sleeper.wait()
