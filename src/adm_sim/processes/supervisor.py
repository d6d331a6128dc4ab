"""Start, watch and stop node processes (no ``launch`` and no ``ros2`` CLI in the PyPI wheels).

Used by the launch scripts and by the tests alike. Every node runs as
``python -m <module> --ros-args ...`` in its own process group, under an environment of
:func:`adm_sim.processes.dds_env.local_ros_env` (this machine only, a ROS_DOMAIN_ID of its own).
:class:`Supervisor` reports the first node that dies, stops all of them on exit, Ctrl-C or
SIGTERM (SIGTERM first so the nodes finish their files, SIGKILL after a grace period) and, when
a process had to be killed or died by a signal, removes the Fast DDS shared-memory files it left
(:func:`adm_sim.processes.dds_env.clean_dead_shm`: the files the supervisor noted while the node
lived, once no live process uses them; also at the next start).

Children die with their parent
-------------------------------
Every process started here is tied to the process that started it (:func:`child_setup`, run in
the child between ``fork`` and ``exec``): on Linux it asks the kernel with
``prctl(PR_SET_PDEATHSIG, SIGTERM)`` to send it SIGTERM the moment its parent ends, however the
parent ends (SIGKILL included, when nothing of the parent runs any more). SIGTERM and not SIGKILL:
a node ends on SIGTERM like on Ctrl-C, finishes its recording and lets Fast DDS remove its own
shared-memory files, so a killed launcher leaves neither processes nor ``/dev/shm/fastrtps_*``
files behind. The setting survives ``execve`` (it is only reset for set-user-ID binaries), so it
also covers the interpreter the ROS wheels' ``.pth`` bootstrapper re-executes in place
(``os.execve`` of the same pid with ``LD_LIBRARY_PATH`` set). A parent that died between
``fork`` and the ``prctl`` call is caught by comparing ``getppid()`` with the parent's pid.
The kernel signals on the death of the parent *thread*: start processes from the thread that
lives as long as the supervisor (the main thread of the launch scripts).

This module imports nothing from ROS.
"""

from __future__ import annotations

import ctypes
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from adm_sim.errors import AdmSimError, RunError
from adm_sim.interrupts import held, raise_interrupt
from adm_sim.processes.dds_env import clean_dead_shm, local_ros_env, record_shm

__all__ = ["NodeDied", "Supervisor", "child_setup", "ros_args"]


def _best_effort(fn, *args):
    """Shared-memory housekeeping never fails a run: stale files are also reclaimed at the next start."""
    try:
        return fn(*args)
    except (AdmSimError, OSError):
        return None


class NodeDied(RunError):
    """A supervised node exited before its job was done."""


def ros_args(params_file=None, params=None, log_level=None):
    """``--ros-args`` list: a params file first, then ``-p name:=value`` overrides.

    Strings are single-quoted so that ``'280'`` or ``'true'`` stay strings (not YAML numbers or
    booleans); booleans are written ``true``/``false``.
    """
    out = ["--ros-args"]
    if params_file:
        out += ["--params-file", str(params_file)]
    for k, v in (params or {}).items():
        if isinstance(v, bool):
            v = "true" if v else "false"
        elif isinstance(v, str):
            v = "'" + v.replace("'", "") + "'"
        out += ["-p", f"{k}:={v}"]
    if log_level:
        out += ["--log-level", log_level]
    return out


def _default_signals():
    """In the child before exec: SIGINT/SIGTERM back to their defaults (not inherited as ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


#: ``PR_SET_PDEATHSIG`` of <linux/prctl.h>.
_PR_SET_PDEATHSIG = 1
_PRCTL: list = []


def _prctl():
    """libc's ``prctl`` (looked up in the parent: no ``dlopen`` between fork and exec), or None
    off Linux."""
    if not _PRCTL:
        fn = None
        if sys.platform.startswith("linux"):
            try:
                fn = ctypes.CDLL(None, use_errno=True).prctl
                fn.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong]
                fn.restype = ctypes.c_int
            except (OSError, AttributeError):
                fn = None
        _PRCTL.append(fn)
    return _PRCTL[0]


def child_setup(parent_pid=None, sig=signal.SIGTERM):
    """The ``preexec_fn`` of every supervised process: default signal handlers and ``sig`` on the
    death of the parent (see the module docstring, "Children die with their parent").

    Returns a function to pass as ``preexec_fn``; call this in the parent (it resolves ``prctl``
    there and records the parent's pid).
    """
    prctl = _prctl()
    parent = os.getpid() if parent_pid is None else parent_pid

    def preexec():
        _default_signals()
        if prctl is not None:
            prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
            if os.getppid() != parent:  # the parent died before the prctl: nobody will signal us
                os.kill(os.getpid(), sig)

    return preexec


class Supervisor:
    """The node processes of one launch (or one test).

    Parameters
    ----------
    log_dir : path
        Each node's stderr goes to ``<log_dir>/<name>.log``, its stdout to ``<name>.out``
        (unless captured line by line, see :meth:`start`).
    domain_id : int or None
        ROS_DOMAIN_ID; ``None`` reserves a free one for the life of the supervisor.
    env : LocalRosEnv or None
        An environment of :func:`adm_sim.processes.dds_env.local_ros_env` to use instead (its
        reservation stays with the caller).
    cwd : path or None
        Working directory of the processes.
    """

    def __init__(self, log_dir, domain_id=None, env=None, cwd=None):
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self._own_env = env is None
        self.env = local_ros_env(domain_id) if env is None else env
        self.env.setdefault("OPENBLAS_NUM_THREADS", "1")
        self.env["PYTHONUNBUFFERED"] = "1"
        self.cwd = cwd
        self.procs = {}
        self.lines = queue.Queue()
        self._old = {}
        self._files = []
        self._noted = 0.0
        _best_effort(clean_dead_shm)  # what our processes killed earlier left

    @property
    def domain_id(self):
        return self.env.domain_id

    def start(self, name, module, args=(), capture=False):
        """Start ``python -m module args``; with ``capture`` its stdout lines go to :attr:`lines`
        as ``(name, line)`` (``(name, None)`` at its end)."""
        return self.start_command(name, [sys.executable, "-m", module] + list(args), capture)

    def start_command(self, name, cmd, capture=False):
        """Start the command line ``cmd`` (a list) as node ``name``; see :meth:`start`."""
        err = open(self.log_dir / f"{name}.log", "w")
        out = subprocess.PIPE if capture else open(self.log_dir / f"{name}.out", "w")
        self._files += [err] if capture else [err, out]
        p = subprocess.Popen(list(cmd), env=self.env, cwd=self.cwd, start_new_session=True, stderr=err, stdout=out,
                             text=True, bufsize=1, preexec_fn=child_setup())
        self.procs[name] = p
        if capture:
            def pump():
                for line in p.stdout:
                    self.lines.put((name, line.rstrip("\n")))
                self.lines.put((name, None))

            threading.Thread(target=pump, name=f"stdout-{name}", daemon=True).start()
        return p

    def stderr(self, name):
        """Everything node ``name`` wrote to stderr so far."""
        return (self.log_dir / f"{name}.log").read_text()

    def stdout(self, name):
        """Everything node ``name`` wrote to stdout so far (not captured)."""
        return (self.log_dir / f"{name}.out").read_text()

    def dead(self, names=None):
        """``(name, returncode)`` of the first supervised process that has exited, or None.

        Polled with SIGINT and SIGTERM held (:func:`adm_sim.interrupts.held`; one that comes is
        raised at the end): ``Popen.poll`` takes a lock before its ``try``, and an interrupt raised
        between the two leaves it taken, after which every ``wait`` of that process times out,
        even once the process is gone (seen as a launcher's traceback on SIGTERM)."""
        with held():
            self._note_shm()
            for name, p in self.procs.items():
                if (names is None or name in names) and p.poll() is not None:
                    return name, p.returncode
        return None

    def _note_shm(self, every_s=0.5):
        """Note the Fast DDS files the live nodes use (:func:`record_shm`), at most every ``every_s``."""
        now = time.monotonic()
        if now - self._noted >= every_s:
            self._noted = now
            _best_effort(record_shm, [p.pid for p in self.procs.values() if p.poll() is None])

    def log_tail(self, name, n=5):
        """The ``error:`` lines of a node's stderr (else its last ``n`` lines)."""
        try:
            lines = self.stderr(name).strip().splitlines()
        except OSError:
            return ""
        err = [ln for ln in lines if ln.startswith("error:")]
        return "\n".join((err or lines)[-n:])

    def kill(self, name, sig=signal.SIGKILL):
        """Send ``sig`` to the process group of node ``name`` and wait for it."""
        p = self.procs[name]
        os.killpg(p.pid, sig)
        with held():
            p.wait(10)

    def stop(self, grace_s=5.0):
        """Stop every process (SIGTERM, then SIGKILL after ``grace_s``); clean shared memory.

        SIGTERM rather than SIGINT: a launcher started in the background of a non-interactive
        shell passes SIGINT on as ignored, and rclpy handles both the same way. SIGINT and SIGTERM
        are held meanwhile (one that comes is raised once every process is stopped): the stop is
        bounded (``grace_s`` + 5 s a process), and an interrupt inside ``Popen.wait`` could leave
        the process's wait lock taken (see :meth:`dead`).
        """
        with held():
            self._stop(grace_s)

    def _stop(self, grace_s):
        self._note_shm(every_s=0.0)
        live = [p for p in self.procs.values() if p.poll() is None]
        for p in live:
            try:
                os.killpg(p.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        t_end = time.monotonic() + grace_s
        for p in live:
            try:
                p.wait(max(0.05, t_end - time.monotonic()))
            except subprocess.TimeoutExpired:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                p.wait(5)
        for f in self._files:
            f.close()
        self._files = []
        _best_effort(clean_dead_shm)  # what a node killed by a signal left
        if self._own_env:
            self.env.release()

    # -- signals: SIGTERM behaves like Ctrl-C
    def __enter__(self):
        # KeyboardInterrupt for both, as in a command (adm_sim.interrupts.raise_interrupt): held
        # where the supervisor polls and waits on its processes
        self._old[signal.SIGTERM] = signal.signal(signal.SIGTERM, raise_interrupt)
        self._old[signal.SIGINT] = signal.signal(signal.SIGINT, raise_interrupt)
        return self

    def __exit__(self, *exc):
        try:
            self.stop()
        finally:
            for s, h in self._old.items():
                signal.signal(s, h)
