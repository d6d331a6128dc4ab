"""The bridge's flow control, counting alone (:class:`adm_sim.nodes.flow_control.FlowControl`).

A run's end waits for its recorders' acknowledgements with a patience that counts from the last one:
a recorder that acknowledged part of the run and then nothing is dropped after it (the clock once
stopped at such an acknowledgement, and ``calibrate.py`` with thinned monitoring hung after a run,
about 1 launch in 20 beside two busy processes).

A client the bridge's view of the graph showed too late joins the flow control at its first
acknowledgement of the run (:meth:`FlowControl.join`).

Seen once under two busy processes: a monitor started beside ``calibrate.py --wait-clients 1`` was on
the launcher's view of the graph, and 2 s later still not on the bridge's; run 1 did not wait for it and
it lost 188 of 521 samples. The client acknowledges its first sample of a run at once, while its
queue (at least FLOW_WINDOW) still holds every sample, so a run that takes it then loses nothing.
ROS-free: the counting alone.
"""

from __future__ import annotations

from adm_sim import protocol as P
from adm_sim.nodes.flow_control import FlowControl

REC, MON = "/adm/recorder", "/monitor"


def _publish(flow, n, topic=P.TOPIC_ACCEL):
    for _ in range(n):
        flow.count(topic)


def test_a_client_acknowledging_this_run_joins_and_is_waited_for():
    flow = FlowControl([REC])
    _publish(flow, 40)
    flow.take(P.ack_record(REC, 3, 40), now=1.0)
    assert flow.join(P.ack_record(MON, 3, 1, topics=[P.TOPIC_ACCEL]), run_id=3, now=1.0)
    assert flow.acked == {REC: 40, MON: 1}
    assert flow.ack_topics == {MON: (P.TOPIC_ACCEL,)}
    # the recorder keeps up; the client's lag alone now holds the run back
    _publish(flow, P.FLOW_WINDOW - 40)
    flow.take(P.ack_record(REC, 3, P.FLOW_WINDOW), now=2.0)
    assert flow.sent_to(MON) - flow.acked[MON] == P.FLOW_WINDOW - 1
    assert not flow.ahead()
    assert flow.ahead(pending=1)  # one more message: 512 beyond the client's count
    assert not flow.all_acked()
    flow.take(P.ack_record(MON, 3, P.FLOW_WINDOW, topics=[P.TOPIC_ACCEL]), now=3.0)
    assert not flow.ahead(pending=1) and flow.all_acked()


def test_no_join_for_another_run_a_known_node_or_one_dropped():
    flow = FlowControl([REC])
    assert not flow.join(P.ack_record(MON, 2, 5), run_id=3, now=0.0)      # the run before
    assert not flow.join(P.ack_record(MON, None, 5), run_id=3, now=0.0)   # a client that does not know the run yet
    assert not flow.join(P.ack_record(REC, 3, 5), run_id=3, now=0.0)      # already waited for
    assert flow.acked == {REC: 0}
    assert flow.join(P.ack_record(MON, 3, 0), run_id=3, now=0.0)
    _publish(flow, 10)
    flow.pause("step", now=0.0)
    dropped = flow.drop(alive={REC, MON}, patience_s=1.0, now=2.0)  # nothing acknowledged for 2 s
    assert [d[0] for d in dropped] == [REC, MON]
    assert not flow.join(P.ack_record(MON, 3, 10), run_id=3, now=3.0)     # dropped in this run: stays out


def test_a_joined_client_counts_as_on_the_graph_until_the_bridge_sees_it():
    """The bridge's view that missed the client at set-up may still miss it at the next check: the
    client is not dropped as 'left' then; once seen, leaving the graph drops it."""
    flow = FlowControl([REC])
    assert flow.join(P.ack_record(MON, 1, 0), run_id=1, now=0.0)
    _publish(flow, 10)
    flow.pause("step", now=0.0)
    assert flow.drop(alive={REC}, patience_s=5.0, now=1.0) == []  # not yet seen: kept
    flow.pause("step", now=1.0)
    assert flow.drop(alive={REC, MON}, patience_s=5.0, now=2.0) == []  # seen
    flow.pause("step", now=2.0)
    assert flow.drop(alive={REC}, patience_s=5.0, now=3.0) == [(MON, True, 0, 10)]  # then gone: left


def test_the_end_waits_for_a_partial_acknowledgement_no_longer_than_the_patience():
    """At the run's end the recorder has 990 of 1000 messages and acknowledges them at t = 10 s, then
    nothing: it is dropped at the first check more than the patience (5 s) after that acknowledgement,
    not before; had it acknowledged them all, the end would be free at once."""
    flow = FlowControl([REC])
    _publish(flow, 1000)
    flow.pause("end", now=9.0)
    flow.take(P.ack_record(REC, 7, 990), now=10.0)
    assert not flow.all_acked() and flow.wait_since == 10.0
    assert flow.drop(alive={REC}, patience_s=5.0, now=14.9) == []
    assert flow.drop(alive={REC}, patience_s=5.0, now=15.1) == [(REC, False, 990, 1000)]
    assert flow.all_acked()  # nobody left to wait for: the run ends


def test_a_pause_s_patience_starts_with_the_pause():
    """An acknowledgement while the run is not paused, or before an earlier pause ended, does not start
    the next pause's clock early."""
    flow = FlowControl([REC])
    _publish(flow, 600)
    flow.pause("step", now=1.0)
    flow.take(P.ack_record(REC, 2, 100), now=2.0)
    flow.unpause()
    assert flow.wait_since is None
    flow.take(P.ack_record(REC, 2, 200), now=3.0)  # not paused: no clock
    assert flow.wait_since is None
    flow.pause("end", now=20.0)
    assert flow.drop(alive={REC}, patience_s=5.0, now=24.0) == []


def test_a_join_during_a_pause_keeps_the_patience_running():
    """A client that joins while the run waits at its end is waited for with the same patience as the
    others: its acknowledgement restarts the clock (it acknowledged something), it does not stop it."""
    flow = FlowControl([REC])
    _publish(flow, 100)
    flow.pause("end", now=0.0)
    assert flow.join(P.ack_record(MON, 4, 60), run_id=4, now=1.0)
    assert flow.wait_since == 1.0
    dropped = flow.drop(alive={REC}, patience_s=5.0, now=6.5)  # nothing more from either for 5.5 s
    assert [(d[0], d[1]) for d in dropped] == [(REC, False), (MON, False)]
