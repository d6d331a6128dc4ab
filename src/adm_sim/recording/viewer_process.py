"""The rerun processes beside a recording: the ``rerun`` executable, its analytics opt-out, a viewer
bound to the loopback, its ports, and the check that a viewer URL stays on this machine.

Nothing here imports rerun: these are child processes and sockets. The recording itself (sinks,
:class:`~adm_sim.recording.rerun_log.RunLogger`) is :mod:`adm_sim.recording.rerun_log`.

Privacy and network
-------------------
Rerun collects usage data by default. It reads its opt-out from its own config file
(``$XDG_CONFIG_HOME/rerun/analytics.json``, written by ``rerun analytics disable``) and skips
analytics whenever the environment variable ``CI`` is set; rerun 0.41 has no other switch (no
``RERUN_ANALYTICS`` variable, no SDK argument). :func:`~adm_sim.recording.rerun_log.init_rerun`
therefore calls :func:`ensure_analytics_disabled`, which runs ``rerun analytics disable`` (with
``CI=1`` so that this command records nothing itself) unless the config already says disabled. A
viewer spawned here is bound to 127.0.0.1 (``rr.spawn`` would bind 0.0.0.0), and a viewer URL must
be a loopback URL (:func:`check_loopback`).
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlparse

from adm_sim.errors import InputError, RunError

__all__ = [
    "analytics_config_path",
    "check_loopback",
    "ensure_analytics_disabled",
    "free_port",
    "rerun_cli",
    "rerun_cli_env",
    "spawn_viewer",
    "wait_for_port",
]

#: Host names a viewer URL may carry (besides any 127.x.y.z).
LOOPBACK_HOSTS = frozenset({"127.0.0.1", "localhost", "::1"})


# ---------------------------------------------------------------- the rerun CLI and its analytics


def rerun_cli() -> str:
    """Path of the ``rerun`` executable of this environment (the venv's ``bin/rerun``)."""
    here = Path(sys.executable).with_name("rerun")
    if here.is_file():
        return str(here)
    found = shutil.which("rerun")
    if found is None:
        raise RunError("rerun: no 'rerun' executable next to python or on PATH; "
                       "install rerun-sdk==0.41.0")
    return found


def rerun_cli_env(base: dict | None = None) -> dict:
    """Environment for a ``rerun`` CLI child process: ``CI=1`` (rerun skips analytics on CI)."""
    env = dict(os.environ if base is None else base)
    env.setdefault("CI", "1")
    return env


def analytics_config_path() -> Path:
    """Rerun's analytics config file (``directories::ProjectDirs`` on Linux)."""
    config_home = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(config_home) / "rerun" / "analytics.json"


def _analytics_disabled(path: Path) -> bool:
    try:
        return json.loads(path.read_text()).get("analytics_enabled") is False
    except (OSError, ValueError):
        return False


def ensure_analytics_disabled() -> Path:
    """Make rerun's usage analytics off for this user; return the config file.

    Runs ``rerun analytics disable`` once (idempotent: nothing is run when the config already
    says disabled). Raises :class:`RunError` if the config cannot be written.
    """
    path = analytics_config_path()
    if _analytics_disabled(path):
        return path
    subprocess.run([rerun_cli(), "analytics", "disable"], env=rerun_cli_env(),
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=60, check=False)
    if not _analytics_disabled(path):
        raise RunError(
            f"rerun analytics: could not disable usage analytics (config '{path}'); "
            "run 'rerun analytics disable' by hand"
        )
    return path


# ---------------------------------------------------------------- ports and the viewer process


def free_port() -> int:
    """A TCP port free on 127.0.0.1 at the time of the call."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for_port(port: int, timeout_s: float) -> bool:
    """Whether something listens on 127.0.0.1:``port`` within ``timeout_s`` seconds."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return True
        except OSError:
            time.sleep(0.1)
    return False


#: The spawned viewers, held until exit: a detached viewer outlives this process, and a collected
#: ``Popen`` of a running process warns ``ResourceWarning: subprocess ... is still running``.
_VIEWERS: list[subprocess.Popen] = []


def spawn_viewer(port: int | None = None, memory_limit: str = "25%",
                 timeout_s: float = 20.0) -> tuple[subprocess.Popen, str]:
    """Start a native rerun viewer bound to 127.0.0.1; return the process and its proxy URL.

    ``rr.spawn`` cannot choose the bind address (the viewer would listen on 0.0.0.0), hence this.
    The viewer runs in its own session (it outlives this process); the process object is held
    until exit.
    """
    port = free_port() if port is None else int(port)
    proc = subprocess.Popen(
        [rerun_cli(), "--bind", "127.0.0.1", "--port", str(port),
         "--memory-limit", memory_limit],
        env=rerun_cli_env(dict(os.environ) | {"RERUN_APP_ONLY": "true"}),
        stdin=subprocess.DEVNULL, start_new_session=True,
    )
    if not wait_for_port(port, timeout_s):
        proc.kill()
        proc.wait()
        raise RunError(f"spawn: the rerun viewer did not listen on 127.0.0.1:{port} "
                       f"within {timeout_s:g} s (is there a display?)")
    _VIEWERS.append(proc)
    return proc, f"rerun+http://127.0.0.1:{port}/proxy"


def check_loopback(url: str) -> str:
    """``url`` if it is a rerun URL on this machine; else :class:`InputError` naming it."""
    host = urlparse(url).hostname
    if urlparse(url).scheme not in ("rerun", "rerun+http", "rerun+https") or host is None:
        raise InputError(f"connect_url: {url!r} is not a rerun URL "
                         "(e.g. rerun+http://127.0.0.1:9876/proxy)")
    if host not in LOOPBACK_HOSTS and not host.startswith("127."):
        raise InputError(f"connect_url: host {host!r} is not on this machine; "
                         "allowed 127.0.0.0/8, localhost, ::1")
    return url
