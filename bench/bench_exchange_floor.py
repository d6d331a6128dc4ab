#!/usr/bin/env python
"""The exchange's floor: two processes, one DIM-sized message each way per round trip, no physics.

    .venv/bin/python bench/bench_exchange_floor.py [--trips 10000] [--lanes 32] [--axles 5] [--one-process]
        [--message-objects]

The same messages (the rail state ``2 x lanes x axles`` one way, the forces ``lanes x axles``
back), sent as the nodes send them (:class:`adm_sim.nodes.common.ExchangeWriter`: serialized
bytes, raw subscriptions, :func:`~adm_sim.nodes.common.unpack`; ``--message-objects``: a
``Float64MultiArray`` of :func:`~adm_sim.nodes.common.pack` per message, as before), QoS (``QOS_EXCHANGE``) and executor (rclpy's
``EventsExecutor``) as the bridge and train nodes, shared memory only, a domain of its own. Prints
the wall time per round trip and the CPU time per trip of each process: what a co-simulated DIM
round trip costs before any physics or monitoring (compare ``bench_ros.py``'s DIM trips/s).
``--one-process``: both ends as two nodes of one process on one executor (as ROS composition
hosts nodes), the same messages through the same middleware; the CPU figure is then both ends'.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


#: ``--message-objects``: a Float64MultiArray per message (pack) instead of serialized bytes.
OBJECTS = False


def _node(role, lanes, axles, ex=None):
    import numpy as np
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.node import Node
    from std_msgs.msg import Float64MultiArray

    from adm_sim.nodes import common as c

    if ex is None:
        rclpy.init()
        ex = EventsExecutor()
    node = Node(f"floor_{role}", enable_rosout=False, start_parameter_services=False)
    ex.add_node(node)
    rng = np.random.default_rng(1)
    rail, forces, idx = rng.random((2, lanes, axles)), rng.random((lanes, axles)), np.arange(axles)
    return rclpy, node, ex, Float64MultiArray, c, rail, forces, idx


def _pong_node(lanes, axles, ex=None):
    """The answering end: takes the rail state, answers with the forces; returns its count of trips."""
    rclpy, node, ex, Msg, c, _rail, forces, idx = _node("pong", lanes, axles, ex)
    pub = node.create_publisher(Msg, "/floor/forces", c.QOS_EXCHANGE)
    writer = c.ExchangeWriter(pub)
    seen = [0]

    def on_rail(msg):
        c.unpack(msg)
        seen[0] += 1
        if OBJECTS:
            pub.publish(c.pack(1, seen[0], 0, forces, ("lane", "axle_on"), idx))
        else:
            writer.publish(1, seen[0], 0, forces, ("lane", "axle_on"), idx)

    node.create_subscription(Msg, "/floor/rail", on_rail, c.QOS_EXCHANGE, raw=not OBJECTS)
    return rclpy, ex, seen


def pong(trips, lanes, axles):
    rclpy, ex, seen = _pong_node(lanes, axles)
    t_end = time.monotonic() + 600.0
    while seen[0] < trips and time.monotonic() < t_end:
        ex.spin_once(timeout_sec=0.05)
    cpu0 = time.process_time()
    sys.stdout.write(f"{cpu0}\n")
    rclpy.try_shutdown()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trips", type=int, default=10000)
    ap.add_argument("--lanes", type=int, default=32)
    ap.add_argument("--axles", type=int, default=5)
    ap.add_argument("--one-process", action="store_true", help="both ends in this process, one executor")
    ap.add_argument("--message-objects", action="store_true",
                    help="a message object per message (pack), not serialized bytes as the nodes send")
    ap.add_argument("--pong", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    global OBJECTS
    OBJECTS = args.message_objects
    warm = 100
    if args.pong:
        return pong(args.trips + warm, args.lanes, args.axles)
    env = dict(os.environ, FASTDDS_BUILTIN_TRANSPORTS="SHM", ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=os.environ.get("ROS_DOMAIN_ID", "217"))
    os.environ.update(env)
    other = ex = None
    if args.one_process:
        _, ex, _ = _pong_node(args.lanes, args.axles)
    else:
        other = subprocess.Popen([sys.executable, __file__, "--pong", "--trips", str(args.trips), "--lanes",
                                  str(args.lanes), "--axles", str(args.axles)] + ["--message-objects"] * OBJECTS,
                                 env=env, stdout=subprocess.PIPE, text=True)
    rclpy, node, ex, Msg, c, rail, _forces, idx = _node("ping", args.lanes, args.axles, ex)
    pub = node.create_publisher(Msg, "/floor/rail", c.QOS_EXCHANGE)
    writer = c.ExchangeWriter(pub)
    got = [False]

    def on_forces(msg):
        c.unpack(msg)
        got[0] = True

    node.create_subscription(Msg, "/floor/forces", on_forces, c.QOS_EXCHANGE, raw=not OBJECTS)
    t_end = time.monotonic() + 60.0
    while pub.get_subscription_count() == 0 or node.count_publishers("/floor/forces") == 0:
        if time.monotonic() > t_end:
            if other is not None:
                other.kill()
            raise SystemExit("error: the other process did not match within 60 s")
        ex.spin_once(timeout_sec=0.05)

    def trip(k):
        got[0] = False
        if OBJECTS:
            pub.publish(c.pack(1, k, 0, rail, ("field", "lane", "axle_on"), idx))
        else:
            writer.publish(1, k, 0, (rail[0], rail[1]), ("field", "lane", "axle_on"), idx)
        while not got[0]:
            ex.spin_once(timeout_sec=1.0)

    for k in range(warm):
        trip(k)
    c0, t0 = time.process_time(), time.perf_counter()
    for k in range(args.trips):
        trip(k)
    c1, t1 = time.process_time(), time.perf_counter()
    n = args.trips
    head = (f"{n} round trips, rail {2 * args.lanes * args.axles} doubles, forces {args.lanes * args.axles}"
            f"{' (one process, one executor)' if other is None else ''}: {1e6 * (t1 - t0) / n:.0f} us a trip wall; ")
    if other is None:
        print(f"{head}CPU {1e6 * (c1 - c0) / n:.0f} us a trip (both ends); load {os.getloadavg()[0]:.1f}")
    else:
        out, _ = other.communicate(timeout=60)
        print(f"{head}CPU {1e6 * (c1 - c0) / n:.0f} us a trip here, "
              f"{1e6 * float(out.split()[-1]) / (n + warm):.0f} us in the other (start-up included); "
              f"load {os.getloadavg()[0]:.1f}")
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
