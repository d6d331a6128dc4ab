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
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError
from adm_sim.files import check_path, read_toml
from adm_sim.model.parametric import FIELD_SPANS_M, MASS_FUNCTIONS, field_frequencies_hz
from adm_sim.model.plausibility import check_bridge
from adm_sim.fields import FIELDS, core
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
    """

    span_m: float
    EJ_Nm2: float
    mass_per_length_kg_m: float
    damping_ratio: float
    n_modes: int = 3
    damping_model: str = "rayleigh"
    name: str = ""
    bridge_type: str = ""

    def __post_init__(self):
        for name in ("span_m", "EJ_Nm2", "mass_per_length_kg_m", "damping_ratio"):
            core(name).check(getattr(self, name))
        if int(self.n_modes) != self.n_modes or not (N_MODES_RANGE[0] <= self.n_modes <= N_MODES_RANGE[1]):
            raise InputError(f"n_modes: {self.n_modes!r} is out of range; allowed integer in "
                             f"[{N_MODES_RANGE[0]}, {N_MODES_RANGE[1]}]")
        core("damping_model").check(self.damping_model)
        if self.bridge_type != "":
            core("bridge_type").check(self.bridge_type)
        _check_n0(self.n0_hz, "n0_hz")

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
        """Copy with another structural damping ratio (fraction)."""
        return dataclasses.replace(self, damping_ratio=damping_ratio)

    # ------------------------------------------------------------------ modal data
    @property
    def n0_hz(self):
        """First natural frequency (Hz), Eq. (18)."""
        return math.pi / (2.0 * self.span_m**2) * math.sqrt(self.EJ_Nm2 / self.mass_per_length_kg_m)

    @property
    def mode_numbers(self):
        return np.arange(1, self.n_modes + 1, dtype=float)

    @property
    def omega_rad_s(self):
        """Circular frequencies omega_j (rad/s), shape (n_modes,)."""
        j = self.mode_numbers
        return (j * math.pi / self.span_m) ** 2 * math.sqrt(self.EJ_Nm2 / self.mass_per_length_kg_m)

    @property
    def modal_mass_kg(self):
        """Modal masses M_j = mu L / 2 (kg), shape (n_modes,)."""
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
        ``[0, L]`` (the rectangle function Gamma of Eq. 6).
        """
        x = np.asarray(x_m, dtype=float)[..., None]
        k = self.mode_numbers * math.pi / self.span_m
        on = (x >= 0.0) & (x <= self.span_m)
        s = np.where(on, np.sin(k * x), 0.0)
        c = np.where(on, np.cos(k * x), 0.0)
        return s, k * c, -(k**2) * s

    def describe(self):
        zeta_pct = 100.0 * self.damping_ratio
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
}
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


def resolve_bridge(text):
    """A bridge from a CLI/parameter string: a Table 3 name, a ``key=value`` spec or a file."""
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
