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

The node composes three collaborators: the run's state (:class:`BridgeRunState`), its
monitoring output (:class:`adm_sim.nodes.bridge_outputs.MonitoringOutput`) and its flow control
(:class:`adm_sim.nodes.flow_control.FlowControl`); its callbacks take a message, advance the
run and hand the outputs on.
"""

from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from std_msgs.msg import Float64MultiArray, String

from adm_sim import protocol as P
from adm_sim.errors import InputError
from adm_sim.integrate.lockstep_runs import BridgeHalf
from adm_sim.integrate.mlm_loads import modal_loads_at
from adm_sim.integrate.rk4_sides import BridgeSide
from adm_sim.integrate.run_contract import FAILED, FINISHED, RUNNING
from adm_sim.integrate.step_grid import Grid, make_grid
from adm_sim.limits import ACC_LIMITS_M_S2, TRACK_TYPES
from adm_sim.model.bridge import Bridge
from adm_sim.model.plausibility import response_warnings
from adm_sim.nodes import common as c
from adm_sim.nodes.bridge_outputs import BridgePublishers, MonitoringOutput, frame_id, monitor_steps
from adm_sim.nodes.flow_client import named_publishers
from adm_sim.nodes.flow_control import PAUSE_END, PAUSE_STEP, FlowControl
from adm_sim.nodes.params import (MONITOR_SAMPLES_PER_PERIOD, bridge_from_params, bridge_plausibility,
                                   bridge_preset, bridge_specs, step_options)

__all__ = ["TRACK_TYPES", "MONITOR_SAMPLES_PER_PERIOD", "monitor_steps", "frame_id", "bridge_specs", "BridgeNode",
           "BridgeRunState", "main"]

#: The layout labels of the DIM rail state; the forces topic the bridge waits on (relative name).
RAIL_DIMS, TOPIC_FORCES = ("field", "lane", "axle_on"), P.relative(P.TOPIC_FORCES)


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
    flow: FlowControl          #: the recorders' and opted-in clients' acknowledgements
    wall0: float = 0.0         #: ``time.perf_counter()`` at the set-up
    monitor: MonitoringOutput | None = None  #: what the run publishes besides the exchange
    disp: np.ndarray | None = None  #: (n_lanes,) midspan displacement at the step's start (DIM)
    block: list | None = None  #: MLM block in progress: [modal loads, next index, steps]
    rx_at: float = 0.0         #: when the train's last exchange message came (it waits since then)
    done_step: int = 0         #: the steps done when the run ended

    def info(self):
        """The run's identity for its status records."""
        return {"model": self.model, "phase": self.phase, "n_steps": self.grid.n_steps, "n_lanes": self.grid.n_lanes,
                "ds_m": self.grid.ds_m, "bridge": self.bridge.describe(), "train": self.train}


class BridgeNode(c.LockstepNode):
    """Owns the modal beam; see the module docstring."""

    def __init__(self, **kw):
        super().__init__(P.BRIDGE_NODE, **kw)

        self.declare_parameter("bridge", "B1", ParameterDescriptor(
            description="preset (B1..B4, spec 'L=15,n0=8.26,mu=19042,zeta_pct=1.85' or "
                        "'spans=15/15,EJ=2.7e10,mu=19042,zeta_pct=1.5', or TOML file) giving the defaults of the "
                        "numeric parameters (a continuous deck: spans_m, span_EJ_Nm2, span_mu_kg_m)", read_only=True))
        self.preset = bridge_preset(self.get_parameter("bridge").value)
        specs = bridge_specs(self.preset)
        self._preset_defaults = {s.name: s.default for s in specs}
        self.bridge = self.declare_run_parameters(specs)  # validates the startup values

        R, pub = P.relative, self.create_publisher
        self.pub_rail = pub(Float64MultiArray, R(P.TOPIC_RAIL), c.QOS_EXCHANGE)
        self.rail_writer = c.ExchangeWriter(self.pub_rail)
        self.pub_ready = pub(String, R(P.TOPIC_READY), c.QOS_CONTROL)
        self.pub_status = pub(String, R(P.TOPIC_STATUS), c.QOS_CONTROL)
        self.outputs = BridgePublishers(self)
        self.pub_desc = pub(String, R(P.TOPIC_BRIDGE_DESC), c.QOS_LATCHED)
        self.create_subscription(String, R(P.TOPIC_SETUP), self._on_setup, c.QOS_CONTROL)
        self.exchange = c.ExchangeLane(self)
        self.exchange_subscriptions = [
            self.exchange.subscribe(Float64MultiArray, R(P.TOPIC_FORCES), self._on_forces, c.QOS_EXCHANGE, raw=True),
            self.exchange.subscribe(Float64MultiArray, R(P.TOPIC_AXLE_BLOCK), self._on_axle_block, c.QOS_EXCHANGE, raw=True),
            # acknowledgements of the recorders, served as fast as the exchange (flow control)
            self.exchange.subscribe(String, R(P.TOPIC_ACK), self._on_ack, c.QOS_CONTROL)]

        self.run = None  # the active run (BridgeRunState) or None
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
                    "name": b.name, "bridge_type": b.bridge_type, "spans_m": list(b.spans_m),
                    "span_EJ_Nm2": list(b.span_EJ_Nm2), "span_mu_kg_m": list(b.span_mu_kg_m)},
            description=b.describe(), n0_hz=b.n0_hz, supports_m=b.supports_m.tolist(),
            frequencies_hz=b.frequencies_hz.tolist(), modal_masses_kg=b.modal_mass_kg.tolist(),
            response_m=p["response_m"], midspan_m=b.midspan_m,
            step={"steps_per_period": p["steps_per_period"], "free_vibration_periods": p["free_vibration_periods"],
                  "ds_m": p["ds_m"]},
            delta_zeta=p["delta_zeta"], delta_zeta_lanes=p["delta_zeta_lanes"],
            track_type=p["track_type"], acc_limit_m_s2=ACC_LIMITS_M_S2[p["track_type"]])))

    # ------------------------------------------------------------------ run set-up
    def _on_setup(self, msg):
        cfg = P.decode(msg.data)
        if self.run is not None:
            raise c.ExchangeError(f"bridge: run {cfg.get('run_id')} requested while run {self.run.id} is active")
        try:
            self.run = self._new_run(cfg, self.param_values())
        except (InputError, KeyError, ValueError) as exc:
            self.pub_ready.publish(c.json_msg(P.ready_error(cfg.get("run_id"), str(exc))))
            self._status(cfg.get("run_id"), P.FAILED, message=str(exc))
            self.get_logger().error(f"run {cfg.get('run_id')} rejected: {exc}")
            return
        r, grid = self.run, self.run.grid
        self.pub_ready.publish(c.json_msg(P.ready_record(
            r.id, ds_m=grid.ds_m, n_steps=grid.n_steps, span_m=r.bridge.span_m, n_lanes=grid.n_lanes,
            t0_s=self.t_offset_s)))
        self._status(r.id, P.STARTED, **r.info(), **r.monitor.info(), flow_nodes=sorted(r.flow.acked))
        self.get_logger().info(f"run {r.id}: {r.model.upper()} {r.bridge.describe()}, "
                               f"{grid.n_lanes} lanes, {grid.n_steps} steps of {grid.ds_m * 1000:.2f} mm")
        self._ask_partner()

    def _new_run(self, cfg, p):
        """The :class:`BridgeRunState` of the set-up record ``cfg`` with the parameter values ``p``;
        raises :class:`InputError`, ``KeyError`` or ``ValueError`` for a set-up it cannot run."""
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
                          np.asarray(cfg["wheel_mass_kg"], dtype=float) if dim else None, dz,
                          response_m=p["response_m"] or None)
        half = BridgeHalf(cfg["model"], grid, side)
        phase = cfg.get("phase") or P.plain_run_phase(cfg["model"], p["delta_zeta"], p["delta_zeta_lanes"])
        r = BridgeRunState(
            id=int(cfg["run_id"]), model=cfg["model"], phase=phase, train=cfg.get("train", ""), grid=grid, run=half,
            bridge=bridge, speeds_kmh=np.asarray(cfg["speeds_kmh"], dtype=float),
            dz=np.broadcast_to(np.asarray(dz, dtype=float), (grid.n_lanes,)).copy(),
            flow=FlowControl(self._recorders()), wall0=time.perf_counter())
        r.monitor = MonitoringOutput(r, self.outputs, r.flow, p, t0_s=self.t_offset_s, namespace=self.get_namespace())
        return r

    # ------------------------------------------------------------------ lockstep
    def _ask_partner(self):
        """Publish the rail state for the current (step, stage) (MLM: a token for the next block)."""
        r, run = self.run, self.run.run
        since = r.rx_at if r.flow.forced else None  # after a forced pause the train's silence began earlier
        r.flow.forced = False
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
        run, out = r.run, r.monitor
        run_id, k, stage, idx, G = c.unpack(msg)
        c.check_step("bridge", (run_id, k, stage), (r.id, run.k, run.stage))
        self._received()
        run.step(G)  # one RK4 stage with the partner's interaction forces
        if run.status != RUNNING:
            if stage == 0 and run.status != FAILED:
                out.step_done(k, r.disp, run.acc_m_s2)
            self._finish()
        elif stage != 0:
            self._ask_partner()
        elif r.flow.ahead(out.step_messages(k)):
            out.step_done(k, r.disp, run.acc_m_s2)
            self._pause(PAUSE_STEP)
        else:
            # the exchange first: the train computes the next stage while step k's monitoring is
            # published (stage 1's rail state leaves step k's state, acceleration and deflection
            # as they are; the window is checked with step k's messages counted, as before)
            self._ask_partner()
            out.step_done(k, r.disp, run.acc_m_s2)

    def _on_axle_block(self, msg):
        r = self.run
        if r is None or r.model != "mlm":
            raise c.ExchangeError("bridge: axle block received with no MLM run active")
        run_id, k0, stage, _, block = c.unpack(msg)
        c.check_step("bridge", (run_id, k0, stage), (r.id, r.run.k, 0))
        self._received()
        n = (block.shape[0] - 2) // 2
        r.block = [modal_loads_at(r.bridge, block[:-1], block[-1]), 0, n]
        self._advance_block()

    def _received(self):
        """The train's exchange message came: it waits from now on."""
        self.partner.clear()
        self.run.rx_at = time.monotonic()

    def _advance_block(self):
        """Step through the MLM block of axle loads; pause when the recorders lag a window behind."""
        r = self.run
        run, flow = r.run, r.flow
        loads, j, n = r.block
        while j < n:
            k, disp = run.k, run.disp_m
            run.step(loads[2 * j], loads[2 * j + 1], loads[2 * j + 2])
            j += 1
            if run.status == FAILED:
                break
            r.monitor.step_done(k, disp, run.acc_m_s2)
            if j < n and flow.ahead():
                r.block[1] = j
                self._pause(PAUSE_STEP)
                return
        r.block = None
        if run.status != RUNNING:
            self._finish()
        elif flow.ahead():
            self._pause(PAUSE_STEP)
        else:
            self._ask_partner()

    def _go_on(self):
        """The next exchange: the rest of the MLM block in progress, else the partner's next message."""
        if self.run.block is not None:
            self._advance_block()
        else:
            self._ask_partner()

    # ------------------------------------------------------------------ flow control
    def _recorders(self):
        """Names of the nodes that acknowledge what they received (publishers of ``/adm/run/ack``:
        the recorders and the clients that opted into the flow control), those known by name only: an
        acknowledgement carries its node's real name, so one not yet named would be waited for in vain."""
        return named_publishers(self.get_publishers_info_by_topic(self.resolve_topic_name(P.relative(P.TOPIC_ACK))))

    def _on_ack(self, msg):
        r = self.run
        if r is None:
            return
        ack, now = P.decode(msg.data), time.monotonic()
        if r.flow.take(ack, now):
            self._resume()
        elif r.flow.join(ack, r.id, now):  # a client the bridge's view of the graph showed too late
            self.get_logger().info(f"run {r.id}: '{ack['node']}' joined the flow control at its acknowledgement "
                                   f"of {r.flow.acked[ack['node']]} of {r.flow.sent} messages")

    def _pause(self, what):
        """Wait for the recorders before ``what`` (``step``: the next exchange; ``end``: the result)."""
        r = self.run
        r.flow.pause(what, time.monotonic())
        if what == PAUSE_STEP:  # the train waits meanwhile: a partner that dies now is still noticed
            topic = P.TOPIC_FORCES if r.model == "dim" else P.TOPIC_AXLE_BLOCK
            self.partner.waiting(f"at step {r.run.k} of run {r.id} (waiting for the recorders)", P.relative(topic), r.rx_at)

    def _resume(self):
        r = self.run
        if r is None or r.flow.paused is None:
            return
        flow = r.flow
        if flow.paused == PAUSE_END:
            if flow.all_acked():
                flow.unpause()
                self._publish_end()
            return
        if flow.ahead():
            return
        flow.unpause()
        self._go_on()

    def _check_recorders(self):
        """Between turns: a recorder that left the graph or acknowledged nothing for
        ``partner_timeout_s`` is dropped from the flow control of this run (with a warning)."""
        r = self.run
        if r is None or r.flow.paused is None:
            return
        flow, patience_s = r.flow, 0.5 * self.partner.timeout_s
        if flow.paused == PAUSE_STEP and time.monotonic() - r.rx_at > patience_s:
            # the train waits too: go on to the next exchange (at most one MLM block beyond the
            # window; the recorders' queues hold it) rather than let the train's partner watch fire
            flow.forced = True
            flow.unpause()
            self._go_on()
            return
        if flow.wait_since is None:
            return
        for name, left, acked, sent in flow.drop(set(self._recorders()), patience_s, time.monotonic()):
            self.get_logger().warning(
                f"run {r.id}: recorder '{name}' {'left' if left else 'acknowledged nothing for'}"
                f"{'' if left else f' {patience_s:g} s'}; it is no longer waited for "
                f"({acked} of {sent} messages acknowledged)")
        self._resume()

    # ------------------------------------------------------------------ the run's end
    def _status(self, run_id, state, **extra):
        self.pub_status.publish(c.json_msg(P.status_record(P.BRIDGE_NODE, run_id, state, **extra)))

    def _finish(self):
        """End of the run's steps: the last monitoring messages (the final progress record counts
        them), then, once every recorder has acknowledged them all, :meth:`_publish_end`."""
        r, run = self.run, self.run.run
        self.partner.clear()  # the train has sent its last message
        r.done_step = r.grid.n_steps if run.status == FINISHED else run.k
        r.monitor.finish(r.done_step)
        if r.flow.all_acked():
            self._publish_end()
        else:
            self._pause(PAUSE_END)

    def _publish_end(self):
        """The run's summary, result and status ``done`` (or ``failed``, no result), after its data."""
        r, run = self.run, self.run.run
        ok = run.status == FINISHED
        t1 = r.monitor.sim_time(r.done_step)
        r.monitor.end(r.done_step, ok)
        wall = time.perf_counter() - r.wall0
        # the monitoring of the run again: a client that missed ``started`` can still place its samples
        extra = self._result_checks(r) if ok else {}
        self._status(r.id, P.DONE if ok else P.FAILED, **r.info(), **r.monitor.info(), wall_s=wall,
                     t1_s=t1, message=run.message, samples=dict(r.flow.counts), **extra)
        if ok:
            self.get_logger().info(f"run {r.id} done in {wall:.2f} s: "
                                   f"max |a| {np.max(run.max_acc_m_s2):.4f} m/s^2")
        else:
            self.get_logger().error(f"run {r.id} failed: {run.message}")
        self.t_offset_s = t1
        self.run = None
        self.partner.clear()

    def _result_checks(self, r):
        """The contact check (DIM) and the plausibility warnings of a finished run's result, as
        ``adm-sim sweep`` prints them, each also logged as a warning."""
        run, extra = r.run, {}
        if run.contact is not None:
            extra["contact"] = run.contact.to_dict()
        ia, idisp = int(np.argmax(run.max_acc_m_s2)), int(np.argmax(run.max_disp_m))
        extra["warnings"] = response_warnings(r.bridge.span_m, run.max_acc_m_s2[ia], run.max_disp_m[idisp],
                                              f"run {r.id}: at {r.speeds_kmh[ia]:g} km/h",
                                              f"run {r.id}: at {r.speeds_kmh[idisp]:g} km/h")
        for w in extra["warnings"] + ([] if run.contact is None or run.contact.first() is None
                                      else [run.contact.message(f"run {r.id}")]):
            self.get_logger().warning(w)
        return extra

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
