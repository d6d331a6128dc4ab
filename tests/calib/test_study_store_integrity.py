"""Integrity of the study's result store: every line checksummed, damage named, never used silently.

Property tests flip bytes at every offset of a small ``results.jsonl`` (and of its gzip form) and
assert that a reader either refuses the file naming the damaged line (number and byte offset),
or, when asked to skip damage, returns only records equal to those written and accounts for every
record it left out.
"""

import gzip
import json

import pytest

from adm_calib import study as st
from adm_calib.calib_commands import main
from adm_calib.study.store import CHECK_KEY, ResultsWriter, _line
from adm_sim.errors import InputError

RECS = [{"bridge": f"L{L}-f1-mu1", "train": "ICE-2", "status": "ok", "delta_zeta_vbi_pct": 0.125 * L,
         "mlm_peak_acc_m_s2": 1.5 + L / 7, "wall_s": 1.25, "message": "é"} for L in (38, 39, 40)]


def _write(path, recs=RECS):
    path.write_bytes(b"".join(_line(r) for r in recs))
    return path.read_bytes()


def test_lines_are_json_with_a_checksum_and_read_back_exactly(tmp_path):
    data = _write(tmp_path / "results.jsonl")
    lines = data.splitlines()
    assert len(lines) == 3
    for line, rec in zip(lines, RECS):
        parsed = json.loads(line)                       # still one JSON object per line
        assert list(parsed)[-1] == CHECK_KEY and len(parsed[CHECK_KEY]) == 8
        assert {k: v for k, v in parsed.items() if k != CHECK_KEY} == rec
    c = st.read_results(tmp_path / "results.jsonl")
    assert c.records == RECS and c.checksummed and not c.damaged and c.lines == 3


@pytest.mark.parametrize("mask", [0x01, 0x80])
def test_every_flipped_byte_is_refused_or_named(tmp_path, mask):
    path = tmp_path / "results.jsonl"
    good = _write(path)
    starts = [0]
    for line in good.splitlines(keepends=True)[:-1]:
        starts.append(starts[-1] + len(line))
    refused = named = 0
    for i in range(len(good)):
        bad = bytearray(good)
        bad[i] ^= mask
        path.write_bytes(bytes(bad))
        line_no = max(k for k, s in enumerate(starts) if s <= i) + 1
        try:
            st.read_results(path)
            c = st.read_results(path)
            # read without complaint: only a flip of the last newline (the last line is then a
            # truncated tail, returned for the caller to name) may do that
            assert i == len(good) - 1 and c.truncated_tail and c.records == RECS[:2], i
            continue
        except InputError as exc:
            refused += 1
            assert f"damaged line {line_no} (byte {starts[line_no - 1]}, " in str(exc) or (
                good[i:i + 1] == b"\n" and f"damaged line {line_no}" in str(exc)), (i, str(exc))
        c = st.read_results(path, skip_damaged=True)
        # nothing corrupt passes; nothing intact is left out without a DamagedLine or a tail
        assert all(r in RECS for r in c.records), i
        spans = [(d.offset, d.offset + d.length) for d in c.damaged]
        if c.truncated_tail:
            spans.append((c.valid_bytes, len(good)))
        for k, r in enumerate(RECS):          # each record left out lies in a named damaged span
            if r not in c.records:
                lo, hi = starts[k], starts[k] + len(_line(r))
                assert any(a < hi and lo < b for a, b in spans), (i, k)
        assert c.damaged and c.damaged[0].line_no == line_no and c.damaged[0].offset == starts[line_no - 1], i
        named += 1
    assert refused == named == len(good) - 1


def test_gzip_damage_and_cuts_are_refused(tmp_path):
    path = tmp_path / "results.jsonl.gz"
    good = gzip.compress(b"".join(_line(r) for r in RECS), mtime=0)
    path.write_bytes(good)
    assert st.read_results(path).records == RECS
    passed = 0
    for i in range(len(good)):
        for mask in (0x01, 0x80):
            bad = bytearray(good)
            bad[i] ^= mask
            path.write_bytes(bytes(bad))
            try:
                c = st.read_results(path)
            except InputError as exc:
                assert "results" in str(exc) and "\n" not in str(exc)
                continue
            # only bits the gzip checks do not cover (the text flag, mtime, extra flags, OS; unused
            # padding bits of the last deflate byte) may pass; what is read is then what was written
            assert c.records == RECS, i
            passed += 1
    assert passed <= 16
    for n in range(len(good)):
        path.write_bytes(good[:n])
        with pytest.raises(InputError, match=r"cut short|empty, not gzip|damaged gzip data"):
            st.read_results(path)
    path.write_bytes(good + b"\0" * 16)                  # zero padding, as gzip(1) accepts
    assert st.read_results(path).records == RECS
    path.write_bytes(good + b"garbage")
    with pytest.raises(InputError, match="damaged gzip data"):
        st.read_results(path)


def test_writer_drops_damage_and_tail_and_says_where(tmp_path):
    path = tmp_path / "results.jsonl"
    good = _write(path)
    second = good.index(b"\n") + 1
    bad = bytearray(good)
    bad[second + 20] ^= 0x01
    path.write_bytes(bytes(bad) + b'{"bridge": "cut')
    with ResultsWriter(path) as w:
        assert set(w.records) == {("L38-f1-mu1", "ICE-2"), ("L40-f1-mu1", "ICE-2")}
        assert w.notes == [
            f"dropped results.jsonl line 2 (byte {second}, {len(_line(RECS[1]))} bytes): checksum mismatch; "
            f"that case runs again",
            f"dropped a truncated last line 4 (byte {len(good)}, 15 bytes, no newline) of results.jsonl; "
            f"that case runs again"]
        w.append(RECS[1])
    c = st.read_results(path)
    assert c.records == [RECS[0], RECS[2], RECS[1]] and not c.truncated_tail


def test_file_without_checksums_is_read_and_given_them(tmp_path):
    path = tmp_path / "results.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in RECS))
    c = st.read_results(path)
    assert c.records == RECS and not c.checksummed
    with ResultsWriter(path) as w:
        assert w.notes == ["added line checksums to the 3 lines of results.jsonl written without them"]
    c = st.read_results(path)
    assert c.records == RECS and c.checksummed
    # in a checksummed file, a line without its checksum is damage
    path.write_bytes(path.read_bytes() + (json.dumps(RECS[0]) + "\n").encode())
    with pytest.raises(InputError, match=r"damaged line 4 \(byte \d+, \d+ bytes\): no line checksum"):
        st.read_results(path)


def test_study_fit_refuses_a_damaged_results_file(tmp_path, capsys):
    path = tmp_path / "results.jsonl"
    good = _write(path)
    bad = bytearray(good)
    bad[good.index(b"0.125") if b"0.125" in good else good.index(b'"wall_s":1.25') + 10] ^= 0x02
    path.write_bytes(bytes(bad))
    out = tmp_path / "fit"
    assert main(["study-fit", "--results", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: results ") and "damaged line 1 (byte 0, " in err[0]
    assert not out.exists()
