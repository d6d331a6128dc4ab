"""Record ROS 2 messages to MCAP, read them back, salvage the files of killed writers.

Files follow the ROS 2 profile that rosbag2 writes (https://mcap.dev/spec/registry): profile
``ros2``, schema encoding ``ros2msg``, message encoding ``cdr``. A schema is the ``.msg`` text of
the type with every dependency appended once, depth first, each after a line of 80 ``=`` and a
line ``MSG: pkg/Type`` (rosbag2 ``LocalMessageDefinitionSource``). Messages are serialised with
``rclpy.serialization.serialize_message`` (about 3x faster than mcap-ros2-support's encoder), so
the files read with mcap-ros2-support, ``rosbags`` and ``rerun mcap convert`` alike.

Chunks are small (64 KiB before compression by default) and written straight to the operating
system, so a writer killed with SIGKILL loses at most the open chunk; :func:`salvage` recovers
every complete record of such a file with ``mcap.reader.NonSeekingReader`` and writes a clean one.

Command line::

    python -m adm_sim.ros.mcap_log salvage IN.mcap OUT.mcap
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Iterator, Mapping
from pathlib import Path

from adm_sim.errors import InputError

__all__ = [
    "McapRecorder",
    "exact_cdr",
    "main",
    "message_definition",
    "read_messages",
    "salvage",
    "type_name",
]

DEFAULT_CHUNK_SIZE = 64 * 1024
_SEPARATOR = "=" * 80
_PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 "
    "string wstring".split()
)


# ---------------------------------------------------------------- schemas


def type_name(msg_type) -> tuple[str, str]:
    """``(package, Type)`` of an rclpy message class, e.g. ``('std_msgs', 'Float64MultiArray')``."""
    module = getattr(msg_type, "__module__", "")
    pkg, _, sub = module.partition(".")
    if not sub.startswith("msg") or not hasattr(msg_type, "get_fields_and_field_types"):
        raise InputError(
            f"msg_type: {msg_type!r} is not a ROS 2 message class; "
            "allowed a class from a <package>.msg module, e.g. std_msgs.msg.Float64MultiArray"
        )
    return pkg, msg_type.__name__


def _share_dirs() -> list[Path]:
    dirs = [Path(sys.prefix) / "share"]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            dirs.append(Path(prefix) / "share")
    return dirs


def _msg_file(pkg: str, name: str) -> Path:
    for share in _share_dirs():
        path = share / pkg / "msg" / f"{name}.msg"
        if path.is_file():
            return path
    searched = ", ".join(str(d / pkg / "msg") for d in _share_dirs())
    raise InputError(f"msg_type: no definition {pkg}/msg/{name}.msg found (searched {searched})")


def _dependencies(text: str, pkg: str) -> list[tuple[str, str]]:
    """Complex field types of a ``.msg`` text as ``(package, Type)``, in order of appearance."""
    deps: list[tuple[str, str]] = []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        base = re.sub(r"\[[^\]]*\]$", "", line.split()[0])  # Type[], Type[3], Type[<=3]
        base = base.split("<=")[0]  # string<=10
        if base in _PRIMITIVES:
            continue
        parts = base.split("/")
        if len(parts) == 1:
            dep = ("std_msgs", "Header") if base == "Header" else (pkg, base)
        else:
            dep = (parts[0], parts[-1])  # pkg/Type or pkg/msg/Type
        if dep not in deps:
            deps.append(dep)
    return deps


_DEFINITIONS: dict[tuple[str, str], str] = {}


def message_definition(msg_type) -> tuple[str, str]:
    """Schema name and rosbag2-style ``ros2msg`` text of a message class.

    Returns
    -------
    (str, str)
        ``('geometry_msgs/msg/AccelStamped', text)``: the installed ``.msg`` text followed by each
        dependency once (depth first), after a line of 80 ``=`` and ``MSG: pkg/Type``.
    """
    pkg, name = type_name(msg_type)
    key = (pkg, name)
    if key not in _DEFINITIONS:
        seen: set[tuple[str, str]] = {key}

        def expand(p: str, n: str) -> str:
            text = _msg_file(p, n).read_text()
            out = text
            for dep in _dependencies(text, p):
                if dep not in seen:
                    seen.add(dep)
                    out += f"\n{_SEPARATOR}\nMSG: {dep[0]}/{dep[1]}\n" + expand(*dep)
            return out

        _DEFINITIONS[key] = expand(pkg, name)
    return f"{pkg}/msg/{name}", _DEFINITIONS[key]


# ---------------------------------------------------------------- exact CDR length
#
# rmw_fastrtps' rmw_serialize reports the *estimated* size as the buffer length. For an empty
# sequence of 8-byte elements (e.g. JointState.velocity = []) the estimate exceeds the payload by
# up to 8 bytes of uninitialised memory, which strict readers (rosbags: "CDR message size
# mismatch") reject. Types that can carry such a sequence get their payload trimmed to the exact
# XCDR1 length computed here (OMG DDS-XTypes 7.4.1: primitives aligned to their size, at most 8;
# strings and sequences prefixed by a 4-byte-aligned uint32 length).

_PRIM_SIZE = {
    "boolean": 1, "octet": 1, "char": 1, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
    "wchar": 2, "int32": 4, "uint32": 4, "float": 4, "int64": 8, "uint64": 8, "double": 8,
}


def _align(pos: int, n: int) -> int:
    return (pos + n - 1) & ~(n - 1)


def _nested_class(t):
    import importlib

    return getattr(importlib.import_module(".".join(t.namespaces)), t.name)


def _size_of(t, value, pos: int) -> int:
    from rosidl_parser import definition as d

    if isinstance(t, d.BasicType):
        n = _PRIM_SIZE[t.typename]
        return _align(pos, n) + n
    if isinstance(t, d.AbstractString):
        return _align(pos, 4) + 4 + len(value.encode()) + 1
    if isinstance(t, d.NamespacedType):
        return _body_size(value, pos)
    if isinstance(t, d.AbstractNestedType):  # Array, UnboundedSequence, BoundedSequence
        if not isinstance(t, d.Array):
            pos = _align(pos, 4) + 4
        vt = t.value_type
        count = len(value)
        if isinstance(vt, d.BasicType):
            if count:
                n = _PRIM_SIZE[vt.typename]
                pos = _align(pos, n) + n * count
            return pos
        for item in value:
            pos = _size_of(vt, item, pos)
        return pos
    raise TypeError(f"no CDR size rule for {t!r}")


def _body_size(msg, pos: int) -> int:
    for field, ft in zip(msg.__slots__, msg.SLOT_TYPES):
        pos = _size_of(ft, getattr(msg, field), pos)
    return pos


def _needs_trim(msg_type, _seen=None) -> bool:
    """Whether ``msg_type`` has (at any depth) a sequence of 8-byte or nested elements."""
    from rosidl_parser import definition as d

    seen = set() if _seen is None else _seen
    if msg_type in seen:
        return False
    seen.add(msg_type)
    for t in msg_type.SLOT_TYPES:
        while isinstance(t, d.AbstractNestedType):
            if isinstance(t, d.AbstractSequence):
                vt = t.value_type
                if isinstance(vt, d.NamespacedType) or (
                        isinstance(vt, d.BasicType) and _PRIM_SIZE[vt.typename] == 8):
                    return True
            t = t.value_type
        if isinstance(t, d.AbstractWString):
            return False  # no exact rule; keep rclpy's buffer as it is
        if isinstance(t, d.NamespacedType) and _needs_trim(_nested_class(t), seen):
            return True
    return False


def exact_cdr(msg, data: bytes) -> bytes:
    """``data`` (rclpy-serialised ``msg``) cut to its exact CDR length (4-byte header + body)."""
    try:
        n = 4 + _body_size(msg, 0)
    except (TypeError, KeyError, AttributeError):
        return data
    return data[:n] if n <= len(data) else data


# ---------------------------------------------------------------- writing


class _DirectFile:  # not a RawIOBase, so mcap's Writer uses it as given (no BufferedWriter)
    """Write-through file: every record reaches the operating system at once (no user-space
    buffer for a SIGKILL to lose)."""

    def __init__(self, path: Path, overwrite: bool):
        flags = os.O_WRONLY | os.O_CREAT | (os.O_TRUNC if overwrite else os.O_EXCL)
        self._fd = os.open(path, flags, 0o644)
        self._pos = 0

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        self._pos += len(data)
        return len(data)

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class McapRecorder:
    """Context manager writing ROS 2 messages into an MCAP file.

    Parameters
    ----------
    path : str or path-like
        Output file. An existing file is refused unless ``overwrite=True``.
    chunk_size : int
        Bytes of serialised records per chunk (before compression), >= 1024. A writer killed
        with SIGKILL loses at most the open chunk; see :func:`salvage`.
    overwrite : bool
        Replace an existing file.
    compression : {'zstd', 'lz4', ''}
        Chunk compression.

    Examples
    --------
    >>> with McapRecorder("run.mcap") as rec:                      # doctest: +SKIP
    ...     rec.write_metadata("run", {"bridge": "B1", "model": "MLM"})
    ...     rec.write("/adm/midspan/accel", msg, log_time_ns=t_ns)
    """

    def __init__(self, path, chunk_size: int = DEFAULT_CHUNK_SIZE, overwrite: bool = False,
                 compression: str = "zstd"):
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        if not isinstance(chunk_size, int) or chunk_size < 1024:
            raise InputError(f"chunk_size: {chunk_size!r} B is out of range; allowed >= 1024 B")
        kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}
        if compression not in kinds:
            raise InputError(f"compression: {compression!r} is not one of 'zstd', 'lz4', ''")
        if self.path.exists() and not overwrite:
            raise InputError(
                f"path: '{self.path}' already exists; refusing to overwrite it "
                "(pass overwrite=True or choose another file)"
            )
        try:
            self._file = _DirectFile(self.path, overwrite)
        except FileExistsError:
            raise InputError(
                f"path: '{self.path}' already exists; refusing to overwrite it "
                "(pass overwrite=True or choose another file)"
            ) from None
        except OSError as exc:
            raise InputError(f"path: cannot create '{self.path}': {exc.strerror}") from None
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=kinds[compression])
        self._writer.start(profile="ros2", library="adm-sim mcap_log")
        self._schemas: dict[type, int] = {}
        self._channels: dict[str, tuple[int, type]] = {}
        self._trim: dict[type, bool] = {}
        self._sequence: dict[int, int] = {}
        self._finished = False
        self.message_count = 0
        from rclpy.serialization import serialize_message

        self._serialize = serialize_message

    # -- context manager
    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, *exc) -> None:
        self.finish()

    def __repr__(self) -> str:
        state = "finished" if self._finished else "open"
        return (f"McapRecorder('{self.path}', {state}, topics={len(self._channels)}, "
                f"messages={self.message_count})")

    def _check_open(self) -> None:
        if self._finished:
            raise InputError(f"McapRecorder: '{self.path}' is finished; no more writes")

    def register(self, topic: str, msg_type) -> int:
        """Register ``topic`` with message class ``msg_type``; returns the channel id.

        Registering a topic again with the same type returns its id; with another type it is an
        error.
        """
        self._check_open()
        if not isinstance(topic, str) or not topic.startswith("/"):
            raise InputError(f"topic: {topic!r} is not an absolute ROS topic name (e.g. '/adm/x')")
        known = self._channels.get(topic)
        if known is not None:
            if known[1] is not msg_type:
                raise InputError(
                    f"topic: '{topic}' is registered as {'/'.join(type_name(known[1]))}, "
                    f"not {'/'.join(type_name(msg_type))}"
                )
            return known[0]
        schema_id = self._schemas.get(msg_type)
        if schema_id is None:
            name, text = message_definition(msg_type)
            schema_id = self._writer.register_schema(name=name, encoding="ros2msg",
                                                     data=text.encode())
            self._schemas[msg_type] = schema_id
        channel_id = self._writer.register_channel(topic=topic, message_encoding="cdr",
                                                   schema_id=schema_id)
        self._channels[topic] = (channel_id, msg_type)
        self._sequence[channel_id] = 0
        return channel_id

    def write(self, topic: str, msg, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Serialise ``msg`` and add it to ``topic`` (registered on first use).

        Parameters
        ----------
        log_time_ns : int
            Record time in ns; for simulation runs the sim time (``header.stamp``).
        publish_time_ns : int or None
            Publication time in ns; default ``log_time_ns``.
        """
        known = self._channels.get(topic)
        if known is None or known[1] is not type(msg):
            channel_id = self.register(topic, type(msg))
        else:
            self._check_open()
            channel_id = known[0]
        data = self._serialize(msg)
        trim = self._trim.get(type(msg))
        if trim is None:
            trim = self._trim[type(msg)] = _needs_trim(type(msg))
        if trim:
            data = exact_cdr(msg, data)
        self._add(channel_id, data, log_time_ns, publish_time_ns)

    def write_serialized(self, topic: str, data: bytes, log_time_ns: int,
                         publish_time_ns: int | None = None) -> None:
        """Add an already CDR-serialised message (a ``raw=True`` subscription) to a registered
        ``topic``."""
        self._check_open()
        known = self._channels.get(topic)
        if known is None:
            raise InputError(f"topic: '{topic}' is not registered; call register(topic, type)")
        self._add(known[0], bytes(data), log_time_ns, publish_time_ns)

    def _add(self, channel_id: int, data: bytes, log_time_ns, publish_time_ns) -> None:
        log_time = int(log_time_ns)
        if log_time < 0:
            raise InputError(f"log_time_ns: {log_time} ns is out of range; allowed >= 0 ns")
        publish = log_time if publish_time_ns is None else int(publish_time_ns)
        seq = self._sequence[channel_id]
        self._sequence[channel_id] = seq + 1
        self._writer.add_message(channel_id=channel_id, log_time=log_time, data=data,
                                 publish_time=publish, sequence=seq)
        self.message_count += 1

    def write_metadata(self, name: str, data: Mapping[str, object]) -> None:
        """Add a metadata record (run information: bridge, train, model, speeds); values are
        converted with ``str``."""
        self._check_open()
        self._writer.add_metadata(str(name), {str(k): str(v) for k, v in data.items()})

    def flush(self) -> None:
        """Close the open chunk so that everything written so far survives a kill."""
        self._check_open()
        self._writer.flush()

    def finish(self) -> None:
        """Write the summary and close the file (idempotent)."""
        if self._finished:
            return
        self._finished = True
        try:
            self._writer.finish()
        finally:
            self._file.close()


# ---------------------------------------------------------------- reading, salvage


def read_messages(path, topics=None) -> Iterator[tuple[str, int, object]]:
    """Yield ``(topic, log_time_ns, message)`` of a finished MCAP file in log-time order.

    Messages are decoded by mcap-ros2-support from the schemas in the file (attribute access
    like rclpy messages; arrays as lists). A killed writer's file must be :func:`salvage`-d first.
    """
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    path = Path(path)
    if not path.is_file():
        raise InputError(f"path: MCAP file '{path}' does not exist")
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        try:
            for _schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=topics, log_time_order=True
            ):
                yield channel.topic, message.log_time, decoded
        except McapError as exc:
            raise InputError(
                f"path: '{path}' is not a complete MCAP file ({type(exc).__name__}: {exc}); "
                f"recover it with: python -m adm_sim.ros.mcap_log salvage {path} OUT.mcap"
            ) from None


def _recoverable(path: Path):
    """Yield the complete records of a possibly truncated MCAP: ('metadata', rec) first pass,
    then ('message', (schema, channel, message))."""
    import struct

    from mcap.exceptions import McapError
    from mcap.reader import NonSeekingReader

    errors = (McapError, EOFError, struct.error, ValueError, RuntimeError, KeyError)
    with open(path, "rb") as f:
        try:
            for meta in NonSeekingReader(f).iter_metadata():
                yield "metadata", meta
        except errors:
            pass
    with open(path, "rb") as f:
        try:
            for item in NonSeekingReader(f).iter_messages(log_time_order=False):
                yield "message", item
        except errors:
            pass


def salvage(src, dst, overwrite: bool = False) -> int:
    """Recover every complete message of a truncated or killed MCAP into a clean file.

    Parameters
    ----------
    src : path-like
        The damaged (or intact) MCAP.
    dst : path-like
        The new file; refused if it exists unless ``overwrite``.

    Returns
    -------
    int
        Number of messages written to ``dst``. Metadata records are kept.

    Raises
    ------
    InputError
        ``src`` missing, ``dst`` existing or equal to ``src``, or nothing recoverable.
    """
    from mcap.writer import CompressionType, Writer

    src, dst = Path(src), Path(dst)
    if not src.is_file():
        raise InputError(f"src: MCAP file '{src}' does not exist")
    if dst.exists() and (not overwrite or dst.resolve() == src.resolve()):
        raise InputError(f"dst: '{dst}' already exists; refusing to overwrite it")
    tmp = dst.with_name(dst.name + ".part")
    count = 0
    try:
        with open(tmp, "wb") as out:
            writer = Writer(out, chunk_size=1024 * 1024, compression=CompressionType.ZSTD)
            writer.start(profile="ros2", library="adm-sim mcap_log salvage")
            schema_ids: dict[int, int] = {}
            channel_ids: dict[int, int] = {}
            for kind, item in _recoverable(src):
                if kind == "metadata":
                    writer.add_metadata(item.name, dict(item.metadata))
                    continue
                schema, channel, message = item
                if channel.id not in channel_ids:
                    sid = 0
                    if schema is not None:
                        if schema.id not in schema_ids:
                            schema_ids[schema.id] = writer.register_schema(
                                name=schema.name, encoding=schema.encoding, data=schema.data)
                        sid = schema_ids[schema.id]
                    channel_ids[channel.id] = writer.register_channel(
                        topic=channel.topic, message_encoding=channel.message_encoding,
                        schema_id=sid, metadata=dict(channel.metadata))
                writer.add_message(channel_id=channel_ids[channel.id], log_time=message.log_time,
                                   data=message.data, publish_time=message.publish_time,
                                   sequence=message.sequence)
                count += 1
            writer.finish()
        if count == 0:
            raise InputError(f"src: '{src}' holds no complete message to recover")
        os.replace(tmp, dst)
    finally:
        if tmp.exists():
            tmp.unlink()
    return count


# ---------------------------------------------------------------- command line


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line on stderr, exit 2
        self.exit(2, f"error: {message}\n")


def main(argv=None) -> int:
    """``python -m adm_sim.ros.mcap_log salvage IN.mcap OUT.mcap [--overwrite]``."""
    parser = _Parser(prog="python -m adm_sim.ros.mcap_log",
                     description="MCAP tools for adm-sim runs.")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("salvage", help="recover the complete records of a killed run's MCAP")
    p.error = parser.error  # type: ignore[method-assign]
    p.add_argument("src", metavar="IN.mcap")
    p.add_argument("dst", metavar="OUT.mcap")
    p.add_argument("--overwrite", action="store_true", help="replace OUT.mcap if it exists")
    args = parser.parse_args(argv)
    try:
        n = salvage(args.src, args.dst, overwrite=args.overwrite)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"salvaged {n} messages from {args.src} into {args.dst}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
