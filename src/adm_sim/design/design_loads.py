"""EN 1991-2 6.4.6.5(3): the design comparison of a dynamic analysis with Φ x α x LM71.

Where a dynamic analysis is required, EN 1991-2:2003 6.4.6.5(3) asks the bridge to be designed for
the more unfavourable of

    (1 + φ'_dyn + φ''/2) x (HSLM or real train, static)    and    Φ x (α x LM71, static),

for every load effect (here: the midspan bending moment and the midspan deflection of a simply
supported span; :mod:`adm_sim.design.check_effects` does the moment and shear along the span and the
reactions). φ''/2 is the carefully maintained track's share (Annex C's ``1 + φ' + φ''/2``, with
Φ2); for standard maintenance (Φ3) the full φ'' of Annex C's ``1 + φ' + φ''`` is used
(:func:`phi_dd_factor`). Annex C's two formulas are cited by their content: the equation numbers
the standard's text gives them could not be confirmed here. Standard maintenance (Φ3) is the
default: EN 1991-2 6.4.5.2(3)P uses Φ3 where no dynamic factor is specified
(:data:`DEFAULT_MAINTENANCE`). The pieces, each with its clause:

* φ'_dyn = max |y_dyn / y_stat| - 1, EN 1991-2 6.4.6.5(3) Eq. (6.14): the dynamic *increment*
  (not the ratio), y_dyn the largest dynamic response of the train over the speeds of the analysis
  and y_stat the largest static response of the same train at the same point;
  :func:`phi_dyn_prime`.
* φ'' (track irregularities), EN 1991-2 Annex C Eqs. (C.6)-(C.8):
  ``φ'' = α_v / 100 [56 e^-(LΦ/10)^2 + 50 (LΦ n0 / 80 - 1) e^-(LΦ/20)^2] >= 0``,
  ``α_v = v / 22`` for v <= 22 m/s else 1; :func:`phi_double_prime`. φ' of Annex C (C.3)-(C.5),
  ``φ' = K / (1 - K + K^4)`` for K < 0.76 else 1.325, ``K = v / (2 LΦ n0)``, is
  :func:`phi_prime` (a cross-check; 6.4.6.5 uses φ'_dyn from the analysis instead).
* Φ, EN 1991-2 6.4.5.2: Φ2 = 1.44 / (sqrt(LΦ) - 0.2) + 0.82 within [1.00, 1.67] for carefully
  maintained track (Eq. 6.4), Φ3 = 2.16 / (sqrt(LΦ) - 0.2) + 0.73 within [1.00, 2.00] for
  standard maintenance (Eq. 6.5); LΦ the determinant length, the span for a simply supported main
  girder (Table 6.2, case 5.1); :func:`phi2`, :func:`phi3`, :func:`dynamic_factor`.
* the Eurocode ADM, EN 1991-2 6.4.6.3.1 Eq. (6.13), Fig. 6.15: the additional damping Δζ (%) of a
  span L < 30 m, ``(0.0187 L - 0.00064 L^2) / (1 - 0.0441 L - 0.0044 L^2 + 0.000255 L^3)``, 0 for
  L >= 30 m; :func:`adm_delta_zeta_pct` (``adm_calib.reference`` re-exports it).
* LM71, EN 1991-2 6.3.2 Fig. 6.2: four 250 kN axles at 1.6 m with 0.8 m to the 80 kN/m
  distributed load on both sides, unlimited (so the point forces take a 6.4 m window out of the
  distributed load), times the classification factor α of 6.3.2(3) (0.75, 0.83, 0.91, 1.00, 1.10,
  1.21, 1.33, 1.46; 1.00 unless specified; 1.33 is common on new high-speed lines);
  :func:`lm71_midspan`.

Statics of the simply supported span (Euler-Bernoulli, span L, stiffness EJ), by influence lines.
A point force P at ``a <= L/2`` from the nearer support gives the midspan moment ``P a / 2`` and the
midspan deflection ``P a (3 L^2 - 4 a^2) / (48 EJ)``; a distributed load q over the whole span
``q L^2 / 8`` and ``5 q L^4 / (384 EJ)``; partial distributed loads integrate the same influence
lines in closed form.

Maxima over positions are exact, not sampled: between two breakpoints (an axle, or an end of the
LM71 point-force window, crossing a support or midspan) the effect is a polynomial in the
position of the load (degree 1 for the moment of an axle train, 2 for the LM71 moment, 3 for the
deflection of an axle train, 4 for the LM71 deflection), whose maximum is at a breakpoint or at a
root of its derivative; both are evaluated (:func:`_piecewise_polynomial_max`). For the moment of
an axle train this reduces to "an axle at midspan" (the moment is piecewise linear and only the
midspan kink of the influence line is concave). For LM71 the largest midspan moment has an axle
at midspan, not the four axles symmetric about it: shifting the group by 0.8 m keeps the
point-force part and adds ``q 0.8^2 / 2 = 25.6 kNm`` of distributed load (x α).

Independent public sources read for the formulas (their code is not used here): Annex C K, φ', α_v
and φ'' as coded in bacadra/bacadra's EN 15528 dynamic-factor class (identical to ours); Φ2, Φ3
in an Italian NTC18 implementation (same formulas; it caps Φ2 at 2.0 where EN caps it at 1.67) and
Φ3(35 m) = 1.1079 quoted from a design report; φ'_dyn = y_dyn / y_stat - 1 per response quantity
(moment and deflection each their own) in addeKTH/BeamDyn ``dynamicfactor.js``. The equation
numbers (6.4), (6.5), (6.14), (C.3)-(C.8) are as we read EN 1991-2:2003; no stored copy of the
printed text was found to confirm them.

numpy only; no ROS.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError
from adm_sim.fields import check_choice, check_range

#: Classification factors α allowed by EN 1991-2 6.3.2(3).
LM71_ALPHAS = (0.75, 0.83, 0.91, 1.00, 1.10, 1.21, 1.33, 1.46)
#: LM71 (EN 1991-2 6.3.2 Fig. 6.2): axle load Q_vk (N), distributed load q_vk (N/m).
LM71_AXLE_LOAD_N = 250e3
LM71_UDL_N_M = 80e3
#: Axle positions relative to the centre of the point-force group (m), 1.6 m apart, and half its
#: window (m): 0.8 m + 3 x 1.6 m + 0.8 m = 6.4 m free of the distributed load.
LM71_AXLES_M = (-2.4, -0.8, 0.8, 2.4)
LM71_HALF_WINDOW_M = 3.2
#: Track maintenance classes of EN 1991-2 6.4.5.2(2)/(3).
MAINTENANCE = ("careful", "standard")
#: The default: EN 1991-2 6.4.5.2(3)P, where no dynamic factor is specified Φ3 (standard maintenance) is used.
DEFAULT_MAINTENANCE = "standard"
#: Annex C's dynamic factor of a real train per track maintenance, cited by its content (the equation
#: numbers of the standard's text could not be confirmed here).
ANNEX_C_FORMULA = {"standard": "1 + phi' + phi''", "careful": "1 + phi' + phi''/2"}


def maintenance_text(maintenance, named_by_user):
    """One line: which Φ and which share of φ'' the check uses, and why (the user named careful
    maintenance, or the standard's default for no specified dynamic factor)."""
    if maintenance == "careful":
        return ("Phi2 and phi''/2 (carefully maintained track, EN 1991-2 6.4.5.2(2); Annex C: "
                f"{ANNEX_C_FORMULA['careful']}): named with --track-maintenance careful")
    why = ("named with --track-maintenance standard" if named_by_user else
           "the default: EN 1991-2 6.4.5.2(3)P uses Phi3 where no dynamic factor is specified; give "
           "--track-maintenance careful for carefully maintained track (Phi2)")
    return (f"Phi3 and phi'' (standard maintenance, EN 1991-2 6.4.5.2(3); Annex C: "
            f"{ANNEX_C_FORMULA['standard']}): {why}")


# --------------------------------------------------------------------------- dynamic factors

def _length(name, value):
    return check_range(name, value, "m", 0.0, None, lo_open=True)


def phi2(L_phi_m):
    """Dynamic factor Φ2 for carefully maintained track, EN 1991-2 6.4.5.2(2) Eq. (6.4).

    ``Φ2 = 1.44 / (sqrt(LΦ) - 0.2) + 0.82`` with ``1.00 <= Φ2 <= 1.67``.

    Parameters
    ----------
    L_phi_m : float
        Determinant length LΦ (m), > 0 (EN 1991-2 Table 6.2; the span for a simply supported
        main girder, case 5.1). The upper bound holds up to LΦ = 3.59 m, the lower from 67.24 m.
    """
    L = _length("L_phi_m", L_phi_m)
    d = math.sqrt(L) - 0.2
    if d <= 1.44 / (1.67 - 0.82):  # also covers sqrt(L) <= 0.2, where the formula has no meaning
        return 1.67
    return min(1.67, max(1.00, 1.44 / d + 0.82))


def phi3(L_phi_m):
    """Dynamic factor Φ3 for standard maintenance, EN 1991-2 6.4.5.2(3) Eq. (6.5).

    ``Φ3 = 2.16 / (sqrt(LΦ) - 0.2) + 0.73`` with ``1.00 <= Φ3 <= 2.00``.

    Parameters
    ----------
    L_phi_m : float
        Determinant length LΦ (m), > 0. The upper bound holds up to LΦ = 3.61 m, the lower
        from 67.24 m.
    """
    L = _length("L_phi_m", L_phi_m)
    d = math.sqrt(L) - 0.2
    if d <= 2.16 / (2.00 - 0.73):
        return 2.00
    return min(2.00, max(1.00, 2.16 / d + 0.73))


def dynamic_factor(L_phi_m, maintenance=DEFAULT_MAINTENANCE):
    """Φ of EN 1991-2 6.4.5.2: Φ2 for ``"careful"``, Φ3 for ``"standard"`` track maintenance."""
    m = check_choice("maintenance", maintenance, MAINTENANCE)
    return phi2(L_phi_m) if m == "careful" else phi3(L_phi_m)


def _annex_c_inputs(L_phi_m, n0_hz, v_m_s):
    L = _length("L_phi_m", L_phi_m)
    n0 = check_range("n0_hz", n0_hz, "Hz", 0.0, None, lo_open=True)
    v = check_range("v_m_s", v_m_s, "m/s", 0.0, None)
    return L, n0, v


def phi_double_prime(L_phi_m, n0_hz, v_m_s):
    """φ'' of EN 1991-2 Annex C Eqs. (C.6)-(C.8): the effect of track irregularities.

    ``φ'' = α / 100 [56 e^-(LΦ/10)^2 + 50 (LΦ n0 / 80 - 1) e^-(LΦ/20)^2]``, ``φ'' >= 0``,
    ``α = v / 22`` if ``v <= 22 m/s``, else 1.

    Parameters
    ----------
    L_phi_m : float
        Determinant length LΦ (m), > 0.
    n0_hz : float
        First natural bending frequency of the loaded bridge (Hz), > 0.
    v_m_s : float
        Maximum permitted vehicle speed (m/s), >= 0 (Annex C). Above 22 m/s (79.2 km/h) φ'' does
        not depend on it.
    """
    L, n0, v = _annex_c_inputs(L_phi_m, n0_hz, v_m_s)
    alpha = v / 22.0 if v <= 22.0 else 1.0
    value = alpha / 100.0 * (56.0 * math.exp(-((L / 10.0) ** 2))
                             + 50.0 * (L * n0 / 80.0 - 1.0) * math.exp(-((L / 20.0) ** 2)))
    return max(0.0, value)


def phi_prime(L_phi_m, n0_hz, v_m_s):
    """φ' of EN 1991-2 Annex C Eqs. (C.3)-(C.5), for a cross-check of φ'_dyn.

    ``K = v / (2 LΦ n0)``; ``φ' = K / (1 - K + K^4)`` for ``K < 0.76``, else 1.325.
    """
    L, n0, v = _annex_c_inputs(L_phi_m, n0_hz, v_m_s)
    K = v / (2.0 * L * n0)
    return K / (1.0 - K + K**4) if K < 0.76 else 1.325


def phi_dyn_prime(max_dyn, max_stat):
    """Dynamic increment φ'_dyn = max |y_dyn / y_stat| - 1, EN 1991-2 6.4.6.5(3) Eq. (6.14).

    Parameters
    ----------
    max_dyn : float or array_like
        Largest dynamic response y_dyn: one value, or one per speed ``(n_speeds,)``.
    max_stat : float or array_like
        The corresponding largest static response y_stat (same unit), non-zero: one value, or one
        per entry of ``max_dyn``.

    Returns
    -------
    float
        The increment (a ratio of 1.644 gives 0.644).
    """
    dyn = np.atleast_1d(np.asarray(max_dyn, dtype=float))
    stat = np.atleast_1d(np.asarray(max_stat, dtype=float))
    if dyn.size == 0 or not np.all(np.isfinite(dyn)):
        raise InputError(f"max_dyn: {max_dyn!r} must be one or more finite numbers")
    if not np.all(np.isfinite(stat)) or np.any(stat == 0.0):
        raise InputError(f"max_stat: {max_stat!r} must be finite and non-zero (the static response y_stat)")
    try:
        ratio = np.abs(dyn / stat)
    except ValueError:
        raise InputError(f"max_stat: {stat.size} values do not match the {dyn.size} of max_dyn; "
                         "give one value or one per max_dyn entry") from None
    return float(ratio.max() - 1.0)


def phi_dd_factor(maintenance):
    """The share r of φ'' in ``1 + φ'_dyn + r φ''``: EN 1991-2 Annex C gives the dynamic factor of a
    real train as ``1 + φ' + φ''/2`` for carefully maintained track and ``1 + φ' + φ''`` for
    standard maintenance (cited by content: the equation numbers could not be confirmed here);
    6.4.6.5(3) Eq. (6.15) writes ``φ''/2``, the careful-track case, the one its Φ2 alternative
    pairs with. With standard maintenance (Φ3) the full φ'' goes with it, as in ``1 + φ' + φ''``.
    Returns 0.5 for ``"careful"``, 1.0 for ``"standard"``. An independent public
    implementation pairs them the same way (bacadra/bacadra ``bacadra/bicad/railb/en155.py``, commit
    0399243f: mode 'clea' ``1 + φ' + 0.50 φ''``, mode 'stan' ``1 + φ' + φ''``; tested to 1e-12)."""
    m = check_choice("maintenance", maintenance, MAINTENANCE)
    return 0.5 if m == "careful" else 1.0


# --------------------------------------------------------------------------- Eurocode ADM
def adm_delta_zeta_pct(span_m):
    """Additional damping of the Eurocode ADM (%), EN 1991-2 6.4.6.3.1 Eq. (6.13), Fig. 6.15.

    Parameters
    ----------
    span_m : float
        Span L (m), > 0.

    Returns
    -------
    float
        ``(0.0187 L - 0.00064 L^2) / (1 - 0.0441 L - 0.0044 L^2 + 0.000255 L^3)`` for L < 30 m,
        else 0.
    """
    L = check_range("span_m", span_m, "m", 0.0, None, lo_open=True)
    if L >= 30.0:
        return 0.0
    # The rational function dips below zero (by at most 0.003 %) for 29.2 m < L < 30 m; the
    # standard's Fig. 6.15 ends at zero there, and additional damping is never negative.
    return max(0.0, (0.0187 * L - 0.00064 * L**2) / (1.0 - 0.0441 * L - 0.0044 * L**2 + 0.000255 * L**3))


def check_alpha(alpha):
    """The classification factor α if it is one of EN 1991-2 6.3.2(3), else :class:`InputError`."""
    allowed_text = ", ".join(f"{x:.2f}" for x in LM71_ALPHAS)
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        a = math.nan
    if isinstance(alpha, bool) or not math.isfinite(a):
        raise InputError(f"alpha: {alpha!r} is not a number; allowed a classification factor of EN 1991-2 "
                         f"6.3.2(3): {allowed_text}")
    for allowed in LM71_ALPHAS:
        if abs(a - allowed) < 1e-9:
            return allowed
    raise InputError(f"alpha: {a:g} is not a classification factor of EN 1991-2 6.3.2(3); allowed "
                     f"{', '.join(f'{x:.2f}' for x in LM71_ALPHAS)}")


# --------------------------------------------------------------------------- influence lines

def _span_ej(span_m, EJ_Nm2):
    L = check_range("span_m", span_m, "m", 0.0, None, lo_open=True)
    EJ = check_range("EJ_Nm2", EJ_Nm2, "N m^2", 0.0, None, lo_open=True)
    return L, EJ


def _moment_influence(x, L):
    """Midspan moment per unit force at ``x`` from midspan (m): ``a / 2``, a the distance to the
    nearer support; zero off the span. Shape of ``x``."""
    a = L / 2.0 - np.abs(x)
    return np.where(a > 0.0, a / 2.0, 0.0)


def _deflection_influence(x, L, EJ):
    """Midspan deflection per unit force at ``x`` from midspan: ``a (3 L^2 - 4 a^2) / (48 EJ)``."""
    a = L / 2.0 - np.abs(x)
    return np.where(a > 0.0, a * (3.0 * L * L - 4.0 * a * a) / (48.0 * EJ), 0.0)


def _moment_area(x, L):
    """Integral of the moment influence line from midspan to ``x`` (clipped to the span); odd in x."""
    u = np.clip(x, -L / 2.0, L / 2.0)
    return L * u / 4.0 - u * np.abs(u) / 4.0


def _deflection_area(x, L, EJ):
    """Integral of the deflection influence line from midspan to ``x`` (clipped); odd in x.

    With ``F(a) = 3 L^2 a^2 / 2 - a^4``: ``sign(x) [F(L/2) - F(L/2 - |x|)] / (48 EJ)``.
    """
    u = np.clip(x, -L / 2.0, L / 2.0)
    a = L / 2.0 - np.abs(u)
    F = lambda b: 1.5 * L * L * b * b - b**4  # noqa: E731
    return np.sign(u) * (F(L / 2.0) - F(a)) / (48.0 * EJ)


def point_load_midspan(span_m, EJ_Nm2, a_m, load_n=1.0):
    """Midspan moment (N m) and deflection (m) of a force at ``a_m`` from the left support.

    Closed forms for ``a <= L/2`` (mirrored beyond): ``M = P a / 2``,
    ``w = P a (3 L^2 - 4 a^2) / (48 EJ)``; zero off the span.
    """
    L, EJ = _span_ej(span_m, EJ_Nm2)
    x = np.asarray(a_m, dtype=float) - L / 2.0
    return load_n * _moment_influence(x, L), load_n * _deflection_influence(x, L, EJ)


def udl_midspan(span_m, EJ_Nm2, q_n_m, start_m=None, end_m=None):
    """Midspan moment (N m) and deflection (m) of a distributed load q on ``[start, end]``.

    Whole span (the default): ``q L^2 / 8`` and ``5 q L^4 / (384 EJ)``; a part: the closed-form
    integral of the influence lines. Positions from the left support, clipped to the span.
    """
    L, EJ = _span_ej(span_m, EJ_Nm2)
    x0 = -L / 2.0 if start_m is None else float(start_m) - L / 2.0
    x1 = L / 2.0 if end_m is None else float(end_m) - L / 2.0
    if x1 < x0:
        raise InputError(f"end_m: {x1 + L / 2:g} m is before start_m {x0 + L / 2:g} m")
    M = q_n_m * float(_moment_area(x1, L) - _moment_area(x0, L))
    w = q_n_m * float(_deflection_area(x1, L, EJ) - _deflection_area(x0, L, EJ))
    return M, w


# --------------------------------------------------------------------------- exact maxima

def _piecewise_polynomial_max(f, breakpoints, degree):
    """Largest value of ``f`` over ``[breakpoints[0], breakpoints[-1]]`` and where it occurs.

    ``f`` (vectorised) must be a polynomial of at most ``degree`` between consecutive breakpoints.
    On each piece the polynomial is interpolated through ``degree + 1`` points (exact up to
    round-off) and ``f`` itself is evaluated at the piece ends and at the real roots of the
    derivative inside the piece.
    """
    b = np.unique(np.asarray(breakpoints, dtype=float))
    cand = [b]
    scale = max(1.0, float(np.abs(b).max()))
    s0, h = b[:-1], np.diff(b)
    keep = h > 1e-12 * scale
    s0, h = s0[keep], h[keep]
    if degree >= 2 and s0.size:
        t = np.linspace(0.0, 1.0, degree + 1)
        vals = f((s0[:, None] + h[:, None] * t[None, :]).ravel()).reshape(s0.size, degree + 1)
        # coefficients in t, highest power first, of every piece at once (exact interpolation)
        coef = np.linalg.solve(np.vander(t, degree + 1), vals.T).T
        deriv = coef[:, :-1] * np.arange(degree, 0, -1)[None, :]
        peak = np.abs(deriv).max(axis=1)
        if degree == 3:  # the derivative is a quadratic: roots of all pieces at once
            A, B, C = (np.where(np.abs(deriv[:, i]) > 1e-13 * peak, deriv[:, i], 0.0) for i in range(3))
            disc = B * B - 4.0 * A * C
            sq = np.sqrt(np.where(disc >= 0.0, disc, np.nan))
            with np.errstate(divide="ignore", invalid="ignore"):
                # stable quadratic roots; a linear derivative (A = 0) has its one root -C / B
                qq = -0.5 * (B + np.copysign(sq, B))
                r = np.stack([np.where(A != 0.0, qq / A, -C / B), np.where(A != 0.0, C / qq, np.nan)], axis=1)
            r = np.where((r > 0.0) & (r < 1.0), r, np.nan)
            ok = np.isfinite(r)
            cand.append((s0[:, None] + h[:, None] * r)[ok])
            return _best(f, cand)
        for k in np.flatnonzero(peak > 0.0):
            roots = np.roots(np.trim_zeros(np.where(np.abs(deriv[k]) > 1e-13 * peak[k], deriv[k], 0.0), "f"))
            r = roots[np.abs(roots.imag) < 1e-9].real
            r = r[(r > 0.0) & (r < 1.0)]
            if r.size:
                cand.append(s0[k] + h[k] * r)
    return _best(f, cand)


def _best(f, candidates):
    s = np.concatenate(candidates)
    v = f(s)
    i = int(np.argmax(v))
    return float(v[i]), float(s[i])


#: Entries kept by every cache of static results (functools.lru_cache on private functions of this
#: module, :mod:`adm_sim.design.check_effects` and :mod:`adm_sim.design.check`): the check computes the same train's
#: and LM71's static effects once per train, not again per mass or stiffness bound (they do not depend
#: on the mass). Arrays enter a cache as :func:`array_key` and leave it read-only.
CACHE_SIZE = 256


def array_key(a):
    """An exact, hashable key of an array: ``(bytes, shape, dtype)``; :func:`array_from_key` rebuilds it."""
    a = np.ascontiguousarray(a)
    return a.tobytes(), a.shape, a.dtype.str


def array_from_key(key):
    """The array of an :func:`array_key` (read-only: it shares the key's bytes)."""
    data, shape, dtype = key
    return np.frombuffer(data, dtype=np.dtype(dtype)).reshape(shape)


def read_only(*arrays):
    """Mark ``arrays`` read-only (a cached value is shared by every caller) and return them."""
    for a in arrays:
        a.flags.writeable = False
    return arrays[0] if len(arrays) == 1 else arrays


@dataclass(frozen=True)
class MidspanMax:
    """Largest static midspan effects and where the load stood.

    Attributes
    ----------
    moment_Nm, deflection_m : float
        Largest midspan bending moment (N m) and deflection (m, downwards positive).
    moment_position_m, deflection_position_m : float
        For an axle train: position of the first axle from the left support (m). For LM71: shift
        of the centre of the four point forces from midspan (m).
    """

    moment_Nm: float
    deflection_m: float
    moment_position_m: float
    deflection_position_m: float

    def __repr__(self):
        return (f"MidspanMax(M={self.moment_Nm / 1e3:.6g} kNm at {self.moment_position_m:.4g} m, "
                f"w={self.deflection_m * 1e3:.6g} mm at {self.deflection_position_m:.4g} m)")


def _train_arrays(axle_offsets_m, axle_loads_n):
    a = np.asarray(axle_offsets_m, dtype=float).ravel()
    P = np.asarray(axle_loads_n, dtype=float).ravel()
    if a.size == 0 or a.size != P.size:
        raise InputError(f"axle_offsets_m/axle_loads_n: {a.size} offsets and {P.size} loads; "
                         "give one load per axle, at least one axle")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(P))):
        raise InputError("axle_offsets_m/axle_loads_n: every offset (m) and load (N) must be finite")
    if np.any(P < 0.0):
        raise InputError(f"axle_loads_n: {P.min():g} N is negative; allowed >= 0 N (downwards)")
    return a, P


def train_midspan_max(span_m, EJ_Nm2, axle_offsets_m, axle_loads_n):
    """Exact largest static midspan moment and deflection of an axle train crossing the span.

    The first axle stands at ``s`` from the left support, axle ``i`` at ``s - a_i``. Breakpoints:
    every axle at a support or at midspan (``s = a_i``, ``a_i + L/2``, ``a_i + L``); between them
    the moment is linear and the deflection cubic in ``s`` (:func:`_piecewise_polynomial_max`).

    Parameters
    ----------
    span_m, EJ_Nm2 : float
        Span L (m) and bending stiffness EJ (N m^2), > 0.
    axle_offsets_m : array_like, shape (n_axles,)
        Distance of every axle behind the first (m).
    axle_loads_n : array_like, shape (n_axles,)
        Static axle loads (N), >= 0.

    Returns
    -------
    MidspanMax
    """
    L, EJ = _span_ej(span_m, EJ_Nm2)
    a, P = _train_arrays(axle_offsets_m, axle_loads_n)
    return _train_midspan_max_cached(L, EJ, array_key(a), array_key(P))


@functools.lru_cache(maxsize=CACHE_SIZE)
def _train_midspan_max_cached(L, EJ, a_key, P_key):
    """:func:`_train_midspan_max` once per span, stiffness and axles (:func:`array_key`)."""
    return _train_midspan_max(L, EJ, array_from_key(a_key), array_from_key(P_key))


def _train_midspan_max(L, EJ, a, P):
    """:func:`train_midspan_max` of checked arrays."""

    def moment(s):
        s = np.atleast_1d(s)
        return _moment_influence(s[:, None] - a[None, :] - L / 2.0, L) @ P

    def deflection(s):
        s = np.atleast_1d(s)
        return _deflection_influence(s[:, None] - a[None, :] - L / 2.0, L, EJ) @ P

    bp = np.concatenate([a, a + L / 2.0, a + L])
    M, sM = _piecewise_polynomial_max(moment, bp, 1)
    w, sw = _piecewise_polynomial_max(deflection, bp, 3)
    return MidspanMax(M, w, sM, sw)


def _lm71_effects(L, EJ):
    """Vectorised unclassified (α = 1) LM71 midspan moment and deflection as functions of the
    shift ``d`` of the point-force group's centre from midspan."""
    c = np.asarray(LM71_AXLES_M)
    P, q, hw = LM71_AXLE_LOAD_N, LM71_UDL_N_M, LM71_HALF_WINDOW_M
    M_full = q * L * L / 8.0
    w_full = 5.0 * q * L**4 / (384.0 * EJ)

    def moment(d):
        d = np.atleast_1d(d)
        pts = P * _moment_influence(d[:, None] + c[None, :], L).sum(-1)
        gap = _moment_area(d + hw, L) - _moment_area(d - hw, L)
        return pts + M_full - q * gap

    def deflection(d):
        d = np.atleast_1d(d)
        pts = P * _deflection_influence(d[:, None] + c[None, :], L, EJ).sum(-1)
        gap = _deflection_area(d + hw, L, EJ) - _deflection_area(d - hw, L, EJ)
        return pts + w_full - q * gap

    return moment, deflection


def lm71_midspan(span_m, EJ_Nm2, alpha=1.0):
    """Largest static midspan moment and deflection of α x LM71 (EN 1991-2 6.3.2, Fig. 6.2).

    Four 250 kN axles at 1.6 m and 80 kN/m everywhere on the span outside the 6.4 m window of the
    axles (0.8 m beyond the outer ones), at the most unfavourable position: the exact maximum over
    the shift ``d`` of the group from midspan, breakpoints where an axle or a window end crosses a
    support or midspan (moment quadratic, deflection quartic in ``d`` between them). On spans
    shorter than the group only what fits is on the span. ``d`` beyond ``L/2 + 3.2 m`` leaves the
    distributed load alone on the whole span; that case is a breakpoint too.

    Parameters
    ----------
    span_m, EJ_Nm2 : float
        Span L (m) and bending stiffness EJ (N m^2), > 0.
    alpha : float
        Classification factor α of EN 1991-2 6.3.2(3): 0.75, 0.83, 0.91, 1.00 (default), 1.10,
        1.21, 1.33, 1.46.

    Returns
    -------
    MidspanMax
        Effects times α; positions are the shift of the group centre from midspan (m).
    """
    L, EJ = _span_ej(span_m, EJ_Nm2)
    al = check_alpha(alpha)
    return _lm71_midspan(L, EJ, al)


@functools.lru_cache(maxsize=CACHE_SIZE)
def _lm71_midspan(L, EJ, al):
    """:func:`lm71_midspan` of checked values (cached: a frozen result of three floats)."""
    moment, deflection = _lm71_effects(L, EJ)
    ends = np.array([-L / 2.0, 0.0, L / 2.0])
    rel = np.concatenate([LM71_AXLES_M, [-LM71_HALF_WINDOW_M, LM71_HALF_WINDOW_M]])
    bp = (ends[:, None] - rel[None, :]).ravel()
    lim = L / 2.0 + LM71_HALF_WINDOW_M
    bp = np.clip(bp, -lim, lim)
    bp = np.concatenate([bp, [-lim, lim]])
    M, dM = _piecewise_polynomial_max(moment, bp, 2)
    w, dw = _piecewise_polynomial_max(deflection, bp, 4)
    return MidspanMax(al * M, al * w, dM, dw)


# --------------------------------------------------------------------------- 6.4.6.5(3)

@dataclass(frozen=True)
class DesignComparison:
    """EN 1991-2 6.4.6.5(3) for one train: every number and which side governs.

    Attributes
    ----------
    train : str
    span_m, L_phi_m, n0_hz, speed_m_s : float
        Span, determinant length LΦ, first frequency and the speed used for φ'' (m, Hz, m/s).
    maintenance : str
        ``"careful"`` (Φ2) or ``"standard"`` (Φ3).
    Phi, alpha, phi_dd : float
        Φ (6.4.5.2), classification factor α (6.3.2(3)) and φ'' (Annex C).
    phi_dyn_moment, phi_dyn_deflection : float
        φ'_dyn (Eq. 6.14) used for each effect.
    train_static_moment_Nm, train_static_deflection_m : float
        Largest static midspan effects of the train.
    lm71_static_moment_Nm, lm71_static_deflection_m : float
        Largest static midspan effects of α x LM71 (α included, Φ not).
    """

    train: str
    span_m: float
    L_phi_m: float
    n0_hz: float
    speed_m_s: float
    maintenance: str
    Phi: float
    alpha: float
    phi_dd: float
    phi_dyn_moment: float
    phi_dyn_deflection: float
    train_static_moment_Nm: float
    train_static_deflection_m: float
    lm71_static_moment_Nm: float
    lm71_static_deflection_m: float

    @property
    def phi_dd_factor(self):
        """r in ``1 + φ'_dyn + r φ''``: 1/2 for carefully maintained track (6.4.6.5(3) Eq. (6.15),
        Annex C's ``1 + φ' + φ''/2``), 1 for standard maintenance (Annex C's ``1 + φ' + φ''``)."""
        return phi_dd_factor(self.maintenance)

    @property
    def factor_moment(self):
        """1 + φ'_dyn + r φ'' for the moment (r = 1/2 careful, 1 standard maintenance)."""
        return 1.0 + self.phi_dyn_moment + self.phi_dd_factor * self.phi_dd

    @property
    def factor_deflection(self):
        """1 + φ'_dyn + r φ'' for the deflection."""
        return 1.0 + self.phi_dyn_deflection + self.phi_dd_factor * self.phi_dd

    @property
    def train_design_moment_Nm(self):
        return self.factor_moment * self.train_static_moment_Nm

    @property
    def train_design_deflection_m(self):
        return self.factor_deflection * self.train_static_deflection_m

    @property
    def lm71_design_moment_Nm(self):
        return self.Phi * self.lm71_static_moment_Nm

    @property
    def lm71_design_deflection_m(self):
        return self.Phi * self.lm71_static_deflection_m

    @property
    def ratio_moment(self):
        """Train design moment / (Φ α LM71) moment: > 1 means the train governs."""
        return self.train_design_moment_Nm / self.lm71_design_moment_Nm

    @property
    def ratio_deflection(self):
        return self.train_design_deflection_m / self.lm71_design_deflection_m

    @property
    def governs_moment(self):
        """``"train"`` or ``"LM71"`` (the train only if strictly larger)."""
        return "train" if self.ratio_moment > 1.0 else "LM71"

    @property
    def governs_deflection(self):
        return "train" if self.ratio_deflection > 1.0 else "LM71"

    def describe(self):
        """One line: both effects, both sides, the governing one."""
        phi = "Φ2" if self.maintenance == "careful" else "Φ3"
        dd = f"{self.phi_dd:.3f}/2" if self.phi_dd_factor == 0.5 else f"{self.phi_dd:.3f}"
        return (f"{self.train}: EN 1991-2 6.4.6.5(3) M {self.train_design_moment_Nm / 1e3:.1f} kNm "
                f"(1+{self.phi_dyn_moment:.3f}+{dd}) vs {phi}={self.Phi:.3f} x "
                f"{self.alpha:.2f} LM71 {self.lm71_design_moment_Nm / 1e3:.1f} kNm -> {self.governs_moment} "
                f"({self.ratio_moment:.3f}); w {self.train_design_deflection_m * 1e3:.2f} mm "
                f"(1+{self.phi_dyn_deflection:.3f}+{dd}) vs "
                f"{self.lm71_design_deflection_m * 1e3:.2f} mm -> {self.governs_deflection} "
                f"({self.ratio_deflection:.3f})")

    def to_dict(self):
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        for k in ("phi_dd_factor", "factor_moment", "factor_deflection", "train_design_moment_Nm", "train_design_deflection_m",
                  "lm71_design_moment_Nm", "lm71_design_deflection_m", "ratio_moment", "ratio_deflection",
                  "governs_moment", "governs_deflection"):
            d[k] = getattr(self, k)
        return d


def design_comparison(train, span_m, EJ_Nm2, n0_hz, axle_offsets_m, axle_loads_n, speed_m_s,
                      phi_dyn_deflection, phi_dyn_moment=None, maintenance=DEFAULT_MAINTENANCE, alpha=1.0,
                      L_phi_m=None):
    """EN 1991-2 6.4.6.5(3) for the midspan moment and deflection of a simply supported span.

    ``(1 + φ'_dyn + φ''/2) x train`` against ``Φ x α x LM71``, static effects exact
    (:func:`train_midspan_max`, :func:`lm71_midspan`).

    Parameters
    ----------
    train : str
        Name shown in the result.
    span_m, EJ_Nm2, n0_hz : float
        Span (m), bending stiffness (N m^2), first natural frequency of the loaded bridge (Hz).
    axle_offsets_m, axle_loads_n : array_like, shape (n_axles,)
        The train (offsets behind the first axle, m; static axle loads, N).
    speed_m_s : float
        Speed for φ'' (Annex C: the maximum permitted vehicle speed, m/s). Above 22 m/s φ'' does
        not depend on it.
    phi_dyn_deflection : float
        φ'_dyn of the midspan deflection (Eq. 6.14; :func:`phi_dyn_prime`), >= -1.
    phi_dyn_moment : float or None
        φ'_dyn of the midspan moment; ``None`` takes the deflection's (an approximation the caller
        should state: it is exact only when one mode carries both responses).
    maintenance : str
        ``"careful"`` (Φ2, 6.4.5.2(2)) or ``"standard"`` (Φ3, 6.4.5.2(3); the default, 6.4.5.2(3)P).
    alpha : float
        Classification factor α of 6.3.2(3).
    L_phi_m : float or None
        Determinant length; ``None`` is the span (Table 6.2 case 5.1).

    Returns
    -------
    DesignComparison
    """
    L, EJ = _span_ej(span_m, EJ_Nm2)
    m = check_choice("maintenance", maintenance, MAINTENANCE)
    al = check_alpha(alpha)
    Lphi = L if L_phi_m is None else _length("L_phi_m", L_phi_m)
    pdd = check_range("phi_dyn_deflection", phi_dyn_deflection, "-", -1.0, None)
    pdm = pdd if phi_dyn_moment is None else check_range("phi_dyn_moment", phi_dyn_moment, "-", -1.0, None)
    phi_dd = phi_double_prime(Lphi, n0_hz, speed_m_s)
    tr = train_midspan_max(L, EJ, axle_offsets_m, axle_loads_n)
    lm = lm71_midspan(L, EJ, al)
    return DesignComparison(
        train=str(train), span_m=L, L_phi_m=Lphi, n0_hz=float(n0_hz), speed_m_s=float(speed_m_s),
        maintenance=m, Phi=dynamic_factor(Lphi, m), alpha=al, phi_dd=phi_dd,
        phi_dyn_moment=pdm, phi_dyn_deflection=pdd,
        train_static_moment_Nm=tr.moment_Nm, train_static_deflection_m=tr.deflection_m,
        lm71_static_moment_Nm=lm.moment_Nm, lm71_static_deflection_m=lm.deflection_m)


def governing(comparisons, effect="moment"):
    """The comparison with the largest train-to-LM71 ratio for ``effect`` (``"moment"`` or
    ``"deflection"``)."""
    e = check_choice("effect", effect, ("moment", "deflection"))
    comps = list(comparisons)
    if not comps:
        raise InputError("comparisons: empty; give at least one DesignComparison")
    return max(comps, key=lambda c: getattr(c, f"ratio_{e}"))
