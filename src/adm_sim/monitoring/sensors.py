"""What the monitor reads from a sensor message: its types, the axis and its sign (ROS-free).

``geometry_msgs/msg/AccelStamped`` (``accel.linear``) and ``sensor_msgs/msg/Imu``
(``linear_acceleration``) are read alike: the component of the chosen axis (``z`` by default, z up as
REP 103; ``-z`` for a sensor mounted z down, ``x``, ``y`` for another mounting), times its sign.
An Imu that carries no linear acceleration (REP 145: ``linear_acceleration_covariance[0] = -1``) or
whose covariance marks the chosen axis as absent (its diagonal entry negative) is refused.
Messages are read by attribute (rclpy messages and mcap-ros2-support's decoded ones alike). Stamps
must strictly increase (:func:`stamp_order` says why a sample's does not).
"""

from __future__ import annotations

import math

from adm_sim.errors import InputError

ACCEL_TYPE = "geometry_msgs/msg/AccelStamped"
IMU_TYPE = "sensor_msgs/msg/Imu"
#: Message types the monitor reads.
SENSOR_TYPES = (ACCEL_TYPE, IMU_TYPE)
#: Axis choices (sign and component).
AXES = ("z", "-z", "x", "-x", "y", "-y")
_DIAG = {"x": 0, "y": 4, "z": 8}


def parse_axis(text, option="--axis"):
    """``(component, sign)`` of an axis choice ``z``, ``-z``, ``x``, ... (one line when not one)."""
    t = str(text).strip()
    if t not in AXES:
        raise InputError(f"{option}: {text!r} is not an axis; allowed {', '.join(AXES)} (z up by default)")
    return t[-1], -1.0 if t.startswith("-") else 1.0


def vector_of(msg, type_name):
    """The acceleration vector of a sensor message of ``type_name``."""
    return msg.linear_acceleration if type_name == IMU_TYPE else msg.accel.linear


def stamp_s(msg):
    st = msg.header.stamp
    return st.sec + 1e-9 * st.nanosec


def check_imu(msg, component, where):
    """Refuse an Imu without linear acceleration or without the chosen axis (one line)."""
    cov = list(msg.linear_acceleration_covariance)
    if len(cov) == 9 and cov[0] == -1.0:
        raise InputError(f"{where}: the Imu messages carry no linear acceleration (linear_acceleration_covariance[0] "
                         f"= -1, REP 145); give a topic with acceleration")
    k = _DIAG[component]
    if len(cov) == 9 and math.isfinite(cov[k]) and cov[k] < 0:
        raise InputError(f"{where}: the Imu messages mark axis {component} as absent "
                         f"(linear_acceleration_covariance[{k}] = {cov[k]:g}); choose another with --axis "
                         f"({', '.join(AXES)})")


def stamp_order(t_s, index, last_s, last_index):
    """None when sample ``index`` (stamp ``t_s``, s) comes after sample ``last_index`` (``last_s``);
    else the one-line words of why not (a duplicate stamp, or time going back): the monitor reads a
    sensor's stamps as strictly increasing (a data logger's CSV: :mod:`adm_sim.inputs.sensor_csv`)."""
    if last_s is None or t_s > last_s:
        return None
    how = "repeats the stamp of" if t_s == last_s else f"goes back {last_s - t_s:.9g} s from"
    return f"sample {index} stamped {t_s:.9f} s {how} sample {last_index} ({last_s:.9f} s)"


def restarts_stamp_order(record, last_s):
    """Whether a run record (a decoded status message) starts the stamp order again: a bridge's
    ``started`` record whose ``t0_s`` lies before the last stamp taken ``last_s`` (s), i.e. a new bridge
    whose sim time starts again."""
    return (last_s is not None and record.get("node") == "bridge" and record.get("state") == "started"
            and float(record.get("t0_s", last_s)) < last_s)


def sample_of(msg, type_name, component, sign):
    """``(stamp in s, acceleration in m/s²)`` of one sensor message."""
    return stamp_s(msg), sign * float(getattr(vector_of(msg, type_name), component))
