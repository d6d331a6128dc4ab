"""One topic -> rerun feed: what each adm-sim topic draws in the viewer, live and in a replay.

:class:`ViewerFeed` takes one message at a time, ``feed(topic, msg, t_ns)``, and hands it to a
:class:`adm_sim.recording.rerun_log.RunLogger` (the adm-sim topics: descriptions, run status,
midspan acceleration, beam, results, calibration) or draws it generically (``AccelStamped`` outside
a recorded run by ``header.frame_id``, ``DiagnosticArray`` as a text log, ``JointState``,
``Float64MultiArray`` and ``Float64`` as scalar series under ``topics/``). The live driver calls it
from its subscriptions; ``replay.py`` from the decoded MCAP. Messages are read by attribute, so
rclpy messages and mcap-ros2-support's decoded ones work alike; this module imports no rclpy.

``t_ns`` is the sim time of the message (``header.stamp`` when it has one, else the time it was
recorded at; :func:`stamp_ns`). A topic under a namespace (``/b1/adm/midspan/accel``) is drawn as
the topic it ends with. Each result is drawn for its run (:class:`RunPhases`) with the phase of the
driver's ``requested`` record of that run id on ``/adm/run/status``. The driver learns a run's id
from the bridge's answer to its start request and publishes the record then, which can be after the
run's result arrived (a short run, a loaded machine: two publishers, no order between them); such a
result, and what follows it, waits for the record (:meth:`ViewerFeed.feed`), and is drawn with phase
``unknown`` only when the next run starts or the feed finishes without it.
"""

from __future__ import annotations

import sys
from collections import defaultdict

import numpy as np
import rerun as rr

from adm_sim import protocol as P
from adm_sim.recording.rerun_log import _part
from adm_sim.recording.viewer_process import check_viewer  # the viewer handshake (its home)

__all__ = ["RunPhases", "ViewerFeed", "check_viewer", "matrix_of", "stamp_ns"]

def stamp_ns(msg, log_time_ns: int) -> int:
    """``header.stamp`` of ``msg`` in ns, else ``log_time_ns``."""
    header = getattr(msg, "header", None)
    if header is not None:
        return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
    return int(log_time_ns)


def matrix_of(msg) -> np.ndarray:
    """The array of a ``Float64MultiArray`` in the shape of its layout (row major)."""
    shape = tuple(int(d.size) for d in msg.layout.dim)
    data = np.asarray(msg.data, dtype=np.float64)
    return np.array(data[int(msg.layout.data_offset):], dtype=np.float64).reshape(shape)


def _level(level) -> int:
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


class RunPhases:
    """Which run each result belongs to, and its phase as the driver recorded it (``requested``
    records on ``/adm/run/status``, :func:`adm_sim.protocol.request_record`).

    A result belongs to the earliest run the bridge announced (``started``) that has neither a
    result nor a failure yet: a bridge sends one result per run, in order, and the next run's
    ``started`` can carry the same sim time as the last result. A run without a phase record (a
    recording made before runs carried their phase) is ``unknown``, with one warning line per
    source on stderr.

    Parameters
    ----------
    source : str
        What the messages come from, for the warning (``"RUN.mcap: 'run.mcap'"``).
    """

    def __init__(self, source: str = "the run"):
        self.source = source
        self.by_run: dict[int, str] = {}
        self.pending: list[int] = []  # announced runs still waiting for their result
        self.last = P.PHASE_UNKNOWN  # phase of the last run whose result was seen
        self.warned = False

    def status(self, st: dict) -> None:
        if P.is_request(st):
            self.by_run[int(st["run_id"])] = str(st.get("phase", P.PHASE_UNKNOWN))
        elif P.is_bridge_start(st) and int(st["run_id"]) not in self.pending:
            self.pending.append(int(st["run_id"]))
        elif st.get("node") == P.BRIDGE_NODE and P.is_failure(st) and st.get("run_id") in self.pending:
            self.pending.remove(st["run_id"])

    def next_run(self) -> int | None:
        """The run the next result belongs to (``None``: no announced run waits for one)."""
        return self.pending[0] if self.pending else None

    def result(self) -> tuple[int | None, str]:
        """``(run_id, phase)`` of the next result (``(None, unknown)``: a result of no announced
        run, which is not drawn)."""
        if not self.pending:
            return None, P.PHASE_UNKNOWN
        run_id = self.pending.pop(0)
        phase = self.by_run.get(run_id)
        if phase is None:
            phase = P.PHASE_UNKNOWN
            if not self.warned:
                self.warned = True
                print(f"warning: {self.source} records no phase for run {run_id} (recorded before runs "
                      f"carried their phase); its runs are shown with phase '{P.PHASE_UNKNOWN}'",
                      file=sys.stderr, flush=True)
        self.last = phase
        return run_id, phase


#: protocol topic names by themselves, to recognise them under a namespace
_KNOWN = sorted(P.TOPICS, key=len, reverse=True)


def canonical_topic(topic: str) -> str:
    """The protocol topic ``topic`` is (``/b1/adm/midspan/accel`` -> ``/adm/midspan/accel``), or
    ``topic`` itself when it is none of them."""
    if topic in P.TOPICS:
        return topic
    for known in _KNOWN:
        if topic.endswith(known):
            return known
    return topic


class ViewerFeed:
    """Feed messages to a :class:`~adm_sim.recording.rerun_log.RunLogger`, one at a time.

    Parameters
    ----------
    viz : RunLogger
        The logger (rerun must be initialised: :func:`~adm_sim.recording.rerun_log.init_rerun`).
    phases : RunPhases or None
        The run/phase bookkeeping of the results; a new one by default.

    Examples
    --------
    >>> feed = ViewerFeed(RunLogger())                # doctest: +SKIP
    >>> feed(topic, msg, t_ns)                         # each message, in time order
    >>> feed.finish()                                  # the generic series, then flush
    """

    def __init__(self, viz, phases: RunPhases | None = None):
        self.viz = viz
        self.phases = phases if phases is not None else RunPhases()
        self.counts: dict[str, int] = defaultdict(int)
        self._deflection = None
        self._accel: dict = defaultdict(lambda: ([], []))  # AccelStamped outside a run: lane -> (t, a)
        #: draws waiting for the phase of a result's run: [(run_id or None, draw)], in arrival order
        self._waiting: list = []
        self._series: dict = defaultdict(lambda: defaultdict(lambda: ([], [])))  # topic -> name -> (t, v)
        handlers = {
            P.TOPIC_BRIDGE_DESC: lambda m, t: self.viz.bridge_description(P.decode(m.data)),
            P.TOPIC_TRAIN_DESC: lambda m, t: self.viz.train_description(P.decode(m.data)),
            P.TOPIC_STATUS: self._status,
            P.TOPIC_ACCEL: self._run_accel,
            P.TOPIC_BEAM: self._beam,
            P.TOPIC_AXLES: self._axles,
            P.TOPIC_RESULT: self._result,
            P.TOPIC_CAL_ITERATION: self._iteration,
            P.TOPIC_CAL_RESULT: lambda m, t: self.viz.calibration_result(P.decode(m.data)),
            P.TOPIC_PROGRESS: lambda m, t: self.viz.flush(),
        }
        self._handlers = {k: v for k, v in handlers.items() if k in P.RUN_LOGGER_TOPICS}

    def __call__(self, topic: str, msg, t_ns: int) -> None:
        self.feed(topic, msg, t_ns)

    def feed(self, topic: str, msg, t_ns: int) -> None:
        """Draw one message of ``topic`` at sim time ``t_ns`` (ns)."""
        self.counts[topic] += 1
        t_s = int(t_ns) * 1e-9
        name = canonical_topic(topic)
        if name in P.RUN_LOGGER_TOPICS:
            handler = self._handlers.get(name)
            if handler is not None:
                handler(msg, t_s)
        else:
            self._generic(topic, msg, t_s)

    # -- the adm-sim topics
    def _status(self, msg, t_s):
        st = P.decode(msg.data)
        if self._waiting and P.is_bridge_start(st):
            self._draw_waiting(force=True)  # a later run starts: the waiting result's record did not come
        self.phases.status(st)
        if self._waiting and P.is_request(st):
            self._draw_waiting()
        self.viz.run_started(st)

    def _run_accel(self, msg, t_s):
        if self.viz.runs:
            self.viz.accel(t_s, msg.accel.linear.z)
        else:
            lane = self._accel[msg.header.frame_id or P.TOPIC_ACCEL]
            lane[0].append(t_s)
            lane[1].append(msg.accel.linear.z)

    def _beam(self, msg, t_s):
        self._deflection = matrix_of(msg)

    def _axles(self, msg, t_s):
        if self._deflection is not None:
            ax = matrix_of(msg)
            self.viz.beam(t_s, self._deflection[0], self._deflection[1], ax[0], ax[1])

    def _result(self, msg, t_s):
        result = matrix_of(msg)
        run_id = self.phases.next_run()
        if self._waiting or (run_id is not None and run_id not in self.phases.by_run):
            self._waiting.append((run_id, lambda: self._draw_result(result)))  # its phase record is still to come
        else:
            self._draw_result(result)

    def _draw_result(self, result):
        run_id, phase = self.phases.result()
        self.viz.run_done(result, phase, run_id)

    def _iteration(self, msg, t_s):
        i, dz_pct, mlm_peak, dim_peak = matrix_of(msg).ravel()[:4]
        draw = lambda: self.viz.iteration(int(i), dz_pct, mlm_peak, dim_peak, self.phases.last)  # noqa: E731
        if self._waiting:
            self._waiting.append((None, draw))  # after the result it follows
        else:
            draw()

    def _draw_waiting(self, force: bool = False) -> None:
        """Draw the waiting results (and what came after them) in order, each once its run's phase
        record is here; with ``force`` all of them (a run without a record: phase ``unknown``)."""
        while self._waiting:
            run_id, draw = self._waiting[0]
            if not force and run_id is not None and run_id not in self.phases.by_run:
                return
            self._waiting.pop(0)
            draw()

    # -- any other topic
    def _generic(self, topic, msg, t_s):
        if hasattr(msg, "accel") and hasattr(msg, "header"):  # AccelStamped
            lane = self._accel[msg.header.frame_id or topic]
            lane[0].append(t_s)
            lane[1].append(msg.accel.linear.z)
        elif hasattr(msg, "status") and hasattr(msg, "header"):  # DiagnosticArray
            rr.set_time(P.SIM_TIME, duration=t_s)
            for st in msg.status:
                level = {0: "INFO", 1: "WARN", 2: "ERROR", 3: "WARN"}.get(_level(st.level), "INFO")
                values = ", ".join(f"{kv.key}={kv.value}" for kv in st.values)
                rr.log(f"{P.ENTITIES['diagnostics']}/{_part(st.name or 'status')}",
                       rr.TextLog(f"{st.message} {values}".strip(), level=level))
        elif hasattr(msg, "position") and hasattr(msg, "name"):  # JointState
            for i, name in enumerate(msg.name):
                for field in ("position", "velocity", "effort"):
                    vals = getattr(msg, field)
                    if i < len(vals):
                        s = self._series[f"{topic}/{field}"][name]
                        s[0].append(t_s)
                        s[1].append(vals[i])
        elif hasattr(msg, "data") and hasattr(msg, "layout"):  # Float64MultiArray
            for i, v in enumerate(msg.data):
                s = self._series[topic][str(i)]
                s[0].append(t_s)
                s[1].append(v)
        elif hasattr(msg, "data") and isinstance(msg.data, float):  # Float64
            s = self._series[topic]["value"]
            s[0].append(t_s)
            s[1].append(msg.data)

    def finish(self) -> None:
        """Flush the logger and send the generic series gathered so far (as columns)."""
        self._draw_waiting(force=True)
        self.viz.flush()
        for lane, (t, a) in self._accel.items():
            rr.send_columns(f"{P.ENTITIES['topics']}/midspan_acceleration_m_s2/{_part(lane)}",
                            indexes=[rr.TimeColumn(P.SIM_TIME, duration=np.asarray(t))],
                            columns=rr.Scalars.columns(scalars=np.asarray(a, dtype=float)))
        for topic, named in self._series.items():
            for name, (t, v) in named.items():
                rr.send_columns(f"{P.ENTITIES['topics']}{topic}/{_part(name)}",
                                indexes=[rr.TimeColumn(P.SIM_TIME, duration=np.asarray(t))],
                                columns=rr.Scalars.columns(scalars=np.asarray(v, dtype=float)))
        self._accel.clear()
        self._series.clear()
