"""Shared helpers of the ROS 2 tests: node processes on a private domain, an in-process driver.

Every test gets its own ``ROS_DOMAIN_ID`` (reserved with :func:`adm_sim.processes.dds_env.local_ros_env`)
and shared-memory transport only; processes are started, stopped and cleaned up after by
:class:`adm_sim.processes.supervisor.Supervisor`, as in the launch scripts.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager
from pathlib import Path

import pytest

from adm_sim.processes.dds_env import local_ros_env
from adm_sim.processes.supervisor import Supervisor, ros_args

ROOT = Path(__file__).resolve().parents[1]


class NodeProcs(Supervisor):
    """Node processes of one test on one domain (the launch scripts' supervisor; parameters as a
    dict). Logs go to the test's ``tmp_path`` (``<name>.log`` stderr, ``<name>.out`` stdout)."""

    def __init__(self, env, tmp_path):
        super().__init__(tmp_path, env=env, cwd=ROOT)

    def start(self, name, module, params=None, extra=()):
        return super().start(name, module, ros_args(params=params or {}) + list(extra))

    def stop_all(self):
        self.stop()


#: Domain reservations are kept for the whole session: a process killed with SIGKILL stays in
#: Fast DDS discovery until its lease expires, so a domain id must not be handed to the next test.
_HELD = []


def held_domain():
    """A ROS_DOMAIN_ID no other test of this session used (held to the session's end), and the
    environment for child processes; for a fixture of wider scope than :func:`ros_domain`."""
    env = local_ros_env()
    _HELD.append(env)
    env["OPENBLAS_NUM_THREADS"] = "1"
    env["PYTHONUNBUFFERED"] = "1"
    return env


@pytest.fixture
def ros_domain():
    """A ROS_DOMAIN_ID no other test of this session used, and the environment for child processes."""
    yield held_domain()


@pytest.fixture
def node_procs(ros_domain, tmp_path):
    procs = NodeProcs(ros_domain, tmp_path)
    yield procs
    procs.stop_all()


@contextmanager
def driver_node(domain_id, cls=None, namespace=None, **params):
    """A driver node in this process (isolated context, in ``namespace`` if given), spun in a
    background thread."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from adm_sim.nodes.driver import RunDriver

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=int(domain_id))
    kw = {} if namespace is None else {"namespace": namespace}
    node = (cls or RunDriver)(context=ctx, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()], **kw)
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


@pytest.fixture
def ctx():
    """An isolated rclpy context for in-process nodes (no other process involved)."""
    import rclpy  # noqa: PLC0415  rclpy only for the ROS tests that use it

    c = rclpy.context.Context()
    rclpy.init(context=c, domain_id=0)
    yield c
    rclpy.try_shutdown(context=c)
