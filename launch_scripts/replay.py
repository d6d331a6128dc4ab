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
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path


from adm_sim import protocol as P
from adm_sim.cliutil import Parser, add_domain_id, add_overwrite, option_help, run_cli
from adm_sim.errors import InputError, RunError
from adm_sim.fields import view
from adm_sim.files import claim_output, mcap_input, write_atomic
from adm_sim.processes.dds_env import apply_local_ros_env, check_domain_id, client_export_line
from adm_sim.recording import viewer_process as vp
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
    """Log the recording into rerun (:func:`_replay_feed.feed_all`), its reader's failures on a
    cut-short file named as ``RUN.mcap``'s."""
    from _replay_feed import feed_all  # noqa: PLC0415  rerun (~0.9 s) only with a viewer or an .rrd: --help, bad input and --republish answer without it

    messages = decode_messages(sorted_messages(found), args.mcap)  # damage was named by check_readable
    return feed_all(args, _guarded(messages, args.mcap), save_path, beat)


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


# ---------------------------------------------------------------- ROS 2 republish (in _republish.py)


#: Heartbeat period of the replay's writers (s): a subscriber acknowledges samples when a heartbeat
#: asks, so the wait for every acknowledgement (``_republish._FlowControl``) lasts up to one period.
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
        from _republish import republish  # noqa: PLC0415  rclpy (~0.2 s) only when republishing: --help, bad input and the viewer paths answer without it

        n = republish(args, found, _writer_profile)
        print(f"republished {n} messages on domain {env.domain_id}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
