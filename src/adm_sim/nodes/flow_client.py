"""The client side of the bridge's flow control: :class:`FlowClient` (docs/ros.md, "Flow control").

The bridge side is :class:`adm_sim.nodes.flow_control.FlowControl`.
"""

from __future__ import annotations

from std_msgs.msg import String

from adm_sim import protocol as P
from adm_sim.nodes.qos import QOS_CONTROL, QOS_MONITOR

#: What rmw reports as a publisher's node name and namespace while the node's name has not been
#: discovered yet (it comes on a topic of its own, after the endpoint itself).
NODE_NAME_UNKNOWN, NODE_NAMESPACE_UNKNOWN = "_NODE_NAME_UNKNOWN_", "_NODE_NAMESPACE_UNKNOWN_"


def named_publishers(infos):
    """Fully qualified node names of ``infos`` (``Node.get_publishers_info_by_topic``), leaving out
    the publishers whose node name is not known yet: an acknowledgement carries its node's real
    name, so a client taken as ``_NODE_NAME_UNKNOWN_`` would be waited for in vain."""
    return sorted({i.node_namespace.rstrip("/") + "/" + i.node_name for i in infos
                   if i.node_name != NODE_NAME_UNKNOWN and i.node_namespace != NODE_NAMESPACE_UNKNOWN})


class FlowClient:
    """Opt a client node into the bridge's flow control: one call, ``FlowClient(node)``, before the
    run starts; then ``flow.received()`` in the callback of every message of ``topics``.

    The bridge takes every publisher of ``/adm/run/ack`` at a run's set-up as a node to wait for,
    and one its view of the graph missed then at its first acknowledgement of the run
    (docs/ros.md, "Flow control"): it never publishes more than :data:`adm_sim.protocol.FLOW_WINDOW`
    messages of ``topics`` beyond this client's acknowledgement, and ends the run only once the
    client has them all. Subscribe to ``topics`` RELIABLE with a history of at least
    ``FLOW_WINDOW`` (:data:`QOS_MONITOR`). The counting is :class:`adm_sim.protocol.AckCounter`;
    ``runs`` gives ``run_id -> (received, published)`` of the runs ended.

    The client opts in (creates its ``/adm/run/ack`` publisher, which the bridge and the launchers'
    ``--wait-clients`` look for) once the node subscribes to each of ``topics`` (made before or after
    this call) and each of those subscriptions is matched with a publisher: a client the bridge waits
    for from a run's first sample is one that can receive it (on a loaded machine discovery can match
    the subscriptions seconds after the node appeared). ``opted_in`` says whether it has.

    Parameters
    ----------
    node : rclpy.node.Node
        The client's node.
    topics : sequence of str
        The topics the client reads, of :data:`adm_sim.protocol.SAMPLE_TOPICS` (default the midspan
        acceleration).
    graph : str or None
        The namespace of the graph (``/b1``: its ``/b1/adm/run/ack``); ``None``: the node's own
        (relative names).
    """

    def __init__(self, node, topics=(P.TOPIC_ACCEL,), graph=None):
        self.counter = P.AckCounter(node.get_fully_qualified_name(), topics)

        def name(topic):
            return P.relative(topic) if graph is None else graph.rstrip("/") + topic

        self.node, self.pub, self._ack_topic = node, None, name(P.TOPIC_ACK)
        self._wanted = {node.resolve_topic_name(name(t)) for t in topics}
        node.create_subscription(String, name(P.TOPIC_PROGRESS), self._on_progress, QOS_MONITOR)
        node.create_subscription(String, name(P.TOPIC_STATUS), self._on_status, QOS_CONTROL)
        self._timer = node.create_timer(0.05, self._opt_in)

    @property
    def runs(self):
        return self.counter.runs

    @property
    def opted_in(self):
        return self.pub is not None

    def _opt_in(self):
        """Create the acknowledgement publisher once the node subscribes to every counted topic and
        each of those subscriptions has a matched publisher. A node that subscribes after this call
        (the monitor node subscribes once it has seen the topic's publishers) is not opted in before."""
        subs = [s for s in self.node.subscriptions if s.topic_name in self._wanted]
        if (self.pub is None and {s.topic_name for s in subs} == self._wanted
                and all(s.get_publisher_count() > 0 for s in subs)):
            self.pub = self.node.create_publisher(String, self._ack_topic, QOS_CONTROL)
            self._timer.cancel()
            self.node.destroy_timer(self._timer)

    def received(self, n=1):
        """``n`` messages of the counted topics arrived."""
        self._send(self.counter.count(n))

    def _on_progress(self, msg):
        self._send(self.counter.final(P.decode(msg.data)))

    def _on_status(self, msg):
        rec = P.decode(msg.data)
        if P.is_bridge_start(rec):
            self.counter.started(rec.get("run_id"))

    def _send(self, rec):
        if rec is not None and self.pub is not None:
            self.pub.publish(String(data=P.encode(rec)))
