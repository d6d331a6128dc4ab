"""Record ROS 2 messages to MCAP, read them back, salvage the files of killed writers.

The one name to import the MCAP log by; each concern has its own module of the recording wing:

========================================  ==========================================================
:mod:`adm_sim.recording.mcap_schema`      schemas (rosbags' ROS 2 Jazzy type store)
:mod:`adm_sim.recording.mcap_qos`         the QoS metadata of a channel (:data:`QOS_CLASSES`)
:mod:`adm_sim.recording.mcap_write`       :class:`McapRecorder`, the writer a SIGKILL leaves readable
:mod:`adm_sim.recording.mcap_records`     the records of a file read byte by byte (chunks, CRCs)
:mod:`adm_sim.recording.mcap_scan`        :func:`scan`: every record checked, each damage named
:mod:`adm_sim.recording.mcap_read`        :func:`read_messages` and :func:`checked_scan`
:mod:`adm_sim.recording.mcap_salvage`     :func:`salvage`: the intact messages into a clean file
========================================  ==========================================================

Files follow the ROS 2 profile that rosbag2 writes (https://mcap.dev/spec/registry): profile
``ros2``, schema encoding ``ros2msg``, message encoding ``cdr``. Schema text and serialisation
both come from rosbags' ROS 2 Jazzy type store (``Typestore.generate_msgdef``: the definition
with every dependency after a line of 80 ``=`` and ``MSG: pkg/Type``; ``Typestore.serialize_cdr``
reading the rclpy message by attribute). Its CDR has exact lengths: rclpy's ``serialize_message``
reports rmw_fastrtps' *estimated* size, up to 8 bytes too long for an empty ``float64[]``, which
rosbags refuses. The files read with mcap-ros2-support, ``rosbags`` and ``rerun mcap convert``.

Each channel carries ``offered_qos_profiles`` as rosbag2 writes it (:func:`qos_profiles_yaml`),
the QoS of the topic's class (:data:`QOS_CLASSES`) unless the caller gives its own.

Chunks are small (64 KiB before compression by default) and written straight to the operating
system, so a writer killed with SIGKILL loses at most the open chunk; the recorder also writes the
data-section CRC (header, metadata, message indexes). Every reader checks a file first
(:func:`scan`, :func:`checked_scan`): record framing, chunk decompression and CRC, summary and
data-section CRC; a damaged place is named with its offset and the messages lost there per topic,
and reading goes on at the next intact chunk. :func:`read_messages` refuses a damaged file with one
line unless asked to skip the damage; :func:`salvage` writes every intact message of a killed or
damaged file into a clean one (command line: ``adm-sim salvage IN.mcap OUT.mcap``).
"""

from __future__ import annotations

from adm_sim.recording.mcap_read import (check_intact, checked_scan, decode_messages, iter_raw_messages,
                                         read_messages, sorted_messages)
from adm_sim.recording.mcap_records import inner_records as _inner_records  # noqa: F401  the integrity tests' name
from adm_sim.recording.mcap_records import parse_chunk as _parse_chunk  # noqa: F401  the integrity tests' name
from adm_sim.recording.mcap_salvage import salvage
from adm_sim.recording.mcap_scan import Damage, Scan, scan
from adm_sim.recording.mcap_qos import QOS_CLASSES, QOS_DEFAULT, parse_qos_profiles, qos_profiles_yaml, topic_qos
from adm_sim.recording.mcap_schema import message_definition, type_name
from adm_sim.recording.mcap_write import DEFAULT_CHUNK_SIZE, McapRecorder

__all__ = [
    "DEFAULT_CHUNK_SIZE",
    "McapRecorder",
    "QOS_CLASSES",
    "QOS_DEFAULT",
    "parse_qos_profiles",
    "qos_profiles_yaml",
    "topic_qos",
    "message_definition",
    "Damage",
    "Scan",
    "check_intact",
    "checked_scan",
    "decode_messages",
    "sorted_messages",
    "iter_raw_messages",
    "scan",
    "read_messages",
    "salvage",
    "type_name",
]
