"""One registry of every user-facing value: name, unit, type, allowed range or choices, one-line doc.

Each value is a :class:`Field` in the core's unit (SI, a fraction for damping). The surfaces a user
types it on -- a TOML key, a command-line flag, a ROS 2 parameter, a ``key=value`` bridge spec --
are :class:`Spelling` s of the field: the name as typed there, its unit, and the values with a
special meaning there (``n0_hz = 0``: "from EJ_Nm2"). A spelling in another unit than the field
converts by :data:`SCALES`, the one table of unit conversions (``zeta_pct`` in % at the node and in
specs, ``damping_ratio`` a fraction in the core; axle loads in kN in train files, N in the core).

Every message about a bad value is built here (:meth:`View.check`): the name as typed, the value,
the unit and the allowed range, one line, :class:`~adm_sim.errors.InputError` (exit 2). The table of
every field and its spellings: docs/fields.md (checked against :data:`FIELDS` by tests/inputs/test_fields.py).

The checks every loader uses (:func:`check_range`, :func:`check_number`, :func:`check_int`,
:func:`check_choice`) live here too, at the top: a field's check is one of them with the field's
unit and range. Numbers and text only; no ROS, no argparse (:mod:`adm_sim.cliutil` builds the options,
:mod:`adm_sim.nodes.common` the parameter descriptors from these fields).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from adm_sim.errors import InputError
from adm_sim.limits import CHECK_MIN_SPEED_M_S, DESIGN_SPEED_FACTOR, MAX_DELTA_ZETA, TRACK_TYPES


# ---------------------------------------------------------------------- the checks
def check_range(field, value, unit, lo=None, hi=None, lo_open=False, hi_open=False, *, argument=False):
    """Return ``float(value)`` or raise :class:`InputError` naming field, value, unit and range.

    ``argument=True``: ``field`` is a function argument (the error's ``field``, shown as its flag
    on a command line).

    Parameters
    ----------
    field : str
        Name shown to the user (``"span_m"``, ``"vehicles.PC.k_p_N_m"``).
    value : object
        Value to check; must convert to a finite float.
    unit : str
        Unit shown in the message (``"m"``, ``"%"``, ``"-"``).
    lo, hi : float or None
        Bounds; ``None`` means unbounded.
    lo_open, hi_open : bool
        Whether the bound itself is excluded.
    """
    try:
        return _check_range(field, value, unit, lo, hi, lo_open, hi_open)
    except InputError as exc:
        if argument:
            exc.field = field
        raise


def _check_range(field, value, unit, lo, hi, lo_open, hi_open):
    rng = _range_text(lo, hi, lo_open, hi_open, unit)
    if isinstance(value, bool):  # a TOML/YAML true is not the number 1
        raise InputError(f"{field}: {str(value).lower()} is a boolean, not a number; allowed {rng}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{field}: {value!r} is not a number; allowed {rng}") from None
    if not math.isfinite(x):
        unit_text = "" if unit in ("", "-") else f" {unit}"  # '-' (dimensionless) after a value reads as a dash
        raise InputError(f"{field}: {value!r}{unit_text} is not finite; allowed {rng}")
    bad_lo = lo is not None and (x <= lo if lo_open else x < lo)
    bad_hi = hi is not None and (x >= hi if hi_open else x > hi)
    if bad_lo or bad_hi:
        raise InputError(f"{field}: {x:g} {unit} is out of range; allowed {rng}")
    return x


def check_number(field, value, unit, lo=None, hi=None, lo_open=False, hi_open=False):
    """:func:`check_range` for values read from a typed file (TOML): a string is refused too."""
    if isinstance(value, str):
        rng = _range_text(lo, hi, lo_open, hi_open, unit)
        raise InputError(f"{field}: {value!r} is a string, not a number (write it without quotes); allowed {rng}")
    return check_range(field, value, unit, lo, hi, lo_open, hi_open)


def check_int(field, value, lo, hi, unit=""):
    """An integer in ``[lo, hi]`` from a number or its text; booleans and fractions are refused."""
    u = f" {unit}" if unit else ""
    x = None
    if isinstance(value, int) and not isinstance(value, bool):
        x = value
    elif isinstance(value, str):
        try:
            x = int(value.strip())
        except ValueError:
            x = None
    if x is None:
        shown = str(value).lower() if isinstance(value, bool) else repr(value)
        raise InputError(f"{field}: {shown} is not an integer; allowed integer in [{lo}, {hi}]{u}")
    if not lo <= x <= hi:
        raise InputError(f"{field}: {x}{u} is out of range; allowed integer in [{lo}, {hi}]{u}")
    return x


def check_choice(field, value, allowed):
    """``value`` if it is one of the strings ``allowed``, else :class:`InputError` listing them."""
    if not isinstance(value, str) or value not in allowed:
        raise InputError(f"{field}: {value!r} is not allowed; allowed {' or '.join(repr(a) for a in allowed)}")
    return value


def _range_text(lo, hi, lo_open, hi_open, unit):
    if lo is None and hi is None:
        return "any finite value" + ("" if unit in ("", "-") else f" in {unit}")
    if hi is None:
        return f"{'>' if lo_open else '>='} {lo:g} {unit}"
    if lo is None:
        return f"{'<' if hi_open else '<='} {hi:g} {unit}"
    left = "(" if lo_open else "["
    right = ")" if hi_open else "]"
    return f"{left}{lo:g}, {hi:g}{right} {unit}"


# ---------------------------------------------------------------------- fields, spellings, views
#: The unit conversions between a field's unit and a spelling's: ``(field unit, spelling unit) ->
#: (a, b)`` with ``value in field unit = value in spelling unit * a / b`` (two exact factors, so that
#: ``pct / 100`` and ``kN * 1000`` stay the numbers they were).
SCALES = {
    ("- (fraction)", "%"): (1.0, 100.0),
    ("N", "kN"): (1000.0, 1.0),
}

#: The surfaces a value is typed on.
SURFACES = ("toml", "spec", "cli", "ros", "count")


@dataclass(frozen=True)
class Spelling:
    """How one surface spells a :class:`Field`.

    ``surface``: ``toml`` (a key of a bridge/train file), ``spec`` (a key of a ``key=value``
    bridge spec), ``cli`` (a flag), ``ros`` (a parameter). ``unit``: None for the field's own unit,
    else a unit of :data:`SCALES`. ``special``: ``((value, meaning), ...)`` accepted besides the
    range (``((0.0, "from EJ_Nm2"),)``). ``lo``/``hi``: a narrower range than the field's on this
    surface only (in the field's unit; None: the field's). ``many``: a comma list of values of
    the field (``delta_zeta_lanes``), each checked by the field.
    """

    surface: str
    key: str
    unit: str | None = None
    special: tuple = ()
    lo: float | None = None
    hi: float | None = None
    many: bool = False


@dataclass(frozen=True)
class Field:
    """One user-facing value in the core's unit.

    ``type``: ``float``, ``int``, ``str`` (with ``choices``: one of them; without: free text such
    as a train name, or a speed list whose speeds lie in ``[lo, hi]``). ``lo``/``hi``:
    the allowed range (None: unbounded); ``lo_open``/``hi_open``: the bound itself excluded.
    ``lo_text``: a lower bound set by another value, stated in words (``"-zeta"``); ``lo`` is then
    its loosest value.
    """

    name: str
    unit: str
    type: type
    doc: str
    group: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple = ()
    lo_text: str = ""
    spellings: tuple = field(default=(), compare=False)

    @property
    def range(self):
        """``(lo, hi)`` in the field's unit."""
        return (self.lo, self.hi)

    def view(self, surface=None, key=None):
        """The :class:`View` of this field as ``surface`` spells it (``key`` when it has several
        spellings there); ``surface=None``: the core's own name and unit."""
        if surface is None:
            return View(self, Spelling("core", self.name))
        hits = [s for s in self.spellings if s.surface == surface and (key is None or s.key == key)]
        if not hits:
            raise KeyError(f"{self.name}: no {surface} spelling {key or ''}".rstrip())
        return View(self, hits[0])

    def views(self):
        return [View(self, s) for s in self.spellings]

    def check(self, value, name=None, **kw):
        """``value`` checked in the core's unit (:meth:`View.check`), the message naming ``name``
        (default: the field's name)."""
        return self.view().check(value, name=name, **kw)


def _round(x):
    """A scaled bound without the binary noise of the scaling (100 * 0.2 = 20, not 20.000000000000004)."""
    return None if x is None else float(f"{x:.12g}")


@dataclass(frozen=True)
class View:
    """A :class:`Field` as one surface spells it: name, unit and range in that unit, the check."""

    field: Field
    spelling: Spelling

    @property
    def key(self):
        return self.spelling.key

    @property
    def unit(self):
        return self.spelling.unit or self.field.unit

    @property
    def factors(self):
        """``(a, b)``: value in the field's unit = value in this view's unit x a / b (:data:`SCALES`)."""
        return (1.0, 1.0) if self.unit == self.field.unit else SCALES[(self.field.unit, self.unit)]

    def _shown(self, x):
        a, b = self.factors
        return x if a == b else _round(x * b / a)

    @property
    def lo(self):
        lo = self.field.lo if self.spelling.lo is None else self.spelling.lo
        return None if lo is None else self._shown(lo)

    @property
    def hi(self):
        hi = self.field.hi if self.spelling.hi is None else self.spelling.hi
        return None if hi is None else self._shown(hi)

    @property
    def lo_open(self):
        return self.field.lo_open if self.spelling.lo is None else False

    @property
    def hi_open(self):
        return self.field.hi_open if self.spelling.hi is None else False

    @property
    def special(self):
        return self.spelling.special

    def to_core(self, x):
        """A value of this view in the field's (core) unit."""
        a, b = self.factors
        return x if a == b else x * a / b

    def from_core(self, x):
        """A value in the field's (core) unit in this view's unit (exact factors, no rounding)."""
        a, b = self.factors
        return x if a == b else x * b / a

    def range_text(self, lo=None):
        """The allowed values as the messages and the help texts state them (``[1, 150] m``,
        ``0 (from EJ_Nm2) or [0.5, 100] Hz``, ``'rayleigh' or 'modal'``, ``integer in [1, 20]``)."""
        f = self.field
        if f.choices:
            return " or ".join(repr(c) for c in f.choices)
        lo = self.lo if lo is None else lo
        if f.type is int:
            text = f"integer in [{lo}, {self.hi}]" + (f" {self.unit}" if self.unit and self.unit != "-" else "")
        elif f.type is float or (f.type is str and self.hi is not None):
            text = _range_text(lo, self.hi, self.lo_open, self.hi_open, self.unit)
        else:
            return ""
        outside = self.specials_outside(lo)
        if outside:
            text = " or ".join(f"{v:g} ({what})" for v, what in outside) + f" or {text}"
        return text

    def specials_outside(self, lo=None):
        """The special values that lie outside the range (only these widen what is allowed)."""
        lo = self.lo if lo is None else lo
        return tuple((v, w) for v, w in self.special
                     if (lo is not None and v < lo) or (self.hi is not None and v > self.hi))

    def check(self, value, name=None, lo=None, typed=False, argument=False, lo_core=None):
        """``value`` as this view's type in its unit, or :class:`InputError`: one line naming
        ``name`` (default: the spelling's key), the value, the unit and the allowed range.

        ``lo``: a lower bound set by another value (``delta_zeta >= -zeta``), in this view's unit;
        ``lo_core``: the same in the field's unit (converted here).
        ``typed``: the value comes from a typed file (TOML): a string is not a number.
        ``argument``: ``name`` is a library argument, shown as its flag on a command line.
        """
        f, name = self.field, self.key if name is None else name
        if lo_core is not None:
            lo = self.from_core(lo_core)
        if f.choices:
            return check_choice(name, value, f.choices)
        if f.type is int:
            if any(value == v and type(value) is int for v, _ in self.specials_outside()):
                return value
            return check_int(name, value, self.lo, self.hi, "" if self.unit == "-" else self.unit)
        if f.type is not float:
            return value
        if self.specials_outside() and not isinstance(value, bool):
            try:
                if any(float(value) == v for v, _ in self.specials_outside()):
                    return float(value)
            except (TypeError, ValueError):
                pass
        lo = self.lo if lo is None else lo
        try:
            if typed:
                return check_number(name, value, self.unit, lo, self.hi, self.lo_open, self.hi_open)
            return check_range(name, value, self.unit, lo, self.hi, self.lo_open, self.hi_open, argument=argument)
        except InputError as exc:
            if not self.specials_outside() or "out of range" not in str(exc):
                raise
            x = float(value)
            raise InputError(f"{name}: {x:g} {self.unit} is out of range; allowed {self.range_text(lo)}",
                             field=exc.field) from None

    def help(self, text):
        """``text`` with the unit and the allowed values of this view, for a ``--help`` line or a
        parameter description (``"span L (m, [1, 150] m)"``)."""
        rng = self.range_text()
        if self.field.lo_text and self.field.type is float:
            rng = rng.replace(f"[{self.lo:g},", f"[{self.field.lo_text},", 1)
        if rng and self.field.type is str and not self.field.choices:
            rng = f"each in {rng}"  # a list of values (speeds), each in the range
        inside = [f"{v:g} = {what}" for v, what in self.special if (v, what) not in self.specials_outside()]
        rng = "; ".join([rng] + inside) if rng else "; ".join(inside)
        return f"{text} ({rng})" if rng else text


# ---------------------------------------------------------------------- the registry
def _F(name, unit, type_, doc, group, *spellings, **kw):
    return Field(name, unit, type_, doc, group, spellings=tuple(spellings), **kw)


def _S(surface, key, unit=None, special=(), lo=None, hi=None, many=False):
    return Spelling(surface, key, unit, special, lo, hi, many)


def _toml_spec(*keys, unit=None):
    """The same key in a TOML bridge file and a ``key=value`` bridge spec."""
    return tuple(_S(s, k, unit) for k in keys for s in ("toml", "spec"))


_FIELDS = [
    # -------------------------------------------------------------- bridge (paper Section 2.1, Table 3)
    _F("span_m", "m", float, "span L", "bridge",
       *_toml_spec("L", "span_m"), _S("ros", "span_m"),
       _S("cli", "--span", lo=4.0, hi=40.0), _S("cli", "--spans", lo=4.0, hi=40.0),  # the studied spans
       lo=1.0, hi=150.0),
    _F("EJ_Nm2", "N m^2", float, "bending stiffness EJ (Eq. 18 gives n0 from it)", "bridge",
       *_toml_spec("EJ", "EJ_Nm2"), _S("ros", "EJ_Nm2", lo=1.0, hi=1.0e14),
       _S("ros", "span_EJ_Nm2", lo=1.0, hi=1.0e14, many=True), lo=0.0, lo_open=True),
    _F("n0_hz", "Hz", float, "first natural frequency n0 (EJ from Eq. 18)", "bridge",
       *_toml_spec("n0", "n0_hz"), _S("ros", "n0_hz", special=((0.0, "from EJ_Nm2"),)), lo=0.5, hi=100.0),
    _F("mass_per_length_kg_m", "kg/m", float, "mass per length mu", "bridge",
       *_toml_spec("mu", "mu_kg_m", "mass_per_length_kg_m"), _S("ros", "mu_kg_m"), _S("ros", "span_mu_kg_m", many=True),
       _S("cli", "--mu", lo=500.0, hi=100_000.0),  # recommend: the 0.5-100 t/m of the lower-bound rules
       lo=100.0, hi=1.0e6),
    _F("damping_ratio", "- (fraction)", float, "structural damping zeta", "bridge",
       *_toml_spec("zeta", "damping_ratio"), *_toml_spec("zeta_pct", unit="%"), _S("ros", "zeta_pct", "%"),
       _S("cli", "--zeta-pct", "%"),
       lo=0.0, hi=0.20),
    _F("n_modes", "-", int, "retained modes (paper: 3, Section 2.3)", "bridge",
       *_toml_spec("n_modes"), _S("cli", "--modes"), lo=1, hi=20),
    _F("deck_spans_m", "m", str, "spans of a continuous deck, left to right (TOML list; spec 12/16/12); each span",
       "bridge", *_toml_spec("spans"), _S("cli", "--deck-spans"), _S("ros", "spans_m", many=True), lo=1.0, hi=150.0),
    _F("n_spans", "spans", int, "spans of a continuous deck, pinned over the intermediate supports", "bridge",
       _S("count", "spans"), _S("cli", "--spans-layout"), lo=1, hi=6),
    _F("deck_n_modes", "-", int, "retained modes of a continuous deck (default: every mode up to 30 Hz, 1.5 n0 "
       "or the third, whichever is higher)", "bridge", _S("count", "n_modes"),
       _S("ros", "n_modes"),  # the bridge node: one range for both; one span is held to n_modes' by the node's reader
       lo=1, hi=50),
    _F("damping_model", "", str, "Rayleigh anchored at modes 1 and 3, or equal modal damping", "bridge",
       *_toml_spec("damping_model"), _S("ros", "damping_model"), choices=("rayleigh", "modal")),
    _F("bridge_type", "", str, "concrete/filler beam or steel/composite (Table 2 damping and class)", "bridge",
       *_toml_spec("type", "bridge_type", "class"), _S("cli", "--type"), choices=("cfb", "sc")),
    _F("bridge", "", str, "bridge: B1..B4, a key=value spec or a TOML file", "bridge",
       _S("cli", "--bridge"), _S("ros", "bridge")),
    # -------------------------------------------------------------- run (Sections 2.3, 3.3)
    _F("speeds_kmh", "km/h", str, "speeds: start:stop:step (stop included) or a comma list; each speed", "run",
       _S("cli", "--speeds"), _S("ros", "speeds_kmh"), lo=1.0, hi=600.0),
    _F("delta_zeta", "- (fraction)", float, "additional damping delta_zeta (zeta + delta_zeta >= 0)", "run",
       _S("cli", "--delta-zeta-pct", "%"), _S("ros", "delta_zeta"), _S("ros", "delta_zeta_lanes", many=True),
       lo=-MAX_DELTA_ZETA, hi=MAX_DELTA_ZETA, lo_text="-zeta"),
    _F("steps_per_period", "steps", float, "RK4 steps per period of the highest bridge mode", "run",
       _S("cli", "--steps-per-period"), _S("ros", "steps_per_period"), lo=4.0, hi=10000.0),
    _F("free_vibration_periods", "periods", float, "fundamental periods simulated after the last axle left",
       "run", _S("ros", "free_vibration_periods"), lo=0.0, hi=100.0),
    _F("ds_m", "m", float, "train advance per step", "run",
       _S("ros", "ds_m", special=((0.0, "from steps_per_period"),)), lo=1e-5, hi=10.0),
    _F("model", "", str, "train model: Moving Load Model or Detailed Interaction Model", "run",
       _S("cli", "--model"), _S("ros", "model"), choices=("mlm", "dim")),
    _F("dim_grid", "", str, "DIM speeds: paper (5 km/h + 1 km/h near the MLM peak), window (the paper's speeds near the association window) or full (every MLM speed)",
       "run", _S("cli", "--dim-grid"), _S("ros", "dim_grid"), choices=("paper", "window", "full")),
    _F("track_type", "", str, "deck acceleration limit, EN 1990 A2.4.4.2.1(4)P", "run",
       _S("cli", "--track"), _S("ros", "track_type"), choices=TRACK_TYPES),
    _F("train", "", str, "train: a name or a TOML train file", "run", _S("cli", "--train"), _S("ros", "train")),
    _F("mlm_block_steps", "steps", int, "MLM: steps per axle-position block", "run",
       _S("ros", "mlm_block_steps"), lo=1, hi=10_000_000),
    _F("partner_timeout_s", "s", float, "error when the partner node sends nothing for this long during a run",
       "run", _S("ros", "partner_timeout_s"), lo=0.5, hi=600.0),
    _F("run_timeout_s", "s", float, "longest a single run may take", "run", _S("ros", "run_timeout_s"),
       lo=1.0, hi=86400.0),
    _F("wait_clients", "", int, "before the first run, wait until this many clients opted into the flow "
       "control (publishers of /adm/run/ack beside the run's own recorder)", "run",
       _S("ros", "wait_clients"), _S("cli", "--wait-clients"), lo=0, hi=100),
    _F("max_line_speed_kmh", "km/h", float, f"maximum line speed V of the EN 1991-2 check "
       f"({CHECK_MIN_SPEED_M_S:g} m/s up to {DESIGN_SPEED_FACTOR:g} V)",
       "run", _S("cli", "--max-line-speed"), lo=3.6 * CHECK_MIN_SPEED_M_S, hi=500.0, lo_open=True),
    _F("step_kmh", "km/h", float, "speed step of the EN 1991-2 check", "run", _S("cli", "--speed-step"),
       lo=0.0, hi=1.0, lo_open=True),
    _F("trains", "", str, "trains of the EN 1991-2 check: hslm, HSLM-Ak, train names or TOML train files, "
       "comma separated", "run", _S("cli", "--trains")),
    _F("damping", "", str, "additional damping of the EN 1991-2 check: EN 1991-2 6.4.6.3.1 (adm), the paper's "
       "lower bounds (lb) or the calibrated VBI (vbi); lb and vbi: adm-calib check only", "run",
       _S("cli", "--damping"), choices=("none", "adm", "lb", "vbi")),
    _F("track_maintenance", "", str, "EN 1991-2 6.4.5.2 track maintenance of the LM71 dynamic factor: careful "
       "(Phi2) or standard (Phi3)", "run", _S("cli", "--track-maintenance")),
    _F("alpha", "-", str, "LM71 classification factor alpha, one of EN 1991-2 6.3.2(3)", "run", _S("cli", "--alpha")),
    _F("response_m", "m", float, "where the bridge node takes its midspan topics and a run's maxima, from the left "
       "abutment (0 < x < L, the deck's length)", "run", _S("ros", "response_m", special=((0.0, "midspan"),)),
       lo=0.001, hi=900.0),
    _F("where", "", str, "where the acceleration is taken: deck, midspan or x=<m> with 0 < x < L", "run",
       _S("cli", "--where")),
    _F("scheduler", "", str, "address of a running dask scheduler on this machine (tcp://127.0.0.1:PORT)", "run",
       _S("cli", "--scheduler")),
    _F("jobs", "processes", int, "worker processes of table4", "run", _S("cli", "--jobs"), lo=1, hi=64),
    _F("workers", "processes", int, "worker processes of the local study cluster", "run", _S("cli", "--workers"),
       lo=1, hi=64),
    _F("freq_index", "-", int, "n0 of a span in the study: 1 = LB ... 3 = fit ... 5 = UB power law (Section 3.1.1)",
       "run", _S("cli", "--freq-index"), lo=1, hi=5),
    _F("limit", "cases", int, "run at most this many of the pending study cases", "run", _S("cli", "--limit"),
       lo=1, hi=1_000_000),
    _F("domain_id", "", int, "ROS_DOMAIN_ID (up to 232 with shared memory only, 101 with UDP: Fast DDS ports)",
       "run", _S("cli", "--domain-id"), lo=0, hi=232),
    # -------------------------------------------------------------- monitoring and outputs (ROS)
    _F("warn_fraction", "-", float, "diagnostics WARN above this fraction of the acceleration limit", "outputs",
       _S("ros", "warn_fraction"), lo=0.0, hi=1.0),
    _F("monitor_speed_kmh", "km/h", float, "lane shown on the monitoring topics: nearest speed", "outputs",
       _S("ros", "monitor_speed_kmh", special=((0.0, "first lane"),)), lo=0.0, hi=600.0),
    _F("monitor_every_steps", "steps", int, "decimation of the acceleration monitor (every n-th step)", "outputs",
       _S("ros", "monitor_every_steps", special=((0, "auto"),)), lo=0, hi=1_000_000),
    _F("beam_every_steps", "steps", int, "decimation of the beam and clock topics", "outputs",
       _S("ros", "beam_every_steps", special=((0, "auto"),)), lo=0, hi=1_000_000),
    _F("beam_points", "-", int, "points along the span on the beam topic", "outputs",
       _S("ros", "beam_points"), lo=2, hi=1000),
    _F("chunk_size", "B", int, "MCAP chunk size (loss bound of a killed recorder)", "outputs",
       _S("ros", "chunk_size"), lo=1024, hi=1 << 26),
    # -------------------------------------------------------------- replay (launch_scripts/replay.py)
    _F("exaggeration", "x", float, "display factor on beam deflections", "replay",
       _S("cli", "--exaggeration"), lo=0.0, hi=1e6, lo_open=True),
    _F("rate", "x simulated time", float, "republish speed, multiples of simulated time", "replay",
       _S("cli", "--rate", special=((0.0, "as fast as possible"),)), lo=0.0, hi=1e6),
    _F("wait_subscribers_s", "s", float, "wait up to this long until every republished topic has a subscriber",
       "replay",
       _S("cli", "--wait-subscribers"), lo=0.0, hi=3600.0),
    # -------------------------------------------------------------- monitor (monitor node, launch_scripts/monitor.py)
    _F("topic_timeout_s", "s", float, "error when no publisher offers the monitored topic for this long", "monitor",
       _S("ros", "topic_timeout_s"), _S("cli", "--timeout"), lo=0.1, hi=3600.0),
    _F("settle_s", "s", float, "a run's passage completes this long after its done record when no later "
       "sample came", "monitor", _S("ros", "settle_s"), lo=0.0, hi=600.0),
    _F("quiet_s", "s", float, "without run records, a passage completes after this much quiet signal", "monitor",
       _S("ros", "quiet_s"), lo=0.0, hi=3600.0),
    _F("min_cycles", "periods", float, "free decay needed to identify damping", "monitor",
       _S("ros", "min_cycles"), _S("cli", "--min-cycles"), lo=2.0, hi=1000.0),
    _F("passages", "-", int, "stop after this many passages (live)", "monitor", _S("cli", "--passages"),
       lo=1, hi=1_000_000),
    _F("duration_s", "s", float, "stop after this long (live)", "monitor", _S("cli", "--duration"), lo=0.1, hi=1e7),
    # -------------------------------------------------------------- vehicle (train files, Appendix A)
    _F("m_c_kg", "kg", float, "car body mass", "vehicle", _S("toml", "m_c_kg"), lo=1.0, hi=5.0e5),
    _F("J_c_kgm2", "kg m^2", float, "car body pitch inertia", "vehicle", _S("toml", "J_c_kgm2"), lo=1.0, hi=1.0e8),
    _F("m_b_kg", "kg", float, "bogie mass", "vehicle", _S("toml", "m_b_kg"), lo=1.0, hi=1.0e5),
    _F("J_b_kgm2", "kg m^2", float, "bogie pitch inertia", "vehicle", _S("toml", "J_b_kgm2"), lo=1.0, hi=1.0e6),
    _F("m_w_kg", "kg", float, "wheelset mass", "vehicle", _S("toml", "m_w_kg"), _S("toml", "wheelsets.mass_kg"),
       lo=0.0, hi=1.0e4),
    _F("k_s_N_m", "N/m", float, "secondary suspension stiffness", "vehicle", _S("toml", "k_s_N_m"), lo=1.0, hi=1.0e10),
    _F("c_s_Ns_m", "N s/m", float, "secondary suspension damping", "vehicle", _S("toml", "c_s_Ns_m"),
       lo=0.0, hi=1.0e8),
    _F("k_p_N_m", "N/m", float, "primary suspension stiffness", "vehicle", _S("toml", "k_p_N_m"), lo=1.0, hi=1.0e10),
    _F("c_p_Ns_m", "N s/m", float, "primary suspension damping", "vehicle", _S("toml", "c_p_Ns_m"),
       lo=0.0, hi=1.0e8),
    _F("d_m", "m", float, "vehicle length", "vehicle", _S("toml", "d_m"), lo=1.0, hi=60.0),
    _F("r_m", "m", float, "bogie pivot distance (optional)", "vehicle", _S("toml", "r_m"), lo=0.5, hi=60.0),
    _F("b_m", "m", float, "bogie wheelbase", "vehicle", _S("toml", "b_m"), lo=0.5, hi=10.0),
    _F("axle_load_n", "N", float, "static axle load (one value or [front, rear])", "vehicle",
       _S("toml", "axle_load_kN", "kN"), _S("toml", "axle_loads_kN", "kN"),
       _S("toml", "wheelsets.static_load_kN", "kN"), lo=1000.0, hi=500_000.0),
    _F("count", "-", int, "vehicles of one composition entry", "vehicle", _S("toml", "count"), lo=1, hi=100),
    # -------------------------------------------------------------- vehicle file (bodies, wheelsets, stages)
    _F("vehicle_length_m", "m", float, "vehicle length, coupler to coupler (vehicle file)", "vehicle",
       _S("toml", "length_m"), lo=0.0, hi=1000.0),
    _F("body_mass_kg", "kg", float, "mass of a body: car body, bogie, ... (vehicle file)", "vehicle",
       _S("toml", "bodies.mass_kg"), lo=1.0, hi=5.0e5),
    _F("body_pitch_inertia_kgm2", "kg m^2", float, "pitch inertia of a body about its centre of gravity "
       "(vehicle file; omitted: the body does not pitch)", "vehicle", _S("toml", "bodies.pitch_inertia_kgm2"),
       lo=1.0, hi=1.0e8),
    _F("vehicle_x_m", "m", float, "position behind the vehicle's front end: a body's centre of gravity, a "
       "wheelset, a stage (vehicle file)", "vehicle",
       _S("toml", "bodies.x_m"), _S("toml", "wheelsets.x_m"), _S("toml", "stages.x_m"), lo=-100.0, hi=1000.0),
    _F("stage_k_N_m", "N/m", float, "stiffness of a spring-damper stage (vehicle file)", "vehicle",
       _S("toml", "stages.k_N_m"), lo=1.0, hi=1.0e10),
    _F("stage_c_Ns_m", "N s/m", float, "damping of a spring-damper stage (vehicle file)", "vehicle",
       _S("toml", "stages.c_Ns_m"), lo=0.0, hi=1.0e8),
    # -------------------------------------------------------------- bounded work (sizes of one run)
    _F("n_speeds", "speeds", int, "speeds of one run or check: a --speeds grid or list, the check's grid from "
       "--speed-step (memory and time grow with it)", "limits",
       _S("count", "--speeds"), _S("count", "speeds"), _S("count", "--speed-step"), lo=1, hi=20_000),
    _F("n_lanes", "lanes", int, "lanes of one run: speeds x additional dampings (the train node's speeds_kmh)",
       "limits", _S("count", "speeds_kmh"), lo=1, hi=20_000),
    _F("n_trains", "trains", int, "trains of one check (--trains; hslm counts 10)", "limits",
       _S("count", "--trains"), lo=1, hi=40),
    _F("n_axles", "axles", int, "axles of one train (train file composition)", "limits",
       _S("count", "axles"), lo=1, hi=400),
    _F("train_length_m", "m", float, "length of one train, first to last axle (train file composition)", "limits",
       _S("count", "train length"), lo=0.0, hi=1000.0),
]

#: Every field, by its core name.
FIELDS = {f.name: f for f in _FIELDS}
#: The groups, in the order of docs/fields.md.
GROUPS = ("bridge", "run", "outputs", "replay", "monitor", "vehicle", "limits")
#: Vehicle-type fields of a train file, in the order of the file format (``r_m`` optional).
VEHICLE_FIELDS = ("m_c_kg", "J_c_kgm2", "m_b_kg", "J_b_kgm2", "m_w_kg", "k_s_N_m", "c_s_Ns_m", "k_p_N_m",
                  "c_p_Ns_m", "d_m", "r_m", "b_m")
VEHICLE_OPTIONAL = ("r_m",)

# ---------------------------------------------------------------------- train files: keys and tolerances
# One reader takes both forms of a train file (:mod:`adm_sim.inputs.train_files`): vehicle types of
# Table A1 (``[vehicle_types.<NAME>]``) or vehicles of bodies, wheelsets and stages (``[vehicles.<NAME>]``).
#: Top-level keys of a train file, by the table of its form.
TRAIN_FILE_KEYS = {table: ("name", "description", "source", "paper_train", table, "composition",
                           "loads_differ_from_masses") for table in ("vehicle_types", "vehicles")}
#: Keys of a ``[[composition]]`` entry, by form and kind of entry.
COMPOSITION_KEYS = {"vehicle_types": {"vehicle": ("vehicle", "count"),
                                      "jacobs_set": ("jacobs_set", "bogies", "axle_loads_kN", "reversed")},
                    "vehicles": {"vehicle": ("vehicle", "count", "reversed")}}
#: Keys of a ``[vehicles.<NAME>]`` table.
VEHICLE_KEYS = ("length_m", "bodies", "wheelsets", "stages")
#: Keys of the tables of a vehicle: ``(key, toml spelling of its field or None for a name, required)``.
VEHICLE_TABLE_KEYS = {
    "bodies": (("name", None, True), ("mass_kg", "bodies.mass_kg", True),
               ("pitch_inertia_kgm2", "bodies.pitch_inertia_kgm2", False), ("x_m", "bodies.x_m", True)),
    "wheelsets": (("name", None, True), ("mass_kg", "wheelsets.mass_kg", True), ("x_m", "wheelsets.x_m", True),
                  ("static_load_kN", "wheelsets.static_load_kN", False)),
    "stages": (("upper", None, True), ("lower", None, True), ("x_m", "stages.x_m", True),
               ("k_N_m", "stages.k_N_m", True), ("c_Ns_m", "stages.c_Ns_m", True)),
}
#: Largest relative difference between axle loads and the masses they carry times g (both forms;
#: ``loads_differ_from_masses = true`` lifts it).
AXLE_LOAD_REL_TOL = 0.005


#: ``(surface, key) -> View``: every spelling once (a key is spelled by one field per surface, tested)
_VIEWS = {(s.surface, s.key): View(f, s) for f in _FIELDS for s in f.spellings}


def view(surface, key):
    """The :class:`View` a surface spells ``key`` (``view("ros", "zeta_pct")``), or KeyError."""
    try:
        return _VIEWS[surface, key]
    except KeyError:
        raise KeyError(f"no {surface} spelling {key!r} in the field registry") from None


def spellings(surface):
    """``{key: View}`` of every spelling on ``surface``."""
    return {k: v for (s, k), v in _VIEWS.items() if s == surface}


def core(name):
    """The core's view of field ``name`` (its own name and unit)."""
    return FIELDS[name].view()


def argument_flag(name):
    """The command-line flag of library argument ``name`` (an :class:`~adm_sim.errors.InputError`'s
    ``field``): the one ``cli`` spelling of the field of that name; None when there is no such field
    or it has no single flag. Library messages name the argument (``max_line_speed_kmh: ...``), the
    command line shows the flag the user typed (:func:`adm_sim.cliutil.cli_message`)."""
    f = FIELDS.get(name) if isinstance(name, str) else None
    flags = [s.key for s in f.spellings if s.surface == "cli"] if f is not None else []
    return flags[0] if len(flags) == 1 else None


def count_text(n):
    """A count for a message: exact below a billion, then 3 significant digits (``9.6e+301``, never
    a 300-digit number)."""
    if abs(n) >= 1_000_000_000:
        return f"{n:.3g}"
    return f"{n:g}" if isinstance(n, float) else f"{n}"


def check_count(name, n, where, given):
    """``n``, a size of one run's input (field ``name`` of group ``limits``), or :class:`InputError`
    refusing it up front, one line naming ``where`` (the flag, parameter or file the user typed),
    what was ``given`` there and the limit (``--speed-step: 0.0001 km/h gives 4560001 speeds;
    allowed at most 20000 speeds (speeds of one run or check; bounded work)``)."""
    f = FIELDS[name]
    if not f.lo <= n <= f.hi:
        shown = count_text(n)
        what = f.doc.split(":")[0].split(" (")[0]
        raise InputError(f"{where}: {given} gives {shown} {f.unit}; allowed at most {f.hi:g} {f.unit} "
                         f"({what}; bounded work)", field=where)
    return n


def delta_zeta_view(name):
    """The :class:`View` of the additional damping Δζ as a caller names it: a spelling of field
    ``delta_zeta`` (``--delta-zeta-pct`` in %, the ROS parameters ``delta_zeta`` and
    ``delta_zeta_lanes`` as fractions), else the core's own (a fraction, library argument ``delta_zeta``)."""
    f = FIELDS["delta_zeta"]
    hits = [s for s in f.spellings if s.key == name]
    return View(f, hits[0]) if hits else f.view()


def check_delta_zeta(field, value, damping_ratio, *, pct=None, positive_for=None, remedy=""):
    """``float(value)``, an additional damping Δζ in the unit of ``field`` (:func:`delta_zeta_view`:
    ``--delta-zeta-pct`` in %, anything else a fraction; ``pct`` forces % or a fraction), or
    :class:`InputError` naming ``field``: the one check of the Δζ sign rule.

    Δζ lies in the registry's ``[-ζ, 0.2]`` (``[-100 ζ, 20] %``): total damping ζ + Δζ >= 0.
    ``positive_for``: what needs ζ + Δζ > 0 (the exact envelope divides by the damping at
    resonance), e.g. ``"the exact MLM envelope"``; then Δζ = -ζ is refused too, in the one text
    ``<field>: zeta + delta_zeta = 0 %; <positive_for> needs damping > 0 % (allowed <field> > -1.85 %<remedy>)``.
    ``damping_ratio`` is the bridge's ζ (fraction).
    """
    if pct is None:
        v = delta_zeta_view(field)
    else:
        v = view("cli", "--delta-zeta-pct") if pct else FIELDS["delta_zeta"].view()
    x = v.check(value, name=field, lo_core=-damping_ratio)
    total = damping_ratio + v.to_core(x)
    if positive_for is not None and total <= 0.0:
        raise InputError(f"{field}: zeta + delta_zeta = {100 * total:g} %; {positive_for} needs damping > 0 % "
                         f"(allowed {field} > {v.from_core(-damping_ratio) + 0.0:g} {v.unit}{remedy})")  # + 0.0: no "-0"
    return x


def check_delta_zeta_pct(field, value_pct, damping_ratio, **kw):
    """:func:`check_delta_zeta` of a Δζ in %: ``float(value_pct)`` in ``[-100 ζ, 20] %``."""
    return check_delta_zeta(field, value_pct, damping_ratio, pct=True, **kw)


def check_delta_zeta_fraction(name, delta_zeta, damping_ratio, **kw):
    """A Δζ given as a fraction (the core's unit) checked as the caller names it (``name``): in % for
    ``--delta-zeta-pct`` (``0.5`` is refused as ``50 %``), a fraction for ``delta_zeta``
    (:func:`delta_zeta_view`). Returns ``delta_zeta`` itself (no unit round trip), keywords as
    :func:`check_delta_zeta`. The one check of a sweep's Δζ (:func:`adm_sim.integrate.sweep.lane_damping`)."""
    v = delta_zeta_view(name)
    check_delta_zeta(name, v.from_core(delta_zeta), damping_ratio, **kw)
    return delta_zeta


__all__ = ["check_range", "check_number", "check_int", "check_choice", "check_count", "check_delta_zeta", "check_delta_zeta_pct",
           "check_delta_zeta_fraction", "delta_zeta_view",
           "SCALES", "SURFACES", "Spelling", "Field", "View", "FIELDS", "GROUPS", "VEHICLE_FIELDS",
           "VEHICLE_OPTIONAL", "TRAIN_FILE_KEYS", "COMPOSITION_KEYS", "VEHICLE_KEYS", "VEHICLE_TABLE_KEYS",
           "AXLE_LOAD_REL_TOL", "view", "spellings", "core", "argument_flag"]
