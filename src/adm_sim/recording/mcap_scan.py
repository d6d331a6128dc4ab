"""Check every record of an MCAP file and name each damaged place: :func:`scan`.

Every reader checks a file first: record framing, chunk decompression and CRC
(:mod:`adm_sim.recording.mcap_records`), the summary's CRC and the data section's CRC when the
writer wrote one. A damaged place is a :class:`Damage` with its offset and the messages lost there
per topic (from the message indexes after a chunk, or the summary's statistics); the reading goes
on at the next intact chunk, found by its own framing and CRC, so a broken record length does not
end it. A file cut short (a killed writer) is ``truncated``. Nothing is decoded: the intact
messages, in file order, are in the :class:`Scan` for :mod:`adm_sim.recording.mcap_read` and
:mod:`adm_sim.recording.mcap_salvage`.
"""

from __future__ import annotations

import io
import zlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.records import Channel, Message, Schema, Statistics

from adm_sim.recording.mcap_records import (CHUNK, DATA_END, DATA_OPS, FOOTER, MAGIC, MESSAGE_INDEX, index_ok,
                                            inner_records, message_index_counts, next_chunk, parse_chunk,
                                            read_record, record_starts_at, uint_le)

__all__ = ["Damage", "Scan", "scan"]


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


def _read_summary(data, scan: Scan):
    """Schemas, channels and statistics of the summary section, if its CRC holds; the start of
    the summary (or of the footer) as the end of the data section."""

    n = len(data)
    foot = n - 8 - 29
    if n < 8 + 29 + 8 or bytes(data[n - 8:]) != MAGIC or data[foot] != FOOTER or uint_le(data, foot + 1, 8) != 20:
        return None, None, n
    scan.footer_ok = True
    summary_start, crc = uint_le(data, foot + 9, 8), uint_le(data, foot + 25, 4)
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
        op, length = data[pos], uint_le(data, pos + 1, 8)
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
    path = Path(path)
    data = path.read_bytes()
    result = Scan(path)
    if bytes(data[:8]) != MAGIC:
        result.damage.append(Damage(0, "file magic is damaged", {}))
    sum_schemas, sum_channels, end = _read_summary(data, result)
    # the data section ends at its DataEnd record, right before the summary (when the footer holds)
    limit = end
    if result.footer_ok and end >= 8 + 13 and data[end - 13] == DATA_END and uint_le(data, end - 12, 8) == 4:
        limit = end - 13
    walk = _Walk(data, result, dict(sum_schemas or {}), dict(sum_channels or {}), end=end, limit=limit)
    _settle_damage(result, walk.run())
    return result


class _Walk:
    """The walk of :func:`scan` over the data section, record by record from the header on: each
    record's framing is checked, each chunk decompressed and checked, the messages of the intact
    ones filed in ``result`` with the schemas and channels known so far (``schemas``,
    ``channels``: by id, the summary's first). ``end`` is where the data section ends at the
    latest (the summary or the footer when the footer holds, else the end of the file), ``limit``
    its DataEnd record when the footer locates it."""

    def __init__(self, data, result: Scan, schemas: dict, channels: dict, *, end: int, limit: int):
        self.data, self.result, self.schemas, self.channels = data, result, schemas, channels
        self.end, self.limit = end, limit
        self.verified = 8  # end of the last chunk whose CRC held: nothing before it is read again
        self.data_end: int | None = None  # offset of the DataEnd record, once read

    def run(self) -> int | None:
        """Walk to the DataEnd record (or the end); returns its offset, or None when none was read."""
        data, end, result = self.data, self.end, self.result
        pos: int | None = 8
        while pos is not None and pos < end:
            if pos + 9 > end:
                result.truncated = True
                break
            op, length = data[pos], uint_le(data, pos + 1, 8)
            rec_end = pos + 9 + length
            if op not in DATA_OPS or rec_end > end or (op == 0x01) != (pos == 8) or (
                    op == MESSAGE_INDEX and not index_ok(data, pos, length)) or (op == DATA_END and length != 4):
                nxt = self.resume(pos + 1)
                if nxt is None and op in DATA_OPS and rec_end > end and not result.footer_ok:
                    result.truncated = True  # a killed writer's last record
                    break
                result.damage.append(Damage(pos, "broken record framing", None))
                pos = nxt
                continue
            if op == CHUNK:
                pos = self.chunk(pos, rec_end)
                continue
            if op == DATA_END:
                self.data_end_record(pos)
                break
            pos = self.record(pos, op, length, rec_end)
        return self.data_end

    def resume(self, after: int) -> int | None:
        """Where reading goes on after damage: the next intact chunk after the last verified one
        (a damaged length of an unchecked record may have jumped over intact chunks), else the
        data section's end record (when the footer locates it)."""
        nxt = next_chunk(self.data, min(after, self.verified), self.limit)
        if nxt is not None:
            return nxt
        return self.limit if self.limit < self.end else None

    def take(self, rec) -> None:
        """File a schema, a channel or a message (on no known channel: an orphan)."""
        if isinstance(rec, Schema):
            self.schemas.setdefault(rec.id, rec)
        elif isinstance(rec, Channel):
            self.channels.setdefault(rec.id, rec)
        else:
            ch = self.channels.get(rec.channel_id)
            if ch is None:
                self.result.orphan_messages += 1
            else:
                self.result.messages.append((self.schemas.get(ch.schema_id), ch, rec))

    def chunk(self, pos: int, rec_end: int) -> int | None:
        """The Chunk record at ``pos``: its messages filed when it checks out, else the damage with the
        messages its indexes count; returns where the reading goes on."""
        data, result, channels, schemas = self.data, self.result, self.channels, self.schemas
        result.chunks += 1
        raw, why, inner_end = self.chunk_contents(pos, rec_end)
        records: list = []
        if why is None:
            try:
                records = inner_records(raw)
            except Exception:
                why = "chunk's records are damaged"
        if why is None:
            for rec in records:
                ch = channels.get(rec.channel_id) if type(rec) is Message else None
                if ch is None:
                    self.take(rec)  # a schema, a channel or a message on no known channel
                else:  # a message (nearly every record), as take() files it
                    result.messages.append((schemas.get(ch.schema_id), ch, rec))
            self.verified = inner_end
            return inner_end
        if why == "broken record framing":
            result.damage.append(Damage(pos, why, None))
            return self.resume(pos + 1)
        counts, after = message_index_counts(data, rec_end, self.limit)
        result.damage.append(Damage(pos, why, {channels[c].topic if c in channels else f"channel {c}": k
                                               for c, k in counts.items()} if counts else None))
        return after

    def chunk_contents(self, pos: int, rec_end: int):
        """``(records, why, end)`` of the Chunk record at ``pos``: its decompressed records (or None
        and the reason) and where it ends. A record length that disagrees with the chunk's own sizes
        while the contents pass their CRC is named (as damage with nothing lost) and the contents kept."""
        data, end = self.data, self.end
        raw, why = parse_chunk(data, pos, end)
        inner_end = rec_end
        if why != "broken record framing":  # the record length agrees with the chunk's own sizes
            return raw, why, inner_end
        raw, why2 = parse_chunk(data, pos, end, check_length=False)
        if why2 is not None:
            return raw, why, inner_end
        # the contents check out by their own length: one of the two lengths is damaged
        n_comp = uint_le(data, pos + 9 + 28, 4)
        inner_end = pos + 9 + 32 + n_comp + 8 + uint_le(data, pos + 9 + 32 + n_comp, 8)
        what = "chunk record length is damaged"
        # zstd stops at the end of its frame, so a records length enlarged by damage still
        # decompresses: when the outer length also holds the contents, it is the records
        # length that is damaged, and the chunk ends where its record says (a reading on
        # from the enlarged length would jump over intact chunks)
        raw_outer, why3 = None, "not tried"
        if not record_starts_at(data, inner_end, end) and record_starts_at(data, rec_end, end):
            raw_outer, why3 = parse_chunk(data, pos, end, records_end=rec_end)
        if why3 is None:
            raw, inner_end, what = raw_outer, rec_end, "chunk's records length is damaged"
        self.result.damage.append(Damage(pos, f"{what} (its contents pass their CRC and are kept)", {}))
        return raw, None, inner_end

    def data_end_record(self, pos: int) -> None:
        """The DataEnd record at ``pos``: the data section's CRC checked (when the writer wrote one and
        nothing else was found damaged)."""
        self.data_end = pos
        result = self.result
        crc = uint_le(self.data, pos + 9, 4)
        if crc and zlib.crc32(self.data[:pos]) != crc and not result.damage:
            result.damage.append(Damage(0, "data section fails its CRC (outside the chunks: header, "
                                           "metadata or message indexes)", {}))

    def record(self, pos: int, op: int, length: int, rec_end: int) -> int | None:
        """A record outside the chunks at ``pos``: a header, schema, channel, message or metadata
        record is read (and filed), others are passed; returns where the reading goes on."""
        if op in (0x01, 0x03, 0x04, 0x05, 0x0C):
            try:
                rec = read_record(self.data, pos, op, length)
            except Exception:
                self.result.damage.append(Damage(pos, "record is damaged", None))
                return self.resume(pos + 1)
            if op == 0x0C:
                self.result.metadata.append(rec)
            elif op != 0x01:
                self.take(rec)
        return rec_end


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

