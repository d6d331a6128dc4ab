"""The bridge's side of the flow control of one run: what it published, what each recorder or
opted-in client acknowledged, and whether the run waits for them (docs/ros.md, "Flow control").

The bridge never publishes more than :data:`adm_sim.protocol.FLOW_WINDOW` messages of the counted
topics (:data:`adm_sim.protocol.SAMPLE_TOPICS`) beyond the slowest acknowledgement, and ends a run
only once every acknowledging node has them all. A client's side is
:class:`adm_sim.nodes.flow_client.FlowClient`. ROS-free: the node publishes, this counts.
"""

from __future__ import annotations

from adm_sim import protocol as P

#: What a run waits for the recorders' acknowledgement before: the next exchange, or its end.
PAUSE_STEP, PAUSE_END = "step", "end"


class FlowControl:
    """The counts and acknowledgements of one run.

    Parameters
    ----------
    nodes : iterable of str
        Fully qualified names of the nodes that acknowledge (the publishers of ``/adm/run/ack``
        at the run's set-up).

    Attributes
    ----------
    acked : dict
        Node -> messages it acknowledged (a node dropped from the flow control leaves it).
    ack_topics : dict
        Node -> the topics its count covers, when not every counted topic (a client that reads
        the acceleration alone).
    counts : dict
        Topic -> messages published (the run's ``samples``).
    sent : int
        Messages published over every counted topic.
    paused : str or None
        :data:`PAUSE_STEP` or :data:`PAUSE_END` while the run waits for the acknowledgements.
    wait_since : float or None
        ``time.monotonic()`` since which the run waits with no acknowledgement (the pause's start
        or its last acknowledgement).
    forced : bool
        A pause outlasted half the partner timeout: the run went on to the next exchange.
    """

    def __init__(self, nodes):
        self.acked = {n: 0 for n in nodes}
        self._unseen = set()  # joined (:meth:`join`), not yet on the bridge's view of the graph
        self._dropped = set()
        self.ack_topics = {}
        self.counts = {t: 0 for t in P.SAMPLE_TOPICS}
        self.sent = 0
        self.paused = None
        self.wait_since = None
        self.forced = False

    def count(self, topic):
        """One message of ``topic`` published."""
        self.counts[topic] += 1
        self.sent += 1

    def sent_to(self, name):
        """Messages published so far on the topics node ``name`` acknowledges."""
        topics = self.ack_topics.get(name)
        return self.sent if topics is None else sum(self.counts[t] for t in topics)

    def take(self, ack, now):
        """Take an acknowledgement record (:class:`adm_sim.protocol.AckCounter`) received at ``now``
        (``time.monotonic()``); returns whether it came from a node this run waits for. During a pause
        the patience of :meth:`drop` counts again from ``now``: a node that acknowledged part of what
        it waits for and then nothing is dropped after the patience, as one that never acknowledged
        (the pause's clock stopped at such an acknowledgement once, and a run whose recorder missed
        its last messages waited for it without end)."""
        name = ack.get("node")
        if name not in self.acked:
            return False
        topics = ack.get("topics")
        if topics is not None:  # a client that counts some topics only (checked: the known ones)
            self.ack_topics[name] = tuple(t for t in topics if t in self.counts)
        self.acked[name] = max(self.acked[name], int(ack["received"]))
        self.wait_since = None if self.paused is None else now
        return True

    def join(self, ack, run_id, now):
        """Take a node that acknowledges run ``run_id`` (at ``now``, as :meth:`take`) without having been on the bridge's view of
        the graph at the run's set-up: discovery on a loaded machine can show a client to the bridge
        seconds after it opted in (and after a launcher's ``--wait-clients`` saw it), and a client
        acknowledges its first sample of a run at once, while its queue (at least
        :data:`adm_sim.protocol.FLOW_WINDOW`) still holds every sample. From then on the run waits for
        it as for the others. An acknowledgement of another run, of a node already waited for, or of
        one dropped in this run joins nothing. Returns whether the node joined."""
        name = ack.get("node")
        if not name or ack.get("run_id") != run_id or name in self.acked or name in self._dropped:
            return False
        self.acked[name] = 0
        self._unseen.add(name)
        return self.take(ack, now)

    def ahead(self, pending=0):
        """Whether the run is more than the window ahead of the slowest acknowledging node (with
        ``pending`` messages more published)."""
        if self.forced or not self.acked:
            return False
        if not self.ack_topics:  # recorders only: each counts every topic
            return self.sent + pending - min(self.acked.values()) >= P.FLOW_WINDOW
        return any(self.sent_to(n) + pending - a >= P.FLOW_WINDOW for n, a in self.acked.items())

    def all_acked(self):
        """Whether every acknowledging node has every message published so far."""
        if not self.ack_topics:
            return not self.acked or min(self.acked.values()) >= self.sent
        return all(a >= self.sent_to(n) for n, a in self.acked.items())

    def pause(self, what, now):
        """Wait for the acknowledgements before ``what`` (:data:`PAUSE_STEP`, :data:`PAUSE_END`)."""
        self.paused = what
        if self.wait_since is None:
            self.wait_since = now

    def unpause(self):
        """The pause is over: the next one's patience starts when it starts."""
        self.paused = None
        self.wait_since = None

    def drop(self, alive, patience_s, now):
        """Stop waiting for the nodes not in ``alive`` (they left the graph), or for every node when
        none acknowledged anything for ``patience_s``. Returns ``[(name, left, acked, sent), ...]``
        of the nodes dropped (``left``: it left the graph)."""
        stale = now - self.wait_since > patience_s
        self._unseen -= set(alive)  # a node that joined counts as on the graph until the bridge has seen it
        dropped = []
        for name in list(self.acked):
            left = name not in alive and name not in self._unseen
            if left or stale:
                dropped.append((name, left, self.acked[name], self.sent_to(name)))
                del self.acked[name]
                self._dropped.add(name)
        if dropped:  # the patience of those left starts again; else it runs on (checked every turn)
            self.wait_since = None if not self.acked else now
        return dropped
