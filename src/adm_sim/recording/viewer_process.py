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
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from urllib.parse import urlparse

from adm_sim.errors import InputError, RunError

__all__ = [
    "analytics_config_path",
    "check_loopback",
    "check_viewer",
    "ensure_analytics_disabled",
    "close_watched",
    "exit_if_abandoned",
    "free_port",
    "handshake",
    "rerun_cli",
    "rerun_cli_env",
    "spawn_viewer",
    "stop_viewer",
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


#: Seconds a spawned viewer must stay alive after its first answer (:func:`spawn_viewer`): on a
#: machine without a display the rerun viewer listens and answers, then exits.
SPAWN_SETTLE_S = 1.5


def spawn_viewer(port: int | None = None, memory_limit: str = "25%", timeout_s: float = 20.0,
                 settle_s: float | None = None, what: str = "spawn") -> tuple[subprocess.Popen, str]:
    """Start a native rerun viewer bound to 127.0.0.1, check it; return the process and its proxy URL.

    ``rr.spawn`` cannot choose the bind address (the viewer would listen on 0.0.0.0), hence this.
    The viewer must listen within ``timeout_s``, answer the handshake of :func:`handshake` and be
    alive ``settle_s`` (default :data:`SPAWN_SETTLE_S`) later (on a machine without a display it
    listens, then exits at once);
    otherwise :class:`RunError`, one line with the viewer's own last word (its log goes to a
    temporary file). The viewer runs in its own session (it outlives this process); the
    process object is held until exit. Interrupted while it is checked (Ctrl-C, SIGTERM), the
    viewer is ended before the interrupt goes on; :func:`stop_viewer` ends one that the run it
    was spawned for no longer needs.
    """
    port = free_port() if port is None else int(port)
    url = f"rerun+http://127.0.0.1:{port}/proxy"
    log = tempfile.TemporaryFile(prefix="adm_sim_viewer_")
    proc = subprocess.Popen(
        [rerun_cli(), "--bind", "127.0.0.1", "--port", str(port),
         "--memory-limit", memory_limit],
        env=rerun_cli_env(dict(os.environ) | {"RERUN_APP_ONLY": "true"}),
        stdin=subprocess.DEVNULL, stdout=log, stderr=log, start_new_session=True,
    )

    def died(why: str) -> RunError:
        try:  # a viewer on its way out: let it end and say why
            proc.wait(1.0)
            why = "exited at once"
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.seek(0)
        lines = [re.sub(r"\x1b\[[0-9;]*m", "", ln).strip() for ln in log.read().decode(errors="replace").splitlines()]
        lines = [ln for ln in lines if ln] or ["no output"]
        last = ([ln for ln in lines if "error" in ln.lower()] or lines)[-1]
        last = last if len(last) <= 160 else "..." + last[-150:]
        log.close()
        return RunError(f"{what}: the rerun viewer {why} (exit status {proc.returncode}: {last}); is there a display?")

    try:
        t_end = time.monotonic() + timeout_s
        while not wait_for_port(port, 0.2):
            if proc.poll() is not None:
                raise died("exited at once")
            if time.monotonic() > t_end:
                raise died(f"did not listen on 127.0.0.1:{port} within {timeout_s:g} s")
        try:
            handshake(url, what=what)
        except RunError:
            raise died("does not answer") from None
        t_end = time.monotonic() + (SPAWN_SETTLE_S if settle_s is None else settle_s)
        while time.monotonic() < t_end:
            if proc.poll() is not None:
                raise died("exited at once")
            time.sleep(0.05)
    except BaseException:  # an interrupt while it is checked: the viewer is not left behind
        stop_viewer(proc)
        log.close()
        raise
    _VIEWERS.append(proc)
    return proc, url


def stop_viewer(proc: subprocess.Popen) -> None:
    """End a viewer of :func:`spawn_viewer` that was given nothing to show (the run it was started
    for was refused or interrupted before it began): killed, waited for, no longer held."""
    if proc.poll() is None:
        proc.kill()
        try:
            proc.wait(10.0)
        except subprocess.TimeoutExpired:  # a kill not yet delivered; the kernel ends it
            pass
    if proc in _VIEWERS:
        _VIEWERS.remove(proc)


# ---------------------------------------------------------------- handshake and watchdog

#: Seconds a viewer has to answer the handshake (:func:`handshake`).
HANDSHAKE_S = 5.0
#: While a recording is flushed to a viewer (:func:`close_watched`), the viewer is asked every
#: this many seconds whether it still answers.
WATCH_EVERY_S = 2.0
#: The longest a flush to a viewer that keeps answering may take.
CLOSE_LIMIT_S = 600.0
#: URLs of the viewers given up during this process (rerun's own flush at interpreter exit would
#: wait for them again: :func:`exit_if_abandoned`).
ABANDONED: list[str] = []


#: The HTTP/2 client connection preface and an empty SETTINGS frame (RFC 9113, 3.4 and 6.5).
_H2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + b"\x00\x00\x00\x04\x00\x00\x00\x00\x00"
_H2_SETTINGS = 0x04


def check_viewer(url: str, timeout_s: float = 5.0, what: str = "--connect") -> str:
    """Check that a rerun viewer answers at ``url`` (``rerun+http://127.0.0.1:PORT/proxy``) before
    anything is logged to it; raise :class:`~adm_sim.errors.RunError` (one line) otherwise.

    A rerun viewer serves gRPC, which is HTTP/2: on a new connection it answers the client's
    connection preface with its own SETTINGS frame. A closed port, a server of another protocol
    (a plain HTTP/1.1 server answers ``HTTP/1.1 400``) or a socket that accepts and never answers
    (within ``timeout_s``) is refused here, instead of a run that logs into nothing or hangs.
    """
    u = urlparse(url)
    host, port = u.hostname, u.port
    if host is None or port is None:
        raise RunError(f"{what}: {url!r} names no host and port")
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except TimeoutError:
        raise RunError(f"{what}: no viewer at {url} (no connection within {timeout_s:g} s)") from None
    except OSError as exc:
        raise RunError(f"{what}: no viewer at {url} ({exc.strerror or exc}); start one with 'rerun' "
                       f"or use --spawn") from None
    with sock:
        sock.settimeout(timeout_s)
        try:
            sock.sendall(_H2_PREFACE)
            head = b""
            while len(head) < 9:
                chunk = sock.recv(9 - len(head))
                if not chunk:
                    raise RunError(f"{what}: {url} is not a rerun viewer (it closed the connection "
                                   f"without an HTTP/2 answer)")
                head += chunk
        except TimeoutError:
            raise RunError(f"{what}: the viewer at {url} does not answer (no HTTP/2 answer within "
                           f"{timeout_s:g} s)") from None
        except OSError as exc:
            raise RunError(f"{what}: {url} is not a rerun viewer ({exc.strerror or exc})") from None
    if head[3] != _H2_SETTINGS or head[5:9] != b"\x00\x00\x00\x00":
        raise RunError(f"{what}: {url} is not a rerun viewer (it answered {head!r}, not an HTTP/2 "
                       f"SETTINGS frame)")
    return url


def handshake(url: str, what: str = "connect_url", timeout_s: float = HANDSHAKE_S) -> str:
    """``url`` if a rerun viewer answers there within ``timeout_s`` (the HTTP/2 preface of gRPC,
    :func:`check_viewer`); else :class:`RunError`, one line: a
    closed port, a server of another protocol, a socket that accepts and never answers."""
    return check_viewer(url, timeout_s=timeout_s, what=what)


def close_watched(close, url: str, what: str = "connect_url", every_s: float | None = None,
                  limit_s: float | None = None) -> bool:
    """Call ``close()`` (rerun's flush and disconnect, which waits for the viewer at ``url``) and
    return ``True`` when it returns; never hang on a viewer that stopped answering.

    ``close()`` runs in a helper thread. Every ``every_s`` while it runs the viewer is asked for a
    handshake: a viewer that does not answer any more (stopped, a silent peer) is given up at once,
    one ``warning:`` line on stderr, ``False``; so is one that answers but has not taken the
    recording after ``limit_s``. A viewer given up is kept in :data:`ABANDONED`.
    """
    every_s = WATCH_EVERY_S if every_s is None else float(every_s)
    limit_s = CLOSE_LIMIT_S if limit_s is None else float(limit_s)
    failed: list[BaseException] = []

    def work():
        try:
            close()
        except BaseException as exc:  # handed to the caller as it is
            failed.append(exc)

    th = threading.Thread(target=work, name="rerun-close", daemon=True)
    th.start()
    t_end = time.monotonic() + limit_s
    why = None
    while True:
        th.join(every_s)
        if not th.is_alive():
            break
        if time.monotonic() > t_end:
            why = f"took the recording for longer than {limit_s:g} s"
            break
        try:
            handshake(url, what=what, timeout_s=min(HANDSHAKE_S, every_s + 1.0))
        except RunError as exc:
            why = f"stopped answering ({str(exc).removeprefix(what + ': ')})"
            break
    if why is not None:
        ABANDONED.append(url)
        print(f"warning: {what}: the rerun viewer at {url} {why}; it was given up and may miss the end of "
              "the run", file=sys.stderr, flush=True)
        return False
    if failed:
        raise failed[0]
    return True


def exit_if_abandoned(code: int) -> None:
    """End the process now with ``code`` when a viewer was given up (:data:`ABANDONED`): rerun's
    flush at interpreter exit would wait for it again, and hang. Otherwise return."""
    if not ABANDONED:
        return
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


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
