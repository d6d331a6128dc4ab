"""Calibration node: Δζ_VBI of one bridge and train from co-simulated runs (paper Section 4).

The node is a :class:`adm_sim.nodes.driver.RunDriver` (it records the run to MCAP and rerun)
that follows :func:`adm_calib.calibrate.calibrate` step by step, with every speed sweep replaced
by a co-simulated run of the bridge and train nodes:

1. MLM over the speed range (``speeds_kmh``), all runs on the one space step that the full range
   needs (:func:`adm_calib.calibrate.calibration_step`, set as ``ds_m`` on the bridge node);
2. DIM on the paper's speed grid (:func:`adm_calib.calibrate.dim_speeds_paper`), refined around the
   associated DIM peak as ``calibrate`` does; MLM/DIM peaks by :mod:`adm_calib.peaks`;
3. Δζ by :func:`adm_calib.calibrate.solve_delta_zeta` whose MLM evaluator sets ``delta_zeta``
   (or ``delta_zeta_lanes`` for the vectorised bracketing ladder) on the bridge node through its
   parameter service and runs the MLM; every evaluation is one iteration on
   ``/adm/calibration/iteration`` and in rerun.

``adm_calib.calibrate.calibrate`` runs its sweeps in-process and has no hook for an external
evaluator, so steps 1-3 are repeated here (same functions, same order); the result is the same
:class:`adm_calib.calibrate.CalibrationResult`, published as JSON on ``/adm/calibration/result``
and written to ``summary_path`` with the keys of ``adm-calib calibrate --json``.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_msgs.msg import Float64MultiArray, String

from adm_calib import peaks as pk
from adm_calib.calibrate import (CalibrationOptions, CalibrationResult, _fine_step, _grid_between, _speeds,
                                 dim_speeds_paper, solve_delta_zeta)
from adm_calib.reference import adm_delta_zeta_pct, eada_for, lower_bound_for
from adm_sim.bridge import Bridge
from adm_sim.nodes import common as c
from adm_sim.nodes.driver import RunDriver, run_driver, say
from adm_sim.stepping import StepOptions, make_grid, speeds_to_m_s
from adm_sim.sweep import parse_speeds
from adm_sim.trains import load_train

CALIBRATION_SPECS = [
    c.ParamSpec("speeds_kmh", "160:350:1", "km/h", "MLM speed range: start:stop:step or a comma list"),
    c.ParamSpec("dim_grid", "paper", "", "paper (5 km/h + fine around the MLM peak) | full (every MLM speed)"),
]


def calibration_step(bridge, train, speeds_kmh, options):
    """Step settings shared by every run of one calibration (fixed ``ds_m``), as ``calibrate``."""
    base = options.step or StepOptions()
    ds = make_grid(bridge, train.length_m, speeds_to_m_s(speeds_kmh), base).ds_m
    return StepOptions(base.steps_per_period, base.free_vibration_periods, ds)


class CalibrationNode(RunDriver):
    """Drives MLM and DIM runs and adjusts ``delta_zeta`` on the bridge node."""

    def __init__(self, **kw):
        super().__init__(name="calibration", extra_specs=CALIBRATION_SPECS, **kw)
        self.pub_iter = self.create_publisher(Float64MultiArray, c.TOPIC_CAL_ITERATION, c.QOS_CONTROL)
        self.pub_result = self.create_publisher(String, c.TOPIC_CAL_RESULT, c.QOS_CONTROL)
        self.pub_diag = self.create_publisher(DiagnosticArray, c.TOPIC_DIAGNOSTICS, c.QOS_CONTROL)
        self.iteration = 0

    # ------------------------------------------------------------------ co-simulated sweeps
    def sweep(self, model, speeds, dz=0.0, label=None):
        """Max midspan acceleration per speed (m/s^2) from one co-simulated run."""
        dz = np.asarray(dz, dtype=float)
        if dz.ndim == 0 or np.all(dz == dz.flat[0]):
            r = self.request_run(model, np.asarray(speeds, float), delta_zeta=float(dz.flat[0]), delta_zeta_lanes=[],
                                 label=label)
        else:
            r = self.request_run(model, np.asarray(speeds, float), delta_zeta=0.0, delta_zeta_lanes=dz, label=label)
        return np.asarray(r["max_acc_m_s2"], dtype=float)

    def _iteration(self, dz, mlm_peak, dim_peak):
        self.iteration += 1
        i = self.iteration
        self.publish_recorded(self.pub_iter, c.TOPIC_CAL_ITERATION, c.matrix_msg(
            ("quantity:iteration,delta_zeta_pct,mlm_peak_m_s2,dim_peak_m_s2",), [i, 100 * dz, mlm_peak, dim_peak]))
        say("iteration", i=i, delta_zeta_pct=100 * dz, mlm_peak_m_s2=mlm_peak, dim_peak_m_s2=dim_peak,
            ratio=mlm_peak / dim_peak)
        if self.rerun:
            from adm_sim.ros import rerun_log

            rerun_log.log_delta_zeta_iteration(i, 100 * dz, mlm_peak, dim_peak)

    # ------------------------------------------------------------------ the job
    def job(self):
        self.wait_for_graph()
        bd = self.description("bridge")
        td = self.description("train")
        bridge = Bridge(**bd["bridge"])
        train = load_train(td["train"])
        st = bd["step"]
        base = StepOptions(st["steps_per_period"], st["free_vibration_periods"], st["ds_m"] or None)
        p = self.param_values()
        opt = CalibrationOptions(dim_grid=p["dim_grid"], step=base)
        v = _speeds(parse_speeds(p["speeds_kmh"]))
        step = calibration_step(bridge, train, v, opt)
        self.set_params(c.BRIDGE_NODE, ds_m=step.ds_m, delta_zeta=0.0, delta_zeta_lanes="")
        say("calibration", bridge=bridge.describe(), train=train.name, speeds=len(v), ds_m=step.ds_m)
        timings = {}

        t0 = time.perf_counter()
        mlm = self.sweep("mlm", v, label="MLM zeta")
        timings["mlm_sweep"] = time.perf_counter() - t0
        mlm_peak = pk.find_peak(v, mlm, opt.min_prominence_rel)

        t0 = time.perf_counter()
        vd = v if opt.dim_grid == "full" else dim_speeds_paper(v, mlm_peak.speed_kmh if mlm_peak.found else None, opt)
        dim = self.sweep("dim", vd, label="DIM")
        refined = False
        dim_peak = pk.Peak(found=False, reason="no MLM peak to associate with")
        if mlm_peak.found:
            dim_peak = pk.associate_peak(vd, dim, mlm_peak.speed_kmh, opt.association_window_kmh,
                                         opt.min_prominence_rel)
            fine = _fine_step(v)
            for _ in range(2):
                if not dim_peak.found or opt.dim_grid == "full":
                    break
                i = dim_peak.index
                gaps = [vd[i] - vd[i - 1] if i > 0 else 0.0, vd[i + 1] - vd[i] if i + 1 < vd.size else 0.0]
                if max(gaps) <= fine + 1e-9:
                    break
                extra = _grid_between(dim_peak.speed_kmh - 5.0, dim_peak.speed_kmh + 5.0, fine, v.min(), v.max())
                extra = np.setdiff1d(np.round(extra, 9), vd)
                if extra.size == 0:
                    break
                acc_extra = self.sweep("dim", extra, label="DIM refine")
                all_v, all_a = np.concatenate([vd, extra]), np.concatenate([dim, acc_extra])
                order = np.argsort(all_v)
                vd, dim = all_v[order], all_a[order]
                refined = True
                dim_peak = pk.associate_peak(vd, dim, mlm_peak.speed_kmh, opt.association_window_kmh,
                                             opt.min_prominence_rel)
        timings["dim_sweep"] = time.perf_counter() - t0

        solve = None
        adapted = pk.Peak(found=False)
        v_ad, a_ad = np.zeros(0), np.zeros(0)
        t0 = time.perf_counter()
        if not mlm_peak.found:
            status, message = "no_mlm_peak", mlm_peak.reason
        elif not dim_peak.found:
            status, message = "no_dim_peak", dim_peak.reason
        else:
            h = opt.relocation_window_kmh
            w = v[(v >= mlm_peak.speed_kmh - h - 1e-9) & (v <= mlm_peak.speed_kmh + h + 1e-9)]
            target = dim_peak.acc_m_s2

            def mlm_eval(s, dz):
                acc = self.sweep("mlm", s, dz, label="MLM trial")
                dzs = np.asarray(dz, dtype=float)
                for value in np.unique(dzs):  # one iteration per trial damping (the ladder has several)
                    lanes = dzs == value
                    peak = pk.window_max(np.asarray(s)[lanes], acc[lanes], mlm_peak.speed_kmh, (h, h))[1]
                    self._iteration(float(value), float(peak), float(target))
                return acc

            solve = solve_delta_zeta(mlm_eval, mlm_peak.speed_kmh, w, target, bridge.damping_ratio, opt)
            status, message = solve.status, solve.message
            adapted = solve.adapted_peak
            if solve.delta_zeta is not None:
                v_ad, a_ad = v, self.sweep("mlm", v, solve.delta_zeta, label="MLM zeta+dz")
        timings["solve"] = time.perf_counter() - t0

        eada, eada_note = eada_for(bridge, train)
        lb, lb_note = lower_bound_for(bridge, train)
        res = CalibrationResult(
            bridge=bridge, train_name=train.name, status=status, message=message,
            delta_zeta_vbi=None if solve is None else solve.delta_zeta, mlm_peak=mlm_peak, dim_peak=dim_peak,
            adapted_peak=adapted, solve=solve, delta_zeta_adm_pct=adm_delta_zeta_pct(bridge.span_m),
            delta_zeta_eada_pct=eada, eada_note=eada_note, delta_zeta_lb_pct=lb, lb_note=lb_note,
            mlm_speeds_kmh=v, mlm_acc_m_s2=mlm, dim_speeds_kmh=np.asarray(vd, float), dim_acc_m_s2=dim,
            adapted_speeds_kmh=v_ad, adapted_acc_m_s2=a_ad, dim_grid=opt.dim_grid, dim_refined=refined,
            ds_m=step.ds_m, timings_s=timings)
        self._publish_result(res)
        summary = res.to_dict(curves=True)
        summary["co_simulation"] = {"runs": self.n_runs, "delta_zeta_trials": self.iteration}
        return summary

    def _publish_result(self, res):
        d = res.to_dict(curves=False)
        self.publish_recorded(self.pub_result, c.TOPIC_CAL_RESULT, c.json_msg(res.to_dict(curves=True)))
        ok = res.status == "ok"
        st = DiagnosticStatus(level=DiagnosticStatus.OK if ok else DiagnosticStatus.WARN,
                              name="adm_calib/calibration: delta_zeta_vbi", hardware_id=d["bridge"],
                              message=(f"dz_VBI = {d['delta_zeta_vbi_pct']:.4f} %" if ok else f"{res.status}: {res.message}"))
        st.values = [KeyValue(key=k, value=str(d[k])) for k in
                     ("train", "status", "zeta_pct", "delta_zeta_vbi_pct", "delta_zeta_adm_pct", "delta_zeta_eada_pct",
                      "delta_zeta_lb_pct")]
        arr = DiagnosticArray(status=[st])
        arr.header.stamp.sec, arr.header.stamp.nanosec = divmod(self._clock_ns, 1_000_000_000)
        self.publish_recorded(self.pub_diag, c.TOPIC_DIAGNOSTICS, arr)
        if self.rerun:
            from adm_sim.ros import rerun_log

            rerun_log.log_run_info({k: d[k] for k in ("bridge_description", "train", "status", "zeta_pct",
                                                       "delta_zeta_vbi_pct", "delta_zeta_adm_pct",
                                                       "delta_zeta_eada_pct", "delta_zeta_lb_pct")})


def main(args=None):
    return run_driver(CalibrationNode, args=args, name="calibration")


if __name__ == "__main__":
    sys.exit(main())
