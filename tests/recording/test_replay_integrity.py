"""Recordings as they leave a run and come back: the QoS each MCAP channel was offered with (as
rosbag2 writes it), a republish that keeps it (descriptions latched) and loses nothing at
``--rate 0``, one viewer feed for replay and the live driver, and integrity checked wherever a
recording is read (replay, salvage): a damaged chunk is named, skipped only when asked, and no
intact one is dropped.

The recording is a real one: ``crossing.py`` B3 x ICE-2, MLM, 300 km/h (5747 messages, 14 chunks).
"""

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mcap")

from adm_sim import protocol as P  # noqa: E402
from adm_sim.errors import InputError  # noqa: E402
from adm_sim.recording.mcap_log import (QOS_CLASSES, _inner_records, _parse_chunk, checked_scan,  # noqa: E402
                                        parse_qos_profiles, qos_profiles_yaml, salvage, scan)

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
REPLAY = ROOT / "launch_scripts" / "replay.py"
SIM = [PY, "-m", "adm_sim.cli.sim_commands"]


def _records(data: bytes):
    """``(offset, opcode, end)`` of the data section's records, by the specification's framing."""
    out, pos = [], 8
    while pos + 9 <= len(data):
        op, length = data[pos], int.from_bytes(data[pos + 1:pos + 9], "little")
        out.append((pos, op, pos + 9 + length))
        if op == 0x0F:
            break
        pos += 9 + length
    return out


def _key(item):
    _schema, channel, message = item
    return channel.topic, message.log_time, message.sequence, bytes(message.data)


@pytest.fixture(scope="module")
def layout(recording):
    """The intact file: its bytes, its messages (keys) in file order, and each chunk's byte range
    with its messages (decompressed by the chunk parser, independent of the scan's walk)."""
    from mcap.reader import make_reader

    data = recording.read_bytes()
    base = scan(recording)
    assert not base.damaged and base.chunks >= 10
    keys = [_key(m) for m in base.messages]
    with recording.open("rb") as f:  # the scan reads what mcap's own reader reads, in file order, field by field
        assert [(c.topic, m.channel_id, m.log_time, m.publish_time, m.sequence, m.data) for _s, c, m in base.messages] \
            == [(c.topic, m.channel_id, m.log_time, m.publish_time, m.sequence, m.data)
                for _s, c, m in make_reader(f).iter_messages(log_time_order=False)]
    channels = {m[1].id: m[1] for m in base.messages}
    chunks = []
    for pos, op, end in _records(data):
        if op == 0x06:
            raw, why = _parse_chunk(data, pos, len(data))
            assert why is None
            chunks.append((pos, end, [(channels[r.channel_id].topic, r.log_time, r.sequence, bytes(r.data))
                                      for r in _inner_records(raw) if hasattr(r, "channel_id")]))
    assert sum(len(c[2]) for c in chunks) == len(keys) == sum(base.expected.values())
    return data, keys, chunks


# ---------------------------------------------------------------- QoS in the recording


@pytest.mark.slow
def test_channels_carry_offered_qos_profiles_as_rosbag2(recording):
    """Every channel has ``offered_qos_profiles``; rosbags (a rosbag2 reader) parses it to the QoS
    the nodes offer: descriptions transient local depth 1, monitoring reliable depth 5000."""
    from rosbags.highlevel import AnyReader

    with AnyReader([recording]) as reader:
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    assert set(qos) >= {P.TOPIC_BRIDGE_DESC, P.TOPIC_TRAIN_DESC, P.TOPIC_ACCEL, P.TOPIC_STATUS, P.TOPIC_CLOCK}
    for topic, profiles in qos.items():
        assert len(profiles) == 1, topic
        q = profiles[0]
        hist, depth, rel, dur = QOS_CLASSES[P.TOPICS[topic][1]]
        assert (q.history.name.lower(), q.depth, q.reliability.name.lower(), q.durability.name.lower()) == \
            (hist, depth, rel, dur), topic
        assert (q.deadline.sec, q.deadline.nsec) == (9223372036, 854775807)
    assert qos[P.TOPIC_BRIDGE_DESC][0].durability.name == "TRANSIENT_LOCAL"
    assert qos[P.TOPIC_ACCEL][0].depth == 5000


def test_qos_classes_are_the_nodes_profiles():
    from adm_sim.nodes import common as c

    for cls, profile in (("C", c.QOS_CONTROL), ("X", c.QOS_EXCHANGE), ("M", c.QOS_MONITOR), ("L", c.QOS_LATCHED),
                         ("H", c.QOS_HISTORY)):
        assert QOS_CLASSES[cls] == parse_qos_profiles(qos_profiles_yaml(profile)), cls


# ---------------------------------------------------------------- one viewer feed


class _FakeLogger:
    def __init__(self):
        self.calls, self.runs = [], []

    def __getattr__(self, name):
        def record(*args):
            self.calls.append((name, args))
            if name == "run_started" and P.is_bridge_start(args[0]):
                self.runs.append(args[0])
        return record


@pytest.mark.slow
def test_viewer_feed_routes_each_topic_once_and_names_the_phase(recording):
    """The recorded run fed through ViewerFeed: every acceleration sample reaches the logger with
    its stamp, the result is drawn once with the phase of the driver's request, namespaced topics
    are drawn as the topic they end with."""
    from adm_sim.recording.mcap_log import read_messages
    from adm_sim.recording.viewer_feed import ViewerFeed, canonical_topic, stamp_ns

    viz = _FakeLogger()
    feed = ViewerFeed(viz)
    n_accel, last_acc = 0, None
    for topic, t_ns, msg in read_messages(recording):
        if topic == P.TOPIC_ACCEL and viz.runs:
            n_accel += 1
            last_acc = (stamp_ns(msg, t_ns) * 1e-9, msg.accel.linear.z)
        feed(topic, msg, stamp_ns(msg, t_ns))
    accel = [a for name, a in viz.calls if name == "accel"]
    assert len(accel) == n_accel > 1000 and accel[-1] == last_acc
    done = [a for name, a in viz.calls if name == "run_done"]
    assert len(done) == 1 and done[0][1] != P.PHASE_UNKNOWN and done[0][2] == 1
    assert abs(float(done[0][0][1].max()) - 2.7984) < 5e-5  # the crossing's printed peak, m/s^2
    assert canonical_topic("/b3/adm/midspan/accel") == P.TOPIC_ACCEL
    assert canonical_topic("/other/topic") == "/other/topic"


# ---------------------------------------------------------------- damage named, skipped only when asked


def _damaged(tmp_path, data, edit, name="bad.mcap"):
    d = bytearray(data)
    edit(d)
    path = tmp_path / name
    path.write_bytes(bytes(d))
    return path


@pytest.mark.slow
def test_flipped_byte_in_a_chunk_replay_refuses_or_skips_and_salvage_names_it(tmp_path, layout):
    data, keys, chunks = layout
    start, end, msgs = chunks[len(chunks) // 2]
    bad = _damaged(tmp_path, data, lambda d: d.__setitem__((start + end) // 2, d[(start + end) // 2] ^ 0x10))
    topics = {}
    for m in msgs:
        topics[m[0]] = topics.get(m[0], 0) + 1
    named = (f"at byte {start}: {len(msgs)} messages lost ("
             + ", ".join(f"{t} {n}" for t, n in sorted(topics.items())) + ")")
    r = subprocess.run([PY, str(REPLAY), str(bad), "--rrd", str(tmp_path / "o.rrd")], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1, r.stderr
    assert r.stderr.startswith(f"error: RUN.mcap: '{bad}' is damaged (1 of {len(chunks)} chunks") and named in r.stderr
    assert "--skip-damaged" in r.stderr and not (tmp_path / "o.rrd").exists()
    r = subprocess.run([PY, str(REPLAY), str(bad), "--rrd", str(tmp_path / "o.rrd"), "--skip-damaged"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    warnings = [line for line in r.stderr.splitlines() if line.startswith("warning: RUN.mcap: skipped damage")]
    assert len(warnings) == 2 and named in warnings[0]
    assert f"in all {len(msgs)} of {len(keys)} recorded messages lost" in warnings[1]
    assert r.stdout.splitlines()[-1].startswith(f"logged {len(keys) - len(msgs)} messages on ")
    r = subprocess.run(SIM + ["salvage", str(bad), str(tmp_path / "s.mcap")], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0
    lines = r.stdout.splitlines()
    assert lines[0] == f"recovered {len(keys) - len(msgs)} messages into {tmp_path / 's.mcap'}"
    assert lines[1] == f"lost: 1 of {len(chunks)} chunks were damaged and skipped"
    assert lines[2].startswith("dropped: chunk ") and lines[2].endswith(named)


@pytest.mark.slow
def test_zeroed_block_and_broken_chunk_length_salvage_every_intact_chunk(tmp_path, layout):
    """4 KiB zeroed inside a chunk: that chunk is dropped (named), every chunk after it recovered.
    A chunk's record length flipped: the chunk's own sizes and CRC still hold, nothing is lost, and
    the damage is still named (replay refuses the file without --skip-damaged)."""
    data, keys, chunks = layout
    start, end, msgs = chunks[3]
    bad = _damaged(tmp_path, data, lambda d: d.__setitem__(slice(start + 100, start + 4196), bytes(4096)))
    report = {}
    n = salvage(bad, tmp_path / "z.mcap", report=report)
    lost = {k for c in chunks if c[0] < start + 4196 and c[1] > start + 100 for k in c[2]}
    assert n == len(keys) - len(lost) and report["lost_chunks"] >= 1
    got = {_key(m) for m in scan(tmp_path / "z.mcap").messages}
    assert got == set(keys) - lost  # every chunk after the damage is back
    assert report["damage"][0].startswith("chunk ") and f"at byte {start}:" in report["damage"][0]
    bad = _damaged(tmp_path, data, lambda d: d.__setitem__(start + 3, d[start + 3] ^ 0x01), "len.mcap")
    report = {}
    assert salvage(bad, tmp_path / "l.mcap", report=report) == len(keys)
    assert report["damage"] == [f"chunk record length is damaged (its contents pass their CRC and are kept) at "
                                f"byte {start}: no message lost"]
    with pytest.raises(InputError, match=r"is damaged .*chunk record length is damaged"):
        checked_scan(bad)


@pytest.mark.slow
def test_enlarged_records_length_of_a_chunk_jumps_over_nothing(tmp_path, layout):
    """A chunk's compressed-records length enlarged by a flipped bit (+65536; zstd still decompresses
    the frame, whose CRC holds): the chunk is kept and the damage named, and no intact chunk after it
    is jumped over (the reading goes on where the chunk's record ends). Found by the property test
    below at byte 92 of a recording: 3 intact chunks were dropped."""
    data, keys, chunks = layout
    start, _end, _msgs = chunks[0]
    at = start + 9 + 32 + int.from_bytes(data[start + 9 + 28:start + 9 + 32], "little")  # the records length
    bad = _damaged(tmp_path, data, lambda d: d.__setitem__(at + 2, d[at + 2] ^ 0x01))
    s = scan(bad)
    assert [_key(m) for m in s.messages] == keys
    assert s.lines()[0] == (f"chunk's records length is damaged (its contents pass their CRC and are kept) at "
                            f"byte {start}: no message lost")
    report = {}
    assert salvage(bad, tmp_path / "s.mcap", report=report) == len(keys)
    with pytest.raises(InputError, match=r"is damaged .*chunk's records length is damaged"):
        checked_scan(bad)


# ---------------------------------------------------------------- property: nothing corrupt, nothing dropped silently


@pytest.mark.slow
def test_flipped_and_zeroed_bytes_never_pass_silently(tmp_path_factory, layout):
    """Bits flipped and runs of 1, 16 or 4096 bytes zeroed at many offsets (half of them at record
    boundaries, where lengths and opcodes live): every message read from the damaged file is one
    of the original messages byte for byte; every message of a chunk the damage did not touch is
    read; if anything differs from the original, the file is reported damaged (so replay refuses
    it and salvage names the damage)."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    data, keys, chunks = layout
    original = set(keys)
    heads = [pos for pos, _op, _end in _records(data)]
    where = st.one_of(st.integers(0, len(data) - 1),
                      st.tuples(st.sampled_from(heads), st.integers(0, 41)).map(lambda t: min(t[0] + t[1], len(data) - 1)))
    damage = st.one_of(st.tuples(st.just("flip"), where, st.integers(0, 7)),
                       st.tuples(st.just("zero"), where, st.sampled_from([1, 16, 4096])))
    folder = tmp_path_factory.mktemp("mutations")
    seen = {"damaged": 0, "clean": 0}
    chunk_sets = [(start, end, set(msgs)) for start, end, msgs in chunks]

    @settings(max_examples=250, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
    @given(damage)
    def check(change):
        kind, off, arg = change
        d = bytearray(data)
        if kind == "flip":
            d[off] ^= 1 << arg
            lo, hi = off, off + 1
        else:
            hi = min(len(d), off + arg)
            d[off:hi] = bytes(hi - off)
            lo = off
        if bytes(d) == data:
            return
        path = folder / "m.mcap"
        path.write_bytes(bytes(d))
        s = scan(path)
        got = [(c.topic, m.log_time, m.sequence, bytes(m.data)) for _s, c, m in s.messages]  # _key, inlined
        got_set = set(got)  # once per example (and each chunk's set once), not once per chunk and example
        assert got_set <= original, f"{kind} at {off}: a corrupt message was read"
        for start, end, msgs in chunk_sets:
            if end <= lo or start >= hi:
                assert msgs <= got_set, f"{kind} at {off}: the intact chunk at {start} was dropped"
        if got != keys:
            assert s.damaged and s.lines(), f"{kind} at {off}: messages differ and no damage is reported"
        if s.damaged:  # what checked_scan (replay) refuses
            seen["damaged"] += 1
        else:
            seen["clean"] += 1
            assert got == keys

    check()
    assert seen["damaged"] >= 180  # nearly every byte is covered by a chunk, summary or data-section CRC


# ---------------------------------------------------------------- an output that is an input


@pytest.mark.slow
def test_replay_refuses_to_write_over_its_input(tmp_path, recording):
    src = tmp_path / "in.mcap"
    src.write_bytes(recording.read_bytes())
    before = src.read_bytes()
    (tmp_path / "sym.rrd").symlink_to(src)
    os.link(src, tmp_path / "hard.rrd")
    for rrd, how in ((src, ""), (tmp_path / "sym.rrd", " by another name"), (tmp_path / "hard.rrd", " by another name")):
        r = subprocess.run([PY, str(REPLAY), str(src), "--rrd", str(rrd), "--overwrite"], capture_output=True,
                           text=True, timeout=120)
        assert r.returncode == 2
        assert r.stderr.splitlines() == [f"error: --rrd: '{rrd}' is RUN.mcap, the recording being replayed (the "
                                         f"same file{how}); give another file"]
        assert src.read_bytes() == before and r.stdout == ""


# ---------------------------------------------------------------- republish: live QoS, no loss


@pytest.mark.slow
def test_republish_latches_the_descriptions_and_loses_nothing_at_rate_0(recording):
    """A subscriber that asks for transient local (a late joiner's QoS) gets the bridge description
    (a volatile publisher would not match it), and a subscriber with the recording's QoS (reliable,
    depth 5000) gets every one of the acceleration samples in order at --rate 0. The exported
    ROS_DOMAIN_ID is used."""
    import rclpy
    from geometry_msgs.msg import AccelStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from adm_sim.processes.dds_env import local_ros_env

    want = [m[2].log_time for m in scan(recording).messages if m[1].topic == P.TOPIC_ACCEL]
    with local_ros_env() as env:
        saved = {k: os.environ.get(k) for k in ("ROS_DOMAIN_ID", "FASTDDS_BUILTIN_TRANSPORTS",
                                                "ROS_AUTOMATIC_DISCOVERY_RANGE")}
        os.environ.update({k: env[k] for k in saved})
        ctx = rclpy.context.Context()
        rclpy.init(context=ctx)
        node = rclpy.create_node("monitor", context=ctx)
        got, desc = [], []
        node.create_subscription(AccelStamped, P.TOPIC_ACCEL, got.append,
                                 QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
        node.create_subscription(String, P.TOPIC_BRIDGE_DESC, desc.append,
                                 QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        proc = subprocess.Popen([PY, str(REPLAY), str(recording), "--republish", "--rate", "0",
                                 "--topics", P.TOPIC_ACCEL, P.TOPIC_BRIDGE_DESC, "--wait-subscribers", "10"],
                                env=dict(env), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        stop = threading.Event()

        def spin():  # a subscriber that takes what arrives
            while not stop.is_set():
                ex.spin_once(timeout_sec=0.05)

        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        try:
            out, err = proc.communicate(timeout=120)
            # every reliable sample was acknowledged before the replay ended: it is in this reader's
            # history; wait (bounded) until the executor has taken it all, then until nothing more comes
            deadline = time.monotonic() + 30.0
            while (len(got) < len(want) or not desc) and time.monotonic() < deadline and proc.returncode == 0:
                time.sleep(0.02)
            stop.set()
            spinner.join(timeout=10)
            while True:  # one turn of 0.2 s that takes nothing: no sample is left behind a duplicate
                n = len(got) + len(desc)
                ex.spin_once(timeout_sec=0.2)
                if len(got) + len(desc) == n or time.monotonic() > deadline:
                    break
        finally:
            stop.set()
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            ex.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
    assert proc.returncode == 0, err
    assert out.splitlines()[0] == f"ROS_DOMAIN_ID={env.domain_id}"  # the exported id, not a new one
    assert len(desc) == 1 and P.decode(desc[0].data)["bridge"]["span_m"] == 15.0
    stamps = [m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec for m in got]
    assert len(got) == len(want) > 2000 and stamps == sorted(stamps)


def test_republish_writers_heartbeat_fast_unless_a_profile_is_exported(monkeypatch, tmp_path):
    """The participant of ``--republish`` is created with a Fast DDS profile file whose writers send
    a heartbeat every 0.1 s (the end's wait for every acknowledgement lasts one period; 3 s by
    Fast DDS's default); the file is gone afterwards. A profile file the user exported is left as
    it is (its heartbeat applies). The republish tests above run through the first path."""
    import importlib
    import xml.etree.ElementTree as ET

    monkeypatch.syspath_prepend(str(ROOT / "launch_scripts"))
    replay = importlib.import_module("replay")
    for k in replay._PROFILE_VARS:
        monkeypatch.delenv(k, raising=False)
    with replay._writer_profile():
        path = Path(os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"])
        ns = "{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}"
        writer = ET.parse(path).getroot().find(f"{ns}profiles/{ns}data_writer")
        assert writer.get("is_default_profile") == "true"
        period = writer.find(f"{ns}times/{ns}heartbeatPeriod")
        assert (period.find(f"{ns}sec").text, period.find(f"{ns}nanosec").text) == ("0", "100000000")
    assert not path.exists() and "FASTRTPS_DEFAULT_PROFILES_FILE" not in os.environ
    mine = tmp_path / "mine.xml"
    monkeypatch.setenv("FASTDDS_DEFAULT_PROFILES_FILE", str(mine))
    with replay._writer_profile():
        assert "FASTRTPS_DEFAULT_PROFILES_FILE" not in os.environ
        assert os.environ["FASTDDS_DEFAULT_PROFILES_FILE"] == str(mine)


# ---------------------------------------------------------------- rerun's writer failing


def _limit_file_size(n_bytes):
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (n_bytes, n_bytes))
    return limit


@pytest.mark.slow
def test_rrd_that_cannot_be_written_whole_fails_the_replay(tmp_path, recording):
    """Under ``ulimit -f 64`` (64 KiB) and on a full 16 KiB tmpfs: rerun's file sink fails (it only
    logs it); replay exits 1 with one ``error:`` line and leaves no .rrd, not even a temporary one."""
    targets = [(tmp_path / "small", _limit_file_size(64 * 1024))]
    full = tmp_path / "full"
    full.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16k", "tmpfs", str(full)],
                             capture_output=True).returncode == 0
    if mounted:
        targets.append((full, None))
    try:
        for folder, limit in targets:
            folder.mkdir(exist_ok=True)
            out = folder / "o.rrd"
            r = subprocess.run([PY, str(REPLAY), str(recording), "--rrd", str(out)], capture_output=True, text=True,
                               timeout=300, preexec_fn=limit)
            assert r.returncode == 1, r.stderr
            assert r.stderr.splitlines() == [f"error: --rrd: rerun could not write '{out}' whole (rerun rrd verify: "
                                             f"Missing RRD footer / no RRD manifests); nothing was written (is the "
                                             f"disk full or a file size limit set?)"]
            assert "logged" not in r.stdout and list(folder.iterdir()) == []
    finally:
        if mounted:
            subprocess.run(["umount", str(full)], capture_output=True)
    assert mounted or os.geteuid() != 0  # root can mount the tmpfs: both faults were tested
