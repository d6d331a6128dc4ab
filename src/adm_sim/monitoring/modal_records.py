"""What the monitor reports of a passage: the rules it follows, the first mode it fits, the passage record.

:class:`IdentifySettings` holds the rules of segmentation and identification (the method is in
:mod:`adm_sim.monitoring.modal_id`); :class:`ModalFit` is the first mode identified from a free
decay (:mod:`adm_sim.monitoring.modal_fit`); :class:`Passage` one passage with its peak, its level
against the deck acceleration limit of EN 1990 A2.4.4.2.1(4)P (:func:`acc_level`) and its fit or the
reason there is none, written by ``monitor.py --json`` (:meth:`Passage.to_dict`) and logged one line
each (:meth:`Passage.line`). Numpy-free: plain values only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["BASELINE_AFTER", "BASELINE_BEFORE", "BASELINE_BOTH", "BASELINE_DYNAMIC", "BASELINE_RAW", "BASELINE_TAIL",
           "FIT_GAP_FREE", "FIT_PRESENT", "LEVELS", "LEVEL_TRIAL", "IdentifySettings", "ModalFit", "Passage",
           "acc_level"]

#: Level words of a peak against the limit: within (<= warn fraction), near (<= limit), above.
LEVELS = ("within", "near", "above")
#: Level word of a numerical trial's run (phases :data:`adm_sim.protocol.TRIAL_PHASES`): never compared
#: with the limit.
LEVEL_TRIAL = "trial"
#: How the free decay was fitted: no dropout in its window, or across dropouts.
FIT_GAP_FREE = "gap-free"
FIT_PRESENT = "least squares on the samples present"


@dataclass(frozen=True)
class IdentifySettings:
    """Rules of segmentation and identification (see the module docstring).

    Attributes
    ----------
    min_cycles : float
        Periods of free decay needed to identify damping.
    min_snr : float
        Amplitude at the start of the free decay over the residual RMS.
    max_rel_std : float
        Largest relative standard uncertainty of ζ1 that is still reported.
    max_log_scatter : float
        Weighted RMS scatter of ``ln`` of the half-cycle peak amplitudes about their line, on the
        free decay.
    end_snr : float
        The fit window ends where the fitted envelope falls below this times the residual RMS.
    bandpass : bool
        Band-pass around the FFT peak before fitting.
    band_ratio : float
        The band is ``[f / band_ratio, f band_ratio]``.
    f_range_hz : (float, float)
        Where the first mode is looked for.
    min_samples_per_period : float
        Coarser sampling is refused.
    window_s, trigger_snr, trigger_fraction, release_snr, merge_gap_s, threshold_m_s2
        Segmentation from the signal (:func:`segment_signal`).
    settle_periods : float
        Periods skipped after the start of the free decay (run records: after the train has
        left; the signal: after the log-linear start) when band-passing: the filter's response to
        what came before has decayed to below 1e-3 by then (a start 2.5 periods after an edge
        biases ζ1 by +0.2 %, 4 periods by less than 0.01 %, noise-free).
    baseline_s : float
        The static offset is the median of the quiet samples this long before (and after) a passage
        found in the signal (:func:`static_offset`).
    raw : bool
        Keep the raw signal: no static offset removed (the peak then includes gravity and bias).
    max_gap_periods : float
        Longest dropout inside the free decay that the fit bridges, in periods of the first mode.
    trend_s : float
        Segmentation: the signal's slow trend (gravity, bias, drift) is the median of consecutive
        blocks of this length, interpolated between their centres.
    """

    min_cycles: float = 5.0
    min_snr: float = 10.0
    max_rel_std: float = 0.25
    max_log_scatter: float = 0.03
    end_snr: float = 3.0
    bandpass: bool = True
    band_ratio: float = 2.0
    f_range_hz: tuple = (0.5, 100.0)
    min_samples_per_period: float = 8.0
    window_s: float = 0.5
    trigger_snr: float = 10.0
    trigger_fraction: float = 0.5
    release_snr: float = 2.0
    merge_gap_s: float = 2.0
    threshold_m_s2: float | None = None
    settle_periods: float = 3.0
    baseline_s: float = 2.0
    raw: bool = False
    max_gap_periods: float = 1.0
    trend_s: float = 10.0


@dataclass(frozen=True)
class ModalFit:
    """The first mode identified from a free decay.

    ``f1_hz`` the undamped natural frequency, ``zeta1`` the damping ratio (fraction), their
    standard uncertainties, ``fd_hz`` the damped frequency, ``t_start_s``/``t_end_s`` the fitted
    window, ``n_cycles`` its length in periods, ``snr`` the amplitude at its start over the residual
    RMS, ``amplitude_m_s2`` that amplitude, ``n_samples`` the samples fitted, ``filtered`` whether
    they were band-passed, ``log_scatter`` the scatter of the log cycle amplitudes, ``gaps`` the
    dropouts inside the window (``(t_s, duration_s, samples_missing)``) and ``method`` how they
    were bridged (:data:`FIT_GAP_FREE` or :data:`FIT_PRESENT`).
    """

    f1_hz: float
    zeta1: float
    f1_std_hz: float
    zeta1_std: float
    fd_hz: float
    t_start_s: float
    t_end_s: float
    n_cycles: float
    snr: float
    amplitude_m_s2: float
    n_samples: int
    filtered: bool
    log_scatter: float
    gaps: tuple = ()
    method: str = "gap-free"

    @property
    def zeta1_pct(self):
        return 100.0 * self.zeta1

    @property
    def zeta1_std_pct(self):
        return 100.0 * self.zeta1_std

    def __repr__(self):
        return (f"ModalFit(f1={self.f1_hz:.4f} ± {self.f1_std_hz:.4f} Hz, zeta1={self.zeta1_pct:.3f} ± "
                f"{self.zeta1_std_pct:.3f} %, {self.n_cycles:.1f} cycles from {self.t_start_s:.3f} s, "
                f"SNR {self.snr:.3g})")


@dataclass(frozen=True)
class Passage:
    """One passage: its peak, level and (when identified) first mode; see :meth:`to_dict`."""

    index: int
    t_start_s: float
    t_end_s: float
    peak_acc_m_s2: float
    t_peak_s: float
    limit_m_s2: float
    level: str
    n_samples: int
    fit: ModalFit | None
    reason: str | None
    source: str = "signal"
    run_id: int | None = None
    phase: str | None = None
    info: dict = field(default_factory=dict)
    offset_m_s2: float = 0.0
    offset_drift_m_s3: float = 0.0
    offset_baseline: str = "none"
    raw_peak_acc_m_s2: float | None = None
    n_nonfinite: int = 0
    gaps: tuple = ()
    warnings: tuple = ()

    @property
    def identified(self):
        return self.fit is not None

    def to_dict(self):
        """The JSON record of ``monitor.py --json`` (numbers of the fit are null when not identified)."""
        f = self.fit
        d = {"index": self.index, "run_id": self.run_id, "phase": self.phase, "source": self.source,
             "t_start_s": self.t_start_s, "t_end_s": self.t_end_s, "n_samples": self.n_samples,
             "peak_acc_m_s2": self.peak_acc_m_s2, "t_peak_s": self.t_peak_s, "limit_m_s2": self.limit_m_s2,
             "level": self.level, "identified": f is not None, "reason": self.reason,
             "f1_hz": None if f is None else f.f1_hz, "zeta1_pct": None if f is None else f.zeta1_pct,
             "f1_std_hz": None if f is None else f.f1_std_hz,
             "zeta1_std_pct": None if f is None else f.zeta1_std_pct,
             "signal": "raw" if self.offset_baseline == BASELINE_RAW else "dynamic",
             "offset_m_s2": self.offset_m_s2, "offset_drift_m_s3": self.offset_drift_m_s3,
             "offset_baseline": self.offset_baseline, "raw_peak_acc_m_s2": self.raw_peak_acc_m_s2,
             "nonfinite_samples": self.n_nonfinite,
             "nonfinite_handling": ("excluded (dropouts)" if self.n_nonfinite and self.n_samples > self.n_nonfinite
                                    else "passage refused" if self.n_nonfinite else None),
             "gaps": [_gap_dict(g) for g in self.gaps], "warnings": list(self.warnings),
             "free_decay": None if f is None else {
                 "t_start_s": f.t_start_s, "t_end_s": f.t_end_s, "n_cycles": f.n_cycles, "snr": f.snr,
                 "fd_hz": f.fd_hz, "n_samples": f.n_samples, "bandpass": f.filtered, "log_scatter": f.log_scatter,
                 "method": f.method, "gaps": [_gap_dict(g) for g in f.gaps]}}
        d.update(self.info)
        return d

    def line(self):
        """One log line: peak, level, and f1, ζ1 with their standard uncertainties or the reason."""
        head = f"passage {self.index}" + ("" if self.run_id is None else f" (run {self.run_id}"
                                          + ("" if self.phase is None else f", {self.phase}") + ")")
        lost = self.info.get("samples_lost")
        if self.level == LEVEL_TRIAL:
            level = "a numerical trial, not compared with the limit"
        else:
            level = f"{self.level} the {self.limit_m_s2:g} m/s^2 limit (EN 1990 A2.4.4.2.1)"
        kind = "raw" if self.offset_baseline == BASELINE_RAW else "dynamic"
        offset = (f" (static offset {self.offset_m_s2:.4g} m/s^2 removed, {self.offset_baseline})"
                  if kind == "dynamic" and self.offset_m_s2 != 0.0 else "")
        text = (f"{head}: {kind} peak |a| {self.peak_acc_m_s2:.4f} m/s^2 at t={self.t_peak_s:.3f} s{offset}, {level}"
                + (f", {lost} of {self.info['samples_published']} samples lost" if lost else "")
                + (f", {self.n_nonfinite} non-finite samples excluded" if self.n_nonfinite else "")
                + (f", {len(self.gaps)} dropout(s)" if self.gaps else ""))
        f = self.fit
        if f is None:
            return f"{text}; first mode not identified: {self.reason}"
        how = "" if f.method == FIT_GAP_FREE else f" ({f.method}, across {len(f.gaps)} dropout(s))"
        return (f"{text}; f1 {f.f1_hz:.4f} Hz (u {f.f1_std_hz:.2g} Hz), zeta1 {f.zeta1_pct:.3f} % "
                f"(u {f.zeta1_std_pct:.2g} %), {f.n_cycles:.1f} cycles of free decay{how}")


#: ``offset_baseline`` words: where the static offset removed was taken from.
BASELINE_RAW = "none (raw signal kept)"
BASELINE_DYNAMIC = "none (the bridge publishes the dynamic acceleration)"
BASELINE_BEFORE = "median of the quiet signal before the passage"
BASELINE_BOTH = "medians of the quiet signal before and after the passage, a straight line between them"
BASELINE_AFTER = "median of the quiet signal after the passage"
BASELINE_TAIL = "median of the passage's last samples (no quiet signal before or after it)"


def _gap_dict(g):
    return {"t_s": g[0], "duration_s": g[1], "samples_missing": g[2]}



def acc_level(peak_m_s2, limit_m_s2, warn_fraction=0.8):
    """``within`` (<= ``warn_fraction`` of the limit), ``near`` (<= limit) or ``above`` the limit
    (EN 1990 A2.4.4.2.1(4)P); a non-finite peak is ``above``."""
    if not math.isfinite(peak_m_s2) or peak_m_s2 > limit_m_s2:
        return LEVELS[2]
    return LEVELS[1] if peak_m_s2 > warn_fraction * limit_m_s2 else LEVELS[0]

