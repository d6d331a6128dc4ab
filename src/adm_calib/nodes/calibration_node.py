"""Calibration node: Δζ_VBI of one bridge and train from co-simulated runs (paper Section 4).

The node is a :class:`adm_sim.nodes.driver.RunDriver` (it records the run to MCAP and rerun)
that runs :func:`adm_calib.calibrate.calibrate` with every speed sweep replaced by a
co-simulated run of the bridge and train nodes (its ``sweep`` hook):

1. MLM over the speed range (``speeds_kmh``), all runs on the one space step that the full range
   needs (set as ``ds_m`` on the bridge node);
2. DIM on the paper's speed grid, refined around the associated DIM peak;
3. Δζ by the bracketing root finder, whose MLM evaluations set ``delta_zeta`` (or
   ``delta_zeta_lanes`` for the vectorised bracketing ladder) on the bridge node through its
   parameter service; every trial damping is one iteration on ``/adm/calibration/iteration`` and
   in rerun.

Unless ``monitor_speed_kmh`` is set on the bridge node, every run after the first MLM sweep
monitors the MLM peak speed (midspan history and deflected beam of the resonance).

The result is the same :class:`adm_calib.calibrate.CalibrationResult` as in-process, published
as JSON on ``/adm/calibration/result`` and written to ``summary_path`` with the keys of
``adm-calib calibrate --json``.
"""

from __future__ import annotations

import sys

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.parameter import parameter_value_to_python
from std_msgs.msg import Float64MultiArray, String

from adm_calib import peaks as pk
from adm_calib.calibrate import CalibrationOptions, calibrate, calibration_step
from adm_calib.lanes import response_points_m
from adm_sim import protocol as P
from adm_sim.model.bridge import Bridge
from adm_sim.nodes import common as c
from adm_calib.nodes.params import CALIBRATION_SPECS
from adm_sim.nodes.driver import RunDriver, say
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.inputs.speeds import parse_speeds
from adm_sim.inputs.train_files import load_train

#: ``/diagnostics`` status name of the calibration's verdict (its Δζ of every method; docs/ros.md, "Topics").
DIAG_VERDICT = "adm_calib/calibration: delta_zeta_vbi"
#: ``@run`` label of each run phase (:data:`adm_sim.protocol.PHASES`).
PHASE_LABELS = {phase: P.PHASE_NAMES[phase][1] for phase in P.PHASES}



class CalibrationNode(RunDriver):
    """Drives MLM and DIM runs and adjusts ``delta_zeta`` on the bridge node."""

    job_parameters = tuple(s.name for s in CALIBRATION_SPECS)  # read once, when the calibration starts

    def __init__(self, **kw):
        super().__init__(name=P.CALIBRATION_NODE, extra_specs=CALIBRATION_SPECS, **kw)
        R = P.relative
        self.pub_iter = self.create_publisher(Float64MultiArray, R(P.TOPIC_CAL_ITERATION), c.QOS_CONTROL)
        self.pub_result = self.create_publisher(String, R(P.TOPIC_CAL_RESULT), c.QOS_LATCHED)
        self.pub_diag = self.create_publisher(DiagnosticArray, R(P.TOPIC_DIAGNOSTICS), c.QOS_LATCHED)
        self.iteration = 0

    # ------------------------------------------------------------------ co-simulated sweeps
    def sweep(self, model, speeds, dz=0.0, phase=None):
        """Max midspan acceleration per speed (m/s^2) and the DIM's contact check (``{"max_acc_m_s2",
        "contact"}``, :class:`adm_calib.lanes.HookLanes`) from one co-simulated run of run phase
        ``phase`` (:data:`adm_sim.protocol.PHASES`), handed on to the run's records and rerun."""
        dz = np.asarray(dz, dtype=float)
        label = None if phase is None else PHASE_LABELS[phase]
        if dz.ndim == 0 or np.all(dz == dz.flat[0]):
            r = self.request_run(model, np.asarray(speeds, float), delta_zeta=float(dz.flat[0]), delta_zeta_lanes=[],
                                 label=label, phase=phase)
        else:
            r = self.request_run(model, np.asarray(speeds, float), delta_zeta=0.0, delta_zeta_lanes=dz, label=label,
                                 phase=phase)
        return {"max_acc_m_s2": np.asarray(r["max_acc_m_s2"], dtype=float), "contact": r.get("contact")}

    def _iteration(self, dz, mlm_peak, dim_peak):
        """One trial damping: publish, print and log it (``calibrate``'s ``on_trial``, called after the
        run it was read from: its phase is the phase of the last run requested)."""
        self.iteration += 1
        i = self.iteration
        self.publish_recorded(self.pub_iter, P.TOPIC_CAL_ITERATION, c.matrix_msg(
            ("quantity:" + ",".join(P.ITERATION_FIELDS),), [i, 100 * dz, mlm_peak, dim_peak]))
        say("iteration", i=i, delta_zeta_pct=100 * dz, mlm_peak_m_s2=mlm_peak, dim_peak_m_s2=dim_peak,
            ratio=mlm_peak / dim_peak, phase=self.last_phase)

    def _hook(self, model, speeds, dz, step, phase):
        """``calibrate``'s sweep hook: one co-simulated run on the calibration's space step per
        governing point (:func:`adm_calib.lanes.response_points_m`: midspan of one span, the middle of
        every span of a continuous deck, each set as the bridge's ``response_m``), the largest
        maxima of them, as the in-process lanes take them; the DIM's contact check is the first run's
        (the forces do not depend on the point).

        ``phase`` comes with the lanes from the calibration (:mod:`adm_calib.lanes`) and names the run.
        """
        if self._ds_m != step.ds_m:
            self.set_params(P.BRIDGE_NODE, ds_m=step.ds_m, delta_zeta=0.0, delta_zeta_lanes="")
            self._ds_m = step.ds_m
        run_phase = P.CALIBRATION_PHASES[phase]
        res = None
        for x in self._points:
            if self._response != x:
                self.set_params(P.BRIDGE_NODE, response_m=x)
                self._response = x
            r = self.sweep(model, speeds, dz, phase=run_phase)
            if res is None:
                res = r
            else:
                res["max_acc_m_s2"] = np.maximum(res["max_acc_m_s2"], r["max_acc_m_s2"])
        if run_phase == P.PHASE_MLM_ZETA and self._auto_monitor:
            self._monitor_peak(speeds, res["max_acc_m_s2"])
        return res

    def _monitor_peak(self, speeds, acc):
        """Monitor the MLM peak speed in every later run (when the user set no ``monitor_speed_kmh``)."""

        peak = pk.find_peak(np.asarray(speeds, float), acc)
        if peak.found:
            self.set_params(P.BRIDGE_NODE, monitor_speed_kmh=float(peak.speed_kmh))
            self._auto_monitor = False

    def _user_monitor_speed(self):
        """The bridge node's ``monitor_speed_kmh`` (0 = not chosen by the user)."""

        cli = self.params[P.BRIDGE_NODE]
        if not cli.wait_for_services(timeout_sec=10.0):
            return 0.0
        res = self._wait_future(cli.get_parameters(["monitor_speed_kmh"]), "get monitor_speed_kmh on 'bridge'")
        return float(parameter_value_to_python(res.values[0])) if res.values else 0.0

    # ------------------------------------------------------------------ the job
    def job(self):
        self.wait_for_graph()
        bd = self.description(P.BRIDGE_NODE)
        td = self.description(P.TRAIN_NODE)
        bridge = Bridge(**P.bridge_fields(bd["bridge"]))
        train = load_train(td["train"])
        st = bd["step"]
        base = StepOptions(steps_per_period=st["steps_per_period"], free_vibration_periods=st["free_vibration_periods"],
                           ds_m=st["ds_m"] or None)
        p = self.param_values()
        opt = CalibrationOptions(dim_grid=p["dim_grid"], step=base)
        v = parse_speeds(p["speeds_kmh"], field="speeds_kmh")
        self._n_speeds, self._ds_m = v.size, None
        # the governing points (0 = midspan of one span); the bridge's response_m as it is until set
        self._points = [0.0 if x is None else x for x in response_points_m(bridge)]
        self._response = bd.get("response_m")
        self._auto_monitor = self._user_monitor_speed() <= 0.0
        say("calibration", bridge=bridge.describe(), train=train.name, speeds=len(v),
            ds_m=calibration_step(bridge, train, v, opt).ds_m)
        res = calibrate(bridge, train, v, options=opt, sweep=self._hook, on_trial=self._iteration)
        self._publish_result(res)
        summary = res.to_dict(curves=True)
        # the bridge the graph ran: its spans (a continuous deck), supports, frequencies and modal masses
        summary.update({k: bd.get(k) for k in ("supports_m", "frequencies_hz", "modal_masses_kg")},
                       spans_m=list(bridge.spans_m))
        summary["co_simulation"] = {"runs": self.n_runs, "delta_zeta_trials": self.iteration,
                                    "incomplete_runs": self.incomplete}
        return summary

    def _publish_result(self, res):
        self.publish_recorded(self.pub_result, P.TOPIC_CAL_RESULT, c.json_msg(res.to_dict(curves=True)))
        ok, message, values = res.diagnostic()
        st = DiagnosticStatus(level=DiagnosticStatus.OK if ok else DiagnosticStatus.WARN,
                              name=DIAG_VERDICT,
                              hardware_id=res.bridge.name or res.bridge.describe(), message=message)
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        arr = DiagnosticArray(status=[st])
        arr.header.stamp.sec, arr.header.stamp.nanosec = divmod(self._clock_ns, 1_000_000_000)
        self.publish_recorded(self.pub_diag, P.TOPIC_DIAGNOSTICS, arr)


def main(args=None):
    return c.run_node(CalibrationNode, args=args, name="calibration")


if __name__ == "__main__":
    sys.exit(main())
