"""Record ROS 2 messages to MCAP, read them back, salvage the files of killed writers.

Files follow the ROS 2 profile that rosbag2 writes (https://mcap.dev/spec/registry): profile
``ros2``, schema encoding ``ros2msg``, message encoding ``cdr``. Schema text and serialisation
both come from rosbags' ROS 2 Jazzy type store (``Typestore.generate_msgdef``: the definition
with every dependency after a line of 80 ``=`` and ``MSG: pkg/Type``; ``Typestore.serialize_cdr``
reading the rclpy message by attribute). Its CDR has exact lengths: rclpy's ``serialize_message``
reports rmw_fastrtps' *estimated* size, up to 8 bytes too long for an empty ``float64[]``, which
rosbags refuses. The files read with mcap-ros2-support, ``rosbags`` and ``rerun mcap convert``.

Chunks are small (64 KiB before compression by default) and written straight to the operating
system, so a writer killed with SIGKILL loses at most the open chunk; :func:`salvage` recovers
every complete record of such a file and writes a clean one (command line: ``adm-sim salvage
IN.mcap OUT.mcap``). A damaged file (a chunk that no longer decompresses or fails its CRC) is
read chunk by chunk: every readable chunk is recovered, the damaged ones are counted and skipped.
:func:`read_messages` refuses a damaged file with one line pointing to ``salvage``.
"""

from __future__ import annotations

import array
import os
from collections.abc import Iterator, Mapping
from typing import Any
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError

__all__ = [
    "McapRecorder",
    "message_definition",
    "check_intact",
    "read_messages",
    "salvage",
    "type_name",
]

DEFAULT_CHUNK_SIZE = 64 * 1024


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


_TYPESTORE: Any = None  # rosbags Typestore, loaded on first use


def message_definition(msg_type) -> tuple[str, str]:
    """Schema name and ``ros2msg`` text of a message class, from rosbags' ROS 2 Jazzy type store.

    Returns
    -------
    (str, str)
        ``('geometry_msgs/msg/AccelStamped', text)``: the definition followed by each
        dependency once, after a line of 80 ``=`` and ``MSG: pkg/Type`` (the rosbag2 format;
        ``rosbags.typesys`` ``Typestore.generate_msgdef``).
    """
    global _TYPESTORE
    from rosbags.typesys import Stores, get_typestore

    pkg, name = type_name(msg_type)
    full = f"{pkg}/msg/{name}"
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    if full not in _TYPESTORE.types:
        raise InputError(f"msg_type: {full} is not a ROS 2 Jazzy type known to rosbags; "
                         f"allowed the common_interfaces types")
    text, _ = _TYPESTORE.generate_msgdef(full, ros_version=2)
    return full, text


# ---------------------------------------------------------------- writing


class _Fields:
    """An rclpy message as rosbags' CDR serialiser reads its own messages: attribute access, with
    rclpy's ``byte`` scalars (a ``bytes`` of length 1) as integers and its numeric arrays
    (``array.array``) as numpy arrays (a view, no copy)."""

    __slots__ = ("_msg",)

    def __init__(self, msg):
        self._msg = msg

    def __getattr__(self, name):
        value = getattr(self._msg, name)
        if isinstance(value, bytes) and len(value) == 1:
            return value[0]
        if isinstance(value, array.array):
            return np.frombuffer(value, dtype=value.typecode) if len(value) else np.zeros(0, dtype=value.typecode)
        if hasattr(value, "get_fields_and_field_types"):
            return _Fields(value)
        if isinstance(value, list) and value and hasattr(value[0], "get_fields_and_field_types"):
            return [_Fields(v) for v in value]
        return value


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
        self._writer = Writer(self._file, chunk_size=chunk_size,  # type: ignore[arg-type]  # a write()/tell() file
                              compression=kinds[compression])
        self._writer.start(profile="ros2", library="adm-sim mcap_log")
        self._schemas: dict[type, tuple[int, str]] = {}
        self._channels: dict[str, tuple[int, type]] = {}
        self._sequence: dict[str, int] = {}
        self._finished = False
        self.message_count = 0

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

    def register(self, topic: str, msg_type) -> None:
        """Register ``topic`` with message class ``msg_type`` (schema and channel records).
        Registering a topic again with another type is an error.
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
            return
        if msg_type not in self._schemas:
            name, text = message_definition(msg_type)
            self._schemas[msg_type] = (self._writer.register_schema(name=name, encoding="ros2msg",
                                                                    data=text.encode()), name)
        channel_id = self._writer.register_channel(topic=topic, message_encoding="cdr",
                                                   schema_id=self._schemas[msg_type][0])
        self._channels[topic] = (channel_id, msg_type)
        self._sequence[topic] = 0

    def write(self, topic: str, msg, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Serialise ``msg`` (CDR, by rosbags' type store: the one that gave the schema) into
        ``topic`` (registered on first use).

        Parameters
        ----------
        log_time_ns : int
            Record time in ns; for simulation runs the sim time (``header.stamp``).
        publish_time_ns : int or None
            Publication time in ns; default ``log_time_ns``.
        """
        known = self._channels.get(topic)
        if known is None or known[1] is not type(msg):
            self.register(topic, type(msg))
        else:
            self._check_open()
        log_time = int(log_time_ns)
        if log_time < 0:
            raise InputError(f"log_time_ns: {log_time} ns is out of range; allowed >= 0 ns")
        seq = self._sequence[topic]
        self._sequence[topic] = seq + 1
        data = _TYPESTORE.serialize_cdr(_Fields(msg), self._schemas[type(msg)][1])
        self._writer.add_message(channel_id=self._channels[topic][0], log_time=log_time, data=data,
                                 publish_time=log_time if publish_time_ns is None else int(publish_time_ns),
                                 sequence=seq)
        self.message_count += 1

    def write_metadata(self, name: str, data: Mapping[str, object]) -> None:
        """Add a metadata record (run information: bridge, train, model, speeds); values are
        converted with ``str``."""
        self._check_open()
        self._writer.add_metadata(str(name), {str(k): str(v) for k, v in data.items()})

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
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        try:
            for _schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=topics, log_time_order=True
            ):
                yield channel.topic, message.log_time, decoded
        except McapError as exc:
            raise InputError(
                f"path: '{path}' is not a complete MCAP file ({type(exc).__name__}: {exc}); "
                f"recover it with: adm-sim salvage {path} OUT.mcap"
            ) from None
        except _damage_errors() as exc:
            raise InputError(
                f"path: '{path}' is damaged ({type(exc).__name__}: {' '.join(str(exc).split())}); "
                f"recover its readable chunks with: adm-sim salvage {path} OUT.mcap"
            ) from None


def _damage_errors() -> tuple:
    """Exceptions a reader raises on damaged bytes: a chunk that does not decompress (zstd, lz4),
    a failed CRC (a ``ValueError``), records cut short or with impossible lengths."""
    import struct

    from mcap.exceptions import McapError

    from mcap import stream_reader

    errors: list = [McapError, EOFError, struct.error, ValueError, RuntimeError, KeyError, MemoryError]
    for module, name in (("zstandard", "ZstdError"), ("lz4", "LZ4FrameError")):  # the codecs mcap loaded
        exc = getattr(getattr(stream_reader, module, None), name, None)
        if isinstance(exc, type) and issubclass(exc, Exception):
            errors.append(exc)
    return tuple(errors)


def check_intact(path) -> int:
    """The number of messages of the MCAP ``path`` after checking every record's framing and
    every chunk's decompression and CRC (messages are not decoded); :class:`InputError` (one line
    pointing to ``salvage``) when the file is cut short or damaged."""
    report: dict = {}
    n = sum(kind == "message" for kind, _ in _recoverable(Path(path), report))
    if report["truncated"]:
        raise InputError(f"path: '{path}' is not a complete MCAP file (it ends inside a record); "
                         f"recover it with: adm-sim salvage {path} OUT.mcap")
    if report["lost_chunks"] or report["orphan_messages"]:
        raise InputError(f"path: '{path}' is damaged ({report['lost_chunks']} of {report['chunks']} chunks do not "
                         f"decompress or fail their CRC); recover its readable chunks with: "
                         f"adm-sim salvage {path} OUT.mcap")
    return n


def _recoverable(path: Path, report: dict):
    """Yield the records of a truncated or damaged MCAP in file order: ``('metadata', rec)`` and
    ``('message', (schema, channel, message))``.

    The records are read one by one (a chunk as a whole, not decompressed by the reader); each
    chunk is decompressed and checked against its CRC on its own, so a damaged chunk is skipped
    (counted in ``report['lost_chunks']``) and the chunks after it are still read. Reading stops
    at the first record whose framing is broken (a file cut short: ``report['truncated']``).
    Messages whose channel was only declared in a lost chunk are counted in
    ``report['orphan_messages']``.
    """
    from mcap.records import Channel, Chunk, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    errors = _damage_errors()
    report.update(chunks=0, lost_chunks=0, orphan_messages=0, truncated=False)
    schemas: dict = {}
    channels: dict = {}

    def emit(rec):
        if isinstance(rec, Schema):
            schemas[rec.id] = rec
        elif isinstance(rec, Channel):
            channels[rec.id] = rec
        elif isinstance(rec, Message):
            ch = channels.get(rec.channel_id)
            if ch is None:
                report["orphan_messages"] += 1
                return None
            return "message", (schemas.get(ch.schema_id), ch, rec)
        elif isinstance(rec, Metadata):
            return "metadata", rec
        return None

    with open(path, "rb") as f:
        reader = StreamReader(f, emit_chunks=True, record_size_limit=max(1, path.stat().st_size))
        records = iter(reader.records)
        while True:
            try:
                rec = next(records)
            except StopIteration:
                break
            except errors:
                report["truncated"] = True
                break
            if isinstance(rec, Chunk):
                report["chunks"] += 1
                try:
                    inner = breakup_chunk(rec, validate_crc=True)
                except errors:
                    report["lost_chunks"] += 1
                    continue
                for r in inner:
                    out = emit(r)
                    if out is not None:
                        yield out
            else:
                out = emit(rec)
                if out is not None:
                    yield out


def salvage(src, dst, overwrite: bool = False, report: dict | None = None) -> int:
    """Recover every complete message of a truncated, killed or damaged MCAP into a clean file.

    Parameters
    ----------
    src : path-like
        The damaged (or intact) MCAP.
    dst : path-like
        The new file; refused if it exists unless ``overwrite``.
    report : dict or None
        Filled with ``chunks`` (read), ``lost_chunks`` (damaged, skipped), ``orphan_messages``
        (whose channel was in a lost chunk) and ``truncated`` (the file ends mid-record).

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
    tmp = dst.with_name(f"{dst.name}.part-{os.getpid()}")  # one per salvage run
    count = 0
    try:
        with open(tmp, "wb") as out:
            writer = Writer(out, chunk_size=1024 * 1024, compression=CompressionType.ZSTD)
            writer.start(profile="ros2", library="adm-sim mcap_log salvage")
            schema_ids: dict[int, int] = {}
            channel_ids: dict[int, int] = {}
            for kind, item in _recoverable(src, report if report is not None else {}):
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
