"""The bridge as the user gives it: a Table 3 name (B1..B4), a ``key=value`` spec or a TOML file.

Every reader here turns what was typed into the numbers of :class:`adm_sim.model.bridge.Bridge` and
refuses the rest with one line naming the key as typed, the value, the unit and the allowed range
(the field registry, :mod:`adm_sim.fields`). The model takes the numbers; it knows no spellings.

Keys (SI units): ``L`` (m), ``n0`` (Hz) or ``EJ`` (N m^2), ``mu`` (kg/m), and the damping as exactly
one of ``zeta_pct`` (%), ``zeta`` (fraction) or ``type=cfb|sc`` (EN 1991-2 Table 6.6 / paper Table 2
damping, which also classes the bridge); ``spans`` (m, a TOML list or ``12/16/12`` in a spec) makes a
continuous deck (:mod:`adm_sim.model.spans`), whose ``type`` damping is Table 6.6 with L the longest
span (:func:`adm_sim.model.bridge.deck_damping_pct`, the project's choice).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.fields import FIELDS, check_number, check_range, core
from adm_sim.fields import view as field_view
from adm_sim.files import check_path, read_toml
from adm_sim.model.bridge import TABLE3, Bridge, deck_damping_pct, eurocode_damping_pct, named_bridge
from adm_sim.model.plausibility import check_bridge
from adm_sim.model.spans import RULE_TEXT, deck_modes, rule_mode_count

#: The n0 range (Hz) a bridge may have: the field registry's, named for the messages.
N0_RANGE_HZ = FIELDS["n0_hz"].range
#: Relative slack on the n0 range for an n0 recomputed from EJ (Eq. 18 round trip).
_N0_RTOL = 1e-12


def n0_in_range(n0):
    """n0 (Hz) within :data:`N0_RANGE_HZ`, allowing the rounding of the Eq. 18 round trip."""
    lo, hi = N0_RANGE_HZ
    return lo * (1.0 - _N0_RTOL) <= n0 <= hi * (1.0 + _N0_RTOL)


def check_n0(n0, name="n0_hz"):
    """A computed first frequency (Hz) in the registry's range, else its one-line refusal naming ``name``."""
    if not n0_in_range(n0):
        core("n0_hz").check(n0, name=name)
    return n0


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
#: Where a continuous deck is taken today (the refusal of every other entry names it).
CONTINUOUS_WIRED = ("adm-sim sweep (RK4), adm-sim check, adm-calib calibrate, adm-calib study --spans-layout and the "
                    "ROS graph (the bridge node, crossing.py, calibrate.py)")


class _Given:
    """The keys of one bridge mapping, each quantity once, and their values read as they were typed.

    ``vals``/``given``: quantity -> value / key as typed; ``typed``: a TOML file (numbers must be
    numbers, text must be text), else a ``key=value`` spec (every value is text).
    """

    def __init__(self, data, source, typed):
        self.vals, self.given, self.source, self.typed = {}, {}, source, typed
        self.surface = "toml" if typed else "spec"
        for key, value in data.items():
            if key not in _SPEC_KEYS:
                raise InputError(f"{source}: unknown key {key!r}; allowed {', '.join(sorted(_SPEC_KEYS))}")
            quantity = _SPEC_KEYS[key]
            if quantity in self.vals:
                raise InputError(f"{source}: {self.given[quantity]!r} and {key!r} give the same quantity twice; "
                                 f"give it once")
            if typed and key in _TEXT_KEYS and not isinstance(value, str):
                raise InputError(f"{source}.{key}: {value!r} must be text in quotes")
            self.vals[quantity], self.given[quantity] = value, key

    def __contains__(self, quantity):
        return quantity in self.vals

    def where(self, quantity):
        """The key as the messages name it (``bridge file b.toml.mu``)."""
        return f"{self.source}.{self.given[quantity]}"

    def view(self, quantity):
        """The registry's view of the key as typed (its unit: ``zeta_pct`` in %, ``zeta`` a fraction)."""
        return field_view(self.surface, self.given[quantity])

    def num(self, quantity):
        """The value of ``quantity`` checked as its key was typed (registry field, its unit)."""
        return self.view(quantity).check(self.vals[quantity], name=self.where(quantity), typed=self.typed)

    def text(self, quantity, key=None):
        """A choice (``type``, ``class``, ``damping_model``) checked against the registry's choices."""
        v = self.view(quantity) if key is None else field_view(self.surface, key)
        return v.check(str(self.vals[quantity]), name=self.where(quantity))

    def damping_ratio(self):
        """ζ (fraction) from ``zeta_pct`` (%) or ``zeta`` (fraction); None when neither is given."""
        for quantity in ("zeta_pct", "damping_ratio"):
            if quantity in self:
                return self.view(quantity).to_core(self.num(quantity))
        return None

    def refuse_conflicts(self):
        """Refuse the damping given twice, ``type`` beside ``class``, ``n0`` beside ``EJ``."""
        source = self.source
        damping = [self.given[f] for f in ("zeta_pct", "damping_ratio", "table2_type") if f in self]
        if len(damping) == 2:
            hint = (" (class=cfb|sc classes a bridge of given damping for the lower-bound functions)"
                    if "table2_type" in self else "")
            raise InputError(f"{source}: {damping[0]!r} and {damping[1]!r} both give the damping; give one{hint}")
        if len(damping) > 2:
            raise InputError(f"{source}: {', '.join(repr(d) for d in damping)} all give the damping; give one")
        if "table2_type" in self and "bridge_class" in self:
            raise InputError(f"{source}: {self.given['table2_type']!r} already classes the bridge; drop 'class'")
        if "n0_hz" in self and "EJ_Nm2" in self:
            raise InputError(f"{source}: give either n0 (Hz) or EJ (N m^2), not both")


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
    :class:`~adm_sim.errors.PlausibilityWarning`, not an error.
    """
    g = _Given(data, source, typed)
    g.refuse_conflicts()
    if "deck_spans_m" in g:
        return _deck_from_mapping(g)
    for f in ("EJ_Nm2", "mass_per_length_kg_m"):
        if f in g and (isinstance(g.vals[f], list) or (not typed and SPAN_SEPARATOR in str(g.vals[f]))):
            raise InputError(f"{g.where(f)}: {g.vals[f]!r} gives one value per span; per-span values need "
                             f"spans = [..] (m), the spans of a continuous deck")
    return _span_from_mapping(g)


def _span_from_mapping(g):
    """One simply supported span from the checked keys of :func:`bridge_from_mapping`."""
    source = g.source
    for need, what in (("span_m", "L (span, m)"), ("mass_per_length_kg_m", "mu (mass per length, kg/m)")):
        if need not in g:
            raise InputError(f"{source}: missing key {what}")
    L = g.num("span_m")
    mu = g.num("mass_per_length_kg_m")
    btype = ""
    for f in ("table2_type", "bridge_class"):
        if f in g:
            btype = g.text(f)
    zeta = g.damping_ratio()
    if zeta is None and "table2_type" in g:
        zeta = eurocode_damping_pct(L, btype) / 100.0
    elif zeta is None:
        zp, z = field_view(g.surface, "zeta_pct"), field_view(g.surface, "zeta")
        raise InputError(f"{source}: missing damping: give zeta_pct (%, {zp.lo:g}..{zp.hi:g}), zeta (fraction, "
                         f"{z.lo:g}..{z.hi:g}) or type=cfb|sc (Table 2 damping)")
    kw = dict(name=str(g.vals.get("name", "")), bridge_type=btype)
    if "n_modes" in g:
        kw["n_modes"] = g.num("n_modes")
    if "damping_model" in g:
        kw["damping_model"] = g.text("damping_model", "damping_model")
    if "n0_hz" in g:
        bridge = Bridge.from_frequency(L, g.num("n0_hz"), mu, zeta, **kw)
    elif "EJ_Nm2" in g:
        EJ = g.num("EJ_Nm2")
        n0 = math.pi / (2.0 * L**2) * math.sqrt(EJ / mu)
        if not n0_in_range(n0):
            raise InputError(f"{g.where('EJ_Nm2')}: {EJ:g} N m^2 gives n0 = {n0:.4g} Hz with L = {L:g} m and "
                             f"mu = {mu:g} kg/m (Eq. 18); allowed n0 in [{N0_RANGE_HZ[0]:g}, {N0_RANGE_HZ[1]:g}] Hz")
        bridge = Bridge(span_m=L, EJ_Nm2=EJ, mass_per_length_kg_m=mu, damping_ratio=zeta, **kw)
    else:
        raise InputError(f"{source}: missing stiffness: give n0 (Hz, {N0_RANGE_HZ[0]:g}..{N0_RANGE_HZ[1]:g}) or EJ "
                         f"(N m^2, > {FIELDS['EJ_Nm2'].lo:g})")
    check_bridge(bridge, source, 100.0 * zeta if "zeta_pct" in g else None)  # warnings, never a refusal
    return bridge


def _span_values(value, typed):
    """The numbers of a per-span key as typed: a TOML list (or one number), or ``a/b/c`` in a spec."""
    if typed:
        return list(value) if isinstance(value, list) else [value]
    return [p.strip() for p in str(value).split(SPAN_SEPARATOR)]


def _deck_spans(g):
    """The spans (m) of ``spans``, each checked, their count in the registry's range."""
    fspans, fcount = FIELDS["deck_spans_m"], FIELDS["n_spans"]
    key, shown = g.where("deck_spans_m"), g.vals["deck_spans_m"]
    raw = _span_values(shown, g.typed)
    if not raw or (g.typed and not isinstance(shown, list)):
        raise InputError(f"{key}: {shown!r} is not a list of spans; give e.g. spans = [12.0, 16.0, 12.0] (m), "
                         f"{fcount.lo}..{fcount.hi} spans each in [{fspans.lo:g}, {fspans.hi:g}] m")
    if not fcount.lo <= len(raw) <= fcount.hi:
        raise InputError(f"{key}: {len(raw)} spans is out of range; allowed {fcount.lo}..{fcount.hi} spans, "
                         f"each in [{fspans.lo:g}, {fspans.hi:g}] m")
    check = check_number if g.typed else check_range
    spans = [check(f"{key}[{i}]", v, "m", fspans.lo, fspans.hi) for i, v in enumerate(raw)]
    if "span_m" in g:
        raise InputError(f"{g.source}: {g.given['span_m']!r} and 'spans' both give the length; give L for one span "
                         f"or spans = [..] (m) for a continuous deck")
    return spans


def _one_span(g, span):
    """``spans`` of one span: the simply supported beam (sine modes, Eq. 4), as if given by ``L``."""
    data = {g.given[f]: (v[0] if isinstance(v, list) and len(v) == 1 else v) for f, v in g.vals.items()
            if f != "deck_spans_m"}
    data["L"] = span
    for k in ("EJ", "EJ_Nm2", "mu", "mu_kg_m", "mass_per_length_kg_m"):
        if not g.typed and k in data and SPAN_SEPARATOR not in str(data[k]):
            data[k] = str(data[k])
    return bridge_from_mapping(data, source=g.source, typed=g.typed)


def _per_span(g, quantity, n, what):
    """One value of ``quantity`` per span (one value given: the same for every span)."""
    ws = g.where(quantity)
    items = _span_values(g.vals[quantity], g.typed)
    if len(items) not in (1, n):
        raise InputError(f"{ws}: {len(items)} values for {n} spans; allowed one value or one per span ({what})")
    v = g.view(quantity)
    out = [v.check(x, name=ws if len(items) == 1 else f"{ws}[{i}]", typed=g.typed) for i, x in enumerate(items)]
    return out if len(out) == n else out * n


def _deck_stiffness(g, spans, mu):
    """EJ (N m^2) per span: given, or one EJ for every span from ``n0`` (omega grows as sqrt(EJ))."""
    n = len(spans)
    if "EJ_Nm2" in g:
        return _per_span(g, "EJ_Nm2", n, "N m^2")
    if "n0_hz" in g:
        n0 = g.num("n0_hz")
        f1 = float(deck_modes(spans, [1.0] * n, mu, 1).frequencies_hz[0])
        return [(n0 / f1) ** 2] * n
    raise InputError(f"{g.source}: missing stiffness: give EJ (N m^2, > {FIELDS['EJ_Nm2'].lo:g}; one value or one "
                     f"per span) or n0 (Hz, {N0_RANGE_HZ[0]:g}..{N0_RANGE_HZ[1]:g}: one EJ for every span)")


def _deck_mode_count(g, spans, EJ, mu):
    """``n_modes`` as given (a warning below the rule), else the rule of :func:`rule_mode_count`."""
    rule = rule_mode_count(spans, EJ, mu)
    if "n_modes" in g:
        n_modes = field_view("count", "n_modes").check(g.vals["n_modes"], name=g.where("n_modes"))
        if n_modes < rule:
            warnings.warn(f"{g.where('n_modes')}: {n_modes} modes is fewer than the {rule} that the rule asks for "
                          f"on this deck ({RULE_TEXT})", PlausibilityWarning, stacklevel=4)
        return n_modes
    if rule > FIELDS["deck_n_modes"].hi:
        raise InputError(f"{g.source}: the rule ({RULE_TEXT}) asks for {rule} modes of this deck; allowed at "
                         f"most {FIELDS['deck_n_modes'].hi} (give n_modes)")
    return rule


def _deck_from_mapping(g):
    """A continuous deck from the keys of :func:`bridge_from_mapping` with ``spans``."""
    spans = _deck_spans(g)
    if len(spans) == 1:
        return _one_span(g, spans[0])
    if "mass_per_length_kg_m" not in g:
        raise InputError(f"{g.source}: missing key mu (mass per length, kg/m; one value or one per span)")
    mu = _per_span(g, "mass_per_length_kg_m", len(spans), "kg/m")
    kw = dict(name=str(g.vals.get("name", "")))
    for f in ("table2_type", "bridge_class"):
        if f in g:
            kw["bridge_type"] = g.text(f)
    zeta = g.damping_ratio()
    if zeta is None and "table2_type" in g:
        pct, _, kw["damping_source"] = deck_damping_pct(spans, kw["bridge_type"])
        zeta = pct / 100.0
    elif zeta is None:
        zp = field_view(g.surface, "zeta_pct")
        raise InputError(f"{g.source}: missing damping of the continuous deck: give zeta_pct (%, {zp.lo:g}..{zp.hi:g}), "
                         f"zeta (fraction) or type=cfb|sc (EN 1991-2 Table 6.6 with L the longest span)")
    else:
        kw["damping_source"] = f"the user's value ({g.given['zeta_pct' if 'zeta_pct' in g else 'damping_ratio']})"
    if "damping_model" in g:
        kw["damping_model"] = g.text("damping_model", "damping_model")
    EJ = _deck_stiffness(g, spans, mu)
    f1 = float(deck_modes(spans, EJ, mu, 1).frequencies_hz[0])
    if not n0_in_range(f1):
        raise InputError(f"{g.source}: the deck's first frequency is {f1:.4g} Hz; allowed n0 in "
                         f"[{N0_RANGE_HZ[0]:g}, {N0_RANGE_HZ[1]:g}] Hz (check EJ and mu)")
    return Bridge.continuous(spans, EJ, mu, zeta, n_modes=_deck_mode_count(g, spans, EJ, mu), **kw)


def parse_bridge_spec(spec):
    """Parse ``"L=15,n0=8.26,mu=19042,zeta_pct=1.85"`` into a :class:`~adm_sim.model.bridge.Bridge`."""
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
