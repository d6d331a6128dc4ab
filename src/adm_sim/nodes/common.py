"""The shared names of the ROS 2 nodes, one import for a node module (``from adm_sim.nodes import
common as c``): each lives in the module of its concern.

- :mod:`adm_sim.nodes.qos`: the QoS profiles of the topics (``QOS_*``);
- :mod:`adm_sim.nodes.messages`: sim time stamps, labelled arrays, protocol records as messages;
- :mod:`adm_sim.nodes.exchange`: the lockstep exchange, its messages, lane and partner watch;
- :mod:`adm_sim.nodes.flow_client`: a client's side of the bridge's flow control;
- :mod:`adm_sim.nodes.param_node`: ROS parameters from the ROS-free specs (:mod:`adm_sim.nodes.params`);
- :mod:`adm_sim.nodes.node_base`: the nodes' bases, main-loop hooks and parameters locked during a run;
- :mod:`adm_sim.nodes.node_main`: the ``main`` of every node (:func:`run_node`).

Every topic, its layout and its QoS: docs/ros.md, section "Topics"; their names and records:
:mod:`adm_sim.protocol` (ROS-free).
"""

from __future__ import annotations

from rclpy.experimental import EventsExecutor

from adm_sim.nodes.exchange import (ExchangeError, ExchangeLane, ExchangeWriter, PartnerWatch, check_step, pack,
                                    parse_cdr, unpack)
from adm_sim.nodes.flow_client import FlowClient
from adm_sim.nodes.messages import (float64_data, json_msg, matrix_from_msg, matrix_msg, matrix_step,
                                    to_time_msg)
from adm_sim.nodes.node_base import LockstepNode, NodeBase
from adm_sim.nodes.node_main import check_sections_apply, run_node, stopped_by_signal
from adm_sim.nodes.param_node import SHARED_PARAMETER_NAMES, ParamNodeMixin
from adm_sim.nodes.params import ParamSpec, format_float_list, param, parse_float_list
from adm_sim.nodes.qos import QOS_CONTROL, QOS_EXCHANGE, QOS_HISTORY, QOS_LATCHED, QOS_MONITOR

__all__ = ["EventsExecutor", "ExchangeError", "ExchangeLane", "ExchangeWriter", "PartnerWatch", "check_step",
           "pack", "parse_cdr", "unpack", "FlowClient", "float64_data", "json_msg", "matrix_from_msg",
           "matrix_msg", "matrix_step", "to_time_msg", "LockstepNode", "NodeBase", "check_sections_apply",
           "run_node", "stopped_by_signal", "SHARED_PARAMETER_NAMES", "ParamNodeMixin", "ParamSpec",
           "format_float_list", "param", "parse_float_list", "QOS_CONTROL", "QOS_EXCHANGE", "QOS_HISTORY",
           "QOS_LATCHED", "QOS_MONITOR"]
