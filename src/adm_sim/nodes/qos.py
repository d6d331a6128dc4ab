"""QoS profiles of the node graph's topics (docs/ros.md, section "Topics": every topic and its QoS)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from adm_sim import protocol as P

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
