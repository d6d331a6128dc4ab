"""Shared pieces of the ROS 2 node graph: topic names, QoS, exchange message layout, parameters.

The exchange between the bridge and the train node is the one of :mod:`adm_sim.stepping`
(paper Section 2.3): one message each way per RK4 stage for the DIM, one block of axle positions
per many steps for the MLM. Every exchange message is a ``std_msgs/Float64MultiArray`` whose
``data`` starts with a small header of ``layout.data_offset`` doubles (integers carried exactly in
float64) that names the run, the step and the stage, so a receiver raises instead of silently
desynchronising::

    data[0] run_id   data[1] k (step)   data[2] stage (0..3)   data[3] n (count of indices)
    data[4:4+n]      axle indices (int) ; layout.data_offset = 4 + n
    data[data_offset:]  the array described by layout.dim (row-major)

See ``ros_ws/README-topics.md`` for every topic, its layout and its QoS.
"""

from __future__ import annotations

import json
import math

import numpy as np
from builtin_interfaces.msg import Time
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String

from adm_sim.errors import InputError

# ---------------------------------------------------------------------- names
NS = "/adm"
TOPIC_SETUP = f"{NS}/run/setup"            # train -> bridge, std_msgs/String (JSON)
TOPIC_READY = f"{NS}/run/ready"            # bridge -> train, std_msgs/String (JSON)
TOPIC_RAIL = f"{NS}/exchange/rail"         # bridge -> train, Float64MultiArray
TOPIC_FORCES = f"{NS}/exchange/forces"     # train -> bridge (DIM), Float64MultiArray
TOPIC_AXLE_BLOCK = f"{NS}/exchange/axle_block"  # train -> bridge (MLM), Float64MultiArray
TOPIC_RESULT = f"{NS}/run/result"          # bridge, Float64MultiArray (quantity x lane)
TOPIC_STATUS = f"{NS}/run/status"          # bridge/train, std_msgs/String (JSON)
TOPIC_ACCEL = f"{NS}/midspan/accel"        # bridge, geometry_msgs/AccelStamped
TOPIC_STATE = f"{NS}/midspan/state"        # bridge, Float64MultiArray (lane x [disp, acc])
TOPIC_BEAM = f"{NS}/beam/deflection"       # bridge, Float64MultiArray (2 x points)
TOPIC_AXLES = f"{NS}/beam/axles"           # bridge, Float64MultiArray (2 x axles on)
TOPIC_PROGRESS = f"{NS}/progress"          # bridge, std_msgs/String (JSON)
TOPIC_BRIDGE_DESC = f"{NS}/bridge/description"  # bridge, std_msgs/String (JSON), latched
TOPIC_TRAIN_DESC = f"{NS}/train/description"    # train, std_msgs/String (JSON), latched
TOPIC_DIAGNOSTICS = "/diagnostics"
TOPIC_CLOCK = "/clock"
TOPIC_CAL_ITERATION = f"{NS}/calibration/iteration"  # calibration, Float64MultiArray
TOPIC_CAL_RESULT = f"{NS}/calibration/result"        # calibration, std_msgs/String (JSON)

BRIDGE_NODE = "bridge"
TRAIN_NODE = "train"

#: RESULT rows (quantity x lane).
RESULT_ROWS = ("speed_kmh", "max_acc_m_s2", "max_disp_m", "delta_zeta")

#: EN 1990 A2.4.4.2.1(4)P: peak deck acceleration limits (m/s^2) by track type.
ACC_LIMITS_M_S2 = {"ballasted": 3.5, "direct_fastening": 5.0}

# ---------------------------------------------------------------------- QoS
#: Lockstep exchange: reliable, volatile; strict alternation keeps at most one message in flight.
QOS_EXCHANGE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=16,
                          reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
#: Run control and results: reliable, deep history.
QOS_CONTROL = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
#: Monitoring streams (midspan, beam, clock, progress): reliable, deep history for recorders.
QOS_MONITOR = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
#: Descriptions: latched (transient local), last value only.
QOS_LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)

HEADER_LEN = 4


class ExchangeError(RuntimeError):
    """The lockstep exchange lost its partner or its order."""


# ---------------------------------------------------------------------- time
def to_time_msg(t_s):
    """``builtin_interfaces/Time`` from seconds (sim time)."""
    ns = int(round(float(t_s) * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def time_ns(t_s):
    return int(round(float(t_s) * 1e9))


# ---------------------------------------------------------------------- exchange messages
def pack(run_id, k, stage, array, dims, index=None):
    """Exchange message: header ``[run_id, k, stage, n]``, ``n`` indices, then ``array`` row-major.

    Parameters
    ----------
    array : ndarray
        Payload; its shape must equal the sizes of ``dims``.
    dims : sequence of str
        Labels of the payload dimensions (``MultiArrayLayout.dim``).
    index : ndarray (n,) of int, optional
        Axle indices carried before the payload.
    """
    a = np.ascontiguousarray(array, dtype=np.float64)
    idx = np.zeros(0) if index is None else np.asarray(index, dtype=np.float64)
    head = np.array([run_id, k, stage, idx.size], dtype=np.float64)
    msg = Float64MultiArray()
    msg.layout.data_offset = HEADER_LEN + idx.size
    stride = a.size
    for label, size in zip(dims, a.shape):
        msg.layout.dim.append(MultiArrayDimension(label=label, size=int(size), stride=int(stride)))
        stride = stride // size if size else 0
    msg.data = np.concatenate([head, idx, a.ravel()])
    return msg


def unpack(msg):
    """``(run_id, k, stage, index (n,) int, payload ndarray)`` of an exchange message (copies)."""
    data = np.frombuffer(msg.data, dtype=np.float64) if not isinstance(msg.data, np.ndarray) else msg.data
    if data.size < HEADER_LEN:
        raise ExchangeError(f"exchange message too short ({data.size} values)")
    run_id, k, stage, n = (int(x) for x in data[:HEADER_LEN])
    off = msg.layout.data_offset
    index = data[HEADER_LEN:HEADER_LEN + n].astype(np.intp)
    shape = tuple(d.size for d in msg.layout.dim)
    payload = np.array(data[off:], dtype=np.float64).reshape(shape)
    return run_id, k, stage, index, payload


def check_step(who, got, expected):
    """Raise :class:`ExchangeError` when ``(run_id, k, stage)`` is not the one expected."""
    if tuple(got) != tuple(expected):
        raise ExchangeError(f"{who}: exchange out of step: expected run/step/stage {tuple(expected)}, "
                            f"got {tuple(got)}")


def matrix_msg(dims, array):
    """Plain 2-D ``Float64MultiArray`` (no header) with labelled dimensions."""
    a = np.ascontiguousarray(array, dtype=np.float64)
    msg = Float64MultiArray()
    stride = a.size
    for label, size in zip(dims, a.shape):
        msg.layout.dim.append(MultiArrayDimension(label=label, size=int(size), stride=int(stride)))
        stride = stride // size if size else 0
    msg.data = a.ravel()
    return msg


def matrix_from_msg(msg):
    shape = tuple(d.size for d in msg.layout.dim)
    data = np.asarray(msg.data, dtype=np.float64) if not isinstance(msg.data, np.ndarray) else msg.data
    return np.array(data[msg.layout.data_offset:], dtype=np.float64).reshape(shape)


def json_msg(obj):
    return String(data=json.dumps(obj))


# ---------------------------------------------------------------------- parameters
_TYPES = {float: ParameterType.PARAMETER_DOUBLE, int: ParameterType.PARAMETER_INTEGER,
          str: ParameterType.PARAMETER_STRING, bool: ParameterType.PARAMETER_BOOL}


class ParamSpec:
    """One declared parameter: default, unit, range and description."""

    def __init__(self, name, default, unit, description, lo=None, hi=None, read_only=False):
        self.name, self.default, self.unit = name, default, unit
        self.description, self.lo, self.hi, self.read_only = description, lo, hi, read_only

    def descriptor(self):
        typ = _TYPES[type(self.default)]
        d = ParameterDescriptor(name=self.name, type=typ, read_only=self.read_only,
                                description=f"{self.description} [{self.unit}]" if self.unit else self.description)
        if self.lo is not None and typ == ParameterType.PARAMETER_DOUBLE:
            d.floating_point_range = [FloatingPointRange(from_value=float(self.lo), to_value=float(self.hi), step=0.0)]
        elif self.lo is not None and typ == ParameterType.PARAMETER_INTEGER:
            d.integer_range = [IntegerRange(from_value=int(self.lo), to_value=int(self.hi), step=1)]
        d.additional_constraints = "" if self.lo is None else f"{self.lo:g} <= {self.name} <= {self.hi:g} {self.unit}".strip()
        return d


class ParamNodeMixin:
    """Declares :class:`ParamSpec` parameters and words range rejections like the core.

    rclpy checks ``FloatingPointRange``/``IntegerRange`` before any on-set callback; its message
    lacks the unit, so this mixin rewrites that reason in the wording of
    :func:`adm_sim.errors.check_range` (field, value, unit, allowed range).
    """

    _specs: dict

    def declare_specs(self, specs):
        from rclpy.exceptions import InvalidParameterTypeException

        self._specs = {s.name: s for s in specs}
        for s in specs:
            try:
                self.declare_parameter(s.name, s.default, s.descriptor())
            except InvalidParameterTypeException as exc:  # e.g. -p speeds_kmh:=280 (a YAML integer)
                unit = f" ({s.unit})" if s.unit else ""
                raise InputError(f"{s.name}: the given value has the wrong type ({exc}); expected a "
                                 f"{type(s.default).__name__}{unit}, e.g. {s.default!r}: quote text values "
                                 f"in YAML and -p overrides") from None

    def _range_reason(self, parameter):
        s = self._specs.get(parameter.name)
        if s is None or s.lo is None:
            return None
        unit = f" {s.unit}" if s.unit else ""
        return (f"{s.name}: {parameter.value:g}{unit} is out of range; "
                f"allowed [{s.lo:g}, {s.hi:g}]{unit}; keeping {self.get_parameter(s.name).value:g}{unit}")

    def _apply_floating_point_range(self, parameter, floating_point_range):  # rclpy Node hook
        res = super()._apply_floating_point_range(parameter, floating_point_range)
        if not res.successful:
            res.reason = self._range_reason(parameter) or res.reason
        return res

    def _apply_integer_range(self, parameter, integer_range):  # rclpy Node hook
        res = super()._apply_integer_range(parameter, integer_range)
        if not res.successful:
            res.reason = self._range_reason(parameter) or res.reason
        return res

    def param_values(self):
        """Current values of the declared parameters, ``{name: value}``."""
        return {n: self.get_parameter(n).value for n in self._specs}


def parse_float_list(field, text, unit):
    """Floats from a comma list (``"0.001,0.002"``); empty text gives an empty array."""
    parts = [p.strip() for p in str(text).split(",") if p.strip()]
    try:
        return np.array([float(p) for p in parts], dtype=float)
    except ValueError:
        raise InputError(f"{field}: {text!r} is not a comma list of numbers ({unit})") from None


def format_float_list(values):
    """Comma list of floats that parses back exactly (``repr``)."""
    return ",".join(repr(float(x)) for x in np.atleast_1d(values))


def acc_level(max_acc, limit, warn_fraction):
    """Diagnostic level for a peak deck acceleration: 0 OK, 1 WARN, 2 ERROR (bytes)."""
    if not math.isfinite(max_acc) or max_acc > limit:
        return 2
    if max_acc > warn_fraction * limit:
        return 1
    return 0


# ---------------------------------------------------------------------- lockstep partner watch
class PartnerWatch:
    """Detects a vanished partner while this node waits for its message.

    Armed by :meth:`waiting` when a message is expected; :meth:`check` (called between executor
    turns, never inside a callback) raises :class:`ExchangeError` when the partner's publisher
    left the graph (a clean exit) or when nothing came for ``timeout_s`` (a killed process: Fast
    DDS only notices it after its lease expires).
    """

    GRAPH_CHECK_AFTER_S = 0.5

    def __init__(self, node, partner, topic, timeout_s):
        import time as _time

        self._now = _time.monotonic
        self.node, self.partner, self.topic, self.timeout_s = node, partner, topic, float(timeout_s)
        self.since = None
        self.what = ""

    def waiting(self, what, topic=None):
        self.since = self._now()
        self.what = what
        if topic is not None:
            self.topic = topic

    def clear(self):
        self.since = None

    def check(self):
        if self.since is None:
            return
        dt = self._now() - self.since
        if dt < self.GRAPH_CHECK_AFTER_S:
            return
        if self.node.count_publishers(self.topic) == 0:
            raise ExchangeError(f"partner node '{self.partner}' vanished {self.what} "
                                f"(no publisher left on {self.topic})")
        if dt > self.timeout_s:
            raise ExchangeError(f"partner node '{self.partner}' vanished {self.what} "
                                f"(no message on {self.topic} for {self.timeout_s:g} s)")


class FastLane:
    """Waits on the lockstep exchange subscriptions alone, outside the executor.

    One executor turn rebuilds a wait set of every entity of the node (parameter services
    included), which costs several times the message itself; while a run is active the run loop
    of :func:`run_node` waits here on the exchange subscriptions only and calls their callbacks
    directly, and gives the executor a turn between bursts (services, set-up messages). The
    callbacks, their order and the messages are the same as with the executor alone.
    """

    def __init__(self, node, subscriptions):
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

        self.subs = list(subscriptions)
        self.ws = _rclpy.WaitSet(len(self.subs), 0, 0, 0, 0, 0, node.context.handle)

    def turn(self, timeout_s):
        """Wait up to ``timeout_s`` for an exchange message and handle it; True if one came."""
        ws = self.ws
        ws.clear_entities()
        for s in self.subs:
            ws.add_subscription(s.handle)
        ws.wait(int(timeout_s * 1e9))
        ready = ws.get_ready_entities("subscription")
        handled = False
        for s in self.subs:
            if s.handle.pointer in ready:
                with s.handle:
                    info = s.handle.take_message(s.msg_type, s.raw)
                if info is not None:
                    s.callback(info[0])
                    handled = True
        return handled


def run_node(make_node, args=None, name="node"):
    """Standard ``main``: init, spin with the partner watch between turns, clean shutdown.

    While the node has a run active (``node.run``) the exchange subscriptions listed in
    ``node.fast_subscriptions`` are served by a :class:`FastLane`, with an executor turn at
    least every 50 ms. Returns the process exit code: 0, 2 on a lockstep or input error, 130 on
    Ctrl-C.
    """
    import sys
    import time

    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = make_node()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        fast = FastLane(node, getattr(node, "fast_subscriptions", ()))
        while rclpy.ok() and not getattr(node, "finished", False):
            if getattr(node, "run", None) is not None and fast.subs:
                deadline = time.monotonic() + 0.05
                while node.run is not None and fast.turn(0.02) and time.monotonic() < deadline:
                    pass
                node.watch()
                executor.spin_once(timeout_sec=0.0)
            else:
                executor.spin_once(timeout_sec=0.2)
            node.watch()
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 130
    except (ExchangeError, InputError) as exc:
        print(f"error: {name}: {exc}", file=sys.stderr, flush=True)
        code = 2
        if node is not None:
            try:
                node.report_failure(str(exc))
                # let the failure reach the other nodes before this process leaves the graph
                from rclpy.duration import Duration

                node.pub_status.wait_for_all_acked(Duration(seconds=1.0))
            except Exception:
                pass
    except Exception:
        if rclpy.ok():
            raise
        code = 130  # shut down (SIGINT/SIGTERM) while a callback was publishing
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code
