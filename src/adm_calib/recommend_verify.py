"""A recommendation that holds: is a lower bound Δζ_LB conservative, and the value that is.

A lower bound (paper Section 4.3, Eq. 20) is conservative for a bridge when the bridge's own
Δζ_VBI (Section 4) is at least the bound: the MLM with ``zeta + Δζ_LB`` then peaks at least as
high as the DIM. Two sources of evidence, in the order of their weight:

* **the engineer's own calibration** (:func:`verify`, ``recommend --verify`` and the check's
  ``--damping lb``): the bridge and train of the question calibrated (Section 4) over the design
  speed range; the value that holds is ``min(Δζ_LB, Δζ_VBI)`` (the lower damping gives the higher
  MLM response), reported beside the bound with the calibration's status. Where Δζ_VBI is not
  determined (:data:`adm_calib.peaks.UNDETERMINED_STATUSES`) the minimum is still taken, and the
  bound is not called conservative.
* **the shipped study's nearby cases** (:func:`study_verdict`, every ``recommend``): the cases of
  the same train and mass function(s) within +-0.5 Hz of the asked n0
  (:func:`adm_calib.recommend_warnings.neighbourhood`); the bound is conservative there when none of
  them, retained or excluded, has a Δζ_VBI below it. No nearby case: not shown, so ``false``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from adm_calib.calibrate import calibrate
from adm_calib.recommend_warnings import NEIGHBOURHOOD_HZ, neighbourhood

#: Tolerance (%-points) of "Δζ_VBI at least the bound": the calibration's printed digits.
VERIFY_ATOL_PCT = 5e-5


@dataclass(frozen=True)
class Verdict:
    """Whether a Δζ is conservative, why, and from what evidence (``"study"`` or ``"calibration"``)."""

    conservative: bool
    reason: str
    source: str

    def to_dict(self):
        return {"conservative": self.conservative, "conservative_reason": self.reason,
                "conservative_source": self.source}


def study_verdict(rec, cases=None, half_width_hz=NEIGHBOURHOOD_HZ):
    """:class:`Verdict` of a :class:`adm_calib.reference.Recommendation` from the shipped study's
    cases near it (same train and mass function(s), n0 within ``half_width_hz``)."""
    near = neighbourhood(rec.train, rec.mass_functions, rec.n0_hz, cases=cases, half_width_hz=half_width_hz)
    where = (f"{rec.train} {'/'.join(rec.mass_functions)} within +/-{half_width_hz:g} Hz of n0 = {rec.n0_hz:g} Hz")
    if not near:
        return Verdict(False, f"no study case of {where}: nothing shows the bound holds here; run --verify", "study")
    low = min(near, key=lambda c: c.delta_zeta_vbi_pct)
    below = [c for c in near if c.delta_zeta_vbi_pct < rec.delta_zeta_pct - VERIFY_ATOL_PCT]
    lowest = f"lowest dz_VBI {low.delta_zeta_vbi_pct:.4f} % ({low.bridge}, {low.n0_hz:.2f} Hz)"
    if below:
        return Verdict(False, f"{len(below)} of the {len(near)} study cases of {where} have dz_VBI below "
                              f"dz_LB = {rec.delta_zeta_pct:.4f} % ({lowest}); run --verify for this bridge", "study")
    return Verdict(True, f"all {len(near)} study cases of {where} have dz_VBI >= dz_LB ({lowest})", "study")


@dataclass(frozen=True)
class Verification:
    """The own calibration beside a bound (percent of critical damping).

    ``verified_pct = min(bound_pct, Δζ_VBI)`` (the bound where there is no Δζ_VBI); ``verdict``
    says whether the bound itself is conservative for this bridge.
    """

    bound_pct: float
    verified_pct: float
    calibration: object
    verdict: Verdict
    zeta_pct: float
    zeta_source: str
    speeds_text: str
    calibration_s: float
    total_s: float

    @property
    def status(self):
        return self.calibration.status

    @property
    def vbi_pct(self):
        return self.calibration.delta_zeta_vbi_pct

    def to_dict(self):
        r = self.calibration
        return {"bound_pct": self.bound_pct, "verified_pct": self.verified_pct,
                "rule": "min(bound, dz_VBI)", "delta_zeta_vbi_pct": self.vbi_pct,
                "calibration_status": r.status, "calibration_message": r.message,
                "delta_zeta_determined": r.determined, "advice": r.advice,
                "zeta_pct": self.zeta_pct, "zeta_source": self.zeta_source, "speeds": self.speeds_text,
                "mlm_peak": r.mlm_peak.to_dict(), "dim_peak": r.dim_peak.to_dict(),
                "calibration_s": self.calibration_s, "total_s": self.total_s, **self.verdict.to_dict()}

    def lines(self, name="dz_LB"):
        r = self.calibration
        vbi = "n/a" if self.vbi_pct is None else f"{self.vbi_pct:.4f} %"
        mark = "" if r.determined else f" NOT DETERMINED ({r.status})"
        out = [f"dz_verified = {self.verified_pct:.4f} %  = min({name} {self.bound_pct:.4f} %, dz_VBI {vbi}{mark})",
               f"calibration: status {r.status}: {r.message}",
               f"calibration: {r.bridge.describe()}; zeta {self.zeta_pct:.3f} % ({self.zeta_source}); "
               f"speeds {self.speeds_text}; {self.calibration_s:.2f} s"]
        if r.advice:
            out.append(f"advice: {r.advice}")
        return out


def verify(bound_pct, bridge, train, speeds_kmh=None, *, zeta_source="", speeds_text="", options=None):
    """Calibrate ``bridge`` x ``train`` (Section 4) and judge ``bound_pct`` against its Δζ_VBI.

    Parameters
    ----------
    bound_pct : float
        The lower bound (%), e.g. :attr:`adm_calib.reference.Recommendation.delta_zeta_pct`.
    bridge : adm_sim.model.bridge.Bridge
    train : adm_sim.model.trains.Train
        With vehicles (the DIM needs them).
    speeds_kmh : array_like, optional
        The design speed range (km/h); default 160..350 at 1 km/h (the study's).

    Returns
    -------
    Verification
    """
    t0 = time.perf_counter()
    res = calibrate(bridge, train, speeds_kmh, options=options, adapted_curve=False)
    t_cal = time.perf_counter() - t0
    vbi = res.delta_zeta_vbi_pct
    verified = float(bound_pct) if vbi is None else min(float(bound_pct), float(vbi))
    if vbi is None:
        verdict = Verdict(False, f"the calibration gave no dz_VBI ({res.status}: {res.message})", "calibration")
    elif not res.determined:
        verdict = Verdict(False, f"dz_VBI = {vbi:.4f} % is not determined ({res.status}); the lower of the two is "
                                 f"used", "calibration")
    elif vbi >= bound_pct - VERIFY_ATOL_PCT:
        verdict = Verdict(True, f"the bridge's own dz_VBI = {vbi:.4f} % >= {bound_pct:.4f} % (calibration, status ok)",
                          "calibration")
    else:
        verdict = Verdict(False, f"the bridge's own dz_VBI = {vbi:.4f} % < {bound_pct:.4f} %: the bound would let the "
                                 f"MLM peak fall below the DIM peak; use {verified:.4f} %", "calibration")
    return Verification(bound_pct=float(bound_pct), verified_pct=verified, calibration=res, verdict=verdict,
                        zeta_pct=100.0 * bridge.damping_ratio, zeta_source=zeta_source,
                        speeds_text=speeds_text or f"{res.mlm_speeds_kmh[0]:g}..{res.mlm_speeds_kmh[-1]:g} km/h",
                        calibration_s=t_cal, total_s=time.perf_counter() - t0)
