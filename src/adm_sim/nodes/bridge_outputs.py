"""The bridge node's monitoring output: sim time, the midspan acceleration and state, the deflected
beam, progress, ``/diagnostics``, the per-passage summary and the result of a run.

:class:`BridgePublishers` holds the node's publishers of these topics; :class:`MonitoringOutput`
publishes one run's messages on them (what, how often, in which frame and sim time), each counted
by the run's :class:`~adm_sim.nodes.flow_control.FlowControl`. Topics, layouts and QoS: docs/ros.md,
section "Topics".
"""

from __future__ import annotations

import math
import re

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import AccelStamped
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String

from adm_sim import protocol as P
from adm_sim.limits import ACC_LIMITS_M_S2
from adm_sim.nodes.messages import json_msg, matrix_msg, to_time_msg
from adm_sim.nodes.params import MONITOR_SAMPLES_PER_PERIOD
from adm_sim.nodes.qos import QOS_HISTORY, QOS_LATCHED, QOS_MONITOR

#: The monitoring topics and their message types (each counted, :data:`adm_sim.protocol.SAMPLE_TOPICS`).
MONITORING_TYPES = ((P.TOPIC_CLOCK, Clock), (P.TOPIC_ACCEL, AccelStamped), (P.TOPIC_STATE, Float64MultiArray),
                    (P.TOPIC_BEAM, Float64MultiArray), (P.TOPIC_AXLES, Float64MultiArray),
                    (P.TOPIC_PROGRESS, String), (P.TOPIC_DIAGNOSTICS, DiagnosticArray))


def monitor_steps(bridge, grid, lane, every, beam_every):
    """Monitoring and beam decimation (steps) of a run; 0 = automatic.

    Samples are taken every ``every`` steps, i.e. uniformly in every lane's time. Automatic:
    ``floor(T_top v / ds / MONITOR_SAMPLES_PER_PERIOD)`` (at least 1), ``T_top`` the period of the
    highest retained mode and ``v`` the monitored lane's speed; the beam every 4 monitoring steps.
    """
    if every <= 0:
        steps_per_top = (2.0 * np.pi / bridge.omega_rad_s[-1]) * grid.speeds_m_s[lane] / grid.ds_m
        every = max(1, int(steps_per_top // MONITOR_SAMPLES_PER_PERIOD))
    if beam_every <= 0:
        beam_every = 4 * every
    return int(every), int(beam_every)


def beam_grid_m(bridge, n_points):
    """The abscissae (m from the left abutment) of the deflected beam on the beam topic, shape (n,).

    One span: ``n_points`` points in equal steps over ``[0, L]`` (``np.linspace``). A continuous deck:
    the ``n_points - 1`` intervals spread over the spans by length (the larger remainders first), at
    least one per span (so a deck of more spans than intervals gets its supports alone), each span's
    points equally spaced from its left support, and every support one of the points (its abscissa
    exactly :attr:`Bridge.supports_m`): the deflection line passes through the piers at zero.
    """
    if not bridge.is_continuous:
        return np.linspace(0.0, bridge.span_m, int(n_points))
    spans, sup = np.asarray(bridge.spans_m, dtype=float), bridge.supports_m
    share = (int(n_points) - 1) * spans / spans.sum()
    parts = np.maximum(1, np.floor(share).astype(int))
    for i in np.argsort(-(share - np.floor(share)), kind="stable"):
        if parts.sum() >= int(n_points) - 1:
            break
        parts[i] += 1
    xs = [sup[i] + spans[i] * np.arange(k) / k for i, k in enumerate(parts)]
    return np.concatenate(xs + [sup[-1:]])


def frame_id(bridge, namespace="/"):
    """Frame id of a bridge's midspan: ``<namespace>/<bridge>/midspan`` without the leading ``/``
    (``b3/B1/midspan`` for the node ``/b3/bridge``; ``B1/midspan`` in the root namespace), the
    bridge's name (else ``bridge``) with characters outside ``[A-Za-z0-9_]`` replaced by ``_``:
    two graphs of one preset under two namespaces have distinct frames."""

    name = re.sub(r"[^A-Za-z0-9_]", "_", bridge.name or "bridge")
    ns = namespace.strip("/")
    return f"{ns}/{name}/midspan" if ns else f"{name}/midspan"


def diagnostic_level(max_acc, limit, warn_fraction):
    """Diagnostic level for a peak deck acceleration: 0 OK, 1 WARN, 2 ERROR (EN 1990 A2.4.4.2.1;
    a non-finite peak is 2)."""
    if not math.isfinite(max_acc) or max_acc > limit:
        return 2
    if max_acc > warn_fraction * limit:
        return 1
    return 0


class BridgePublishers:
    """The bridge node's publishers of the monitoring topics, the summary and the result."""

    def __init__(self, node):
        R, pub = P.relative, node.create_publisher
        self.result = pub(Float64MultiArray, R(P.TOPIC_RESULT), QOS_LATCHED)
        self.summary = pub(DiagnosticStatus, R(P.TOPIC_SUMMARY), QOS_HISTORY)
        #: monitoring publishers, counted per run (:data:`adm_sim.protocol.SAMPLE_TOPICS`): each with a
        #: history of at least the flow-control window, /diagnostics too (its 100 a run can make up most
        #: of a window when the other topics are thinned: with KEEP_LAST 100 a lagging recorder lost them)
        self.topics = {t: pub(typ, R(t), QOS_MONITOR) for t, typ in MONITORING_TYPES}
        #: the run's final /diagnostics, latched (a late joiner gets the last verdict)
        self.diag_final = pub(DiagnosticArray, R(P.TOPIC_DIAGNOSTICS), QOS_LATCHED)


class MonitoringOutput:
    """The monitoring messages of one run (``run``, a :class:`~adm_sim.nodes.bridge_node.BridgeRunState`).

    Parameters
    ----------
    run : BridgeRunState
        The run: its id, model, phase, grid, bridge, speeds and :class:`BridgeHalf` (maxima, modal state).
    pubs : BridgePublishers or None
        Where to publish (``None``: :meth:`publish` is replaced, e.g. to count in a test).
    flow : FlowControl
        Counts every message published on a counted topic.
    values : dict
        The bridge node's parameter values (``monitor_speed_kmh``, ``monitor_every_steps``,
        ``beam_every_steps``, ``beam_points``, ``track_type``, ``warn_fraction``).
    t0_s : float
        Session sim time at the run's start (s): sim time continues across runs.
    namespace : str
        The node's namespace (the frame id, :func:`frame_id`).
    """

    def __init__(self, run, pubs, flow, values, *, t0_s, namespace="/"):
        p, bridge, grid = values, run.bridge, run.grid
        self.run, self.pubs, self.flow = run, pubs, flow
        speeds = run.speeds_kmh
        self.lane = 0 if p["monitor_speed_kmh"] <= 0.0 else int(np.argmin(np.abs(speeds - p["monitor_speed_kmh"])))
        self.every, self.beam_every = monitor_steps(bridge, grid, self.lane, int(p["monitor_every_steps"]),
                                                    int(p["beam_every_steps"]))
        self.tick = max(1, grid.n_steps // 100)  #: progress every this many steps
        self.frame = frame_id(bridge, namespace)
        self.v_mon = float(grid.speeds_m_s[self.lane])  #: the monitored lane's speed (m/s): sim time runs in its time
        self.t0 = t0_s
        self.x_beam = beam_grid_m(bridge, int(p["beam_points"]))
        self.phi_beam = bridge.shapes(self.x_beam)[0]
        self.track = p["track_type"]
        self.limit = ACC_LIMITS_M_S2[self.track]  #: EN 1990 A2.4.4.2.1 limit (m/s^2)
        self.warn = float(p["warn_fraction"])
        self.peak = (-1.0, 0)  #: (exact max |a| of the monitored lane so far, its step)
        self.accel_msg = None  #: the message of the midspan acceleration samples (its stamp and value set per sample)

    # ------------------------------------------------------------------ per step
    def step_done(self, k, disp, acc):
        """Monitoring after step ``k`` produced its midspan displacement and acceleration."""
        a = abs(float(acc[self.lane]))
        if a > self.peak[0]:
            self.peak = (a, k)
        if k % self.every == 0:
            self._accel(k, acc)
        if k % self.beam_every == 0:
            self._beam(k, disp, acc)
        if k % self.tick == 0:
            self.progress(k + 1)

    def step_messages(self, k):
        """How many monitoring messages :meth:`step_done` publishes for step ``k``."""
        return (k % self.every == 0) + 4 * (k % self.beam_every == 0) + 2 * (k % self.tick == 0)

    def sim_time(self, k):
        """Session sim time of step ``k``: the monitored lane's own time since its first axle
        entered the bridge, plus the run's offset (``/clock`` and every stamp)."""
        return self.t0 + self.run.grid.front_m(k) / self.v_mon

    def info(self):
        """What the monitoring topics of the run show: for the rerun run-time timeline and the run table."""
        v = float(self.run.speeds_kmh[self.lane])
        return {"t0_s": self.t0, "monitor_lane": self.lane, "monitor_speed_kmh": v, "time_lane": self.lane,
                "clock_speed_kmh": v, "monitor_every_steps": self.every, "beam_every_steps": self.beam_every,
                "frame_id": self.frame, "acc_sign": "z-up (REP 103)"}

    def publish(self, topic, msg, pub=None):
        """Publish a monitoring message and count it (flow control, the run's ``samples``)."""
        (pub or self.pubs.topics[topic]).publish(msg)
        self.flow.count(topic)

    def _accel(self, k, acc):
        a = self.accel_msg  # one message per run, its stamp and value set per sample (publish copies it)
        if a is None:
            a = self.accel_msg = AccelStamped()
            a.header.frame_id = self.frame
        a.header.stamp = to_time_msg(self.sim_time(k))
        a.accel.linear.z = -float(acc[self.lane])  # the core's acceleration is positive downwards
        self.publish(P.TOPIC_ACCEL, a)

    def _beam(self, k, disp, acc):
        """Sim time, every lane's midspan state, the deflected beam and the axles of the monitored lane;
        the arrays carry the step ``k`` before their data (``layout.data_offset`` = 1)."""
        self.publish(P.TOPIC_CLOCK, Clock(clock=to_time_msg(self.sim_time(k))))
        self.publish(P.TOPIC_STATE, matrix_msg(("lane", "quantity:disp_m,acc_m_s2"), np.column_stack([disp, acc]),
                                               step=k))
        side = self.run.run.bridge_side
        q = side.q[self.lane]
        w = self.phi_beam @ q
        _, xa = side.axles_on(k, 0)
        wa = self.run.bridge.shapes(xa)[0] @ q if xa.size else np.zeros(0)
        self.publish(P.TOPIC_BEAM, matrix_msg(("row:x_m,w_m", "point"), np.vstack([self.x_beam, w]), step=k))
        self.publish(P.TOPIC_AXLES, matrix_msg(("row:x_m,w_m", "axle_on"), np.vstack([xa, wa]), step=k))

    def progress(self, done, final=False):
        """The progress record after ``done`` steps and, unless ``final``, the diagnostics so far;
        the run's ``final`` record carries what the run published, itself included."""
        r, n = self.run, self.run.grid.n_steps
        t = self.sim_time(min(done, n))
        if final:
            self.flow.count(P.TOPIC_PROGRESS)
            self.pubs.topics[P.TOPIC_PROGRESS].publish(json_msg(P.progress_record(
                r.id, r.model, done, n, t, samples=self.flow.counts)))
            return
        self.publish(P.TOPIC_PROGRESS, json_msg(P.progress_record(r.id, r.model, done, n, t)))
        self.diagnostics(done, final=False)

    # ------------------------------------------------------------------ verdicts
    def level(self, peak):
        """Diagnostic level of a peak: ERROR only for a run of the bridge as specified; a numerical
        trial (:data:`adm_sim.protocol.TRIAL_PHASES`) reports at most WARN."""
        level = diagnostic_level(peak, self.limit, self.warn)
        return min(level, 1) if self.run.phase in P.TRIAL_PHASES else level

    def diagnostics(self, done, final):
        """``/diagnostics`` after ``done`` steps: the largest peak of every lane against the limit
        (``final``: the run's verdict, also latched)."""
        r = self.run
        max_acc = r.run.max_acc_m_s2
        i = int(np.argmax(max_acc))
        peak = float(max_acc[i])
        level = self.level(peak)
        trial = r.phase in P.TRIAL_PHASES
        word = {0: "within", 1: "near", 2: "above"}[diagnostic_level(peak, self.limit, self.warn)]
        st = DiagnosticStatus(level=bytes([level]), name=P.DIAG_TRIAL_NAME if trial else P.DIAG_NAME,
                              hardware_id=r.bridge.name or "bridge",
                              message=(f"{'numerical trial (' + r.phase + '): ' if trial else ''}"
                                       f"max |a| {peak:.3f} m/s^2 at {r.speeds_kmh[i]:g} km/h {word} the "
                                       f"{self.limit:g} m/s^2 limit ({self.track} track, EN 1990 A2.4.4.2.1)"
                                       f"{'' if final else ' so far'}"))
        vals = {"run_id": r.id, "phase": r.phase, "model": r.model, "max_acc_m_s2": peak,
                "speed_kmh": float(r.speeds_kmh[i]), "limit_m_s2": self.limit, "track_type": self.track,
                "step": done, "n_steps": r.grid.n_steps, "final": final}
        contact = r.run.contact  # the DIM's own assumption: every wheel stays on the rail
        if contact is not None:
            vals["contact"] = contact.status
            lost = contact.message("contact_lost")
            if lost is not None:
                st.message += f"; {lost}"
                st.level = bytes([max(level, 1)])
        st.values = [KeyValue(key=k, value=str(v)) for k, v in vals.items()]
        arr = DiagnosticArray(status=[st])
        arr.header.stamp = to_time_msg(self.sim_time(min(done, r.grid.n_steps)))
        self.publish(P.TOPIC_DIAGNOSTICS, arr, self.pubs.diag_final if final else None)

    def finish(self, done):
        """The run's last monitoring messages after ``done`` steps: progress, the final diagnostics,
        sim time and the final progress record (which counts them all)."""
        self.progress(done)
        self.diagnostics(done, final=True)
        self.publish(P.TOPIC_CLOCK, Clock(clock=to_time_msg(self.sim_time(done))))
        self.progress(done, final=True)

    def summary(self, done):
        """The per-passage summary (``/adm/run/summary``, latched): the monitored lane's passage."""
        r, run = self.run, self.run.run
        lane, grid = self.lane, r.grid
        _, k = self.peak
        peak = float(run.max_acc_m_s2[lane])  # the same value, exactly (every step is folded in both)
        level = self.level(peak)
        i = int(np.argmax(run.max_acc_m_s2))
        vals = P.summary_values(
            run_id=r.id, phase=r.phase, bridge=r.bridge.describe(), train=r.train, model=r.model,
            speed_kmh=float(r.speeds_kmh[lane]), peak_acc_m_s2=peak, t_peak_s=self.sim_time(k),
            run_time_peak_s=self.sim_time(k) - self.t0, step_peak=k, x_front_peak_m=float(grid.front_m(k)),
            limit_m_s2=self.limit, track_type=self.track, level=level,
            max_acc_all_lanes_m_s2=float(run.max_acc_m_s2[i]), speed_at_max_kmh=float(r.speeds_kmh[i]),
            n_lanes=grid.n_lanes, n_steps=grid.n_steps, steps_done=done, t0_s=self.t0, t1_s=self.sim_time(done),
            frame_id=self.frame, samples=self.flow.counts)
        return DiagnosticStatus(level=bytes([level]), name=P.SUMMARY_NAME, hardware_id=r.bridge.name or "bridge",
                                message=(f"run {r.id} ({r.phase}): peak {peak:.4f} m/s^2 at {vals['speed_kmh']} "
                                         f"km/h, t = {vals['t_peak_s']} s, limit {self.limit:g} m/s^2"),
                                values=[KeyValue(key=k, value=v) for k, v in vals.items()])

    def end(self, done, ok):
        """The run's summary and, when it finished (``ok``), its result: per lane the speed, the
        maxima and the additional damping (:data:`adm_sim.protocol.RESULT_ROWS`)."""
        r, run = self.run, self.run.run
        self.pubs.summary.publish(self.summary(done))
        if ok:
            res = np.vstack([r.speeds_kmh, run.max_acc_m_s2, run.max_disp_m, r.dz])
            self.pubs.result.publish(matrix_msg(("quantity:" + ",".join(P.RESULT_ROWS), "lane"), res))
