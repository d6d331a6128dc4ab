"""One rule for the files of every entry point (CLIs, launch scripts, nodes, the study).

Inputs (:func:`input_file`, :func:`read_toml`)
    A file read by a run must be a regular file: a folder, a named pipe (whose ``open`` for
    reading blocks until a writer appears), a socket or a device is refused with one line
    before it is opened. An MCAP input (:func:`mcap_input`) must also start with the MCAP magic bytes;
    a TOML input (bridge and train files) must parse. A text input (:func:`read_text`: TOML files,
    params YAML files) must be UTF-8; a UTF-8 byte order mark at its start is accepted and dropped.
    A path with a component longer than 255 bytes is refused naming the option (:func:`check_path`).

Outputs (:func:`claim_output`, :func:`write_atomic`)
    A file written by a run is checked before any work, by one function:

    1. a regular-file path (not a folder, not a pipe or a device), with the suffix the writer
       needs;
    2. not an input of the same run (paths compared after ``resolve()``, so ``./t.toml`` and a
       symlink to it are the same file);
    3. in a folder that exists and is writable, probed by creating a temporary file there, writing
       one byte and removing it (permissions and read-only mounts show up here as bad input; a
       full disk, a full quota or ``ulimit -f`` as a failed run, exit 1; both before the work);
    4. never replaced unless the caller passes ``overwrite`` (``--overwrite``, a node's
       ``overwrite`` parameter);
    5. claimed with an exclusive ``fcntl.flock`` on a sidecar lock file ``.<name>.lock`` beside
       it, holding the claimer's pid: a second writer of the same file (another process, or the
       same process twice) is refused with one line naming the first. The claim lasts until
       :func:`release` (:func:`adm_sim.cliutil.run_cli` releases every claim when a command
       ends; the kernel drops the lock when a process dies, so a killed run never blocks the next);
    6. written beside and renamed (:func:`write_atomic`): the path holds either its old content or
       the complete new one, never a half-written file; a write the system refuses (a full disk,
       a file larger than ``ulimit -f``) is one :class:`~adm_sim.errors.RunError` naming the path,
       and leaves neither the temporary file nor the lock.

Output sets (:class:`OutputSet`)
    The outputs of one command (``--json`` and ``--plot``, a folder of tables and figures) are
    written as a set: each beside its final name, all renamed at the end; a command that fails or
    is interrupted before that leaves none of them (and no temporary file).

Output folders (:func:`check_output_folder`, :func:`make_output_folder`, :func:`claim_folder`)
    A folder a run writes into (``adm-calib --out``, a launch's ``--out``) is checked before any
    work by the same rule: not an existing file; the folder, or while it does not exist its nearest
    existing ancestor, writable (probed); none of the files it will hold an input of the run. It
    is created once every input is checked, and removed again if the command ends before anything
    was written into it (:func:`release_all`). A folder that several processes write (a launch and
    its nodes) is claimed as a whole by a lock file ``.launch.lock`` in it, holding the claimer's
    pid; the files in it are claimed by their writers.

Every refusal is an :class:`adm_sim.errors.InputError` (one line; exit code 2 in the CLIs and
nodes). This module imports only the standard library.
"""

from __future__ import annotations

import errno
import fcntl
import os
import re
import stat
import tempfile
import tomllib
from pathlib import Path

from adm_sim.errors import InputError, RunError
from adm_sim.interrupts import held

__all__ = ["check_path", "read_text", "check_output_folder", "claim_folder", "claim_output", "claimed", "input_file", "is_input", "lock_path",
           "make_output_folder", "mcap_input", "OutputSet", "probe_writable", "read_toml", "refuse_special", "release", "release_all",
           "write_atomic"]

#: Claims held by this process: resolved output path (or folder) -> (fd of the lock file, lock path).
_CLAIMS: dict[Path, tuple[int, Path]] = {}
#: Folders :func:`make_output_folder` created in this process (innermost first); removed again while empty.
_CREATED: list[Path] = []
#: The lock file of a claimed folder (:func:`claim_folder`).
FOLDER_LOCK = ".launch.lock"

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def _kind(mode):
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


# ---------------------------------------------------------------------- inputs
def refuse_special(path, where):
    """Raise one line when ``path`` exists and is neither a regular file nor a folder (a named
    pipe, a socket, a device), before anything opens it; missing files and folders are left to
    the caller's own message."""
    try:
        st = Path(path).stat()
    except OSError:
        return
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode)):
        raise InputError(f"{where}: is {_kind(st.st_mode)}, not a regular file")


#: Longest name of one path component (bytes), the NAME_MAX of Linux file systems.
NAME_MAX_BYTES = 255


def check_path(text, option):
    """``text`` unless a component of the path is longer than :data:`NAME_MAX_BYTES` (the system
    would refuse it with ``File name too long``); one line naming ``option`` otherwise."""
    for part in Path(str(text)).parts:
        n = len(os.fsencode(part))
        if n > NAME_MAX_BYTES:
            shown = part if len(part) <= 24 else part[:24] + "..."
            raise InputError(f"{option}: a path component ({shown!r}) is {n} bytes long; allowed at most "
                             f"{NAME_MAX_BYTES} bytes per file or folder name", field=option)
    return text


def read_text(path, what):
    """The text of input file ``path`` (UTF-8; a UTF-8 byte order mark at its start is accepted
    and dropped); :class:`InputError` naming ``what`` and the path when it cannot be read or is
    not UTF-8 text (a binary file)."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(f"{what} {str(p)!r}: cannot read ({exc.strerror})") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what} {str(p)!r}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
                         f"{exc.start}); give a text file") from None


def input_file(text, option, what="file"):
    """``Path(text)`` if it names an existing regular file (symlinks followed); else one line.

    Called before the file is opened, so a named pipe never blocks the run.
    """
    if text is None or not str(text).strip():
        raise InputError(f"{option}: '' is empty; give a {what}")
    check_path(text, option)
    p = Path(text)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise InputError(f"{option}: {str(text)!r} is not a file") from None
    except OSError as exc:
        raise InputError(f"{option}: {str(text)!r}: cannot read ({exc.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{option}: {str(text)!r} is not a file")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{option}: {str(text)!r} is {_kind(st.st_mode)}, not a regular file; give a {what}")
    return p


def is_input(path, inputs):
    """The option of ``inputs`` (``{option: path}`` or ``(option, path)`` pairs) whose existing
    file is the same file as ``path`` (resolved paths compared), or None."""
    target = Path(path).resolve()
    pairs = inputs.items() if isinstance(inputs, dict) else (inputs or ())
    for option, p in pairs:
        if p is None or not str(p).strip():
            continue
        try:
            if Path(p).is_file() and Path(p).resolve() == target:
                return option
        except (OSError, RuntimeError):
            continue
    return None


def read_toml(path, what):
    """Parse a TOML input file; unreadable or invalid files raise :class:`InputError`.

    ``what`` names the file's role in the message (``"bridge file"``, ``"train file"``).
    """
    p = Path(path)
    refuse_special(p, f"{what} {str(p)!r}")
    text = read_text(p, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{what} {str(p)!r}: not valid TOML ({exc})") from None


# ---------------------------------------------------------------------- outputs
def lock_path(path):
    """The sidecar lock file of output ``path``: ``.<name>.lock`` in the same folder."""
    p = Path(path)
    return p.with_name(f".{p.name}.lock")


#: Errors of a write that the system refuses for want of room (a full disk, a quota, ``ulimit -f``):
#: a failed run (exit 1), where a folder the user may not write in is bad input (exit 2).
NO_ROOM = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


def probe_writable(parent, option, text):
    """Create a temporary file in ``parent``, write one byte, remove it; one line naming ``option``
    if that fails: :class:`InputError` for a folder that cannot be written (permissions, a
    read-only mount), :class:`RunError` when there is no room (a full disk, ``ulimit -f``)."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".adm-probe-", dir=parent)
    except OSError as exc:
        raise _refusal(exc)(f"{option}: {text!r}: cannot write in the directory {str(parent)!r} "
                            f"({exc.strerror})") from None
    try:
        os.write(fd, b"\0")
    except OSError as exc:
        raise _refusal(exc)(f"{option}: {text!r}: cannot write in the directory {str(parent)!r} "
                            f"({exc.strerror})") from None
    finally:
        os.close(fd)
        os.unlink(probe)


def _refusal(exc):
    return RunError if exc.errno in NO_ROOM else InputError


def claim_output(text, option, overwrite=False, suffix=None, inputs=None,
                 overwrite_hint="use --overwrite to replace it"):
    """Check output ``text`` by the rule of the module docstring and claim it; returns the Path.

    Parameters
    ----------
    text : str or path-like
        The output path as the user gave it.
    option : str
        The option or parameter named in messages (``"--json"``, ``"record_path"``).
    overwrite : bool
        Whether an existing file may be replaced.
    suffix : str or None
        Required suffix (``".png"``), compared case-insensitively.
    inputs : dict or None
        ``{option: path}`` of the run's input files; the output may be none of them.
    overwrite_hint : str
        How the user allows a replacement (a node: ``set -p overwrite:=true to replace it``).

    Raises
    ------
    InputError
        One line naming ``option``, the path and the reason.
    """
    if text is None or not str(text).strip():
        raise InputError(f"{option}: '' is empty; give a file name")
    text = str(text)
    check_path(text, option)
    p = Path(text)
    if suffix and p.suffix.lower() != suffix:
        raise InputError(f"{option}: {text!r} must end in {suffix}")
    if p.is_dir():
        raise InputError(f"{option}: {text!r} is a directory; give a file name")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{option}: {text!r}: the directory {str(parent)!r} does not exist")
    try:
        st = p.stat()
    except OSError:
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise InputError(f"{option}: {text!r} is {_kind(st.st_mode)}, not a regular file; give a file name")
    same = is_input(p, inputs)
    if same is not None:
        raise InputError(f"{option}: {text!r} is the {same} file, an input of this run; give another file")
    if st is not None and not overwrite:
        raise InputError(f"{option}: {text!r} exists; {overwrite_hint}")
    probe_writable(parent, option, text)
    _lock(p, option, text)
    return p


def _holder(lock):
    try:
        pid = Path(lock).read_text().strip()
    except OSError:
        pid = ""
    return f"process {pid}" if pid.isdigit() else "another process"


def _lock(p, option, text):
    key = p.resolve()
    if key in _CLAIMS:
        raise InputError(f"{option}: {text!r} is already being written by this process ({os.getpid()}); "
                         f"give each output once")
    _lock_file(key, lock_path(key), option, text)


def _lock_file(key, lock, option, text):
    """Create, lock and claim ``lock``, signals held back meanwhile (:func:`adm_sim.interrupts.held`:
    one that comes is raised once the claim is recorded, which the runner then releases; between
    the file's creation and the claim it would leave the file behind). Any other exception on the
    way gives the lock file up (:func:`_abandon`)."""
    while True:
        with held():
            if _lock_file_once(key, lock, option, text):
                return


def _lock_file_once(key, lock, option, text):
    """One try of :func:`_lock_file`: True once claimed, False when the file locked was replaced."""
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise InputError(f"{option}: {text!r}: cannot create its lock file {str(lock)!r} "
                         f"({exc.strerror})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            fd = None
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise InputError(f"{option}: {text!r} is being written by {_holder(lock)} (lock "
                                 f"{str(lock)!r}); wait for it to finish or choose another file") from None
            raise InputError(f"{option}: {text!r}: cannot lock {str(lock)!r} ({exc.strerror})") from None
        try:  # the holder we waited for may have removed the file we locked: lock the current one
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            _claimed(key, fd, lock)
            return True
        os.close(fd)
        fd = None
        return False
    except BaseException:
        if fd is not None and key not in _CLAIMS:
            _abandon(fd, lock)
        raise


def _abandon(fd, lock):
    """A lock file opened but not claimed when an exception came: removed when this process holds
    or can take its lock (then it is nobody else's), closed either way."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        if os.fstat(fd).st_ino == os.stat(lock).st_ino:
            os.unlink(lock)
    except OSError:
        pass
    finally:
        os.close(fd)


def _claimed(key, fd, lock):
    """Record the claim, then write the pid into its lock file: the claim is recorded first so that
    :func:`release` removes the lock file even when the pid cannot be written (a full disk, ``ulimit
    -f 0``); the pid only names the holder in another process's message, the ``flock`` is the claim."""
    _CLAIMS[key] = (fd, lock)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    except OSError:
        pass


def claimed(path):
    """Whether this process holds the claim on ``path``."""
    return Path(path).resolve() in _CLAIMS


def release(path):
    """Give up the claim on ``path`` (idempotent): the lock file is removed, then the claim dropped
    and unlocked (in that order, so an interrupt in between leaves no lock file)."""
    key = Path(path).resolve()
    entry = _CLAIMS.get(key)
    if entry is None:
        return
    fd, lock = entry
    try:
        os.unlink(lock)
    except OSError:
        pass
    if _CLAIMS.pop(key, None) is not None:
        os.close(fd)


def release_all():
    """Give up every claim of this process and remove the output folders it created that are still
    empty (the end of a command)."""
    for key in list(_CLAIMS):
        release(key)
    while _CREATED:
        try:  # a folder that received files stays
            _CREATED.pop(0).rmdir()
        except OSError:
            pass


def write_atomic(path, write, option="output"):
    """``write(tmp_path)`` beside ``path``, then rename: an earlier file is replaced only by a
    complete one, and a failed write leaves nothing.

    ``path`` should have been claimed with :func:`claim_output`; if not, it is claimed here (with
    overwrite, the caller having checked it) for the time of the write. The claim is released
    once the file is in place.
    """
    p = Path(path)
    if not claimed(p):
        _lock(p, option, str(p))
    tmp = p.with_name(f".{p.stem}.tmp-{os.getpid()}{p.suffix}")
    try:
        write(tmp)
        os.replace(tmp, p)
    except OSError as exc:
        if exc.filename not in (None, str(tmp), str(p)):
            raise  # not the output: another file the writer reads or writes
        raise RunError(f"{option}: {str(p)!r}: cannot write ({exc.strerror or exc})") from None
    except RuntimeError as exc:  # a writer in Rust (rerun) reports the system's refusal as "... (os error 27)"
        code = re.search(r"\(os error (\d+)\)", str(exc))
        if code is None:
            raise
        raise RunError(f"{option}: {str(p)!r}: cannot write ({os.strerror(int(code.group(1)))})") from None
    finally:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        release(p)


class OutputSet:
    """The outputs of one command written as a set: all or nothing.

    Each :meth:`write` writes one output beside its final name (a temporary ``.<stem>.tmp-<pid>``
    file, as :func:`write_atomic`); :meth:`commit` renames every one into place at the end, with
    SIGINT and SIGTERM held back for the renames, then prints the notes (``wrote ...``). If the
    command fails or is interrupted before the commit (an exception, ``KeyboardInterrupt``), every
    temporary file is removed and no output of the set appears: an earlier file under a final name
    keeps its content, a re-run finds nothing in its way. Used as a context manager::

        with OutputSet() as outs:
            outs.write(json_path, lambda p: p.write_text(text), "--json", note=f"wrote {json_path}")
            outs.write(plot_path, plot, "--plot", note=f"wrote {plot_path}")
        # both renamed here, or neither

    A write the system refuses is one :class:`~adm_sim.errors.RunError` naming the output (as
    :func:`write_atomic`). The paths should have been claimed with :func:`claim_output`; if not,
    each is claimed here until the set ends.
    """

    def __init__(self):
        self._staged = []   # (tmp, final path, option)
        self._notes = []
        self.written = []   # final paths, once committed

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if kind is None:
            self.commit()
        else:
            self.abort()
        return False

    def write(self, path, write, option="output", note=None):
        """``write(tmp_path)`` beside ``path``; renamed by :meth:`commit`."""
        p = Path(path)
        if not claimed(p):
            _lock(p, option, str(p))
        tmp = p.with_name(f".{p.stem}.tmp-{os.getpid()}{p.suffix}")
        self._staged.append((tmp, p, option))
        try:
            write(tmp)
        except OSError as exc:
            if exc.filename not in (None, str(tmp), str(p)):
                raise
            raise RunError(f"{option}: {str(p)!r}: cannot write ({exc.strerror or exc})") from None
        except RuntimeError as exc:
            code = re.search(r"\(os error (\d+)\)", str(exc))
            if code is None:
                raise
            raise RunError(f"{option}: {str(p)!r}: cannot write ({os.strerror(int(code.group(1)))})") from None
        if not tmp.exists():
            raise RunError(f"{option}: {str(p)!r}: the writer wrote nothing")
        if note is not None:
            self._notes.append(note)
        return p

    def commit(self):
        """Rename every written output into place (signals held back meanwhile), release the
        claims, print the notes."""
        with held():  # a signal now is raised after the last rename, whichever thread took it
            try:
                for tmp, p, option in self._staged:
                    try:
                        os.replace(tmp, p)
                    except OSError as exc:
                        raise RunError(f"{option}: {str(p)!r}: cannot write ({exc.strerror or exc})") from None
                    self.written.append(p)
            finally:
                if len(self.written) != len(self._staged):
                    self.abort()
        self._release()
        for note in self._notes:
            print(note)

    def abort(self):
        """Remove every temporary file of the set and release the claims."""
        for tmp, _, _ in self._staged:
            try:
                tmp.unlink()
            except FileNotFoundError:
                pass
        self._release()

    def _release(self):
        for _, p, _ in self._staged:
            release(p)


# ---------------------------------------------------------------------- output folders
def check_output_folder(text, option, names=(), inputs=None):
    """Check output folder ``text`` before any work by the rule of the module docstring; returns its Path.

    ``names``: the files the run will write in it; ``inputs``: ``{option: path}`` of the run's input
    files (none of ``names`` may be one of them).
    """
    if text is None or not str(text).strip():
        raise InputError(f"{option}: '' is empty; give a directory")
    check_path(text, option)
    out = Path(text)
    if out.exists() and not out.is_dir():
        raise InputError(f"{option}: {str(out)!r} is not a directory")
    anc = out.absolute()
    while not anc.is_dir() and anc != anc.parent:
        anc = anc.parent
    probe_writable(anc, option, str(text))
    for name in names:
        same = is_input(out / name, inputs)
        if same is not None:
            raise InputError(f"{option}: {str(out / name)!r} is the {same} file, an input of this run; "
                             f"give another file")
    return out


def make_output_folder(out, option):
    """Create output folder ``out`` (and its missing parents); returns whether it was created here.
    The folders created here are removed again by :func:`release_all` while they are empty."""
    out = Path(out)
    created = [] if out.exists() else [p for p in [out, *out.absolute().parents] if not p.exists()]
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{option}: cannot create {str(out)!r} ({exc.strerror})") from None
    _CREATED.extend(created)
    return bool(created)


def claim_folder(out, option, names=(), overwrite=False):
    """Claim folder ``out`` as a whole (an exclusive ``flock`` on ``<out>/.launch.lock`` holding the
    pid) for a run whose files other processes write; returns the ``names`` that exist in it.

    A folder another process holds is refused naming its pid; a folder that holds any of ``names``
    (an earlier run) is refused unless ``overwrite``. The kernel drops the lock when the process
    ends, however it ends; :func:`release` (``release(out)``) removes the lock file.
    """
    out = Path(out)
    key = out.resolve()
    lock = out / FOLDER_LOCK
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise InputError(f"{option}: cannot create {str(out)!r} ({exc.strerror})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        pid = os.pread(fd, 32, 0).decode(errors="replace").strip()
        os.close(fd)
        raise InputError(f"{option}: {str(out)!r} is being written by another launch (process {pid or '?'}); "
                         f"wait for it to finish or choose another folder") from None
    _claimed(key, fd, lock)
    old = [n for n in names if (out / n).exists()]
    if old and not overwrite:
        release(key)
        raise InputError(f"{option}: {str(out)!r} holds an earlier run ({', '.join(old)}); "
                         f"choose another folder or pass --overwrite")
    return old


_MCAP_MAGIC = b"\x89MCAP0\r\n"


def mcap_input(text, option, damaged_magic=False):
    """Check an MCAP input before any work: a readable regular file that starts with the MCAP magic.

    A file whose first 8 bytes (the magic) are damaged while the rest reads as MCAP (the closing
    magic, or the header record after the opening one) is named so and pointed to ``adm-sim
    salvage``; with ``damaged_magic`` (salvage itself) it is accepted and the scan recovers it."""
    p = input_file(text, option, "MCAP file")
    try:
        with p.open("rb") as f:
            head = f.read(9)
            size = f.seek(0, 2)
            f.seek(max(size - 8, 0))
            tail = f.read(8)
    except OSError as exc:
        raise InputError(f"{option}: {text!r}: cannot read ({exc.strerror}; a file that cannot be read)") from None
    if head[:8] != _MCAP_MAGIC:
        if tail == _MCAP_MAGIC or head[8:9] == b"\x01":
            if damaged_magic:
                return p
            raise InputError(f"{option}: {text!r} is damaged: its MCAP magic (bytes 0-7) is broken while the rest "
                             f"reads as MCAP; recover its intact chunks with: adm-sim salvage {text} OUT.mcap")
        raise InputError(f"{option}: {text!r} is not an MCAP file (it does not start with the MCAP magic bytes)")
    return p
