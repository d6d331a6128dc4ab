"""Shared pieces of the ROS 2 node graph: topic names, QoS, exchange message layout, parameters.

The exchange between the bridge and the train node is the one of :mod:`adm_sim.integrate.rk4_sides`
(paper Section 2.3): one message each way per RK4 stage for the DIM, one block of axle positions
per many steps for the MLM. Every exchange message is a ``std_msgs/Float64MultiArray`` whose
``data`` starts with a small header of ``layout.data_offset`` doubles (integers carried exactly in
float64) that names the run, the step and the stage, so a receiver raises instead of silently
desynchronising::

    data[0] run_id   data[1] k (step)   data[2] stage (0..3)   data[3] n (count of indices)
    data[4:4+n]      axle indices (int) ; layout.data_offset = 4 + n
    data[data_offset:]  the array described by layout.dim (row-major)

Every topic, its layout and its QoS: docs/ros.md, section "Topics"; their names and records:
:mod:`adm_sim.protocol` (ROS-free).
"""

from __future__ import annotations

import array
import functools
import math
import struct
import sys
import time
import warnings

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String

from adm_sim import protocol as P
from adm_sim.cliutil import one_line_warnings
from adm_sim.errors import AdmSimError, InputError, PlausibilityWarning, RunError
from adm_sim.files import release_all
from adm_sim.protocol import EXCHANGE_HEADER_LEN as HEADER_LEN
from adm_sim.protocol import encode

# ---------------------------------------------------------------------- names
# Topic and node names, record layouts: one home, the ROS-free :mod:`adm_sim.protocol`. These

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
#: The per-passage summary: transient local with a history of :data:`adm_sim.protocol.SUMMARY_HISTORY`
#: passages, so a client that lags or joins late reads the passages it missed.
QOS_HISTORY = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=P.SUMMARY_HISTORY,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Descriptions: latched (transient local), last value only.
QOS_LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class FlowClient:
    """Opt a client node into the bridge's flow control: one call, ``FlowClient(node)``, before the
    run starts; then ``flow.received()`` in the callback of every message of ``topics``.

    The bridge takes every publisher of ``/adm/run/ack`` at a run's set-up as a node to wait for
    (docs/ros.md, "Flow control"): it never publishes more than :data:`adm_sim.protocol.FLOW_WINDOW`
    messages of ``topics`` beyond this client's acknowledgement, and ends the run only once the
    client has them all. Subscribe to ``topics`` RELIABLE with a history of at least
    ``FLOW_WINDOW`` (:data:`QOS_MONITOR`). The counting is :class:`adm_sim.protocol.AckCounter`;
    ``runs`` gives ``run_id -> (received, published)`` of the runs ended.

    Parameters
    ----------
    node : rclpy.node.Node
        The client's node.
    topics : sequence of str
        The topics the client reads, of :data:`adm_sim.protocol.SAMPLE_TOPICS` (default the midspan
        acceleration).
    graph : str or None
        The namespace of the graph (``/b1``: its ``/b1/adm/run/ack``); ``None``: the node's own
        (relative names).
    """

    def __init__(self, node, topics=(P.TOPIC_ACCEL,), graph=None):
        self.counter = P.AckCounter(node.get_fully_qualified_name(), topics)

        def name(topic):
            return P.relative(topic) if graph is None else graph.rstrip("/") + topic

        self.pub = node.create_publisher(String, name(P.TOPIC_ACK), QOS_CONTROL)
        node.create_subscription(String, name(P.TOPIC_PROGRESS), self._on_progress, QOS_MONITOR)
        node.create_subscription(String, name(P.TOPIC_STATUS), self._on_status, QOS_CONTROL)

    @property
    def runs(self):
        return self.counter.runs

    def received(self, n=1):
        """``n`` messages of the counted topics arrived."""
        self._send(self.counter.count(n))

    def _on_progress(self, msg):
        self._send(self.counter.final(P.decode(msg.data)))

    def _on_status(self, msg):
        rec = P.decode(msg.data)
        if P.is_bridge_start(rec):
            self.counter.started(rec.get("run_id"))

    def _send(self, rec):
        if rec is not None:
            self.pub.publish(String(data=P.encode(rec)))


class ExchangeError(RunError):
    """The lockstep exchange lost its partner or its order (a :class:`RunError`: exit 1)."""


# ---------------------------------------------------------------------- time
def to_time_msg(t_s):
    """``builtin_interfaces/Time`` from seconds (sim time)."""
    ns = int(round(float(t_s) * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


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
    a = np.asarray(array, dtype=np.float64)
    buf, payload = _exchange_buffer(run_id, k, stage, a.shape, index)
    payload[...] = a
    msg = Float64MultiArray()
    msg.layout.data_offset = buf.size - a.size
    msg.layout.dim = list(_layout_dims(tuple(dims), a.shape))
    msg.data = float64_data(buf)
    return msg


def _exchange_buffer(run_id, k, stage, shape, index):
    """``(buffer, payload view)`` of an exchange message: the header ``[run_id, k, stage, n]`` and the
    ``n`` indices written, the payload (of ``shape``, row-major) left for the caller to fill."""
    n = 0 if index is None else len(index)
    off = HEADER_LEN + n
    buf = np.empty(off + math.prod(shape))
    buf[:HEADER_LEN] = (run_id, k, stage, n)
    if n:
        buf[HEADER_LEN:off] = index
    return buf, buf[off:].reshape(shape)


@functools.lru_cache(maxsize=256)
def _layout_dims(labels, shape):
    """The ``MultiArrayDimension``s of a payload (kept per labels and shape: a DIM run sends a few
    shapes tens of thousands of times; the messages only read them)."""
    dims, stride = [], int(np.prod(shape)) if shape else 0
    for label, size in zip(labels, shape):
        dims.append(MultiArrayDimension(label=label, size=int(size), stride=int(stride)))
        stride = stride // size if size else 0
    return tuple(dims)


@functools.lru_cache(maxsize=256)
def _cdr_prefix(dims, shape, n):
    """The serialized bytes of an exchange message before its doubles (:func:`pack`'s layout for
    payload ``shape`` after ``n`` indices, by ``rclpy.serialization.serialize_message``), or None
    where the serialization is not little-endian CDR (the message is then sent itself)."""
    total = HEADER_LEN + n + math.prod(shape)
    msg = Float64MultiArray()
    msg.layout.dim = list(_layout_dims(dims, shape))
    msg.layout.data_offset = HEADER_LEN + n
    msg.data = array.array("d", bytes(8 * total))
    raw = serialize_message(msg)
    if sys.byteorder != "little" or raw[1] != 1:
        return None
    return raw[:len(raw) - 8 * total]


def float64_data(values):
    """``values`` (ndarray of float64) as the ``array.array('d')`` a ``float64[]`` field holds, copied
    as bytes: assigning an ndarray makes the message build that array value by value (about
    0.5 us a value: 1.6 ms for 3000 doubles, against 17 us so). The same bytes either way."""
    out = array.array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def unpack(msg):
    """``(run_id, k, stage, index (n,) int, payload ndarray)`` of an exchange message (copies).

    ``msg`` is the message or, from a raw subscription (:meth:`ExchangeLane.subscribe`), its
    serialized bytes (:func:`parse_cdr`)."""
    if isinstance(msg, bytes):
        shape, off, data = parse_cdr(msg)
    else:
        data = np.frombuffer(msg.data, dtype=np.float64) if not isinstance(msg.data, np.ndarray) else msg.data
        layout = msg.layout
        shape, off = tuple([d.size for d in layout.dim]), layout.data_offset
    if data.size < HEADER_LEN:
        raise ExchangeError(f"exchange message too short ({data.size} values)")
    run_id, k, stage, n = map(int, data[:HEADER_LEN].tolist())
    index = data[HEADER_LEN:HEADER_LEN + n].astype(np.intp)
    payload = data[off:].reshape(shape).copy()
    return run_id, k, stage, index, payload


_U32 = struct.Struct("<I")


def parse_cdr(raw):
    """``(shape, data_offset, data ndarray)`` of a serialized ``std_msgs/Float64MultiArray``
    (little-endian CDR, as rmw_fastrtps writes it on this machine: a 4-byte encapsulation header,
    then ``layout.dim`` (count; per dimension its label string, size and stride),
    ``layout.data_offset``, ``data`` (count, aligned to 8, the doubles)). ``data`` is a view of
    ``raw``; the labels and strides are not read (:func:`pack` writes them from the shape)."""
    if len(raw) < 12 or raw[1] != 1:
        raise ExchangeError(f"exchange message is not little-endian CDR ({len(raw)} bytes)")
    b = memoryview(raw)[4:]
    u = _U32.unpack_from
    try:
        (nd,) = u(b, 0)
        pos, sizes = 4, []
        for _ in range(nd):
            (ln,) = u(b, pos)
            pos = (pos + 4 + ln + 3) & ~3
            sizes.append(u(b, pos)[0])
            pos += 8
        off, count = u(b, pos)[0], u(b, pos + 4)[0]
        pos += 8
        if count:
            pos = (pos + 7) & ~7
        data = np.frombuffer(b, dtype="<f8", count=count, offset=pos)
    except (struct.error, ValueError) as exc:
        raise ExchangeError(f"exchange message is not a Float64MultiArray ({len(raw)} bytes: {exc})") from None
    return tuple(sizes), off, data


class ExchangeWriter:
    """The exchange messages of one publisher, as :func:`pack` makes them, serialized with less work.

    The serialized layout (dimensions, data offset, value count) is made once per payload shape
    and index count by ``rclpy.serialization.serialize_message`` and kept; a message is then
    that prefix and the float64 bytes of header, indices and payload, published as
    serialized bytes (``Publisher.publish`` of ``bytes``). Receivers get the message of
    :func:`pack`: the same layout and the same data bytes. Rows of one shape (the rail
    displacement and velocity) are written straight into the buffer, no stacking first.
    """

    def __init__(self, publisher):
        self.publisher = publisher

    def publish(self, run_id, k, stage, rows, dims, index=None):
        """Publish ``[run_id, k, stage, n]``, the ``n`` indices, then ``rows``: one array, or a
        tuple of arrays of one shape sent as one array of a leading dimension of their count."""
        tup = isinstance(rows, tuple)
        shape = (len(rows),) + rows[0].shape if tup else rows.shape
        buf, view = _exchange_buffer(run_id, k, stage, shape, index)
        if tup:
            for i, row in enumerate(rows):
                view[i] = row
        else:
            view[...] = rows
        prefix = _cdr_prefix(tuple(dims), shape, buf.size - view.size - HEADER_LEN)
        if prefix is None:
            self.publisher.publish(pack(run_id, k, stage, view, dims, index))
        else:
            self.publisher.publish(prefix + buf.tobytes())


def check_step(who, got, expected):
    """Raise :class:`ExchangeError` when ``(run_id, k, stage)`` is not the one expected."""
    if tuple(got) != tuple(expected):
        raise ExchangeError(f"{who}: exchange out of step: expected run/step/stage {tuple(expected)}, "
                            f"got {tuple(got)}")


def matrix_msg(dims, array, step=None):
    """Plain 2-D ``Float64MultiArray`` with labelled dimensions; with ``step``, the step index is
    carried before the data (``data[0]``, ``layout.data_offset`` = 1; :func:`matrix_step`)."""
    a = np.asarray(array, dtype=np.float64)
    msg = Float64MultiArray()
    msg.layout.dim = list(_layout_dims(tuple(dims), a.shape))
    if step is None:
        msg.data = float64_data(a)
    else:
        msg.layout.data_offset = 1
        buf = np.empty(a.size + 1)
        buf[0] = step
        buf[1:] = a.reshape(-1)
        msg.data = float64_data(buf)
    return msg


def matrix_step(msg):
    """The step index a monitoring array carries (:func:`matrix_msg`), ``None`` if it has none."""
    return int(msg.data[0]) if msg.layout.data_offset == 1 and len(msg.data) else None


def matrix_from_msg(msg):
    shape = tuple(d.size for d in msg.layout.dim)
    data = np.asarray(msg.data, dtype=np.float64) if not isinstance(msg.data, np.ndarray) else msg.data
    return np.array(data[msg.layout.data_offset:], dtype=np.float64).reshape(shape)


def json_msg(record):
    """``std_msgs/String`` carrying a protocol record (:func:`adm_sim.protocol.encode`)."""
    return String(data=encode(record))


# ---------------------------------------------------------------------- parameters
# The specs, the params-file checks and the list helpers are ROS-free (adm_sim.nodes.params);
# they are imported here for the nodes.
from adm_sim.nodes.params import unapplied_sections  # noqa: E402
from adm_sim.nodes.params import (RCLPY_PARAMETERS, ParamSpec, check_params_file,  # noqa: E402,F401
                                  format_float_list, load_params_yaml, param, parse_float_list)

class ParamNodeMixin:
    """Declares :class:`ParamSpec` parameters and refuses out-of-range values in the core's words.

    :meth:`declare_specs` declares the parameters, checks the start-up values (a node started
    with ``-p span_m:=-5.0`` raises :class:`InputError`, which :func:`run_node` prints as one
    line, exit 2) and registers an on-set callback that refuses later sets with the same reason
    (``span_m: -5 m is out of range; allowed [1, 150] m``); the node keeps its old values.
    """

    _specs: dict

    def declare_specs(self, specs, on_set=None):
        """Declare ``specs``, check their start-up values and refuse out-of-range sets.

        ``on_set`` (a node's own on-set callback) runs after the range checks have passed; on-set
        callbacks only validate, state changes belong in a post-set callback (ros2/demos).
        """

        self._specs = {s.name: s for s in specs}
        for s in specs:
            try:
                self.declare_parameter(s.name, s.default, s.descriptor())
            except InvalidParameterTypeException as exc:  # e.g. -p speeds_kmh:=280 (a YAML integer)
                unit = f" ({s.unit})" if s.unit else ""
                raise InputError(f"{s.name}: the given value has the wrong type ({exc}); expected a "
                                 f"{type(s.default).__name__}{unit}, e.g. {s.default!r}: quote text values "
                                 f"in YAML and -p overrides") from None
        for name, value in self.param_values().items():
            self._specs[name].check(value)
        self._refuse_undeclared()
        self._on_set_checked = on_set
        self.add_on_set_parameters_callback(self._check_ranges)

    def _refuse_undeclared(self):
        """A start-up value (``-p name:=value``, a params file's section of this node) for a
        parameter the node does not declare is refused: rclpy would silently ignore it, and a
        typo (``-p span:=20.0`` for ``span_m``) would run with the default. Names of a params
        file's ``/**`` section (meant for every node, each taking its own) are exempt."""
        overrides = getattr(self, "_parameter_overrides", {}) or {}
        unknown = sorted(n for n in overrides
                         if not self.has_parameter(n) and n not in SHARED_PARAMETER_NAMES)
        if unknown:
            allowed = sorted(set(self._parameters) | set(RCLPY_PARAMETERS))
            raise InputError(f"{unknown[0]}: unknown parameter of node '{self.get_name()}'; allowed "
                             f"{', '.join(allowed)}")

    def _check_ranges(self, params):
        """On-set callback: every value in its range (else the reason, old values kept), then the
        node's own callback."""
        for p in params:
            s = self._specs.get(p.name)
            if s is None:
                continue
            try:
                s.check(p.value)
            except InputError as exc:
                return SetParametersResult(successful=False, reason=f"{exc}; keeping {self.get_parameter(s.name).value!r}")
        return SetParametersResult(successful=True) if self._on_set_checked is None else self._on_set_checked(params)

    def param_values(self):
        """Current values of the declared parameters, ``{name: value}``."""
        return {n: self.get_parameter(n).value for n in self._specs}


#: Parameter names of the ``/**`` sections of the params files this process was started with
#: (set by :func:`run_node`): every node takes the ones it declares and ignores the others.
SHARED_PARAMETER_NAMES: set = set()


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

    #: The partner is hosted by this process (:mod:`adm_sim.nodes.composed`): it cannot vanish
    #: without this node, and its silence is this process's own work (an MLM block of a few
    #: seconds under load), so :meth:`check` does nothing.
    same_process = False

    def __init__(self, node, partner, topic, timeout_s):

        self._now = time.monotonic
        self.node, self.partner, self.topic, self.timeout_s = node, partner, topic, float(timeout_s)
        self.since = None
        self.what = ""

    def waiting(self, what, topic=None, since=None):
        """Expect a message (``since``: the partner's silence began earlier, a ``time.monotonic()``).

        ``what`` (where the node waits, for the error) is a string or ``(format, *args)``, formatted
        only when the partner is reported vanished (the nodes call this once per exchange)."""
        self.since = self._now() if since is None else since
        self.what = what
        if topic is not None:
            self.topic = topic

    def clear(self):
        self.since = None

    def check(self):
        if self.since is None or self.same_process:
            return
        dt = self._now() - self.since
        if dt < self.GRAPH_CHECK_AFTER_S:
            return
        what = self.what if isinstance(self.what, str) else self.what[0].format(*self.what[1:])
        if self.node.count_publishers(self.topic) == 0:
            raise ExchangeError(f"partner node '{self.partner}' vanished {what} "
                                f"(no publisher left on {self.topic})")
        if dt > self.timeout_s:
            raise ExchangeError(f"partner node '{self.partner}' vanished {what} "
                                f"(no message on {self.topic} for {self.timeout_s:g} s)")


class ExchangeLane:
    """The lockstep exchange subscriptions on a node of their own, served by their own executor.

    One turn of an executor waits on every entity of its nodes; for the bridge or train node
    that is a dozen parameter services besides the exchange, which costs several times the
    message itself. The exchange subscriptions therefore live on a second node in the same
    context (``<name>_exchange``: no parameter services, no rosout, no type description service)
    with an executor of its own: rclpy's ``rclpy.experimental.EventsExecutor`` (public API,
    implemented in C++). Measured CPU time per DIM-sized round trip in a ping-pong of two
    processes: about 270 us with it, 450-640 us with a ``SingleThreadedExecutor``, about 280 us
    with the private wait set this replaces. While a run is active :func:`run_node` spins it in
    bursts (:meth:`spin`) and gives the main node's executor a turn at least every 50 ms.
    Callbacks and their order are those of a single executor.
    """

    def __init__(self, node):

        self.node = Node(f"{node.get_name()}_exchange", namespace=node.get_namespace(), context=node.context,
                         use_global_arguments=False,
                         enable_rosout=False, start_parameter_services=False,
                         parameter_overrides=[Parameter("start_type_description_service", value=False)])
        self.executor = EventsExecutor(context=node.context)
        self.executor.add_node(self.node)
        self._own_executor = True
        self.error = None

    def share(self, executor):
        """Serve the lane's node by ``executor`` (the one executor of a process hosting several
        nodes, :func:`run_node` with a tuple of nodes) instead of its own; :meth:`raise_error`
        then passes on a callback's exception."""
        self.executor.remove_node(self.node)
        self.executor.shutdown()
        executor.add_node(self.node)
        self.executor, self._own_executor = executor, False

    def subscribe(self, msg_type, topic, callback, qos, raw=False):
        """An exchange subscription (on the lane's node); ``raw``: ``callback`` gets the serialized
        bytes (rclpy builds no message object; :func:`unpack` reads them).

        An exception of ``callback`` is kept and raised by :meth:`spin` (the executor would log
        it with its stack first); one raised because the context is shutting down (Ctrl-C,
        SIGTERM while publishing) is dropped.
        """
        def guarded(msg):
            if self.error is not None:
                return
            try:
                callback(msg)
            except Exception as exc:
                if self.node.context.ok():
                    self.error = exc

        return self.node.create_subscription(msg_type, topic, guarded, qos, raw=raw)

    def spin(self, until_s, active, turn_s=0.02):
        """Serve exchange messages until ``time.monotonic()`` passes ``until_s`` or ``active()``
        turns false; raises the exception of a callback."""

        while active() and time.monotonic() < until_s:
            self.turn(turn_s)

    def turn(self, timeout_s=0.0):
        """One turn of the lane's executor (``timeout_s`` 0: handle what is there, do not wait)."""
        self.executor.spin_once(timeout_sec=timeout_s)
        self.raise_error()

    def raise_error(self):
        """Raise the exception a callback of the lane kept, if any."""
        if self.error is not None:
            exc, self.error = self.error, None
            raise exc

    def destroy(self):
        if self._own_executor:
            self.executor.shutdown()
        self.node.destroy_node()


class NodeBase(ParamNodeMixin, Node):
    """Base of the adm-sim nodes: the hooks of :func:`run_node` with their defaults.

    ``run`` is the active lockstep run (or None), ``exchange`` the node's :class:`ExchangeLane`
    (or None), ``finished`` ends the main loop.
    """

    run = None
    exchange = None
    finished = False

    def make_executor(self):
        """The executor :func:`run_node` spins the node with: a ``SingleThreadedExecutor``."""
        return SingleThreadedExecutor(context=self.context)

    def begin(self):
        """Called once before the main loop (a driver starts its job here)."""

    def watch(self):
        """Called between executor turns, never inside a callback; raises to end the node."""

    def end(self, executor):
        """Called when the loop ends normally; returns the exit code."""
        return 0

    def report_failure(self, message):
        """Tell the other nodes that this one stops with ``message`` (best effort)."""

    def close(self):
        """Finish the node's files (always called before :meth:`destroy_node`)."""

    def destroy_node(self):
        if self.exchange is not None:
            self.exchange.destroy()
            self.exchange = None
        return super().destroy_node()


class LockstepNode(NodeBase):
    """Base of the bridge and train nodes: the parameter life cycle of a node that runs lockstep runs.

    :meth:`declare_run_parameters` declares the specs; then every set passes three stages, in
    the order of ros2/demos ``set_parameters_callback.py``:

    1. the range of each value (:class:`ParamSpec`, in :class:`ParamNodeMixin`);
    2. on-set, :meth:`_check_set`: refused while a run is active (``<node>: parameters are locked
       while run 3 is in progress ...``, :meth:`lock_reason`) or when :meth:`validate` raises
       :class:`InputError` for the new values taken together; nothing changes here;
    3. post-set, :meth:`_apply_set`: :meth:`configure` with the new values, the partner timeout
       and the latched description (:meth:`publish_description`) follow them.
    """

    partner = None

    def make_executor(self):
        """rclpy's ``EventsExecutor`` for the node's own entities (parameter services, run control),
        as for the exchange lane: while a run is active :func:`run_node` gives it a turn every 50 ms,
        and a ``SingleThreadedExecutor`` rebuilt its wait set of a dozen services, subscriptions and
        publishers' events for each turn even with nothing to do. Callbacks and their order are
        those of a single-threaded executor."""
        return EventsExecutor(context=self.context)

    def declare_run_parameters(self, specs):
        """Declare ``specs`` and install the on-set and post-set stages; returns
        :meth:`validate` of the start-up values (they are checked before the node runs)."""
        self.declare_specs(specs, on_set=self._check_set)
        checked = self.validate(self.param_values())
        self._warn_implausible(self.param_values())
        self.add_post_set_parameters_callback(self._apply_set)
        return checked

    def plausibility(self, values):
        """Issue the :class:`~adm_sim.errors.PlausibilityWarning` of the valid values ``values``
        (:mod:`adm_sim.model.plausibility`: a value the model computes but no real bridge has)."""

    def _warn_implausible(self, values):
        """:meth:`plausibility` of ``values`` at start-up and after every set, each warning once
        per node (the same value set again is not warned again); :func:`run_node` prints each as
        one line ``warning: <node>: ...``."""
        said = self.__dict__.setdefault("_plausibility_said", set())
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PlausibilityWarning)
            self.plausibility(values)
        for w in caught:
            text = str(w.message)
            if not issubclass(w.category, PlausibilityWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            elif text not in said:
                said.add(text)
                warnings.warn(text, PlausibilityWarning, stacklevel=2)

    def validate(self, values):
        """Raise :class:`InputError` when ``values`` (every parameter) do not make a valid node."""

    def configure(self, values):
        """Change the node's state to ``values`` (post-set; they passed :meth:`validate`)."""

    def publish_description(self):
        """Publish the node's latched description."""

    def lock_reason(self):
        """Why parameters are locked now: the run in progress (``self.run``, a run-state dataclass
        with an ``id``, as :class:`~adm_sim.nodes.train_node.TrainRunState`)."""
        return f"run {self.run.id} is in progress"

    def _check_set(self, params):
        if self.run is not None:
            return SetParametersResult(successful=False, reason=(
                f"{self.get_name()}: parameters are locked while {self.lock_reason()}"))
        values = self.param_values()
        values.update({p.name: p.value for p in params})
        try:
            self.validate(values)
        except InputError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_set(self, params):
        values = self.param_values()
        self.configure(values)
        self._warn_implausible(values)
        if self.partner is not None and any(p.name == "partner_timeout_s" for p in params):
            self.partner.timeout_s = float(values["partner_timeout_s"])
        self.publish_description()


def run_node(make_node, args=None, name="node"):
    """The ``main`` of every node: init, spin until finished, one-line errors and warnings, clean shutdown.

    ``make_node`` may also return a tuple of nodes: they are hosted by this one process (as ROS
    composition hosts nodes), every entity of theirs, exchange lanes included, served by one
    executor (:func:`_spin_composed`).

    Every Python warning raised in the node (start-up, parameter callbacks, the driver's job) is
    printed as one line ``warning: <name>: ...`` on stderr, as the CLIs print theirs
    (:class:`adm_sim.cliutil.one_line_warnings`; Python's filters still print a repeated warning once).
    """

    with one_line_warnings(prefix=f"{name}: ", categories=(Warning,), repeat=False):
        code = _run_node(make_node, args, name)
    from adm_sim.recording.viewer_process import exit_if_abandoned  # noqa: PLC0415  (no rerun import)

    exit_if_abandoned(code)  # a rerun viewer given up: rerun's flush at exit would hang on it
    return code


def _run_node(make_node, args, name):
    """:func:`run_node` without the warning display.

    While the node has a run active (``node.run``) its :class:`ExchangeLane` is served in bursts
    of up to 50 ms, each followed by the partner watch and one turn of the node's executor;
    otherwise the executor spins with a 0.2 s timeout. Returns the process exit code: 0, 2 on
    bad input (start-up parameters, params file), 1 on a failed run or a lockstep failure (a
    :class:`RunError`), 130 on Ctrl-C or SIGTERM.
    """



    argv = sys.argv if args is None else list(args)
    param_docs = []  # (file, its YAML): every section must reach its node (check_sections_apply)
    try:  # a params file that is not YAML: our line, before rcl prints its own
        for i, a in enumerate(argv[:-1]):
            if a == "--params-file":
                doc = load_params_yaml(argv[i + 1])
                param_docs.append((argv[i + 1], doc))
                shared = doc.get("/**") if isinstance(doc, dict) else None
                if isinstance(shared, dict) and isinstance(shared.get("ros__parameters"), dict):
                    SHARED_PARAMETER_NAMES.update(shared["ros__parameters"])
    except InputError as exc:
        print(f"error: {name}: {exc}", file=sys.stderr, flush=True)
        return 2
    try:
        rclpy.init(args=args)
    except Exception as exc:  # malformed --ros-args: rcl's message, one line
        reason = " ".join(str(exc).split())
        print(f"error: {name}: cannot start: {reason}", file=sys.stderr, flush=True)
        return 2
    nodes = []
    code = 0
    try:
        made = make_node()
        nodes = list(made) if isinstance(made, tuple) else [made]
        check_sections_apply(nodes, param_docs)
        node = nodes[0]
        executor = node.make_executor()
        for n in nodes:
            executor.add_node(n)
        if len(nodes) > 1:
            code = _spin_composed(nodes, executor)
        else:
            node.begin()
            lane = node.exchange
            while rclpy.ok() and not node.finished:
                if lane is not None and node.run is not None:
                    lane.spin(time.monotonic() + 0.05, lambda: node.run is not None)
                    node.watch()
                    executor.spin_once(timeout_sec=0.0)
                else:
                    executor.spin_once(timeout_sec=0.2)
                    if lane is not None:  # a stray exchange message with no run active is an error now
                        lane.turn()
                node.watch()
            code = node.end(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 130
    except AdmSimError as exc:  # ExchangeError is a RunError
        print(f"error: {name}: {exc}", file=sys.stderr, flush=True)
        code = 2 if isinstance(exc, InputError) else 1  # the CLIs' mapping (adm_sim.cliutil.run_cli)
        for node in nodes:
            try:
                node.report_failure(str(exc))
                pub = getattr(node, "pub_status", None)
                if pub is not None:  # let the failure reach the other nodes before this one leaves

                    pub.wait_for_all_acked(Duration(seconds=1.0))
            except Exception:
                pass
    except Exception:
        if rclpy.ok():
            raise
        code = 130  # shut down (SIGINT/SIGTERM) while a callback was publishing
    finally:
        for node in nodes:
            node.close()
            node.destroy_node()
        rclpy.try_shutdown()
        release_all()  # every output this node claimed, however it ended (no stray lock file)
    return code


def check_sections_apply(nodes, param_docs):
    """Refuse (:class:`InputError`, exit 2) a params-file section that names one of ``nodes`` but
    that rcl does not apply to it: rcl matches sections by fully qualified name, so under
    ``-r __ns:=/b3`` a section keyed ``bridge`` (read ``/bridge``) would leave the node
    ``/b3/bridge`` on its defaults without a word."""
    for node in nodes:
        fqn = node.get_fully_qualified_name()
        for path, doc in param_docs:
            missed = unapplied_sections(doc, fqn)
            if missed:
                base = fqn.rsplit("/", 1)[-1]
                raise InputError(f"--params-file {path!r}: section {missed[0]!r} is not applied to the node {fqn!r} "
                                 f"(rcl reads it as {('/' + missed[0]).replace('//', '/')!r}); key it {fqn!r} or "
                                 f"'/**/{base}'")


#: How often the composed loop runs the nodes' :meth:`NodeBase.watch` (s).
WATCH_EVERY_S = 0.05


def _spin_composed(nodes, executor):
    """The main loop of several nodes in one process: one executor serves every entity of theirs
    (their exchange lanes moved onto it, :meth:`ExchangeLane.share`), one event per turn in the
    order they came, so a message one node publishes to another is taken on the next turn with
    no other process to wake. Between turns the kept exceptions of the lanes are raised and,
    every :data:`WATCH_EVERY_S`, every node's :meth:`NodeBase.watch` runs. Returns the exit code
    (the largest of the nodes' :meth:`NodeBase.end`)."""

    lanes = [n.exchange for n in nodes if n.exchange is not None]
    for lane in lanes:
        lane.share(executor)
    for n in nodes:
        n.begin()
    next_watch, timeout_s, now = 0.0, 0.2, time.monotonic
    while True:  # per event: one turn, the lanes' errors; the rest every WATCH_EVERY_S
        executor.spin_once(timeout_sec=timeout_s)
        for lane in lanes:
            if lane.error is not None:
                lane.raise_error()
        if now() >= next_watch:
            next_watch = now() + WATCH_EVERY_S
            for n in nodes:
                n.watch()
            if not rclpy.ok() or any(n.finished for n in nodes):
                break
            timeout_s = 0.05 if any(n.run is not None for n in nodes) else 0.2
    return max(n.end(executor) for n in nodes)
