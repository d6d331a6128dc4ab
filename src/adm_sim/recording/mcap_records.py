"""The records of an MCAP file read byte by byte, so that a damaged one is found and named.

The layout is the MCAP specification's (https://mcap.dev/spec): a record is an opcode byte and a
little-endian 8-byte length; a Chunk holds compressed records with the CRC-32 of the uncompressed
ones; MessageIndex records follow their chunk. :func:`parse_chunk` decompresses and checks one
chunk, :func:`inner_records` reads the records inside it, :func:`next_chunk` finds the next intact
chunk after damage; schemas, channels and metadata are read by mcap's own record readers. The
walk over a whole file is :func:`adm_sim.recording.mcap_scan.scan`.
"""

from __future__ import annotations

import io
import struct
import zlib

from mcap import stream_reader
from mcap.data_stream import ReadDataStream
from mcap.records import Channel, Header, Message, Metadata, Schema

__all__ = ["CHUNK", "DATA_END", "DATA_OPS", "FOOTER", "MAGIC", "MESSAGE_INDEX", "decompress", "index_ok",
           "inner_records", "message_index_counts", "next_chunk", "parse_chunk", "read_record", "record_starts_at",
           "uint_le"]

MAGIC = b"\x89MCAP0\r\n"
#: records of the data section: header (first), schema, channel, message, chunk, message index,
#: attachment, metadata, data end
DATA_OPS = frozenset((0x01, 0x03, 0x04, 0x05, 0x06, 0x07, 0x09, 0x0C, 0x0F))
CHUNK, MESSAGE_INDEX, DATA_END, FOOTER = 0x06, 0x07, 0x0F, 0x02


def uint_le(data, pos, n):
    """The unsigned little-endian integer of ``n`` bytes at ``pos``."""
    return int.from_bytes(data[pos:pos + n], "little")


def decompress(compression: str, raw: bytes, size: int) -> bytes:
    """A chunk's records decompressed (``zstd``, ``lz4`` or none), at most ``size`` bytes."""
    if compression == "zstd":
        return stream_reader.zstandard.ZstdDecompressor().decompress(raw, max_output_size=size)
    if compression == "lz4":
        return stream_reader.lz4.decompress(raw)
    if compression == "":
        return raw
    raise ValueError(f"unknown compression {compression!r}")


def parse_chunk(data, pos: int, end: int, check_length: bool = True, records_end: int | None = None):
    """The records inside the Chunk record at ``pos`` (decompressed, CRC checked) or a reason.
    ``records_end``: read the compressed records up to there instead of by their own length field."""

    body = pos + 9
    length = uint_le(data, pos + 1, 8)
    if body + 32 > end:
        return None, "broken record framing"
    size, crc = uint_le(data, body + 16, 8), uint_le(data, body + 24, 4)
    n_comp = uint_le(data, body + 28, 4)
    if n_comp > 16 or body + 32 + n_comp + 8 > end:
        return None, "chunk header is damaged"
    try:
        compression = bytes(data[body + 32:body + 32 + n_comp]).decode()
    except UnicodeDecodeError:
        return None, "chunk header is damaged"
    at = body + 32 + n_comp
    n_rec = uint_le(data, at, 8) if records_end is None else records_end - (at + 8)
    if n_rec < 0 or at + 8 + n_rec > end or (check_length and at + 8 + n_rec != body + length):
        return None, "broken record framing"
    if size > 1 << 34:
        return None, "chunk header is damaged"
    try:
        raw = decompress(compression, bytes(data[at + 8:at + 8 + n_rec]), size)
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


def inner_records(raw: bytes):
    """The schema, channel and message records inside a decompressed chunk, in order. Messages
    (nearly every record) are read here by the specification's layout, into mcap's own
    ``Message``, as mcap's ``Message.read`` reads them (a record shorter than its 22-byte head is
    damaged); schemas and channels by mcap's readers. Raises on a record cut short."""
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


def next_chunk(data, start: int, end: int) -> int | None:
    """Offset of the next intact Chunk record at or after ``start`` (found by its opcode and a
    header, decompression and CRC that check out), or None."""
    pos = start
    while True:
        pos = data.find(b"\x06", pos, end)
        if pos < 0:
            return None
        if pos + 9 + 32 <= end:
            raw, why = parse_chunk(data, pos, end)
            if why is None:
                return pos
        pos += 1


def record_starts_at(data, pos: int, end: int) -> bool:
    """A data-section record's framing at ``pos``: a known opcode and a length within ``end``."""
    if pos + 9 > end or data[pos] not in DATA_OPS:
        return False
    length = uint_le(data, pos + 1, 8)
    return pos + 9 + length <= end and (data[pos] != MESSAGE_INDEX or index_ok(data, pos, length))


def index_ok(data, pos: int, length: int) -> bool:
    """A MessageIndex record's own framing: channel id, then ``length - 6`` bytes of 16-byte entries."""
    return length >= 6 and uint_le(data, pos + 11, 4) == length - 6 and (length - 6) % 16 == 0


def message_index_counts(data, pos: int, end: int):
    """Counts per channel id of the MessageIndex records starting at ``pos`` (as the writer puts
    them right after their chunk), and the offset after them."""
    counts: dict = {}
    while pos + 9 <= end and data[pos] == MESSAGE_INDEX:
        length = uint_le(data, pos + 1, 8)
        if pos + 9 + length > end or length < 8:
            break
        channel_id, n_bytes = uint_le(data, pos + 9, 2), uint_le(data, pos + 11, 4)
        if n_bytes != length - 6 or n_bytes % 16:
            break
        counts[channel_id] = counts.get(channel_id, 0) + n_bytes // 16
        pos += 9 + length
    return counts, pos


def read_record(data, pos: int, op: int, length: int):
    """The header, schema, channel, message or metadata record (``op``) at ``pos``, read by mcap's
    own record readers; raises when it does not read back to its stated length."""
    stream = ReadDataStream(io.BytesIO(data[pos + 9:pos + 9 + length]))
    reader = {0x01: Header.read, 0x03: Schema.read, 0x04: Channel.read, 0x0C: Metadata.read}.get(op)
    rec = Message.read(stream, length) if reader is None else reader(stream)
    if op != 0x05 and stream.count != length:
        raise ValueError("record length")
    return rec

