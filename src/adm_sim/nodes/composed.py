"""The bridge and the train node in one process (as ROS composition hosts nodes).

    python -m adm_sim.nodes.composed --ros-args [--params-file FILE] [-p bridge:NAME:=VALUE]
        [-p train:NAME:=VALUE]

The same :class:`~adm_sim.nodes.bridge_node.BridgeNode` and
:class:`~adm_sim.nodes.train_node.TrainNode`, their names, topics, parameters, services, QoS
and messages unchanged: only the process is shared. One executor serves both (their exchange
lanes included, :func:`adm_sim.nodes.common.run_node`), so a DIM round trip (one per RK4 stage)
wakes no other process: in ``bench/bench_exchange_floor.py`` the same messages cost a third of
the CPU a trip of two processes (docs/benchmarks.md). A params file's ``bridge`` and ``train``
sections go to their node; ``-p`` overrides name their node (``-p bridge:ds_m:=0.05``), a
plain ``-p name:=value`` reaches both. A failure of either node ends the process (exit status 1,
``error: bridge+train: ...``; each node reports it on ``/adm/run/status``).
"""

from __future__ import annotations

import sys

from adm_sim.nodes import common as c
from adm_sim.nodes.bridge_node import BridgeNode
from adm_sim.nodes.train_node import TrainNode

#: The process's name in its ``error:`` and ``warning:`` lines.
NAME = "bridge+train"


def make_nodes():
    """The bridge node, then the train node (one context: the process's). Their partner watches
    stand down (:attr:`~adm_sim.nodes.common.PartnerWatch.same_process`): each one's partner
    lives and dies with it, and the time one spends in a callback is the other's silence."""
    bridge = BridgeNode()
    try:
        train = TrainNode()
    except BaseException:
        bridge.destroy_node()
        raise
    bridge.partner.same_process = train.partner.same_process = True
    return bridge, train


def main(args=None):
    return c.run_node(make_nodes, args=args, name=NAME)


if __name__ == "__main__":
    sys.exit(main())
