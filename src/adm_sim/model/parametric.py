"""The parametric bridge field of the paper (Section 3.1.1, Table 1, Eq. 19): numbers only.

* n0 = a L^b power laws of the first natural frequency (Fig. 8): fit, upper and lower bound;
* the mass functions mu = k L + d (t/m) of Table 1, Eq. (19): mu1-mu3 concrete/filler beam
  (``cfb``), mu4-mu6 steel/composite (``sc``);
* the studied spans, 4 to 40 m every 1 m.

:func:`adm_sim.model.bridge.parametric_field` builds the 1110 bridges of Section 3.3 from these bands;
:mod:`adm_sim.model.plausibility` warns outside them. Imports only :mod:`adm_sim.errors`.
"""

from __future__ import annotations

from adm_sim.errors import InputError

#: n0 = a L^b power laws of Section 3.1.1 (fit, upper bound, lower bound).
N0_FIT = (97.76, -0.9124)
N0_UB = (113.1, -0.8312)
N0_LB = (82.43, -0.9937)
#: Table 1 mass functions mu = k L + d (t/m, Eq. 19); mu1-mu3 CFB, mu4-mu6 SC.
MASS_FUNCTIONS = {
    "mu1": (0.843, 10.45, "cfb"),
    "mu2": (0.7002, 8.539, "cfb"),
    "mu3": (0.5584, 6.627, "cfb"),
    "mu4": (0.1214, 9.5174, "sc"),
    "mu5": (0.1214, 5.918, "sc"),
    "mu6": (0.1214, 2.1691, "sc"),
}
FIELD_SPANS_M = tuple(float(L) for L in range(4, 41))


def field_frequencies_hz(span_m):
    """The five n0 of one span (Section 3.1.1): LB, mid(LB, fit), fit, mid(fit, UB), UB."""
    lb = N0_LB[0] * span_m ** N0_LB[1]
    fit = N0_FIT[0] * span_m ** N0_FIT[1]
    ub = N0_UB[0] * span_m ** N0_UB[1]
    return (lb, 0.5 * (lb + fit), fit, 0.5 * (fit + ub), ub)


def mass_function_t_m(name, span_m):
    """Mass per length (t/m) of mass function ``name`` (Eq. 19, Table 1)."""
    if name not in MASS_FUNCTIONS:
        raise InputError(f"mass_function: {name!r} unknown; allowed {', '.join(MASS_FUNCTIONS)}")
    k, d, _ = MASS_FUNCTIONS[name]
    return k * span_m + d


__all__ = ["N0_FIT", "N0_UB", "N0_LB", "MASS_FUNCTIONS", "FIELD_SPANS_M", "field_frequencies_hz", "mass_function_t_m"]
