"""Start, watch and stop the node processes of one launch (no ``launch``/``ros2`` CLI here).

Every node runs as ``python -m <module> --ros-args ...`` in its own process group, under an
environment of :func:`adm_sim.ros.env.local_ros_env` (shared memory only, a ROS_DOMAIN_ID of its
own). :class:`Supervisor` reports the first node that dies, stops all of them on exit, Ctrl-C or
SIGTERM (SIGINT first so the nodes finish their files, SIGKILL after a grace period) and removes
the Fast DDS shared-memory files of the processes it had to kill.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from adm_sim.ros.env import cleanup_shm, local_ros_env, shm_files_of

ROOT = Path(__file__).resolve().parents[1]
PARAMS_DIR = ROOT / "ros_ws" / "params"
#: Files a launch writes into its output folder.
OUTPUTS = ("run.mcap", "run.rrd", "summary.json")


def _default_signals():
    """In the child before exec: SIGINT/SIGTERM back to their defaults (not inherited as ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


class NodeDied(RuntimeError):
    """A supervised node exited before its job was done."""


def check_inputs(bridge=None, train=None, speeds=None, params_file=None):
    """Validate a launch's bridge, train, speeds and params file before any process starts.

    Raises :class:`adm_sim.errors.InputError` with the one-line reason.
    """
    from adm_sim.bridge import resolve_bridge
    from adm_sim.errors import InputError
    from adm_sim.sweep import parse_speeds
    from adm_sim.trains import load_train

    if bridge:
        resolve_bridge(bridge)
    if train:
        load_train(train)
    if speeds:
        parse_speeds(speeds)
    if params_file and not Path(params_file).is_file():
        raise InputError(f"--params-file: {params_file!r} does not exist")


def prepare_out(out, overwrite):
    """Create the output folder; an earlier run in it is kept unless ``overwrite`` (InputError)."""
    from adm_sim.errors import InputError

    out.mkdir(parents=True, exist_ok=True)
    old = [f for f in OUTPUTS if (out / f).exists()]
    if old and not overwrite:
        raise InputError(f"--out: {str(out)!r} holds an earlier run ({', '.join(old)}); "
                         f"choose another folder or pass --overwrite")
    for f in old:
        (out / f).unlink()


def run_graph(sup, params_file, bridge_params, train_params, driver, driver_module, driver_params, on_line):
    """Start the bridge, train and driver nodes and follow the driver until it exits.

    Every stdout line of the driver goes to ``on_line``. Raises :class:`NodeDied` naming the node
    when the bridge or the train dies, or when the driver fails.
    """
    t_start = time.monotonic()
    sup.start("bridge", "adm_sim.nodes.bridge_node", ros_args(params_file, bridge_params))
    sup.start("train", "adm_sim.nodes.train_node", ros_args(params_file, train_params))
    sup.start(driver, driver_module, ros_args(params_file, driver_params), capture=True)
    while True:
        try:
            _, line = sup.lines.get(timeout=0.2)
        except queue.Empty:
            line = None
        if line is not None:
            on_line(line)
        if time.monotonic() - t_start < 5:
            sup.note_shm()
        died = sup.dead(("bridge", "train"))
        if died:
            raise NodeDied(f"node '{died[0]}' died (exit status {died[1]}): {sup.log_tail(died[0])}")
        done = sup.dead((driver,))
        if done and sup.lines.empty():
            if done[1] != 0:
                raise NodeDied(f"node '{driver}' failed (exit status {done[1]}): {sup.log_tail(driver)}")
            return


def ros_args(params_file=None, params=None, log_level=None):
    """``--ros-args`` list: a params file first, then ``-p name:=value`` overrides."""
    out = ["--ros-args"]
    if params_file:
        out += ["--params-file", str(params_file)]
    for k, v in (params or {}).items():
        if isinstance(v, bool):
            v = "true" if v else "false"
        elif isinstance(v, str):  # quoted: '280' or 'true' stay strings, not YAML numbers/bools
            v = "'" + v.replace("'", "") + "'"
        out += ["-p", f"{k}:={v}"]
    if log_level:
        out += ["--log-level", log_level]
    return out


class Supervisor:
    """The processes of one launch.

    Parameters
    ----------
    log_dir : path
        Each node's stderr goes to ``<log_dir>/<name>.log``.
    domain_id : int or None
        ROS_DOMAIN_ID; ``None`` reserves a free one for the life of the supervisor.
    """

    def __init__(self, log_dir, domain_id=None):
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = local_ros_env(domain_id)
        self.env.setdefault("OPENBLAS_NUM_THREADS", "1")
        self.env["PYTHONUNBUFFERED"] = "1"
        self.procs = {}
        self.lines = queue.Queue()
        self._shm = {}
        self._old = {}

    @property
    def domain_id(self):
        return self.env.domain_id

    def start(self, name, module, args, capture=False):
        """Start ``python -m module args``; with ``capture`` its stdout lines go to :attr:`lines`."""
        err = open(self.log_dir / f"{name}.log", "w")
        cmd = [sys.executable, "-m", module] + list(args)
        p = subprocess.Popen(cmd, env=self.env, cwd=ROOT, start_new_session=True, stderr=err,
                             stdout=subprocess.PIPE if capture else err, text=True, bufsize=1,
                             preexec_fn=_default_signals)
        self.procs[name] = p
        if capture:
            def pump():
                for line in p.stdout:
                    self.lines.put((name, line.rstrip("\n")))
                self.lines.put((name, None))

            threading.Thread(target=pump, name=f"stdout-{name}", daemon=True).start()
        return p

    def note_shm(self):
        """Remember which Fast DDS files each live node maps (exact clean-up after a kill)."""
        for p in self.procs.values():
            if p.poll() is None:
                self._shm[p.pid] = shm_files_of(p.pid) | self._shm.get(p.pid, set())

    def dead(self, names=None):
        """``(name, returncode)`` of the first supervised process that has exited, or None."""
        for name, p in self.procs.items():
            if (names is None or name in names) and p.poll() is not None:
                return name, p.returncode
        return None

    def log_tail(self, name, n=5):
        try:
            lines = (self.log_dir / f"{name}.log").read_text().strip().splitlines()
        except OSError:
            return ""
        err = [ln for ln in lines if ln.startswith("error:")]
        return "\n".join((err or lines)[-n:])

    def stop(self, grace_s=5.0):
        """Stop every process (SIGTERM, then SIGKILL after ``grace_s``); clean their shm files.

        SIGTERM rather than SIGINT: a launcher started in the background of a non-interactive
        shell passes SIGINT on as ignored, and rclpy handles both the same way.
        """
        self.note_shm()
        live = [p for p in self.procs.values() if p.poll() is None]
        for p in live:
            try:
                os.killpg(p.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        t_end = time.monotonic() + grace_s
        killed = []
        for p in live:
            try:
                p.wait(max(0.05, t_end - time.monotonic()))
            except subprocess.TimeoutExpired:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                p.wait(5)
                killed.append(p.pid)
        dead_abnormally = [p.pid for p in self.procs.values() if p.returncode is not None and p.returncode < 0]
        cleanup_shm(set(killed) | set(dead_abnormally), owned=self._shm or None)
        self.env.release()

    # -- signals: SIGTERM behaves like Ctrl-C
    def __enter__(self):
        def on_term(signum, frame):
            raise KeyboardInterrupt

        self._old[signal.SIGTERM] = signal.signal(signal.SIGTERM, on_term)
        self._old[signal.SIGINT] = signal.signal(signal.SIGINT, signal.default_int_handler)
        return self

    def __exit__(self, *exc):
        try:
            self.stop()
        finally:
            for s, h in self._old.items():
                signal.signal(s, h)
