"""Monitor node: the passages of any ``geometry_msgs/AccelStamped`` or ``sensor_msgs/Imu`` topic,
their EN 1990 level and the first mode (f1, ζ1) identified from each free decay.

A thin adapter over :class:`adm_sim.monitoring.modal_id.PassageTracker` (ROS-free): it subscribes to the
acceleration ``topic`` (ours, ``/adm/midspan/accel``, or a real accelerometer's; ``axis`` the
component and its sign, ``z`` up by default, :mod:`adm_sim.monitoring.sensors`), to the run
records on ``status_topic`` when a graph publishes them (one passage per run, samples assigned by
stamp) and to the latched bridge and train descriptions (span, train length, track type and
limit); without run records it segments passages by the signal and removes each passage's static
offset (gravity, bias; ``raw`` keeps it). ``|a|`` is used, so the sign convention of the sensor
does not matter for the peak. Each passage is logged as one line and, with ``json_path``, the JSON
file (``{"passages": [...]}``, :meth:`adm_sim.monitoring.modal_id.Passage.to_dict`) is rewritten
after each one (written beside and renamed: always complete).

QoS: the sample subscription is made once the topic's publishers are on the graph, with their
type and reliability: RELIABLE, KEEP_LAST 5000 (the depth of the bridge's monitoring topics), or
BEST_EFFORT when a publisher offers only that (the sensor-data profile of many drivers; a reliable
subscription would not match it). A best-effort publisher that joins later switches the
subscription to best effort (the monitor's own log line, not rclpy's incompatible-QoS warning).

Bad input (exit 2, one line ``error: monitor: ...`` and nothing before it): a parameter out of
range, a topic that has another type than ``AccelStamped`` or ``Imu``, an Imu without the chosen
axis, a topic that no publisher offers within ``topic_timeout_s``. A sample whose stamp does not
come after the last one taken (a duplicate, or time going back) is refused and the node goes on: one
warning naming the topic and the sample (counted from 1 as received) where such a stretch starts,
one where it ends; a bridge's ``started`` run record earlier than the last stamp (a new bridge's
sim time) starts the order again.

    python -m adm_sim.nodes.monitor_node --ros-args -p topic:=/adm/midspan/accel -p json_path:=passages.json
"""

from __future__ import annotations

import json
import sys
import time

import rclpy
from geometry_msgs.msg import AccelStamped
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from adm_sim import protocol as P
from adm_sim.errors import InputError
from adm_sim.files import claim_output, release_all, write_atomic
from adm_sim.limits import TRACK_TYPES, check_track_type
from adm_sim.monitoring.modal_id import IdentifySettings, PassageTracker, run_topics_for
from adm_sim.monitoring.sensors import (ACCEL_TYPE, AXES, IMU_TYPE, SENSOR_TYPES, check_imu, parse_axis,
                                        restarts_stamp_order, sample_of, stamp_order)
from adm_sim.nodes import common as c

__all__ = ["ACCEL_TYPE", "MONITOR_SPECS", "MonitorNode", "main", "passages_document"]

#: Message classes of the types the monitor reads.
SENSOR_CLASSES = {ACCEL_TYPE: AccelStamped, IMU_TYPE: Imu}
#: Samples: reliable, as deep as the bridge's monitoring history (bursts of whole step blocks).
QOS_SAMPLES = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
QOS_SAMPLES_BEST_EFFORT = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                                     reliability=ReliabilityPolicy.BEST_EFFORT,
                                     durability=DurabilityPolicy.VOLATILE)

MONITOR_SPECS = [
    c.ParamSpec("topic", P.TOPIC_ACCEL, "", f"the {ACCEL_TYPE} or {IMU_TYPE} topic to monitor"),
    c.ParamSpec("axis", "z", "", f"the sensor's vertical axis and its sign: {' | '.join(AXES)} (z up)"),
    c.ParamSpec("raw", False, "", "keep the raw signal: no static offset (gravity, bias) removed"),
    c.ParamSpec("status_topic", "", "", f"run records ({P.TOPIC_STATUS} JSON); empty = the one beside the "
                                        "topic when it ends in /adm/midspan/accel"),
    c.ParamSpec("track_type", "", "", f"limit of EN 1990 A2.4.4.2.1: {' | '.join(TRACK_TYPES)}; empty = the "
                                      "bridge description's, else ballasted"),
    c.param("warn_fraction", 0.8, "level 'near' above this fraction of the limit"),
    c.param("topic_timeout_s", 10.0),
    c.param("settle_s", 1.0),
    c.param("quiet_s", 10.0),
    c.param("min_cycles", 5.0),
    c.ParamSpec("bandpass", True, "", "band-pass around the FFT peak before the fit"),
    c.ParamSpec("json_path", "", "", "JSON file of the passages, rewritten after each; empty = none"),
    c.ParamSpec("overwrite", False, "", "replace an existing json_path"),
    c.ParamSpec("flow_control", True, "", "opt into the bridge's flow control on our own topic (no sample lost)"),
]


class MonitorNode(c.ParamNodeMixin, Node):
    """Subscribes, tracks passages, reports them; see the module docstring.

    ``on_passage`` (optional) is called with every :class:`adm_sim.monitoring.modal_id.Passage` after it is
    logged; ``quiet``: log nothing (the launcher prints the lines itself, on stdout); ``on_warning``
    (optional) takes the warnings (a sample refused for its stamp) instead of the ROS logger.
    """

    def __init__(self, on_passage=None, quiet=False, on_warning=None, **kw):
        super().__init__("monitor", **kw)
        self.quiet = quiet
        self.on_warning = on_warning
        self.declare_specs(MONITOR_SPECS)
        p = self.param_values()
        track = p["track_type"] or None
        if track is not None:
            check_track_type("track_type", track)
        self.topic = self.resolve_topic_name(p["topic"]) if p["topic"] else ""
        if not self.topic:
            raise InputError("topic: '' is empty; give the AccelStamped or Imu topic to monitor")
        self.axis, self.sign = parse_axis(p["axis"], "axis")
        self.timeout_s = float(p["topic_timeout_s"])
        self.on_passage = on_passage
        self.json_path = p["json_path"] or None
        if self.json_path is not None:
            claim_output(self.json_path, "json_path", bool(p["overwrite"]), ".json",
                         overwrite_hint="set -p overwrite:=true to replace it")
        settings = IdentifySettings(min_cycles=float(p["min_cycles"]), bandpass=bool(p["bandpass"]), raw=bool(p["raw"]))
        self.tracker = PassageTracker(track_type=track, warn_fraction=float(p["warn_fraction"]), settings=settings,
                                      on_passage=self._report, settle_s=float(p["settle_s"]),
                                      quiet_s=float(p["quiet_s"]))
        self.sub = None  # made once the topic's publishers (type, reliability) are known: check_topic
        self.kind = None
        self.imu_checked = False
        self.best_effort = False
        ours = run_topics_for(self.topic)
        status = p["status_topic"] or (ours[0] if ours else "")
        self.status_topic = self.resolve_topic_name(status) if status else ""
        if status:
            self.create_subscription(String, status, self._on_status, c.QOS_CONTROL)
        if ours:
            self.create_subscription(String, ours[1], self._on_bridge, c.QOS_LATCHED)
            self.create_subscription(String, ours[2], self._on_train, c.QOS_LATCHED)
        # opt into the bridge's flow control (adm_sim.nodes.common.FlowClient): the runs wait for this monitor
        self.flow = c.FlowClient(self, graph=self.topic[:-len(P.TOPIC_ACCEL)]) if ours and p["flow_control"] else None
        self.started = time.monotonic()
        self.seen = False
        self.samples = 0
        self.last_stamp = (None, 0)  # stamp (s) and number of the last sample taken
        self.refusing = None  # the first sample of a stretch refused for its stamp
        self.refused_samples = 0
        self.status_text = f" with run records on {status}" if status else ""
        self.create_timer(0.2, self._tick)

    # ------------------------------------------------------------------ callbacks
    def _on_accel(self, msg):
        if not self.imu_checked:
            check_imu(msg, self.axis, f"topic: {self.topic!r}")
            self.imu_checked = True
        t, a = sample_of(msg, self.kind, self.axis, self.sign)  # the sample's own stamp
        self.samples += 1
        if self.flow is not None:
            self.flow.received()
        if self._stamp_refused(t):
            return
        self.tracker.sample(t, a, time.monotonic())

    def _stamp_refused(self, t):
        """A sample whose stamp does not come after the last one taken is refused (counted in
        :attr:`refused_samples`); one warning where a stretch of them starts, one where it ends."""
        why = stamp_order(t, self.samples, self.last_stamp[0], self.last_stamp[1])
        if why is not None:
            if self.refusing is None:
                self.refusing = self.samples
                self._warn(f"{self.topic}: {why}: refused, with every sample until the stamps pass "
                           f"{self.last_stamp[0]:.9f} s (stamps must strictly increase)")
            self.refused_samples += 1
            return True
        if self.refusing is not None:
            self._warn(f"{self.topic}: samples {self.refusing} to {self.samples - 1} refused (stamps not after "
                       f"{self.last_stamp[0]:.9f} s); taken again from sample {self.samples}")
            self.refusing = None
        self.last_stamp = (t, self.samples)
        return False

    def _on_status(self, msg):
        rec = P.decode(msg.data)
        if restarts_stamp_order(rec, self.last_stamp[0]):  # sim time started again (a new bridge)
            self.last_stamp = (None, self.samples)
        self.tracker.status(rec, time.monotonic())

    def _on_bridge(self, msg):
        self.tracker.bridge_description(P.decode(msg.data))

    def _on_train(self, msg):
        self.tracker.train_description(P.decode(msg.data))

    def _tick(self):
        self.check_topic()
        # while a publisher of run records is on the graph, samples wait for their records
        self.tracker.records_expected = bool(self.status_topic) and self.count_publishers(self.status_topic) > 0
        self.tracker.poll(time.monotonic())

    # ------------------------------------------------------------------ graph
    def check_topic(self):
        """Raise :class:`InputError` when the topic has another type, or when no publisher offered
        it within ``topic_timeout_s``; subscribe once its publishers are found, with their type and
        reliability (best effort when one of them offers only that)."""
        infos = self.get_publishers_info_by_topic(self.topic)  # publishers only
        types = sorted({i.topic_type for i in infos})
        if types:
            kinds = [t for t in types if t in SENSOR_TYPES]
            if not kinds or len(types) > 1:
                raise InputError(f"topic: {self.topic!r} has type {', '.join(types)}, not {' or '.join(SENSOR_TYPES)}; "
                                 f"give an AccelStamped or Imu topic")
            if not self.seen:
                self.seen = True
                self.kind = kinds[0]
                self.imu_checked = self.kind != IMU_TYPE
                best = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos)
                self._subscribe(best)
                self._log(f"monitoring {self.topic} ({self.kind}, axis {'-' if self.sign < 0 else ''}{self.axis}"
                          f"{', best effort' if best else ''}){self.status_text}")
        elif not self.seen and time.monotonic() - self.started > self.timeout_s:
            raise InputError(f"topic: {self.topic!r} did not appear within {self.timeout_s:g} s on "
                             f"ROS_DOMAIN_ID {self._domain_id()}; check the name and the domain id")

    def _domain_id(self):
        try:
            return self.context.get_domain_id()
        except Exception:  # pragma: no cover - older rclpy
            return "?"

    def _subscribe(self, best_effort):
        if self.sub is not None:
            self.destroy_subscription(self.sub)
        self.best_effort = bool(best_effort)
        events = SubscriptionEventCallbacks(incompatible_qos=self._on_incompatible)
        self.sub = self.create_subscription(SENSOR_CLASSES[self.kind], self.topic, self._on_accel,
                                            QOS_SAMPLES_BEST_EFFORT if best_effort else QOS_SAMPLES,
                                            event_callbacks=events)

    def _on_incompatible(self, _status):
        """A best-effort publisher joined a reliable subscription: subscribe best effort (matches both)."""
        if not self.best_effort:
            self._subscribe(True)
            self._log(f"{self.topic}: a best-effort publisher joined; subscribed best effort")

    # ------------------------------------------------------------------ reports
    def _log(self, text):
        if not self.quiet:
            self.get_logger().info(text)

    def _warn(self, text):
        if self.on_warning is not None:
            self.on_warning(text)
        else:
            self.get_logger().warning(text)

    def _report(self, passage):
        self._log(passage.line())
        if self.json_path is not None:
            self.write_json()
        if self.on_passage is not None:
            self.on_passage(passage)

    def write_json(self):
        doc = passages_document(self.tracker, self.topic, "live")
        write_atomic(self.json_path, lambda tmp: tmp.write_text(json.dumps(doc, indent=1) + "\n"), "json_path")

    def finish(self):
        """Complete every pending passage (the end of monitoring)."""
        self.tracker.flush()


def passages_document(tracker, topic, source):
    """The JSON document of the passages: ``{"passages": [...], "topic", "source", "dropped_samples"}``."""
    return {"passages": [p.to_dict() for p in tracker.passages], "topic": topic, "source": source,
            "dropped_samples": tracker.dropped, "nonfinite_samples": tracker.nonfinite}


def main(args=None):
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = MonitorNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except InputError as exc:
        print(f"error: monitor: {' '.join(str(exc).split())}", file=sys.stderr, flush=True)
        code = 2
    except Exception as exc:
        if not c.stopped_by_signal(exc):  # else Ctrl-C shut rclpy down under the executor: the same stop
            raise
    finally:
        if node is not None and code == 0:  # bad input: nothing reported or written after the error line
            try:
                node.finish()
            except InputError as exc:  # the last JSON could not be written
                print(f"error: monitor: {exc}", file=sys.stderr, flush=True)
                code = code or 2
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        release_all()
    return code


if __name__ == "__main__":
    sys.exit(main())
