"""Settings of one calibration (paper Section 4) and its speed range (Section 3.3).

:class:`CalibrationOptions` holds the rules' numbers (DIM grid, association and relocation
windows, root tolerance, peak-match acceptance); :func:`check_speeds` the MLM speeds every run of a
calibration shares (default 160..350 km/h at 1 km/h).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError
from adm_sim.fields import check_range
from adm_sim.fields import FIELDS
from adm_sim.limits import default_speeds_kmh
from adm_sim.integrate.step_grid import StepOptions, speeds_to_m_s

from adm_calib import peaks as pk

#: Default speed range (km/h), Section 3.3 (one home: :mod:`adm_sim.limits`).
DEFAULT_SPEEDS_KMH = default_speeds_kmh()

#: Root tolerance on Δζ (fraction) fitted to the digits a calibration prints: Δζ in percent to four
#: decimals (0.5533 %), so the search stops when the bracket is narrower than half a unit of the
#: last digit, 0.00005 % = 5e-7. The root returned is an end of that bracket, so it lies within
#: 0.00005 % of the exact root (B1 x ICE-2: 0.55331 % against 0.5532986 % at 1e-8, in 3 root
#: runs instead of 6).
XTOL_DELTA_ZETA = 5e-7
#: Root tolerance of the parametric study (its results are compared case by case to 1e-6 %).
XTOL_STUDY = 1e-8


@dataclass(frozen=True)
class CalibrationOptions:
    """Settings of one calibration (speeds in km/h, damping as fractions).

    Parameters
    ----------
    dim_grid : {"paper", "window", "full"}
        DIM speeds as in Section 3.3 (coarse + refined), the part of them where the associated DIM
        peak can lie (:func:`adm_calib.speed_grids.dim_speeds_window`: the same result, about half the
        DIM lanes), or at every MLM speed.
    dim_coarse_step_kmh : float
        Coarse DIM step (paper: 5 km/h).
    dim_refine_kmh : (float, float)
        Fine DIM interval ``[v_max - below, v_max + above]`` around the MLM peak (paper: 20, 5).
    association_window_kmh : (float, float)
        DIM peak association window below/above the MLM peak speed (see :mod:`adm_calib.peaks`).
    relocation_window_kmh : float
        Half width of the window in which the MLM peak is re-located at trial dampings.
    xtol : float
        Absolute tolerance of the root in Δζ (fraction); default :data:`XTOL_DELTA_ZETA`
        (half a unit of the printed fourth decimal of Δζ in percent).
    match_rtol : float
        Acceptance of the peak match (paper: 0.1 %).
    min_prominence_rel : float
        Smallest relative prominence of a peak.
    step : adm_sim.integrate.step_grid.StepOptions or None
        Time-integration settings of the core (``None``: its defaults).
    ladder_first_stage : float or None
        Damping ladder of the root's bracket in two requests: the trial dampings up to this value
        (fraction) first, the rest only for the cases without a sign change in them (the bracket is
        the first sign change, so it is the same; fewer MLM lanes). ``None`` (default): the whole
        ladder in one request.
    speed_refinement_kmh : float or None
        Refined mode: locate the MLM peak and the DIM peak to this speed resolution (e.g. 0.05
        km/h) between the neighbours of the peak on the MLM speed grid (:func:`refine_peaks`).
        ``None`` (default): the paper's rule, peaks as sampled on the 1 km/h grid.
    """

    dim_grid: str = "paper"
    dim_coarse_step_kmh: float = 5.0
    dim_refine_kmh: tuple = (20.0, 5.0)
    association_window_kmh: tuple = pk.ASSOCIATION_WINDOW_KMH
    relocation_window_kmh: float = 5.0
    xtol: float = XTOL_DELTA_ZETA
    match_rtol: float = 1e-3
    min_prominence_rel: float = pk.MIN_PROMINENCE_REL
    step: StepOptions | None = None
    speed_refinement_kmh: float | None = None
    ladder_first_stage: float | None = None

    def __post_init__(self):
        FIELDS["dim_grid"].check(self.dim_grid)
        check_range("dim_coarse_step_kmh", self.dim_coarse_step_kmh, "km/h", 0.0, 100.0, lo_open=True)
        check_range("relocation_window_kmh", self.relocation_window_kmh, "km/h", 0.0, 100.0, lo_open=True)
        check_range("xtol", self.xtol, "- (fraction)", 0.0, 1e-4, lo_open=True)
        check_range("match_rtol", self.match_rtol, "-", 0.0, 0.1, lo_open=True)
        if self.speed_refinement_kmh is not None:
            check_range("speed_refinement_kmh", self.speed_refinement_kmh, "km/h", 0.001, 1.0)


def check_speeds(speeds_kmh):
    """The MLM speeds (km/h) of a calibration: the default range, or the given ones sorted and unique
    (at least 3, each a valid speed)."""
    v = DEFAULT_SPEEDS_KMH if speeds_kmh is None else np.asarray(speeds_kmh, dtype=float)
    if v.ndim != 1 or v.size < 3:
        raise InputError(f"speeds_kmh: need at least 3 speeds (km/h), got {v.size}", field="speeds_kmh")
    v = np.unique(v)
    speeds_to_m_s(v)
    return v
