"""EN 1991-2 dynamic design check of a simply supported bridge (``adm-sim check``, ``adm-calib check``).

For every load train (HSLM-A1 .. A10, real trains by their static axle loads, user TOML trains)
the exact moving-load envelopes (:mod:`adm_sim.envelope`) of the maximum deck acceleration (by
default anywhere on the deck, with the position where it occurs; or at midspan or a given point),
of the maximum midspan deflection and of the maximum midspan bending moment are computed over the
speeds the standard asks for, the governing train, speed and position found and the deck
acceleration compared with the limit of EN 1990 A2.4.4.2.1.

Rules (each with its clause):

* speeds: 40 m/s up to the maximum design speed 1.2 V (EN 1991-2 6.4.6.2(1)), V the maximum line
  speed, at ``step_kmh`` <= 1 km/h; every interior local maximum of every envelope of at least a
  quarter of its largest value and every predicted HSLM resonance ``v = n0 D / i`` is refined at
  0.1 km/h over +-1 km/h;
* modes: every mode up to max(30 Hz, 1.5 n0, n3) (EN 1990 A2.4.4.2.1);
* where: EN 1990 A2.4.4.2.1 limits the peak deck acceleration, not the midspan one (mode 2 has a
  node at midspan): ``where="deck"`` (default) takes the largest |a| over every position of the
  span, exact in time and position (:mod:`adm_sim.envelope`); ``"midspan"`` or a position x (m);
* damping model (ζ per mode): ``rayleigh13`` (Rayleigh damping anchored at modes 1 and 3: mode 2
  gets 0.625 ζ with 3 modes; the paper's Rayleigh damping, Section 2.1, does not name its anchors)
  or ``modal`` (ζ of EN 1991-2 Table 6.6 on every mode, what EN 1991-2 6.4.6.3.1 implies); every
  output states ζ of every mode used;
* damping: the bridge's ζ (Table 2 / EN 1991-2 Table 6.6 when given by type) plus Δζ by method:
  ``none``; ``adm`` the Eurocode ADM (EN 1991-2 6.4.6.3.1 Eq. (6.13), spans < 30 m; refused for
  L >= 30 m; :func:`adm_sim.design_loads.adm_delta_zeta_pct`); ``lb`` the paper's lower-bound
  functions (Section 4.3; only the four trains of the study and bridges inside the studied
  field); ``vbi`` Δζ_VBI calibrated for the real train (Section 4, runs the DIM). ``lb`` and
  ``vbi`` belong to adm-calib: the core asks a ``damping_provider`` for them (``adm-calib check``
  passes :func:`adm_calib.check.calibrated_damping`) and refuses them without one. HSLM trains
  are loads, not vehicles: they get only what the standard allows (the ADM), so ``lb`` and
  ``vbi`` refuse them;
* limits: 3.5 m/s² ballasted, 5 m/s² direct fastened deck (EN 1990 A2.4.4.2.1(4));
* dynamic enhancement of the midspan deflection phi'_dyn = max |y_dyn / y_stat| - 1 per train
  (EN 1991-2 6.4.6.5(3), Eq. 6.14), y_dyn the largest dynamic and y_stat the largest static
  midspan deflection of the same train on the same modes;
* screening, printed beside the result: EN 1991-2 6.4.4 (Fig. 6.9 flow chart, Fig. 6.10 limits
  of n0: upper 94.76 L^-0.748, lower 80 / L for 4 m <= L <= 20 m and 23.58 L^-0.592 for
  20 m < L <= 100 m); a dynamic analysis is required above 200 km/h or outside the limits.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from adm_sim.fields import FIELDS
from adm_sim.errors import InputError, check_range

#: Lowest speed of the check (m/s), EN 1991-2 6.4.6.2(1).
MIN_SPEED_M_S = 40.0
#: Maximum design speed = this factor x maximum line speed, EN 1991-2 6.4.6.2(1).
DESIGN_SPEED_FACTOR = 1.2
#: Deck acceleration limits (m/s^2), EN 1990 A2.4.4.2.1(4).
from adm_sim.limits import ACC_LIMITS_M_S2  # noqa: E402  (EN 1990 A2.4.4.2.1(4)P, one track vocabulary)
#: Damping methods of the check; the core computes ``none`` and ``adm`` (EN 1991-2 6.4.6.3.1).
DAMPING_METHODS = ("none", "adm", "lb", "vbi")
#: The methods only adm-calib provides (the paper's lower bounds, the calibrated Δζ_VBI).
CALIB_DAMPING_METHODS = ("lb", "vbi")
#: Damping models of the check -> ``Bridge.damping_model``.
DAMPING_MODELS = {"rayleigh13": "rayleigh", "modal": "modal"}
#: Refinement around every resonance: half-width and step (km/h).
REFINE_HALF_WIDTH_KMH = 1.0
REFINE_STEP_KMH = 0.1
#: Interior maxima below this fraction of the train's largest value are ripples, not refined.
REFINE_MIN_FRACTION = 0.25
#: Passenger comfort: vertical car-body acceleration b_v (m/s^2) per level, EN 1990 A2.4.4.3.2 Table A2.9.
COMFORT_LEVELS_M_S2 = (("very good", 1.0), ("good", 1.3), ("acceptable", 2.0))
#: Spans below which HSLM-B applies instead of HSLM-A for simply supported bridges (EN 1991-2 6.4.6.1.1(5)).
HSLM_B_SPAN_M = 7.0


@dataclass
class TrainCheck:
    """The envelopes of one train and the damping it was given."""

    name: str
    kind: str  # "hslm" or "train"
    speeds_kmh: np.ndarray
    max_acc_m_s2: np.ndarray
    max_disp_m: np.ndarray
    delta_zeta_pct: float
    damping_note: str
    static_disp_m: float
    comfort_b_v_m_s2: np.ndarray | None = None  # per speed of the base grid (DIM), or None
    x_acc_m: np.ndarray | None = None  # position of the largest acceleration per speed (m)
    max_disp_midspan_m: np.ndarray | None = None  # per speed; None: max_disp_m is the midspan one
    max_moment_Nm: np.ndarray | None = None  # max |midspan bending moment| per speed (N m)
    zeta: tuple = ()  # damping ratio of every mode used (fractions, with this train's Δζ)
    static_moment_Nm: float | None = None  # largest static midspan moment on the same modes (N m)
    design: object = None  # adm_sim.design_loads.DesignComparison (EN 1991-2 6.4.6.5(3)) or None

    @property
    def i_max(self):
        return int(np.argmax(self.max_acc_m_s2))

    @property
    def midspan_disp_m(self):
        return self.max_disp_m if self.max_disp_midspan_m is None else self.max_disp_midspan_m

    @property
    def phi_dyn(self):
        """phi'_dyn = max |y_dyn / y_stat| - 1 at midspan (EN 1991-2 6.4.6.5(3), Eq. 6.14)."""
        return float(self.midspan_disp_m.max() / self.static_disp_m) - 1.0

    @property
    def phi_dyn_moment(self):
        """phi'_dyn of the midspan bending moment, Eq. (6.14), dynamic and static on the same modes."""
        if self.max_moment_Nm is None or not self.static_moment_Nm:
            return None
        return float(self.max_moment_Nm.max() / self.static_moment_Nm) - 1.0

    @property
    def x_max_m(self):
        """Position of the largest acceleration (m)."""
        return None if self.x_acc_m is None else float(self.x_acc_m[self.i_max])

    def zeta_text(self):
        return "/".join(f"{100 * z:.3g}" for z in self.zeta)

    def comfort_dict(self):
        """Largest b_v and the EN 1990 A2.4.4.3 level it reaches, or None (no DIM run)."""
        if self.comfort_b_v_m_s2 is None:
            return None
        bv = float(self.comfort_b_v_m_s2.max())
        return {"b_v_m_s2": bv, "level": comfort_level(bv),
                "b_v_curve_m_s2": self.comfort_b_v_m_s2.tolist()}

    def to_dict(self):
        i = self.i_max
        curve = {"speeds_kmh": self.speeds_kmh.tolist(), "max_acc_m_s2": self.max_acc_m_s2.tolist(),
                 "max_disp_m": self.max_disp_m.tolist()}
        for key, arr in (("x_acc_m", self.x_acc_m), ("max_disp_midspan_m", self.max_disp_midspan_m),
                         ("max_moment_Nm", self.max_moment_Nm)):
            if arr is not None:
                curve[key] = arr.tolist()
        return {"train": self.name, "kind": self.kind, "delta_zeta_pct": self.delta_zeta_pct,
                "damping_note": self.damping_note, "zeta_per_mode_pct": [100 * z for z in self.zeta],
                "max_acc_m_s2": float(self.max_acc_m_s2[i]), "at_speed_kmh": float(self.speeds_kmh[i]),
                "at_x_m": self.x_max_m,
                "max_disp_m": float(self.max_disp_m.max()), "max_disp_midspan_m": float(self.midspan_disp_m.max()),
                "static_disp_m": self.static_disp_m, "static_moment_Nm": self.static_moment_Nm,
                "phi_dyn_moment": self.phi_dyn_moment,
                "en1991_2_6_4_6_5": None if self.design is None else self.design.to_dict(),
                "max_moment_Nm": None if self.max_moment_Nm is None else float(self.max_moment_Nm.max()),
                "phi_dyn": self.phi_dyn, "comfort": self.comfort_dict(), "curve": curve}


@dataclass
class CheckResult:
    """Verdict of the dynamic check and every curve behind it."""

    bridge: object
    max_line_speed_kmh: float
    track: str
    damping: str
    speeds_kmh: np.ndarray
    trains: list
    modes: tuple
    f_limit_hz: float
    screening: str
    timings_s: dict = field(default_factory=dict)
    where: object = "midspan"
    damping_model: str = "rayleigh13"
    track_maintenance: str = "careful"
    alpha: float = 1.0

    def design_governing(self):
        """Per effect, the train whose EN 1991-2 6.4.6.5(3) design value is largest against
        Φ x α x LM71, as ``{"moment": DesignComparison, "deflection": DesignComparison}``."""
        from adm_sim.design_loads import governing

        comps = [c.design for c in self.trains if c.design is not None]
        return {e: governing(comps, e) for e in ("moment", "deflection")} if comps else {}

    @property
    def limit_m_s2(self):
        return ACC_LIMITS_M_S2[self.track]

    @property
    def governing(self):
        """(train check, speed km/h, acceleration m/s^2) of the largest acceleration."""
        t = max(self.trains, key=lambda c: c.max_acc_m_s2.max())
        return t, float(t.speeds_kmh[t.i_max]), float(t.max_acc_m_s2.max())

    @property
    def where_text(self):
        from adm_sim.envelope import where_text

        return where_text(self.where)

    def damping_model_text(self):
        """The damping model and the ζ of every mode of the bridge without Δζ."""
        z = self.bridge.modal_damping_ratios(0.0)
        modes = ", ".join(f"{100 * x:.4g} %" for x in z)
        if self.damping_model == "modal":
            how = "modal: zeta on every mode (EN 1991-2 6.4.6.3.1, Table 6.6)"
        else:
            how = "rayleigh13: Rayleigh damping anchored at modes 1 and 3"
        return f"damping model {how}; zeta per mode {modes}"

    def position_text(self, t):
        x = t.x_max_m
        if x is None:
            return ""
        return f", x = {x:.3f} m ({x / self.bridge.span_m:.3f} L)"

    @property
    def passed(self):
        return self.governing[2] <= self.limit_m_s2

    def summary(self):
        b = self.bridge
        v = self.speeds_kmh
        lines = [b.describe(),
                 f"speeds: {v.min():g} .. {v.max():g} km/h (40 m/s .. 1.2 x {self.max_line_speed_kmh:g} km/h, "
                 f"EN 1991-2 6.4.6.2), {v.size} speeds at <= 1 km/h, refined at {REFINE_STEP_KMH:g} km/h "
                 f"around every resonance",
                 f"modes: {', '.join(str(j) for j in self.modes)} (EN 1990 A2.4.4.2.1: at least all modes up to "
                 f"max(30 Hz, 1.5 n0, n3) = {self.f_limit_hz:.1f} Hz; "
                 + ("every mode moves the deck)" if self.where != "midspan" else "even modes do not move midspan)"),
                 f"acceleration: {self._where_sentence()}",
                 f"{self.damping_model_text()}",
                 f"damping: zeta = {100 * b.damping_ratio:.3g} % plus, per train:"]
        for note in dict.fromkeys(f"  {c.damping_note}" for c in self.trains):
            lines.append(note)
        xs = self.where != "midspan"
        lines.append(f"{'train':14s} {'max acc':>9s} {'at':>8s}" + (f" {'x':>7s}" if xs else "")
                     + f" {'max disp':>9s} {'phi_dyn':>8s} {'dzeta':>7s}  zeta per mode")
        lines.append(f"{'':14s} {'(m/s2)':>9s} {'(km/h)':>8s}" + (f" {'(m)':>7s}" if xs else "")
                     + f" {'(mm)':>9s} {'(-)':>8s} {'(%)':>7s}  (%)")
        for c in self.trains:
            i = c.i_max
            lines.append(f"{c.name:14s} {c.max_acc_m_s2[i]:9.4f} {c.speeds_kmh[i]:8.1f}"
                         + (f" {c.x_max_m:7.3f}" if xs else "")
                         + f" {1000 * c.midspan_disp_m.max():9.3f} {c.phi_dyn:8.3f} {c.delta_zeta_pct:7.3f}  "
                         f"{c.zeta_text()}")
        lines.append("max disp: midspan; phi_dyn = phi'_dyn = max |y_dyn / y_stat| - 1 at midspan (EN 1991-2 "
                     "6.4.6.5(3), Eq. 6.14)")
        lines.extend(self._design_lines())
        for c in self.trains:
            cd = c.comfort_dict()
            if cd is not None:
                lines.append(f"passenger comfort {c.name}: largest vertical car-body acceleration b_v = "
                             f"{cd['b_v_m_s2']:.3f} m/s2 (DIM): {cd['level']} (EN 1990 A2.4.4.3: 1.0 very good, "
                             f"1.3 good, 2.0 acceptable)")
        t, sp, acc = self.governing
        margin = self.limit_m_s2 - acc
        what = {"deck": "max deck acceleration (whole deck)", "midspan": "max midspan acceleration"}.get(
            self.where, f"max acceleration at {self.where_text}")
        lines.append(f"governing: {t.name} at {sp:g} km/h{self.position_text(t)}, {what} {acc:.4f} m/s2; limit "
                     f"{self.limit_m_s2:g} m/s2 ({self.track} track, EN 1990 A2.4.4.2.1): "
                     f"{'PASS' if self.passed else 'FAIL'}, margin {margin:+.4f} m/s2 "
                     f"({100 * margin / self.limit_m_s2:+.1f} % of the limit); damping model {self.damping_model} "
                     f"(zeta per mode {t.zeta_text()} %)")
        lines.append(self.screening)
        return "\n".join(lines)

    def _design_lines(self):
        """EN 1991-2 6.4.6.5(3): the midspan moment and deflection per train against Φ x α x LM71."""
        comps = [c.design for c in self.trains if c.design is not None]
        if not comps:
            return []
        d0 = comps[0]
        phi = "Phi2 (careful maintenance, 6.4.5.2(2))" if self.track_maintenance == "careful" else \
            "Phi3 (standard maintenance, 6.4.5.2(3))"
        out = [f"EN 1991-2 6.4.6.5(3), midspan of the simply supported span: (1 + phi'_dyn + phi''/2) x train "
               f"vs {phi} = {d0.Phi:.3f} x alpha = {d0.alpha:g} x LM71 (6.3.2); phi'' = {d0.phi_dd:.4f} (Annex C, "
               f"v = {self.max_line_speed_kmh:g} km/h); alpha x LM71 static: M {d0.lm71_static_moment_Nm / 1e3:.1f} kNm, "
               f"w {1e3 * d0.lm71_static_deflection_m:.3f} mm",
               f"{'train':14s} {'phi_M':>7s} {'M design':>10s} {'M/LM71':>7s} {'phi_w':>7s} {'w design':>9s} "
               f"{'w/LM71':>7s}",
               f"{'':14s} {'(-)':>7s} {'(kNm)':>10s} {'(-)':>7s} {'(-)':>7s} {'(mm)':>9s} {'(-)':>7s}"]
        for c in self.trains:
            d = c.design
            if d is None:
                continue
            out.append(f"{c.name:14s} {d.phi_dyn_moment:7.3f} {d.train_design_moment_Nm / 1e3:10.1f} "
                       f"{d.ratio_moment:7.3f} {d.phi_dyn_deflection:7.3f} {1e3 * d.train_design_deflection_m:9.3f} "
                       f"{d.ratio_deflection:7.3f}")
        for e, d in self.design_governing().items():
            side = "the train" if getattr(d, f"governs_{e}") == "train" else "Phi x alpha x LM71"
            out.append(f"design {e}: governed by {side} (largest train ratio {getattr(d, f'ratio_{e}'):.3f}, "
                       f"{d.train})")
        return out

    def _where_sentence(self):
        if self.where == "deck":
            return ("largest |a| anywhere on the deck (EN 1990 A2.4.4.2.1), exact in time and position "
                    "(adm_sim.envelope: closed form, Newton in (t, x))")
        if self.where == "midspan":
            return "at midspan only (--where midspan; the standard limits the whole deck)"
        return f"at {self.where_text} only (--where; the standard limits the whole deck)"

    def to_dict(self):
        t, sp, acc = self.governing
        return {"bridge": self.bridge.describe(), "max_line_speed_kmh": self.max_line_speed_kmh,
                "design_speed_kmh": DESIGN_SPEED_FACTOR * self.max_line_speed_kmh, "track": self.track,
                "damping": self.damping, "damping_model": self.damping_model,
                "zeta_per_mode_pct": [100 * z for z in self.bridge.modal_damping_ratios(0.0)],
                "where": self.where, "limit_m_s2": self.limit_m_s2, "modes": list(self.modes),
                "f_limit_hz": self.f_limit_hz,
                "governing": {"train": t.name, "speed_kmh": sp, "acc_m_s2": acc, "x_m": t.x_max_m,
                              "where": self.where, "zeta_per_mode_pct": [100 * z for z in t.zeta]},
                "verdict": "pass" if self.passed else "fail", "margin_m_s2": self.limit_m_s2 - acc,
                "screening": self.screening, "timings_s": self.timings_s,
                "track_maintenance": self.track_maintenance, "alpha": self.alpha,
                "en1991_2_6_4_6_5_governing": {e: {"train": d.train, "governs": getattr(d, f"governs_{e}"),
                                                   "ratio_train_to_lm71": getattr(d, f"ratio_{e}")}
                                               for e, d in self.design_governing().items()},
                "trains": [c.to_dict() for c in self.trains]}

    def write_csv(self, path):
        """Every curve in long format: train, speed_kmh, max_acc_m_s2, x_acc_m, max_disp_m (at
        ``where``), max_disp_midspan_m, max_moment_Nm, delta_zeta_pct, zeta_per_mode_pct (``/``-joined)."""
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["train", "speed_kmh", "max_acc_m_s2", "x_acc_m", "max_disp_m", "max_disp_midspan_m",
                        "max_moment_Nm", "delta_zeta_pct", "zeta_per_mode_pct"])
            for c in self.trains:
                n = c.speeds_kmh.size
                xa = c.x_acc_m if c.x_acc_m is not None else np.full(n, np.nan)
                mo = c.max_moment_Nm if c.max_moment_Nm is not None else np.full(n, np.nan)
                for v, a, x, d, dm, m in zip(c.speeds_kmh, c.max_acc_m_s2, xa, c.max_disp_m, c.midspan_disp_m, mo):
                    w.writerow([c.name, f"{v:.3f}", f"{a:.8g}", f"{x:.6g}", f"{d:.8g}", f"{dm:.8g}", f"{m:.8g}",
                                f"{c.delta_zeta_pct:.6g}", "/".join(f"{100 * z:.6g}" for z in c.zeta)])


# ---------------------------------------------------------------------- inputs
def check_speeds_kmh(max_line_speed_kmh, step_kmh=1.0):
    """The speeds of the check (km/h): 40 m/s .. 1.2 V at ``step_kmh``, both ends included."""
    lo = MIN_SPEED_M_S * 3.6
    try:
        V = FIELDS["max_line_speed_kmh"].check(max_line_speed_kmh, lo=lo)
    except InputError as exc:
        raise InputError(f"{exc} (the check runs from 40 m/s = 144 km/h up to 1.2 V, EN 1991-2 6.4.6.2; "
                         f"1.2 V at most 600 km/h)", field="max_line_speed_kmh") from None
    step = FIELDS["step_kmh"].check(step_kmh, argument=True)
    hi = DESIGN_SPEED_FACTOR * V
    n = int(math.floor((hi - lo) / step + 1e-9))
    v = lo + step * np.arange(n + 1)
    if hi - v[-1] > 1e-9:
        v = np.append(v, hi)
    return v


def resolve_trains(spec):
    """Trains from ``"hslm,ICE-2,my.toml"``: ``hslm`` is HSLM-A1 .. A10; duplicates refused."""
    from adm_sim.hslm import HSLM_A_NAMES
    from adm_sim.trains import load_train

    names = []
    for part in str(spec).split(","):
        part = part.strip()
        if not part:
            continue
        names.extend(HSLM_A_NAMES if part.lower() == "hslm" else [part])
    if not names:
        raise InputError(f"trains: {spec!r} names no train; allowed hslm, HSLM-A1 .. HSLM-A10, ICE-2, Eurostar, "
                         f"Railjet, ICE-4, Eurostar-table or .toml train files, comma separated", field="trains")
    trains = [load_train(n) for n in names]
    seen = set()
    for t in trains:
        if t.name in seen:
            raise InputError(f"trains: {t.name!r} is given twice in {spec!r}; give every train once", field="trains")
        seen.add(t.name)
    return trains


def _is_hslm(train):
    from adm_sim.hslm import HSLM_A_TABLE

    return train.name in HSLM_A_TABLE and not train.units


def calib_methods_refusal(method):
    """The one-line refusal of ``--damping lb|vbi`` where no adm-calib provider is given."""
    return InputError(f"damping {method}: the paper's lower bounds and the calibrated Δζ_VBI are adm-calib's; "
                      f"run adm-calib check with the same options (allowed here: --damping none or adm)",
                      field="damping")


def delta_zeta_for(bridge, train, method, calibrate_options=None, damping_provider=None):
    """Δζ (%) and the sentence saying why, for one train; refuses a method that does not apply.

    ``none`` and ``adm`` (the Eurocode ADM, EN 1991-2 6.4.6.3.1 Eq. (6.13)) are computed here;
    ``lb`` and ``vbi`` come from ``damping_provider(bridge, train, method, calibrate_options)``
    (adm-calib's :func:`adm_calib.check.calibrated_damping`) and are refused without one.
    """
    from adm_sim.design_loads import adm_delta_zeta_pct

    L = bridge.span_m
    if method not in DAMPING_METHODS:
        raise InputError(f"damping: {method!r} is not allowed; allowed {', '.join(DAMPING_METHODS)}", field="damping")
    if method == "none":
        return 0.0, f"{train.name}: no additional damping (--damping none)"
    if method == "adm":
        if L >= 30.0:
            raise InputError(f"damping adm: the Eurocode ADM applies to spans < 30 m (EN 1991-2 6.4.6.3.1); "
                             f"this bridge spans {L:g} m; allowed --damping none", field="damping")
        return adm_delta_zeta_pct(L), (f"Eurocode ADM, L = {L:g} m < 30 m (EN 1991-2 6.4.6.3.1): "
                                       f"{adm_delta_zeta_pct(L):.3f} % for every train")
    if damping_provider is None:
        raise calib_methods_refusal(method)
    if _is_hslm(train):
        raise InputError(f"damping {method}: {train.name} is an HSLM load train, not a vehicle; the "
                         f"{'lower-bound functions' if method == 'lb' else 'calibrated Δζ_VBI'} apply only to the "
                         f"real trains of the study; allowed for HSLM: --damping none or adm", field="damping")
    return damping_provider(bridge, train, method, calibrate_options)


def static_midspan_max(bridge, offsets, loads, n_per_span=2000):
    """Largest static midspan deflection (m) and bending moment (N m) of the axles as they cross,
    on the bridge's modes (the same truncation as the dynamic envelopes, so that their ratio is
    φ'_dyn of Eq. (6.14) without a modal-truncation bias): ``q_j = F sin(j pi a / L) / K_j``,
    ``w = sum_j q_j sin(j pi / 2)``, ``M = EJ sum_j q_j (j pi / L)^2 sin(j pi / 2)``."""
    L = bridge.span_m
    s = np.arange(0.0, offsets[-1] + L, L / n_per_span)
    j = bridge.mode_numbers
    gain = np.sin(j * np.pi / 2) / bridge.modal_stiffness_N_m  # midspan per unit modal force
    mgain = gain * bridge.EJ_Nm2 * (j * np.pi / L) ** 2
    w = np.zeros_like(s)
    m = np.zeros_like(s)
    for a, F in zip(offsets, loads):
        x = s - a
        on = (x >= 0) & (x <= L)
        sh = np.sin(np.outer(x[on], j) * np.pi / L)
        w[on] += F * (sh * gain).sum(-1)
        m[on] += F * (sh * mgain).sum(-1)
    return float(np.abs(w).max()), float(np.abs(m).max())


def static_midspan_max_m(bridge, offsets, loads, n_per_span=2000):
    """Largest static midspan deflection (m) of the axles as they cross, on the bridge's modes."""
    return static_midspan_max(bridge, offsets, loads, n_per_span)[0]


def comfort_level(b_v_m_s2):
    """EN 1990 A2.4.4.3.2 Table A2.9 level reached by ``b_v`` (m/s^2)."""
    for name, lim in COMFORT_LEVELS_M_S2:
        if b_v_m_s2 <= lim:
            return name
    return "beyond acceptable"


def comfort_b_v(bridge, train, speeds_kmh, options=None):
    """Largest vertical car-body acceleration b_v (m/s^2) per speed from the DIM (bridge ζ only).

    Every car body's acceleration at its two pivot points (bounce plus pitch; the body's extremes,
    since the motion is linear along the body) by differencing the DIM velocities over each step,
    maximum over the crossing. A vehicle is integrated while an axle is on the bridge (the core's
    rule on a rigid track), so its motion after leaving the bridge is not followed.
    """
    from adm_sim.lockstep_runs import InProcessRun
    from adm_sim.rk4_sides import BridgeSide, TrainSide
    from adm_sim.step_grid import StepOptions, make_grid, speeds_to_m_s

    if not train.units:
        raise InputError(f"comfort: {train.name!r} has no vehicles; b_v needs the DIM")
    v = speeds_to_m_s(speeds_kmh)
    grid = make_grid(bridge, train.length_m, v, options or StepOptions())
    side = TrainSide(train, grid, bridge.span_m)
    run = InProcessRun("dim", grid, BridgeSide(bridge, grid, train.axle_offsets_m, train.wheel_mass_kg, np.zeros(v.shape)),
                       train_side=side)
    iz, ith, half = [], [], []
    start = 0
    for unit in train.units:  # DOFs per unit: [z, theta] of its cars, then of its bogies (trains.py)
        for ci, (_, (p1, p2)) in enumerate(unit.cars):
            iz.append(start + 2 * ci)
            ith.append(start + 2 * ci + 1)
            half.append(0.5 * (p2 - p1))
        start += unit.n_dof
    iz, ith, half = np.array(iz), np.array(ith), np.array(half)
    dt = grid.dt_s[:, None]
    prev_z, prev_th = side.xd[:, iz].copy(), side.xd[:, ith].copy()
    b_v = np.zeros(v.size)
    for _ in range(grid.n_steps):
        if run.step() is not None:
            raise InputError(run.message)
        z, th = side.xd[:, iz], side.xd[:, ith]
        az, ath = (z - prev_z) / dt, (th - prev_th) / dt
        b_v = np.maximum(b_v, np.maximum(np.abs(az + half * ath), np.abs(az - half * ath)).max(1))
        prev_z, prev_th = z.copy(), th.copy()
    return b_v


def screening(bridge, max_line_speed_kmh):
    """EN 1991-2 6.4.4 (Figs. 6.9, 6.10): is a dynamic analysis required? One sentence."""
    L, n0 = bridge.span_m, bridge.n0_hz
    if not 4.0 <= L <= 100.0:
        return (f"screening (EN 1991-2 6.4.4, Fig. 6.10): L = {L:g} m is outside 4..100 m of Fig. 6.10: "
                f"dynamic analysis required")
    upper = 94.76 * L ** -0.748
    lower = 80.0 / L if L <= 20.0 else 23.58 * L ** -0.592
    inside = lower <= n0 <= upper
    fast = max_line_speed_kmh > 200.0
    need = fast or not inside
    why = []
    if fast:
        why.append(f"V = {max_line_speed_kmh:g} km/h > 200 km/h")
    why.append(f"n0 = {n0:.3f} Hz {'within' if inside else 'outside'} the limits [{lower:.3f}, {upper:.3f}] Hz for L = {L:g} m")
    return (f"screening (EN 1991-2 6.4.4, Figs. 6.9/6.10): {'; '.join(why)}: dynamic analysis "
            f"{'required' if need else 'not required by Fig. 6.10 (check v/n0 against Annex F before relying on it)'}")


def _refinement(speeds, acc, extra, vmin, vmax):
    """Speeds at REFINE_STEP_KMH over +-REFINE_HALF_WIDTH_KMH around interior maxima and ``extra``."""
    from adm_sim.peaks import local_maxima  # the project's one peak rule, every maximum kept

    i = local_maxima(acc, min_prominence_rel=0.0)
    i = i[acc[i] >= REFINE_MIN_FRACTION * acc.max()]  # resonance peaks, not ripples of a low plateau
    centres = np.concatenate([speeds[i], extra])
    off = np.arange(-REFINE_HALF_WIDTH_KMH, REFINE_HALF_WIDTH_KMH + 1e-9, REFINE_STEP_KMH)
    fine = (np.round(centres[:, None] / REFINE_STEP_KMH) * REFINE_STEP_KMH + off[None, :]).ravel()
    fine = fine[(fine >= vmin) & (fine <= vmax)]
    return np.setdiff1d(np.round(fine, 6), np.round(speeds, 6))


def run_check(bridge, max_line_speed_kmh, trains, track="ballasted", damping="none", step_kmh=1.0,
              progress=None, calibrate_options=None, comfort=False, n_modes=None, where="deck",
              damping_model=None, track_maintenance="careful", alpha=1.0, damping_provider=None):
    """The dynamic check of ``bridge`` for ``trains`` (see the module doc).

    Parameters
    ----------
    bridge : adm_sim.bridge.Bridge
        Its ``n_modes`` is replaced by the modes EN 1990 A2.4.4.2.1 asks for.
    max_line_speed_kmh : float
        Maximum line speed V (km/h), > 144 km/h (40 m/s).
    trains : list of adm_sim.trains.Train
    track : {"ballasted", "direct_fastening"}
    damping : {"none", "adm", "lb", "vbi"}
        ``lb`` and ``vbi`` need ``damping_provider``; without one they are refused (InputError)
        before any work.
    step_kmh : float
        Speed step (km/h), (0, 1].
    progress : callable(done, total), optional
        Called once per train.
    n_modes : int, optional
        More modes than EN 1990 A2.4.4.2.1 asks for (at least that many, at most 20).
    comfort : bool
        Also run the DIM of every train with vehicles over the speeds for the passenger comfort
        b_v (EN 1990 A2.4.4.3); HSLM trains have no car bodies.
    where : {"deck", "midspan"} or float or str
        Where the acceleration is taken: anywhere on the deck (default, EN 1990 A2.4.4.2.1), at
        midspan, or at a position x (m, 0 < x < L; text ``"x=<m>"`` accepted).
    damping_model : {"rayleigh13", "modal"}, optional
        ζ per mode: Rayleigh anchored at modes 1 and 3, or ζ on every mode; default the bridge's
        own ``damping_model`` ("rayleigh" is rayleigh13).
    track_maintenance : {"careful", "standard"}
        Track maintenance for the dynamic factor Φ of LM71 in EN 1991-2 6.4.6.5(3): Φ2 (careful,
        6.4.5.2(2)) or Φ3 (standard, 6.4.5.2(3)); φ'' of Annex C enters as φ''/2 either way.
    alpha : float
        Classification factor α of LM71 (EN 1991-2 6.3.2(3)).
    damping_provider : callable(bridge, train, method, calibrate_options) -> (pct, note), optional
        Δζ (%) and its sentence for ``lb`` and ``vbi``; adm-calib passes
        :func:`adm_calib.check.calibrated_damping`. The core never imports adm_calib.

    Returns
    -------
    CheckResult
    """
    from adm_sim.envelope import check_frequency_limit_hz, check_mode_count, moving_load_envelope, parse_where
    from adm_sim.hslm import regular_coach_length_m

    if damping_model is None:
        damping_model = {v: k for k, v in DAMPING_MODELS.items()}[bridge.damping_model]
    if damping_model not in DAMPING_MODELS:
        raise InputError(f"damping_model: {damping_model!r} is not allowed; allowed {', '.join(DAMPING_MODELS)}",
                         field="damping_model")
    where = parse_where(where, bridge.span_m)
    if track not in ACC_LIMITS_M_S2:
        raise InputError(f"track: {track!r} is not allowed; allowed {', '.join(ACC_LIMITS_M_S2)}", field="track")
    if damping not in DAMPING_METHODS:
        raise InputError(f"damping: {damping!r} is not allowed; allowed {', '.join(DAMPING_METHODS)}", field="damping")
    if damping in CALIB_DAMPING_METHODS and damping_provider is None:
        raise calib_methods_refusal(damping)
    speeds = check_speeds_kmh(max_line_speed_kmh, step_kmh)
    from adm_sim.design_loads import MAINTENANCE, check_alpha, design_comparison

    if track_maintenance not in MAINTENANCE:
        raise InputError(f"track_maintenance: {track_maintenance!r} is not one of EN 1991-2 6.4.5.2's; allowed "
                         f"{', '.join(MAINTENANCE)} (careful: Φ2, standard: Φ3)", field="track_maintenance")
    try:
        alpha = check_alpha(alpha)
    except InputError as exc:
        raise InputError(f"alpha: {str(exc).partition(': ')[2]}", field="alpha") from None
    if bridge.span_m < HSLM_B_SPAN_M and any(_is_hslm(t) for t in trains):
        raise InputError(f"trains: HSLM-A applies to spans >= {HSLM_B_SPAN_M:g} m; this bridge spans "
                         f"{bridge.span_m:g} m, where EN 1991-2 6.4.6.1.1(5) asks for HSLM-B, which adm-sim "
                         f"does not include (see the README); check real trains only", field="trains")
    f_lim = check_frequency_limit_hz(bridge)
    most = FIELDS["n_modes"].hi
    need = min(most, check_mode_count(bridge))
    if n_modes is not None:
        try:
            x = check_range("n_modes", n_modes, "-", need, most)
        except InputError as exc:
            raise InputError(f"{exc} (EN 1990 A2.4.4.2.1 asks for every mode up to {f_lim:.1f} Hz: {need} modes)",
                             field="n_modes") from None
        if x != int(x):
            raise InputError(f"n_modes: {x:g} is not an integer; allowed [{need}, 20]", field="n_modes")
        n_modes = int(x)
    b = dataclasses.replace(bridge, n_modes=need if n_modes is None else n_modes,
                            damping_model=DAMPING_MODELS[damping_model])
    t_start = time.perf_counter()
    dz = [None] * len(trains)  # every refusal before any sweep: load trains (cheap refusals) first
    for i in sorted(range(len(trains)), key=lambda i: bool(trains[i].units)):
        dz[i] = delta_zeta_for(b, trains[i], damping, calibrate_options, damping_provider)
    t_damp = time.perf_counter() - t_start
    out = []
    vmin, vmax = speeds[0], speeds[-1]
    for n, (t, (dz_pct, note)) in enumerate(zip(trains, dz)):
        env = moving_load_envelope(b, t.axle_offsets_m, t.axle_loads_n, speeds, delta_zeta=dz_pct / 100.0,
                                   where=where)
        extra = np.array([])
        if _is_hslm(t):
            D = regular_coach_length_m(t.name)
            i = np.arange(1, 50)
            extra = 3.6 * b.n0_hz * D / i
        fine = _refinement(speeds, env.max_acc_m_s2, extra, vmin, vmax)
        v_all = speeds
        cols = [env.max_acc_m_s2, env.max_disp_m, env.x_acc_m, env.max_disp_midspan_m, env.max_moment_Nm]
        if fine.size:
            ef = moving_load_envelope(b, t.axle_offsets_m, t.axle_loads_n, fine, delta_zeta=dz_pct / 100.0,
                                      where=where)
            v_all = np.concatenate([speeds, fine])
            order = np.argsort(v_all, kind="stable")
            v_all = v_all[order]
            cols = [np.concatenate([c, f])[order] for c, f in zip(cols, [
                ef.max_acc_m_s2, ef.max_disp_m, ef.x_acc_m, ef.max_disp_midspan_m, ef.max_moment_Nm])]
        acc, disp, x_acc, disp_mid, moment = cols
        b_v = comfort_b_v(b, t, speeds) if comfort and t.units else None
        y_stat, m_stat = static_midspan_max(b, t.axle_offsets_m, t.axle_loads_n)
        tc = TrainCheck(name=t.name, kind="hslm" if _is_hslm(t) else "train", speeds_kmh=v_all,
                        max_acc_m_s2=acc, max_disp_m=disp, delta_zeta_pct=float(dz_pct),
                        damping_note=note, static_disp_m=y_stat, static_moment_Nm=m_stat,
                        comfort_b_v_m_s2=b_v, x_acc_m=x_acc, max_disp_midspan_m=disp_mid,
                        max_moment_Nm=moment, zeta=env.zeta)
        # EN 1991-2 6.4.6.5(3): (1 + phi'_dyn + phi''/2) x train against Phi x alpha x LM71; phi'' at
        # the maximum line speed (Annex C: the maximum permitted vehicle speed)
        tc.design = design_comparison(t.name, b.span_m, b.EJ_Nm2, b.n0_hz, t.axle_offsets_m, t.axle_loads_n,
                                      float(max_line_speed_kmh) / 3.6, phi_dyn_deflection=tc.phi_dyn,
                                      phi_dyn_moment=tc.phi_dyn_moment, maintenance=track_maintenance, alpha=alpha)
        out.append(tc)
        if progress is not None:
            progress(n + 1, len(trains))
    return CheckResult(bridge=b, max_line_speed_kmh=float(max_line_speed_kmh), track=track, damping=damping,
                       speeds_kmh=speeds, trains=out, modes=tuple(int(j) for j in b.mode_numbers),
                       f_limit_hz=f_lim, screening=screening(b, float(max_line_speed_kmh)),
                       timings_s={"damping": t_damp, "envelopes": time.perf_counter() - t_start - t_damp},
                       where=where, damping_model=damping_model, track_maintenance=track_maintenance,
                       alpha=alpha)
