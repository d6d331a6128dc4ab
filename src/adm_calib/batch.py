"""Batched calibration: Section 4's steps 1-3 for many bridges at once, in lockstep.

:func:`calibrate_batch` runs :func:`adm_calib.calibrate.calibrate_cases` (the one calibration)
over :class:`adm_calib.lanes.CompiledLanes`: every sweep of every bridge is a lane of one compiled
run (:class:`adm_sim.batch.BatchRunner`):

1. one MLM run: every bridge x every speed;
2. one DIM run over every bridge's Section 3.3 speeds, then at most two refinement runs;
3. one MLM run over every bridge's damping ladder (bracketing), then the roots of
   ``peak_MLM(zeta + dz) / peak_DIM - 1`` for all bracketed bridges together with
   :func:`scipy.optimize.elementwise.find_root` (Chandrupatla, vectorised): one batched MLM run
   per iteration, tolerance ``xtol`` on Δζ;
4. one MLM run at every root (the check of the match).

Space step: all lanes share one ``ds``; by default the smallest of the bridges' own calibration
steps (:func:`adm_calib.calibrate.batch_step`).
"""

from __future__ import annotations

from adm_calib.calibrate import CalibrationOptions, _speeds, batch_step, calibrate_cases
from adm_calib.lanes import CompiledLanes

__all__ = ["batch_step", "calibrate_batch"]


def calibrate_batch(bridges, train, speeds_kmh=None, options=None, step=None):
    """Calibrate Δζ_VBI for every bridge (one span) under ``train``, all in lockstep.

    Parameters
    ----------
    bridges : sequence of adm_sim.bridge.Bridge
        Same span, mode count and damping model.
    train : adm_sim.trains.Train
    speeds_kmh : array_like, optional
        MLM speeds (km/h); default 160..350 at 1 km/h.
    options : CalibrationOptions, optional
    step : adm_sim.stepping.StepOptions, optional
        Shared step (``ds_m`` set); default :func:`batch_step`.

    Returns
    -------
    list of CalibrationResult
        One per bridge, in order; ``solve.method`` is ``"find_root"`` (``"exact"`` when a ladder
        point is the root). ``timings_s`` holds the batch's phase times divided by its size.
    """
    opt = options or CalibrationOptions()
    v = _speeds(speeds_kmh)
    step = step or batch_step(bridges, train, v, opt)
    return calibrate_cases(bridges, train, CompiledLanes(bridges, train, step), v, opt, step)
