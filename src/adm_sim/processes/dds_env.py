"""Keep every ROS 2 run on this machine and apart from every other run.

* :func:`local_ros_env` returns an environment for a run (or its child processes) with
  ``FASTDDS_BUILTIN_TRANSPORTS=SHM``, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (with it,
  rmw_fastrtps configures its own transports: shared memory and UDPv4, discovery announced to
  127.0.0.1 only, no multicast; data between processes of this machine over shared memory) and a
  ``ROS_DOMAIN_ID``: the one asked for, else an
  exported ``ROS_DOMAIN_ID``, else a free id in ``[1, 101]`` reserved with an exclusive
  ``fcntl.flock`` on a lock file under ``/tmp/adm_sim_ros_domains/``; the lock is released when
  the run closes it or dies, so concurrent runs never share an id and a killed run never leaks
  one. Ids up to 232 are accepted with shared memory only; with a UDP transport 101 is the
  largest id whose ports stay valid.
* :func:`client_export_line` is the one ``export`` line a ROS 2 client in another shell needs to
  see a run's graph (the transport, the discovery range and the domain id of the run): every
  launcher prints it.
* :func:`cleanup_shm` runs Fast DDS's own ``fastdds shm clean``, which removes the shared-memory
  files (``/dev/shm/fastrtps_*``) of participants that died without cleaning up (a SIGKILL) and
  never those of a live one.

This module imports nothing from ROS, so launchers can prepare the environment before rclpy loads.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shlex
import shutil
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

from adm_sim.errors import InputError, RunError
from adm_sim.fields import FIELDS

__all__ = [
    "DOMAIN_ID_MAX",
    "DOMAIN_ID_MAX_UDP",
    "DomainLock",
    "LocalRosEnv",
    "CLIENT_VARIABLES",
    "cleanup_shm",
    "client_export_line",
    "fastdds_tool",
    "local_ros_env",
]

#: Largest ROS_DOMAIN_ID (the field registry's, adm_sim.fields): 232 with shared memory only (the
#: id only names the shared-memory segments and ports) ...
DOMAIN_ID_MAX = FIELDS["domain_id"].hi
#: ... and 101 with a UDP transport, whose ports 7400 + 250 id + ... must stay below 32768 on Linux
#: (ROS 2 docs, "The ROS_DOMAIN_ID"). Automatically reserved ids are taken from [1, 101].
DOMAIN_ID_MAX_UDP = 101
LOCK_DIR = Path("/tmp/adm_sim_ros_domains")


class DomainLock:
    """Exclusive reservation of one ROS_DOMAIN_ID, held while this object is open.

    Parameters
    ----------
    domain_id : int
        The reserved id.
    fd : int
        Open descriptor of the lock file holding the ``flock``.
    path : pathlib.Path
        The lock file.
    """

    def __init__(self, domain_id: int, fd: int, path: Path):
        self.domain_id = domain_id
        self.path = path
        self._fd: int | None = fd

    @property
    def held(self) -> bool:
        return self._fd is not None

    def release(self) -> None:
        """Release the reservation (idempotent)."""
        if self._fd is not None:
            try:
                fcntl.flock(self._fd, fcntl.LOCK_UN)
            finally:
                os.close(self._fd)
                self._fd = None

    def __enter__(self) -> DomainLock:
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __del__(self) -> None:  # a lost reference must not keep the id forever
        try:
            self.release()
        except Exception:
            pass

    def __repr__(self) -> str:
        state = "held" if self.held else "released"
        return f"DomainLock(domain_id={self.domain_id}, {state}, path='{self.path}')"


class LocalRosEnv(dict):
    """Environment mapping for a local ROS 2 run (a plain ``dict`` for ``subprocess``).

    Attributes
    ----------
    domain_id : int
        The ``ROS_DOMAIN_ID`` of the run.
    lock : DomainLock or None
        The reservation of an automatically chosen id; keep this object (or the lock) alive as
        long as the run. ``None`` when the caller chose the id.
    """

    domain_id: int
    lock: DomainLock | None

    def release(self) -> None:
        """Release the domain-id reservation, if any (idempotent)."""
        if self.lock is not None:
            self.lock.release()

    def __enter__(self) -> LocalRosEnv:
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _try_lock(domain_id: int) -> DomainLock | None:
    LOCK_DIR.mkdir(mode=0o777, parents=True, exist_ok=True)
    path = LOCK_DIR / f"domain_{domain_id:03d}.lock"
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    try:  # the pid names the holder; the flock is the reservation (a full disk does not undo it)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
    except OSError:
        pass
    return DomainLock(domain_id, fd, path)


def reserve_domain_id() -> DomainLock:
    """Reserve a free ROS_DOMAIN_ID in ``[1, DOMAIN_ID_MAX_UDP]`` (0, the ROS default, is left
    alone; ids valid with any transport), the least recently used first.

    Raises
    ------
    InputError
        When all 101 ids are held by other runs.
    """
    n = DOMAIN_ID_MAX_UDP
    start = os.getpid() % n  # spread concurrent starters over the range

    def last_used(domain_id):
        try:
            return (LOCK_DIR / f"domain_{domain_id:03d}.lock").stat().st_mtime
        except OSError:
            return 0.0

    # Least recently used first: a run killed with SIGKILL stays visible to DDS discovery until
    # its lease expires, so its id should not be handed to the next run straight away.
    order = sorted((1 + (start + k) % n for k in range(n)), key=last_used)
    for domain_id in order:
        lock = _try_lock(domain_id)
        if lock is not None:
            return lock
    raise InputError(
        f"ROS_DOMAIN_ID: all ids in [1, {DOMAIN_ID_MAX_UDP}] are reserved by other runs "
        f"(lock files in {LOCK_DIR}); wait for a run to end or pass an explicit id"
    )


def _shm_only(env: Mapping[str, str]) -> bool:
    return env.get("FASTDDS_BUILTIN_TRANSPORTS", "SHM").strip().upper() == "SHM"


def check_domain_id(domain_id, env: Mapping[str, str], source: str = "ROS_DOMAIN_ID") -> int:
    """``domain_id`` (an int, or the text of an exported variable) checked against the range of
    the transport ``env`` selects: ``[0, 232]`` with ``FASTDDS_BUILTIN_TRANSPORTS=SHM`` (the
    default this module sets), ``[0, 101]`` otherwise; :class:`InputError` naming ``source``."""
    shm = _shm_only(env)
    hi = DOMAIN_ID_MAX if shm else DOMAIN_ID_MAX_UDP
    allowed = (f"allowed [0, {hi}]" if shm else
               f"allowed [0, {hi}] with FASTDDS_BUILTIN_TRANSPORTS={env.get('FASTDDS_BUILTIN_TRANSPORTS')} "
               f"(up to {DOMAIN_ID_MAX} with FASTDDS_BUILTIN_TRANSPORTS=SHM)")
    value = domain_id
    if isinstance(value, str):
        try:
            value = int(value.strip())
        except ValueError:
            raise InputError(f"{source}: {domain_id!r} is not an integer; {allowed}") from None
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError(f"{source}: {domain_id!r} is not an integer; {allowed}")
    if not 0 <= value <= hi:
        raise InputError(f"{source}: {value} is out of range; {allowed}")
    return value


def local_ros_env(domain_id: int | None = None, base: dict | None = None) -> LocalRosEnv:
    """Environment for a ROS 2 run that talks to this machine only and to no other run.

    Parameters
    ----------
    domain_id : int or None
        ``ROS_DOMAIN_ID`` in ``[0, 232]`` (``[0, 101]`` when ``FASTDDS_BUILTIN_TRANSPORTS`` is set
        to anything but ``SHM``). ``None``: the ``ROS_DOMAIN_ID`` exported in ``base`` if it is
        set and not empty (checked the same way), else a free id in ``[1, 101]`` reserved with an
        exclusive lock file (see :func:`reserve_domain_id`). A given or exported id is not locked,
        so a child process can be handed the id its parent reserved.
    base : dict or None
        Environment to start from; default a copy of ``os.environ``.

    Returns
    -------
    LocalRosEnv
        A ``dict`` copy of the environment with ``FASTDDS_BUILTIN_TRANSPORTS=SHM`` (unless already
        set), ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and ``ROS_DOMAIN_ID``; its ``.lock``
        holds the reservation and must live as long as the run (``with local_ros_env() as env:``).
    """
    env = LocalRosEnv(os.environ if base is None else base)
    env.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "SHM")
    exported = env.get("ROS_DOMAIN_ID", "").strip()
    lock = None
    if domain_id is not None:
        chosen = check_domain_id(domain_id, env)
    elif exported:
        chosen = check_domain_id(exported, env, "ROS_DOMAIN_ID (exported)")
    else:
        lock = reserve_domain_id()
        chosen = lock.domain_id
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(chosen)
    env.domain_id = chosen
    env.lock = lock
    return env


#: The variables a client needs to join a run's graph, in the order of :func:`client_export_line`.
#: Every participant of a graph needs the same discovery settings: a client with the transport and
#: the domain id but not the discovery range sees no node of a run (docs/ros.md, "Integrating").
CLIENT_VARIABLES = ("FASTDDS_BUILTIN_TRANSPORTS", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID")


def client_export_line(env: Mapping[str, str]) -> str:
    """The shell line that gives a client in another shell the environment of run ``env`` (a
    :class:`LocalRosEnv`, or ``os.environ`` after :func:`apply_local_ros_env`):
    ``export FASTDDS_BUILTIN_TRANSPORTS=SHM ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=42``
    (values shell-quoted where they need it)."""
    return "export " + " ".join(f"{k}={shlex.quote(str(env[k]))}" for k in CLIENT_VARIABLES)


def apply_local_ros_env(domain_id: int | None = None) -> LocalRosEnv:
    """Set the variables of :func:`local_ros_env` in ``os.environ`` of this process.

    Call before ``rclpy.init()``; keep the returned object alive as long as the run.
    """
    env = local_ros_env(domain_id)
    for key in ("FASTDDS_BUILTIN_TRANSPORTS", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID"):
        os.environ[key] = env[key]
    return env


# ---------------------------------------------------------------- shared memory


def fastdds_tool() -> list[str]:
    """Command line of Fast DDS's own ``fastdds`` tool.

    The ``ros-fastrtps`` wheel (a dependency of ``ros-jazzy-rclpy[fastrtps]``) ships it as
    ``<prefix>/bin/fastdds``, a shell launcher of ``<prefix>/tools/fastdds/fastdds.py``; a
    system ROS 2 has it on ``PATH``. The Python script is run with this interpreter (the
    launcher would take whichever ``python3`` is first on ``PATH``).

    Raises
    ------
    InputError
        When no ``fastdds`` tool is installed.
    """
    here = Path(sys.executable).parent
    launcher = here / "fastdds" if (here / "fastdds").is_file() else shutil.which("fastdds")
    if launcher is None:
        raise InputError("fastdds: Fast DDS's tool is not installed (it comes with the ros-fastrtps "
                         "wheel of requirements.txt, or with a system ROS 2 on PATH)")
    script = Path(launcher).resolve().parent.parent / "tools" / "fastdds" / "fastdds.py"
    return [sys.executable, str(script)] if script.is_file() else [str(launcher)]


def cleanup_shm(timeout_s: float = 60.0) -> str:
    """Remove the Fast DDS shared-memory files of dead participants: ``fastdds shm clean``.

    A process killed with SIGKILL leaves its data segment ``fastrtps_<hex>`` (about 0.5 MB) and
    port files in /dev/shm. Fast DDS holds an ``flock`` on each segment's and port's lock file
    for the owner's lifetime; ``fastdds shm clean`` removes exactly the files whose lock no live
    process holds, so the segments of running nodes (of this run or any other) are never
    touched.

    Returns
    -------
    str
        The tool's report (``shm.clean: ... zombie segments cleaned``).
    """
    out = subprocess.run(fastdds_tool() + ["shm", "clean"], capture_output=True, text=True,
                         timeout=timeout_s)
    if out.returncode != 0:
        raise RunError(f"fastdds shm clean failed (exit status {out.returncode}): "
                          f"{(out.stderr or out.stdout).strip()}")
    return out.stdout.strip()


# ---------------------------------------------------------------- our own dead processes' segments
#: Where the Fast DDS files of our processes are noted: one ledger file per process.
SHM_LEDGER_DIR = LOCK_DIR / "shm"
SHM_DIR = Path("/dev/shm")
#: Names of Fast DDS files in /dev/shm: data segments ``fastrtps_<16 hex>``, ports
#: ``fastrtps_port<n>``, data-sharing pools ``fast_datasharing_*``; each with ``_el``/``_sl``
#: lock files and, for a port, a ``sem.<port>_mutex`` semaphore.
_FASTDDS_BASE = ("fastrtps_", "fast_datasharing_")


def _start_time(pid: int) -> str | None:
    """The kernel's start time of ``pid`` (field 22 of /proc/pid/stat): a pid reused later differs."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[1].split()[19]


def _base_name(name: str) -> str | None:
    if name.startswith("sem.") and name.endswith("_mutex"):
        name = name[4:-6]
    for suffix in ("_el", "_sl"):
        if name.endswith(suffix):
            name = name[:-3]
    return name if name.startswith(_FASTDDS_BASE) else None


def mapped_shm(pid: int) -> set[str]:
    """Base names of the Fast DDS files process ``pid`` maps or holds open (its segments, ports
    and their lock files), from /proc; empty when it is gone or not ours to read."""
    names = set()
    try:
        for line in Path(f"/proc/{pid}/maps").read_text().splitlines():
            if "/dev/shm/" not in line:  # most of the ~1000 lines of a ROS process: its libraries
                continue
            parts = line.split(maxsplit=5)
            path = parts[5] if len(parts) == 6 else ""
            if path.startswith("/dev/shm/"):
                names.add(path[9:].removesuffix(" (deleted)"))
        for fd in os.scandir(f"/proc/{pid}/fd"):
            try:
                target = os.readlink(fd.path)
            except OSError:
                continue
            if target.startswith("/dev/shm/"):
                names.add(target[9:])
    except OSError:
        pass
    return {b for b in map(_base_name, names) if b is not None}


def record_shm(pids) -> int:
    """Note in the ledger the Fast DDS files each of ``pids`` (processes of ours) uses now, so
    that :func:`clean_dead_shm` can remove them once the process is dead; returns names noted.

    Called while the processes live (a SIGKILL leaves no chance later); the ledger of a pid
    grows, never shrinks, until its files are cleaned.
    """
    total = 0
    for pid in pids:
        names = mapped_shm(pid)
        start = _start_time(pid)
        if not names or start is None:
            continue
        path = SHM_LEDGER_DIR / f"{pid}-{start}.txt"
        try:
            SHM_LEDGER_DIR.mkdir(mode=0o777, parents=True, exist_ok=True)
            old = set(path.read_text().split()) if path.exists() else set()
            if names - old:
                tmp = path.with_suffix(f".tmp{os.getpid()}")
                tmp.write_text("".join(f"{n}\n" for n in sorted(old | names)))
                os.replace(tmp, path)
        except OSError:
            continue  # best effort: a full /tmp costs the note, never the run
        total += len(names)
    return total


def _locked_by_someone(path: Path) -> bool:
    """True when a live process holds an flock on ``path`` (Fast DDS's lock of a live owner)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        os.close(fd)  # closing drops a lock this call took
    return False


def _in_use() -> set[str]:
    """Base names of Fast DDS files mapped or open in any live process we can read."""
    used = set()
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            used |= mapped_shm(int(entry.name))
    return used


def clean_dead_shm() -> tuple[int, int]:
    """Remove the Fast DDS files our dead processes left: those in the ledger of a process that
    is gone (its pid ended, or now names another process), and only when no live process maps or
    holds them and no live process holds their lock. Ledgers of live processes are kept.

    Returns
    -------
    (int, int)
        Files removed and ledgers closed.
    """
    try:
        ledgers = [p for p in SHM_LEDGER_DIR.iterdir() if p.suffix == ".txt"]
    except OSError:
        return 0, 0
    dead = []
    for p in ledgers:
        pid, _, start = p.stem.partition("-")
        if not pid.isdigit() or _start_time(int(pid)) != start:
            dead.append(p)
    if not dead:
        return 0, 0
    used = _in_use()
    removed = closed = 0
    for ledger in dead:
        try:
            names = set(ledger.read_text().split())
        except OSError:
            continue
        left = set()
        for base in names:
            if _base_name(base) != base:
                continue
            files = [SHM_DIR / base, SHM_DIR / f"{base}_el", SHM_DIR / f"{base}_sl", SHM_DIR / f"sem.{base}_mutex"]
            if base in used or any(_locked_by_someone(f) for f in files[1:3]):
                left.add(base)  # a live process uses it (a peer's port or segment this one mapped)
                continue
            for f in files:
                try:
                    f.unlink()
                    removed += 1
                except FileNotFoundError:
                    pass
                except OSError:
                    left.add(base)
        with contextlib.suppress(OSError):
            if left:  # looked at again at the next clean, once their users are gone too
                if left != names:
                    ledger.write_text("".join(f"{n}\n" for n in sorted(left)))
            else:
                ledger.unlink()
                closed += 1
    return removed, closed
