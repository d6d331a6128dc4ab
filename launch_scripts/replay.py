#!/usr/bin/env python3
"""Show a recorded adm-sim run (MCAP) in rerun, or republish it on ROS 2 in simulated time.

Usage::

    replay.py RUN.mcap --rrd OUT.rrd            # write a rerun recording
    replay.py RUN.mcap --spawn                  # open a native viewer (bound to 127.0.0.1)
    replay.py RUN.mcap --connect rerun+http://127.0.0.1:9876/proxy
    replay.py RUN.mcap --rrd OUT.rrd --via-convert   # rerun's own MCAP importer instead
    replay.py RUN.mcap --republish [--domain-id N] [--rate X] [--topics /adm/midspan/accel ...]

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
``ROS_DOMAIN_ID``, else a free, locked id (printed on the first line); ids up to 232 with shared memory
only, 101 with a UDP transport.

Exit status 0 on success, 2 with one line ``error: ...`` on bad input (checked before anything is
read, written or started: RUN.mcap must be an MCAP file, OUT.rrd a new ``.rrd`` file in an existing
folder unless ``--overwrite``, every number finite and in range), 1 with one line when the replay
itself fails (:func:`adm_sim.errors.run_cli`).
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from adm_sim import protocol as P
from adm_sim.cliutil import Parser, add_domain_id, add_overwrite, option_help
from adm_sim.errors import InputError, RunError, run_cli
from adm_sim.fields import view


def check_args(args):
    """Check every option before anything is read, written or started; raises :class:`InputError`."""
    from adm_sim.files import claim_output, mcap_input

    mcap_input(str(args.mcap), "RUN.mcap")
    if args.rrd is not None:
        claim_output(str(args.rrd), "--rrd", args.overwrite, ".rrd")
    if args.connect is not None and not args.connect.startswith(
            ("rerun+http://127.0.0.1:", "rerun+http://localhost:", "rerun+http://[::1]:")):
        raise InputError(f"--connect: {args.connect!r} is not a loopback rerun URL; allowed "
                         f"rerun+http://127.0.0.1:PORT/proxy (the viewer must run on this machine)")
    args.exaggeration = view("cli", "--exaggeration").check(args.exaggeration)
    args.rate = view("cli", "--rate").check(args.rate)
    args.wait_subscribers = view("cli", "--wait-subscribers").check(args.wait_subscribers)
    if args.domain_id is not None:
        args.domain_id = view("cli", "--domain-id").check(args.domain_id)
    if args.republish:  # the transport's range (232 with shared memory only, else 101), an exported id too
        import os

        from adm_sim.processes.dds_env import check_domain_id

        env = {"FASTDDS_BUILTIN_TRANSPORTS": "SHM", **os.environ}
        if args.domain_id is not None:
            check_domain_id(args.domain_id, env, "--domain-id")
        elif os.environ.get("ROS_DOMAIN_ID", "").strip():
            check_domain_id(os.environ["ROS_DOMAIN_ID"], env, "ROS_DOMAIN_ID (exported)")
    if args.topics is not None and not args.republish:
        raise InputError("--topics: only used with --republish; add --republish or drop --topics")
    return args


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
    p.add_argument("--republish", action="store_true", help="republish the run on ROS 2")
    add_domain_id(p, "ROS_DOMAIN_ID (default: a free one)")
    p.add_argument("--rate", default="1", help=option_help("--rate", "republish speed, multiples of simulated time"))
    p.add_argument("--topics", nargs="+", default=None, help="republish only these topics")
    p.add_argument("--wait-subscribers", default="2", metavar="S", help=option_help(
        "--wait-subscribers", "wait up to S s until every republished topic has a subscriber"))
    args = p.parse_args(argv)
    if args.via_convert and args.rrd is None:
        p.error("--via-convert needs --rrd OUT.rrd")
    if not (args.rrd or args.spawn or args.connect or args.republish):
        p.error("nothing to do: give --rrd, --spawn, --connect and/or --republish")
    return args


# ---------------------------------------------------------------- rerun


def _stamp_ns(msg, log_time_ns: int) -> int:
    header = getattr(msg, "header", None)
    if header is not None:
        return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
    return int(log_time_ns)


def show_in_rerun(args, save_path=None) -> dict[str, int]:
    """Decode the MCAP and log it in the adm-sim layout (into ``save_path``, a new ``.rrd``, if
    given); returns message counts per topic."""
    import rerun as rr

    from adm_sim.nodes.common import matrix_from_msg
    from adm_sim.recording import rerun_log as rl
    from adm_sim.recording.mcap_log import read_messages

    rl.init_rerun("adm_sim_replay", spawn=args.spawn, connect_url=args.connect, save_path=save_path)
    viz = rl.RunLogger(exaggeration=args.exaggeration)
    viz.send_blueprint()
    _log_metadata(args.mcap)
    accel = defaultdict(lambda: ([], []))  # AccelStamped outside any recorded run: frame -> (t, a)
    series = defaultdict(lambda: defaultdict(lambda: ([], [])))  # topic -> name -> (t, v)
    counts: dict[str, int] = defaultdict(int)
    deflection = None
    phases = RunPhases(args.mcap)
    for topic, log_time_ns, msg in _status_first(_guarded(read_messages(args.mcap), args.mcap)):
        counts[topic] += 1
        t_s = _stamp_ns(msg, log_time_ns) * 1e-9
        if topic in P.RUN_LOGGER_TOPICS:
            if topic == P.TOPIC_BRIDGE_DESC:
                viz.bridge_description(P.decode(msg.data))
            elif topic == P.TOPIC_TRAIN_DESC:
                viz.train_description(P.decode(msg.data))
            elif topic == P.TOPIC_STATUS:
                st = P.decode(msg.data)
                phases.status(st)
                viz.run_started(st)
            elif topic == P.TOPIC_ACCEL:
                if viz.runs:
                    viz.accel(t_s, msg.accel.linear.z)
                else:
                    accel[msg.header.frame_id or topic][0].append(t_s)
                    accel[msg.header.frame_id or topic][1].append(msg.accel.linear.z)
            elif topic == P.TOPIC_BEAM:
                deflection = matrix_from_msg(msg)
            elif topic == P.TOPIC_AXLES and deflection is not None:
                ax = matrix_from_msg(msg)
                viz.beam(t_s, deflection[0], deflection[1], ax[0], ax[1])
            elif topic == P.TOPIC_RESULT:
                run_id, phase = phases.result()
                viz.run_done(matrix_from_msg(msg), phase, run_id)
            elif topic == P.TOPIC_CAL_ITERATION:
                i, dz_pct, mlm_peak, dim_peak = matrix_from_msg(msg).ravel()[:4]
                viz.iteration(int(i), dz_pct, mlm_peak, dim_peak, phases.last)
            elif topic == P.TOPIC_CAL_RESULT:
                viz.calibration_result(P.decode(msg.data))
            elif topic == P.TOPIC_PROGRESS:
                viz.flush()
        elif hasattr(msg, "accel") and hasattr(msg, "header"):  # AccelStamped
            lane = msg.header.frame_id or topic
            accel[lane][0].append(t_s)
            accel[lane][1].append(msg.accel.linear.z)
        elif hasattr(msg, "status") and hasattr(msg, "header"):  # DiagnosticArray
            rr.set_time(P.SIM_TIME, duration=t_s)
            for st in msg.status:
                level = {0: "INFO", 1: "WARN", 2: "ERROR", 3: "WARN"}.get(_level(st.level), "INFO")
                values = ", ".join(f"{kv.key}={kv.value}" for kv in st.values)
                rr.log(f"{P.ENTITIES['diagnostics']}/{rl._part(st.name or 'status')}",
                       rr.TextLog(f"{st.message} {values}".strip(), level=level))
        elif hasattr(msg, "position") and hasattr(msg, "name"):  # JointState
            for i, name in enumerate(msg.name):
                for field in ("position", "velocity", "effort"):
                    vals = getattr(msg, field)
                    if i < len(vals):
                        s = series[f"{topic}/{field}"][name]
                        s[0].append(t_s)
                        s[1].append(vals[i])
        elif hasattr(msg, "data") and hasattr(msg, "layout"):  # Float64MultiArray
            for i, v in enumerate(msg.data):
                s = series[topic][str(i)]
                s[0].append(t_s)
                s[1].append(v)
        elif hasattr(msg, "data") and isinstance(msg.data, float):  # Float64
            s = series[topic]["value"]
            s[0].append(t_s)
            s[1].append(msg.data)
    viz.flush()
    for lane, (t, a) in accel.items():
        rr.send_columns(f"{P.ENTITIES['topics']}/midspan_acceleration_m_s2/{rl._part(lane)}",
                        indexes=[rr.TimeColumn(P.SIM_TIME, duration=np.asarray(t))],
                        columns=rr.Scalars.columns(scalars=np.asarray(a, dtype=float)))
    for topic, named in series.items():
        for name, (t, v) in named.items():
            rr.send_columns(f"{P.ENTITIES['topics']}{topic}/{rl._part(name)}",
                            indexes=[rr.TimeColumn(P.SIM_TIME, duration=np.asarray(t))],
                            columns=rr.Scalars.columns(scalars=np.asarray(v, dtype=float)))
    rl.close_rerun()
    return dict(counts)


class RunPhases:
    """Which run each result of a recording belongs to, and its phase as the driver recorded it
    (``requested`` records on ``/adm/run/status``, :func:`adm_sim.protocol.request_record`).

    A result belongs to the earliest run the bridge announced (``started``) that has neither a
    result nor a failure yet: a bridge sends one result per run, in order, and the next run's
    ``started`` can carry the same sim time as the last result. A run without a phase record (a
    recording made before runs carried their phase) is ``unknown``, with one warning line per file.
    """

    def __init__(self, path):
        self.path = path
        self.by_run: dict[int, str] = {}
        self.pending: list[int] = []  # announced runs still waiting for their result
        self.last = P.PHASE_UNKNOWN  # phase of the last run whose result was seen
        self.warned = False

    def status(self, st: dict) -> None:
        if P.is_request(st):
            self.by_run[int(st["run_id"])] = str(st.get("phase", P.PHASE_UNKNOWN))
        elif P.is_bridge_start(st) and int(st["run_id"]) not in self.pending:
            self.pending.append(int(st["run_id"]))
        elif st.get("node") == P.BRIDGE_NODE and P.is_failure(st) and st.get("run_id") in self.pending:
            self.pending.remove(st["run_id"])

    def result(self) -> tuple[int | None, str]:
        """``(run_id, phase)`` of the next result (``(None, unknown)``: a result of no announced
        run, which is not drawn)."""
        if not self.pending:
            return None, P.PHASE_UNKNOWN
        run_id = self.pending.pop(0)
        phase = self.by_run.get(run_id)
        if phase is None:
            phase = P.PHASE_UNKNOWN
            if not self.warned:
                self.warned = True
                print(f"warning: RUN.mcap: '{self.path}' records no phase for run {run_id} (recorded before runs "
                      f"carried their phase); its runs are shown with phase '{P.PHASE_UNKNOWN}'",
                      file=sys.stderr, flush=True)
        self.last = phase
        return run_id, phase


def _level(level) -> int:
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


def _log_metadata(path: Path) -> None:
    """The MCAP's metadata records as a table (``metadata``), outside the default views."""
    import rerun as rr
    from mcap.reader import make_reader

    info = {}
    with open(path, "rb") as f:
        try:
            for meta in make_reader(f).iter_metadata():
                for k, v in meta.metadata.items():
                    info[f"{meta.name}.{k}"] = v
        except Exception:  # metadata are optional decoration
            return
    if info:
        rows = "\n".join(f"| {k} | {v} |" for k, v in info.items())
        rr.log(P.ENTITIES["metadata"], rr.TextDocument(f"| key | value |\n|---|---|\n{rows}\n",
                                           media_type=rr.MediaType.MARKDOWN), static=True)


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


def check_readable(path) -> None:
    """Refuse, before any output is written, an MCAP that cannot be read (cut short, damaged) or
    that holds no message: a replay of it would be an empty recording."""
    from adm_sim.recording.mcap_log import check_intact

    try:
        n = check_intact(path)
    except InputError as exc:
        raise InputError(f"RUN.mcap: {str(exc).removeprefix('path: ')}") from None
    except OSError as exc:
        raise _incomplete(path, exc) from None
    if n == 0:
        raise InputError(f"RUN.mcap: '{path}' holds no message; nothing to replay")


def _level(level) -> int:
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


def convert(args, save_path) -> None:
    from adm_sim.recording.rerun_log import ensure_analytics_disabled, rerun_cli, rerun_cli_env

    ensure_analytics_disabled()
    proc = subprocess.run(
        [rerun_cli(), "mcap", "convert", str(args.mcap), "-o", str(save_path),
         "--application-id", "adm_sim_replay"],
        env=rerun_cli_env(), capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
        raise RunError(f"rerun mcap convert failed on '{args.mcap}': {last}")


# ---------------------------------------------------------------- ROS 2 republish


def republish(args, env) -> int:
    """Publish the recorded topics and /clock in simulated time; returns messages published."""
    import importlib

    import rclpy
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    def msg_class(schema_name: str):
        pkg, _, name = schema_name.partition("/msg/")
        if not name:
            pkg, _, name = schema_name.partition("/")
        return getattr(importlib.import_module(f"{pkg}.msg"), name)

    context = rclpy.context.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("adm_replay", context=context)
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    clock_pub = node.create_publisher(Clock, P.TOPIC_CLOCK, 10)
    pubs = {}
    sent = 0
    try:
        with open(args.mcap, "rb") as f:
            reader = make_reader(f)
            try:
                summary = reader.get_summary()
            except (McapError, OSError) as exc:
                raise _incomplete(args.mcap, exc) from None
            if summary is None:
                raise InputError(f"{args.mcap}: no summary; salvage the file first")
            for ch in summary.channels.values():
                if ch.topic == P.TOPIC_CLOCK or (args.topics and ch.topic not in args.topics):
                    continue
                schema = summary.schemas[ch.schema_id]
                pubs[ch.id] = node.create_publisher(msg_class(schema.name), ch.topic, qos)
            if not pubs:
                raise InputError(f"--topics: none of {args.topics} is in '{args.mcap}'")
            deadline = time.monotonic() + args.wait_subscribers
            while time.monotonic() < deadline and any(
                    p.get_subscription_count() == 0 for p in pubs.values()):
                time.sleep(0.05)
            start_wall = time.monotonic()
            start_sim = None
            last_clock = None
            for _schema, channel, message in reader.iter_messages(log_time_order=True):
                pub = pubs.get(channel.id)
                if pub is None:
                    continue
                t_ns = message.log_time
                if start_sim is None:
                    start_sim = t_ns
                if args.rate > 0:
                    due = start_wall + (t_ns - start_sim) * 1e-9 / args.rate
                    pause = due - time.monotonic()
                    if pause > 0:
                        time.sleep(pause)
                if t_ns != last_clock:
                    clock = Clock()
                    clock.clock.sec, clock.clock.nanosec = divmod(t_ns, 1_000_000_000)
                    clock_pub.publish(clock)
                    last_clock = t_ns
                pub.publish(bytes(message.data))
                sent += 1
        time.sleep(0.2)  # let reliable late packets drain before the participant goes away
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return sent


def main(argv=None) -> int:
    return run_cli(lambda: _run(parse_args(argv)))


def _run(args) -> int:
    from adm_sim.files import write_atomic

    check_args(args)
    if args.rrd or args.spawn or args.connect:
        check_readable(args.mcap)
    env = None
    if args.republish:
        from adm_sim.processes.dds_env import apply_local_ros_env

        env = apply_local_ros_env(args.domain_id)  # before rclpy creates a participant
        print(f"ROS_DOMAIN_ID={env.domain_id}", flush=True)
    if args.rrd and args.via_convert:
        write_atomic(args.rrd, lambda tmp: convert(args, tmp))  # a failed replay leaves no stub
        print(f"wrote {args.rrd} (rerun mcap convert)")
    elif args.rrd:
        counts = {}
        write_atomic(args.rrd, lambda tmp: counts.update(show_in_rerun(args, tmp)))
        print(f"logged {sum(counts.values())} messages on {len(counts)} topics to {args.rrd}")
    elif args.spawn or args.connect:
        counts = show_in_rerun(args)
        where = args.rrd or args.connect or "the spawned viewer"
        print(f"logged {sum(counts.values())} messages on {len(counts)} topics to {where}")
    if args.republish:
        n = republish(args, env)
        print(f"republished {n} messages on domain {env.domain_id}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
