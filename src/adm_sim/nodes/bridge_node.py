"""Bridge node: the modal beam (:class:`adm_sim.integrate.rk4_sides.BridgeSide`) in lockstep with the train node.

Per run (requested by the train node on ``/adm/run/setup``) the node builds the bridge from its
parameters, the shared space grid (:func:`adm_sim.integrate.step_grid.make_grid`) and a ``BridgeSide`` for
all speed lanes, held by a :class:`adm_sim.integrate.lockstep_runs.BridgeHalf` (step, stage,
status, maxima, finite-value check), then

* DIM: for every RK4 stage publishes the rail displacement/velocity under the axles on the bridge
  (``/adm/exchange/rail``) and advances the stage with the train's interaction forces
  (``/adm/exchange/forces``): the calls and their order are those of :func:`adm_sim.integrate.sweep.run_sweep`.
* MLM: asks for a block of steps (``/adm/exchange/rail`` with no axles) and advances it with the
  axle positions and loads of ``/adm/exchange/axle_block`` (modal loads at the stage points).

A solution that stops being finite ends the run at that step: ``/adm/run/status`` ``failed`` with
the run's one-line message and no result (the train node ends its run on that status).

It publishes sim time on ``/clock``, the midspan acceleration/state, the deflected beam, progress,
``/diagnostics`` against the EN 1990 A2.4.4.2.1 deck acceleration limit and, at the end, the
per-lane maxima on ``/adm/run/result``. Topics, layouts and QoS: docs/ros.md, section "Topics".
"""

from __future__ import annotations

import dataclasses
import re
import sys
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import AccelStamped
from rcl_interfaces.msg import ParameterDescriptor
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String

from adm_sim.model.bridge import Bridge
from adm_sim.inputs.bridges import resolve_bridge
from adm_sim import protocol as P
from adm_sim.errors import InputError
from adm_sim.limits import ACC_LIMITS_M_S2, TRACK_TYPES
from adm_sim.model.plausibility import response_warnings
from adm_sim.integrate.lockstep_runs import BridgeHalf
from adm_sim.integrate.mlm_loads import modal_loads_at
from adm_sim.nodes import common as c
from adm_sim.nodes.params import (MONITOR_SAMPLES_PER_PERIOD, bridge_from_params, bridge_plausibility, bridge_specs,
                                   step_options)
from adm_sim.integrate.rk4_sides import BridgeSide
from adm_sim.integrate.run_contract import FAILED, FINISHED, RUNNING
from adm_sim.integrate.step_grid import Grid, make_grid

__all__ = ["TRACK_TYPES", "MONITOR_SAMPLES_PER_PERIOD", "monitor_steps", "bridge_specs", "BridgeNode", "main"]


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


def frame_id(bridge, namespace="/"):
    """Frame id of a bridge's midspan: ``<namespace>/<bridge>/midspan`` without the leading ``/``
    (``b3/B1/midspan`` for the node ``/b3/bridge``; ``B1/midspan`` in the root namespace), the
    bridge's name (else ``bridge``) with characters outside ``[A-Za-z0-9_]`` replaced by ``_``:
    two graphs of one preset under two namespaces have distinct frames."""

    name = re.sub(r"[^A-Za-z0-9_]", "_", bridge.name or "bridge")
    ns = namespace.strip("/")
    return f"{ns}/{name}/midspan" if ns else f"{name}/midspan"


#: The layout labels of the DIM rail state; the forces topic the bridge waits on (relative name).
RAIL_DIMS, TOPIC_FORCES = ("field", "lane", "axle_on"), P.relative(P.TOPIC_FORCES)

#: What a run waits for the recorders' acknowledgement before (flow control).
PAUSE_STEP, PAUSE_END = "step", "end"


@dataclasses.dataclass
class BridgeRunState:
    """The bridge node's active run (``BridgeNode.run``; ``None`` between runs)."""

    id: int
    model: str
    phase: str                 #: :data:`adm_sim.protocol.PHASES`
    train: str
    grid: Grid
    run: BridgeHalf            #: step, stage, status, maxima
    bridge: Bridge
    speeds_kmh: np.ndarray     #: (n_lanes,) km/h
    dz: np.ndarray             #: (n_lanes,) additional damping (fraction)
    lane: int                  #: the monitored lane
    every: int                 #: monitoring decimation (steps)
    beam_every: int            #: beam, state and /clock decimation (steps)
    frame: str                 #: frame id of the samples
    v_mon: float               #: monitored lane's speed (m/s): sim time runs in its time
    x_beam: np.ndarray
    phi_beam: np.ndarray
    limit: float               #: EN 1990 A2.4.4.2.1 limit (m/s^2)
    track: str
    warn: float
    tick: int                  #: progress every this many steps
    t0: float                  #: sim time at the start (s)
    wall0: float
    acked: dict                #: recorder or opted-in client -> messages it acknowledged (flow control)
    disp: np.ndarray | None = None
    peak: tuple = (-1.0, 0)    #: (exact max |a| of the monitored lane so far, its step)
    counts: dict = dataclasses.field(default_factory=dict)  #: topic -> messages published
    sent: int = 0              #: messages published over every counted topic
    paused: str | None = None  #: :data:`PAUSE_STEP` / :data:`PAUSE_END` while waiting for the recorders
    block: list | None = None  #: MLM block in progress: [modal loads, next index, steps]
    ack_wait_since: float | None = None
    pause_since: float = 0.0
    rx_at: float = 0.0         #: when the train's last exchange message came (it waits since then)
    forced: bool = False       #: a pause outlasted half the partner timeout: on to the next exchange
    done_step: int = 0
    accel_msg: AccelStamped | None = None  #: the message of the midspan acceleration samples
    #: acknowledging node -> the topics its count covers, when not every one of
    #: :data:`adm_sim.protocol.SAMPLE_TOPICS` (a client that reads the acceleration alone)
    ack_topics: dict = dataclasses.field(default_factory=dict)

    def sent_to(self, name):
        """Messages published so far on the topics node ``name`` acknowledges."""
        topics = self.ack_topics.get(name)
        return self.sent if topics is None else sum(self.counts[t] for t in topics)


class BridgeNode(c.LockstepNode):
    """Owns the modal beam; see the module docstring."""

    def __init__(self, **kw):
        super().__init__(P.BRIDGE_NODE, **kw)

        self.declare_parameter("bridge", "B1", ParameterDescriptor(
            description="preset (B1..B4, spec 'L=15,n0=8.26,mu=19042,zeta_pct=1.85' or TOML file) giving the "
                        "defaults of the numeric parameters", read_only=True))
        self.preset = resolve_bridge(self.get_parameter("bridge").value)
        specs = bridge_specs(self.preset)
        self._preset_defaults = {s.name: s.default for s in specs}
        self.bridge = self.declare_run_parameters(specs)  # validates the startup values

        R, pub = P.relative, self.create_publisher
        self.pub_rail = pub(Float64MultiArray, R(P.TOPIC_RAIL), c.QOS_EXCHANGE)
        self.rail_writer = c.ExchangeWriter(self.pub_rail)
        self.pub_ready = pub(String, R(P.TOPIC_READY), c.QOS_CONTROL)
        self.pub_result = pub(Float64MultiArray, R(P.TOPIC_RESULT), c.QOS_LATCHED)
        self.pub_status = pub(String, R(P.TOPIC_STATUS), c.QOS_CONTROL)
        self.pub_summary = pub(DiagnosticStatus, R(P.TOPIC_SUMMARY), c.QOS_HISTORY)
        #: monitoring publishers, counted per run (:data:`adm_sim.protocol.SAMPLE_TOPICS`)
        self.pubs = {t: pub(typ, R(t), c.QOS_CONTROL if t == P.TOPIC_DIAGNOSTICS else c.QOS_MONITOR)
                     for t, typ in ((P.TOPIC_CLOCK, Clock), (P.TOPIC_ACCEL, AccelStamped),
                                    (P.TOPIC_STATE, Float64MultiArray), (P.TOPIC_BEAM, Float64MultiArray),
                                    (P.TOPIC_AXLES, Float64MultiArray), (P.TOPIC_PROGRESS, String),
                                    (P.TOPIC_DIAGNOSTICS, DiagnosticArray))}
        #: the run's final /diagnostics, latched (a late joiner gets the last verdict)
        self.pub_diag_final = pub(DiagnosticArray, R(P.TOPIC_DIAGNOSTICS), c.QOS_LATCHED)
        self.pub_desc = pub(String, R(P.TOPIC_BRIDGE_DESC), c.QOS_LATCHED)
        self.create_subscription(String, R(P.TOPIC_SETUP), self._on_setup, c.QOS_CONTROL)
        self.exchange = c.ExchangeLane(self)
        self.exchange_subscriptions = [
            self.exchange.subscribe(Float64MultiArray, R(P.TOPIC_FORCES), self._on_forces, c.QOS_EXCHANGE, raw=True),
            self.exchange.subscribe(Float64MultiArray, R(P.TOPIC_AXLE_BLOCK), self._on_axle_block, c.QOS_EXCHANGE, raw=True),
            # acknowledgements of the recorders, served as fast as the exchange (flow control)
            self.exchange.subscribe(String, R(P.TOPIC_ACK), self._on_ack, c.QOS_CONTROL)]

        self.run = None  # the active run (dict) or None
        self.t_offset_s = 0.0  # sim time continues across runs
        self.partner = c.PartnerWatch(self, P.TRAIN_NODE, P.relative(P.TOPIC_FORCES),
                                      self.get_parameter("partner_timeout_s").value)
        self.publish_description()

    # ------------------------------------------------------------------ parameters
    def build_bridge(self, p):
        """The :class:`Bridge` of the parameter values ``p``: the preset with the changed fields.

        Raises :class:`InputError` naming the parameter, value, unit and range.
        """
        return bridge_from_params(self.preset, p, self._preset_defaults)

    step_options = staticmethod(step_options)

    # the parameter life cycle (c.LockstepNode): validate, lock while a run is active, configure
    def validate(self, values):
        return self.build_bridge(values)

    def configure(self, values):
        self.bridge = self.build_bridge(values)

    def plausibility(self, values):
        bridge_plausibility(self.preset, values, self._preset_defaults)

    def lock_reason(self):
        return f"run {self.run.id} is in progress (step {self.run.run.k} of {self.run.grid.n_steps})"

    def publish_description(self):
        b, p = self.bridge, self.param_values()
        self.pub_desc.publish(c.json_msg(P.bridge_description_record(
            bridge={"span_m": b.span_m, "EJ_Nm2": b.EJ_Nm2, "mass_per_length_kg_m": b.mass_per_length_kg_m,
                    "damping_ratio": b.damping_ratio, "n_modes": b.n_modes, "damping_model": b.damping_model,
                    "name": b.name, "bridge_type": b.bridge_type},
            description=b.describe(), n0_hz=b.n0_hz,
            step={"steps_per_period": p["steps_per_period"], "free_vibration_periods": p["free_vibration_periods"],
                  "ds_m": p["ds_m"]},
            delta_zeta=p["delta_zeta"], delta_zeta_lanes=p["delta_zeta_lanes"],
            track_type=p["track_type"], acc_limit_m_s2=ACC_LIMITS_M_S2[p["track_type"]])))

    # ------------------------------------------------------------------ run set-up
    def _on_setup(self, msg):
        cfg = P.decode(msg.data)
        if self.run is not None:
            raise c.ExchangeError(f"bridge: run {cfg.get('run_id')} requested while run {self.run.id} is active")
        p = self.param_values()
        try:
            bridge = self.build_bridge(p)
            v = np.asarray(cfg["speeds_m_s"], dtype=float)
            grid = make_grid(bridge, float(cfg["train_length_m"]), v, self.step_options(p))
            lanes = c.parse_float_list("delta_zeta_lanes", p["delta_zeta_lanes"], "- (fraction)")
            if lanes.size and lanes.size != grid.n_lanes:
                raise InputError(f"delta_zeta_lanes: {lanes.size} values for {grid.n_lanes} speed lanes; "
                                 f"give one per lane or none")
            dz = lanes if lanes.size else p["delta_zeta"]
            dim = cfg["model"] == "dim"
            side = BridgeSide(bridge, grid, np.asarray(cfg["axle_offsets_m"], dtype=float),
                              np.asarray(cfg["wheel_mass_kg"], dtype=float) if dim else None, dz)
            run = BridgeHalf(cfg["model"], grid, side)
        except (InputError, KeyError, ValueError) as exc:
            self.pub_ready.publish(c.json_msg(P.ready_error(cfg.get("run_id"), str(exc))))
            self._status(cfg.get("run_id"), P.FAILED, message=str(exc))
            self.get_logger().error(f"run {cfg.get('run_id')} rejected: {exc}")
            return
        speeds_kmh = np.asarray(cfg["speeds_kmh"], dtype=float)
        mon = 0 if p["monitor_speed_kmh"] <= 0.0 else int(np.argmin(np.abs(speeds_kmh - p["monitor_speed_kmh"])))
        every, beam_every = monitor_steps(bridge, grid, mon, int(p["monitor_every_steps"]), int(p["beam_every_steps"]))
        xb = np.linspace(0.0, bridge.span_m, int(p["beam_points"]))
        phase = cfg.get("phase") or P.plain_run_phase(cfg["model"], p["delta_zeta"], p["delta_zeta_lanes"])
        recorders = self._recorders()
        self.run = BridgeRunState(
            id=int(cfg["run_id"]), model=cfg["model"], grid=grid, run=run, bridge=bridge, speeds_kmh=speeds_kmh,
            dz=np.broadcast_to(np.asarray(dz, dtype=float), (grid.n_lanes,)).copy(), lane=mon, disp=None,
            every=every, beam_every=beam_every, phase=phase, train=cfg.get("train", ""),
            frame=frame_id(bridge, self.get_namespace()), v_mon=float(grid.speeds_m_s[mon]),
            x_beam=xb, phi_beam=bridge.shapes(xb)[0], limit=ACC_LIMITS_M_S2[p["track_type"]],
            track=p["track_type"], warn=float(p["warn_fraction"]), tick=max(1, grid.n_steps // 100),
            t0=self.t_offset_s, wall0=time.perf_counter(),
            peak=(-1.0, 0),  # (exact max |a| of the monitored lane so far, its step)
            counts={t: 0 for t in P.SAMPLE_TOPICS}, sent=0,
            # flow control: recorder -> messages it acknowledged; what waits for an acknowledgement
            acked={n: 0 for n in recorders}, paused=None, block=None, ack_wait_since=None)
        self.pub_ready.publish(c.json_msg(P.ready_record(
            self.run.id, ds_m=grid.ds_m, n_steps=grid.n_steps, span_m=bridge.span_m, n_lanes=grid.n_lanes,
            t0_s=self.t_offset_s)))
        self._status(self.run.id, P.STARTED, **self._run_info(), **self._monitor_info())
        self.get_logger().info(f"run {self.run.id}: {cfg['model'].upper()} {bridge.describe()}, "
                               f"{grid.n_lanes} lanes, {grid.n_steps} steps of {grid.ds_m * 1000:.2f} mm")
        self._ask_partner()

    # ------------------------------------------------------------------ lockstep
    def _run_info(self):
        r = self.run
        return {"model": r.model, "phase": r.phase, "n_steps": r.grid.n_steps, "n_lanes": r.grid.n_lanes,
                "ds_m": r.grid.ds_m, "bridge": r.bridge.describe(), "train": r.train}

    # ------------------------------------------------------------------ flow control
    def _recorders(self):
        """Names of the nodes that acknowledge what they received (publishers of ``/adm/run/ack``:
        the recorders and the clients that opted into the flow control)."""
        return sorted({i.node_namespace.rstrip("/") + "/" + i.node_name
                       for i in self.get_publishers_info_by_topic(self.resolve_topic_name(P.relative(P.TOPIC_ACK)))})

    def _on_ack(self, msg):
        r = self.run
        ack = P.decode(msg.data)
        if r is None or ack.get("node") not in r.acked:
            return
        topics = ack.get("topics")
        if topics is not None:  # a client that counts some topics only (checked: the known ones)
            r.ack_topics[ack["node"]] = tuple(t for t in topics if t in r.counts)
        r.acked[ack["node"]] = max(r.acked[ack["node"]], int(ack["received"]))
        r.ack_wait_since = None
        self._resume()

    def _ahead(self, pending=0):
        """Whether the run is more than the window ahead of the slowest recorder (with ``pending``
        messages more published)."""
        r = self.run
        if r.forced or not r.acked:
            return False
        if not r.ack_topics:  # recorders only: each counts every topic
            return r.sent + pending - min(r.acked.values()) >= P.FLOW_WINDOW
        return any(r.sent_to(n) + pending - a >= P.FLOW_WINDOW for n, a in r.acked.items())

    def _all_acked(self):
        r = self.run
        if not r.ack_topics:
            return not r.acked or min(r.acked.values()) >= r.sent
        return all(a >= r.sent_to(n) for n, a in r.acked.items())

    def _pause(self, what):
        """Wait for the recorders before ``what`` (``step``: the next exchange; ``end``: the result)."""
        r = self.run
        r.paused = what
        r.pause_since = time.monotonic()
        if r.ack_wait_since is None:
            r.ack_wait_since = time.monotonic()
        if what == PAUSE_STEP:  # the train waits meanwhile: a partner that dies now is still noticed
            topic = P.TOPIC_FORCES if r.model == "dim" else P.TOPIC_AXLE_BLOCK
            self.partner.waiting(f"at step {r.run.k} of run {r.id} (waiting for the recorders)", P.relative(topic), r.rx_at)

    def _resume(self):
        r = self.run
        if r is None or r.paused is None:
            return
        if r.paused == PAUSE_END:
            if self._all_acked():
                r.paused = None
                self._publish_end()
            return
        if self._ahead():
            return
        r.paused = None
        if r.block is not None:
            self._advance_block()
        else:
            self._ask_partner()

    def _check_recorders(self):
        """Between turns: a recorder that left the graph or acknowledged nothing for
        ``partner_timeout_s`` is dropped from the flow control of this run (with a warning)."""
        r = self.run
        if r is None or r.paused is None:
            return
        if r.paused == PAUSE_STEP and time.monotonic() - r.rx_at > 0.5 * self.partner.timeout_s:
            # the train waits too: go on to the next exchange (at most one MLM block beyond the
            # window; the recorders' queues hold it) rather than let the train's partner watch fire
            r.forced, r.paused = True, None
            if r.block is not None:
                self._advance_block()
            else:
                self._ask_partner()
            return
        if r.ack_wait_since is None:
            return
        alive = set(self._recorders())
        stale = time.monotonic() - r.ack_wait_since > 0.5 * self.partner.timeout_s
        for name in list(r.acked):
            if name not in alive or stale:
                self.get_logger().warning(
                    f"run {r.id}: recorder '{name}' {'left' if name not in alive else 'acknowledged nothing for'}"
                    f"{'' if name not in alive else f' {0.5 * self.partner.timeout_s:g} s'}; it is no longer waited for "
                    f"({r.acked[name]} of {r.sent_to(name)} messages acknowledged)")
                del r.acked[name]
        r.ack_wait_since = None if not r.acked else time.monotonic()
        self._resume()

    def _ask_partner(self):
        """Publish the rail state for the current (step, stage) (MLM: a token for the next block)."""
        r, run = self.run, self.run.run
        since = r.rx_at if r.forced else None  # after a forced pause the train's silence began earlier
        r.forced = False
        k, stage = run.k, run.stage
        if r.model == "dim":
            if stage == 0:
                r.disp = run.disp_m
            idx, w, wd = run.rail_state()
            self.rail_writer.publish(r.id, k, stage, (w, wd), RAIL_DIMS, idx)
            self.partner.waiting(("at step {} stage {} of run {}", k, stage, r.id), TOPIC_FORCES, since)
        else:
            self.pub_rail.publish(c.pack(r.id, k, 0, np.zeros((r.grid.n_lanes, 0)), ("lane", "axle_on")))
            self.partner.waiting(f"at step {k} of run {r.id}", P.relative(P.TOPIC_AXLE_BLOCK), since)

    def _on_forces(self, msg):
        r = self.run
        if r is None or r.model != "dim":
            raise c.ExchangeError("bridge: interaction forces received with no DIM run active")
        run = r.run
        run_id, k, stage, idx, G = c.unpack(msg)
        c.check_step("bridge", (run_id, k, stage), (r.id, run.k, run.stage))
        self.partner.clear()
        r.rx_at = time.monotonic()
        run.step(G)  # one RK4 stage with the partner's interaction forces
        if run.status != RUNNING:
            if stage == 0 and run.status != FAILED:
                self._step_done(k, r.disp, run.acc_m_s2)
            self._finish()
        elif stage != 0:
            self._ask_partner()
        elif self._ahead(self._step_messages(k)):
            self._step_done(k, r.disp, run.acc_m_s2)
            self._pause(PAUSE_STEP)
        else:
            # the exchange first: the train computes the next stage while step k's monitoring is
            # published (stage 1's rail state leaves step k's state, acceleration and deflection
            # as they are; the window is checked with step k's messages counted, as before)
            self._ask_partner()
            self._step_done(k, r.disp, run.acc_m_s2)

    def _on_axle_block(self, msg):
        r = self.run
        if r is None or r.model != "mlm":
            raise c.ExchangeError("bridge: axle block received with no MLM run active")
        run = r.run
        run_id, k0, stage, _, block = c.unpack(msg)
        c.check_step("bridge", (run_id, k0, stage), (r.id, run.k, 0))
        self.partner.clear()
        r.rx_at = time.monotonic()
        n = (block.shape[0] - 2) // 2
        r.block = [modal_loads_at(r.bridge, block[:-1], block[-1]), 0, n]
        self._advance_block()

    def _advance_block(self):
        """Step through the MLM block of axle loads; pause when the recorders lag a window behind."""
        r = self.run
        run = r.run
        loads, j, n = r.block
        while j < n:
            k, disp = run.k, run.disp_m
            run.step(loads[2 * j], loads[2 * j + 1], loads[2 * j + 2])
            j += 1
            if run.status == FAILED:
                break
            self._step_done(k, disp, run.acc_m_s2)
            if j < n and self._ahead():
                r.block[1] = j
                self._pause(PAUSE_STEP)
                return
        r.block = None
        if run.status != RUNNING:
            self._finish()
        elif self._ahead():
            self._pause(PAUSE_STEP)
        else:
            self._ask_partner()

    # ------------------------------------------------------------------ outputs
    def _step_done(self, k, disp, acc):
        """Monitoring after step ``k`` produced its midspan displacement and acceleration."""
        r = self.run
        a = abs(float(acc[r.lane]))
        if a > r.peak[0]:
            r.peak = (a, k)
        if k % r.every == 0:
            self._monitor(k, disp, acc)
        if k % r.beam_every == 0:
            self._beam(k, disp, acc)
        if k % r.tick == 0:
            self._progress(k + 1)

    def _step_messages(self, k):
        """How many monitoring messages :meth:`_step_done` publishes for step ``k``."""
        r = self.run
        return (k % r.every == 0) + 4 * (k % r.beam_every == 0) + 2 * (k % r.tick == 0)

    def _monitor_info(self):
        """What the monitoring topics of the run show: for the rerun run-time timeline and the run table."""
        r = self.run
        return {"t0_s": r.t0, "monitor_lane": r.lane, "monitor_speed_kmh": float(r.speeds_kmh[r.lane]),
                "time_lane": r.lane, "clock_speed_kmh": float(r.speeds_kmh[r.lane]),
                "monitor_every_steps": r.every, "beam_every_steps": r.beam_every, "frame_id": r.frame,
                "acc_sign": "z-up (REP 103)"}

    def _sim_time(self, k):
        """Session sim time of step ``k``: the monitored lane's own time since its first axle
        entered the bridge, plus the run's offset (``/clock`` and every stamp)."""
        r = self.run
        return r.t0 + r.grid.front_m(k) / r.v_mon

    def _publish(self, topic, msg, pub=None):
        """Publish a monitoring message and count it (flow control, the run's ``samples``)."""
        r = self.run
        (pub or self.pubs[topic]).publish(msg)
        r.counts[topic] += 1
        r.sent += 1

    def _monitor(self, k, disp, acc):
        r = self.run
        a = r.accel_msg  # one message per run, its stamp and value set per sample (publish copies it)
        if a is None:
            a = r.accel_msg = AccelStamped()
            a.header.frame_id = r.frame
        a.header.stamp = c.to_time_msg(self._sim_time(k))
        a.accel.linear.z = -float(acc[r.lane])  # the core's acceleration is positive downwards
        self._publish(P.TOPIC_ACCEL, a)

    def _beam(self, k, disp, acc):
        """Sim time, every lane's midspan state, the deflected beam and the axles of the monitored lane;
        the arrays carry the step ``k`` before their data (``layout.data_offset`` = 1)."""
        self._publish(P.TOPIC_CLOCK, Clock(clock=c.to_time_msg(self._sim_time(k))))
        self._publish(P.TOPIC_STATE, c.matrix_msg(("lane", "quantity:disp_m,acc_m_s2"), np.column_stack([disp, acc]),
                                                  step=k))
        r, side = self.run, self.run.run.bridge_side
        q = side.q[r.lane]
        w = r.phi_beam @ q
        _, xa = side.axles_on(k, 0)
        wa = r.bridge.shapes(xa)[0] @ q if xa.size else np.zeros(0)
        self._publish(P.TOPIC_BEAM, c.matrix_msg(("row:x_m,w_m", "point"), np.vstack([r.x_beam, w]), step=k))
        self._publish(P.TOPIC_AXLES, c.matrix_msg(("row:x_m,w_m", "axle_on"), np.vstack([xa, wa]), step=k))

    def _progress(self, done, final=False):
        r = self.run
        n = r.grid.n_steps
        if final:  # the run's last progress record carries what the run published, itself included
            r.counts[P.TOPIC_PROGRESS] += 1
            r.sent += 1
            self.pubs[P.TOPIC_PROGRESS].publish(c.json_msg(P.progress_record(
                r.id, r.model, done, n, self._sim_time(min(done, n)), samples=r.counts)))
            return
        self._publish(P.TOPIC_PROGRESS, c.json_msg(P.progress_record(r.id, r.model, done, n,
                                                                     self._sim_time(min(done, n)))))
        self._diagnostics(done, final=False)

    def _level(self, peak):
        """Diagnostic level of a peak: ERROR only for a run of the bridge as specified; a numerical
        trial (:data:`adm_sim.protocol.TRIAL_PHASES`) reports at most WARN."""
        r = self.run
        level = c.acc_level(peak, r.limit, r.warn)
        return min(level, 1) if r.phase in P.TRIAL_PHASES else level

    def _diagnostics(self, done, final):
        r = self.run
        max_acc = r.run.max_acc_m_s2
        i = int(np.argmax(max_acc))
        peak = float(max_acc[i])
        level = self._level(peak)
        trial = r.phase in P.TRIAL_PHASES
        word = {0: "within", 1: "near", 2: "above"}[c.acc_level(peak, r.limit, r.warn)]
        st = DiagnosticStatus(level=bytes([level]), name=P.DIAG_TRIAL_NAME if trial else P.DIAG_NAME,
                              hardware_id=r.bridge.name or "bridge",
                              message=(f"{'numerical trial (' + r.phase + '): ' if trial else ''}"
                                       f"max |a| {peak:.3f} m/s^2 at {r.speeds_kmh[i]:g} km/h {word} the "
                                       f"{r.limit:g} m/s^2 limit ({r.track} track, EN 1990 A2.4.4.2.1)"
                                       f"{'' if final else ' so far'}"))
        vals = {"run_id": r.id, "phase": r.phase, "model": r.model, "max_acc_m_s2": peak,
                "speed_kmh": float(r.speeds_kmh[i]), "limit_m_s2": r.limit, "track_type": r.track,
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
        arr.header.stamp = c.to_time_msg(self._sim_time(min(done, r.grid.n_steps)))
        self._publish(P.TOPIC_DIAGNOSTICS, arr, self.pub_diag_final if final else None)

    def _summary(self, done):
        """The per-passage summary (``/adm/run/summary``, latched): the monitored lane's passage."""
        r, run = self.run, self.run.run
        lane, grid = r.lane, r.grid
        peak, k = r.peak
        peak = float(run.max_acc_m_s2[lane])  # the same value, exactly (every step is folded in both)
        level = self._level(peak)
        i = int(np.argmax(run.max_acc_m_s2))
        vals = P.summary_values(
            run_id=r.id, phase=r.phase, bridge=r.bridge.describe(), train=r.train, model=r.model,
            speed_kmh=float(r.speeds_kmh[lane]), peak_acc_m_s2=peak, t_peak_s=self._sim_time(k),
            run_time_peak_s=self._sim_time(k) - r.t0, step_peak=k, x_front_peak_m=float(grid.front_m(k)),
            limit_m_s2=r.limit, track_type=r.track, level=level, max_acc_all_lanes_m_s2=float(run.max_acc_m_s2[i]),
            speed_at_max_kmh=float(r.speeds_kmh[i]), n_lanes=grid.n_lanes, n_steps=grid.n_steps, steps_done=done,
            t0_s=r.t0, t1_s=self._sim_time(done), frame_id=r.frame, samples=r.counts)
        return DiagnosticStatus(level=bytes([level]), name=P.SUMMARY_NAME, hardware_id=r.bridge.name or "bridge",
                                message=(f"run {r.id} ({r.phase}): peak {peak:.4f} m/s^2 at {vals['speed_kmh']} "
                                         f"km/h, t = {vals['t_peak_s']} s, limit {r.limit:g} m/s^2"),
                                values=[KeyValue(key=k, value=v) for k, v in vals.items()])

    def _status(self, run_id, state, **extra):
        self.pub_status.publish(c.json_msg(P.status_record(P.BRIDGE_NODE, run_id, state, **extra)))

    def _finish(self):
        """End of the run's steps: the last monitoring messages (the final progress record counts
        them), then, once every recorder has acknowledged them all, :meth:`_publish_end`."""
        r, run = self.run, self.run.run
        self.partner.clear()  # the train has sent its last message
        n = r.grid.n_steps
        done = n if run.status == FINISHED else run.k
        r.done_step = done
        self._progress(done)
        self._diagnostics(done, final=True)
        self._publish(P.TOPIC_CLOCK, Clock(clock=c.to_time_msg(self._sim_time(done))))
        self._progress(done, final=True)
        if self._all_acked():
            self._publish_end()
        else:
            self._pause(PAUSE_END)

    def _publish_end(self):
        """The run's summary, result and status ``done`` (or ``failed``, no result), after its data."""
        r, run = self.run, self.run.run
        done = r.done_step
        ok = run.status == FINISHED
        t1 = self._sim_time(done)
        self.pub_summary.publish(self._summary(done))
        if ok:
            res = np.vstack([r.speeds_kmh, run.max_acc_m_s2, run.max_disp_m, r.dz])
            self.pub_result.publish(c.matrix_msg(("quantity:" + ",".join(P.RESULT_ROWS), "lane"), res))
        wall = time.perf_counter() - r.wall0
        # the monitoring of the run again: a client that missed ``started`` can still place its samples
        extra = {}
        if ok:  # the contact check (DIM) and the plausibility warnings of the result, as adm-sim sweep prints them
            if run.contact is not None:
                extra["contact"] = run.contact.to_dict()
            ia, idisp = int(np.argmax(run.max_acc_m_s2)), int(np.argmax(run.max_disp_m))
            extra["warnings"] = response_warnings(r.bridge.span_m, run.max_acc_m_s2[ia], run.max_disp_m[idisp],
                                                  f"run {r.id}: at {r.speeds_kmh[ia]:g} km/h",
                                                  f"run {r.id}: at {r.speeds_kmh[idisp]:g} km/h")
            for w in extra["warnings"] + ([] if run.contact is None or run.contact.first() is None
                                          else [run.contact.message(f"run {r.id}")]):
                self.get_logger().warning(w)
        self._status(r.id, P.DONE if ok else P.FAILED, **self._run_info(), **self._monitor_info(), wall_s=wall,
                     t1_s=t1, message=run.message, samples=dict(r.counts), **extra)
        if ok:
            self.get_logger().info(f"run {r.id} done in {wall:.2f} s: "
                                   f"max |a| {np.max(run.max_acc_m_s2):.4f} m/s^2")
        else:
            self.get_logger().error(f"run {r.id} failed: {run.message}")
        self.t_offset_s = t1
        self.run = None
        self.partner.clear()

    # ------------------------------------------------------------------ supervision
    def watch(self):
        self.partner.check()
        self._check_recorders()

    def report_failure(self, message):
        rid = None if self.run is None else self.run.id
        self._status(rid, P.FAILED, message=message)


def main(args=None):
    return c.run_node(BridgeNode, args=args, name="bridge")


if __name__ == "__main__":
    sys.exit(main())
