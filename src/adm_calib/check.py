"""``adm-calib check``: the EN 1991-2 dynamic check of :mod:`adm_sim.check` with all four damping
methods.

The check itself (speeds, envelopes, refinement, static effects, the EN 1991-2 6.4.6.5(3)
comparison, screening, comfort, outputs) and the damping methods ``none`` and ``adm`` (the Eurocode
ADM, EN 1991-2 6.4.6.3.1 Eq. (6.13)) live in the core, :mod:`adm_sim.check`, which never imports
adm_calib. This module supplies what only adm-calib knows, as the core's ``damping_provider``:

* ``lb``: the paper's lower-bound functions (Eq. 20, Tables B1-B4, Section 4.3), only for the four
  trains of the study and bridges inside the studied field (:func:`adm_calib.reference.lower_bound_for`);
* ``vbi``: Δζ_VBI calibrated for the real train (Section 4: the MLM peak matched to the DIM peak,
  :func:`adm_calib.calibrate.calibrate`).

The core names are re-exported, so ``from adm_calib.check import run_check, TrainCheck, ...`` works
as before.
"""

from __future__ import annotations

from adm_sim import check as _core
from adm_sim.check import (  # noqa: F401  (re-exported: the check's names as adm_calib.check had them)
    ACC_LIMITS_M_S2, CALIB_DAMPING_METHODS, COMFORT_LEVELS_M_S2, DAMPING_METHODS, DAMPING_MODELS,
    DESIGN_SPEED_FACTOR, HSLM_B_SPAN_M, MIN_SPEED_M_S, REFINE_HALF_WIDTH_KMH, REFINE_MIN_FRACTION,
    REFINE_STEP_KMH, CheckResult, TrainCheck, _is_hslm, _refinement, check_speeds_kmh, comfort_b_v,
    comfort_level, resolve_trains, screening, static_midspan_max, static_midspan_max_m,
)
from adm_sim.errors import InputError


def calibrated_damping(bridge, train, method, calibrate_options=None):
    """Δζ (%) and the sentence saying why for ``lb`` (paper Section 4.3) or ``vbi`` (Section 4):
    the core's ``damping_provider``. HSLM trains are refused by the core before this is called."""
    if method == "lb":
        from adm_calib.reference import lower_bound_for

        pct, note = lower_bound_for(bridge, train)
        if pct is None:
            raise InputError(f"damping lb: {train.name} on {bridge.name or 'this bridge'}: {note}", field="damping")
        return pct, f"{train.name}: lower bound {pct:.3f} % ({note})"
    if method == "vbi":
        if not train.units:
            raise InputError(f"damping vbi: {train.name!r} has no vehicles; Δζ_VBI needs the DIM", field="damping")
        from adm_calib.calibrate import calibrate

        res = calibrate(bridge, train, options=calibrate_options, adapted_curve=False)
        if res.delta_zeta_vbi is None:
            raise InputError(f"damping vbi: {train.name} on {bridge.name or 'this bridge'}: no Δζ_VBI "
                             f"({res.status}: {res.message}); use --damping none", field="damping")
        pct = res.delta_zeta_vbi_pct
        return pct, (f"{train.name}: calibrated Δζ_VBI = {pct:.3f} % (MLM peak {res.mlm_peak.acc_m_s2:.4f} m/s2 "
                     f"matched to the DIM peak {res.dim_peak.acc_m_s2:.4f} m/s2, Section 4)")
    raise InputError(f"damping: {method!r} is not one of adm-calib's; allowed {', '.join(CALIB_DAMPING_METHODS)}", field="damping")


def delta_zeta_for(bridge, train, method, calibrate_options=None):
    """:func:`adm_sim.check.delta_zeta_for` with adm-calib's ``lb`` and ``vbi``."""
    return _core.delta_zeta_for(bridge, train, method, calibrate_options, damping_provider=calibrated_damping)


def run_check(*args, damping_provider=calibrated_damping, **kwargs):
    """:func:`adm_sim.check.run_check` with all four damping methods (``lb``, ``vbi`` from
    :func:`calibrated_damping`); same parameters, same :class:`CheckResult`."""
    return _core.run_check(*args, damping_provider=damping_provider, **kwargs)
