"""The QoS of an MCAP channel (``offered_qos_profiles``), as rosbag2 writes it and a replay reads it.

Each channel carries the profiles its publishers offered, as rosbag2 (Jazzy, metadata version 9)
writes them (:func:`qos_profiles_yaml`): the QoS of the topic's class (:data:`QOS_CLASSES`, by
:data:`adm_sim.protocol.TOPICS`) unless the recorder is given its own. :func:`parse_qos_profiles`
reads the first profile back, so a replay publishes each topic as the run did (descriptions
latched).
"""

from __future__ import annotations

from collections.abc import Mapping

import yaml

from adm_sim import protocol as P

__all__ = ["QOS_CLASSES", "QOS_DEFAULT", "parse_qos_profiles", "qos_profiles_yaml", "topic_qos"]


# ---------------------------------------------------------------- QoS metadata

#: The QoS of each class of :data:`adm_sim.protocol.TOPICS` as the nodes offer it
#: (:mod:`adm_sim.nodes.common`, ``QOS_*``; a test keeps the two equal): ``(history, depth,
#: reliability, durability)`` in rosbag2's lower-case names.
QOS_CLASSES = {
    "C": ("keep_last", 100, "reliable", "volatile"),
    "X": ("keep_last", 16, "reliable", "volatile"),
    "M": ("keep_last", 5000, "reliable", "volatile"),
    "L": ("keep_last", 1, "reliable", "transient_local"),
    "H": ("keep_last", 1000, "reliable", "transient_local"),
}
#: rclpy's default profile (``depth=10``), for a topic of no known class.
QOS_DEFAULT = ("keep_last", 10, "reliable", "volatile")
#: An unset (infinite) duration as rmw reports an offered profile and rosbag2 writes it.
_INFINITE = (9223372036, 854775807)


def topic_qos(topic: str) -> tuple[str, int, str, str]:
    """``(history, depth, reliability, durability)`` of an adm-sim topic by its class in
    :data:`adm_sim.protocol.TOPICS` (also under a namespace: ``/b1/adm/midspan/accel``), else
    :data:`QOS_DEFAULT`."""

    entry = P.TOPICS.get(topic)
    if entry is None:
        entry = next((P.TOPICS[k] for k in sorted(P.TOPICS, key=len, reverse=True) if topic.endswith(k)), None)
    return QOS_CLASSES.get(entry[1], QOS_DEFAULT) if entry is not None else QOS_DEFAULT


def _qos_tuple(qos) -> tuple[str, int, str, str]:
    """A QoS given as a tuple, a dict with rosbag2's keys, or an rclpy ``QoSProfile`` (read by
    attribute: its policies' ``name``)."""
    if isinstance(qos, tuple):
        return qos
    if isinstance(qos, Mapping):
        return (str(qos["history"]), int(qos["depth"]), str(qos["reliability"]), str(qos["durability"]))
    return (qos.history.name.lower(), int(qos.depth), qos.reliability.name.lower(), qos.durability.name.lower())


def qos_profiles_yaml(qos) -> str:
    """``offered_qos_profiles`` of an MCAP channel as rosbag2 (Jazzy, metadata version 9) writes it:
    a YAML list with one profile per publisher, policies by name, durations as ``sec``/``nsec``
    (an unset duration as rmw's infinite, 9223372036 s 854775807 ns).

    Parameters
    ----------
    qos : tuple, dict or rclpy QoSProfile
        ``(history, depth, reliability, durability)``, e.g. ``('keep_last', 1, 'reliable',
        'transient_local')``.
    """
    history, depth, reliability, durability = _qos_tuple(qos)
    sec, nsec = _INFINITE
    duration = f"\n    sec: {sec}\n    nsec: {nsec}"
    return (f"- history: {history}\n  depth: {depth}\n  reliability: {reliability}\n"
            f"  durability: {durability}\n  deadline:{duration}\n  lifespan:{duration}\n"
            f"  liveliness: automatic\n  liveliness_lease_duration:{duration}\n"
            f"  avoid_ros_namespace_conventions: false")


def parse_qos_profiles(text: str) -> tuple[str, int, str, str] | None:
    """The first profile of an ``offered_qos_profiles`` text as ``(history, depth, reliability,
    durability)`` (lower-case names; rosbag2 also writes the enums as integers in older versions),
    or ``None`` when the text holds none."""
    try:
        items = yaml.safe_load(text) if text else None
    except yaml.YAMLError:
        return None
    if not isinstance(items, list) or not items or not isinstance(items[0], dict):
        return None
    first = items[0]
    by_int = {"history": {0: "system_default", 1: "keep_last", 2: "keep_all"},
              "reliability": {0: "system_default", 1: "reliable", 2: "best_effort"},
              "durability": {0: "system_default", 1: "transient_local", 2: "volatile"}}

    def name(key, default):
        value = first.get(key, default)
        return by_int[key].get(value, default) if isinstance(value, int) else str(value).lower()

    try:
        depth = int(first.get("depth", 10))
    except (TypeError, ValueError):
        depth = 10
    return (name("history", "keep_last"), depth, name("reliability", "reliable"), name("durability", "volatile"))

