"""Reference additional-damping methods: Eurocode ADM, EADA and the lower-bound functions.

All functions return the additional damping in percent of critical (``*_pct``).

Eurocode ADM (EN 1991-2 6.4.6.3.1, Fig. 6.15; paper Fig. 4)
    ``dz = (0.0187 L - 0.00064 L^2) / (1 - 0.0441 L - 0.0044 L^2 + 0.000255 L^3)`` in % for
    ``L < 30 m``, ``0`` for ``L >= 30 m``. The function lives in the core
    (:func:`adm_sim.design.design_loads.adm_delta_zeta_pct`, EN 1991-2 Eq. (6.13)) and is re-exported here.

Equivalent Additional Damping Approach, EADA (Yau et al., paper Eq. 3)
    ``dz ~= mu_1 r_1 sqrt(r_1^2 + (2 zeta_1)^2)`` with ``mu_1 = m_1 / M_1``, ``r_1 = omega_1 / Omega_1``
    and ``zeta_1 = c_1 / (2 m_1 omega_1)`` (Eq. 2).

    Bridge side: first mode of the simply supported beam, ``M_1 = mu L / 2`` (modal mass of
    ``sin(pi x / L)``) and ``Omega_1 = 2 pi n0``.

    Train side, the "half coach" of paper Fig. 6(a): one end of a passenger car, i.e. half the car
    body ``m_c / 2`` resting on one bogie through the secondary stage (``k_s``, ``c_s`` per bogie),
    the bogie ``m_b`` resting on two wheelsets through the primary stage (``k_p``, ``c_p`` per axle,
    so ``2 k_p``, ``2 c_p`` per bogie). The wheelsets follow the rail (unsprung) and are not part of
    the tuning unit. Yau et al.'s tuning unit is a single-degree-of-freedom oscillator, so the
    two-stage chain is reduced to its first (bounce) mode:

    * stiffness and damping: the secondary and primary Kelvin elements act in series. Their
      complex stiffness at the tuning frequency,
      ``K*(w) = [1 / (k_s + i w c_s) + 1 / (2 k_p + i w 2 c_p)]^-1``, gives ``k_1 = Re K*(w_1)``
      and ``c_1 = Im K*(w_1) / w_1``. (A plain series formula for the dampers would give
      ``c_1 = 0`` when one stage has no damper, as the unpowered ICE-4 primary stage, although the
      stiff primary spring passes the secondary damper force to the bridge.)
    * mass: Rayleigh reduction with the static deflection shape of the chain (car body 1, bogie
      ``a = k_s / (k_s + 2 k_p)``): ``m_1 = m_c / 2 + a^2 m_b``. With the actual data ``a`` is
      0.05-0.1, so ``m_1`` is essentially half the car body.
    * ``w_1 = sqrt(k_1 / m_1)`` depends on ``k_1(w_1)``; a fixed-point iteration converges in a few
      steps because the primary stage is much stiffer than the secondary one.

    EADA is not defined for trains with Jacobs bogies (the Eurostar): a car end does not rest on a
    bogie of its own (paper Section 4.4). For the ICE-4 the unpowered passenger cars are used
    (Section 4.4); for the other trains the passenger car type that occurs most often.

Lower-bound functions (paper Eq. 20, Tables B1-B4, Section 4.2-4.3)
    ``dz(n0) = a n0^3 + b n0^2 + c n0 + d`` (% with n0 in Hz), valid from 2.1 Hz to the first root
    above 2.1 Hz (the printed "upper limit"); ``0`` beyond the root; refused below 2.1 Hz and above
    the highest frequency of the studied parametric field (Section 3.1.1, L = 4 m upper bound).
    Section 4.3 rules for a bridge of mass ``mu`` at span ``L``: outside the mass functions of its
    type (CFB mu1-mu3, SC mu4-mu6) the nearest function; inside, the next heavier function (safe
    side, default) or linear interpolation in ``mu`` between the two adjacent functions. Only the
    four trains of the study are allowed.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections import Counter
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources

import numpy as np

from adm_sim.fields import FIELDS, view
from adm_sim.design.design_loads import adm_delta_zeta_pct  # noqa: F401  (the Eurocode ADM lives in the core; re-exported)
from adm_sim.errors import InputError
from adm_sim.fields import check_range
from adm_sim.model.parametric import MASS_FUNCTIONS, N0_FIT, N0_UB, mass_function_t_m

from adm_calib.lower_bound import FIT_RANGE_MAX_HZ, LOWER_LIMIT_HZ, first_root_hz, lower_bound_pct, zero_from_hz

#: Trains of the study, in the paper's order (Table A1).
STUDY_TRAINS = ("ICE-2", "Eurostar", "Railjet", "ICE-4")
#: Mass functions per bridge type, heaviest first (Table 1).
TYPE_MASS_FUNCTIONS = {"cfb": ("mu1", "mu2", "mu3"), "sc": ("mu4", "mu5", "mu6")}
#: Spans a bridge may have (m), the field registry's range of ``span_m``.
SPAN_RANGE_M = FIELDS["span_m"].range
#: Spans of the parametric field (m), Section 3.1.1.
STUDY_SPAN_RANGE_M = (view("cli", "--span").lo, view("cli", "--span").hi)  # the field registry's
#: Highest first frequency of the parametric field: upper bound n0 = 113.1 L^-0.8312 at L = 4 m.
STUDY_N0_MAX_HZ = round(N0_UB[0] * STUDY_SPAN_RANGE_M[0] ** N0_UB[1], 2)
#: Relative tolerance within which a bridge mass counts as lying on a mass function.
ON_FUNCTION_RTOL = 1e-3


# ---------------------------------------------------------------------- trains
def canonical_train_name(name):
    """Study train name for ``name`` (case, dashes and blanks ignored: "ice2" -> "ICE-2").

    Raises
    ------
    InputError
        If the train is not one of the four trains of the study.
    """
    key = re.sub(r"[^a-z0-9]", "", str(name).lower())
    for t in STUDY_TRAINS:
        if re.sub(r"[^a-z0-9]", "", t.lower()) == key:
            return t
    raise InputError(f"train: {name!r} was not studied by the paper; allowed {', '.join(STUDY_TRAINS)} "
                     f"(the lower-bound functions must not be applied to other trains, Section 4.3)")


# ---------------------------------------------------------------------- Eurocode ADM
# ---------------------------------------------------------------------- EADA
@dataclass(frozen=True)
class HalfCoach:
    """Single-degree-of-freedom tuning unit of EADA (paper Fig. 6a), SI units.

    ``m_1`` (kg), ``k_1`` (N/m), ``c_1`` (N s/m), ``omega_1`` (rad/s), ``zeta_1`` (fraction, Eq. 2).
    """

    vehicle: str
    m_1_kg: float
    k_1_N_m: float
    c_1_Ns_m: float
    omega_1_rad_s: float
    zeta_1: float


def half_coach(vehicle, label=""):
    """Reduce one car end (half car body on one bogie) to the EADA tuning unit.

    Parameters
    ----------
    vehicle : VehicleType-like
        Attributes ``m_c_kg, m_b_kg, k_s_N_m, c_s_Ns_m`` (per bogie), ``k_p_N_m, c_p_Ns_m``
        (per axle); a missing damper is 0 or None.
    label : str
        Vehicle name shown in the output.

    Returns
    -------
    HalfCoach
        See the module docstring for the derivation.
    """
    m_c = float(vehicle.m_c_kg)
    m_b = float(vehicle.m_b_kg)
    k_s = float(vehicle.k_s_N_m)
    c_s = float(vehicle.c_s_Ns_m or 0.0)
    k_p2 = 2.0 * float(vehicle.k_p_N_m)
    c_p2 = 2.0 * float(vehicle.c_p_Ns_m or 0.0)
    a = k_s / (k_s + k_p2)
    m_1 = 0.5 * m_c + a * a * m_b
    w = math.sqrt(k_s * k_p2 / (k_s + k_p2) / m_1)
    for _ in range(100):
        kstar = 1.0 / (1.0 / complex(k_s, w * c_s) + 1.0 / complex(k_p2, w * c_p2))
        w_new = math.sqrt(kstar.real / m_1)
        if abs(w_new - w) <= 1e-12 * w:
            w = w_new
            break
        w = w_new
    kstar = 1.0 / (1.0 / complex(k_s, w * c_s) + 1.0 / complex(k_p2, w * c_p2))
    k_1 = kstar.real
    c_1 = kstar.imag / w
    return HalfCoach(vehicle=label, m_1_kg=m_1, k_1_N_m=k_1, c_1_Ns_m=c_1,
                     omega_1_rad_s=w, zeta_1=c_1 / (2.0 * m_1 * w))


def eada_vehicle(train):
    """The vehicle type EADA uses for ``train``, or ``(None, reason)``.

    Returns
    -------
    (str or None, str)
        Key of ``train.vehicle_types`` and a sentence saying why it was chosen (or why EADA is
        not defined).
    """
    if getattr(train, "jacobs", False):
        return None, (f"EADA is not defined for {train.name}: a train with Jacobs bogies does not fit "
                      f"the half-coach model of Yau et al. (paper Section 4.4)")
    types = dict(train.vehicle_types)
    if not types:
        return None, (f"EADA is not defined for {train.name}: its vehicles are bodies and stages (a vehicle file), "
                      f"not the coach types of the half-coach model of Yau et al. (paper Section 4.4)")
    unpowered = [k for k in types if "unpowered" in k.lower()]
    if unpowered:
        return unpowered[0], f"{train.name}: unpowered passenger car '{unpowered[0]}' (paper Section 4.4)"
    counts = Counter(car[0] for unit in getattr(train, "units", ()) for car in unit.cars)
    pcs = [k for k in types if not re.search(r"\bloc", k.lower())] or list(types)
    if counts:
        best = max(pcs, key=lambda k: counts.get(k, 0))
    else:
        best = pcs[0]
    return best, f"{train.name}: passenger car '{best}' (most frequent car type)"


def eada_delta_zeta_pct(coach, mass_per_length_kg_m, span_m, n0_hz):
    """Additional damping of EADA (%), paper Eq. (3) with Eq. (2).

    Parameters
    ----------
    coach : HalfCoach
        Tuning unit from :func:`half_coach`.
    mass_per_length_kg_m, span_m, n0_hz : float
        Bridge mu (kg/m), L (m) and first frequency (Hz); ``M_1 = mu L / 2``, ``Omega_1 = 2 pi n0``.
    """
    M_1 = 0.5 * float(mass_per_length_kg_m) * float(span_m)
    Omega_1 = 2.0 * math.pi * float(n0_hz)
    mu_1 = coach.m_1_kg / M_1
    r_1 = coach.omega_1_rad_s / Omega_1
    return 100.0 * mu_1 * r_1 * math.sqrt(r_1**2 + (2.0 * coach.zeta_1) ** 2)


#: Why the paper's simplified methods give no value on a continuous deck.
DECK_NOTE = ("the paper's lower-bound functions (Tables B1-B4) were fitted on simply supported spans "
             "(Section 3.1), not on continuous decks")
EADA_DECK_NOTE = "EADA (Eq. 3) is a simply supported span's method: not evaluated on a continuous deck"


def _deck_spans(bridge):
    """The spans of a continuous deck of two or more spans (``spans=A/B``), else None."""
    return bridge.spans_m if bridge.is_continuous and len(bridge.spans_m) > 1 else None


def eada_for(bridge, train):
    """EADA for a bridge and a train: ``(delta_zeta_pct or None, note)``; None on a continuous deck."""
    if _deck_spans(bridge):
        return None, EADA_DECK_NOTE
    key, note = eada_vehicle(train)
    if key is None:
        return None, note
    coach = half_coach(train.vehicle_types[key], label=key)
    dz = eada_delta_zeta_pct(coach, bridge.mass_per_length_kg_m, bridge.span_m, bridge.n0_hz)
    return dz, (f"{note}; m_1={coach.m_1_kg:.0f} kg, k_1={coach.k_1_N_m:.4g} N/m, "
                f"c_1={coach.c_1_Ns_m:.4g} Ns/m, f_1={coach.omega_1_rad_s / (2 * math.pi):.3f} Hz, "
                f"zeta_1={100 * coach.zeta_1:.2f} %")


# ---------------------------------------------------------------------- lower bounds
@dataclass(frozen=True)
class LowerBound:
    """One lower-bound function of Tables B1-B4 (Eq. 20): dz in %, n0 in Hz."""

    train: str
    mass_function: str
    a: float
    b: float
    c: float
    d: float
    upper_limit_hz: float
    r2: float
    max_res_pct: float
    min_res_pct: float
    lower_limit_hz: float = LOWER_LIMIT_HZ
    source: str = ""
    fit_range_max_hz: float = math.inf

    @property
    def zero_from_hz(self):
        """0 from here on: the first root (Section 4.2.1), or the end of the fitted n0 range where
        the cubic has no root there (re-derived functions; no extrapolation above 21 Hz)."""
        return zero_from_hz(self.coefficients, self.lower_limit_hz, self.fit_range_max_hz)

    @property
    def coefficients(self):
        return (self.a, self.b, self.c, self.d)

    def polynomial_pct(self, n0_hz):
        """Eq. (20) without the validity rules (%), any shape."""
        return np.polyval(self.coefficients, n0_hz)

    @property
    def first_root_hz(self):
        """First real root of Eq. (20) above the lower limit (Hz), computed."""
        return first_root_hz(self.coefficients, self.lower_limit_hz)

    def value_pct(self, n0_hz):
        """Lower bound (%) at ``n0_hz``, any shape (:func:`adm_calib.lower_bound.lower_bound_pct`)."""
        return lower_bound_pct(self.coefficients, n0_hz, self.lower_limit_hz, self.fit_range_max_hz)

    def delta_zeta_pct(self, n0_hz):
        """Lower bound (%) at ``n0_hz``: Eq. (20) up to the first root, 0 beyond.

        Raises
        ------
        InputError
            Below the lower limit (2.1 Hz).
        """
        n0 = check_range("n0_hz", n0_hz, "Hz", self.lower_limit_hz, None)
        return lower_bound_pct(self.coefficients, n0, self.lower_limit_hz, self.fit_range_max_hz)


#: Sets of lower-bound functions: the published ones and the ones re-derived from the shipped study.
LOWER_BOUND_FILES = {"paper": "data/lower_bounds.toml", "ours": "data/lower_bounds_study.toml",
                     "conservative": "data/lower_bounds_conservative.toml"}
#: What each set of functions is, as printed by ``recommend``.
FUNCTION_SOURCES = {"paper": "Tables B1-B4 (paper)", "ours": "re-derived from the shipped study (ours)",
                    "conservative": "conservative: the largest cubic below every retained case of the shipped "
                                    "study (linear programme)"}


@lru_cache(maxsize=4)
def lower_bound_table(functions="paper"):
    """Lower-bound functions ``{train: {mass_function: LowerBound}}``.

    ``functions="paper"``: Tables B1-B4 as printed; ``"ours"``: the functions fitted by
    ``adm-calib study-fit`` to the study shipped in ``results/study`` (same rules, Section 4.2.1);
    ``"conservative"``: the linear-programme bounds of the same study
    (:mod:`adm_calib.study.conservative`), below every retained case up to their first root.
    """
    if functions not in LOWER_BOUND_FILES:
        raise InputError(f"functions: {functions!r} is not allowed; allowed {', '.join(map(repr, LOWER_BOUND_FILES))}")
    text = resources.files("adm_calib").joinpath(LOWER_BOUND_FILES[functions]).read_text()
    data = tomllib.loads(text)
    cols = data["columns"]
    out = {}
    for train, tab in data["tables"].items():
        out[train] = {}
        for mf, row in tab.items():
            if not mf.startswith("mu"):
                continue
            vals = dict(zip(cols, row))
            out[train][mf] = LowerBound(train=train, mass_function=mf, lower_limit_hz=data["lower_limit_hz"],
                                        source=tab.get("source", ""),
                                        fit_range_max_hz=data.get("fit_range_max_hz", math.inf), **vals)
    return out


def lower_bound(train, mass_function):
    """The :class:`LowerBound` for a study train and a mass function ``"mu1"..."mu6"``."""
    t = canonical_train_name(train)
    table = lower_bound_table()[t]
    if mass_function not in table:
        raise InputError(f"mass_function: {mass_function!r} unknown; allowed {', '.join(table)}")
    return table[mass_function]


def span_from_frequency_m(n0_hz):
    """Span (m) from the fitted power law n0 = 97.76 L^-0.9124 (Section 3.1.1)."""
    return (float(n0_hz) / N0_FIT[0]) ** (1.0 / N0_FIT[1])


@dataclass(frozen=True)
class Recommendation:
    """Additional damping by Section 4.3 for one bridge and one study train."""

    train: str
    n0_hz: float
    mu_t_m: float
    bridge_type: str
    span_m: float
    span_estimated: bool
    rule: str
    mass_functions: tuple
    weights: tuple
    function_values_pct: tuple
    mass_function_t_m: dict
    delta_zeta_pct: float
    beyond_root: bool
    explanation: str = field(default="")
    functions: str = "paper"

    def to_dict(self):
        return {
            "train": self.train, "n0_hz": self.n0_hz, "mu_t_m": self.mu_t_m, "bridge_type": self.bridge_type,
            "span_m": self.span_m, "span_estimated": self.span_estimated, "rule": self.rule,
            "mass_functions": list(self.mass_functions), "weights": list(self.weights),
            "function_values_pct": list(self.function_values_pct),
            "mass_function_t_m": dict(self.mass_function_t_m),
            "delta_zeta_lb_pct": self.delta_zeta_pct, "beyond_root": self.beyond_root,
            "explanation": self.explanation, "functions": self.functions,
        }


def recommend(train, n0_hz, mu_t_m, bridge_type, *, span_m=None, interpolate=False, functions="paper",
              extrapolate=False, table=None):
    """Additional damping (%) from the lower-bound functions by the rules of Section 4.3.

    Parameters
    ----------
    train : str
        One of the four study trains (case-insensitive).
    n0_hz : float
        First natural frequency (Hz), 2.1 Hz up to the field's highest frequency.
    mu_t_m : float
        Bridge mass per length (t/m).
    bridge_type : {"cfb", "sc"}
        Concrete/filler beam or steel/composite.
    span_m : float, optional
        Span (m) placing ``mu`` among the mass functions (Eq. 19); estimated from n0 by the fitted
        power law when omitted.
    interpolate : bool
        Linear interpolation in mu between the adjacent functions instead of the safe-side rule.
    functions : {"paper", "ours", "conservative"}
        Published functions (Tables B1-B4), the ones re-derived from the shipped study by least
        squares, or its conservative (linear-programme) bounds.
    extrapolate : bool
        Accept a span outside the studied 4..40 m (up to the bridge model's 1..150 m): the mass
        functions of Eq. (19) are then extrapolated. The n0 validity of the functions still holds.
    table : dict, optional
        ``{mass_function: LowerBound}`` of a train outside the paper's (a functions file of
        ``adm-calib study-fit``, :func:`adm_calib.study.own_train.read_functions`): used in place of
        the four trains' sets; ``train`` is then its name as given and ``functions`` the text
        printed for the set.

    Raises
    ------
    InputError
        Unknown train or type, frequency, mass or span outside the validity of the functions.
    """
    own = table is not None
    t = canonical_train_name(train) if table is None else str(train)
    if bridge_type not in TYPE_MASS_FUNCTIONS:
        raise InputError(f"bridge_type: {bridge_type!r} is not allowed; allowed 'cfb' or 'sc'")
    table = lower_bound_table(functions)[t] if table is None else table
    lo_hz = next(iter(table.values())).lower_limit_hz
    try:
        n0 = check_range("n0_hz", n0_hz, "Hz", lo_hz, STUDY_N0_MAX_HZ)
    except InputError as exc:
        raise InputError(f"{exc} (validity of the lower-bound functions: {lo_hz:g} Hz up to the highest "
                         f"frequency of the studied bridges, Section 4.2.2)") from None
    mu = check_range("mu", mu_t_m, "t/m", 0.5, 100.0)
    estimated = span_m is None
    if estimated:
        L = span_from_frequency_m(n0)
        if not extrapolate and not STUDY_SPAN_RANGE_M[0] <= L <= STUDY_SPAN_RANGE_M[1]:
            raise InputError(f"span_m: estimated {L:.3g} m from n0={n0:g} Hz is outside the studied spans "
                             f"[{STUDY_SPAN_RANGE_M[0]:g}, {STUDY_SPAN_RANGE_M[1]:g}] m; give --span")
    else:
        L = check_range("span_m", span_m, "m", *(SPAN_RANGE_M if extrapolate else STUDY_SPAN_RANGE_M))
    names = TYPE_MASS_FUNCTIONS[bridge_type]
    mus = {m: mass_function_t_m(m, L) for m in names}
    used, weights, rule = _section_43_rule(mu, mus, names, bridge_type, interpolate)
    if own and any(m not in table for m in used):
        raise InputError(f"functions: {functions} has no lower-bound function {', '.join(m for m in used if m not in table)} "
                         f"for {t} (its study did not run it, or it gave fewer than 4 interval minima); allowed a bridge "
                         f"whose rule uses {', '.join(table)}")
    if any(m not in table for m in used):
        raise InputError(f"functions: {functions!r} has no lower-bound function for {t} "
                         f"{', '.join(m for m in used if m not in table)}")
    values = tuple(table[m].delta_zeta_pct(n0) for m in used)
    dz = float(sum(w * v for w, v in zip(weights, values)))
    beyond = all(n0 >= table[m].zero_from_hz for m in used)
    funcs = ", ".join(f"{m} ({1000 * mus[m]:.0f} kg/m = {mus[m]:.3f} t/m at L={L:g} m): {v:.4f} %"
                      for m, v in zip(used, values))
    source = FUNCTION_SOURCES.get(functions, functions)
    expl = (f"{source}; {t}, {bridge_type.upper()}, n0={n0:g} Hz, mu={1000 * mu:g} kg/m ({mu:g} t/m), L={L:.3g} m"
            f"{' (estimated from n0 = 97.76 L^-0.9124)' if estimated else ''}; {rule}; {funcs}"
            f"{'; n0 beyond the first root: 0' if beyond else ''}")
    return Recommendation(train=t, n0_hz=n0, mu_t_m=mu, bridge_type=bridge_type, span_m=L,
                          span_estimated=estimated, rule=rule, mass_functions=used, weights=weights,
                          function_values_pct=values, mass_function_t_m=mus, delta_zeta_pct=dz,
                          beyond_root=beyond, explanation=expl, functions=functions)


def _section_43_rule(mu, mus, names, bridge_type, interpolate):
    """The mass functions of Section 4.3 for ``mu`` (t/m) among ``mus`` (t/m at the span, ``names``
    heavy to light): ``(used, weights, rule)`` - the function ``mu`` lies on (to
    :data:`ON_FUNCTION_RTOL`), the nearest outside them, else the next heavier (safe side) or the
    two adjacent ones interpolated linearly in mu."""
    heavy, light = mus[names[0]], mus[names[-1]]
    tol = ON_FUNCTION_RTOL
    on = [m for m in names if abs(mu - mus[m]) <= tol * mus[m]]
    if on:
        return (on[0],), (1.0,), f"mu lies on mass function {on[0]}"
    if mu > heavy:
        return (names[0],), (1.0,), (f"mu above the heaviest {bridge_type.upper()} mass function: "
                                     f"nearest function {names[0]} (Section 4.3)")
    if mu < light:
        return (names[-1],), (1.0,), (f"mu below the lightest {bridge_type.upper()} mass function: "
                                      f"nearest function {names[-1]} (Section 4.3)")
    i = next(k for k in range(len(names) - 1) if mus[names[k + 1]] <= mu <= mus[names[k]])
    up, lo = names[i], names[i + 1]
    if interpolate:
        w_up = (mu - mus[lo]) / (mus[up] - mus[lo])
        return (up, lo), (w_up, 1.0 - w_up), f"mu between {up} and {lo}: linear interpolation in mu (Section 4.3)"
    return (up,), (1.0,), f"mu between {up} and {lo}: next heavier function {up}, safe side (Section 4.3)"


def lower_bound_for(bridge, train):
    """Lower-bound Δζ for a :class:`~adm_sim.model.bridge.Bridge` and a train (name or ``Train``).

    Returns ``(pct or None, note)``.

    Never raises for a valid bridge: outside the validity the value is ``None`` with the reason, also
    on a continuous deck of two or more spans (:data:`DECK_NOTE`; a deck of one span is the simply
    supported span).
    """
    if spans := _deck_spans(bridge):
        return None, (f"lower bound not defined: a continuous deck of {len(spans)} spans "
                      f"{'/'.join(f'{x:g}' for x in spans)} m; {DECK_NOTE}")
    if bridge.bridge_type not in TYPE_MASS_FUNCTIONS:
        return None, "lower bound not defined: the bridge type (cfb|sc) is unknown"
    if not isinstance(train, str):
        train = getattr(train, "paper_train", "") or train.name
    try:
        rec = recommend(train, bridge.n0_hz, bridge.mass_per_length_kg_m / 1000.0, bridge.bridge_type,
                        span_m=bridge.span_m)
    except InputError as exc:
        return None, f"lower bound not defined: {exc}"
    return rec.delta_zeta_pct, rec.explanation


__all__ = [
    "STUDY_TRAINS", "TYPE_MASS_FUNCTIONS", "MASS_FUNCTIONS", "adm_delta_zeta_pct", "HalfCoach", "half_coach",
    "eada_vehicle", "eada_delta_zeta_pct", "eada_for", "LowerBound", "lower_bound_table", "lower_bound",
    "span_from_frequency_m", "Recommendation", "recommend", "lower_bound_for", "canonical_train_name",
    "first_root_hz", "lower_bound_pct", "LOWER_LIMIT_HZ", "FIT_RANGE_MAX_HZ", "DECK_NOTE", "EADA_DECK_NOTE",
]
