"""Train node: the vehicles (:class:`adm_sim.integrate.rk4_sides.TrainSide`) in lockstep with the bridge node.

A run starts with the ``~/start_run`` service (std_srvs/Trigger): once the bridge node is
connected and its description has arrived (before that: "retry"), the node validates its
parameters and the train on the bridge's spans (a continuous deck's span shorter than the train's
longest axle group is refused, as ``adm-sim sweep`` refuses it), publishes the run set-up (``/adm/run/setup``: speeds, axle offsets, loads and wheelset
masses) and waits for the bridge's grid (``/adm/run/ready``). Then

* DIM: for every RK4 stage it answers the rail state under its axles (``/adm/exchange/rail``)
  with the interaction forces ``G = F - F_k1 - F_c1`` (``/adm/exchange/forces``);
* MLM: it answers each request of the bridge with the axle positions at the half-step points of
  a block of ``mlm_block_steps`` steps and the axle loads (``/adm/exchange/axle_block``); the
  MLM needs no feedback from the bridge.

Step and stage are kept by a :class:`adm_sim.integrate.lockstep_runs.TrainHalf`. A run that
the bridge reports ``failed`` on ``/adm/run/status`` (e.g. a solution that is not finite) ends
here too.
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import Trigger

from adm_sim import protocol as P
from adm_sim.errors import InputError
from adm_sim.inputs.track_profile import parse_irregularity
from adm_sim.nodes import common as c
from adm_sim.integrate.lockstep_runs import TrainHalf
from adm_sim.integrate.mlm_loads import half_step_positions
from adm_sim.nodes.params import TRAIN_SPECS, check_run_phase, validate_train  # noqa: F401 (re-exported)
from adm_sim.integrate.rk4_sides import TrainSide
from adm_sim.integrate.run_contract import FINISHED
from adm_sim.integrate.step_grid import Grid, speeds_to_m_s
from adm_sim.integrate.sweep import check_span_lengths
from adm_sim.model.trains import Train

#: The layout labels of the DIM interaction forces; the rail topic the train waits on (relative name).
FORCES_DIMS, TOPIC_RAIL = ("lane", "axle_on"), P.relative(P.TOPIC_RAIL)


@dataclasses.dataclass
class TrainRunState:
    """The train node's active run (``TrainNode.run``; ``None`` between runs)."""

    id: int
    model: str
    phase: str                    #: :data:`adm_sim.protocol.PHASES`
    train: Train
    v: np.ndarray                 #: (n_lanes,) speeds, m/s
    block: int                    #: MLM steps per axle block
    irregularity: str = ""        #: track profile spec (:func:`adm_sim.inputs.track_profile.parse_irregularity`)
    grid: Grid | None = None      #: from the bridge's /adm/run/ready
    run: TrainHalf | None = None  #: step, stage, status


class TrainNode(c.LockstepNode):
    """Owns the vehicles; see the module docstring."""

    def __init__(self, **kw):
        super().__init__(P.TRAIN_NODE, **kw)
        self.train = self.declare_run_parameters(TRAIN_SPECS)[0]  # validates the startup values
        R = P.relative
        self.pub_setup = self.create_publisher(String, R(P.TOPIC_SETUP), c.QOS_CONTROL)
        self.pub_forces = self.create_publisher(Float64MultiArray, R(P.TOPIC_FORCES), c.QOS_EXCHANGE)
        self.forces_writer = c.ExchangeWriter(self.pub_forces)
        self.pub_block = self.create_publisher(Float64MultiArray, R(P.TOPIC_AXLE_BLOCK), c.QOS_EXCHANGE)
        self.pub_status = self.create_publisher(String, R(P.TOPIC_STATUS), c.QOS_CONTROL)
        self.pub_desc = self.create_publisher(String, R(P.TOPIC_TRAIN_DESC), c.QOS_LATCHED)
        self.create_subscription(String, R(P.TOPIC_READY), self._on_ready, c.QOS_CONTROL)
        self.create_subscription(String, R(P.TOPIC_STATUS), self._on_status, c.QOS_CONTROL)
        self.exchange = c.ExchangeLane(self)
        self.exchange_subscriptions = [
            self.exchange.subscribe(Float64MultiArray, R(P.TOPIC_RAIL), self._on_rail, c.QOS_EXCHANGE, raw=True)]
        self.create_service(Trigger, "~/start_run", self._on_start)
        self._bridge_desc = None
        self.create_subscription(String, R(P.TOPIC_BRIDGE_DESC), self._on_bridge_description, c.QOS_LATCHED)
        self.run = None
        self._pending = []  # rail messages that arrived before /adm/run/ready
        self.next_run_id = 1
        self.partner = c.PartnerWatch(self, P.BRIDGE_NODE, R(P.TOPIC_RAIL), self.get_parameter("partner_timeout_s").value)
        self.publish_description()

    # ------------------------------------------------------------------ parameters
    _validate = staticmethod(validate_train)

    # the parameter life cycle (c.LockstepNode): validate, lock while a run is active, configure
    def validate(self, values):
        return self._validate(values)

    def configure(self, values):
        self.train = self._validate(values)[0]

    def publish_description(self):
        t = self.train
        self.pub_desc.publish(c.json_msg(P.train_description_record(
            self.get_parameter("train").value, t.name, t.describe(), t.length_m, t.n_axles,
            self.get_parameter("model").value, self.get_parameter("speeds_kmh").value)))

    def _bridge_dz(self):
        """``(delta_zeta, delta_zeta_lanes)`` of the bridge's latched description (to name a run
        requested without a phase as the bridge will); ``(0.0, "")`` before it arrived."""
        d = self._bridge_desc or {}
        return d.get("delta_zeta", 0.0), d.get("delta_zeta_lanes", "")

    def _on_bridge_description(self, msg):
        self._bridge_desc = P.decode(msg.data)

    # ------------------------------------------------------------------ run control
    def _on_start(self, request, response):
        if self.run is not None:
            response.success, response.message = False, f"run {self.run.id} is in progress"
            return response
        missing = [t for t, n in ((P.TOPIC_SETUP, self.count_subscribers(P.relative(P.TOPIC_SETUP))),
                                  (P.TOPIC_RAIL, self.count_publishers(P.relative(P.TOPIC_RAIL)))) if n == 0]
        if missing or self._bridge_desc is None:
            response.success = False
            response.message = (f"bridge node not connected yet (nothing on "
                                f"{', '.join(missing or [P.TOPIC_BRIDGE_DESC])}); retry")
            return response
        p = self.param_values()
        try:
            train, speeds = self._validate(p)
            # a deck's span shorter than the train's longest axle group, as adm-sim sweep refuses it
            check_span_lengths(((self._bridge_desc or {}).get("bridge") or {}).get("spans_m") or (), train)
        except InputError as exc:
            response.success, response.message = False, str(exc)
            return response
        run_id = self.next_run_id
        self.next_run_id += 1
        v = speeds_to_m_s(speeds)
        dim = p["model"] == "dim"
        phase = p["run_phase"] or P.plain_run_phase(p["model"], *self._bridge_dz())
        self.run = TrainRunState(id=run_id, model=p["model"], train=train, v=v, run=None, grid=None,
                        block=int(p["mlm_block_steps"]), phase=phase, irregularity=p["irregularity"])
        self._pending = []
        self.pub_setup.publish(c.json_msg(P.setup_record(
            run_id, p["model"], train.name, speeds, v, train.length_m, train.axle_offsets_m, train.axle_loads_n,
            train.wheel_mass_kg if dim else None, phase=p["run_phase"])))
        self.partner.waiting(f"before run {run_id} started", P.relative(P.TOPIC_READY))
        response.success = True
        response.message = f"run_id={run_id} model={p['model']} lanes={v.size} train={train.name} phase={phase}"
        return response

    def _on_ready(self, msg):
        cfg = P.decode(msg.data)
        r = self.run
        if r is None or cfg.get("run_id") != r.id:
            return  # another run's answer (e.g. a rejected request)
        if P.is_rejected(cfg):
            self.get_logger().error(f"run {r.id} rejected by the bridge: {cfg['error']}")
            self.pub_status.publish(c.json_msg(P.status_record(P.TRAIN_NODE, r.id, P.FAILED, phase=r.phase,
                                                               message=cfg["error"])))
            self.run = None
            self.partner.clear()
            return
        r.grid = Grid(speeds_m_s=r.v, ds_m=float(cfg["ds_m"]), n_steps=int(cfg["n_steps"]))
        side = None
        if r.model == "dim":  # the profile on this deck (the same spec gives the same profile, bit for bit)
            span = float(cfg["span_m"])
            side = TrainSide(r.train, r.grid, span, irregularity=parse_irregularity(r.irregularity, span))
        r.run = TrainHalf(r.model, r.grid, train_side=side)
        self.pub_status.publish(c.json_msg(P.status_record(P.TRAIN_NODE, r.id, P.STARTED, model=r.model,
                                                           phase=r.phase, n_steps=r.grid.n_steps)))
        self.partner.waiting(f"at step 0 of run {r.id}", P.relative(P.TOPIC_RAIL))
        pending, self._pending = self._pending, []
        for m in pending:
            self._on_rail(m)

    def _on_rail(self, msg):
        r = self.run
        if r is None:
            raise c.ExchangeError("train: rail state received with no run active")
        if r.grid is None:
            self._pending.append(msg)
            return
        run = r.run
        run_id, k, stage, idx, payload = c.unpack(msg)
        c.check_step("train", (run_id, k, stage), (r.id, run.k, run.stage))
        self.partner.clear()
        if r.model == "dim":
            run.step(idx, payload[0], payload[1])  # one RK4 stage with the bridge's rail state
            G = run.interaction_n
            self.forces_writer.publish(run_id, k, stage, G, FORCES_DIMS, idx)
        else:
            k0 = run.k
            run.advance(r.block)  # books the block whose axle positions are sent now
            b = run.k - k0
            x = half_step_positions(r.grid.ds_m, r.train.axle_offsets_m, k0, b)
            block = np.vstack([x, r.train.axle_loads_n[None, :]])
            self.pub_block.publish(c.pack(run_id, k0, 0, block, ("row:positions_m(2n+1),loads_n", "axle")))
        if run.status == FINISHED:
            self.pub_status.publish(c.json_msg(P.status_record(P.TRAIN_NODE, r.id, P.DONE, model=r.model,
                                                               phase=r.phase)))
            self.run = None
            self.partner.clear()
        else:
            self.partner.waiting(("at step {} stage {} of run {}", run.k, run.stage, r.id), TOPIC_RAIL)

    def _on_status(self, msg):
        """End the exchanging run when the bridge reports it failed (its message is passed on)."""
        st = P.decode(msg.data)
        r = self.run
        if r is None or r.run is None or st.get("node") != P.BRIDGE_NODE or not P.is_failure(st, r.id):
            return
        self.get_logger().error(f"run {r.id} failed on the bridge at step {r.run.k}: {st.get('message', '')}")
        self.pub_status.publish(c.json_msg(P.status_record(P.TRAIN_NODE, r.id, P.FAILED, phase=r.phase,
                                                           message=st.get("message", ""))))
        self.run = None
        self.partner.clear()

    # ------------------------------------------------------------------ supervision
    def watch(self):
        self.partner.check()

    def report_failure(self, message):
        rid = None if self.run is None else self.run.id
        self.pub_status.publish(c.json_msg(P.status_record(P.TRAIN_NODE, rid, P.FAILED, message=message)))


def main(args=None):
    return c.run_node(TrainNode, args=args, name="train")


if __name__ == "__main__":
    sys.exit(main())
