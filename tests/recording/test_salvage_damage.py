"""Salvage past any damage (issue 38 item 4): a small recording (600 messages in 68 chunks of 1 KiB)
damaged in each of its parts: the opening magic, the header record, the footer, the summary, one
chunk and the data-end record. ``adm-sim salvage`` recovers exactly the messages of every intact
chunk and names the damage; replay and the monitor refuse the file naming the damage and point to
salvage (the damaged magic was refused as "not an MCAP file", recovering none of its messages)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mcap")

from adm_sim.cli.sim_commands import main  # noqa: E402
from adm_sim.recording.mcap_log import McapRecorder, _inner_records, _parse_chunk, scan  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable


def _records(data):
    out, pos = [], 8
    while pos + 9 <= len(data):
        op, length = data[pos], int.from_bytes(data[pos + 1:pos + 9], "little")
        out.append((pos, op, pos + 9 + length))
        if op == 0x0F:
            break
        pos += 9 + length
    return out


@pytest.fixture(scope="module")
def fixture(tmp_path_factory):
    from std_msgs.msg import Float64MultiArray

    path = tmp_path_factory.mktemp("mcap") / "run.mcap"
    with McapRecorder(path, chunk_size=1024) as rec:
        for i in range(600):
            m = Float64MultiArray()
            m.data = [float(i)] * 8
            rec.write("/adm/midspan/accel" if i % 2 else "/adm/progress", m, log_time_ns=1000 * i)
    data = path.read_bytes()
    recs = _records(data)
    chunks = [(p, e) for p, op, e in recs if op == 0x06]
    assert len(chunks) == 68 and len(scan(path).messages) == 600
    return data, recs, chunks


def _keys(path):
    return sorted((c.topic, m.log_time, bytes(m.data)) for _s, c, m in scan(path).messages)


def _damage(data, recs, chunks, part):
    d = bytearray(data)
    de = next(r for r in recs if r[1] == 0x0F)
    k = chunks[len(chunks) // 2][0]
    if part == "magic":
        d[0:8] = bytes(8)
    elif part == "header":
        d[9 + 8:9 + 12] = b"\xff" * 4  # the header's profile length
    elif part == "footer":
        d[len(d) - 37:len(d) - 8] = bytes(29)
    elif part == "summary":
        d[de[2] + 20] ^= 0xFF
    elif part == "chunk":
        d[k + 80] ^= 0x10  # inside the compressed records
    elif part == "data-end":
        d[de[0]:de[2]] = bytes(de[2] - de[0])
    return bytes(d), k


@pytest.mark.parametrize("part,named", [
    ("magic", "damaged: file magic is damaged at byte 0: no message lost"),
    ("header", "damaged: record is damaged at byte 8: no message lost"),
    ("footer", "damaged: summary or footer is damaged at byte"),
    ("summary", "damaged: summary fails its CRC at byte"),
    ("chunk", "dropped: chunk "),
    ("data-end", "damaged: broken record framing at byte"),
])
def test_salvage_recovers_every_intact_chunk_and_names_the_damage(tmp_path, capsys, fixture, part, named):
    data, recs, chunks = fixture
    bad, k = _damage(data, recs, chunks, part)
    src = tmp_path / "bad.mcap"
    src.write_bytes(bad)
    intact = {key for key in _keys_of(data, chunks, skip=k if part == "chunk" else None)}
    assert main(["salvage", str(src), str(tmp_path / "out.mcap")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"recovered {len(intact)} messages into {tmp_path / 'out.mcap'}"
    assert any(line.startswith(named) for line in out), out
    assert set(_keys(tmp_path / "out.mcap")) == intact
    assert len(intact) == (600 - _count(data, k) if part == "chunk" else 600)


def _keys_of(data, chunks, skip=None):
    """The messages of every chunk but ``skip``, decompressed by the chunk parser (independent of the scan)."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "i.mcap"
        p.write_bytes(data)
        topics = {m[1].id: m[1].topic for m in scan(p).messages}
    out = set()
    for pos, _end in chunks:
        if pos == skip:
            continue
        raw, why = _parse_chunk(data, pos, len(data))
        assert why is None
        out |= {(topics[r.channel_id], r.log_time, bytes(r.data)) for r in _inner_records(raw) if hasattr(r, "channel_id")}
    return out


def _count(data, pos):
    raw, _ = _parse_chunk(data, pos, len(data))
    return sum(1 for r in _inner_records(raw) if hasattr(r, "channel_id"))


@pytest.mark.slow
@pytest.mark.parametrize("part,words", [
    ("magic", "is damaged: its MCAP magic (bytes 0-7) is broken while the rest reads as MCAP; recover its intact "
              "chunks with: adm-sim salvage"),
    ("footer", {"replay": "is damaged (summary or footer is damaged at byte",
                "monitor": "is not a complete MCAP file"}),
])
@pytest.mark.parametrize("entry", ["replay", "monitor"])
def test_replay_and_monitor_name_the_damage_and_point_to_salvage(tmp_path, fixture, part, words, entry):
    data, recs, chunks = fixture
    bad, _ = _damage(data, recs, chunks, part)
    src = tmp_path / "bad.mcap"
    src.write_bytes(bad)
    words = words if isinstance(words, str) else words[entry]
    argv = ([PY, str(ROOT / "launch_scripts" / "replay.py"), str(src), "--rrd", str(tmp_path / "o.rrd")]
            if entry == "replay" else [PY, str(ROOT / "launch_scripts" / "monitor.py"), "--mcap", str(src)])
    r = subprocess.run(argv, capture_output=True, text=True, timeout=120, env=dict(os.environ), cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    (line,) = r.stderr.splitlines()
    assert line.startswith("error: ") and words in line and f"adm-sim salvage {src}" in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.mcap"]


def test_a_file_that_is_no_mcap_at_all_is_still_refused(tmp_path, capsys):
    (tmp_path / "x.mcap").write_bytes(b"hello, this is no recording\n" * 10)
    assert main(["salvage", str(tmp_path / "x.mcap"), str(tmp_path / "o.mcap")]) == 2
    assert "is not an MCAP file (it does not start with the MCAP magic bytes)" in capsys.readouterr().err
