"""Read the messages of an MCAP recording after checking the whole file (:func:`read_messages`).

Every reader checks a file first (:func:`checked_scan`, by :func:`adm_sim.recording.mcap_scan.scan`):
a damaged or cut-short file is one :class:`~adm_sim.errors.InputError` naming the first damaged
place and pointing to ``adm-sim salvage``, unless asked to skip the damage (then each skipped place
is handed to ``warn`` and the intact chunks are read). Messages come in log-time order (file order
among equal times), decoded by mcap-ros2-support from the schemas in the file (attribute access
like rclpy messages; arrays as lists).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from mcap_ros2.decoder import DecoderFactory

from adm_sim.errors import InputError
from adm_sim.recording.mcap_scan import Scan, scan

__all__ = ["check_intact", "checked_scan", "decode_messages", "iter_raw_messages", "read_messages",
           "sorted_messages"]


def _refusal(path, s: Scan) -> InputError:
    """The one line that refuses a cut-short or damaged file, with the command that recovers it."""
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

