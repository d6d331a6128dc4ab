"""Passages of trains in a midspan acceleration record: peak, EN 1990 level, first mode from the free decay.

A monitoring record (``/adm/midspan/accel``, a real accelerometer's ``AccelStamped`` or ``Imu``
topic, an MCAP of either, a data logger's CSV) is cut into *passages*; for each one this module reports the peak ``|a|`` and its
time, its level against the deck acceleration limit of EN 1990 A2.4.4.2.1(4)P (3.5 m/s² ballasted,
5 m/s² direct fastening, :mod:`adm_sim.limits`) and the first bending mode's natural frequency
``f1`` and damping ratio ``ζ1`` identified from the free vibration after the train has left.
Numpy and scipy only (no ROS); the monitor node and ``launch_scripts/monitor.py`` feed it.

Passages
--------
*From run records* (:class:`PassageTracker` with ``/adm/run/status``): one passage per run, the
samples whose stamp lies in ``[t0_s, t1_s)`` of the bridge's ``started`` / ``done`` records (each
end :data:`STAMP_TOLERANCE_S` early: a first sample stamped ``t0_s`` rounded to the ns is the run's),
assigned by stamp, not by arrival (a ``done`` may arrive before the last samples). The train has
left at ``t0_s + (train length + deck length) / v`` (the latched descriptions; the deck length is
``span_m`` of one span, the sum of ``spans_m`` of a continuous deck: the last axle leaves after the
last span); the free decay is taken
from ``settle_periods`` (3) periods after that. Stamps are in the monitored lane's time (a
``started`` record naming its ``time_lane``), or rescaled to it from the clock lane's.

*From the signal* (:func:`segment_signal`, no run records): ``e(t)`` is the moving maximum of
``|a - median(a)|`` over ``window_s``; the noise level ``σ_n`` the 10th percentile of the maxima of
``|a - median(a)|`` in consecutive ``window_s`` windows (the envelope of the quiet signal). A
passage is a stretch where ``e`` exceeds the release level ``release_snr σ_n`` that contains a sample above the trigger ``min(trigger_snr σ_n,
trigger_fraction max|a|)`` (or ``threshold_m_s2`` when given); stretches closer than
``merge_gap_s`` are one passage. The free decay starts at the first half-cycle peak after the
largest one from which the logarithms of the half-cycle peak amplitudes lie on a straight line
(weighted RMS scatter at most ``max_log_scatter``, weights the squared amplitudes, plus three times
the scatter the noise gives unfiltered; peaks below 5 % of the largest or 3 noise levels left
out), plus ``settle_periods`` when band-passed.

First mode (:func:`identify_first_mode`)
----------------------------------------
1. Frequency start value: the peak of the Hann-windowed, zero-padded FFT of the free decay in
   ``f_range_hz`` (parabolic interpolation on the log magnitude, within half a bin of the peak); a
   band whose largest value is at its edge, on the flank of a larger peak outside it (a slow swing,
   a mode above what the sampling resolves), has no peak and is refused. Samples are sorted by
   stamp, a repeated stamp keeps its first sample, and stamps that scatter by more than 1 % of
   the median interval are interpolated linearly onto a grid at that interval
   (:func:`uniform_samples`).
2. Optional band-pass (default on): zero-phase 2nd-order Butterworth (``sosfiltfilt``) over
   ``[f/2, 2 f]`` (``band_ratio``), applied to the whole passage so the decay window does not start
   at a filter edge; one period at the end of the window is dropped, ``settle_periods`` at its
   start (the filter's response to what came before). A decaying sinusoid ``e^{st}`` is an
   eigenfunction of a linear filter, so the filter changes amplitude and phase but neither the
   frequency nor the decay rate; higher modes (a simply supported beam's third mode is at 9 f1)
   no longer bias the fit.
3. Decay-rate start value: the logarithmic decrement, the slope of ``ln`` of the half-cycle peak
   amplitudes against time.
4. Fit, :func:`scipy.optimize.least_squares`, of ``a(t) = e^{-σ t} (B1 cos ω_d t + B2 sin ω_d t) + c``
   (``t`` from the window start) to the free-decay samples; then ``ω1 = sqrt(ω_d² + σ²)``,
   ``f1 = ω1 / 2π`` (the undamped natural frequency, as n0) and ``ζ1 = σ / ω1``. The window ends
   where the fitted envelope falls below ``end_snr`` times the residual RMS (one refit).
5. Standard uncertainties: the covariance ``s² (JᵀJ)⁻¹`` of the fit's Jacobian ``J`` at the
   solution, with ``s²`` the residuals' one-sided power spectral density at ``f_d`` (Welch) times
   ``f_s / 2`` instead of their plain variance: for white noise the two agree; for coloured
   residuals (band-passed noise, unmodelled modes) it counts the noise where the mode is, not the
   noise the filter removed. ``u(f1)`` and ``u(ζ1)`` follow from ``u(σ)``, ``u(ω_d)`` and their
   covariance by first-order propagation. Valid for one dominant mode in the band; two close modes
   beat and are refused by the scatter rule.

Real sensors (:func:`analyse_passage`)
--------------------------------------
* Static offset: the peak and the level are those of the dynamic signal ``a - offset(t)``; the
  offset (gravity, bias, drift) comes from the quiet signal before and after a passage found in
  the signal (:func:`static_offset`: the line through the two medians, one median, or the median
  of the passage's tail), none for the bridge's own topic (run records: the dynamic acceleration)
  or with ``raw``. Segmentation works on ``|a - trend|`` (:func:`_trend`).
* Dropouts: a stamp interval above 1.5 sample intervals (:func:`find_gaps`); non-finite samples
  are excluded, counted and count as dropouts. The fit of step 4 uses the samples present only;
  for the band-pass each dropout is filled with the first mode fitted to the samples within one
  period on either side (:func:`_fill_gaps`), then refilled with the fitted mode and fitted again.
  A dropout longer than ``max_gap_periods`` inside the fit window refuses the passage.
* Plausibility (:func:`sensor_warnings`): a dynamic peak above 50 m/s² or a static offset near
  neither 0 nor g is warned with its likely cause (units).
* A run of a numerical trial (:data:`adm_sim.protocol.TRIAL_PHASES`) has the level
  :data:`LEVEL_TRIAL`, never compared with the limit.

A passage whose free decay is too short (fewer than ``min_cycles`` periods), has a dropout longer
than ``max_gap_periods`` periods inside the fit window, too noisy (amplitude at its start below
``min_snr`` times the residual RMS), not exponential, or whose ζ1 is not positive or more
uncertain than ``max_rel_std`` gets no numbers: ``identified`` false and a one-line ``reason``.

Modules
-------
This module is the one name to import the wing by; the work is done in
:mod:`adm_sim.monitoring.modal_records` (settings, the fitted mode, the passage record),
:mod:`adm_sim.monitoring.modal_fit` (the steps of the first-mode identification),
:mod:`adm_sim.monitoring.modal_passages` (offset, peak, level, segmentation by the signal) and
:mod:`adm_sim.monitoring.modal_tracker` (the incremental :class:`PassageTracker`).
"""

from __future__ import annotations

from adm_sim.monitoring.modal_fit import find_gaps, identify_first_mode, uniform_samples
from adm_sim.monitoring.modal_passages import (G_M_S2, OFFSET_NEAR_G_M_S2, OFFSET_NEAR_ZERO_M_S2, analyse_passage,
                                               analyse_record, segment_signal, sensor_warnings, static_offset)
from adm_sim.monitoring.modal_records import (BASELINE_AFTER, BASELINE_BEFORE, BASELINE_BOTH, BASELINE_DYNAMIC,
                                              BASELINE_RAW, BASELINE_TAIL, FIT_GAP_FREE, FIT_PRESENT, LEVEL_TRIAL,
                                              LEVELS, IdentifySettings, ModalFit, Passage, acc_level)
from adm_sim.monitoring.modal_tracker import STAMP_TOLERANCE_S, PassageTracker, run_topics_for

__all__ = ["BASELINE_AFTER", "BASELINE_BEFORE", "BASELINE_BOTH", "BASELINE_DYNAMIC", "BASELINE_RAW", "BASELINE_TAIL",
           "FIT_GAP_FREE", "FIT_PRESENT", "G_M_S2", "LEVELS", "LEVEL_TRIAL", "OFFSET_NEAR_G_M_S2", "OFFSET_NEAR_ZERO_M_S2",
           "STAMP_TOLERANCE_S", "IdentifySettings", "ModalFit", "Passage", "PassageTracker", "acc_level",
           "analyse_passage", "analyse_record", "find_gaps", "identify_first_mode", "run_topics_for", "segment_signal",
           "sensor_warnings", "static_offset", "uniform_samples"]
