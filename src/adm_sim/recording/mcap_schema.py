"""ROS 2 message schemas of an MCAP recording, as rosbag2 writes them.

Schema text comes from rosbags' ROS 2 Jazzy type store (``Typestore.generate_msgdef``: the
definition with every dependency after a line of 80 ``=`` and ``MSG: pkg/Type``, schema encoding
``ros2msg``); the same store serialises the messages (:mod:`adm_sim.recording.mcap_write`). The
QoS metadata of a channel is :mod:`adm_sim.recording.mcap_qos`.
"""

from __future__ import annotations

import functools

from rosbags.typesys import Stores, get_typestore

from adm_sim.errors import InputError

__all__ = ["message_definition", "type_name", "typestore"]


# ---------------------------------------------------------------- schemas


def type_name(msg_type) -> tuple[str, str]:
    """``(package, Type)`` of an rclpy message class, e.g. ``('std_msgs', 'Float64MultiArray')``."""
    module = getattr(msg_type, "__module__", "")
    pkg, _, sub = module.partition(".")
    if not sub.startswith("msg") or not hasattr(msg_type, "get_fields_and_field_types"):
        raise InputError(
            f"msg_type: {msg_type!r} is not a ROS 2 message class; "
            "allowed a class from a <package>.msg module, e.g. std_msgs.msg.Float64MultiArray"
        )
    return pkg, msg_type.__name__


@functools.cache
def typestore():
    """rosbags' ROS 2 Jazzy type store, built once (on first use) for the schemas and the CDR."""
    return get_typestore(Stores.ROS2_JAZZY)


def message_definition(msg_type) -> tuple[str, str]:
    """Schema name and ``ros2msg`` text of a message class, from rosbags' ROS 2 Jazzy type store.

    Returns
    -------
    (str, str)
        ``('geometry_msgs/msg/AccelStamped', text)``: the definition followed by each
        dependency once, after a line of 80 ``=`` and ``MSG: pkg/Type`` (the rosbag2 format;
        ``rosbags.typesys`` ``Typestore.generate_msgdef``).
    """
    pkg, name = type_name(msg_type)
    full = f"{pkg}/msg/{name}"
    store = typestore()
    if full not in store.types:
        raise InputError(f"msg_type: {full} is not a ROS 2 Jazzy type known to rosbags; "
                         f"allowed the common_interfaces types")
    text, _ = store.generate_msgdef(full, ros_version=2)
    return full, text
