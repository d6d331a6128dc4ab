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
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.files import check_path, read_toml
from adm_sim.model.parametric import FIELD_SPANS_M, MASS_FUNCTIONS, field_frequencies_hz
from adm_sim.model.plausibility import check_bridge
from adm_sim.fields import FIELDS, check_number, check_range, core
from adm_sim.fields import view as field_view

#: Allowed input ranges (SI): span, first frequency, modes; the field registry's
#: (:mod:`adm_sim.fields`), named here for the callers that need the numbers.
SPAN_RANGE_M = FIELDS["span_m"].range
N0_RANGE_HZ = FIELDS["n0_hz"].range
N_MODES_RANGE = FIELDS["n_modes"].range


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

    def __post_init__(self):
        if self.spans_m:
            self._check_deck()
            return
        for name in ("span_m", "EJ_Nm2", "mass_per_length_kg_m", "damping_ratio"):
            core(name).check(getattr(self, name))
        if int(self.n_modes) != self.n_modes or not (N_MODES_RANGE[0] <= self.n_modes <= N_MODES_RANGE[1]):
            raise InputError(f"n_modes: {self.n_modes!r} is out of range; allowed integer in "
                             f"[{N_MODES_RANGE[0]}, {N_MODES_RANGE[1]}]")
        core("damping_model").check(self.damping_model)
        if self.bridge_type != "":
            core("bridge_type").check(self.bridge_type)
        _check_n0(self.n0_hz, "n0_hz")

    def _check_deck(self):
        """The checks of a continuous deck (the readers at the edge name the keys as typed)."""
        n = FIELDS["n_spans"].check(len(self.spans_m), name="spans")
        lo, hi = FIELDS["deck_spans_m"].range
        for i, L in enumerate(self.spans_m):
            check_range(f"spans[{i}]", L, "m", lo, hi)
        for key, vals, fld in (("EJ", self.span_EJ_Nm2, "EJ_Nm2"), ("mu", self.span_mu_kg_m, "mass_per_length_kg_m")):
            if len(vals) != n:
                raise InputError(f"{key}: {len(vals)} values for {n} spans; give one value or one per span")
            for i, v in enumerate(vals):
                core(fld).check(v, name=f"{key}[{i}]")
        core("damping_ratio").check(self.damping_ratio)
        if self.span_m != math.fsum(self.spans_m):
            raise InputError(f"span_m: {self.span_m:g} m is not the deck length {math.fsum(self.spans_m):g} m")
        FIELDS["deck_n_modes"].check(self.n_modes, name="n_modes")
        core("damping_model").check(self.damping_model)
        if self.bridge_type != "":
            core("bridge_type").check(self.bridge_type)
        _check_n0(self.n0_hz, "n0_hz")

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
            from adm_sim.model.spans import rule_mode_count  # noqa: PLC0415

            Bridge(span_m=math.fsum(spans), EJ_Nm2=1.0, mass_per_length_kg_m=1.0, damping_ratio=damping_ratio,
                   spans_m=spans, span_EJ_Nm2=EJ, span_mu_kg_m=mu, n_modes=1)  # checks before the count
            n_modes = rule_mode_count(spans, EJ, mu)
            if n_modes > FIELDS["deck_n_modes"].hi:
                raise InputError(f"n_modes: the rule asks for {n_modes} modes of this deck; at most "
                                 f"{FIELDS['deck_n_modes'].hi} are allowed (give a stiffer or shorter deck)")
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
        from adm_sim.model.spans import deck_modes  # noqa: PLC0415

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
        L = core("span_m").check(span_m)
        n0 = core("n0_hz").check(n0_hz)
        mu = core("mass_per_length_kg_m").check(mass_per_length_kg_m)
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
    L = core("span_m").check(span_m)
    if bridge_type == "sc":
        return 0.5 + 0.125 * (20.0 - L) if L < 20.0 else 0.5
    if bridge_type == "cfb":
        return 1.5 + 0.07 * (20.0 - L) if L < 20.0 else 1.5
    core("bridge_type").check(bridge_type)


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


# ---------------------------------------------------------------------- user input
#: Spec / file keys -> quantity. ``type`` (alias ``bridge_type``) gives the Table 2 damping and the
#: class; ``class`` only classes the bridge (cfb|sc) for the lower-bound functions.
_SPEC_KEYS = {
    "L": "span_m", "span_m": "span_m",
    "n0": "n0_hz", "n0_hz": "n0_hz",
    "EJ": "EJ_Nm2", "EJ_Nm2": "EJ_Nm2",
    "mu": "mass_per_length_kg_m", "mu_kg_m": "mass_per_length_kg_m",
    "mass_per_length_kg_m": "mass_per_length_kg_m",
    "zeta_pct": "zeta_pct", "zeta": "damping_ratio", "damping_ratio": "damping_ratio",
    "type": "table2_type", "bridge_type": "table2_type", "class": "bridge_class",
    "n_modes": "n_modes", "damping_model": "damping_model", "name": "name",
    "spans": "deck_spans_m",
}
#: The separator of per-span values in a ``key=value`` spec (``spans=12/16/12``).
SPAN_SEPARATOR = "/"
#: Keys whose value is text (every other key is a number).
_TEXT_KEYS = ("type", "bridge_type", "class", "damping_model", "name")
#: Relative slack on the n0 range for an n0 recomputed from EJ (Eq. 18 round trip).
_N0_RTOL = 1e-12


def _n0_in_range(n0):
    """n0 within :data:`N0_RANGE_HZ`, allowing the rounding of the Eq. 18 round trip."""
    lo, hi = N0_RANGE_HZ
    return lo * (1.0 - _N0_RTOL) <= n0 <= hi * (1.0 + _N0_RTOL)


def _check_n0(n0, field):
    if not _n0_in_range(n0):
        core("n0_hz").check(n0, name=field)


def bridge_from_mapping(data, source="bridge", typed=False):
    """Build a bridge from a mapping of spec keys (SI units); every error names the key as typed.

    Keys: ``L`` (m), ``n0`` (Hz) or ``EJ`` (N m^2), ``mu`` (kg/m), and the damping as exactly one
    of ``zeta_pct`` (%), ``zeta`` (fraction) or ``type=cfb|sc`` (EN 1991-2 Table 6.6 / paper
    Table 2 damping, which also classes the bridge). ``class=cfb|sc`` classes a bridge of given
    damping for the lower-bound functions without changing its damping. Optional ``n_modes``
    (1..20), ``damping_model`` (rayleigh|modal), ``name``. Refused: unknown keys, a quantity given
    twice (``L=15,L=20``, ``L`` and ``span_m``, ``zeta_pct`` and ``zeta``), ``type`` together with
    a damping value or with ``class``, ``n0`` together with ``EJ``. With ``typed`` (a TOML file)
    numbers must be numbers and text must be text. Values that no real bridge has (n0 off the
    Fig. 8 band, mu off Table 1, damping that looks like a fraction) give a
    :class:`~adm_sim.model.plausibility.PlausibilityWarning`, not an error.
    """
    vals, given = {}, {}
    for key, value in data.items():
        if key not in _SPEC_KEYS:
            raise InputError(f"{source}: unknown key {key!r}; allowed {', '.join(sorted(_SPEC_KEYS))}")
        field_ = _SPEC_KEYS[key]
        if field_ in vals:
            raise InputError(f"{source}: {given[field_]!r} and {key!r} give the same quantity twice; give it once")
        if typed and key in _TEXT_KEYS and not isinstance(value, str):
            raise InputError(f"{source}.{key}: {value!r} must be text in quotes")
        vals[field_], given[field_] = value, key
    where = {f: f"{source}.{k}" for f, k in given.items()}
    surface = "toml" if typed else "spec"

    def num(f):
        """The value of quantity ``f`` checked as its key was typed (registry field, its unit)."""
        return field_view(surface, given[f]).check(vals[f], name=where[f], typed=typed)

    damping = [given[f] for f in ("zeta_pct", "damping_ratio", "table2_type") if f in vals]
    if len(damping) == 2:
        hint = (" (class=cfb|sc classes a bridge of given damping for the lower-bound functions)"
                if "table2_type" in vals else "")
        raise InputError(f"{source}: {damping[0]!r} and {damping[1]!r} both give the damping; give one{hint}")
    if len(damping) > 2:
        raise InputError(f"{source}: {', '.join(repr(d) for d in damping)} all give the damping; give one")
    if "table2_type" in vals and "bridge_class" in vals:
        raise InputError(f"{source}: {given['table2_type']!r} already classes the bridge; drop 'class'")
    if "n0_hz" in vals and "EJ_Nm2" in vals:
        raise InputError(f"{source}: give either n0 (Hz) or EJ (N m^2), not both")
    if "deck_spans_m" in vals:
        return _deck_from_mapping(vals, given, where, source, typed)
    for f in ("EJ_Nm2", "mass_per_length_kg_m"):
        if f in vals and (isinstance(vals[f], list) or (not typed and SPAN_SEPARATOR in str(vals[f]))):
            raise InputError(f"{where[f]}: {vals[f]!r} gives one value per span; per-span values need "
                             f"spans = [..] (m), the spans of a continuous deck")

    for need, what in (("span_m", "L (span, m)"), ("mass_per_length_kg_m", "mu (mass per length, kg/m)")):
        if need not in vals:
            raise InputError(f"{source}: missing key {what}")
    L = num("span_m")
    mu = num("mass_per_length_kg_m")
    btype = ""
    for f in ("table2_type", "bridge_class"):
        if f in vals:
            btype = field_view(surface, given[f]).check(str(vals[f]), name=where[f])
    if "zeta_pct" in vals or "damping_ratio" in vals:
        f = "zeta_pct" if "zeta_pct" in vals else "damping_ratio"
        zeta = field_view(surface, given[f]).to_core(num(f))
    elif "table2_type" in vals:
        zeta = eurocode_damping_pct(L, btype) / 100.0
    else:
        zp, z = field_view(surface, "zeta_pct"), field_view(surface, "zeta")
        raise InputError(f"{source}: missing damping: give zeta_pct (%, {zp.lo:g}..{zp.hi:g}), zeta (fraction, "
                         f"{z.lo:g}..{z.hi:g}) or type=cfb|sc (Table 2 damping)")
    kw = dict(name=str(vals.get("name", "")), bridge_type=btype)
    if "n_modes" in vals:
        kw["n_modes"] = num("n_modes")
    if "damping_model" in vals:
        kw["damping_model"] = field_view(surface, "damping_model").check(str(vals["damping_model"]),
                                                                        name=where["damping_model"])
    if "n0_hz" in vals:
        n0 = num("n0_hz")
        return _plausible(Bridge.from_frequency(L, n0, mu, zeta, **kw), source, zeta, "zeta_pct" in vals)
    if "EJ_Nm2" in vals:
        EJ = num("EJ_Nm2")
        n0 = math.pi / (2.0 * L**2) * math.sqrt(EJ / mu)
        if not _n0_in_range(n0):
            raise InputError(f"{where['EJ_Nm2']}: {EJ:g} N m^2 gives n0 = {n0:.4g} Hz with L = {L:g} m and "
                             f"mu = {mu:g} kg/m (Eq. 18); allowed n0 in [{N0_RANGE_HZ[0]:g}, {N0_RANGE_HZ[1]:g}] Hz")
        bridge = Bridge(span_m=L, EJ_Nm2=EJ, mass_per_length_kg_m=mu, damping_ratio=zeta, **kw)
        return _plausible(bridge, source, zeta, "zeta_pct" in vals)
    raise InputError(f"{source}: missing stiffness: give n0 (Hz, {N0_RANGE_HZ[0]:g}..{N0_RANGE_HZ[1]:g}) or EJ "
                     f"(N m^2, > {FIELDS['EJ_Nm2'].lo:g})")


def _span_values(key, value, source, typed, unit):
    """The numbers of a per-span key as typed: a TOML list (or one number), or ``a/b/c`` in a spec."""
    if typed:
        if isinstance(value, list):
            return list(value)
        return [value]
    text = str(value)
    return [p.strip() for p in text.split(SPAN_SEPARATOR)]


def _deck_from_mapping(vals, given, where, source, typed):
    """A continuous deck from the keys of :func:`bridge_from_mapping` with ``spans``."""
    surface = "toml" if typed else "spec"
    fspans, fcount = FIELDS["deck_spans_m"], FIELDS["n_spans"]
    key = where["deck_spans_m"]
    raw = _span_values("spans", vals["deck_spans_m"], source, typed, "m")
    shown = vals["deck_spans_m"]
    if not raw or (typed and not isinstance(shown, list)):
        raise InputError(f"{key}: {shown!r} is not a list of spans; give e.g. spans = [12.0, 16.0, 12.0] (m), "
                         f"{fcount.lo}..{fcount.hi} spans each in [{fspans.lo:g}, {fspans.hi:g}] m")
    if not fcount.lo <= len(raw) <= fcount.hi:
        raise InputError(f"{key}: {len(raw)} spans is out of range; allowed {fcount.lo}..{fcount.hi} spans, "
                         f"each in [{fspans.lo:g}, {fspans.hi:g}] m")
    check = check_number if typed else check_range
    spans = [check(f"{key}[{i}]", v, "m", fspans.lo, fspans.hi) for i, v in enumerate(raw)]
    if "span_m" in vals:
        raise InputError(f"{source}: {given['span_m']!r} and 'spans' both give the length; give L for one span "
                         f"or spans = [..] (m) for a continuous deck")
    if "table2_type" in vals:
        raise InputError(f"{where['table2_type']}: the Table 2 damping of a continuous deck needs the length the "
                         f"standard names for continuous decks, which is not wired; give zeta_pct (%) and "
                         f"class=cfb|sc")
    n = len(spans)
    if n == 1:  # one span: the simply supported beam of today (sine modes, Eq. 4), as if given by L
        data = {given[f]: (v[0] if isinstance(v, list) and len(v) == 1 else v) for f, v in vals.items()
                if f != "deck_spans_m"}
        data["L"] = spans[0]
        for k in ("EJ", "EJ_Nm2", "mu", "mu_kg_m", "mass_per_length_kg_m"):
            if not typed and k in data and SPAN_SEPARATOR not in str(data[k]):
                data[k] = str(data[k])
        return bridge_from_mapping(data, source=source, typed=typed)

    def per_span(f, what):
        ws = where[f]
        items = _span_values(given[f], vals[f], source, typed, "")
        if len(items) not in (1, n):
            raise InputError(f"{ws}: {len(items)} values for {n} spans; allowed one value or one per span "
                             f"({what})")
        v = field_view(surface, given[f])
        out = [v.check(x, name=ws if len(items) == 1 else f"{ws}[{i}]", typed=typed) for i, x in enumerate(items)]
        return out if len(out) == n else out * n

    if "mass_per_length_kg_m" not in vals:
        raise InputError(f"{source}: missing key mu (mass per length, kg/m; one value or one per span)")
    mu = per_span("mass_per_length_kg_m", "kg/m")
    if "zeta_pct" in vals or "damping_ratio" in vals:
        f = "zeta_pct" if "zeta_pct" in vals else "damping_ratio"
        zeta = field_view(surface, given[f]).to_core(field_view(surface, given[f]).check(vals[f], name=where[f],
                                                                                            typed=typed))
    else:
        zp = field_view(surface, "zeta_pct")
        raise InputError(f"{source}: missing damping of the continuous deck: give zeta_pct (%, {zp.lo:g}..{zp.hi:g}) "
                         f"or zeta (fraction)")
    kw = dict(name=str(vals.get("name", "")))
    if "bridge_class" in vals:
        kw["bridge_type"] = field_view(surface, given["bridge_class"]).check(str(vals["bridge_class"]),
                                                                            name=where["bridge_class"])
    if "damping_model" in vals:
        kw["damping_model"] = field_view(surface, "damping_model").check(str(vals["damping_model"]),
                                                                        name=where["damping_model"])
    from adm_sim.model.spans import RULE_TEXT, deck_modes, rule_mode_count  # noqa: PLC0415

    if "EJ_Nm2" in vals:
        EJ = per_span("EJ_Nm2", "N m^2")
    elif "n0_hz" in vals:
        n0 = field_view(surface, given["n0_hz"]).check(vals["n0_hz"], name=where["n0_hz"], typed=typed)
        f1 = float(deck_modes(spans, [1.0] * n, mu, 1).frequencies_hz[0])  # omega grows as sqrt(EJ)
        EJ = [(n0 / f1) ** 2] * n
    else:
        raise InputError(f"{source}: missing stiffness: give EJ (N m^2, > {FIELDS['EJ_Nm2'].lo:g}; one value or one "
                         f"per span) or n0 (Hz, {N0_RANGE_HZ[0]:g}..{N0_RANGE_HZ[1]:g}: one EJ for every span)")
    f1 = float(deck_modes(spans, EJ, mu, 1).frequencies_hz[0])
    if not _n0_in_range(f1):
        raise InputError(f"{source}: the deck's first frequency is {f1:.4g} Hz; allowed n0 in "
                         f"[{N0_RANGE_HZ[0]:g}, {N0_RANGE_HZ[1]:g}] Hz (check EJ and mu)")
    rule = rule_mode_count(spans, EJ, mu)
    if "n_modes" in vals:
        nv = field_view("count", "n_modes")
        n_modes = nv.check(vals["n_modes"], name=where["n_modes"])
        if n_modes < rule:
            warnings.warn(f"{where['n_modes']}: {n_modes} modes is fewer than the {rule} that the rule asks for "
                          f"on this deck ({RULE_TEXT})", PlausibilityWarning, stacklevel=3)
    else:
        n_modes = rule
        if n_modes > FIELDS["deck_n_modes"].hi:
            raise InputError(f"{source}: the rule ({RULE_TEXT}) asks for {n_modes} modes of this deck; allowed at "
                             f"most {FIELDS['deck_n_modes'].hi} (give n_modes)")
    return Bridge.continuous(spans, EJ, mu, zeta, n_modes=n_modes, **kw)


def _plausible(bridge, source, zeta, zeta_in_pct):
    """``bridge``, after the plausibility warnings of :mod:`adm_sim.model.plausibility` (never a refusal)."""
    check_bridge(bridge, source, 100.0 * zeta if zeta_in_pct else None)
    return bridge


def parse_bridge_spec(spec):
    """Parse ``"L=15,n0=8.26,mu=19042,zeta_pct=1.85"`` into a :class:`Bridge`."""
    data = {}
    for part in spec.split(","):
        if not part.strip():
            continue
        if "=" not in part:
            raise InputError(f"bridge spec: {part!r} is not key=value (e.g. L=15,n0=8.26,mu=19042,zeta_pct=1.85)")
        k, v = part.split("=", 1)
        if k.strip() in data:
            raise InputError(f"bridge spec: {k.strip()!r} is given twice ({data[k.strip()]!r} and {v.strip()!r}); "
                             f"give it once")
        data[k.strip()] = v.strip()
    if "name" not in data:
        data["name"] = "custom"
    return bridge_from_mapping(data, source="bridge spec")


def load_bridge_file(path):
    """Read a bridge from a TOML file with the keys of :func:`bridge_from_mapping`."""
    p = Path(path)
    data = read_toml(p, "bridge file")
    data.setdefault("name", p.stem)
    return bridge_from_mapping(data, source=f"bridge file {p.name}", typed=True)


#: Where a continuous deck is taken today (the refusal of every other entry names it).
CONTINUOUS_WIRED = "adm-sim sweep --model mlm (RK4)"


def resolve_bridge(text, continuous=False):
    """A bridge from a CLI/parameter string: a Table 3 name, a ``key=value`` spec or a file.

    ``continuous``: the caller takes a continuous deck (``spans`` of two or more); without it such a
    deck is refused with one line naming where continuous decks are taken (:data:`CONTINUOUS_WIRED`).
    """
    bridge = _resolve_bridge(text)
    if bridge.is_continuous and not continuous:
        raise InputError(f"bridge: {text!r} is a continuous deck of {len(bridge.spans_m)} spans; this entry takes one "
                         f"simply supported span (allowed: L=..., B1..B4; continuous decks: {CONTINUOUS_WIRED})",
                         field="bridge")
    return bridge


def _resolve_bridge(text):
    if text.upper() in TABLE3:
        return named_bridge(text)
    if "=" not in text or text.endswith(".toml"):
        check_path(text, "bridge")
    try:
        exists = Path(text).is_file()
    except OSError:  # a spec longer than a file name can be
        exists = False
    if exists:  # an existing file wins, even with '=' in its name
        return load_bridge_file(text)
    if "=" in text:
        return parse_bridge_spec(text)
    raise InputError(f"bridge: {text!r} is neither a named bridge ({', '.join(TABLE3)}), "
                     f"a spec like L=15,n0=8.26,mu=19042,zeta_pct=1.85, nor a file", field="bridge")
