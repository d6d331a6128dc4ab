"""Ctrl-C that lands while an executor builds its next wait set is a stop, not a crash.

rclpy's signal handler shuts the context down from another thread. When that happens between two
waits, the executor's next wait set fails with a ``RuntimeError`` of the invalid context ("failed to
initialize wait set: the given context is not valid"), not ``ExternalShutdownException``
(ros2/rclpy#398). A fresh-clone run of the suite met it once: the docs' minimal client, stopped with
Ctrl-C after it had counted every sample, exited 1 with that traceback.

Each test makes the race certain: a prelude replaces ``SingleThreadedExecutor.spin_once`` (what
``rclpy.spin`` turns) by one that shuts its context down, as the handler does, and raises that error.
Then the program under test runs as a user runs it, in its own process.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from ros_fixtures import ros_domain  # noqa: F401  (fixture)
from test_ros_client_env import docs_client

pytest.importorskip("rclpy")

ROOT = Path(__file__).resolve().parents[2]

RACE = (
    "import rclpy.executors\n"
    "def _race(self, *args, **kwargs):\n"
    "    self.context.shutdown()  # what rclpy's signal handler does, from its own thread\n"
    "    raise RuntimeError('failed to initialize wait set: the given context is not valid, either rcl_init() '\n"
    "                       'was not called or rcl_shutdown() was called.')\n"
    "rclpy.executors.SingleThreadedExecutor.spin_once = _race\n"
)


def _run(code, env, cwd):
    return subprocess.run([sys.executable, "-c", RACE + code], env=dict(env), cwd=cwd, capture_output=True,
                          text=True, timeout=120)


def _interrupted(script_name, argv, env, cwd):
    """``launch_scripts/<script_name> argv`` under the race: the interrupt's one line and exit 130."""
    script = ROOT / "launch_scripts" / script_name
    code = (f"import runpy, sys\nsys.argv = {[str(script), *argv]!r}\nsys.path.insert(0, {str(script.parent)!r})\n"
            f"runpy.run_path({str(script)!r}, run_name='__main__')\n")
    r = _run(code, env, cwd)
    assert r.returncode == 130, r.stderr
    assert re.fullmatch(r"error: interrupted[^\n]*\n", r.stderr), r.stderr


def test_stopped_by_signal_is_true_only_after_a_shutdown_or_an_interrupt(ros_domain):  # noqa: F811
    """The test the nodes apply to an executor's error: a bug while the context is up, the stop once it is
    shut down, and an error raised from a KeyboardInterrupt always the stop."""
    import rclpy

    from adm_sim.nodes.common import stopped_by_signal

    c = rclpy.context.Context()
    rclpy.init(context=c, domain_id=int(ros_domain.domain_id))
    race = RuntimeError("failed to initialize wait set: the given context is not valid")
    try:
        assert stopped_by_signal(race, c) is False
        try:
            raise ImportError("initialization failed") from KeyboardInterrupt()
        except ImportError as exc:
            assert stopped_by_signal(exc, c) is True
        c.shutdown()
        assert stopped_by_signal(race, c) is True
    finally:
        rclpy.try_shutdown(context=c)


@pytest.mark.slow
def test_docs_client_stops_cleanly_when_ctrl_c_races_the_wait_set(ros_domain, tmp_path):  # noqa: F811
    """The minimal client of docs/ros.md, as it stands there: exit 0, nothing on stderr (it failed with
    exit 1 and the traceback before the docs caught the race)."""
    r = _run(docs_client(), ros_domain, tmp_path)
    assert (r.returncode, r.stderr) == (0, ""), r.stderr


@pytest.mark.slow
def test_monitor_node_stops_cleanly(ros_domain, tmp_path):  # noqa: F811
    """``python -m adm_sim.nodes.monitor_node``: the same stop as Ctrl-C, exit 0, nothing on stderr (exit 1
    and the traceback before)."""
    code = "import sys\nfrom adm_sim.nodes.monitor_node import main\nsys.exit(main([]))\n"
    r = _run(code, ros_domain, tmp_path)
    assert (r.returncode, r.stderr) == (0, ""), r.stderr


@pytest.mark.slow
def test_live_monitor_command_reports_the_interrupt(ros_domain, tmp_path):  # noqa: F811
    """``launch_scripts/monitor.py`` live: the interrupt's one line and exit 130, as on any Ctrl-C."""
    _interrupted("monitor.py", ["--domain-id", str(ros_domain.domain_id), "--duration", "30"], ros_domain, tmp_path)


@pytest.mark.slow
def test_replay_republish_reports_the_interrupt(recording, ros_domain, tmp_path):  # noqa: F811
    """``launch_scripts/replay.py --republish`` waiting for a client: the interrupt's one line and exit 130."""
    _interrupted("replay.py", [str(recording), "--republish", "--rate", "0", "--wait-clients", "1", "--domain-id",
                               str(ros_domain.domain_id)], ros_domain, tmp_path)
