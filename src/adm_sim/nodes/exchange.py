"""The lockstep exchange of the bridge and train nodes: its messages, its lane, its partner watch.

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

import numpy as np
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray

from adm_sim.errors import RunError
from adm_sim.nodes.messages import float64_data, layout_dims
from adm_sim.protocol import EXCHANGE_HEADER_LEN as HEADER_LEN


class ExchangeError(RunError):
    """The lockstep exchange lost its partner or its order (a :class:`RunError`: exit 1)."""


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
    msg.layout.dim = list(layout_dims(tuple(dims), a.shape))
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
def _cdr_prefix(dims, shape, n):
    """The serialized bytes of an exchange message before its doubles (:func:`pack`'s layout for
    payload ``shape`` after ``n`` indices, by ``rclpy.serialization.serialize_message``), or None
    where the serialization is not little-endian CDR (the message is then sent itself)."""
    total = HEADER_LEN + n + math.prod(shape)
    msg = Float64MultiArray()
    msg.layout.dim = list(layout_dims(dims, shape))
    msg.layout.data_offset = HEADER_LEN + n
    msg.data = array.array("d", bytes(8 * total))
    raw = serialize_message(msg)
    if sys.byteorder != "little" or raw[1] != 1:
        return None
    return raw[:len(raw) - 8 * total]


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
