"""Keep every ROS 2 run on this machine and apart from every other run.

* :func:`local_ros_env` returns an environment for a run (or its child processes) with Fast DDS
  restricted to shared memory (``FASTDDS_BUILTIN_TRANSPORTS=SHM``: no UDP socket at all),
  ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a ``ROS_DOMAIN_ID`` of its own. A free domain id
  in ``[1, 101]`` is reserved with an exclusive ``fcntl.flock`` on a lock file under
  ``/tmp/adm_sim_ros_domains/``; the lock is released when the run closes it or dies, so concurrent
  runs never share an id and a killed run never leaks one.
* :func:`cleanup_shm` removes the Fast DDS shared-memory files (``/dev/shm/fastrtps_*``,
  ``fast_datasharing_*``) that killed processes left behind, and never a file that a live process
  still maps, holds open or locks.

This module imports nothing from ROS, so launchers can prepare the environment before rclpy loads.
"""

from __future__ import annotations

import fcntl
import os
import re
from pathlib import Path

from adm_sim.errors import InputError

__all__ = [
    "DOMAIN_ID_MAX",
    "DomainLock",
    "LocalRosEnv",
    "cleanup_shm",
    "local_ros_env",
    "shm_files_of",
]

#: Largest ROS_DOMAIN_ID whose Fast DDS ports stay valid on Linux (ROS 2 docs, "The ROS_DOMAIN_ID").
DOMAIN_ID_MAX = 101
LOCK_DIR = Path("/tmp/adm_sim_ros_domains")
SHM_DIR = Path("/dev/shm")

# Files Fast DDS creates in /dev/shm: per-participant data segments ``fastrtps_<16 hex>``, port
# segments ``fastrtps_port<N>``, their lock files ``*_el`` / ``*_sl``, port mutexes
# ``sem.fastrtps_port<N>_mutex`` and data-sharing segments ``fast_datasharing_<guid>``.
_FASTDDS_SHM = re.compile(r"^(sem\.)?(fastrtps_|fast_datasharing_)")
_DATA_SEGMENT = re.compile(r"^fastrtps_[0-9a-f]{16}(_el|_sl)?$|^fast_datasharing_")


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
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return DomainLock(domain_id, fd, path)


def reserve_domain_id() -> DomainLock:
    """Reserve a free ROS_DOMAIN_ID in ``[1, DOMAIN_ID_MAX]`` (0, the ROS default, is left alone),
    the least recently used first.

    Raises
    ------
    InputError
        When all 101 ids are held by other runs.
    """
    n = DOMAIN_ID_MAX
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
        f"ROS_DOMAIN_ID: all ids in [1, {DOMAIN_ID_MAX}] are reserved by other runs "
        f"(lock files in {LOCK_DIR}); wait for a run to end or pass an explicit id"
    )


def local_ros_env(domain_id: int | None = None, base: dict | None = None) -> LocalRosEnv:
    """Environment for a ROS 2 run that talks to this machine only and to no other run.

    Parameters
    ----------
    domain_id : int or None
        ``ROS_DOMAIN_ID`` in ``[0, 101]``. ``None`` reserves a free id in ``[1, 101]`` with an
        exclusive lock file (see :func:`reserve_domain_id`); an explicit id is not locked, so a
        child process can be handed the id its parent reserved.
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
    if domain_id is None:
        lock = reserve_domain_id()
        chosen = lock.domain_id
    else:
        if isinstance(domain_id, bool) or not isinstance(domain_id, int):
            raise InputError(
                f"ROS_DOMAIN_ID: {domain_id!r} is not an integer; allowed [0, {DOMAIN_ID_MAX}]"
            )
        if not 0 <= domain_id <= DOMAIN_ID_MAX:
            raise InputError(
                f"ROS_DOMAIN_ID: {domain_id} is out of range; allowed [0, {DOMAIN_ID_MAX}]"
            )
        lock = None
        chosen = domain_id
    env.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "SHM")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(chosen)
    env.domain_id = chosen
    env.lock = lock
    return env


def apply_local_ros_env(domain_id: int | None = None) -> LocalRosEnv:
    """Set the variables of :func:`local_ros_env` in ``os.environ`` of this process.

    Call before ``rclpy.init()``; keep the returned object alive as long as the run.
    """
    env = local_ros_env(domain_id)
    for key in ("FASTDDS_BUILTIN_TRANSPORTS", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID"):
        os.environ[key] = env[key]
    return env


# ---------------------------------------------------------------- shared memory


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    # a zombie (killed, not yet reaped) holds no mapping any more: count it as dead
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _names_used_by(pid: int | str) -> set[str]:
    """Names of /dev/shm files that process ``pid`` maps or holds open."""
    names: set[str] = set()
    prefix = str(SHM_DIR) + "/"
    try:
        with open(f"/proc/{pid}/maps") as f:
            for line in f:
                i = line.find(prefix)
                if i >= 0:
                    names.add(line[i + len(prefix):].split(" (deleted)")[0].strip())
    except OSError:
        pass
    try:
        for fd in os.scandir(f"/proc/{pid}/fd"):
            try:
                target = os.readlink(fd.path)
            except OSError:
                continue
            if target.startswith(prefix):
                names.add(target[len(prefix):])
    except OSError:
        pass
    return {n for n in names if _FASTDDS_SHM.match(n)}


def shm_files_of(pid: int) -> set[str]:
    """Fast DDS /dev/shm files that the live process ``pid`` maps or holds open.

    Record this while a process runs to attribute its files exactly when it is killed later.
    """
    return _names_used_by(pid)


def _locked_inodes() -> set[int]:
    inodes: set[int] = set()
    try:
        with open("/proc/locks") as f:
            for line in f:
                parts = line.split()
                # "1: FLOCK ADVISORY WRITE 4891 00:1a:1234 0 EOF" ('->' marks blocked waiters)
                if "->" in parts:
                    continue
                for p in parts:
                    if p.count(":") == 2:
                        try:
                            inodes.add(int(p.rsplit(":", 1)[1]))
                        except ValueError:
                            pass
                        break
    except OSError:
        pass
    return inodes


def _in_use() -> set[str]:
    used: set[str] = set()
    me = os.getpid()
    for entry in os.scandir("/proc"):
        if entry.name.isdigit() and int(entry.name) != me:
            used |= _names_used_by(entry.name)
    used |= _names_used_by(me)
    return used


def _base(name: str) -> str:
    """Segment a Fast DDS /dev/shm file belongs to: ``sem.X_mutex``, ``X_el``, ``X_sl`` -> ``X``."""
    if name.startswith("sem.") and name.endswith("_mutex"):
        return name[4:-6]
    if name.endswith(("_el", "_sl")):
        return name[:-3]
    return name


def _live_segments(present: dict, locked: set[int], mapped: set[str]) -> set[str]:
    """Segments whose owner is alive: Fast DDS holds an ``flock`` on ``<segment>_el`` (data and
    port segments) or ``<segment>_sl`` (shared port) for the owner's lifetime; a segment without
    any lock file counts as alive while some live process maps it."""
    live, has_lock_file = set(), set()
    for name, entry in present.items():
        if name.endswith(("_el", "_sl")):
            has_lock_file.add(name[:-3])
            try:
                if entry.inode() in locked:
                    live.add(name[:-3])
            except OSError:
                continue
    for name in mapped:
        if _base(name) not in has_lock_file:
            live.add(_base(name))
    return live


def cleanup_shm(pids, owned: dict[int, set[str]] | None = None) -> list[str]:
    """Remove Fast DDS shared-memory files left in /dev/shm by killed processes.

    A process killed with SIGKILL leaves its data segment ``fastrtps_<hex>`` (about 0.5 MB) with
    its lock file ``..._el``, and may leave port segments ``fastrtps_port<N>`` that the next
    participant cleans. A segment is alive while its owner holds the ``flock`` on
    ``<segment>_el`` / ``_sl`` (listed in /proc/locks); such a segment, and everything of it, is
    never removed. Unlinking a dead segment that a live peer still maps is safe: the mapping stays
    valid until the peer drops it.

    Parameters
    ----------
    pids : iterable of int
        Ids of the processes that were killed. Processes still alive are ignored.
    owned : dict or None
        ``pid -> names`` recorded with :func:`shm_files_of` while the processes ran: then only
        the dead segments among those (data and port segments, with their lock and mutex files)
        are removed. Without it (Fast DDS names carry no pid), the data segments
        ``fastrtps_<16 hex>`` and ``fast_datasharing_*`` whose owner is dead are removed, with
        their lock files; port segments are left to Fast DDS.

    Returns
    -------
    list of str
        Names of the removed files, sorted.
    """
    dead = [int(p) for p in pids if not _pid_alive(int(p))]
    if not dead or not SHM_DIR.is_dir():
        return []
    present = {e.name: e for e in os.scandir(SHM_DIR) if _FASTDDS_SHM.match(e.name)}
    if owned is not None:
        bases = set()
        for pid in dead:
            bases |= {_base(n) for n in owned.get(pid, ())}
    else:
        bases = {_base(n) for n in present if _DATA_SEGMENT.match(n)}
    if not bases:
        return []
    live = _live_segments(present, _locked_inodes(), _in_use())
    removed = []
    for name in sorted(present):
        if _base(name) in bases and _base(name) not in live:
            try:
                os.unlink(SHM_DIR / name)
                removed.append(name)
            except FileNotFoundError:
                continue
    return removed
