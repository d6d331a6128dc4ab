"""The lower-bound function of paper Eq. (20) with its validity rules, in one place.

``dz(n0) = a n0^3 + b n0^2 + c n0 + d`` (Δζ in % of critical damping, n0 in Hz), Section 4.2.1
and Appendix B. Rules (Section 4.2.2, Appendix B): the function applies from the lower limit
2.1 Hz to its first real root above 2.1 Hz (the printed "upper limit"); the lower bound is zero
from that root on ("set to zero from the first intersection of the fitted polynomial with the
abscissa", Section 4.2.1). A function re-derived from study data over ``[lo, hi]`` Hz is not
extrapolated: where its cubic has no root below ``hi`` it is zero above ``hi`` (the paper fits
nothing above 21 Hz, Section 4.2.1). Below the lower limit the function is not defined.

Every caller (the published and re-derived functions of :mod:`adm_calib.reference`, the fits of
:mod:`adm_calib.study.fit`, the figures) evaluates the bound through :func:`lower_bound_pct`.
"""

from __future__ import annotations

import math

import numpy as np

from adm_sim.errors import InputError

#: Lower validity limit of the lower-bound functions (Hz), Section 4.2.2 and Appendix B.
LOWER_LIMIT_HZ = 2.1
#: Upper end of the n0 range the paper fitted (Hz): the last interval boundary of Section 4.2.1.
FIT_RANGE_MAX_HZ = 21.0


def first_root_hz(coefficients, lower_limit_hz=LOWER_LIMIT_HZ):
    """First real root of the cubic Eq. (20) above ``lower_limit_hz`` (Hz); ``inf`` if none.

    Section 4.2.1: the lower bound is set to zero from the first intersection with the abscissa.
    ``coefficients`` are ``(a, b, c, d)``, highest power first (:func:`numpy.polyval` order).
    """
    roots = np.roots(np.asarray(coefficients, dtype=float))
    real = sorted(r.real for r in roots if abs(r.imag) < 1e-9 * max(1.0, abs(r)) and r.real > lower_limit_hz)
    return float(real[0]) if real else math.inf


def zero_from_hz(coefficients, lower_limit_hz=LOWER_LIMIT_HZ, fit_range_max_hz=math.inf):
    """n0 (Hz) from which the bound is 0: the first root above the lower limit, or the end of the
    fitted range where the cubic has no root before it."""
    return min(first_root_hz(coefficients, lower_limit_hz), float(fit_range_max_hz))


def lower_bound_pct(coefficients, n0_hz, lower_limit_hz=LOWER_LIMIT_HZ, fit_range_max_hz=math.inf):
    """The lower bound Δζ (%) at ``n0_hz``: Eq. (20) from the lower limit up to the first root (or
    the end of the fitted range), 0 from there on.

    Parameters
    ----------
    coefficients : (a, b, c, d)
        Eq. (20), Δζ in %, n0 in Hz.
    n0_hz : float or array_like, any shape
        First natural frequency (Hz), >= ``lower_limit_hz``.
    lower_limit_hz : float
        2.1 Hz for every published and re-derived function.
    fit_range_max_hz : float
        Upper end of the n0 range the cubic was fitted over (``inf`` for the published functions,
        whose printed upper limits are their roots).

    Returns
    -------
    float or ndarray
        A float for a scalar ``n0_hz``, else an array of its shape.

    Raises
    ------
    InputError
        If any ``n0_hz`` is below the lower limit or not a number.
    """
    n0 = np.asarray(n0_hz, dtype=float)
    if np.any(~(n0 >= lower_limit_hz)):
        bad = n0.flat[int(np.argmax(~(n0 >= lower_limit_hz)))]
        raise InputError(f"n0_hz: {bad:g} Hz is outside the validity of Eq. (20); allowed >= {lower_limit_hz:g} Hz "
                         f"(Section 4.2.2)")
    top = zero_from_hz(coefficients, lower_limit_hz, fit_range_max_hz)
    out = np.where(n0 >= top, 0.0, np.polyval(np.asarray(coefficients, dtype=float), n0))
    return float(out) if out.ndim == 0 else out


__all__ = ["LOWER_LIMIT_HZ", "FIT_RANGE_MAX_HZ", "first_root_hz", "zero_from_hz", "lower_bound_pct"]
