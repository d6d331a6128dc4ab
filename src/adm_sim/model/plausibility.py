"""Plausibility bounds: one table, each bound with the reason for it.

The input ranges of :mod:`adm_sim.model.bridge` and :mod:`adm_sim.model.trains` refuse what the model cannot
compute. These bounds are wider questions: a value the model computes but no real railway bridge or
train has. Crossing one gives a :class:`PlausibilityWarning` (a normal Python warning for library
callers; the command lines print it as one line ``warning: ...`` on stderr, :func:`adm_sim.cliutil.run_cli`),
never a refusal. The exception is ``adm-calib recommend``: its answer exists only inside the field the
paper studied (Section 3.1: spans 4..40 m, n0 within the Fig. 8 band, mu within Table 1), so there the
:data:`FIELD` rows refuse (:func:`check_studied_field`) unless the user asks to extrapolate.

Sources of the bounds:

* Fig. 8 band, paper Section 3.1.1: ``n0_LB = 82.43 L^-0.9937``, ``n0_UB = 113.1 L^-0.8312`` (Hz).
* Table 1 / Eq. (19) mass functions ``mu(L) = k L + d`` (t/m): lightest ``mu6`` (0.1214, 2.1691),
  lightest concrete ``mu3`` (0.5584, 6.627), heaviest ``mu1`` (0.843, 10.45).
* EN 1991-2 Table 6.6 (paper Table 2): lower-limit damping 0.5 .. 4 % (L >= 4 m).
* EN 1990 A2.4.4.2.1(4)P deck acceleration limits 3.5 / 5 m/s²; EN 1990 A2.4.4.2.3 deflections.
* EN 15528 line categories: axle loads up to 25 t (245 kN); EN 1991-2 LM71 250 kN, HSLM 170..210 kN.

No ROS; the constants come from :mod:`adm_sim.model.bridge` (written once). ``docs/plausibility.md`` holds
:data:`TABLE` and :data:`FIELD` as :func:`markdown_table` prints them (``python -m adm_sim.model.plausibility``;
a test checks the two are equal).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.model.parametric import FIELD_SPANS_M, MASS_FUNCTIONS, N0_LB, N0_UB


# ---------------------------------------------------------------------- the sources
#: Fig. 8 band (Section 3.1.1), n0 = a L^b (Hz); Table 1 mass functions (t/m), mu = k L + d: the
#: lightest mu6, the lightest concrete mu3, the heaviest mu1; the spans of the field (Section 3.1).
MU6, MU3, MU1 = (MASS_FUNCTIONS[m][:2] for m in ("mu6", "mu3", "mu1"))
FIELD_SPAN_M = (FIELD_SPANS_M[0], FIELD_SPANS_M[-1])


def n0_lb_hz(span_m):
    """Lower bound of the Fig. 8 band (Hz), ``82.43 L^-0.9937`` (Section 3.1.1)."""
    return N0_LB[0] * span_m ** N0_LB[1]


def n0_ub_hz(span_m):
    """Upper bound of the Fig. 8 band (Hz), ``113.1 L^-0.8312`` (Section 3.1.1)."""
    return N0_UB[0] * span_m ** N0_UB[1]


def _mu_kg_m(kd, span_m):
    return 1000.0 * (kd[0] * span_m + kd[1])


# ---------------------------------------------------------------------- the table
@dataclass(frozen=True)
class Bound:
    """One row: a quantity, its unit, the plausible range (text and function) and the reason.

    ``limits(ctx)`` gives ``(lo, hi)`` in ``unit`` (``None``: unbounded) for the context ``ctx``
    (``span_m``, ``mu_kg_m``); ``applies(ctx)`` says whether the row applies at all; ``exempt`` values
    are plausible whatever the limits (zero damping is a deliberate choice, not a typo).
    """

    key: str
    quantity: str
    unit: str
    bound: str
    reason: str
    checked_in: str
    limits: Callable[[dict], tuple]
    applies: Callable[[dict], bool] = lambda ctx: True
    exempt: tuple = ()
    per_span: bool = False

    def range_text(self, ctx):
        lo, hi = self.limits(ctx)
        if lo is None:
            return f"<= {_fmt(hi)} {self.unit}"
        if hi is None:
            return f">= {_fmt(lo)} {self.unit}"
        return f"[{_fmt(lo)}, {_fmt(hi)}] {self.unit}"

    def outside(self, value, ctx):
        """Whether ``value`` (in ``unit``) is implausible in the context ``ctx``."""
        if value in self.exempt or not self.applies(ctx):
            return False
        lo, hi = self.limits(ctx)
        return (lo is not None and value < lo) or (hi is not None and value > hi)

    def message(self, label, value, ctx, hint=""):
        """The one-line warning text (without the ``warning: `` the CLIs add)."""
        at = f" for L = {_fmt(ctx['span_m'])} m" if self.per_span and "span_m" in ctx else ""
        return (f"{label}: {_fmt(value)} {self.unit} is outside the plausible range {self.range_text(ctx)}{at}"
                f"{hint}; {self.reason}")


def _fmt(x):
    """A number for a message: 4 significant digits, whole numbers from 10^4 to 10^9 (kg/m), powers
    of ten beyond (a count of 300 digits says nothing)."""
    return f"{x:.4g}" if abs(x) < 1e4 or abs(x) >= 1e9 else f"{x:.0f}"


def _light(ctx):
    return ctx["mu_kg_m"] < _mu_kg_m(MU3, ctx["span_m"])


#: The plausibility bounds (warnings), one row each.
TABLE = (
    Bound("n0", "first natural frequency n0", "Hz", "0.5 x n0_LB(L) .. 2 x n0_UB(L)",
          "the Fig. 8 band of real bridges, n0_LB = 82.43 L^-0.9937 .. n0_UB = 113.1 L^-0.8312 Hz (paper "
          "Section 3.1.1); a factor 2 beyond it is another structure or a typing error (rad/s for Hz?)",
          "bridge specs and files; bridge node parameters n0_hz (or EJ_Nm2 with mu_kg_m)",
          lambda c: (0.5 * n0_lb_hz(c["span_m"]), 2.0 * n0_ub_hz(c["span_m"])), per_span=True),
    Bound("mu", "mass per length mu", "kg/m", "0.5 x mu6(L) .. 2 x mu1(L)",
          "Table 1 (Eq. 19) spans the real bridges from mu6 = 0.1214 L + 2.1691 t/m (lightest, steel/composite) "
          "to mu1 = 0.843 L + 10.45 t/m (heaviest, concrete); a factor 2 beyond it is no railway bridge",
          "bridge specs and files; bridge node parameter mu_kg_m",
          lambda c: (0.5 * _mu_kg_m(MU6, c["span_m"]), 2.0 * _mu_kg_m(MU1, c["span_m"])), per_span=True),
    Bound("zeta_pct_fraction", "damping given as zeta_pct", "%", "0 or >= 0.1 %",
          "EN 1991-2 Table 6.6 lower limits are 0.5 .. 4 %, so a value below 0.1 % looks like a fraction "
          "typed into the % key",
          "bridge specs and files (zeta_pct); bridge node parameter zeta_pct",
          lambda c: (0.1, None), exempt=(0.0,)),
    Bound("zeta_light", "damping of a light bridge (mu < mu3(L))", "%", ">= 0.1 % when mu < mu3(L)",
          "a deck lighter than the lightest concrete mass function mu3 = 0.5584 L + 6.627 t/m (Table 1) with "
          "almost no damping resonates to hundreds of m/s²; EN 1991-2 Table 6.6 gives steel/composite "
          "bridges >= 0.5 %",
          "bridge specs and files; bridge node parameter zeta_pct (with mu_kg_m)",
          lambda c: (0.1, None), applies=_light, per_span=True),
    Bound("axle_load", "axle load", "kN", "20 .. 300 kN",
          "European lines carry axles up to 25 t (EN 15528 line category E, 245 kN), LM71 (EN 1991-2 6.3.2) "
          "has 250 kN, HSLM 170 .. 210 kN; below 2 t an axle carries no rail vehicle",
          "train files (--train FILE.toml; train node parameter train)",
          lambda c: (20.0, 300.0)),
    Bound("car_body_mass", "car body mass m_c", "t", "<= 100 t",
          "a four-axle vehicle at the 25 t axles of EN 15528 weighs about 100 t with its bogies, so its car "
          "body alone is lighter",
          "train files (--train FILE.toml; train node parameter train)",
          lambda c: (None, 100.0)),
    Bound("acceleration", "peak deck acceleration", "m/s²", "<= 50 m/s²",
          "about 5 g, ten times the EN 1990 A2.4.4.2.1(4)P limits (3.5 / 5 m/s²); no real deck survives it "
          "(check the damping, mass and frequency)",
          "adm-sim sweep and check results, adm-calib calibrate and table4 peaks, the study's rows (warnings); every "
          "run of the driver and calibration nodes (and /diagnostics) and the bridge node's done record, the "
          "crossing.py and calibrate.py summaries",
          lambda c: (None, 50.0)),
    Bound("deflection", "peak midspan deflection", "m", "<= L/100",
          "six times the L/600 of EN 1990 A2.4.4.2.3 and far beyond the small deflections of the linear "
          "beam model (Eq. 4)",
          "adm-sim sweep and check results; every run of the driver and calibration nodes (and /diagnostics), "
          "the crossing.py summary",
          lambda c: (None, c["span_m"] / 100.0), per_span=True),
)

#: The field the paper studied (Section 3.1): ``adm-calib recommend`` refuses outside it unless
#: ``--extrapolate`` (then it warns).
FIELD = (
    Bound("field_span", "span L (recommend)", "m", "4 .. 40 m",
          "the parametric study covers spans 4 .. 40 m (paper Section 3.1); the lower-bound functions are "
          "fitted there",
          "adm-calib recommend",
          lambda c: FIELD_SPAN_M),
    Bound("field_n0", "n0 (recommend)", "Hz", "n0_LB(L) .. n0_UB(L)",
          "the study's bridges lie in the Fig. 8 band n0_LB = 82.43 L^-0.9937 .. n0_UB = 113.1 L^-0.8312 Hz "
          "(paper Section 3.1.1)",
          "adm-calib recommend",
          lambda c: (n0_lb_hz(c["span_m"]) * (1 - 1e-9), n0_ub_hz(c["span_m"]) * (1 + 1e-9)), per_span=True),
    Bound("field_mu", "mu (recommend)", "kg/m", "mu6(L) .. mu1(L)",
          "the study's bridges lie between the Table 1 mass functions mu6 = 0.1214 L + 2.1691 t/m and mu1 = "
          "0.843 L + 10.45 t/m (Eq. 19)",
          "adm-calib recommend",
          lambda c: (_mu_kg_m(MU6, c["span_m"]) * (1 - 1e-9), _mu_kg_m(MU1, c["span_m"]) * (1 + 1e-9)), per_span=True),
)

ROWS = {b.key: b for b in TABLE + FIELD}


def warn(key, label, value, ctx=None, hint="", stacklevel=3):
    """Issue the :class:`PlausibilityWarning` of row ``key`` if ``value`` is outside; return whether it was."""
    row, ctx = ROWS[key], ctx or {}
    if not row.outside(value, ctx):
        return False
    warnings.warn(row.message(label, value, ctx, hint), PlausibilityWarning, stacklevel=stacklevel)
    return True


# ---------------------------------------------------------------------- entry points
def check_bridge(bridge, source="bridge", zeta_pct_given=None, labels=None):
    """Warn about a bridge read from user input: n0 off the Fig. 8 band, mu off Table 1, damping that
    looks like a fraction (``zeta_pct_given``, the value typed for ``zeta_pct``) or tiny on a light deck.

    ``labels``: how the caller's input names n0, mu and zeta_pct (``{"n0": ..., "mu": ...,
    "zeta_pct": ...}``, the ROS parameters ``n0_hz``, ``mu_kg_m``, ``zeta_pct`` for the bridge
    node, and ``"zeta_light"`` for the light-deck damping row); default the spec keys after
    ``source``. A label is used as it is."""
    lab = {"n0": f"{source}: n0", "mu": f"{source}: mu", "zeta_pct": f"{source}.zeta_pct"} | (labels or {})
    ctx = {"span_m": bridge.span_m, "mu_kg_m": bridge.mass_per_length_kg_m}
    warn("n0", lab["n0"], bridge.n0_hz, ctx)
    warn("mu", lab["mu"], bridge.mass_per_length_kg_m, ctx)
    key = lab["zeta_pct"].rsplit(".", 1)[-1].rsplit(" ", 1)[-1]
    if zeta_pct_given is not None and warn("zeta_pct_fraction", lab["zeta_pct"], zeta_pct_given, ctx,
                                           hint=f" (if {zeta_pct_given:g} is a fraction, write {key}={100 * zeta_pct_given:g})"):
        return
    mu3 = _mu_kg_m(MU3, bridge.span_m)
    light = lab.get("zeta_light", f"{source}: damping of a light deck")
    warn("zeta_light", f"{light} (mu = {_fmt(bridge.mass_per_length_kg_m)} kg/m < mu3(L) = {_fmt(mu3)} kg/m)",
         100.0 * bridge.damping_ratio, ctx)


def warn_implausible_train(train, source="train"):
    """Warn about a train read from a file: axle loads and car body masses no rail vehicle has
    (the largest and the smallest axle load, the heaviest car body: at most three lines)."""
    loads_kn = [float(x) / 1000.0 for x in train.axle_loads_n]
    if loads_kn:
        lo, hi = ROWS["axle_load"].limits({})
        if max(loads_kn) > hi:
            warn("axle_load", f"{source}: largest axle load", max(loads_kn))
        if min(loads_kn) < lo:
            warn("axle_load", f"{source}: smallest axle load", min(loads_kn))
    bodies = [(vt.m_c_kg / 1000.0, name) for name, vt in train.vehicle_types.items()]
    if bodies:
        m_t, name = max(bodies)
        warn("car_body_mass", f"{source}: vehicle_types.{name}.m_c_kg", m_t)


def check_response(span_m, max_acc_m_s2, max_disp_m=None, label="result", disp_label=None):
    """Warn about peak results no real bridge survives: the largest acceleration (m/s²) and the
    largest deflection (m, ``None`` where the result has none) over the speeds (``label``,
    ``disp_label`` say where each was found)."""
    ctx = {"span_m": span_m}
    warn("acceleration", f"{label}: peak acceleration", float(max_acc_m_s2), ctx)
    if max_disp_m is not None:
        warn("deflection", f"{disp_label or label}: peak deflection", float(max_disp_m), ctx)


def response_warnings(span_m, max_acc_m_s2, max_disp_m=None, label="result", disp_label=None):
    """The messages :func:`check_response` warns, as a list of one-line strings (for results that
    carry their warnings: the study's rows, the bridge node's result), without warning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PlausibilityWarning)
        check_response(span_m, max_acc_m_s2, max_disp_m, label, disp_label)
    return [str(w.message) for w in caught if issubclass(w.category, PlausibilityWarning)]


#: How a caller names the three values and the switch that accepts extrapolation: a library caller
#: by the arguments, the command line (``adm-calib recommend``) by its flags.
ARGUMENT_NAMES = {"span_m": "span_m", "n0_hz": "n0_hz", "mu_kg_m": "mu_kg_m", "extrapolate": "extrapolate=True"}


def check_studied_field(span_m, n0_hz, mu_kg_m, extrapolate=False, names=None):
    """Refuse (``InputError``, one line naming the field) a ``recommend`` outside the studied field,
    or with ``extrapolate`` warn about it; the span is checked first (the other bands depend on it).

    ``names`` (default :data:`ARGUMENT_NAMES`) says how the message names ``span_m``, ``n0_hz``,
    ``mu_kg_m`` and the ``extrapolate`` switch: a command line passes its flags."""
    nm = {**ARGUMENT_NAMES, **(names or {})}
    ctx = {"span_m": span_m, "mu_kg_m": mu_kg_m}
    for key, label, value in (("field_span", nm["span_m"], span_m), ("field_n0", nm["n0_hz"], n0_hz),
                              ("field_mu", nm["mu_kg_m"], mu_kg_m)):
        row = ROWS[key]
        if row.outside(value, ctx):
            ctx_shown = ctx if key != "field_span" else {}
            text = row.message(label, value, ctx_shown).replace("plausible range", "studied field")
            if not extrapolate:
                raise InputError(f"{text}; outside the studied field the lower bounds are extrapolated "
                                 f"(give {nm['extrapolate']} to accept)")
            warnings.warn(f"{text}; extrapolated ({nm['extrapolate']})", PlausibilityWarning, stacklevel=2)


# ---------------------------------------------------------------------- documentation
def markdown_table():
    """The table of ``docs/plausibility.md`` (both parts), generated from :data:`TABLE` and :data:`FIELD`."""
    head = "| quantity | unit | plausible | checked in | reason |\n|---|---|---|---|---|\n"

    def rows(tab):
        return "".join(f"| {b.quantity} | {b.unit} | {b.bound} | {b.checked_in} | {b.reason} |\n" for b in tab)

    return ("## Warnings\n\n" + head + rows(TABLE)
            + "\n## The studied field (`adm-calib recommend` refuses outside it unless `--extrapolate`)\n\n"
            + head.replace("plausible", "field") + rows(FIELD))


__all__ = ["PlausibilityWarning", "Bound", "TABLE", "FIELD", "ROWS", "warn", "check_bridge", "warn_implausible_train",
           "check_response", "check_studied_field", "ARGUMENT_NAMES", "markdown_table", "n0_lb_hz", "n0_ub_hz"]


if __name__ == "__main__":  # regenerate the table of docs/plausibility.md: python -m adm_sim.model.plausibility
    print(markdown_table(), end="")
