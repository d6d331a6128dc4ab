"""The result of one calibration: Δζ_VBI with its peaks, flags, curves and the reference methods
(ADM, EADA, lower bound), as a dict for JSON and as a readable report."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from adm_calib import peaks as pk
from adm_calib.damping_root import DampingSolve
from adm_calib.reference import adm_delta_zeta_pct, eada_for, lower_bound_for

def _f(x):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)


@dataclass(frozen=True, repr=False)
class CalibrationResult:
    """Δζ_VBI of one bridge and train with the peaks, flags, curves and reference methods.

    Damping values are fractions (``delta_zeta_vbi``) and percent in :meth:`to_dict`.
    Curves: ``mlm_speeds_kmh``/``mlm_acc_m_s2`` (n_mlm,), ``dim_*`` (n_dim,), ``adapted_*``
    (n_mlm,) for the MLM at ``zeta + Δζ_VBI`` (empty when there is no Δζ_VBI).
    """

    bridge: object
    train_name: str
    status: str
    message: str
    delta_zeta_vbi: float | None
    mlm_peak: pk.Peak
    dim_peak: pk.Peak
    adapted_peak: pk.Peak
    solve: DampingSolve | None
    delta_zeta_adm_pct: float | None
    delta_zeta_eada_pct: float | None
    eada_note: str
    delta_zeta_lb_pct: float | None
    lb_note: str
    mlm_speeds_kmh: np.ndarray
    mlm_acc_m_s2: np.ndarray
    dim_speeds_kmh: np.ndarray
    dim_acc_m_s2: np.ndarray
    adapted_speeds_kmh: np.ndarray
    adapted_acc_m_s2: np.ndarray
    dim_grid: str = "paper"
    dim_refined: bool = False
    ds_m: float = float("nan")
    timings_s: dict = field(default_factory=dict)

    @property
    def delta_zeta_vbi_pct(self):
        return None if self.delta_zeta_vbi is None else 100.0 * self.delta_zeta_vbi

    @property
    def determined(self):
        """Whether Δζ_VBI is determined: status ``ok`` (a value under another status is reported but
        not determined, :data:`adm_calib.peaks.UNDETERMINED_STATUSES`)."""
        return self.status == "ok" and self.delta_zeta_vbi is not None

    @property
    def advice(self):
        """The one-line advice of an undetermined Δζ_VBI (the part of the message after "not determined: ")."""
        head, sep, tail = self.message.partition("not determined: ")
        return tail if sep else None

    @property
    def zeta_pct(self):
        return 100.0 * self.bridge.damping_ratio

    def to_dict(self, curves=True):
        """JSON-ready mapping; damping in percent (``*_pct``)."""
        s = self.solve
        d = {
            "bridge": self.bridge.name or self.bridge.describe(),
            "bridge_description": self.bridge.describe(),
            "spans_m": list(self.bridge.spans_m) if self.bridge.is_continuous else [self.bridge.span_m],
            "frequencies_hz": self.bridge.frequencies_hz.tolist(),
            "modal_masses_kg": self.bridge.modal_mass_kg.tolist(),
            "train": self.train_name,
            "status": self.status,
            "message": self.message,
            "zeta_pct": self.zeta_pct,
            "delta_zeta_vbi_pct": _f(self.delta_zeta_vbi_pct),
            "delta_zeta_determined": self.determined,
            "advice": self.advice,
            "delta_zeta_adm_pct": _f(self.delta_zeta_adm_pct),
            "delta_zeta_eada_pct": _f(self.delta_zeta_eada_pct),
            "eada_note": self.eada_note,
            "delta_zeta_lb_pct": _f(self.delta_zeta_lb_pct),
            "lb_note": self.lb_note,
            "mlm_peak": self.mlm_peak.to_dict(),
            "dim_peak": self.dim_peak.to_dict(),
            "adapted_mlm_peak": self.adapted_peak.to_dict(),
            "mlm_max_at_range_end": bool(self.mlm_peak.max_at_range_end),
            "dim_is_local_max": bool(self.dim_peak.found and self.dim_peak.is_local_max),
            "dim_max_at_range_end": (None if self.dim_peak.max_at_range_end is None
                                     else bool(self.dim_peak.max_at_range_end)),
            "dim_speed_shift_kmh": (_f(self.dim_peak.speed_kmh - self.mlm_peak.speed_kmh)
                                    if self.mlm_peak.found and self.dim_peak.found else None),
            "adapted_is_local_max": bool(self.adapted_peak.found and self.adapted_peak.is_local_max),
            "association_rule": self.dim_peak.reason,
            "solver": None if s is None else {
                "method": s.method, "iterations": s.iterations, "function_calls": s.function_calls,
                "ladder_runs": s.ladder_runs,
                "bracket_pct": None if s.bracket is None else [100 * s.bracket[0], 100 * s.bracket[1]],
                "residual_rel": _f(s.residual_rel), "status": s.status, "message": s.message},
            "dim_grid": self.dim_grid,
            "dim_refined": self.dim_refined,
            "ds_m": self.ds_m,
            "timings_s": dict(self.timings_s),
        }
        if curves:
            d["curves"] = {
                "mlm": {"speeds_kmh": self.mlm_speeds_kmh.tolist(), "max_acc_m_s2": self.mlm_acc_m_s2.tolist()},
                "dim": {"speeds_kmh": self.dim_speeds_kmh.tolist(), "max_acc_m_s2": self.dim_acc_m_s2.tolist()},
                "mlm_adapted": {"speeds_kmh": self.adapted_speeds_kmh.tolist(),
                                "max_acc_m_s2": self.adapted_acc_m_s2.tolist()},
            }
        return d

    def diagnostic(self):
        """``(determined, message, {key: text})`` of the ROS calibration's diagnostic status
        (``/diagnostics``; the node publishes WARN unless determined). An undetermined Δζ_VBI is
        named so, with its status and advice."""
        d = self.to_dict(curves=False)
        if self.determined:
            message = f"dz_VBI = {d['delta_zeta_vbi_pct']:.4f} %"
        elif self.delta_zeta_vbi is not None and self.status in pk.UNDETERMINED_STATUSES:
            message = f"dz_VBI = {d['delta_zeta_vbi_pct']:.4f} % NOT DETERMINED ({self.status}): {self.advice}"
        else:
            message = f"{self.status}: {self.message}"
        keys = ("train", "status", "delta_zeta_determined", "advice", "zeta_pct", "delta_zeta_vbi_pct",
                "delta_zeta_adm_pct", "delta_zeta_eada_pct", "delta_zeta_lb_pct")
        return self.determined, message, {k: str(d[k]) for k in keys}

    def to_json(self, curves=True, **kw):
        return json.dumps(self.to_dict(curves=curves), indent=kw.pop("indent", 2), **kw)

    def summary(self):
        """Readable multi-line report."""
        def pct(x):
            return "n/a" if x is None else f"{x:.3f} %"

        def peak(p):
            return "none" if not p.found else f"{p.acc_m_s2:.4f} m/s^2 at {p.speed_kmh:g} km/h"

        b = self.bridge
        lines = [f"{b.describe()}",
                 "modes: " + ", ".join(f"{f:.4g} Hz ({m / 1000:.5g} t)" for f, m in
                                       zip(b.frequencies_hz, b.modal_mass_kg)) + " (frequency, modal mass)",
                 f"train {self.train_name}; status {self.status}: {self.message}",
                 f"MLM peak       {peak(self.mlm_peak)}"
                 f"{'  (largest MLM value at an end of the speed range)' if self.mlm_peak.max_at_range_end else ''}",
                 f"DIM peak       {peak(self.dim_peak)}"
                 f"{'' if self.dim_peak.is_local_max or not self.dim_peak.found else '  (not a local maximum)'}",
                 f"adapted MLM    {peak(self.adapted_peak)}"]
        if self.solve is not None and self.solve.delta_zeta is not None:
            mark = "" if self.determined else f"  NOT DETERMINED ({self.status})"
            lines.append(f"dz_VBI         {pct(self.delta_zeta_vbi_pct)}{mark}  ({self.solve.method}, "
                         f"{self.solve.iterations} iterations, peak mismatch {100 * self.solve.residual_rel:.2e} %)")
        else:
            lines.append("dz_VBI         n/a")
        adm_note = "EN 1991-2 6.4.6.3.1" if self.delta_zeta_adm_pct is not None else (
            "EN 1991-2 6.4.6.3.1 is written for a simply supported span: not evaluated on a continuous deck")
        lines += [f"dz_ADM         {pct(self.delta_zeta_adm_pct)}  ({adm_note})",
                  f"dz_EADA        {pct(self.delta_zeta_eada_pct)}  ({self.eada_note})",
                  f"dz_LB          {pct(self.delta_zeta_lb_pct)}  ({self.lb_note})",
                  f"zeta           {self.zeta_pct:.3f} %"]
        if self.status != "ok":
            lines.append(f"status {self.status}: {pk.STATUSES.get(self.status, self.message)}")
            if self.advice:
                lines.append(f"advice: {self.advice}")
            lines.append("statuses: " + "; ".join(f"{k} = {v}" for k, v in pk.STATUSES.items()))
        return "\n".join(lines)

    def __repr__(self):
        dz = "n/a" if self.delta_zeta_vbi is None else f"{100 * self.delta_zeta_vbi:.4f} %" + ("" if self.determined else " (not determined)")
        return (f"CalibrationResult({self.bridge.name or 'bridge'} x {self.train_name}, {self.status}, "
                f"dz_VBI={dz}, MLM {self.mlm_peak!r}, DIM {self.dim_peak!r})")


def make_result(*, bridge, train, status, message, solve, mlm_peak, dim_peak, mlm_curve, dim_curve, adapted_curve,
                dim_grid, dim_refined, ds_m, timings_s):
    """The :class:`CalibrationResult` with the reference methods evaluated.

    ``*_curve`` are ``(speeds_kmh, max_acc_m_s2)`` pairs; ``solve`` a
    :class:`~adm_calib.damping_root.DampingSolve` or ``None``.
    """
    adapted = pk.Peak(found=False) if solve is None else solve.adapted_peak
    # EN 1991-2 6.4.6.3.1 Eq. (6.13) is written for the span of a simply supported bridge: none on a deck
    adm = None if bridge.is_continuous and len(bridge.spans_m) > 1 else adm_delta_zeta_pct(bridge.span_m)
    eada, eada_note = eada_for(bridge, train)
    lb, lb_note = lower_bound_for(bridge, train)
    return CalibrationResult(
        bridge=bridge, train_name=train.name, status=status, message=message,
        delta_zeta_vbi=None if solve is None else solve.delta_zeta, mlm_peak=mlm_peak, dim_peak=dim_peak,
        adapted_peak=adapted, solve=solve, delta_zeta_adm_pct=adm,
        delta_zeta_eada_pct=eada, eada_note=eada_note, delta_zeta_lb_pct=lb, lb_note=lb_note,
        mlm_speeds_kmh=mlm_curve[0], mlm_acc_m_s2=mlm_curve[1], dim_speeds_kmh=np.asarray(dim_curve[0], float),
        dim_acc_m_s2=dim_curve[1], adapted_speeds_kmh=adapted_curve[0], adapted_acc_m_s2=adapted_curve[1],
        dim_grid=dim_grid, dim_refined=dim_refined, ds_m=ds_m, timings_s=timings_s)
