"""Write ROS 2 messages into an MCAP file that a killed writer leaves readable: :class:`McapRecorder`.

Files follow the ROS 2 profile that rosbag2 writes (https://mcap.dev/spec/registry): profile
``ros2``, schema encoding ``ros2msg``, message encoding ``cdr``; schemas from
:mod:`adm_sim.recording.mcap_schema`, channel QoS from :mod:`adm_sim.recording.mcap_qos`. Serialisation is rosbags' (``Typestore.serialize_cdr``
reading the rclpy message by attribute): its CDR has exact lengths, whereas rclpy's
``serialize_message`` reports rmw_fastrtps' *estimated* size, up to 8 bytes too long for an empty
``float64[]``, which rosbags refuses.

Chunks are small (64 KiB before compression by default) and written straight to the operating
system, so a writer killed with SIGKILL loses at most the open chunk (:mod:`adm_sim.recording.mcap_salvage`
recovers the rest); the data-section CRC is written too (header, metadata, message indexes).
"""

from __future__ import annotations

import array
import contextlib
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from mcap.writer import CompressionType, Writer

from adm_sim.errors import InputError, RunError
from adm_sim.recording.mcap_qos import qos_profiles_yaml, topic_qos
from adm_sim.recording.mcap_schema import message_definition, type_name, typestore

__all__ = ["DEFAULT_CHUNK_SIZE", "McapRecorder"]

DEFAULT_CHUNK_SIZE = 64 * 1024


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
        data = typestore().serialize_cdr(_Fields(msg), self._schemas[type(msg)][1])
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

