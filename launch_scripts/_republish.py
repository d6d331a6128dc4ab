"""``replay.py --republish``: the recorded topics published again on ROS 2, in simulated time.

Every recorded channel gets a publisher with the QoS it was recorded with (its
``offered_qos_profiles``, else its topic's class), the runs' final ``/diagnostics`` are latched
again as the live bridge's, and a ``rosgraph_msgs/Clock`` goes out on ``/clock`` ahead of each new
stamp. Two flow controls keep every subscriber whole: :class:`_FlowControl` keeps a reliable
publisher's unacknowledged messages within half the history depths, :class:`_ClientFlow` is the
bridge's flow control for the clients that opted in (docs/ros.md, "Flow control"). The command line,
its checks and the ROS environment are ``replay.py``'s; this module is imported only when a replay
republishes (rclpy and the message packages load here, ~0.2 s).
"""

from __future__ import annotations

import importlib
import os
import sys
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from adm_sim import protocol as P
from adm_sim.errors import InputError, RunError
from adm_sim.nodes.common import QOS_CONTROL, stopped_by_signal
from adm_sim.nodes.flow_client import named_publishers
from adm_sim.processes.dds_env import clean_dead_shm, record_shm
from adm_sim.recording.mcap_qos import parse_qos_profiles, topic_qos
from adm_sim.recording.mcap_read import sorted_messages

__all__ = ["republish"]


def _qos_profile(offered: str, topic: str):
    """The rclpy QoS a channel was offered with: its ``offered_qos_profiles`` (rosbag2's metadata,
    written by :class:`adm_sim.recording.mcap_log.McapRecorder`), else the class of its topic in
    :data:`adm_sim.protocol.TOPICS` (recordings made before channels carried it)."""
    history, depth, reliability, durability = parse_qos_profiles(offered) or topic_qos(topic)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if history == "keep_all" else HistoryPolicy.KEEP_LAST,
        depth=max(1, depth),
        reliability=ReliabilityPolicy.BEST_EFFORT if reliability == "best_effort" else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if durability == "transient_local" else DurabilityPolicy.VOLATILE)


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
        names = named_publishers(self.node.get_publishers_info_by_topic(P.TOPIC_ACK))
        while len(names) < want:  # by name: a publisher whose node name is not discovered yet does not count
            if time.monotonic() > t_end:
                raise RunError(f"--wait-clients: {want} client(s) asked for, {len(names)} opted in within "
                               f"{timeout_s:g} s")
            idle()
            self.executor.spin_once(timeout_sec=0.05)
            names = named_publishers(self.node.get_publishers_info_by_topic(P.TOPIC_ACK))
        if want:
            time.sleep(2.0)  # the clients' own view of this replay (their subscriptions matched) can lag this one
            names = named_publishers(self.node.get_publishers_info_by_topic(P.TOPIC_ACK))  # as the graph is now
        self.clients = {n: [0, None] for n in names}
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
    arr = deserialize_message(data, DiagnosticArray)
    return any(kv.key == "final" and kv.value == "True" for st in arr.status for kv in st.values)


def _bridge_record(data: bytes) -> str | None:
    """``started``, ``done`` or ``failed`` when a recorded ``/adm/run/status`` message is the
    bridge's record of that state, else None."""
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


def republish(args, found, writer_profile) -> int:
    """Publish the recorded topics (``found``: the checked scan of the recording) and /clock in
    simulated time, each with the QoS it was recorded with (descriptions latched again),
    flow-controlled; returns messages published. ``writer_profile``: the context manager in which
    the participant is created (``replay._writer_profile``: the writers' heartbeat)."""

    items = [m for m in sorted_messages(found, args.topics) if m[1].topic != P.TOPIC_CLOCK]
    if not items:
        raise InputError(f"--topics: none of {args.topics} is in '{args.mcap}'")

    clean_dead_shm()  # what an earlier replay or node killed with SIGKILL left in /dev/shm
    context = rclpy.context.Context()
    with writer_profile():
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
    except Exception as exc:
        if not stopped_by_signal(exc, context):
            raise
        raise KeyboardInterrupt from exc  # Ctrl-C shut rclpy down under the executor: the interrupt
    finally:
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return sent


