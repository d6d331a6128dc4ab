"""The shared space grid of a run and its discretisation settings.

Space grid
----------
All speed lanes share one grid of *train positions*: at step ``k`` the first axle stands at
``x = s_k = k ds`` on the bridge (``s = 0``: first axle on the left support). Lane ``l`` then has
the time step ``dt_l = ds / v_l``. Axle positions, the set of axles on the bridge, the MLM modal
loads and the active vehicles are therefore the same for every lane at every stage, which keeps a
whole speed sweep cheap. ``ds`` is chosen so that the slowest lane takes ``steps_per_period``
steps per period of the highest retained bridge mode; faster lanes get finer time steps.

Free vibration: the run continues after the last axle has left the bridge for at least
``free_vibration_periods`` (default 2) fundamental periods in every lane, because the largest
acceleration of a resonant crossing can occur up to one period after the train has left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from adm_sim.integrate._jit import RK4_C  # the RK4 tableau, shared with the numba kernels
from adm_sim.errors import InputError
from adm_sim.fields import FIELDS, check_range
from adm_sim.limits import check_work

SPEED_RANGE_KMH = FIELDS["speeds_kmh"].range


@dataclass(frozen=True, kw_only=True)
class StepOptions:
    """Discretisation settings.

    Parameters
    ----------
    steps_per_period : float
        RK4 steps per period of the highest retained bridge mode, at the slowest lane.
    free_vibration_periods : float
        Fundamental periods simulated after the last axle has left (every lane).
    ds_m : float or None
        Train advance per step (m); overrides ``steps_per_period``.
    dense_maxima : bool
        Also take the maximum |midspan acceleration| *between* the steps, from the integrator's
        dense output (:func:`adm_sim.integrate.dense_output.hermite_max_abs_acc`), not only at the step points. Off by default:
        the paper's numbers and the shipped study are the sampled maxima.
    irregularity : adm_sim.model.irregularity.Profile or None
        Track irregularity on the deck under the DIM wheels (:mod:`adm_sim.model.irregularity`);
        ``None`` (default): the paper's smooth track. The MLM ignores it.
    """

    steps_per_period: float = 16.0
    free_vibration_periods: float = 2.0
    ds_m: float | None = None
    dense_maxima: bool = False
    irregularity: object = None

    def __post_init__(self):
        FIELDS["steps_per_period"].check(self.steps_per_period)
        FIELDS["free_vibration_periods"].check(self.free_vibration_periods)
        if self.ds_m is not None:
            FIELDS["ds_m"].check(self.ds_m)

    def halved(self):
        """The same settings with half the step (for convergence checks)."""
        ds = None if self.ds_m is None else 0.5 * self.ds_m
        return StepOptions(steps_per_period=2.0 * self.steps_per_period,
                           free_vibration_periods=self.free_vibration_periods, ds_m=ds,
                           dense_maxima=self.dense_maxima, irregularity=self.irregularity)


@dataclass(frozen=True, kw_only=True)
class Grid:
    """The shared space grid of a run.

    Attributes
    ----------
    speeds_m_s : ndarray, shape (n_lanes,)
    ds_m : float
        Train advance per step (m).
    n_steps : int
        Number of RK4 steps.
    """

    speeds_m_s: np.ndarray
    ds_m: float
    n_steps: int

    @property
    def n_lanes(self):
        return len(self.speeds_m_s)

    @property
    def dt_s(self):
        """Time step per lane (s), shape (n_lanes,)."""
        return self.ds_m / self.speeds_m_s

    def front_m(self, k, stage=0):
        """Position of the first axle at step ``k``, RK stage ``stage`` (m from the left support)."""
        return (k + RK4_C[stage]) * self.ds_m

    def clock_time_s(self, k, stage=0):
        """One time for the whole run: the time of the slowest lane (for ``/clock``)."""
        return self.front_m(k, stage) / float(self.speeds_m_s.min())


def speeds_to_m_s(speeds_kmh):
    """Validate speeds (km/h) and convert to m/s, shape (n_lanes,)."""
    v = np.atleast_1d(np.asarray(speeds_kmh, dtype=float))
    if v.ndim != 1 or v.size == 0:
        raise InputError("speeds_kmh: need a non-empty list of speeds (km/h)")
    lo, hi = SPEED_RANGE_KMH
    if not (np.all(np.isfinite(v)) and v.min() >= lo and v.max() <= hi):  # the first bad speed's message
        for x in v:
            check_range("speed_kmh", x, "km/h", lo, hi)
    return v / 3.6


def make_grid(bridge, train_length_m, speeds_m_s, options=None):
    """Space grid covering the crossing of a train and the free vibration afterwards."""
    options = options or StepOptions()
    v = np.asarray(speeds_m_s, dtype=float)
    if options.ds_m is not None:
        ds = float(options.ds_m)
    else:
        t_top = 2.0 * math.pi / bridge.omega_rad_s[-1]
        ds = float(v.min()) * t_top / options.steps_per_period
    t1 = 1.0 / bridge.n0_hz
    travel = train_length_m + bridge.span_m + options.free_vibration_periods * t1 * float(v.max())
    steps = travel / ds

    def why():  # the inputs that make the run large, for a refusal only
        if options.ds_m is not None:
            how = f"ds = {ds * 1e3:.3g} mm given"
        else:
            how = (f"ds = {ds * 1e3:.3g} mm from the top mode ({bridge.n_modes} modes, "
                   f"{bridge.omega_rad_s[-1] / (2 * math.pi):.4g} Hz) at {options.steps_per_period:g} steps per "
                   f"period and {float(v.min()) * 3.6:g} km/h")
        return (f"large because {v.size} speeds x ({travel:.4g} m of train, span and free vibration / {how}); "
                f"fewer speeds, fewer modes or fewer steps per period make it smaller")

    check_work(v.size, steps if steps >= 2**62 else int(math.ceil(steps)), bridge.n_modes, why)
    return Grid(speeds_m_s=v, ds_m=ds, n_steps=int(math.ceil(steps)))
