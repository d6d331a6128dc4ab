"""``monitor.py`` live: the monitor node (:class:`adm_sim.nodes.monitor_node.MonitorNode`) in this
process on ``--domain-id``, shared memory only, until ``--passages`` passages or ``--duration``
seconds. The command line, its checks and the offline paths (MCAP, CSV) are ``monitor.py``'s; this
module is imported only when a monitor subscribes live (rclpy 82 ms and the monitor node 230 ms load
here), so ``--help``, bad input and the offline paths answer without them.
"""

from __future__ import annotations

import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from adm_sim.nodes.common import stopped_by_signal
from adm_sim.nodes.monitor_node import MonitorNode
from adm_sim.processes.dds_env import apply_local_ros_env

__all__ = ["monitor_live"]


def monitor_live(args, on_passage):
    """Run the monitor node in this process until ``--passages`` or ``--duration``; returns it."""
    env = apply_local_ros_env(args.domain_id)
    context = rclpy.context.Context()
    rclpy.init(args=[], context=context)
    overrides = [Parameter("topic", value=args.topic), Parameter("topic_timeout_s", value=args.timeout),
                 Parameter("min_cycles", value=args.min_cycles), Parameter("bandpass", value=not args.no_bandpass),
                 Parameter("axis", value=args.axis), Parameter("raw", value=bool(args.raw))]
    if args.status_topic:
        overrides.append(Parameter("status_topic", value=args.status_topic))
    if args.track_type:
        overrides.append(Parameter("track_type", value=args.track_type))
    node = None
    try:
        node = MonitorNode(on_passage=on_passage, quiet=True, context=context, parameter_overrides=overrides)
        print(f"ROS_DOMAIN_ID={env.domain_id} (shared memory only); subscribed to {node.topic}", flush=True)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        t_end = None if args.duration is None else time.monotonic() + args.duration
        found = False
        while context.ok():
            try:
                executor.spin_once(timeout_sec=0.1)
            except Exception as exc:
                if not stopped_by_signal(exc, context):
                    raise
                raise KeyboardInterrupt from exc  # Ctrl-C shut rclpy down under the executor: the interrupt
            if node.sub is not None and node.sub.get_publisher_count() > 0 and not found:  # matched: samples from now on
                found = True
                print(f"{node.topic}: {node.count_publishers(node.topic)} publisher(s) found"
                      + (", subscribed best effort" if node.best_effort else ""), flush=True)
            if args.passages is not None and len(node.tracker.passages) >= args.passages:
                break
            if t_end is not None and time.monotonic() >= t_end:
                node.finish()
                break
        return node
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
