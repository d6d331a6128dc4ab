"""Plain messages of the node graph: sim time stamps, labelled arrays, protocol records.

The monitoring arrays (:func:`matrix_msg`) and the exchange messages
(:mod:`adm_sim.nodes.exchange`) share the labelled layout (:func:`layout_dims`) and the byte copy
of their doubles (:func:`float64_data`).
"""

from __future__ import annotations

import array
import functools

import numpy as np
from builtin_interfaces.msg import Time
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String

from adm_sim.protocol import encode


# ---------------------------------------------------------------------- time
def to_time_msg(t_s):
    """``builtin_interfaces/Time`` from seconds (sim time)."""
    ns = int(round(float(t_s) * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


@functools.lru_cache(maxsize=256)
def layout_dims(labels, shape):
    """The ``MultiArrayDimension``s of a payload (kept per labels and shape: a DIM run sends a few
    shapes tens of thousands of times; the messages only read them)."""
    dims, stride = [], int(np.prod(shape)) if shape else 0
    for label, size in zip(labels, shape):
        dims.append(MultiArrayDimension(label=label, size=int(size), stride=int(stride)))
        stride = stride // size if size else 0
    return tuple(dims)


def float64_data(values):
    """``values`` (ndarray of float64) as the ``array.array('d')`` a ``float64[]`` field holds, copied
    as bytes: assigning an ndarray makes the message build that array value by value (about
    0.5 us a value: 1.6 ms for 3000 doubles, against 17 us so). The same bytes either way."""
    out = array.array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out



def matrix_msg(dims, array, step=None):
    """Plain 2-D ``Float64MultiArray`` with labelled dimensions; with ``step``, the step index is
    carried before the data (``data[0]``, ``layout.data_offset`` = 1; :func:`matrix_step`)."""
    a = np.asarray(array, dtype=np.float64)
    msg = Float64MultiArray()
    msg.layout.dim = list(layout_dims(tuple(dims), a.shape))
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
