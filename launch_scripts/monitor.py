#!/usr/bin/env python
"""Monitor a midspan acceleration topic: each passage's peak, EN 1990 level, and the first mode
(f1, ζ1 with standard uncertainties) from its free decay; live on ROS 2 or from an MCAP recording.

Usage::

    monitor.py --domain-id 42 [--topic /adm/midspan/accel] [--passages N | --duration S] [--json F]
    monitor.py --mcap RUN.mcap [--topic /adm/midspan/accel] [--json F]
    monitor.py --csv LOGGER.csv [--time-column t] [--accel-column a] [--json F]

The topic is any ``geometry_msgs/AccelStamped`` or ``sensor_msgs/Imu`` topic (ours, or a real
accelerometer's; ``--axis``: the component and its sign, z up by default); the run records beside
one of ours (``/adm/run/status``, the bridge and train descriptions) cut the passages where they
exist, the signal where they do not (:mod:`adm_sim.monitoring.modal_id`); ``--csv`` reads a data
logger's export (:mod:`adm_sim.inputs.sensor_csv`). The peak and the level are those of the dynamic
signal: a sensor's static offset (gravity, bias, drift) is removed from the quiet signal before and
after each passage (``--raw`` keeps it). Each passage is printed as one line; ``--json F`` writes
``{"passages": [{"peak_acc_m_s2", "offset_m_s2", "t_peak_s", "level", "f1_hz", "zeta1_pct",
"f1_std_hz", "zeta1_std_pct", "identified", "reason", ...}]}`` (numbers of the fit null and the
reason given when a passage's free decay cannot identify damping). Plausibility warnings (units,
non-finite samples) are printed as ``warning: ...`` lines on stderr and kept in the JSON.

Live: the monitor node (:class:`adm_sim.nodes.monitor_node.MonitorNode`) runs in this process on
``--domain-id`` (or an exported ``ROS_DOMAIN_ID``), shared memory only, until ``--passages`` passages
were reported or ``--duration`` seconds passed; the JSON is rewritten after each passage. It prints
one line once subscribed and one when the topic's publishers are found: a run started after that
line is monitored from its first sample (the subscription is volatile: what was published before
it matched is not delivered). Ctrl-C
or SIGTERM: ``error: interrupted``, exit 130; the JSON then holds the passages completed before.

Bad input, one line ``error: ...`` and exit 2, nothing written: an option out of range, a domain
id out of range, an MCAP that is not one, a topic the MCAP does not hold or that has another type,
a live topic that no publisher offers within ``--timeout`` seconds or that has another type, an Imu
without the chosen axis, a CSV file without the named columns or with times that do not increase,
an MCAP whose topic has a stamp that does not increase (a duplicate or going back: the sample is
named; a bridge's ``started`` record earlier than the last stamp starts the order again), a JSON file that exists (without ``--overwrite``). Live, such a sample is refused and the
monitor goes on (the node's warning where a stretch of them starts and one where it ends).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader

from adm_sim import protocol as P
from adm_sim.cliutil import Parser, add_overwrite, option_view, run_cli
from adm_sim.errors import InputError
from adm_sim.fields import view
from adm_sim.files import claim_output, input_file, mcap_input, write_atomic
from adm_sim.inputs.sensor_csv import read_sensor_csv
from adm_sim.limits import TRACK_TYPES
from adm_sim.monitoring import sensors
from adm_sim.monitoring.modal_id import IdentifySettings, PassageTracker, run_topics_for
from adm_sim.monitoring.sensors import AXES, IMU_TYPE, SENSOR_TYPES, check_imu, parse_axis, sample_of
from adm_sim.recording.mcap_read import read_messages


def parse_args(argv=None):
    p = Parser(prog="monitor.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--mcap", metavar="RUN.mcap", help="read a recording instead of subscribing live")
    p.add_argument("--csv", metavar="FILE", help="read a data logger's CSV export instead (header line; time in s, "
                                                  "acceleration in m/s^2)")
    p.add_argument("--time-column", default=None, metavar="NAME", help="--csv: the time column (default t)")
    p.add_argument("--accel-column", default=None, metavar="NAME",
                   help="--csv: the acceleration column (default a)")
    p.add_argument("--topic", default=P.TOPIC_ACCEL,
                   help=f"the AccelStamped or Imu topic (default {P.TOPIC_ACCEL})")
    p.add_argument("--axis", default="z", metavar="AXIS",
                   help=f"the sensor's vertical axis and sign: {', '.join(AXES)} (default z: z up)")
    p.add_argument("--raw", action="store_true",
                   help="keep the raw signal: no static offset (gravity, bias) removed before the peak")
    p.add_argument("--status-topic", default=None,
                   help="run records (default: the one beside the topic when it is one of ours)")
    p.add_argument("--domain-id", default=None, help="live: ROS_DOMAIN_ID of the graph (default: the exported one)")
    p.add_argument("--timeout", default="10", metavar="S", help="live: error when the topic does not appear "
                                                                "within S s (default 10)")
    p.add_argument("--passages", default=None, metavar="N", help="live: stop after N passages")
    p.add_argument("--duration", default=None, metavar="S", help="live: stop after S s")
    p.add_argument("--track-type", choices=TRACK_TYPES, default=None,
                   help="the limit of EN 1990 A2.4.4.2.1 (default: the bridge description's, else ballasted)")
    p.add_argument("--min-cycles", default="5", help="periods of free decay needed to identify damping (default 5)")
    p.add_argument("--no-bandpass", action="store_true", help="fit the raw samples (no band-pass around f1)")
    p.add_argument("--json", metavar="F", help="write the passages as JSON")
    add_overwrite(p, "replace the JSON file if it exists")
    given, argv = list(sys.argv[1:] if argv is None else argv), []
    while given:  # "--axis -z" read as "--axis=-z" (argparse would take "-z" for an option)
        arg = given.pop(0)
        if arg == "--axis" and given and given[0] in AXES:
            arg = f"--axis={given.pop(0)}"
        argv.append(arg)
    return p.parse_args(argv)


def check_args(args):
    """Every option before anything is read, written or started; raises :class:`InputError`."""
    args.axis_component, args.axis_sign = parse_axis(args.axis)
    if args.csv is not None:
        for opt in ("mcap", "domain_id", "passages", "duration", "status_topic"):
            if getattr(args, opt) is not None:
                raise InputError(f"--{opt.replace('_', '-')}: not used with --csv; drop it or drop --csv")
        args.time_column = args.time_column if args.time_column is not None else "t"
        args.accel_column = args.accel_column if args.accel_column is not None else "a"
        for opt, v in (("--time-column", args.time_column), ("--accel-column", args.accel_column)):
            if not v.strip():
                raise InputError(f"{opt}: '' is empty; give the column's name in the header line")
    elif args.time_column is not None or args.accel_column is not None:
        raise InputError(f"{'--time-column' if args.time_column is not None else '--accel-column'}: only used with "
                         f"--csv; drop it or give --csv FILE")
    if not args.topic or not args.topic.startswith("/"):
        raise InputError(f"--topic: {args.topic!r} is not an absolute topic name; give e.g. {P.TOPIC_ACCEL}")
    if args.status_topic is not None and not args.status_topic.startswith("/"):
        raise InputError(f"--status-topic: {args.status_topic!r} is not an absolute topic name; give e.g. "
                         f"{P.TOPIC_STATUS}")
    args.timeout = option_view("--timeout").check(args.timeout)
    args.min_cycles = option_view("--min-cycles").check(args.min_cycles)
    if args.csv is not None:
        input_file(args.csv, "--csv", "CSV file")
    elif args.mcap is not None:
        for opt in ("domain_id", "passages", "duration"):
            if getattr(args, opt) is not None:
                raise InputError(f"--{opt.replace('_', '-')}: only used live; drop it or drop --mcap")
        mcap_input(args.mcap, "--mcap")
    else:
        if args.passages is not None:
            args.passages = option_view("--passages").check(args.passages)
        if args.duration is not None:
            args.duration = option_view("--duration").check(args.duration)
        args.domain_id = live_domain_id(args.domain_id)
    if args.json is not None:
        claim_output(args.json, "--json", args.overwrite, ".json", inputs={"--mcap": args.mcap, "--csv": args.csv})
    return args


def live_domain_id(given):
    """``--domain-id``, else an exported ``ROS_DOMAIN_ID``, checked against the range of the field
    registry; a live monitor must join an existing graph, so one of them is needed."""
    if given is not None:
        return view("cli", "--domain-id").check(given)
    exported = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if exported:
        try:
            return view("cli", "--domain-id").check(exported)
        except InputError as exc:
            raise InputError(f"ROS_DOMAIN_ID (exported): {str(exc).split(': ', 1)[-1]}") from None
    raise InputError("--domain-id: not given and no ROS_DOMAIN_ID exported; give the domain id of the graph to "
                     "monitor (crossing.py and calibrate.py print theirs)")


# ---------------------------------------------------------------- MCAP
def mcap_channels(path):
    """``{topic: schema name}`` of an MCAP's summary; one line when the file has no summary."""
    with open(path, "rb") as f:
        try:
            summary = make_reader(f).get_summary()
        except (McapError, OSError, ValueError) as exc:
            raise InputError(f"--mcap: '{path}' is not a complete MCAP file ({type(exc).__name__}); recover it "
                             f"with: adm-sim salvage {path} OUT.mcap") from None
    if summary is None:
        raise InputError(f"--mcap: '{path}' has no summary (its writer was killed); recover it with: "
                         f"adm-sim salvage {path} OUT.mcap")
    return {ch.topic: summary.schemas[ch.schema_id].name if ch.schema_id in summary.schemas else ""
            for ch in summary.channels.values()}


def check_mcap_topic(path, topic):
    """The topic is in the MCAP with type AccelStamped or Imu; else one line naming the ones that are."""
    channels = mcap_channels(path)
    accel = sorted(t for t, s in channels.items() if s in SENSOR_TYPES)
    hint = f"its AccelStamped and Imu topics: {', '.join(accel)}" if accel else "it holds no AccelStamped or Imu topic"
    if topic not in channels:
        raise InputError(f"--topic: {topic!r} is not in '{path}'; {hint}")
    if channels[topic] not in SENSOR_TYPES:
        raise InputError(f"--topic: {topic!r} in '{path}' has type {channels[topic] or 'unknown'}, not "
                         f"{' or '.join(SENSOR_TYPES)}; {hint}")
    return channels


def monitor_mcap(args, tracker):
    """Feed the MCAP's samples and run records to ``tracker`` in log-time order."""
    channels = check_mcap_topic(args.mcap, args.topic)
    kind = channels[args.topic]
    if args.status_topic is not None and channels.get(args.status_topic) != "std_msgs/msg/String":
        raise InputError(f"--status-topic: {args.status_topic!r} is not a std_msgs/String topic of '{args.mcap}'")
    ours = run_topics_for(args.topic) or (None, None, None)
    status = args.status_topic or ours[0]
    desc = ours[1:]
    topics = [t for t in (args.topic, status, *desc) if t in channels]
    checked = kind != IMU_TYPE
    n, last = 0, None
    for topic, _log_ns, msg in read_messages(args.mcap, topics=topics):
        if topic == args.topic:
            if not checked:
                check_imu(msg, args.axis_component, f"--topic: {args.topic!r} in '{args.mcap}'")
                checked = True
            t, a = sample_of(msg, kind, args.axis_component, args.axis_sign)
            n += 1
            why = sensors.stamp_order(t, n, last, n - 1)
            if why is not None:
                raise InputError(f"--topic: {args.topic!r} in '{args.mcap}': {why} (samples counted from 1 in log "
                                 f"time order); stamps must strictly increase")
            last = t
            tracker.sample(t, a)
        elif topic == status:
            rec = P.decode(msg.data)
            if sensors.restarts_stamp_order(rec, last):
                last = None  # sim time started again (a new bridge): a new stamp order
            tracker.status(rec)
        elif topic == desc[0]:
            tracker.bridge_description(P.decode(msg.data))
        elif topic == desc[1]:
            tracker.train_description(P.decode(msg.data))
    tracker.flush()


# ---------------------------------------------------------------- main
def main(argv=None) -> int:
    return run_cli(lambda: _run(parse_args(argv)))


def _run(args) -> int:
    check_args(args)
    settings = IdentifySettings(min_cycles=args.min_cycles, bandpass=not args.no_bandpass, raw=args.raw)
    reported = []
    offline = args.mcap is not None or args.csv is not None

    def write(dropped=0, nonfinite=0):
        doc = {"passages": [p.to_dict() for p in reported], "topic": None if args.csv else args.topic,
               "axis": args.axis, "source": args.csv or args.mcap or f"live, ROS_DOMAIN_ID {args.domain_id}",
               "dropped_samples": dropped, "nonfinite_samples": nonfinite}
        if args.csv:
            doc["columns"] = {"time": args.time_column, "accel": args.accel_column}
        write_atomic(Path(args.json), lambda tmp: tmp.write_text(json.dumps(doc, indent=1) + "\n"), "--json")

    def on_passage(p):
        reported.append(p)
        print(p.line(), flush=True)
        for w in p.warnings:
            print(f"warning: {w}", file=sys.stderr, flush=True)
        if args.json is not None and not offline:  # live: the file follows every passage
            write()

    if args.csv is not None:
        t, a = read_sensor_csv(args.csv, args.time_column, args.accel_column)
        tracker = PassageTracker(track_type=args.track_type, settings=settings, on_passage=on_passage)
        for ti, ai in zip(t.tolist(), (args.axis_sign * a).tolist()):
            tracker.sample(ti, ai)
        tracker.flush()
    elif args.mcap is not None:
        tracker = PassageTracker(track_type=args.track_type, settings=settings, on_passage=on_passage)
        monitor_mcap(args, tracker)
    else:
        from _monitor_live import monitor_live  # noqa: PLC0415  rclpy and the monitor node (~0.3 s) only live: --help, bad input and MCAP/CSV answer without them

        tracker = monitor_live(args, on_passage).tracker
    outside = tracker.nonfinite - sum(p.n_nonfinite for p in reported)
    if outside > 0:
        print(f"warning: {outside} non-finite samples (NaN or inf) outside every passage excluded", file=sys.stderr,
              flush=True)
    if args.json is not None:
        write(tracker.dropped, tracker.nonfinite)
    n_id = sum(p.identified for p in reported)
    print(f"{len(reported)} passages, {n_id} with the first mode identified"
          + (f", {tracker.nonfinite} non-finite samples excluded" if tracker.nonfinite else "")
          + (f"; wrote {args.json}" if args.json else ""), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
