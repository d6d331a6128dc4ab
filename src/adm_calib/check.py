"""``adm-calib check``: the damping methods ``lb`` and ``vbi`` of the EN 1991-2 dynamic check.

The check itself (speeds, envelopes, refinement, static effects, the EN 1991-2 6.4.6.5(3)
comparison, screening, comfort, outputs) and the damping methods ``none`` and ``adm`` (the Eurocode
ADM, EN 1991-2 6.4.6.3.1 Eq. (6.13)) live in the core, :mod:`adm_sim.design.check`, which never imports
adm_calib. This module holds only what adm-calib adds, :func:`calibrated_damping`, passed to the
core as its ``damping_provider``
(``adm_sim.design.check.run_check(..., damping_provider=calibrated_damping)``):

* ``lb``: the paper's lower-bound functions (Eq. 20, Tables B1-B4, Section 4.3), only for the four
  trains of the study and bridges inside the studied field (:func:`adm_calib.reference.lower_bound_for`),
  verified by the bridge's own calibration: the check uses ``min(bound, Δζ_VBI)`` and names the
  calibration's status (:func:`adm_calib.recommend_verify.verify`);
* ``vbi``: Δζ_VBI calibrated for the real train (Section 4: the MLM peak matched to the DIM peak,
  :func:`adm_calib.calibrate.calibrate`).
"""

from __future__ import annotations

from adm_sim.design.check import CALIB_DAMPING_METHODS
from adm_sim.errors import InputError

from adm_calib.calibrate import calibrate
from adm_calib.recommend_verify import verify
from adm_calib.reference import lower_bound_for


def calibrated_damping(bridge, train, method, calibrate_options=None):
    """Δζ (%) and the sentence saying why for ``lb`` (paper Section 4.3) or ``vbi`` (Section 4):
    the core's ``damping_provider``. HSLM trains are refused by the core before this is called."""
    if method == "lb":
        pct, note = lower_bound_for(bridge, train)
        if pct is None:
            raise InputError(f"damping lb: {train.name} on {bridge.name or 'this bridge'}: {note}", field="damping")
        if not train.units:
            return pct, f"{train.name}: lower bound {pct:.3f} % ({note})"
        # the bridge's own calibration beside the bound: min(bound, Δζ_VBI) holds (adm_calib.recommend_verify)
        ver = verify(pct, bridge, train, options=calibrate_options)
        vbi = "n/a" if ver.vbi_pct is None else f"{ver.vbi_pct:.3f} %"
        return ver.verified_pct, (f"{train.name}: min(lower bound {pct:.3f} %, own dz_VBI {vbi}, calibration status "
                                  f"{ver.status}) = {ver.verified_pct:.3f} %; bound conservative: "
                                  f"{str(ver.verdict.conservative).lower()} ({ver.verdict.reason}); bound: {note}")
    if method == "vbi":
        if not train.units:
            raise InputError(f"damping vbi: {train.name!r} has no vehicles; Δζ_VBI needs the DIM", field="damping")
        res = calibrate(bridge, train, options=calibrate_options, adapted_curve=False)
        if res.delta_zeta_vbi is None:
            raise InputError(f"damping vbi: {train.name} on {bridge.name or 'this bridge'}: no Δζ_VBI "
                             f"({res.status}: {res.message}); use --damping none", field="damping")
        pct = res.delta_zeta_vbi_pct
        note = (f"{train.name}: calibrated Δζ_VBI = {pct:.3f} % (MLM peak {res.mlm_peak.acc_m_s2:.4f} m/s2 "
                f"matched to the DIM peak {res.dim_peak.acc_m_s2:.4f} m/s2, Section 4)")
        if not res.determined:
            note += f"; NOT DETERMINED ({res.status}): {res.advice or res.message}"
        return pct, note
    raise InputError(f"damping: {method!r} is not one of adm-calib's; allowed {', '.join(CALIB_DAMPING_METHODS)}", field="damping")
