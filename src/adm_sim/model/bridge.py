"""Simply supported Bernoulli-Euler beam by modal superposition (paper Section 2.1, 3.1).

Deflection ``w(x, t) = sum_j q_j(t) phi_j(x)`` with the eigenfunctions
``phi_j(x) = sin(j pi x / L)`` (Eq. 4), so the modal matrices of Eq. (5) are diagonal:

* modal mass      ``M_j = mu L / 2``
* circular freq.  ``omega_j = (j pi / L)^2 sqrt(EJ / mu)``; ``n0 = omega_1 / 2 pi`` (Eq. 18)
* modal stiffness ``K_j = M_j omega_j^2``
* modal damping   ``Z_j = 2 zeta_j M_j omega_j``.

Damping: the paper composes Z by Rayleigh damping (Section 2.1) without naming the anchor modes.
We anchor the Rayleigh curve ``zeta_j = a / (2 omega_j) + b omega_j / 2`` at modes 1 and 3,
the two lowest modes that move midspan (mode 2 has a node there), so every mode that contributes
to the midspan response carries exactly ``zeta + delta_zeta``; mode 2 gets ``0.625 (zeta +
delta_zeta)``. ``damping_model="modal"`` gives every mode the same ratio instead.

Limits: linear elastic, simply supported, no shear deformation or rotary inertia, rigid
supports; valid while the retained modes resolve the loading (3 modes by default, Section 2.3).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError, ModelError
from adm_sim.model.parametric import FIELD_SPANS_M, MASS_FUNCTIONS, field_frequencies_hz
from adm_sim.model.spans import deck_modes, rule_mode_count

#: The damping models the modal matrices implement (:meth:`Bridge.modal_damping_ratios`).
DAMPING_MODELS = ("rayleigh", "modal")
#: The bridge types of Table 2 / EN 1991-2 Table 6.6 the model knows ("" = not classed).
BRIDGE_TYPES = ("cfb", "sc")


def _positive(name, value, unit):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"Bridge.{name}: {value!r} is not a number ({unit})") from None
    if not (math.isfinite(x) and x > 0.0):
        raise ModelError(f"Bridge.{name}: {value!r} {unit} must be finite and > 0")
    return x


@dataclass(frozen=True)
class Bridge:
    """A simply supported modal beam.

    Parameters
    ----------
    span_m : float
        Span L (m).
    EJ_Nm2 : float
        Bending stiffness EJ (N m^2).
    mass_per_length_kg_m : float
        Mass per unit length mu (kg/m).
    damping_ratio : float
        Structural damping zeta as a fraction of critical (0.0185 for 1.85 %).
    n_modes : int
        Number of retained modes (paper: 3).
    damping_model : {"rayleigh", "modal"}
        Rayleigh anchored at modes 1 and 3 (default) or equal modal damping.
    name : str
        Label used in outputs.
    bridge_type : {"cfb", "sc", ""}
        Concrete/filler-beam or steel/composite (Table 2); empty if unknown.
    spans_m : tuple of float
        Empty (default): one simply supported span of ``span_m`` with the sine modes of Eq. (4).
        Otherwise a continuous deck over pinned intermediate supports (:mod:`adm_sim.model.spans`),
        left to right; ``span_m`` is then the deck length (their sum), ``EJ_Nm2`` and
        ``mass_per_length_kg_m`` the length-weighted means (labels: the modes use the per-span
        values). Build it with :meth:`Bridge.continuous`.
    span_EJ_Nm2, span_mu_kg_m : tuple of float
        EJ (N m^2) and mu (kg/m) of every span of a continuous deck.
    damping_source : str
        Where ``damping_ratio`` comes from, as the readers found it (a label for the outputs, like
        ``name``; empty: as given). A continuous deck damped by type: :func:`deck_damping_pct`.
        Not compared: two bridges of the same damping are equal whoever gave it.
    """

    span_m: float
    EJ_Nm2: float
    mass_per_length_kg_m: float
    damping_ratio: float
    n_modes: int = 3
    damping_model: str = "rayleigh"
    name: str = ""
    bridge_type: str = ""
    spans_m: tuple = ()
    span_EJ_Nm2: tuple = ()
    span_mu_kg_m: tuple = ()
    damping_source: str = dataclasses.field(default="", compare=False)

    def __post_init__(self):
        """The model's invariants only (:class:`ModelError`); the input ranges are the readers'
        (:mod:`adm_sim.inputs`, the field registry :mod:`adm_sim.fields`)."""
        if self.spans_m:
            self._check_deck()
        for name, unit in (("span_m", "m"), ("EJ_Nm2", "N m^2"), ("mass_per_length_kg_m", "kg/m")):
            _positive(name, getattr(self, name), unit)
        try:
            z = float(self.damping_ratio)
        except (TypeError, ValueError):
            z = math.nan
        if not (math.isfinite(z) and 0.0 <= z < 1.0):
            raise ModelError(f"Bridge.damping_ratio: {self.damping_ratio!r} must be a fraction in [0, 1)")
        try:
            whole = int(self.n_modes) == self.n_modes and not isinstance(self.n_modes, bool)
        except (TypeError, ValueError, OverflowError):
            whole = False
        if not (whole and self.n_modes >= 1):
            raise ModelError(f"Bridge.n_modes: {self.n_modes!r} must be an integer >= 1")
        if self.damping_model not in DAMPING_MODELS:
            raise ModelError(f"Bridge.damping_model: {self.damping_model!r} is not one of {DAMPING_MODELS}")
        if self.bridge_type not in ("",) + BRIDGE_TYPES:
            raise ModelError(f"Bridge.bridge_type: {self.bridge_type!r} is not one of {('',) + BRIDGE_TYPES}")

    def _check_deck(self):
        """A continuous deck's invariants: one EJ and one mu per span, every one finite and > 0, and
        ``span_m`` the deck length."""
        n = len(self.spans_m)
        for key, vals in (("span_EJ_Nm2", self.span_EJ_Nm2), ("span_mu_kg_m", self.span_mu_kg_m)):
            if len(vals) != n:
                raise ModelError(f"Bridge.{key}: {len(vals)} values for {n} spans")
        for key, vals, unit in (("spans_m", self.spans_m, "m"), ("span_EJ_Nm2", self.span_EJ_Nm2, "N m^2"),
                                ("span_mu_kg_m", self.span_mu_kg_m, "kg/m")):
            for i, v in enumerate(vals):
                _positive(f"{key}[{i}]", v, unit)
        if self.span_m != math.fsum(self.spans_m):
            raise ModelError(f"Bridge.span_m: {self.span_m:g} m is not the deck length {math.fsum(self.spans_m):g} m")

    @classmethod
    def continuous(cls, spans_m, EJ_Nm2, mass_per_length_kg_m, damping_ratio, n_modes=None, **kw):
        """A continuous deck of the spans ``spans_m`` (m, left to right, pinned over the supports).

        ``EJ_Nm2`` (N m^2) and ``mass_per_length_kg_m`` (kg/m): one value, or one per span.
        ``n_modes``: None for the rule of :func:`adm_sim.model.spans.rule_mode_count` (every mode up
        to 30 Hz, 1.5 n0 or the third, whichever is higher).
        """
        spans = tuple(float(x) for x in spans_m)
        n = len(spans)

        def per_span(v):
            return tuple(float(x) for x in v) if np.ndim(v) else (float(v),) * n

        EJ, mu = per_span(EJ_Nm2), per_span(mass_per_length_kg_m)
        if n_modes is None:
            Bridge(span_m=math.fsum(spans), EJ_Nm2=1.0, mass_per_length_kg_m=1.0, damping_ratio=damping_ratio,
                   spans_m=spans, span_EJ_Nm2=EJ, span_mu_kg_m=mu, n_modes=1)  # checks before the count
            n_modes = rule_mode_count(spans, EJ, mu)
        L = math.fsum(spans)
        mean = lambda v: math.fsum(a * b for a, b in zip(v, spans)) / L  # noqa: E731
        return cls(span_m=L, EJ_Nm2=mean(EJ) if len(set(EJ)) > 1 else EJ[0],
                   mass_per_length_kg_m=mean(mu) if len(set(mu)) > 1 else mu[0], damping_ratio=damping_ratio,
                   n_modes=n_modes, spans_m=spans, span_EJ_Nm2=EJ, span_mu_kg_m=mu, **kw)

    @property
    def is_continuous(self):
        """True for a deck given by its spans (:mod:`adm_sim.model.spans` modes, even of one span)."""
        return bool(self.spans_m)

    @functools.cached_property
    def deck(self):
        """The exact modes of a continuous deck (:class:`adm_sim.model.spans.DeckModes`), or None."""
        if not self.spans_m:
            return None
        return deck_modes(self.spans_m, self.span_EJ_Nm2, self.span_mu_kg_m, self.n_modes)

    @property
    def supports_m(self):
        """Support abscissae from the left abutment (m), shape (n_spans + 1,)."""
        if not self.spans_m:
            return np.array([0.0, self.span_m])
        return np.concatenate([[0.0], np.cumsum(self.spans_m)])

    @property
    def midspan_m(self):
        """The response point called midspan (m from the left abutment): L / 2 for one span; for a
        continuous deck the middle of its longest span (the first of equal ones), the project's choice."""
        if not self.spans_m:
            return 0.5 * self.span_m
        i = int(np.argmax(self.spans_m))
        return float(self.supports_m[i] + 0.5 * self.spans_m[i])

    @property
    def frequencies_hz(self):
        """Natural frequencies of the retained modes (Hz), shape (n_modes,)."""
        return self.omega_rad_s / (2.0 * math.pi)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_frequency(cls, span_m, n0_hz, mass_per_length_kg_m, damping_ratio, **kw):
        """Bridge from (L, n0, mu, zeta); EJ from Eq. (18): ``EJ = mu (2 L^2 n0 / pi)^2``."""
        L = _positive("span_m", span_m, "m")
        n0 = _positive("n0_hz", n0_hz, "Hz")
        mu = _positive("mass_per_length_kg_m", mass_per_length_kg_m, "kg/m")
        EJ = mu * (2.0 * L**2 * n0 / math.pi) ** 2
        return cls(span_m=L, EJ_Nm2=EJ, mass_per_length_kg_m=mu, damping_ratio=damping_ratio, **kw)

    def with_damping(self, damping_ratio):
        """Copy with another structural damping ratio (fraction) (a continuous deck keeps its modes)."""
        out = dataclasses.replace(self, damping_ratio=damping_ratio)
        if "deck" in self.__dict__:
            out.__dict__["deck"] = self.__dict__["deck"]
        return out

    # ------------------------------------------------------------------ modal data
    @property
    def n0_hz(self):
        """First natural frequency (Hz), Eq. (18) (a continuous deck: its first mode)."""
        if self.spans_m:
            return float(self.deck.frequencies_hz[0])
        return math.pi / (2.0 * self.span_m**2) * math.sqrt(self.EJ_Nm2 / self.mass_per_length_kg_m)

    @property
    def mode_numbers(self):
        return np.arange(1, self.n_modes + 1, dtype=float)

    @property
    def omega_rad_s(self):
        """Circular frequencies omega_j (rad/s), shape (n_modes,)."""
        if self.spans_m:
            return self.deck.omega_rad_s
        j = self.mode_numbers
        return (j * math.pi / self.span_m) ** 2 * math.sqrt(self.EJ_Nm2 / self.mass_per_length_kg_m)

    @property
    def modal_mass_kg(self):
        """Modal masses M_j = mu L / 2 (kg), shape (n_modes,) (a continuous deck: Eq. (5) with
        max |phi_j| = 1, :mod:`adm_sim.model.spans`)."""
        if self.spans_m:
            return self.deck.modal_mass_kg
        return np.full(self.n_modes, 0.5 * self.mass_per_length_kg_m * self.span_m)

    @property
    def modal_stiffness_N_m(self):
        return self.modal_mass_kg * self.omega_rad_s**2

    def modal_damping_ratios(self, delta_zeta=0.0):
        """Damping ratio of every mode for total damping ``zeta + delta_zeta`` (fractions).

        Rayleigh: ``zeta_j = a / (2 omega_j) + b omega_j / 2`` with ``zeta_1 = zeta_3 = zeta_tot``
        (modes 1 and 2 when only two modes are kept; all modes equal with one mode).
        Parameters may be arrays (one value per speed lane); the result then has shape
        ``(n_lanes, n_modes)``.
        """
        zt = np.asarray(self.damping_ratio + np.asarray(delta_zeta, dtype=float), dtype=float)
        w = self.omega_rad_s
        if self.damping_model == "modal" or self.n_modes == 1:
            return zt[..., None] * np.ones_like(w)
        r2 = 2 if self.n_modes >= 3 else 1
        w1, w2 = w[0], w[r2]
        a = 2.0 * w1 * w2 / (w1 + w2)
        b = 2.0 / (w1 + w2)
        return zt[..., None] * (a / (2.0 * w) + b * w / 2.0)

    def modal_damping_Ns_m(self, delta_zeta=0.0):
        """Modal damping coefficients Z_j = 2 zeta_j M_j omega_j (N s/m)."""
        return 2.0 * self.modal_damping_ratios(delta_zeta) * self.modal_mass_kg * self.omega_rad_s

    def shapes(self, x_m):
        """Mode shapes and their x-derivatives at positions ``x_m``.

        Returns ``(phi, phi_x, phi_xx)``, each of shape ``x_m.shape + (n_modes,)``; zero outside
        ``[0, L]`` (the rectangle function Gamma of Eq. 6). A continuous deck: its exact modes
        (:meth:`adm_sim.model.spans.DeckModes.shapes`), x from the left abutment.
        """
        if self.spans_m:
            return self.deck.shapes(x_m)
        x = np.asarray(x_m, dtype=float)[..., None]
        k = self.mode_numbers * math.pi / self.span_m
        on = (x >= 0.0) & (x <= self.span_m)
        s = np.where(on, np.sin(k * x), 0.0)
        c = np.where(on, np.cos(k * x), 0.0)
        return s, k * c, -(k**2) * s

    def describe(self):
        zeta_pct = 100.0 * self.damping_ratio
        if self.spans_m:
            def each(v, scale=1.0, fmt="{:g}"):
                return fmt.format(v[0] / scale) if len(set(v)) == 1 else "/".join(fmt.format(x / scale) for x in v)
            f = ", ".join(f"{x:.3f}" for x in self.frequencies_hz)
            return (f"{self.name or 'bridge'}: continuous deck of {len(self.spans_m)} spans "
                    f"{'+'.join(f'{x:g}' for x in self.spans_m)} m, mu={each(self.span_mu_kg_m, 1000.0, '{:.3f}')} t/m, "
                    f"EJ={each(self.span_EJ_Nm2, fmt='{:.4g}')} N m^2, zeta={zeta_pct:.3g} %, {self.n_modes} modes "
                    f"({self.damping_model}) at {f} Hz")
        return (f"{self.name or 'bridge'}: L={self.span_m:g} m, n0={self.n0_hz:.3f} Hz, "
                f"mu={self.mass_per_length_kg_m:.6g} kg/m ({self.mass_per_length_kg_m / 1000:.3f} t/m), EJ={self.EJ_Nm2:.4g} N m^2, "
                f"zeta={zeta_pct:.3g} %, {self.n_modes} modes ({self.damping_model})")


# ---------------------------------------------------------------------- Eurocode damping
def eurocode_damping_pct(span_m, bridge_type):
    """Lower-limit structural damping (%) of EN 1991-2 Table 6.6 (paper Table 2).

    Steel and composite (``"sc"``): ``0.5 + 0.125 (20 - L)`` for L < 20 m, else 0.5.
    Filler beam and reinforced concrete (``"cfb"``): ``1.5 + 0.07 (20 - L)`` for L < 20 m, else 1.5.
    """
    L = _positive("span_m", span_m, "m")
    if bridge_type == "sc":
        return 0.5 + 0.125 * (20.0 - L) if L < 20.0 else 0.5
    if bridge_type == "cfb":
        return 1.5 + 0.07 * (20.0 - L) if L < 20.0 else 1.5
    raise ModelError(f"bridge_type: {bridge_type!r} has no Table 6.6 damping; allowed {' or '.join(BRIDGE_TYPES)}")


#: The length L that Table 6.6 is read with on a continuous deck, and why. EN 1991-2's wording for
#: continuous decks could not be checked here (docs/check.md lists the searches), so the rule is
#: the project's choice: the longest span. Table 6.6 does not increase with L, so the longest span
#: gives the lowest of the spans' values: the conservative choice (the mean span or the shortest
#: span would give as much or more damping).
DECK_DAMPING_LENGTH_RULE = ("L the longest span: the project's choice, the conservative one (Table 6.6 does not "
                            "increase with L, so the longest span gives the lowest of the spans' values); the "
                            "standard's wording of L for continuous decks could not be checked here")


def deck_damping_length_m(spans_m):
    """L (m) of EN 1991-2 Table 6.6 for a continuous deck of spans ``spans_m`` (m): the longest span
    (:data:`DECK_DAMPING_LENGTH_RULE`); one span: the span."""
    return max(float(x) for x in spans_m)


def deck_damping_pct(spans_m, bridge_type):
    """Lower-limit structural damping (%) of EN 1991-2 Table 6.6 (paper Table 2) for a continuous deck:
    :func:`eurocode_damping_pct` at :func:`deck_damping_length_m` (the longest span, the project's
    choice, :data:`DECK_DAMPING_LENGTH_RULE`). Returns ``(damping_pct, L_m, source_text)``."""
    L = deck_damping_length_m(spans_m)
    pct = eurocode_damping_pct(L, bridge_type)
    text = (f"EN 1991-2 Table 6.6 lower limit for {bridge_type.upper()} (paper Table 2) with L = {L:g} m, "
            f"{DECK_DAMPING_LENGTH_RULE}")
    return pct, L, text


# ---------------------------------------------------------------------- named bridges (Table 3)
#: Table 3: L (m), n0 (Hz), mu (t/m), EJ (N m^2), zeta (%), type.
TABLE3 = {
    "B1": (15.0, 8.26, 19.042, 2.667e10, 1.85, "cfb"),
    "B2": (30.0, 3.60, 29.545, 1.256e11, 1.50, "cfb"),
    "B3": (15.0, 8.26, 7.739, 1.084e10, 1.13, "sc"),
    "B4": (30.0, 3.60, 9.560, 4.064e10, 0.50, "sc"),
}


def named_bridge(name, **kw):
    """Bridge B1-B4 of Table 3 (EJ and mu as printed; n0 follows from Eq. 18)."""
    key = name.upper()
    if key not in TABLE3:
        raise InputError(f"bridge: {name!r} is not a named bridge; allowed {', '.join(TABLE3)}")
    L, _n0, mu_t, EJ, zeta_pct, btype = TABLE3[key]
    return Bridge(span_m=L, EJ_Nm2=EJ, mass_per_length_kg_m=mu_t * 1000.0,
                  damping_ratio=zeta_pct / 100.0, name=key, bridge_type=btype, **kw)


# ---------------------------------------------------------------------- parametric field
def parametric_field(n_modes=3, damping_model="rayleigh"):
    """The 1110 bridges of Section 3.3: 185 (L, n0) pairs x 6 mass functions (:mod:`adm_sim.model.parametric`).

    Each bridge carries its Table 2 damping and a name ``"L15-f3-mu2"`` (span, frequency index
    1..5 from LB to UB, mass function). Returns a list of :class:`Bridge`.
    """
    out = []
    for L in FIELD_SPANS_M:
        for fi, n0 in enumerate(field_frequencies_hz(L), start=1):
            for mname, (k, d, btype) in MASS_FUNCTIONS.items():
                mu = (k * L + d) * 1000.0
                zeta = eurocode_damping_pct(L, btype) / 100.0
                out.append(Bridge.from_frequency(
                    L, n0, mu, zeta, n_modes=n_modes, damping_model=damping_model,
                    name=f"L{L:g}-f{fi}-{mname}", bridge_type=btype))
    return out
