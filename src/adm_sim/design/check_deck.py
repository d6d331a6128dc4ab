"""EN 1991-2 dynamic check of a continuous deck (``adm-sim check`` on a bridge with ``spans``).

The deck of :mod:`adm_sim.model.spans` (1-6 spans, pinned over the intermediate supports, exact
modes). For every load train (HSLM-A1 .. A10, real trains by their static axle loads, TOML trains):

* **acceleration per span** (EN 1990 A2.4.4.2.1): the moving-load sweeps of
  :mod:`adm_sim.design.deck_dynamics` over 40 m/s .. 1.2 V (EN 1991-2 6.4.6.2(1)), refined at
  0.1 km/h around every resonance as the single-span check, read at a grid of points in every span
  (:data:`adm_sim.design.deck_dynamics.POINTS_PER_SPAN` equal intervals, the midspan among them); the
  largest |a| per span and where, against 3.5 / 5 m/s^2; modes: every mode up to
  max(30 Hz, 1.5 n0, n3) (EN 1990 A2.4.4.2.1; :func:`adm_sim.model.spans.rule_mode_count`);
* **EN 1991-2 6.4.6.5(3)** for every effect: the moment at x/L = 0.1 .. 0.9 of every span (sagging),
  the hogging moment at every intermediate support, the shear next to every support, every support
  reaction and the deflection at every midspan; ``(1 + φ'_dyn + r φ'') x train`` against
  ``Φ x α x LM71``, LM71 on the influence line of the continuous beam with its distributed load on
  the unfavourable parts (:mod:`adm_sim.design.deck_statics`), φ'_dyn = dyn/stat - 1 (Eq. 6.14) by the
  mode-acceleration method, r = 1/2 careful, 1 standard maintenance
  (:func:`adm_sim.design.design_loads.phi_dd_factor`);
* **Φ2 / Φ3 and φ''** with the determinant length of EN 1991-2 Table 6.2 for continuous beams:
  ``L_Φ = k L_m``, ``L_m`` the mean span, ``k = 1.2, 1.3, 1.4, 1.5`` for 2, 3, 4, 5 or more spans, and
  not less than the longest span (:func:`determinant_length_m`; the table's wording as quoted in the
  project's issue: the printed table could not be checked here);
* **deflection per span** under Φ x α x LM71 against L/600 (EN 1990 A2.4.4.2.3(1)) and the **end
  rotation at each abutment** (6.5 mrad ballasted, the infrastructure manager's rule the single-span
  check applies, :data:`adm_sim.design.check_sls.END_ROTATION_SOURCE`); δ_H = θ h of EN 1991-2
  6.5.4.5.2 at each abutment with ``deck_end_height_m``; the intermediate supports are continuous:
  no deck end, no end rotation there;
* **screening** of EN 1991-2 6.4.4 (Figs. 6.9/6.10): not applicable. Fig. 6.10's limits of n0 are for
  simply supported spans; that they do not apply to a continuous deck is our reading (the clause's
  text could not be checked here). The dynamic analysis is done.

Not wired for a deck (refused in one line): the Eurocode ADM (Fig. 6.15's L is a span; our reading:
not for continuous decks), the paper's lower bounds and Δζ_VBI (the study is of simply supported
spans), HSLM-B (EN 1991-2 6.4.6.1.1(5): simply supported spans under 7 m), mass and stiffness
bounds, the DIM's passenger comfort and the rough track.

numpy only; no ROS.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from adm_sim.design.check import DAMPING_MODELS, AccelerationVerdict, _refinement, check_speeds_kmh
from adm_sim.design.check_effects import EffectComparison
from adm_sim.design.check_sls import (DELTA_H_LIMITS_M, END_ROTATION_LIMIT_RAD, END_ROTATION_SOURCE,
                                      LATERAL_FREQUENCY_MIN_HZ, check_deck_end_height, check_lateral_frequency)
from adm_sim.design.deck_dynamics import POINTS_PER_SPAN, STEPS_PER_PERIOD, deck_sweep
from adm_sim.design.deck_statics import DeckEffect, beam_of, lm71_max
from adm_sim.design.design_loads import (DEFAULT_MAINTENANCE, MAINTENANCE, check_alpha, dynamic_factor,
                                         maintenance_text, phi_dd_factor, phi_double_prime, phi_dyn_prime)
from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.fields import FIELDS
from adm_sim.limits import ACC_LIMITS_M_S2, DESIGN_SPEED_FACTOR
from adm_sim.model.hslm import HSLM_A_TABLE, POWER_CAR_SPACINGS_M, is_hslm_b_name, regular_spacing_m
from adm_sim.model.spans import RULE_TEXT, rule_mode_count

#: k of EN 1991-2 Table 6.2 for continuous beams by the number of spans (5 or more: 1.5).
LPHI_K = {2: 1.2, 3: 1.3, 4: 1.4, 5: 1.5}
LPHI_SOURCE = ("EN 1991-2 Table 6.2, continuous beams: L_Phi = k x L_m, L_m the mean span, k = 1.2, 1.3, 1.4, 1.5 "
               "for 2, 3, 4, 5 or more spans, not less than the longest span (as quoted in the project's issue; "
               "the printed table could not be checked here)")
SCREENING_TEXT = ("screening (EN 1991-2 6.4.4, Figs. 6.9/6.10): not applicable to a continuous deck: Fig. 6.10's "
                  "limits of n0 are for simply supported spans (our reading; the clause's text could not be "
                  "checked here); the dynamic analysis is done")
#: Sections of the moment in every span (x/L).
MOMENT_SECTIONS = tuple(np.round(np.linspace(0.1, 0.9, 9), 10))
#: One-sided offset (fraction of the span) of the shear next to a support.
SHEAR_OFFSET = 1e-9
#: Sections (x/L) searched for the largest LM71 deflection of a span before refinement.
DEFLECTION_SECTIONS = tuple(np.round(np.linspace(0.2, 0.8, 13), 10))
#: What the deck check does not cover.
NOT_CHECKED_DECK = (
    "deck twist (EN 1990 A2.4.4.2.2)",
    "track-bridge interaction (EN 1991-2 6.5.4)",
    "fatigue (EN 1991-2 6.4.6.6)",
    "passenger comfort (EN 1990 A2.4.4.3): the DIM's b_v is not wired for a continuous deck",
    "horizontal deflection (EN 1990 A2.4.4.2.4(2))",
    "mass and stiffness bounds (EN 1991-2 6.4.6.3.2, 6.4.6.3.3): not wired for a continuous deck",
    "additional damping: the Eurocode ADM (EN 1991-2 6.4.6.3.1, Fig. 6.15) and the paper's lower bounds are for "
    "simply supported spans (our reading)",
    "settlement of the intermediate supports, shear deformation, rotary inertia",
)


def determinant_length_m(spans_m):
    """L_Φ of a continuous deck (m), :data:`LPHI_SOURCE`; one span: the span (Table 6.2 case 5.1)."""
    spans = [float(x) for x in spans_m]
    n = len(spans)
    if n == 1:
        return spans[0]
    k = LPHI_K[min(n, 5)]
    return max(k * math.fsum(spans) / n, max(spans))


def deck_effects(beam):
    """The effects of 6.4.6.5(3) on the deck, in print order: reactions, hogging at the intermediate
    supports, the moment at x/L = 0.1 .. 0.9 of every span, the shear next to every support, the
    deflection at every midspan. Spans are numbered 1 .. N, supports 0 .. N (0 and N the abutments)."""
    sup, spans = beam.supports, beam.spans
    out = [DeckEffect("R", float(sup[k]), k, f"reaction support {k}") for k in range(sup.size)]
    out += [DeckEffect("M", float(sup[k]), -1, f"hogging M support {k}") for k in range(1, sup.size - 1)]
    for i, L in enumerate(spans):
        out += [DeckEffect("M", float(sup[i] + f * L), -1, f"M span {i + 1} {f:.1f} L") for f in MOMENT_SECTIONS]
    for i, L in enumerate(spans):
        out.append(DeckEffect("V", float(sup[i] + SHEAR_OFFSET * L), -1, f"V span {i + 1} at support {i}"))
        out.append(DeckEffect("V", float(sup[i + 1] - SHEAR_OFFSET * L), -1, f"V span {i + 1} at support {i + 1}"))
    out += [DeckEffect("w", float(sup[i] + 0.5 * L), -1, f"w midspan {i + 1}") for i, L in enumerate(spans)]
    return out


def axle_group_m(train):
    """The longest axle group of a train (m): its largest bogie wheelbase; HSLM-A its bogie axle spacing
    and the power car's 3 m (EN 1991-2 Fig. 6.12); 0 for bare axle loads."""
    groups = [vt.b_m for vt in train.vehicle_types.values()]
    if train.name in HSLM_A_TABLE and not train.units:
        groups += [HSLM_A_TABLE[train.name][2], POWER_CAR_SPACINGS_M[0]]
    return max(groups, default=0.0)


def check_deck_trains(bridge, trains):
    """Refuse HSLM-B on a deck and a span shorter than a train's longest axle group (one line)."""
    for t in trains:
        if is_hslm_b_name(t.name):
            raise InputError(f"trains: {t.name}: HSLM-B applies to simply supported spans < 7 m (EN 1991-2 "
                             f"6.4.6.1.1(5)); this is a continuous deck: check it with hslm (HSLM-A1 .. HSLM-A10)",
                             field="trains")
        g = axle_group_m(t)
        for i, L in enumerate(bridge.spans_m):
            if L < g:
                hi = FIELDS["deck_spans_m"].hi
                raise InputError(f"spans[{i}]: {L:g} m is shorter than the longest axle group of {t.name} "
                                 f"({g:g} m); allowed [{g:g}, {hi:g}] m", field="bridge")


def deck_modes_for(bridge, n_modes):
    """The deck with the rule's modes, or ``n_modes`` (int, <= 50; fewer than the rule: a warning
    naming the rule)."""
    need = rule_mode_count(bridge.spans_m, bridge.span_EJ_Nm2, bridge.span_mu_kg_m)
    fld = FIELDS["deck_n_modes"]
    if need > fld.hi:
        raise InputError(f"n_modes: the rule asks for {need} modes of this deck ({RULE_TEXT}); at most {fld.hi} "
                         f"are allowed", field="n_modes")
    if n_modes is None:
        return dataclasses.replace(bridge, n_modes=need), need
    try:
        n = float(n_modes)
    except (TypeError, ValueError):
        n = math.nan
    if not (math.isfinite(n) and n == int(n) and fld.lo <= n <= fld.hi):
        shown = f"{n:g}" if math.isfinite(n) else repr(n_modes)  # --modes arrives as a float: 51, not 51.0
        raise InputError(f"n_modes: {shown} is out of range; allowed an integer in [{fld.lo}, {fld.hi}] (the "
                         f"rule asks for {need} on this deck: {RULE_TEXT})", field="n_modes")
    n = int(n)
    if n < need:
        warnings.warn(f"n_modes: {n} modes is fewer than the {need} that EN 1990 A2.4.4.2.1 asks for on this deck "
                      f"({RULE_TEXT})", PlausibilityWarning, stacklevel=3)
    return dataclasses.replace(bridge, n_modes=n), need


@dataclass
class DeckTrainCheck:
    """The envelopes of one train on the deck: per speed and span, and every effect."""

    name: str
    kind: str
    speeds_kmh: np.ndarray
    acc_span_m_s2: np.ndarray  # (n_speeds, n_spans)
    x_acc_span_m: np.ndarray  # (n_speeds, n_spans)
    acc_midspan_m_s2: np.ndarray  # (n_speeds, n_spans)
    disp_midspan_m: np.ndarray  # (n_speeds, n_spans)
    effects: list
    static_max: np.ndarray  # (n_effects,)
    dynamic_max: np.ndarray  # (n_effects,)
    at_speed_kmh: np.ndarray  # (n_effects,)
    zeta: tuple
    delta_zeta_pct: float = 0.0
    damping_note: str = ""
    effect_design: tuple = ()

    @property
    def max_acc_m_s2(self):
        """Largest acceleration over the spans per speed, (n_speeds,)."""
        return self.acc_span_m_s2.max(1)

    @property
    def max_disp_m(self):
        """Largest midspan deflection over the spans per speed, (n_speeds,)."""
        return self.disp_midspan_m.max(1)

    @property
    def i_max(self):
        return int(np.argmax(self.max_acc_m_s2))

    @property
    def span_max(self):
        """1-based span of the largest acceleration."""
        return int(np.argmax(self.acc_span_m_s2[self.i_max])) + 1

    @property
    def x_max_m(self):
        return float(self.x_acc_span_m[self.i_max, self.span_max - 1])

    @property
    def phi_dyn(self):
        """φ'_dyn per effect (Eq. 6.14), (n_effects,)."""
        return np.array([phi_dyn_prime(d, s) if s > 0.0 else 0.0 for d, s in zip(self.dynamic_max, self.static_max)])

    def zeta_text(self):
        return "/".join(f"{100 * z:.3g}" for z in self.zeta)

    def to_dict(self):
        i = self.i_max
        return {"train": self.name, "kind": self.kind, "delta_zeta_pct": self.delta_zeta_pct,
                "damping_note": self.damping_note, "zeta_per_mode_pct": [100 * z for z in self.zeta],
                "max_acc_m_s2": float(self.max_acc_m_s2[i]), "at_speed_kmh": float(self.speeds_kmh[i]),
                "at_span": self.span_max, "at_x_m": self.x_max_m,
                "per_span": [{"span": s + 1, "max_acc_m_s2": float(self.acc_span_m_s2[:, s].max()),
                              "at_speed_kmh": float(self.speeds_kmh[int(self.acc_span_m_s2[:, s].argmax())]),
                              "at_x_m": float(self.x_acc_span_m[int(self.acc_span_m_s2[:, s].argmax()), s]),
                              "max_acc_midspan_m_s2": float(self.acc_midspan_m_s2[:, s].max()),
                              "max_disp_midspan_m": float(self.disp_midspan_m[:, s].max())}
                             for s in range(self.acc_span_m_s2.shape[1])],
                "effects": [{"effect": e.kind, "x_m": e.x_m, "label": e.label, "static_max": float(st),
                             "dynamic_max": float(dy), "at_speed_kmh": float(sp), "phi_dyn": float(ph),
                             **({} if cmp is None else {"train_design": cmp.train_design,
                                                        "lm71_design": cmp.lm71_design, "ratio": cmp.ratio})}
                            for e, st, dy, sp, ph, cmp in zip(self.effects, self.static_max, self.dynamic_max,
                                                              self.at_speed_kmh, self.phi_dyn,
                                                              self.effect_design or [None] * len(self.effects))],
                "curve": {"speeds_kmh": self.speeds_kmh.tolist(), "max_acc_m_s2": self.max_acc_m_s2.tolist(),
                          "acc_per_span_m_s2": self.acc_span_m_s2.T.tolist(),
                          "x_acc_per_span_m": self.x_acc_span_m.T.tolist()}}


@dataclass(frozen=True)
class DeckServiceability:
    """Deflection per span and end rotation per abutment under Φ x α x LM71 (EN 1990 A2.4.4)."""

    spans_m: tuple
    Phi: float
    alpha: float
    track: str
    deflection_m: tuple  # per span, Φ α LM71
    deflection_x_m: tuple
    end_rotation_rad: tuple  # (left abutment, right abutment), Φ α LM71
    lateral_frequency_hz: float | None = None
    deck_end_height_m: float | None = None

    def deflection_ok(self, i):
        return self.deflection_m[i] <= self.spans_m[i] / 600.0

    def lines(self):
        v = lambda ok: "PASS" if ok else "FAIL"  # noqa: E731
        out = []
        for i, (L, w, x) in enumerate(zip(self.spans_m, self.deflection_m, self.deflection_x_m)):
            out.append(f"EN 1990 A2.4.4.2.3(1) span {i + 1} ({L:g} m): vertical deflection under Phi x alpha x LM71 = "
                       f"{self.Phi:.3f} x {self.alpha:g} x LM71: {1e3 * w:.3f} mm at x = {x:.2f} m, limit L/600 = "
                       f"{1e3 * L / 600.0:.3f} mm: {v(self.deflection_ok(i))} (L/{L / w:.0f})")
        for side, th in zip(("left", "right"), self.end_rotation_rad):
            lim = (f"limit {1e3 * END_ROTATION_LIMIT_RAD:g} mrad at an abutment, ballasted track ({END_ROTATION_SOURCE}): "
                   f"{v(th <= END_ROTATION_LIMIT_RAD)}" if self.track == "ballasted" else
                   "direct fastening: the limit is the relevant authority's; not judged")
            out.append(f"deck end rotation at the {side} abutment under Phi x alpha x LM71: {1e3 * th:.3f} mrad ({lim})")
            if self.deck_end_height_m is not None:
                d = th * self.deck_end_height_m
                out.append(f"deck-end displacement delta_H at the {side} abutment = theta h = {1e3 * d:.3f} mm "
                           f"(EN 1991-2 6.5.4.5.2): limit 8 mm {v(d <= DELTA_H_LIMITS_M[0])}, limit 10 mm "
                           f"{v(d <= DELTA_H_LIMITS_M[1])}")
        out.append("the intermediate supports are continuous: no deck end, no end rotation limit there")
        if self.lateral_frequency_hz is None:
            out.append("lateral frequency (EN 1990 A2.4.4.2.4(3), >= 1.2 Hz): not checked (give --lateral-frequency, Hz)")
        else:
            out.append(f"lateral frequency {self.lateral_frequency_hz:g} Hz (given), limit >= "
                       f"{LATERAL_FREQUENCY_MIN_HZ:g} Hz (EN 1990 A2.4.4.2.4(3)): "
                       f"{v(self.lateral_frequency_hz >= LATERAL_FREQUENCY_MIN_HZ)}")
        return out

    def to_dict(self):
        return {"per_span": [{"span": i + 1, "span_m": L, "deflection_m": w, "deflection_x_m": x,
                              "deflection_limit_m": L / 600.0, "deflection_ok": bool(self.deflection_ok(i))}
                             for i, (L, w, x) in enumerate(zip(self.spans_m, self.deflection_m, self.deflection_x_m))],
                "end_rotation_rad": {"left": self.end_rotation_rad[0], "right": self.end_rotation_rad[1]},
                "end_rotation_limit_rad": END_ROTATION_LIMIT_RAD, "end_rotation_limit_source": END_ROTATION_SOURCE,
                "deck_end_height_m": self.deck_end_height_m, "lateral_frequency_hz": self.lateral_frequency_hz,
                "Phi": self.Phi, "alpha": self.alpha}


def deck_serviceability(bridge, Phi, alpha, track, lateral_frequency_hz=None, deck_end_height_m=None):
    """:class:`DeckServiceability`: the largest LM71 deflection of every span (sections
    :data:`DEFLECTION_SECTIONS`, refined by golden section to 1e-4 L) and the end rotations."""
    beam = beam_of(bridge)
    defl, xs = [], []
    for i, L in enumerate(bridge.spans_m):
        a = beam.supports[i]

        def w_at(x):
            return lm71_max(beam, DeckEffect("w", float(x))).value

        vals = [w_at(a + f * L) for f in DEFLECTION_SECTIONS]
        k = int(np.argmax(vals))
        f = np.asarray(DEFLECTION_SECTIONS)
        lo, hi = a + f[max(k - 1, 0)] * L, a + f[min(k + 1, f.size - 1)] * L
        x, w = _golden_max(w_at, lo, hi, 1e-4 * L)
        if vals[k] >= w:
            x, w = a + f[k] * L, vals[k]
        defl.append(float(Phi * alpha * w))
        xs.append(float(x))
    n = len(bridge.spans_m)
    th = tuple(float(Phi * alpha * lm71_max(beam, DeckEffect("theta", float(beam.supports[k]), k)).value)
               for k in (0, n))
    return DeckServiceability(spans_m=tuple(bridge.spans_m), Phi=float(Phi), alpha=float(alpha), track=track,
                              deflection_m=tuple(defl), deflection_x_m=tuple(xs), end_rotation_rad=th,
                              lateral_frequency_hz=lateral_frequency_hz, deck_end_height_m=deck_end_height_m)


def _golden_max(f, a, b, tol):
    r = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - r * (b - a), a + r * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol:
        if fc > fd:
            b, d, fd = d, c, fc
            c = b - r * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + r * (b - a)
            fd = f(d)
    x = 0.5 * (a + b)
    return x, f(x)


@dataclass
class DeckCheckResult(AccelerationVerdict):
    """Verdict of the deck check and every curve behind it."""

    bridge: object
    max_line_speed_kmh: float
    track: str
    damping: str
    speeds_kmh: np.ndarray
    trains: list
    modes: tuple
    rule_modes: int
    L_phi_m: float
    Phi: float
    phi_dd: float
    track_maintenance: str
    maintenance_named: bool
    alpha: float
    sls: DeckServiceability
    lm71: tuple  # LM71Max per effect (α included)
    where: str = "deck"
    damping_model: str = "modal"
    timings_s: dict = field(default_factory=dict)
    screening: str = SCREENING_TEXT
    is_deck: bool = True
    bounds: tuple = ()
    rough: tuple = ()

    @property
    def passed(self):
        return self.governing[2] <= self.limit_m_s2

    @property
    def where_text(self):
        return "every span (grid)" if self.where == "deck" else "every midspan"

    @property
    def damping_source(self):
        """Where ζ comes from: the reader's label on the bridge, else "as given"."""
        return self.bridge.damping_source or "as given"

    def span_governing(self):
        """Per span: (train check, speed km/h, acceleration m/s^2, x m) of its largest acceleration."""
        out = []
        for s in range(len(self.bridge.spans_m)):
            t = max(self.trains, key=lambda c: c.acc_span_m_s2[:, s].max())
            i = int(t.acc_span_m_s2[:, s].argmax())
            out.append((t, float(t.speeds_kmh[i]), float(t.acc_span_m_s2[i, s]), float(t.x_acc_span_m[i, s])))
        return out

    def effects_governing(self):
        """Per effect: (train check, EffectComparison, index) of the largest 6.4.6.5(3) ratio."""
        out = []
        for i in range(len(self.trains[0].effect_design)):
            t = max(self.trains, key=lambda c: c.effect_design[i].ratio)
            out.append((t, t.effect_design[i], i))
        return out

    def not_checked(self):
        return NOT_CHECKED_DECK

    def envelope_governing(self):
        t, v, a = self.governing
        return "nominal", t, v, a

    def modes_text(self):
        b = self.bridge
        return ", ".join(f"{j} ({x:.3f} Hz, {m / 1000:.5g} t)" for j, x, m in zip(self.modes, b.frequencies_hz,
                                                                                 b.modal_mass_kg))

    def lines(self):
        """Every line ``adm-sim check`` prints for a deck."""
        b = self.bridge
        v = self.speeds_kmh
        spans = "+".join(f"{x:g}" for x in b.spans_m)
        out = [b.describe(),
               f"continuous deck: spans 1..{len(b.spans_m)} = {spans} m, supports 0..{len(b.spans_m)} at "
               + ", ".join(f"{x:g}" for x in b.supports_m) + " m (0 and the last are the abutments)",
               f"speeds: {v.min():g} .. {v.max():g} km/h (40 m/s .. {DESIGN_SPEED_FACTOR:g} x {self.max_line_speed_kmh:g} "
               f"km/h, EN 1991-2 6.4.6.2), {v.size} speeds at <= 1 km/h, refined at 0.1 km/h around every resonance",
               f"modes: {self.modes_text()} (EN 1990 A2.4.4.2.1: every mode up to max(30 Hz, 1.5 n0, n3): "
               f"{self.rule_modes} modes on this deck)",
               f"acceleration: {self.where_text}: the largest |a| over {POINTS_PER_SPAN - 1} points per span (equal "
               f"intervals, the midspan among them), moving loads on the deck's exact modes, RK4 at "
               f"{STEPS_PER_PERIOD:g} steps per period of the top mode (maxima at the steps)",
               f"damping: zeta = {100 * b.damping_ratio:.3g} % ({self.damping_source}; {self.damping_model}; zeta "
               f"per mode {self.trains[0].zeta_text()} %), no additional damping",
               f"track maintenance: {maintenance_text(self.track_maintenance, self.maintenance_named)}",
               f"determinant length L_Phi = {self.L_phi_m:.3f} m ({LPHI_SOURCE}); Phi = {self.Phi:.3f}, "
               f"phi'' = {self.phi_dd:.4f} (Annex C, v = {self.max_line_speed_kmh:g} km/h, n0 = {b.n0_hz:.3f} Hz)"]
        out += self._acc_lines() + self._effect_lines() + self.sls.lines() + [self.screening]
        out.append("not checked: " + "; ".join(self.not_checked()))
        return out

    def _acc_lines(self):
        w = max([14] + [len(c.name) for c in self.trains])
        n = len(self.bridge.spans_m)
        out = [f"{'train':{w}s} " + " ".join(f"{'span ' + str(s + 1):>10s}" for s in range(n))
               + "  max acc per span (m/s2) and its speed (km/h)"]
        for c in self.trains:
            cells = []
            for s in range(n):
                i = int(c.acc_span_m_s2[:, s].argmax())
                cells.append(f"{c.acc_span_m_s2[i, s]:6.3f}@{c.speeds_kmh[i]:3.0f}")
            out.append(f"{c.name:{w}s} " + " ".join(f"{x:>10s}" for x in cells))
        for s, (t, sp, a, x) in enumerate(self.span_governing()):
            out.append(f"span {s + 1}: governing {t.name} at {sp:g} km/h, x = {x:.3f} m, {a:.4f} m/s2; limit "
                       f"{self.limit_m_s2:g} m/s2: {'PASS' if a <= self.limit_m_s2 else 'FAIL'}")
        t, sp, acc = self.governing
        out.append(f"governing: {t.name} at {sp:g} km/h, span {t.span_max}, x = {t.x_max_m:.3f} m, max deck "
                   f"acceleration {acc:.4f} m/s2; limit {self.limit_m_s2:g} m/s2 ({self.track} track, EN 1990 "
                   f"A2.4.4.2.1): {'PASS' if self.passed else 'FAIL'}, margin {self.limit_m_s2 - acc:+.4f} m/s2")
        for end, cs in self.range_end_maxima().items():
            out.append(f"WARNING: the largest acceleration of {', '.join(c.name for c in cs)} lies at the {end} of "
                       f"the checked range: the resonance may lie outside it")
        return out

    def _effect_lines(self):
        gov = self.effects_governing()
        d0 = gov[0][1]
        share = "phi''/2" if d0.phi_dd_factor == 0.5 else "phi''"
        w = max([10] + [len(t.name) for t, _, _ in gov])
        out = [f"EN 1991-2 6.4.6.5(3), every effect of the continuous deck: (1 + phi'_dyn + {share}) x train vs "
               f"Phi = {d0.Phi:.3f} x alpha = {self.alpha:g} x LM71 (6.3.2; on the influence line of the continuous "
               f"beam, the distributed load on its unfavourable parts); phi'_dyn by the mode-acceleration method: "
               f"{len(self.modes)} modes dynamic plus the exact static effect; M in kNm, V and reactions in kN, w in mm",
               f"{'effect':24s} {'train':{w}s} {'phi_dyn':>8s} {'at':>7s} {'static':>9s} {'design':>9s} "
               f"{'Phi LM71':>9s} {'ratio':>6s}"]
        for t, d, i in gov:
            sc = 1e-3 if d.effect.kind != "w" else 1e3
            out.append(f"{d.effect.label:24s} {t.name:{w}s} {d.phi_dyn:8.3f} {t.at_speed_kmh[i]:7.1f} "
                       f"{d.train_static * sc:9.2f} {d.train_design * sc:9.2f} {d.lm71_design * sc:9.2f} {d.ratio:6.3f}")
        t, d, _ = max(gov, key=lambda g: g[1].ratio)
        out.append(f"every effect: governed by {'the train' if d.ratio > 1.0 else 'Phi x alpha x LM71'} (largest "
                   f"ratio {d.ratio:.3f}: {d.effect.label}, {t.name})")
        return out

    def summary(self):
        return "\n".join(self.lines())

    def to_dict(self):
        t, sp, acc = self.governing
        b = self.bridge
        return {"bridge": b.describe(), "continuous_deck": True, "spans_m": list(b.spans_m),
                "supports_m": b.supports_m.tolist(), "max_line_speed_kmh": self.max_line_speed_kmh,
                "design_speed_kmh": DESIGN_SPEED_FACTOR * self.max_line_speed_kmh, "track": self.track,
                "damping": self.damping, "damping_model": self.damping_model, "where": self.where,
                "zeta_pct": 100.0 * b.damping_ratio, "damping_source": self.damping_source,
                "limit_m_s2": self.limit_m_s2, "modes": list(self.modes),
                "frequencies_hz": b.frequencies_hz.tolist(), "modal_masses_kg": b.modal_mass_kg.tolist(),
                "rule_modes": self.rule_modes, "L_phi_m": self.L_phi_m, "L_phi_source": LPHI_SOURCE,
                "Phi": self.Phi, "phi_dd": self.phi_dd, "track_maintenance": self.track_maintenance,
                "track_maintenance_reason": maintenance_text(self.track_maintenance, self.maintenance_named),
                "alpha": self.alpha,
                "governing": {"train": t.name, "speed_kmh": sp, "acc_m_s2": acc, "span": t.span_max,
                              "x_m": t.x_max_m},
                "per_span_governing": [{"span": s + 1, "train": g.name, "speed_kmh": v, "acc_m_s2": a, "x_m": x}
                                       for s, (g, v, a, x) in enumerate(self.span_governing())],
                "verdict": "pass" if self.passed else "fail", "margin_m_s2": self.limit_m_s2 - acc,
                "en1991_2_6_4_6_5_effects": [
                    {"effect": d.effect.kind, "x_m": d.effect.x_m, "label": d.effect.label, "train": g.name,
                     "at_speed_kmh": float(g.at_speed_kmh[i]), "phi_dyn": d.phi_dyn, "phi_dd_factor": d.phi_dd_factor,
                     "train_static": d.train_static, "lm71_static": d.lm71_static, "train_design": d.train_design,
                     "lm71_design": d.lm71_design, "ratio": d.ratio, "lm71_group_centre_m": self.lm71[i].centre_m,
                     "governs": "train" if d.ratio > 1.0 else "LM71"} for g, d, i in self.effects_governing()],
                "en1990_a2_4_4_serviceability": self.sls.to_dict(), "screening": self.screening,
                "not_checked": list(self.not_checked()), "timings_s": self.timings_s,
                "trains": [c.to_dict() for c in self.trains]}

    def write_csv(self, path):
        """Every curve in long format: train, speed_kmh, span, max_acc_m_s2, x_acc_m, max_acc_midspan_m_s2,
        max_disp_midspan_m."""
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["train", "speed_kmh", "span", "max_acc_m_s2", "x_acc_m", "max_acc_midspan_m_s2",
                        "max_disp_midspan_m"])
            for c in self.trains:
                for k, v in enumerate(c.speeds_kmh):
                    for s in range(c.acc_span_m_s2.shape[1]):
                        w.writerow([c.name, f"{v:.3f}", s + 1, f"{c.acc_span_m_s2[k, s]:.8g}",
                                    f"{c.x_acc_span_m[k, s]:.6g}", f"{c.acc_midspan_m_s2[k, s]:.8g}",
                                    f"{c.disp_midspan_m[k, s]:.8g}"])


def _sweep_train(b, beam, effects, t, speeds, where):
    """One train's deck sweep over ``speeds`` and the 0.1 km/h refinement around its resonances."""
    sw = deck_sweep(b, beam, effects, t.axle_offsets_m, t.axle_loads_n, speeds)
    acc = (sw.max_acc_m_s2 if where == "deck" else sw.max_acc_midspan_m_s2).max(1)
    extra = np.array([])
    if t.name in HSLM_A_TABLE and not t.units:
        extra = 3.6 * b.n0_hz * regular_spacing_m(t.name) / np.arange(1, 50)
    fine = _refinement(speeds, acc, extra, speeds[0], speeds[-1])
    if fine.size == 0:
        return sw
    sf = deck_sweep(b, beam, effects, t.axle_offsets_m, t.axle_loads_n, fine)
    v = np.concatenate([sw.speeds_kmh, sf.speeds_kmh])
    order = np.argsort(v, kind="stable")
    cat = {k: np.concatenate([getattr(sw, k), getattr(sf, k)])[order]
           for k in ("max_acc_m_s2", "x_acc_m", "max_acc_midspan_m_s2", "max_disp_midspan_m", "effects_max")}
    return dataclasses.replace(sw, speeds_kmh=v[order], static_max=np.maximum(sw.static_max, sf.static_max), **cat)


def run_deck_check(bridge, max_line_speed_kmh, trains, *, track="ballasted", damping="none", step_kmh=1.0,
                   progress=None, n_modes=None, where="deck", damping_model="modal", track_maintenance=None,
                   alpha=1.0, lateral_frequency_hz=None, deck_end_height_m=None):
    """The dynamic check of a continuous deck (see the module doc). Returns :class:`DeckCheckResult`."""
    if track not in ACC_LIMITS_M_S2:
        raise InputError(f"track: {track!r} is not allowed; allowed {', '.join(ACC_LIMITS_M_S2)}", field="track")
    if damping != "none":
        raise InputError(f"damping {damping}: additional damping is not wired for a continuous deck (the Eurocode ADM "
                         f"of EN 1991-2 6.4.6.3.1 and the paper's Δζ are for simply supported spans, our reading); "
                         f"allowed --damping none", field="damping")
    if where not in ("deck", "midspan"):
        raise InputError(f"where: {where!r} is not taken on a continuous deck; allowed deck (every span's grid) or "
                         f"midspan (every span's midspan)", field="where")
    damping_model = "modal" if damping_model is None else damping_model
    if damping_model not in DAMPING_MODELS:
        raise InputError(f"damping_model: {damping_model!r} is not allowed; allowed {', '.join(DAMPING_MODELS)}",
                         field="damping_model")
    maintenance_named = track_maintenance is not None
    maintenance = DEFAULT_MAINTENANCE if track_maintenance is None else track_maintenance
    if maintenance not in MAINTENANCE:
        raise InputError(f"track_maintenance: {maintenance!r} is not one of EN 1991-2 6.4.5.2's; allowed "
                         f"{', '.join(MAINTENANCE)} (careful: Φ2, standard: Φ3)", field="track_maintenance")
    alpha = check_alpha(alpha)
    lateral = None if lateral_frequency_hz is None else check_lateral_frequency(lateral_frequency_hz)
    h = None if deck_end_height_m is None else check_deck_end_height(deck_end_height_m)
    speeds = check_speeds_kmh(max_line_speed_kmh, step_kmh)
    check_deck_trains(bridge, trains)
    b, need = deck_modes_for(bridge, n_modes)
    b = dataclasses.replace(b, damping_model=DAMPING_MODELS[damping_model])
    t0 = time.perf_counter()
    beam = beam_of(b)
    effects = deck_effects(beam)
    lm71 = tuple(lm71_max(beam, e, alpha) for e in effects)
    L_phi = determinant_length_m(b.spans_m)
    Phi = dynamic_factor(L_phi, maintenance)
    phi_dd = phi_double_prime(L_phi, b.n0_hz, float(max_line_speed_kmh) / 3.6)
    r = phi_dd_factor(maintenance)
    t_static = time.perf_counter() - t0
    zeta = tuple(float(z) for z in b.modal_damping_ratios(0.0))
    out = []
    for n, t in enumerate(trains):
        sw = _sweep_train(b, beam, effects, t, speeds, where)
        i = sw.effects_max.argmax(0)
        tc = DeckTrainCheck(name=t.name, kind="hslm" if (t.name in HSLM_A_TABLE and not t.units) else "train",
                            speeds_kmh=sw.speeds_kmh, acc_span_m_s2=(sw.max_acc_m_s2 if where == "deck"
                                                                     else sw.max_acc_midspan_m_s2),
                            x_acc_span_m=(sw.x_acc_m if where == "deck" else
                                          np.broadcast_to(b.supports_m[:-1] + 0.5 * np.asarray(b.spans_m),
                                                          sw.x_acc_m.shape).copy()),
                            acc_midspan_m_s2=sw.max_acc_midspan_m_s2, disp_midspan_m=sw.max_disp_midspan_m,
                            effects=effects, static_max=sw.static_max,
                            dynamic_max=sw.effects_max[i, np.arange(len(effects))], at_speed_kmh=sw.speeds_kmh[i],
                            zeta=zeta, damping_note=f"{t.name}: no additional damping (--damping none)")
        tc.effect_design = tuple(EffectComparison(effect=e, phi_dyn=float(ph), phi_dd_factor=r, phi_dd=phi_dd, Phi=Phi,
                                                  train_static=float(st), lm71_static=float(lm.value))
                                 for e, ph, st, lm in zip(effects, tc.phi_dyn, tc.static_max, lm71))
        out.append(tc)
        if progress is not None:
            progress(n + 1, len(trains))
    t_dyn = time.perf_counter() - t0 - t_static
    sls = deck_serviceability(b, Phi, alpha, track, lateral, h)
    return DeckCheckResult(bridge=b, max_line_speed_kmh=float(max_line_speed_kmh), track=track, damping=damping,
                           speeds_kmh=speeds, trains=out, modes=tuple(range(1, b.n_modes + 1)), rule_modes=need,
                           L_phi_m=L_phi, Phi=Phi, phi_dd=phi_dd, track_maintenance=maintenance,
                           maintenance_named=maintenance_named, alpha=alpha, sls=sls, lm71=lm71, where=where,
                           damping_model=damping_model,
                           timings_s={"static": t_static, "envelopes": t_dyn,
                                      "serviceability": time.perf_counter() - t0 - t_static - t_dyn})
