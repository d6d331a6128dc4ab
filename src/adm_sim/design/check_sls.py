"""The serviceability checks of EN 1990 A2.4.4 that a single simply supported span (Euler-Bernoulli,
span L, stiffness EJ) can give, beside the deck acceleration of :mod:`adm_sim.design.check`, and the list of
what it cannot give.

* Vertical deflection of the deck, EN 1990 A2.4.4.2.3(1): the largest total vertical deflection
  anywhere along the span under α x LM71 (EN 1991-2 6.3.2) times Φ (6.4.5.2) should not exceed
  L/600. The largest over every section x in [0.3 L, 0.7 L] (where the largest deflection of a
  simply supported span under downward loads lies) and every position of LM71; the influence
  line of the deflection at x is integrated in closed form (point forces) and by the cumulative
  trapezoid rule on 4000 intervals (distributed load; 3e-7 relative on 15 m).
* End rotation of the deck under Φ x α x LM71: on ballasted track 6.5e-3 rad at a deck end next to
  an abutment (10e-3 rad for the sum at a joint between two decks, not checked: one span). This
  limit is an infrastructure manager's rule that the project applies (:data:`END_ROTATION_SOURCE`),
  not EN 1991-2 6.5.4.5.2: that clause limits the deck-end displacements (δ_B, δ_H, δ_V), not a
  rotation.
* Deck-end displacement δ_H of EN 1991-2 6.5.4.5.2 from the end rotation: ``δ_H = θ h`` with h
  the height from the bearings' axis of rotation to the top of the deck, given by the user
  (``--deck-end-height``), compared with the clause's 8 mm and 10 mm (both shown: which one applies
  depends on the case the clause names); without h it is listed as not checked.
  Rotation at the left end of a point force P at a: ``P a (L - a)(2 L - a) / (6 EJ L)``; of a
  distributed load q over the span ``q L^3 / (24 EJ)``. For direct fastening the limit is the
  relevant authority's: the value is printed, not judged.
* Lateral frequency, EN 1990 A2.4.4.2.4(3): the first lateral natural frequency of the span
  should not be less than 1.2 Hz; a value the user gives (``--lateral-frequency``), checked.

Not given by a single-span beam model (printed as not checked): deck twist (A2.4.4.2.2),
track-bridge interaction (EN 1991-2 6.5.4), fatigue (EN 1991-2 6.4.6.6), passenger comfort by the
deflection limits of Fig. A2.3 (A2.4.4.3.2), horizontal deflection (A2.4.4.2.4(2)), continuous and
multi-span decks, HSLM-B for spans under 7 m (EN 1991-2 Annex E), the Annex F screening, and mass
and stiffness bounds (EN 1991-2 6.4.6.3.2/3) unless given.

numpy only; no ROS.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError
from adm_sim.design.design_loads import CACHE_SIZE, LM71_AXLE_LOAD_N, LM71_AXLES_M, LM71_HALF_WINDOW_M, LM71_UDL_N_M

#: Deflection limit L / this, EN 1990 A2.4.4.2.3(1).
DEFLECTION_SPAN_RATIO = 600.0
#: Deck end rotation limit (rad) next to an abutment, ballasted track: an infrastructure manager's
#: rule the project applies, not a limit of EN 1991-2 (:data:`END_ROTATION_SOURCE`).
END_ROTATION_LIMIT_RAD = 6.5e-3
END_ROTATION_SOURCE = ("an infrastructure manager's rule applied by the project's choice, not EN 1991-2: "
                       "6.5.4.5.2 limits the deck-end displacements (delta_B, delta_H, delta_V), not the rotation")
#: Deck-end displacement limits of δ_H (m), EN 1991-2 6.5.4.5.2 (both shown).
DELTA_H_LIMITS_M = (8e-3, 10e-3)
#: Allowed height h (m) from the bearings' axis of rotation to the top of the deck (input sanity range).
DECK_END_HEIGHT_RANGE_M = (0.0, 10.0)
#: Highest first lateral natural frequency (Hz) a user may give: the project's choice (a span's first
#: lateral mode lies at a few Hz; 1e9 Hz is a typo, not a bridge).
LATERAL_FREQUENCY_MAX_HZ = 100.0
#: Lowest first lateral natural frequency (Hz), EN 1990 A2.4.4.2.4(3).
LATERAL_FREQUENCY_MIN_HZ = 1.2
#: What this check does not cover, each with its clause.
NOT_CHECKED = (
    "deck twist (EN 1990 A2.4.4.2.2)",
    "track-bridge interaction (EN 1991-2 6.5.4)",
    "fatigue (EN 1991-2 6.4.6.6)",
    "passenger comfort by the deflection limits of Fig. A2.3 (EN 1990 A2.4.4.3.2); with --comfort the DIM "
    "gives b_v for real trains with vehicles",
    "horizontal deflection (EN 1990 A2.4.4.2.4(2))",
    "continuous and multi-span decks, joints between decks (one simply supported span only)",
    "the N and d of HSLM-B from the span (EN 1991-2 6.4.6.1.1(5), spans under 7 m: give HSLM-B:N=<forces>:d=<m> "
    "read off the standard's figure) and the Annex F screening (when a dynamic analysis is not required)",
    "mass and stiffness bounds (EN 1991-2 6.4.6.3.2, 6.4.6.3.3)",
    "deck-end displacement delta_H = theta h (EN 1991-2 6.5.4.5.2): give --deck-end-height, the height from the "
    "bearings' axis of rotation to the top of the deck (m)",
)


def _lm71_group():
    return np.asarray(LM71_AXLES_M), LM71_AXLE_LOAD_N, LM71_HALF_WINDOW_M, LM71_UDL_N_M


def _deflection_influence(L, EJ, x, u):
    """Deflection at x (m) of a unit force at u (arrays), simply supported span; zero off the span."""
    u = np.asarray(u, dtype=float)
    a = np.where(u <= x, u, L - u)  # distance of the force to its nearer-side support ...
    b = np.where(u <= x, L - x, x)  # ... and of the section to the other support
    w = a * b * (L * L - a * a - b * b) / (6.0 * EJ * L)
    return np.where((u >= 0.0) & (u <= L), w, 0.0)


@functools.lru_cache(maxsize=CACHE_SIZE)
def lm71_max_deflection(span_m, EJ_Nm2, alpha=1.0, n_grid=2000):
    """Largest deflection (m) anywhere on the span under α x LM71 and the section x (m) where it occurs.
    Cached (floats in, floats out): a mass bound of the check has the nominal bridge's span and EJ."""
    c, P, hw, q = _lm71_group()
    L, EJ = span_m, EJ_Nm2
    u = np.linspace(0.0, L, 4001)
    d = np.unique(np.concatenate([np.linspace(-hw, L + hw, n_grid), (np.array([0.0, L])[:, None] - c).ravel()]))
    best, at = 0.0, 0.5 * L
    for x in np.linspace(0.3 * L, 0.7 * L, 41):
        g = _deflection_influence(L, EJ, x, u)
        G = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(u))])
        gap = np.interp(d + hw, u, G) - np.interp(d - hw, u, G)
        w = P * _deflection_influence(L, EJ, x, d[:, None] + c[None, :]).sum(1) + q * (G[-1] - gap)
        if w.max() > best:
            best, at = float(w.max()), float(x)
    return alpha * best, at


@functools.lru_cache(maxsize=CACHE_SIZE)
def lm71_end_rotation(span_m, EJ_Nm2, alpha=1.0, n_grid=4000):
    """Largest end rotation (rad) of the span under α x LM71 (the distributed load on the whole span
    outside the 6.4 m window of the axles). Cached, as :func:`lm71_max_deflection`."""
    c, P, hw, q = _lm71_group()
    L, EJ = span_m, EJ_Nm2

    def point(a):
        return np.where((a >= 0) & (a <= L), a * (L - a) * (2.0 * L - a) / (6.0 * EJ * L), 0.0)

    def area(a):  # integral of point() from 0 to a, clipped: (L^2 a^2 - L a^3 + a^4 / 4) / (6 EJ L)
        a = np.clip(a, 0.0, L)
        return (L * L * a * a - L * a**3 + a**4 / 4.0) / (6.0 * EJ * L)

    d = np.unique(np.concatenate([np.linspace(-hw, L + hw, n_grid), (np.array([0.0, L])[:, None] - c).ravel(),
                                  [hw, L - hw]]))
    th = P * point(d[:, None] + c[None, :]).sum(1) + q * (area(L) - (area(d + hw) - area(d - hw)))
    return alpha * float(th.max())


def check_lateral_frequency(value):
    """The lateral frequency (Hz) the user gives: a finite number > 0, else one-line InputError."""
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise InputError(f"lateral_frequency: {value!r} is not a frequency; give the first lateral natural "
                         f"frequency of the span in Hz, > 0", field="lateral_frequency") from None
    if not np.isfinite(f) or f <= 0.0 or f > LATERAL_FREQUENCY_MAX_HZ:
        raise InputError(f"lateral_frequency: {value!r} Hz is not the frequency of a span; allowed (0, "
                         f"{LATERAL_FREQUENCY_MAX_HZ:g}] Hz (the upper bound is the project's choice: no railway span "
                         f"sways above it; EN 1990 A2.4.4.2.4(3) asks for at least {LATERAL_FREQUENCY_MIN_HZ:g} Hz)",
                         field="lateral_frequency")
    return f


@dataclass(frozen=True)
class Serviceability:
    """EN 1990 A2.4.4 checks of one span beside the deck acceleration."""

    span_m: float
    Phi: float
    alpha: float
    track: str
    deflection_m: float  # Φ α LM71, largest along the span
    deflection_x_m: float
    end_rotation_rad: float  # Φ α LM71
    lateral_frequency_hz: float | None
    deck_end_height_m: float | None = None  # h, bearings' axis of rotation to the top of the deck

    @property
    def delta_h_m(self):
        """δ_H = θ h (m), EN 1991-2 6.5.4.5.2; None without h."""
        return None if self.deck_end_height_m is None else self.end_rotation_rad * self.deck_end_height_m

    @property
    def delta_h_ok(self):
        """``(<= 8 mm, <= 10 mm)`` or None without h."""
        d = self.delta_h_m
        return None if d is None else tuple(bool(d <= lim) for lim in DELTA_H_LIMITS_M)

    @property
    def deflection_limit_m(self):
        return self.span_m / DEFLECTION_SPAN_RATIO

    @property
    def deflection_ok(self):
        return self.deflection_m <= self.deflection_limit_m

    @property
    def end_rotation_ok(self):
        """True/False on ballasted track; None (the relevant authority's limit) on direct fastening."""
        return self.end_rotation_rad <= END_ROTATION_LIMIT_RAD if self.track == "ballasted" else None

    @property
    def lateral_ok(self):
        f = self.lateral_frequency_hz
        return None if f is None else f >= LATERAL_FREQUENCY_MIN_HZ

    def lines(self):
        v = lambda ok: "PASS" if ok else "FAIL"  # noqa: E731
        out = [f"EN 1990 A2.4.4.2.3(1) vertical deflection under Phi x alpha x LM71 = {self.Phi:.3f} x "
               f"{self.alpha:g} x LM71: {1e3 * self.deflection_m:.3f} mm at x = {self.deflection_x_m:.2f} m, limit "
               f"L/600 = {1e3 * self.deflection_limit_m:.3f} mm: {v(self.deflection_ok)} "
               f"(L/{self.span_m / self.deflection_m:.0f})"]
        if self.track == "ballasted":
            out.append(f"deck end rotation under Phi x alpha x LM71: {1e3 * self.end_rotation_rad:.3f} mrad, limit "
                       f"{1e3 * END_ROTATION_LIMIT_RAD:g} mrad at an abutment, ballasted track ({END_ROTATION_SOURCE}): "
                       f"{v(self.end_rotation_ok)}")
        else:
            out.append(f"deck end rotation under Phi x alpha x LM71: {1e3 * self.end_rotation_rad:.3f} mrad "
                       f"(direct fastening: the limit is the relevant authority's; not judged)")
        if self.deck_end_height_m is None:
            out.append("deck-end displacement delta_H = theta h (EN 1991-2 6.5.4.5.2): not checked (give "
                       "--deck-end-height, m)")
        else:
            ok8, ok10 = self.delta_h_ok
            out.append(f"deck-end displacement delta_H = theta h = {1e3 * self.end_rotation_rad:.3f} mrad x "
                       f"{self.deck_end_height_m:g} m = {1e3 * self.delta_h_m:.3f} mm (EN 1991-2 6.5.4.5.2, "
                       f"h given): limit 8 mm {v(ok8)}, limit 10 mm {v(ok10)} (which limit applies depends on the "
                       f"case 6.5.4.5.2 names)")
        if self.lateral_frequency_hz is None:
            out.append("lateral frequency (EN 1990 A2.4.4.2.4(3), >= 1.2 Hz): not checked (give "
                       "--lateral-frequency, Hz)")
        else:
            out.append(f"lateral frequency {self.lateral_frequency_hz:g} Hz (given), limit >= "
                       f"{LATERAL_FREQUENCY_MIN_HZ:g} Hz (EN 1990 A2.4.4.2.4(3)): {v(self.lateral_ok)}")
        return out

    def to_dict(self):
        return {"deflection_m": self.deflection_m, "deflection_x_m": self.deflection_x_m,
                "deflection_limit_m": self.deflection_limit_m, "deflection_ok": self.deflection_ok,
                "end_rotation_rad": self.end_rotation_rad, "end_rotation_limit_rad": END_ROTATION_LIMIT_RAD,
                "end_rotation_ok": self.end_rotation_ok, "end_rotation_limit_source": END_ROTATION_SOURCE,
                "deck_end_height_m": self.deck_end_height_m, "delta_h_m": self.delta_h_m,
                "delta_h_limits_m": list(DELTA_H_LIMITS_M),
                "delta_h_ok": None if self.delta_h_ok is None else list(self.delta_h_ok),
                "delta_h_clause": "EN 1991-2 6.5.4.5.2", "lateral_frequency_hz": self.lateral_frequency_hz,
                "lateral_ok": self.lateral_ok, "Phi": self.Phi, "alpha": self.alpha}


def check_deck_end_height(value, field="deck_end_height_m"):
    """h (m) from the bearings' axis of rotation to the top of the deck: a finite number in
    (0, 10] m, else one-line InputError naming ``field``."""
    lo, hi = DECK_END_HEIGHT_RANGE_M
    try:
        h = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{field}: {value!r} is not a height; give the height from the bearings' axis of rotation "
                         f"to the top of the deck in m, allowed ({lo:g}, {hi:g}] m", field=field) from None
    if not (np.isfinite(h) and lo < h <= hi):
        raise InputError(f"{field}: {value!r} m is out of range; allowed ({lo:g}, {hi:g}] m (the height from the "
                         f"bearings' axis of rotation to the top of the deck)", field=field)
    return h


def serviceability(bridge, Phi, alpha, track, lateral_frequency_hz=None, deck_end_height_m=None):
    """The checks of this module for ``bridge`` with the dynamic factor Φ and classification factor α."""
    w, x = lm71_max_deflection(bridge.span_m, bridge.EJ_Nm2, alpha)
    th = lm71_end_rotation(bridge.span_m, bridge.EJ_Nm2, alpha)
    f = None if lateral_frequency_hz is None else check_lateral_frequency(lateral_frequency_hz)
    return Serviceability(span_m=bridge.span_m, Phi=float(Phi), alpha=float(alpha), track=track,
                          deflection_m=float(Phi) * w, deflection_x_m=x, end_rotation_rad=float(Phi) * th,
                          lateral_frequency_hz=f,
                          deck_end_height_m=None if deck_end_height_m is None else check_deck_end_height(deck_end_height_m))
