#!/usr/bin/env python3
"""Show a recorded adm-sim run (MCAP) in rerun, or republish it on ROS 2 in simulated time.

Usage::

    replay.py RUN.mcap --rrd OUT.rrd            # write a rerun recording
    replay.py RUN.mcap --spawn                  # open a native viewer (bound to 127.0.0.1)
    replay.py RUN.mcap --connect rerun+http://127.0.0.1:9876/proxy
    replay.py RUN.mcap --rrd OUT.rrd --via-convert   # rerun's own MCAP importer instead
    replay.py RUN.mcap --republish [--domain-id N] [--rate X] [--topics /adm/midspan/accel ...] [--wait-clients N]

The recording is decoded with mcap-ros2-support. The adm-sim topics (runs, midspan acceleration,
beam, results, calibration) are drawn by :class:`adm_sim.recording.rerun_log.RunLogger` exactly as the
live recording, with its default blueprint; other topics generically: ``AccelStamped`` outside a
recorded run by ``header.frame_id``, ``DiagnosticArray`` as text log, ``JointState``,
``Float64MultiArray`` and ``Float64`` as scalar series under ``topics/``, metadata records as a
table. Time is the recorded sim time (``header.stamp`` when present, else the record's log time).
Each result is drawn for its run (:class:`RunPhases`) with the phase read from the driver's
``requested`` record of its run id on ``/adm/run/status`` (a Δζ iteration belongs to the run
before it); a recording made before
runs carried their phase replays with phase ``unknown`` (curves ``sweep/curves/unknown*``) and one
line ``warning: ...`` on stderr.

``--republish`` publishes every recorded topic (raw CDR, so any type) except ``/clock``, plus a
``rosgraph_msgs/Clock`` on ``/clock`` ahead of each new time stamp, paced at ``--rate`` times
simulated time (0: as fast as possible). DDS stays on this machine: ``FASTDDS_BUILTIN_TRANSPORTS=SHM``
unless already set, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, and ``--domain-id``, else an exported
``ROS_DOMAIN_ID``, else a free, locked id (printed on the first line, the client's ``export`` line on
the second); ids up to 232 with shared memory only, 101 with a UDP transport. Clients that opted
into the flow control (publishers of ``/adm/run/ack``; ``--wait-clients N`` waits for N of them)
get every sample at any rate: a run's messages stay within ``FLOW_WINDOW`` of each one's
acknowledgement and its ``done`` comes once each has the whole run. Every run's final
``/diagnostics`` is published latched, as the live bridge does. Its writers send a heartbeat every 0.1 s while a sample is not
acknowledged (Fast DDS sends one every 3 s by default, and the replay's end waits for every
subscriber's acknowledgement, which answers a heartbeat), unless a Fast DDS profile file is
exported (``FASTRTPS_DEFAULT_PROFILES_FILE`` or ``FASTDDS_DEFAULT_PROFILES_FILE``): then its
settings are used as they are.

Exit status 0 on success, 2 with one line ``error: ...`` on bad input (checked before anything is
read, written or started: RUN.mcap must be an MCAP file, OUT.rrd a new ``.rrd`` file in an existing
folder unless ``--overwrite``, every number finite and in range), 1 with one line when the replay
itself fails (:func:`adm_sim.cliutil.run_cli`).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from mcap.reader import make_reader

from adm_sim import protocol as P
from adm_sim.cliutil import Parser, add_domain_id, add_overwrite, option_help, run_cli
from adm_sim.errors import InputError, RunError
from adm_sim.fields import view
from adm_sim.files import claim_output, mcap_input, write_atomic
from adm_sim.processes.dds_env import apply_local_ros_env, check_domain_id, clean_dead_shm, client_export_line, record_shm
from adm_sim.recording import viewer_process as vp
from adm_sim.recording.mcap_qos import parse_qos_profiles, topic_qos
from adm_sim.recording.mcap_read import checked_scan, decode_messages, sorted_messages
from adm_sim.recording.mcap_salvage import salvage
from adm_sim.recording.viewer_process import ensure_analytics_disabled, rerun_cli, rerun_cli_env


def check_args(args):
    """Check every option before anything is read, written or started; raises :class:`InputError`."""

    mcap_input(str(args.mcap), "RUN.mcap")
    if args.rrd is not None:
        _refuse_input_as_output(args.mcap, args.rrd)
        claim_output(str(args.rrd), "--rrd", args.overwrite, ".rrd")
    if args.connect is not None and not args.connect.startswith(
            ("rerun+http://127.0.0.1:", "rerun+http://localhost:", "rerun+http://[::1]:")):
        raise InputError(f"--connect: {args.connect!r} is not a loopback rerun URL; allowed "
                         f"rerun+http://127.0.0.1:PORT/proxy (the viewer must run on this machine)")
    args.exaggeration = view("cli", "--exaggeration").check(args.exaggeration)
    args.rate = view("cli", "--rate").check(args.rate)
    args.wait_subscribers = view("cli", "--wait-subscribers").check(args.wait_subscribers)
    args.wait_clients = view("cli", "--wait-clients").check(args.wait_clients)
    if args.domain_id is not None:
        args.domain_id = view("cli", "--domain-id").check(args.domain_id)
    if args.republish:  # the transport's range (232 with shared memory only, else 101), an exported id too


        env = {"FASTDDS_BUILTIN_TRANSPORTS": "SHM", **os.environ}
        if args.domain_id is not None:
            check_domain_id(args.domain_id, env, "--domain-id")
        elif os.environ.get("ROS_DOMAIN_ID", "").strip():
            check_domain_id(os.environ["ROS_DOMAIN_ID"], env, "ROS_DOMAIN_ID (exported)")
    if args.topics is not None and not args.republish:
        raise InputError("--topics: only used with --republish; add --republish or drop --topics")
    return args


def _refuse_input_as_output(mcap: Path, rrd: Path) -> None:
    """``--rrd`` naming the recording being replayed (the same path, a symbolic or a hard link) would
    replace the recording by its own replay."""

    same = Path(rrd).resolve() == Path(mcap).resolve()
    if not same and Path(rrd).exists():
        try:
            same = os.path.samefile(rrd, mcap)
        except OSError:
            same = False
    if same:
        raise InputError(f"--rrd: '{rrd}' is RUN.mcap, the recording being replayed (the same file"
                         f"{'' if str(rrd) == str(mcap) else ' by another name'}); give another file")


def parse_args(argv=None):
    p = Parser(prog="replay.py", description=__doc__.split("\n\n")[0])
    p.add_argument("mcap", metavar="RUN.mcap", type=Path)
    out = p.add_mutually_exclusive_group()
    out.add_argument("--rrd", type=Path, metavar="OUT.rrd", help="write a rerun recording")
    out.add_argument("--spawn", action="store_true", help="open a native rerun viewer")
    out.add_argument("--connect", metavar="URL", help="stream to a running viewer (loopback)")
    p.add_argument("--via-convert", action="store_true",
                   help="with --rrd: use 'rerun mcap convert' instead of the adm-sim views")
    add_overwrite(p, "replace OUT.rrd if it exists")
    p.add_argument("--exaggeration", default="500", help=option_help("--exaggeration", "display factor on beam "
                                                                        "deflections (default 500)"))
    p.add_argument("--skip-damaged", action="store_true",
                   help="replay the intact chunks of a damaged recording (each skipped damage is named on stderr)")
    p.add_argument("--republish", action="store_true", help="republish the run on ROS 2")
    add_domain_id(p, "ROS_DOMAIN_ID (default: a free one)")
    p.add_argument("--rate", default="1", help=option_help("--rate", "republish speed, multiples of simulated time"))
    p.add_argument("--topics", nargs="+", default=None, help="republish only these topics")
    p.add_argument("--wait-subscribers", default="2", metavar="S", help=option_help(
        "--wait-subscribers", "wait up to S s until every republished topic has a subscriber"))
    p.add_argument("--wait-clients", default="0", metavar="N", help=option_help(
        "--wait-clients", "--republish: before the first message, wait (up to 600 s) until N clients opted "
        "into the flow control (docs/recording.md): each gets every sample, at any --rate"))
    args = p.parse_args(argv)
    if args.via_convert and args.rrd is None:
        p.error("--via-convert needs --rrd OUT.rrd")
    if not (args.rrd or args.spawn or args.connect or args.republish):
        p.error("nothing to do: give --rrd, --spawn, --connect and/or --republish")
    return args


# ---------------------------------------------------------------- rerun
def viewer_still_there(url: str, proc=None, what: str = "--connect") -> bool:
    """After logging: one ``warning:`` line when the viewer died or stopped answering (what it shows
    may miss the end of the run); the replay itself stands."""
    if proc is not None and proc.poll() is not None:
        print(f"warning: {what}: the rerun viewer exited during the replay (exit status {proc.returncode}); "
              f"it may show only part of the run", file=sys.stderr)
        return False
    try:
        vp.check_viewer(url, timeout_s=2.0, what=what)
    except RunError as exc:
        print(f"warning: {exc}; it stopped answering during the replay and may show only part of the run",
              file=sys.stderr)
        return False
    return True




#: Seconds without progress after which a viewer that stopped answering is given up (one warning).
VIEWER_STALL_S = 10.0
#: Set when a stalled viewer was given up: rerun's own flush at exit would wait for it again.
_abandoned: list[str] = []


def show_in_rerun(args, found, save_path=None) -> dict[str, int]:
    """Decode the MCAP and log it in the adm-sim layout (into ``save_path``, a new ``.rrd``, if
    given) through the live driver's feed (:class:`adm_sim.recording.viewer_feed.ViewerFeed`);
    ``found`` is the checked :class:`~adm_sim.recording.mcap_log.Scan` of the recording; returns
    message counts per topic.

    Streaming to a viewer (``--connect``), the work runs in a helper thread watched for progress:
    a viewer that stops answering mid-run stalls rerun's sink, and after :data:`VIEWER_STALL_S`
    without progress it is given up with one ``warning:`` line (with ``save_path`` too, the
    ``.rrd`` is then incomplete: :class:`RunError`), never a hang."""

    if not args.connect:
        return _feed_all(args, found, save_path, [0.0, None])
    beat, result = [time.monotonic(), None], []

    def work():
        try:
            result.append(("ok", _feed_all(args, found, save_path, beat)))
        except BaseException as exc:  # handed to the main thread as it is
            result.append(("err", exc))

    th = threading.Thread(target=work, name="rerun-feed", daemon=True)
    th.start()
    while th.is_alive():
        th.join(0.2)
        if th.is_alive() and time.monotonic() - beat[0] > VIEWER_STALL_S:
            _abandoned.append(args.connect)
            why = (f"--connect: the viewer at {args.connect} stopped answering (no progress for "
                   f"{VIEWER_STALL_S:g} s) and was given up")
            if save_path is not None:
                raise RunError(f"{why}; the .rrd would be incomplete")
            print(f"warning: {why}; it shows only part of the run", file=sys.stderr)
            return {} if beat[1] is None else dict(beat[1].counts)
    kind, value = result[0]
    if kind == "err":
        raise value
    return value


def _feed_all(args, found, save_path, beat) -> dict[str, int]:
    """Log the recording into rerun through the live driver's feed; ``beat``: ``[time of the last
    progress, the feed]`` for :func:`show_in_rerun`'s watch."""
    import rerun as rr  # noqa: PLC0415  rerun (~0.9 s) only with a viewer or an .rrd

    from adm_sim.recording import rerun_log as rl  # noqa: PLC0415  rerun (~0.9 s) only with a viewer or an .rrd
    from adm_sim.recording.viewer_feed import RunPhases, ViewerFeed, stamp_ns  # noqa: PLC0415  rerun (~0.9 s) only with a viewer or an .rrd

    rl.init_rerun("adm_sim_replay", spawn=args.spawn, connect_url=args.connect, save_path=save_path)
    viz = rl.RunLogger(exaggeration=args.exaggeration)
    viz.send_blueprint()
    table = _metadata_table(args.mcap)
    if table is not None:  # outside the default views
        rr.log(P.ENTITIES["metadata"], rr.TextDocument(table, media_type=rr.MediaType.MARKDOWN), static=True)
    feed = ViewerFeed(viz, RunPhases(f"RUN.mcap: '{args.mcap}'"))
    beat[1:] = [feed]
    messages = decode_messages(sorted_messages(found), args.mcap)  # damage was named by check_readable
    for topic, log_time_ns, msg in _status_first(_guarded(messages, args.mcap)):
        feed(topic, msg, stamp_ns(msg, log_time_ns))
        beat[0] = time.monotonic()
    feed.finish()
    beat[0] = time.monotonic()
    rl.close_rerun()
    return dict(feed.counts)


def _metadata_table(path: Path) -> str | None:
    """The MCAP's metadata records as a Markdown table (logged to ``metadata``), or None when it has
    none or they cannot be read (they are optional decoration)."""
    info = {}
    with open(path, "rb") as f:
        try:
            for meta in make_reader(f).iter_metadata():
                for k, v in meta.metadata.items():
                    info[f"{meta.name}.{k}"] = v
        except Exception:  # metadata are optional decoration
            return None
    if not info:
        return None
    rows = "\n".join(f"| {k} | {v} |" for k, v in info.items())
    return f"| key | value |\n|---|---|\n{rows}\n"


def _status_first(messages):
    """``messages`` in log-time order with, among those of one log time, the run's opening topics
    first: the recorder writes in order of receipt, and the first monitoring sample of a run (step
    0) carries the same sim time as its ``started`` status, from another publisher."""
    group, t_group = [], None
    for item in messages:
        if item[1] != t_group and group:
            yield from sorted(group, key=lambda m: m[0] not in P.OPENING_TOPICS)  # stable: receipt order otherwise
            group = []
        group.append(item)
        t_group = item[1]
    yield from sorted(group, key=lambda m: m[0] not in P.OPENING_TOPICS)


def _incomplete(path, exc) -> InputError:
    return InputError(f"RUN.mcap: '{path}' is not a complete MCAP file ({type(exc).__name__}); "
                      f"recover it with: adm-sim salvage {path} OUT.mcap")


def _guarded(messages, path):
    """``messages`` with the reader's low-level failures on a cut-short file as one :class:`InputError`
    naming ``RUN.mcap``."""
    try:
        yield from messages
    except OSError as exc:  # e.g. seeking to a footer before the start of a file of a few bytes
        raise _incomplete(path, exc) from None
    except InputError as exc:  # cut short or damaged (read_messages names its argument 'path')
        raise InputError(f"RUN.mcap: {str(exc).removeprefix('path: ')}") from None


def _warn(line: str) -> None:
    print(f"warning: RUN.mcap: {line}", file=sys.stderr, flush=True)


def check_readable(path, skip_damaged: bool = False):
    """Refuse, before any output is written, an MCAP that cannot be read (cut short, damaged: every
    chunk's framing, decompression and CRC is checked; with ``skip_damaged`` its intact chunks are
    used and each skipped damage is named on stderr) or that holds no message: a replay of it would
    be an empty recording."""

    try:
        found = checked_scan(path, skip_damaged, _warn)
    except InputError as exc:
        msg = str(exc).removeprefix("path: ")
        if "--skip-damaged" not in msg and "is damaged" in msg:
            msg = msg.replace("; recover its readable chunks with:", "; replay its intact chunks with --skip-damaged "
                                                                        "or recover them with:")
        raise InputError(f"RUN.mcap: {msg}") from None
    except OSError as exc:
        raise _incomplete(path, exc) from None
    if not found.messages:
        raise InputError(f"RUN.mcap: '{path}' holds no message; nothing to replay")
    check_types(path, found)
    return found


def check_types(path, found) -> None:
    """Refuse, in one line, a recording whose adm-sim topic carries another message type than the
    nodes publish on it (:data:`adm_sim.protocol.TOPICS`): the replay would fail on its first message."""
    seen = {}
    for schema, channel, _msg in found.messages:
        if channel.id not in seen:
            seen[channel.id] = (channel.topic, None if schema is None else schema.name)
    for topic, name in seen.values():
        want = P.TOPICS.get(topic, (None,))[0]
        if want is not None and name is not None and name.replace("/msg/", "/") != want.replace("/msg/", "/"):
            raise InputError(f"RUN.mcap: topic {topic!r} in '{path}' has type {name}, not {want}; a replay takes "
                             f"the types the adm-sim nodes publish (docs/ros.md, Topics)")


def verify_rrd(tmp, final) -> None:
    """``rerun rrd verify`` of the written recording: rerun's file sink reports a failed write (a
    full disk, a file size limit) only in its own log, so a recording that does not load whole is
    this run's failure (:class:`RunError`), and it is never renamed to its final name."""

    try:
        proc = subprocess.run([rerun_cli(), "rrd", "verify", str(tmp)], env=rerun_cli_env(), capture_output=True,
                              text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise RunError(f"--rrd: cannot verify the recording written for '{final}' ({exc})") from None
    if proc.returncode != 0:
        lines = [ln.strip() for ln in (proc.stderr + proc.stdout).splitlines() if ln.strip()]
        why = next((ln for ln in lines if "rrd" in ln.lower() or "footer" in ln.lower()), lines[-1] if lines else "")
        why = why.replace(f'"{tmp}": ', "").replace(str(tmp), "the file")
        raise RunError(f"--rrd: rerun could not write '{final}' whole (rerun rrd verify: {why}); "
                       f"nothing was written (is the disk full or a file size limit set?)")


def convert(args, save_path) -> None:

    ensure_analytics_disabled()
    source = Path(args.mcap)
    if args.skip_damaged:  # rerun's importer reads a clean copy of the intact chunks
        source = Path(save_path).with_name(Path(save_path).name + ".intact.mcap")
        salvage(args.mcap, source, overwrite=True)
    try:
        proc = subprocess.run(
            [rerun_cli(), "mcap", "convert", str(source), "-o", str(save_path),
             "--application-id", "adm_sim_replay"],
            env=rerun_cli_env(), capture_output=True, text=True, timeout=600)
    finally:
        if source != Path(args.mcap):
            source.unlink(missing_ok=True)
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
        raise RunError(f"rerun mcap convert failed on '{args.mcap}': {last}")


# ---------------------------------------------------------------- ROS 2 republish


def _qos_profile(offered: str, topic: str):
    """The rclpy QoS a channel was offered with: its ``offered_qos_profiles`` (rosbag2's metadata,
    written by :class:`adm_sim.recording.mcap_log.McapRecorder`), else the class of its topic in
    :data:`adm_sim.protocol.TOPICS` (recordings made before channels carried it)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415  rclpy (~0.2 s) only when republishing


    history, depth, reliability, durability = parse_qos_profiles(offered) or topic_qos(topic)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if history == "keep_all" else HistoryPolicy.KEEP_LAST,
        depth=max(1, depth),
        reliability=ReliabilityPolicy.BEST_EFFORT if reliability == "best_effort" else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if durability == "transient_local" else DurabilityPolicy.VOLATILE)


#: Heartbeat period of the replay's writers (s): a subscriber acknowledges samples when a heartbeat
#: asks, so the wait for every acknowledgement (:class:`_FlowControl`) lasts up to one period.
HEARTBEAT_S = 0.1
_PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
_WRITER_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <data_writer profile_name="adm_replay_writer" is_default_profile="true">
      <times><heartbeatPeriod><sec>0</sec><nanosec>{ns}</nanosec></heartbeatPeriod></times>
    </data_writer>
  </profiles>
</dds>
"""


@contextlib.contextmanager
def _writer_profile():
    """While the participant is created: a Fast DDS profile file whose writers send a heartbeat
    every :data:`HEARTBEAT_S` (the transport stays the one the environment names), unless the
    user exported a profile file; the file is removed afterwards (Fast DDS reads it once)."""
    if any(os.environ.get(k) for k in _PROFILE_VARS):
        yield
        return
    fd, path = tempfile.mkstemp(prefix="adm_replay_", suffix=".xml")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(_WRITER_PROFILE.format(ns=round(HEARTBEAT_S * 1e9)))
        os.environ[_PROFILE_VARS[0]] = path
        yield
    finally:
        os.environ.pop(_PROFILE_VARS[0], None)
        os.unlink(path)


class _FlowControl:
    """Publish without outrunning the subscribers: at most ``window`` messages of a reliable
    publisher are unacknowledged (``window`` = half the history depth of the publisher, the
    recorded one, and of each matched subscriber whose depth the graph reports); then the replay
    waits until every matched reader acknowledged them (``Publisher.wait_for_all_acked``), so the
    publisher's history never drops a sample a reader has not received. A reader that stays
    silent for ``ack_timeout_s`` is an error. DDS discovery does not carry a reader's history
    depth: a subscriber that must not lose samples at ``--rate 0`` takes them with KEEP_ALL or a
    history as deep as the recording's (5000 for the monitoring topics)."""

    def __init__(self, node, ack_timeout_s: float = 30.0):
        self.node = node
        self.ack_timeout_s = ack_timeout_s
        self.windows: dict = {}
        self.outstanding: dict = {}

    def add(self, pub, topic: str, qos) -> None:
        from rclpy.qos import ReliabilityPolicy  # noqa: PLC0415  rclpy (~0.2 s) only when republishing

        if qos.reliability != ReliabilityPolicy.RELIABLE:
            return  # best effort: nothing to wait for
        infos = self.node.get_subscriptions_info_by_topic(topic)
        deadline = time.monotonic() + 2.0  # the graph cache can lag the match
        while len(infos) < pub.get_subscription_count() and time.monotonic() < deadline:
            time.sleep(0.05)
            infos = self.node.get_subscriptions_info_by_topic(topic)
        # DDS discovery does not carry a reader's history depth (the graph reports 0 then)
        depths = [qos.depth] + [i.qos_profile.depth for i in infos if i.qos_profile.depth > 0]
        self.windows[pub] = max(1, min(depths) // 2)
        self.outstanding[pub] = 0

    def sent(self, pub, topic: str) -> None:
        if pub not in self.windows:
            return
        self.outstanding[pub] += 1
        if self.outstanding[pub] >= self.windows[pub]:
            self.drain(pub, topic)

    def drain(self, pub, topic: str) -> None:
        from rclpy.duration import Duration  # noqa: PLC0415  rclpy (~0.2 s) only when republishing

        if pub.get_subscription_count() and not pub.wait_for_all_acked(Duration(seconds=self.ack_timeout_s)):
            raise RunError(f"republish: the subscribers of '{topic}' acknowledged nothing for "
                           f"{self.ack_timeout_s:g} s; stopped")
        self.outstanding[pub] = 0

    def drain_all(self, topics: dict) -> None:
        for pub in list(self.outstanding):
            if self.outstanding[pub]:
                self.drain(pub, topics[pub])


class _ClientFlow:
    """The bridge's flow control (docs/ros.md, "Flow control") for the clients that opted in: the
    publishers of ``/adm/run/ack`` when the replay starts. The replay counts what it publishes of
    each run (from the bridge's ``started`` record on) per topic of
    :data:`adm_sim.protocol.SAMPLE_TOPICS`, publishes at most :data:`adm_sim.protocol.FLOW_WINDOW`
    messages beyond a client's acknowledgement (over the topics the client counts, all of them
    until it names its own), and publishes a run's ``done`` only once every client acknowledged
    the whole run, as the bridge does. A client that acknowledges nothing for ``ack_timeout_s`` is no longer waited for
    (one ``warning:`` line), as the bridge does."""

    def __init__(self, node, executor, ack_timeout_s: float):
        from std_msgs.msg import String  # noqa: PLC0415  rclpy (~0.2 s) only when republishing

        from adm_sim.nodes.common import QOS_CONTROL  # noqa: PLC0415  rclpy (~0.2 s) only when republishing

        self.node, self.executor, self.ack_timeout_s = node, executor, ack_timeout_s
        self.clients: dict = {}  # name -> [acknowledged, topics or None]
        self.counts = dict.fromkeys(P.SAMPLE_TOPICS, 0)
        self.total = 0
        self.since = time.monotonic()
        node.create_subscription(String, P.relative(P.TOPIC_ACK), self._on_ack, QOS_CONTROL)

    def join(self, want=0, idle=lambda: None, timeout_s=600.0):
        """Take the publishers of ``/adm/run/ack`` on the graph as the clients to wait for, once
        there are ``want`` of them (at most ``timeout_s``, then :class:`RunError`)."""
        t_end = time.monotonic() + timeout_s
        infos = self.node.get_publishers_info_by_topic(P.TOPIC_ACK)
        while len(infos) < want:
            if time.monotonic() > t_end:
                raise RunError(f"--wait-clients: {want} client(s) asked for, {len(infos)} opted in within "
                               f"{timeout_s:g} s")
            idle()
            self.executor.spin_once(timeout_sec=0.05)
            infos = self.node.get_publishers_info_by_topic(P.TOPIC_ACK)
        if want:
            time.sleep(2.0)  # the clients' own view of this replay (their subscriptions matched) can lag this one
        self.clients = {i.node_namespace.rstrip("/") + "/" + i.node_name: [0, None] for i in infos}
        if self.clients:
            print(f"clients opted in: {', '.join(sorted(self.clients))}", flush=True)

    def _on_ack(self, msg):
        rec = P.decode(msg.data)
        c = self.clients.get(rec.get("node"))
        if c is None:
            return
        c[0] = max(c[0], int(rec.get("received", 0)))
        if rec.get("topics") is not None:
            c[1] = tuple(t for t in rec["topics"] if t in self.counts)
        self.since = time.monotonic()

    def _sent_to(self, c):
        return self.total if c[1] is None else sum(self.counts[t] for t in c[1])

    def _wait(self, lagging):
        """Spin until no client is ``lagging`` (a predicate of ``(name, client)``)."""
        self.since = time.monotonic()
        while True:
            late = [n for n, c in self.clients.items() if lagging(c)]
            if not late:
                return
            if time.monotonic() - self.since > self.ack_timeout_s:
                for n in late:
                    print(f"warning: republish: client '{n}' acknowledged nothing for {self.ack_timeout_s:g} s; "
                          f"it is no longer waited for", file=sys.stderr, flush=True)
                    del self.clients[n]
                return
            self.executor.spin_once(timeout_sec=0.01)

    def sent(self, topic: str, n_sent: int):
        """One message of ``topic`` published (``n_sent``: the replay's count so far)."""
        if not self.clients or topic not in self.counts:
            return
        self.counts[topic] += 1
        self.total += 1
        if n_sent % P.ACK_EVERY == 0:
            self.executor.spin_once(timeout_sec=0.0)
        self._wait(lambda c: self._sent_to(c) - c[0] >= P.FLOW_WINDOW)

    def run_end(self):
        """Before a run's ``done`` (or ``failed``) record: every client has the whole run."""
        if self.clients:
            self._wait(lambda c: c[0] < self._sent_to(c))

    def run_start(self):
        """At a run's ``started`` record: count its messages from 0."""
        self.counts = dict.fromkeys(P.SAMPLE_TOPICS, 0)
        self.total = 0
        for c in self.clients.values():
            c[0] = 0


def _is_final_diagnostics(data: bytes) -> bool:
    """Whether a recorded ``/diagnostics`` message is a bridge's final one of a run (value ``final``
    ``True``): the live bridge latches it."""
    from diagnostic_msgs.msg import DiagnosticArray  # noqa: PLC0415  rclpy (~0.2 s) only when republishing
    from rclpy.serialization import deserialize_message  # noqa: PLC0415  rclpy (~0.2 s) only when republishing

    arr = deserialize_message(data, DiagnosticArray)
    return any(kv.key == "final" and kv.value == "True" for st in arr.status for kv in st.values)


def _bridge_record(data: bytes) -> str | None:
    """``started``, ``done`` or ``failed`` when a recorded ``/adm/run/status`` message is the
    bridge's record of that state, else None."""
    from rclpy.serialization import deserialize_message  # noqa: PLC0415  rclpy (~0.2 s) only when republishing
    from std_msgs.msg import String  # noqa: PLC0415  rclpy (~0.2 s) only when republishing

    text = deserialize_message(data, String).data
    if not text.startswith("{"):
        return None
    rec = P.decode(text)
    if rec.get("node") != P.BRIDGE_NODE or rec.get("state") not in (P.STARTED, P.DONE, P.FAILED):
        return None
    return rec["state"]


def _msg_class(schema_name: str):
    """The message class of a recorded schema name (``pkg/msg/Type`` or ``pkg/Type``)."""
    pkg, _, name = schema_name.partition("/msg/")
    if not name:
        pkg, _, name = schema_name.partition("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


class _ShmNote:
    """This process's Fast DDS files, noted at most every 0.5 s while it lives (a SIGKILL gives no
    later chance to name them)."""

    def __init__(self):
        self.at = 0.0

    def __call__(self):
        if time.monotonic() - self.at >= 0.5:
            self.at = time.monotonic()
            record_shm([os.getpid()])


class _Publishers:
    """The replay's publishers: one per recorded channel with the QoS it was recorded with, the
    runs' final ``/diagnostics`` latched again (as the live bridge's), and ``/clock``."""

    def __init__(self, node, items):
        from rosgraph_msgs.msg import Clock  # noqa: PLC0415  rclpy (~0.2 s) only when republishing

        self.Clock = Clock
        self.pubs, self.qos_of, self.topics = {}, {}, {}
        self.diag_final = None
        for schema, ch, _m in items:
            if ch.id in self.pubs:
                continue
            self.qos_of[ch.id] = _qos_profile(ch.metadata.get("offered_qos_profiles", ""), ch.topic)
            self.pubs[ch.id] = node.create_publisher(_msg_class(schema.name), ch.topic, self.qos_of[ch.id])
            self.topics[self.pubs[ch.id]] = ch.topic
            if ch.topic == P.TOPIC_DIAGNOSTICS:
                latched = _qos_profile("", P.TOPIC_BRIDGE_DESC)  # class L: transient local, depth 1
                self.diag_final = node.create_publisher(_msg_class(schema.name), ch.topic, latched)
                self.topics[self.diag_final] = ch.topic
                self.qos_of["diag_final"] = latched
        self.clock_qos = _qos_profile("", P.TOPIC_CLOCK)
        self.clock = node.create_publisher(Clock, P.TOPIC_CLOCK, self.clock_qos)
        self.topics[self.clock] = P.TOPIC_CLOCK

    def wait_subscribers(self, wait_s, note_shm):
        """Up to ``wait_s`` for every recorded topic to have a subscriber."""
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline and any(p.get_subscription_count() == 0 for p in self.pubs.values()):
            note_shm()
            time.sleep(0.05)

    def flow_controlled(self, flow):
        """Register every publisher with the flow control."""
        for cid, pub in self.pubs.items():
            flow.add(pub, self.topics[pub], self.qos_of[cid])
        if self.diag_final is not None:
            flow.add(self.diag_final, P.TOPIC_DIAGNOSTICS, self.qos_of["diag_final"])
        flow.add(self.clock, P.TOPIC_CLOCK, self.clock_qos)

    def publish_clock(self, t_ns, flow):
        clock = self.Clock()
        clock.clock.sec, clock.clock.nanosec = divmod(t_ns, 1_000_000_000)
        self.clock.publish(clock)
        flow.sent(self.clock, P.TOPIC_CLOCK)


def _replay_items(args, items, *, out, flow, clients, note_shm) -> int:
    """Publish ``items`` in their recorded order at ``args.rate`` times sim time (0: as fast as the
    flow control lets), ``/clock`` before each new stamp; returns the messages published."""
    sent = 0
    start_wall = time.monotonic()
    start_sim = items[0][2].log_time
    last_clock = None
    for _schema, channel, message in items:
        pub = out.pubs[channel.id]
        t_ns = message.log_time
        if args.rate > 0:
            pause = start_wall + (t_ns - start_sim) * 1e-9 / args.rate - time.monotonic()
            if pause > 0:
                time.sleep(pause)
        if t_ns != last_clock:
            out.publish_clock(t_ns, flow)
            last_clock = t_ns
        data = bytes(message.data)
        state = _bridge_record(data) if channel.topic == P.TOPIC_STATUS else None
        if state in (P.DONE, P.FAILED):
            clients.run_end()  # as the bridge: a run's done only once the opted-in clients have it whole
        elif state == P.STARTED:
            clients.run_start()
        if channel.topic == P.TOPIC_DIAGNOSTICS and out.diag_final is not None and _is_final_diagnostics(data):
            pub = out.diag_final
        pub.publish(data)
        flow.sent(pub, channel.topic)
        sent += 1
        clients.sent(channel.topic, sent)
        note_shm()
    return sent


def republish(args, found) -> int:
    """Publish the recorded topics (``found``: the checked scan of the recording) and /clock in
    simulated time, each with the QoS it was recorded with (descriptions latched again),
    flow-controlled; returns messages published."""

    import rclpy  # noqa: PLC0415  rclpy (~0.2 s) only when republishing
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415  rclpy (~0.2 s) only when republishing


    items = [m for m in sorted_messages(found, args.topics) if m[1].topic != P.TOPIC_CLOCK]
    if not items:
        raise InputError(f"--topics: none of {args.topics} is in '{args.mcap}'")

    clean_dead_shm()  # what an earlier replay or node killed with SIGKILL left in /dev/shm
    context = rclpy.context.Context()
    with _writer_profile():
        rclpy.init(context=context)
        node = rclpy.create_node("adm_replay", context=context)
    note_shm = _ShmNote()
    note_shm()
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    flow = _FlowControl(node)
    clients = _ClientFlow(node, executor, ack_timeout_s=flow.ack_timeout_s)
    try:
        out = _Publishers(node, items)
        out.wait_subscribers(args.wait_subscribers, note_shm)
        out.flow_controlled(flow)
        clients.join(args.wait_clients, note_shm)
        sent = _replay_items(args, items, out=out, flow=flow, clients=clients, note_shm=note_shm)
        clients.run_end()  # the last run whole for every opted-in client (a recording cut short)
        flow.drain_all(out.topics)  # every reliable message acknowledged before the participant goes away
    finally:
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return sent


def main(argv=None) -> int:
    code = run_cli(lambda: _run(parse_args(argv)))
    if _abandoned:  # rerun's flush at interpreter exit would wait for the given-up viewer again
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _run(args) -> int:

    check_args(args)
    found = check_readable(args.mcap, args.skip_damaged)  # every reader: damage named before anything starts
    env = viewer = None
    if args.connect:  # a viewer that is not there (closed port, another server, silence): one line, exit 1
        vp.check_viewer(args.connect, what="--connect")
    elif args.spawn:  # listening, answering and alive a moment later, or one line with its last word, exit 1
        viewer, args.connect = vp.spawn_viewer(what="--spawn")
        args.spawn = False
    if args.republish:
        try:
            env = apply_local_ros_env(args.domain_id)  # before rclpy creates a participant
        except BaseException:  # refused before anything was shown: the spawned viewer goes too
            if viewer is not None:
                vp.stop_viewer(viewer)
            raise
        print(f"ROS_DOMAIN_ID={env.domain_id}", flush=True)
        print(f"{client_export_line(env)}  # a ROS 2 client in another shell", flush=True)
    if args.rrd and args.via_convert:
        write_atomic(args.rrd, lambda tmp: (convert(args, tmp), verify_rrd(tmp, args.rrd)))  # a failed replay leaves no stub
        print(f"wrote {args.rrd} (rerun mcap convert)")
    elif args.rrd:
        # rerun's own log would add coloured lines to the one error line of a failed write, which
        # verify_rrd reports; RUST_LOG set by the caller is kept
        os.environ.setdefault("RUST_LOG", "off")
        counts = {}
        write_atomic(args.rrd, lambda tmp: (counts.update(show_in_rerun(args, found, tmp)), verify_rrd(tmp, args.rrd)))
        print(f"logged {sum(counts.values())} messages on {len(counts)} topics to {args.rrd}")
    elif args.connect:
        counts = show_in_rerun(args, found)
        where = args.connect if viewer is None else f"the spawned viewer ({args.connect})"
        print(f"logged {sum(counts.values())} messages on {len(counts)} topics to {where}")
    if args.connect and not _abandoned:
        viewer_still_there(args.connect, viewer, "--connect" if viewer is None else "--spawn")
    if args.republish:
        n = republish(args, found)
        print(f"republished {n} messages on domain {env.domain_id}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
