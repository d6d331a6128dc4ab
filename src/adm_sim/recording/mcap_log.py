"""Record ROS 2 messages to MCAP, read them back, salvage the files of killed writers.

Files follow the ROS 2 profile that rosbag2 writes (https://mcap.dev/spec/registry): profile
``ros2``, schema encoding ``ros2msg``, message encoding ``cdr``. Schema text and serialisation
both come from rosbags' ROS 2 Jazzy type store (``Typestore.generate_msgdef``: the definition
with every dependency after a line of 80 ``=`` and ``MSG: pkg/Type``; ``Typestore.serialize_cdr``
reading the rclpy message by attribute). Its CDR has exact lengths: rclpy's ``serialize_message``
reports rmw_fastrtps' *estimated* size, up to 8 bytes too long for an empty ``float64[]``, which
rosbags refuses. The files read with mcap-ros2-support, ``rosbags`` and ``rerun mcap convert``.

Each channel carries ``offered_qos_profiles`` as rosbag2 writes it (:func:`qos_profiles_yaml`),
the QoS of the topic's class (:data:`QOS_CLASSES`) unless the caller gives its own.

Chunks are small (64 KiB before compression by default) and written straight to the operating
system, so a writer killed with SIGKILL loses at most the open chunk; the recorder also writes the
data-section CRC (header, metadata, message indexes). Every reader checks a file first
(:func:`scan`, :func:`checked_scan`): record framing, chunk decompression and CRC, summary and
data-section CRC; a damaged place is named with its offset and the messages lost there per topic,
and reading goes on at the next intact chunk. :func:`read_messages` refuses a damaged file with one
line unless asked to skip the damage; :func:`salvage` writes every intact message of a killed or
damaged file into a clean one (command line: ``adm-sim salvage IN.mcap OUT.mcap``).
"""

from __future__ import annotations

import array
import contextlib
import io
import os
import struct
import zlib
from collections import Counter
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from adm_sim import protocol as P
from adm_sim.errors import InputError, RunError

__all__ = [
    "McapRecorder",
    "QOS_CLASSES",
    "parse_qos_profiles",
    "qos_profiles_yaml",
    "topic_qos",
    "message_definition",
    "Damage",
    "Scan",
    "check_intact",
    "checked_scan",
    "decode_messages",
    "sorted_messages",
    "iter_raw_messages",
    "scan",
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
    from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    pkg, name = type_name(msg_type)
    full = f"{pkg}/msg/{name}"
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    if full not in _TYPESTORE.types:
        raise InputError(f"msg_type: {full} is not a ROS 2 Jazzy type known to rosbags; "
                         f"allowed the common_interfaces types")
    text, _ = _TYPESTORE.generate_msgdef(full, ros_version=2)
    return full, text


# ---------------------------------------------------------------- QoS metadata

#: The QoS of each class of :data:`adm_sim.protocol.TOPICS` as the nodes offer it
#: (:mod:`adm_sim.nodes.common`, ``QOS_*``; a test keeps the two equal): ``(history, depth,
#: reliability, durability)`` in rosbag2's lower-case names.
QOS_CLASSES = {
    "C": ("keep_last", 100, "reliable", "volatile"),
    "X": ("keep_last", 16, "reliable", "volatile"),
    "M": ("keep_last", 5000, "reliable", "volatile"),
    "L": ("keep_last", 1, "reliable", "transient_local"),
    "H": ("keep_last", 1000, "reliable", "transient_local"),
}
#: rclpy's default profile (``depth=10``), for a topic of no known class.
QOS_DEFAULT = ("keep_last", 10, "reliable", "volatile")
#: An unset (infinite) duration as rmw reports an offered profile and rosbag2 writes it.
_INFINITE = (9223372036, 854775807)


def topic_qos(topic: str) -> tuple[str, int, str, str]:
    """``(history, depth, reliability, durability)`` of an adm-sim topic by its class in
    :data:`adm_sim.protocol.TOPICS` (also under a namespace: ``/b1/adm/midspan/accel``), else
    :data:`QOS_DEFAULT`."""

    entry = P.TOPICS.get(topic)
    if entry is None:
        entry = next((P.TOPICS[k] for k in sorted(P.TOPICS, key=len, reverse=True) if topic.endswith(k)), None)
    return QOS_CLASSES.get(entry[1], QOS_DEFAULT) if entry is not None else QOS_DEFAULT


def _qos_tuple(qos) -> tuple[str, int, str, str]:
    """A QoS given as a tuple, a dict with rosbag2's keys, or an rclpy ``QoSProfile`` (read by
    attribute: its policies' ``name``)."""
    if isinstance(qos, tuple):
        return qos
    if isinstance(qos, Mapping):
        return (str(qos["history"]), int(qos["depth"]), str(qos["reliability"]), str(qos["durability"]))
    return (qos.history.name.lower(), int(qos.depth), qos.reliability.name.lower(), qos.durability.name.lower())


def qos_profiles_yaml(qos) -> str:
    """``offered_qos_profiles`` of an MCAP channel as rosbag2 (Jazzy, metadata version 9) writes it:
    a YAML list with one profile per publisher, policies by name, durations as ``sec``/``nsec``
    (an unset duration as rmw's infinite, 9223372036 s 854775807 ns).

    Parameters
    ----------
    qos : tuple, dict or rclpy QoSProfile
        ``(history, depth, reliability, durability)``, e.g. ``('keep_last', 1, 'reliable',
        'transient_local')``.
    """
    history, depth, reliability, durability = _qos_tuple(qos)
    sec, nsec = _INFINITE
    duration = f"\n    sec: {sec}\n    nsec: {nsec}"
    return (f"- history: {history}\n  depth: {depth}\n  reliability: {reliability}\n"
            f"  durability: {durability}\n  deadline:{duration}\n  lifespan:{duration}\n"
            f"  liveliness: automatic\n  liveliness_lease_duration:{duration}\n"
            f"  avoid_ros_namespace_conventions: false")


def parse_qos_profiles(text: str) -> tuple[str, int, str, str] | None:
    """The first profile of an ``offered_qos_profiles`` text as ``(history, depth, reliability,
    durability)`` (lower-case names; rosbag2 also writes the enums as integers in older versions),
    or ``None`` when the text holds none."""
    import yaml  # noqa: PLC0415  yaml only when a log is read or written

    try:
        items = yaml.safe_load(text) if text else None
    except yaml.YAMLError:
        return None
    if not isinstance(items, list) or not items or not isinstance(items[0], dict):
        return None
    first = items[0]
    by_int = {"history": {0: "system_default", 1: "keep_last", 2: "keep_all"},
              "reliability": {0: "system_default", 1: "reliable", 2: "best_effort"},
              "durability": {0: "system_default", 1: "transient_local", 2: "volatile"}}

    def name(key, default):
        value = first.get(key, default)
        return by_int[key].get(value, default) if isinstance(value, int) else str(value).lower()

    try:
        depth = int(first.get("depth", 10))
    except (TypeError, ValueError):
        depth = 10
    return (name("history", "keep_last"), depth, name("reliability", "reliable"), name("durability", "volatile"))


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
        from mcap.writer import CompressionType, Writer  # noqa: PLC0415  mcap/rosbags only when a log is read or written

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
                              compression=kinds[compression], enable_data_crcs=True)
        self._writer.start(profile="ros2", library="adm-sim mcap_log")
        self._schemas: dict[type, tuple[int, str]] = {}
        self._channels: dict[str, tuple[int, type]] = {}
        self._sequence: dict[str, int] = {}
        self._finished = False
        self.failed: str | None = None
        self.message_count = 0

    def _failed(self, exc: OSError):
        """A write that failed (a full disk, a file over ``ulimit -f``): the file cannot be whole,
        so nothing stays under its name; one line for the run's failure."""
        if self.failed is None:
            self.failed = exc.strerror or str(exc)
            self._finished = True
            self._file.close()
            with contextlib.suppress(OSError):
                self.path.unlink()
        return RunError(f"recording '{self.path}': cannot write ({self.failed}); the incomplete file was removed")

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
        if self.failed is not None:
            raise RunError(f"recording '{self.path}': cannot write ({self.failed}); the incomplete file was removed")
        if self._finished:
            raise InputError(f"McapRecorder: '{self.path}' is finished; no more writes")

    def register(self, topic: str, msg_type, qos=None) -> None:
        """Register ``topic`` with message class ``msg_type`` (schema and channel records).
        Registering a topic again with another type is an error.

        The channel carries ``offered_qos_profiles`` as rosbag2 writes it
        (:func:`qos_profiles_yaml`): ``qos`` (an rclpy ``QoSProfile``, a dict or a tuple, see
        there) when given, else the QoS of the topic's class in :data:`adm_sim.protocol.TOPICS`
        (:func:`topic_qos`), so a replay publishes it as the run did (descriptions latched).
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
        profiles = qos_profiles_yaml(topic_qos(topic) if qos is None else qos)
        channel_id = self._writer.register_channel(topic=topic, message_encoding="cdr",
                                                   schema_id=self._schemas[msg_type][0],
                                                   metadata={"offered_qos_profiles": profiles})
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
        self._channel(topic, type(msg))
        data = _TYPESTORE.serialize_cdr(_Fields(msg), self._schemas[type(msg)][1])
        self._add(topic, data, log_time_ns, publish_time_ns)

    def write_serialized(self, topic: str, msg_type, data: bytes, log_time_ns: int) -> None:
        """Write a message already serialised (CDR, e.g. as a subscription with ``raw=True`` takes
        it from the middleware) into ``topic`` of type ``msg_type``: the bytes as they came,
        nothing decoded or encoded again (as rosbag2 records). Otherwise as :meth:`write`."""
        self._channel(topic, msg_type)
        self._add(topic, bytes(data), log_time_ns, None)

    def _channel(self, topic, msg_type):
        """Register ``topic`` for ``msg_type`` on first use (or a new type), else check the writer is open."""
        known = self._channels.get(topic)
        if known is None or known[1] is not msg_type:
            self.register(topic, msg_type)
        else:
            self._check_open()

    def _add(self, topic, data, log_time_ns, publish_time_ns):
        """Add the serialised ``data`` to ``topic`` with the next sequence number; a refused write fails the writer."""
        log_time = int(log_time_ns)
        if log_time < 0:
            raise InputError(f"log_time_ns: {log_time} ns is out of range; allowed >= 0 ns")
        seq = self._sequence[topic]
        self._sequence[topic] = seq + 1
        try:
            self._writer.add_message(channel_id=self._channels[topic][0], log_time=log_time, data=data,
                                     publish_time=log_time if publish_time_ns is None else int(publish_time_ns),
                                     sequence=seq)
        except OSError as exc:
            raise self._failed(exc) from None
        self.message_count += 1

    def write_metadata(self, name: str, data: Mapping[str, object]) -> None:
        """Add a metadata record (run information: bridge, train, model, speeds); values are
        converted with ``str``."""
        self._check_open()
        try:
            self._writer.add_metadata(str(name), {str(k): str(v) for k, v in data.items()})
        except OSError as exc:
            raise self._failed(exc) from None

    def finish(self) -> None:
        """Write the summary and close the file (idempotent).

        Raises
        ------
        RunError
            The summary could not be written (or an earlier write failed): the file is removed.
        """
        if self.failed is not None:
            raise RunError(f"recording '{self.path}': cannot write ({self.failed}); the incomplete file was removed")
        if self._finished:
            return
        self._finished = True
        try:
            self._writer.finish()
        except OSError as exc:
            raise self._failed(exc) from None
        finally:
            self._file.close()


# ---------------------------------------------------------------- reading, integrity

_MAGIC = b"\x89MCAP0\r\n"
#: records of the data section: header (first), schema, channel, message, chunk, message index,
#: attachment, metadata, data end
_DATA_OPS = frozenset((0x01, 0x03, 0x04, 0x05, 0x06, 0x07, 0x09, 0x0C, 0x0F))
_CHUNK, _MESSAGE_INDEX, _DATA_END, _FOOTER = 0x06, 0x07, 0x0F, 0x02


@dataclass
class Damage:
    """One damaged place of an MCAP file.

    Attributes
    ----------
    offset : int
        Byte offset of the damaged record (a chunk's opcode) or region.
    what : str
        What is wrong (``chunk fails its CRC``, ``chunk does not decompress``, ``broken record
        framing``, ``summary fails its CRC``, ...).
    lost : dict
        Messages lost there per topic (from the message indexes that follow a chunk); empty when
        nothing was lost, ``None`` when the count is unknown.
    """

    offset: int
    what: str
    lost: dict | None = field(default_factory=dict)

    @property
    def messages(self) -> int | None:
        return None if self.lost is None else sum(self.lost.values())

    def describe(self) -> str:
        if self.lost is None:
            loss = "messages lost: unknown"
        elif not self.lost:
            loss = "no message lost"
        else:
            loss = (f"{self.messages} messages lost ("
                    + ", ".join(f"{t} {n}" for t, n in sorted(self.lost.items())) + ")")
        return f"{self.what} at byte {self.offset}: {loss}"


@dataclass
class Scan:
    """What :func:`scan` found: every readable message (file order), the metadata records and the
    damage. ``expected`` is the number of messages per topic the file's statistics state (``None``
    without an intact summary)."""

    path: Path
    chunks: int = 0
    damage: list = field(default_factory=list)
    truncated: bool = False
    messages: list = field(default_factory=list)  # (schema, channel, message)
    metadata: list = field(default_factory=list)
    expected: dict | None = None
    orphan_messages: int = 0
    footer_ok: bool = False

    @property
    def damaged(self) -> bool:
        return bool(self.damage) or self.truncated

    @property
    def lost_chunks(self) -> int:
        return sum(d.what.startswith("chunk") or d.what.startswith("broken") for d in self.damage)

    def recovered(self) -> dict:
        return dict(Counter(ch.topic for _s, ch, _m in self.messages))

    def missing(self) -> dict | None:
        """Messages per topic the statistics count and no intact chunk holds (``None`` without
        statistics)."""
        if self.expected is None:
            return None
        got = self.recovered()
        return {t: n - got.get(t, 0) for t, n in self.expected.items() if n > got.get(t, 0)}

    def lines(self) -> list[str]:
        """One line per damage, then the total lost (by the statistics when there are some)."""
        out = [d.describe() for d in self.damage]
        if self.truncated:
            out.append("the file ends inside a record (a writer stopped mid-chunk): the messages of that "
                       "chunk are lost")
        missing = self.missing()
        if missing and self.expected is not None:
            out.append(f"in all {sum(missing.values())} of {sum(self.expected.values())} recorded messages lost ("
                       + ", ".join(f"{t} {n}" for t, n in sorted(missing.items())) + ")")
        return out

    def first(self) -> str:
        if self.damage:
            return self.damage[0].describe()
        return "the file ends inside a record"


def _u(data, pos, n):
    return int.from_bytes(data[pos:pos + n], "little")


def _decompress(compression: str, raw: bytes, size: int) -> bytes:
    from mcap import stream_reader  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    if compression == "zstd":
        return stream_reader.zstandard.ZstdDecompressor().decompress(raw, max_output_size=size)
    if compression == "lz4":
        return stream_reader.lz4.decompress(raw)
    if compression == "":
        return raw
    raise ValueError(f"unknown compression {compression!r}")


def _parse_chunk(data, pos: int, end: int, check_length: bool = True, records_end: int | None = None):
    """The records inside the Chunk record at ``pos`` (decompressed, CRC checked) or a reason.
    ``records_end``: read the compressed records up to there instead of by their own length field."""

    body = pos + 9
    length = _u(data, pos + 1, 8)
    if body + 32 > end:
        return None, "broken record framing"
    size, crc = _u(data, body + 16, 8), _u(data, body + 24, 4)
    n_comp = _u(data, body + 28, 4)
    if n_comp > 16 or body + 32 + n_comp + 8 > end:
        return None, "chunk header is damaged"
    try:
        compression = bytes(data[body + 32:body + 32 + n_comp]).decode()
    except UnicodeDecodeError:
        return None, "chunk header is damaged"
    at = body + 32 + n_comp
    n_rec = _u(data, at, 8) if records_end is None else records_end - (at + 8)
    if n_rec < 0 or at + 8 + n_rec > end or (check_length and at + 8 + n_rec != body + length):
        return None, "broken record framing"
    if size > 1 << 34:
        return None, "chunk header is damaged"
    try:
        raw = _decompress(compression, bytes(data[at + 8:at + 8 + n_rec]), size)
    except Exception:
        return None, "chunk does not decompress"
    if len(raw) != size:
        return None, "chunk does not decompress"
    if crc == 0:
        return None, "chunk has no CRC to check"
    if zlib.crc32(raw) != crc:
        return None, "chunk fails its CRC"
    return raw, None


_RECORD_HEAD = struct.Struct("<BQ")  # a record's opcode and length
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")  # ... and a Message's channel id, sequence, log time, publish time


def _inner_records(raw: bytes):
    """The schema, channel and message records inside a decompressed chunk, in order. Messages
    (nearly every record) are read here by the specification's layout, into mcap's own
    ``Message``, as mcap's ``Message.read`` reads them (a record shorter than its 22-byte head is
    damaged); schemas and channels by mcap's readers. Raises on a record cut short."""
    from mcap.data_stream import ReadDataStream  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    from mcap.records import Channel, Message, Schema  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    out: list = []
    append, record_head, message_head = out.append, _RECORD_HEAD.unpack_from, _MESSAGE_HEAD.unpack_from
    q, n = 0, len(raw)
    while q < n:
        if q + 9 > n:
            raise ValueError("record cut short inside a chunk")
        op, length = record_head(raw, q)
        body, end = q + 9, q + 9 + length
        if end > n:
            raise ValueError("record cut short inside a chunk")
        if op == 0x05:
            if length < 22:
                raise ValueError("message record shorter than its head")
            _op, _length, channel_id, sequence, log_time, publish_time = message_head(raw, q)
            # Message's fields in mcap's order: channel_id, log_time, data, publish_time, sequence
            append(Message(channel_id, log_time, raw[body + 22:end], publish_time, sequence))
        elif op == 0x04:
            append(Channel.read(ReadDataStream(io.BytesIO(raw[body:end]))))
        elif op == 0x03:
            append(Schema.read(ReadDataStream(io.BytesIO(raw[body:end]))))
        q = end
    return out


def _next_chunk(data, start: int, end: int) -> int | None:
    """Offset of the next intact Chunk record at or after ``start`` (found by its opcode and a
    header, decompression and CRC that check out), or None."""
    pos = start
    while True:
        pos = data.find(b"\x06", pos, end)
        if pos < 0:
            return None
        if pos + 9 + 32 <= end:
            raw, why = _parse_chunk(data, pos, end)
            if why is None:
                return pos
        pos += 1


def _record_starts_at(data, pos: int, end: int) -> bool:
    """A data-section record's framing at ``pos``: a known opcode and a length within ``end``."""
    if pos + 9 > end or data[pos] not in _DATA_OPS:
        return False
    length = _u(data, pos + 1, 8)
    return pos + 9 + length <= end and (data[pos] != _MESSAGE_INDEX or _index_ok(data, pos, length))


def _index_ok(data, pos: int, length: int) -> bool:
    """A MessageIndex record's own framing: channel id, then ``length - 6`` bytes of 16-byte entries."""
    return length >= 6 and _u(data, pos + 11, 4) == length - 6 and (length - 6) % 16 == 0


def _message_index_counts(data, pos: int, end: int):
    """Counts per channel id of the MessageIndex records starting at ``pos`` (as the writer puts
    them right after their chunk), and the offset after them."""
    counts: dict = {}
    while pos + 9 <= end and data[pos] == _MESSAGE_INDEX:
        length = _u(data, pos + 1, 8)
        if pos + 9 + length > end or length < 8:
            break
        channel_id, n_bytes = _u(data, pos + 9, 2), _u(data, pos + 11, 4)
        if n_bytes != length - 6 or n_bytes % 16:
            break
        counts[channel_id] = counts.get(channel_id, 0) + n_bytes // 16
        pos += 9 + length
    return counts, pos


def _read_summary(data, scan: Scan):
    """Schemas, channels and statistics of the summary section, if its CRC holds; the start of
    the summary (or of the footer) as the end of the data section."""

    from mcap.data_stream import ReadDataStream  # noqa: PLC0415  mcap/rosbags only when a log is read or written
    from mcap.records import Channel, Schema, Statistics  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    n = len(data)
    foot = n - 8 - 29
    if n < 8 + 29 + 8 or bytes(data[n - 8:]) != _MAGIC or data[foot] != _FOOTER or _u(data, foot + 1, 8) != 20:
        return None, None, n
    scan.footer_ok = True
    summary_start, crc = _u(data, foot + 9, 8), _u(data, foot + 25, 4)
    section = summary_start if 8 <= summary_start <= foot else foot
    if summary_start and not 8 <= summary_start <= foot:
        scan.damage.append(Damage(foot, "footer is damaged", {}))
        return None, None, foot
    if crc and zlib.crc32(bytes(data[section:foot + 25])) != crc:
        scan.damage.append(Damage(section, "summary fails its CRC", {}))
        return None, None, section
    schemas, channels, stats = {}, {}, None
    pos = section
    while pos + 9 <= foot:
        op, length = data[pos], _u(data, pos + 1, 8)
        stream = ReadDataStream(io.BytesIO(bytes(data[pos + 9:pos + 9 + length])))
        try:
            if op == 0x03:
                rec = Schema.read(stream)
                schemas[rec.id] = rec
            elif op == 0x04:
                rec = Channel.read(stream)
                channels[rec.id] = rec
            elif op == 0x0B:
                stats = Statistics.read(stream)
        except Exception:
            break
        pos += 9 + length
    if stats is not None:
        scan.expected = {}
        for cid, count in stats.channel_message_counts.items():
            if cid in channels and count:
                topic = channels[cid].topic
                scan.expected[topic] = scan.expected.get(topic, 0) + count
    return schemas, channels, section


def scan(path) -> Scan:
    """Read every record of the MCAP ``path`` and check it: the chunks' framing, decompression and
    CRC, the summary's CRC and the data section's CRC when the writer wrote one.

    A damaged chunk is recorded with its offset and the messages lost per topic (from the message
    indexes after it) and the reading goes on with the next intact chunk (found by its own framing
    and CRC, so a broken record length does not end the reading). A file cut short (a killed
    writer) is ``truncated``. Nothing is decoded.
    """
    from mcap.records import Channel, Message, Schema  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    path = Path(path)
    data = path.read_bytes()
    result = Scan(path)
    if bytes(data[:8]) != _MAGIC:
        result.damage.append(Damage(0, "file magic is damaged", {}))
    sum_schemas, sum_channels, end = _read_summary(data, result)
    schemas: dict = dict(sum_schemas or {})
    channels: dict = dict(sum_channels or {})
    # the data section ends at its DataEnd record, right before the summary (when the footer holds)
    limit = end
    if result.footer_ok and end >= 8 + 13 and data[end - 13] == _DATA_END and _u(data, end - 12, 8) == 4:
        limit = end - 13

    verified = 8  # end of the last chunk whose CRC held: nothing before it is read again

    def resume(after: int) -> int | None:
        """Where reading goes on after damage: the next intact chunk after the last verified one
        (a damaged length of an unchecked record may have jumped over intact chunks), else the
        data section's end record (when the footer locates it)."""
        nxt = _next_chunk(data, min(after, verified), limit)
        if nxt is not None:
            return nxt
        return limit if limit < end else None

    def take(rec):
        if isinstance(rec, Schema):
            schemas.setdefault(rec.id, rec)
        elif isinstance(rec, Channel):
            channels.setdefault(rec.id, rec)
        else:
            ch = channels.get(rec.channel_id)
            if ch is None:
                result.orphan_messages += 1
            else:
                result.messages.append((schemas.get(ch.schema_id), ch, rec))

    pos: int | None = 8
    data_end = None
    while pos is not None and pos < end:
        if pos + 9 > end:
            result.truncated = True
            break
        op, length = data[pos], _u(data, pos + 1, 8)
        rec_end = pos + 9 + length
        if op not in _DATA_OPS or rec_end > end or (op == 0x01) != (pos == 8) or (
                op == _MESSAGE_INDEX and not _index_ok(data, pos, length)) or (op == _DATA_END and length != 4):
            nxt = resume(pos + 1)
            if nxt is None and op in _DATA_OPS and rec_end > end and not result.footer_ok:
                result.truncated = True  # a killed writer's last record
                break
            result.damage.append(Damage(pos, "broken record framing", None))
            pos = nxt
            continue
        if op == _CHUNK:
            result.chunks += 1
            raw, why = _parse_chunk(data, pos, end)
            inner_end = rec_end
            if why == "broken record framing":  # the record length disagrees with the chunk's own sizes
                raw, why2 = _parse_chunk(data, pos, end, check_length=False)
                if why2 is None:  # the contents check out by their own length: one of the two lengths is damaged
                    n_comp = _u(data, pos + 9 + 28, 4)
                    inner_end = pos + 9 + 32 + n_comp + 8 + _u(data, pos + 9 + 32 + n_comp, 8)
                    what = "chunk record length is damaged"
                    # zstd stops at the end of its frame, so a records length enlarged by damage still
                    # decompresses: when the outer length also holds the contents, it is the records
                    # length that is damaged, and the chunk ends where its record says (a reading on
                    # from the enlarged length would jump over intact chunks)
                    raw_outer, why3 = None, "not tried"
                    if not _record_starts_at(data, inner_end, end) and _record_starts_at(data, rec_end, end):
                        raw_outer, why3 = _parse_chunk(data, pos, end, records_end=rec_end)
                    if why3 is None:
                        raw, inner_end, what = raw_outer, rec_end, "chunk's records length is damaged"
                    result.damage.append(Damage(pos, f"{what} (its contents pass their CRC and are kept)", {}))
                    why = None
            records: list = []
            if why is None:
                try:
                    records = _inner_records(raw)
                except Exception:
                    why = "chunk's records are damaged"
            if why is None:
                for rec in records:
                    ch = channels.get(rec.channel_id) if type(rec) is Message else None
                    if ch is None:
                        take(rec)  # a schema, a channel or a message on no known channel
                    else:  # a message (nearly every record), as take() files it
                        result.messages.append((schemas.get(ch.schema_id), ch, rec))
                pos = verified = inner_end
                continue
            if why == "broken record framing":
                result.damage.append(Damage(pos, why, None))
                pos = resume(pos + 1)
                continue
            counts, after = _message_index_counts(data, rec_end, limit)
            result.damage.append(Damage(pos, why, {channels[c].topic if c in channels else f"channel {c}": k
                                                   for c, k in counts.items()} if counts else None))
            pos = after
            continue
        if op == _DATA_END:
            data_end = pos
            crc = _u(data, pos + 9, 4)
            if crc and zlib.crc32(data[:pos]) != crc and not result.damage:
                result.damage.append(Damage(0, "data section fails its CRC (outside the chunks: header, "
                                               "metadata or message indexes)", {}))
            break
        if op in (0x01, 0x03, 0x04, 0x05, 0x0C):
            try:
                rec = _read_record(data, pos, op, length)
            except Exception:
                result.damage.append(Damage(pos, "record is damaged", None))
                pos = resume(pos + 1)
                continue
            if op == 0x0C:
                result.metadata.append(rec)
            elif op != 0x01:
                take(rec)
        pos = rec_end
    _settle_damage(result, data_end)
    return result


def _read_record(data, pos: int, op: int, length: int):
    """The header, schema, channel, message or metadata record (``op``) at ``pos``, read by mcap's
    own record readers; raises when it does not read back to its stated length."""
    from mcap.data_stream import ReadDataStream  # noqa: PLC0415  mcap/rosbags only when a log is read or written
    from mcap.records import Channel, Header, Message, Metadata, Schema  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    stream = ReadDataStream(io.BytesIO(data[pos + 9:pos + 9 + length]))
    reader = {0x01: Header.read, 0x03: Schema.read, 0x04: Channel.read, 0x0C: Metadata.read}.get(op)
    rec = Message.read(stream, length) if reader is None else reader(stream)
    if op != 0x05 and stream.count != length:
        raise ValueError("record length")
    return rec


def _settle_damage(result: Scan, data_end: int | None) -> None:
    """After the walk: a file without the end of its data section is truncated, a lost summary or
    footer is named, and the statistics say what the damaged places without an index held."""
    if data_end is None and not any(d.what == "broken record framing" for d in result.damage):
        result.truncated = True  # no end of the data section: the writer did not finish the file
    if data_end is not None and not result.footer_ok and not any(d.what.startswith(("summary", "footer"))
                                                                 for d in result.damage):
        result.damage.append(Damage(data_end, "summary or footer is damaged", {}))
    missing = result.missing()
    unknown = [d for d in result.damage if d.lost is None]
    if missing is not None and unknown:  # the statistics account for what the damaged places held
        known: dict = {}
        for d in result.damage:
            for t, k in (d.lost or {}).items():
                known[t] = known.get(t, 0) + k
        rest = {t: n - known.get(t, 0) for t, n in missing.items() if n > known.get(t, 0)}
        if not rest:
            for d in unknown:
                d.lost = {}
        elif len(unknown) == 1:
            unknown[0].lost = rest


def _refusal(path, s: Scan) -> InputError:
    if s.truncated and not s.damage:
        return InputError(f"path: '{path}' is not a complete MCAP file (it ends inside a record); "
                          f"recover it with: adm-sim salvage {path} OUT.mcap")
    n = len(s.damage)
    chunks = (f"{s.lost_chunks} of {s.chunks} chunks do not decompress or fail their CRC; " if s.lost_chunks
              else "")
    return InputError(f"path: '{path}' is damaged ({chunks}{s.first()}{f'; and {n - 1} more' if n > 1 else ''}); "
                      f"recover its readable chunks with: adm-sim salvage {path} OUT.mcap")


def checked_scan(path, skip_damaged: bool = False, warn=None) -> Scan:
    """:func:`scan` of ``path``; damage is an :class:`InputError` (one line naming the first damaged
    place) unless ``skip_damaged``, then each line of :meth:`Scan.lines` goes to ``warn``."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"path: MCAP file '{path}' does not exist")
    s = scan(path)
    if s.damaged:
        if not skip_damaged:
            raise _refusal(path, s)
        for line in s.lines():
            (warn or (lambda text: None))(f"skipped damage in '{path}': {line}")
    return s


def iter_raw_messages(path, skip_damaged: bool = False, warn=None, topics=None):
    """``(schema, channel, message)`` of every intact message in log-time order (file order among
    equal times), after :func:`checked_scan`."""
    yield from sorted_messages(checked_scan(path, skip_damaged, warn), topics)


def read_messages(path, topics=None, skip_damaged: bool = False, warn=None) -> Iterator[tuple[str, int, object]]:
    """Yield ``(topic, log_time_ns, message)`` of an MCAP file in log-time order, every chunk's
    framing, decompression and CRC checked first (:func:`checked_scan`): a damaged or cut-short file
    is one :class:`InputError` naming the damage, unless ``skip_damaged`` (then its intact chunks
    are read and each skipped damage is handed to ``warn``).

    Messages are decoded by mcap-ros2-support from the schemas in the file (attribute access
    like rclpy messages; arrays as lists).
    """
    yield from decode_messages(iter_raw_messages(path, skip_damaged, warn, topics), path)


def sorted_messages(found: Scan, topics=None) -> list:
    """The intact ``(schema, channel, message)`` of a :class:`Scan` in log-time order (file order
    among equal times)."""
    items = [m for m in found.messages if topics is None or m[1].topic in topics]
    items.sort(key=lambda m: m[2].log_time)  # stable
    return items


def decode_messages(items, path="the recording") -> Iterator[tuple[str, int, object]]:
    """``(topic, log_time_ns, decoded message)`` of raw ``(schema, channel, message)`` items."""
    from mcap_ros2.decoder import DecoderFactory  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    factory = DecoderFactory()
    decoders: dict = {}
    for schema, channel, message in items:
        dec = decoders.get(channel.id)
        if dec is None:
            dec = decoders[channel.id] = factory.decoder_for(channel.message_encoding, schema)
        if dec is None:
            raise InputError(f"path: '{path}': no decoder for '{channel.topic}' "
                             f"({channel.message_encoding}, schema {getattr(schema, 'name', None)})")
        try:
            decoded = dec(message.data)
        except Exception as exc:
            raise InputError(f"path: '{path}': a message of '{channel.topic}' at {message.log_time} ns does "
                             f"not decode ({type(exc).__name__}); the file was written wrongly") from None
        yield channel.topic, message.log_time, decoded


def check_intact(path) -> int:
    """The number of messages of the MCAP ``path`` after checking every record's framing and
    every chunk's decompression and CRC (messages are not decoded); :class:`InputError` (one line
    naming the damage and pointing to ``salvage``) when the file is cut short or damaged."""
    return len(checked_scan(path).messages)


def salvage(src, dst, overwrite: bool = False, report: dict | None = None) -> int:
    """Recover every intact message of a truncated, killed or damaged MCAP into a clean file.

    Every chunk is checked (:func:`scan`); a damaged one is skipped and the reading goes on with
    every intact chunk after it.

    Parameters
    ----------
    src : path-like
        The damaged (or intact) MCAP.
    dst : path-like
        The new file; refused if it exists unless ``overwrite``.
    report : dict or None
        Filled with ``chunks`` (read), ``lost_chunks`` (damaged, skipped), ``orphan_messages``
        (whose channel was in a lost chunk), ``truncated`` (the file ends mid-record or was not
        finished) and ``damage`` (the lines of :meth:`Scan.lines`: each damaged place with its
        offset, topics and messages lost).

    Returns
    -------
    int
        Number of messages written to ``dst``. Metadata records are kept.

    Raises
    ------
    InputError
        ``src`` missing, ``dst`` existing or equal to ``src``, or nothing recoverable.
    """
    from mcap.writer import CompressionType, Writer  # noqa: PLC0415  mcap/rosbags only when a log is read or written

    src, dst = Path(src), Path(dst)
    if not src.is_file():
        raise InputError(f"src: MCAP file '{src}' does not exist")
    if dst.exists() and (not overwrite or dst.resolve() == src.resolve() or os.path.samefile(dst, src)):
        raise InputError(f"dst: '{dst}' already exists; refusing to overwrite it")
    found = scan(src)
    if report is not None:
        report.update(chunks=found.chunks, lost_chunks=found.lost_chunks, orphan_messages=found.orphan_messages,
                      truncated=found.truncated, damage=found.lines())
    if not found.messages:
        raise InputError(f"src: '{src}' holds no complete message to recover")
    tmp = dst.with_name(f"{dst.name}.part-{os.getpid()}")  # one per salvage run
    try:
        with open(tmp, "wb") as out:
            writer = Writer(out, chunk_size=1024 * 1024, compression=CompressionType.ZSTD, enable_data_crcs=True)
            writer.start(profile="ros2", library="adm-sim mcap_log salvage")
            for item in found.metadata:
                writer.add_metadata(item.name, dict(item.metadata))
            schema_ids: dict[int, int] = {}
            channel_ids: dict[int, int] = {}
            for schema, channel, message in found.messages:
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
            writer.finish()
        os.replace(tmp, dst)
    except OSError as exc:  # a full disk, ulimit -f: the file it could not write is dst (its .part)
        if exc.filename is None:
            exc.filename = str(dst)
        raise
    finally:
        if tmp.exists():
            tmp.unlink()
    return len(found.messages)
