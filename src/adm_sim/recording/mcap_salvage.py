"""Recover every intact message of a killed, cut-short or damaged MCAP into a clean file: :func:`salvage`.

A writer killed with SIGKILL leaves a file that seeking readers, rosbags and rerun reject; every
chunk is checked (:func:`adm_sim.recording.mcap_scan.scan`), a damaged one skipped, and every intact
message, with its schema, channel (QoS metadata kept) and the metadata records, is written into a
new file, renamed into place only when whole (command line: ``adm-sim salvage IN.mcap OUT.mcap``).
"""

from __future__ import annotations

import os
from pathlib import Path

from mcap.writer import CompressionType, Writer

from adm_sim.errors import InputError
from adm_sim.recording.mcap_scan import scan

__all__ = ["salvage"]


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
