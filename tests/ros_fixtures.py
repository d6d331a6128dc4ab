"""Shared helpers of the ROS 2 tests: node processes on a private domain, an in-process driver.

Every test gets its own ``ROS_DOMAIN_ID`` (reserved with :func:`adm_sim.ros.env.local_ros_env`)
and shared-memory transport only; processes are started in their own process group and killed
with it, and the Fast DDS files of killed processes are removed.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import pytest

from adm_sim.ros.env import cleanup_shm, local_ros_env, shm_files_of

ROOT = Path(__file__).resolve().parents[1]


def ros_args(params):
    """``--ros-args -p k:=v ...`` for a dict of parameters."""
    out = ["--ros-args"]
    for k, v in params.items():
        if isinstance(v, bool):
            v = "true" if v else "false"
        elif isinstance(v, str):
            v = repr(v) if v == "" or "," in v or ":" in v else v
        out += ["-p", f"{k}:={v}"]
    return out


class NodeProcs:
    """Node processes of one test on one domain."""

    def __init__(self, env, tmp_path):
        self.env = env
        self.tmp = Path(tmp_path)
        self.procs = {}
        self.shm = {}

    def start(self, name, module, params=None, extra=()):
        out = open(self.tmp / f"{name}.out", "w")
        err = open(self.tmp / f"{name}.err", "w")
        cmd = [sys.executable, "-m", module] + ros_args(params or {}) + list(extra)
        p = subprocess.Popen(cmd, env=self.env, stdout=out, stderr=err, start_new_session=True, cwd=ROOT)
        self.procs[name] = p
        return p

    def note_shm(self):
        for p in self.procs.values():
            if p.poll() is None:
                self.shm[p.pid] = shm_files_of(p.pid)

    def stderr(self, name):
        return (self.tmp / f"{name}.err").read_text()

    def stdout(self, name):
        return (self.tmp / f"{name}.out").read_text()

    def kill(self, name, sig=signal.SIGKILL):
        p = self.procs[name]
        self.shm[p.pid] = shm_files_of(p.pid)
        os.killpg(p.pid, sig)
        p.wait(10)

    def stop_all(self):
        for p in self.procs.values():
            if p.poll() is None:
                try:
                    os.killpg(p.pid, signal.SIGTERM)
                except ProcessLookupError:
                    pass
        t_end = time.monotonic() + 5
        for p in self.procs.values():
            try:
                p.wait(max(0.1, t_end - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(5)
        cleanup_shm([p.pid for p in self.procs.values()], owned=self.shm or None)


#: Domain reservations are kept for the whole session: a process killed with SIGKILL stays in
#: Fast DDS discovery until its lease expires, so a domain id must not be handed to the next test.
_HELD = []


@pytest.fixture
def ros_domain():
    """A ROS_DOMAIN_ID no other test of this session used, and the environment for child processes."""
    env = local_ros_env()
    _HELD.append(env)
    env["OPENBLAS_NUM_THREADS"] = "1"
    env["PYTHONUNBUFFERED"] = "1"
    yield env


@pytest.fixture
def node_procs(ros_domain, tmp_path):
    procs = NodeProcs(ros_domain, tmp_path)
    yield procs
    procs.stop_all()


@contextmanager
def driver_node(domain_id, cls=None, **params):
    """A driver node in this process (isolated context), spun in a background thread."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from adm_sim.nodes.driver import RunDriver

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=int(domain_id))
    node = (cls or RunDriver)(context=ctx, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    stop = threading.Event()

    def spin():
        while not stop.is_set() and ctx.ok():
            ex.spin_once(timeout_sec=0.05)

    th = threading.Thread(target=spin, daemon=True)
    th.start()
    try:
        yield node
    finally:
        stop.set()
        th.join(5)
        node.close()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
