"""Parameters of the adm-sim nodes, free of ROS: specs, params-file checks, parameter -> model.

Everything a launcher checks before it starts a node (:mod:`launch_scripts._supervisor`) lives
here, so that a launcher never imports a node module (nor rclpy): the parameter specs of the
bridge, train and driver nodes (:class:`ParamSpec`, units and ranges from the field registry
:mod:`adm_sim.fields`), the mapping of the bridge node's parameters to a
:class:`adm_sim.model.bridge.Bridge` (:func:`bridge_from_params`) and of the train node's to a train and
its speed lanes (:func:`validate_train`), and the check of a ROS 2 params YAML
(:func:`check_params_file`). The nodes declare these specs (:mod:`adm_sim.nodes.common`); only
:meth:`ParamSpec.descriptor` touches rclpy's interfaces, and only a node calls it. A test asserts
that importing this module leaves ``rclpy`` out.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from pathlib import Path

import numpy as np
import yaml

from adm_sim import fields
from adm_sim import protocol as P
from adm_sim.model.bridge import Bridge
from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.files import read_text, refuse_special
from adm_sim.fields import check_delta_zeta, check_range, view
from adm_sim.limits import ACC_LIMITS_M_S2, DEFAULT_SPEEDS, check_track_type
from adm_sim.model.plausibility import check_bridge
from adm_sim.model.spans import RULE_TEXT, deck_modes, rule_mode_count
from adm_sim.integrate.run_contract import check_model
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.inputs.bridges import N0_RANGE_HZ, check_n0, resolve_bridge
from adm_sim.inputs.speeds import parse_speeds
from adm_sim.inputs.train_files import load_train

#: Automatic monitoring decimation: at least this many samples per period of the highest retained
#: mode, in the monitored lane's time.
MONITOR_SAMPLES_PER_PERIOD = 8




class ParamSpec:
    """One declared parameter: default, unit, range and description; a thin view of its field in
    the registry (:mod:`adm_sim.fields`) when the registry spells it as a ROS parameter
    (:func:`param`), so unit, range, special values and the check come from there.

    The range is checked by :meth:`check` (the registry's :meth:`adm_sim.fields.View.check`, or the
    core's :func:`adm_sim.errors.check_range` for a parameter outside the registry) in an
    on-set parameter callback, not by a ``FloatingPointRange`` in the descriptor: rclpy applies
    descriptor ranges before any callback with a reason that has no unit, and several ranges are
    not one interval (``n0_hz``: 0 or [0.5, 100]; ``delta_zeta``: [-zeta, 0.2]). The descriptor
    carries the unit in its description and the range as text in ``additional_constraints``.
    """

    def __init__(self, name, default, unit, description, lo=None, hi=None, read_only=False, view=None):
        self.name, self.default, self.unit = name, default, unit
        self.description, self.lo, self.hi, self.read_only = description, lo, hi, read_only
        self.view = view

    def descriptor(self):
        """The ``rcl_interfaces/ParameterDescriptor`` (imports rclpy's interfaces: only a node calls it)."""
        from rcl_interfaces.msg import ParameterDescriptor, ParameterType  # noqa: PLC0415  the module stays ROS-free: only a node calls this

        typ = {float: ParameterType.PARAMETER_DOUBLE, int: ParameterType.PARAMETER_INTEGER,
               str: ParameterType.PARAMETER_STRING, bool: ParameterType.PARAMETER_BOOL}[type(self.default)]
        d = ParameterDescriptor(name=self.name, type=typ, read_only=self.read_only,
                                description=f"{self.description} [{self.unit}]" if self.unit else self.description)
        d.additional_constraints = "" if self.lo is None else f"{self.lo:g} <= {self.name} <= {self.hi:g} {self.unit}".strip()
        if self.view is not None and self.view.specials_outside() and self.lo is not None:
            d.additional_constraints = " or ".join(f"{self.name} = {v:g} ({what})"
                                                   for v, what in self.view.specials_outside()) + \
                f" or {d.additional_constraints}"
        return d

    def check(self, value):
        """Raise :class:`InputError` naming the parameter, value, unit and range when out of range
        (or not one of the choices)."""
        if self.view is not None:
            if self.view.spelling.many:  # a comma list of values, each checked by the node
                return
            self.view.check(value, name=self.name)
        elif self.lo is not None:
            check_range(self.name, value, self.unit or "-", self.lo, self.hi)


def param(name, default, description=None, read_only=False):
    """The :class:`ParamSpec` of ROS parameter ``name`` from the field registry (unit, range,
    special values, check); ``description`` replaces the field's doc where the node says more."""

    v = fields.view("ros", name)
    lo, hi = (None, None) if v.field.type is str or v.spelling.many else (v.lo, v.hi)
    return ParamSpec(name, default, v.unit, description or v.field.doc, lo, hi, read_only, view=v)


def _unique_key_loader():
    """A ``yaml.SafeLoader`` that refuses a key given twice in one mapping (plain YAML keeps the
    last value silently)."""

    class UniqueKeyLoader(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):
            seen = {}
            for key_node, _value in node.value:
                key = self.construct_object(key_node, deep=deep)
                try:
                    hash(key)
                except TypeError:
                    continue  # the base class reports unhashable keys
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"key {key!r} is given twice (lines {seen[key] + 1} and "
                                    f"{key_node.start_mark.line + 1}); give it once", key_node.start_mark)
                seen[key] = key_node.start_mark.line
            return super().construct_mapping(node, deep=deep)

    return UniqueKeyLoader


def load_params_yaml(path):
    """The parsed params YAML ``path``; :class:`InputError` naming the file (and the line) when it
    cannot be read, is not a regular file, is not valid YAML or gives a key twice."""



    where = f"--params-file {str(path)!r}"
    refuse_special(path, where)
    text = read_text(Path(path), "--params-file")  # not UTF-8 (a binary file): one line
    try:
        return yaml.load(text, Loader=_unique_key_loader())  # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise InputError(f"{where}: not valid YAML{at} ({getattr(exc, 'problem', None) or exc})") from None


#: Parameters every rclpy node declares itself (allowed in params files).
RCLPY_PARAMETERS = {"use_sim_time": bool, "start_type_description_service": bool}


def check_params_file(path, specs_by_node, extra_checks=None):
    """Check a ROS 2 params YAML before any node starts; raise :class:`InputError` (one line
    naming the file, the node and the key) on the first problem.

    Parameters
    ----------
    path : path-like
        The params file (``<node>: {ros__parameters: {name: value}}``; ``/**`` for every node).
    specs_by_node : dict
        ``node name -> list of ParamSpec`` of the nodes the launch starts.
    extra_checks : dict or None
        ``(node, name) -> callable(value)`` raising :class:`InputError` (e.g. the bridge preset,
        the train name, the speeds).

    Returns
    -------
    dict
        ``node -> {name: value}`` as the file gives them (``/**`` merged into every node).
    """
    where = f"--params-file {str(path)!r}"
    doc = load_params_yaml(path)
    if not isinstance(doc, dict) or not doc:
        raise InputError(f"{where}: expected '<node>: {{ros__parameters: {{name: value}}}}' entries, got {doc!r}")
    nodes = sorted(specs_by_node)
    values = {n: {} for n in nodes}
    for node, body in doc.items():
        if node not in specs_by_node and node != "/**":
            raise InputError(f"{where}: {node!r} is not a node of this launch; allowed {', '.join(nodes)} or '/**'")
        if not isinstance(body, dict) or set(body) != {"ros__parameters"} or not isinstance(body["ros__parameters"], dict):
            raise InputError(f"{where}: {node}: expected exactly one key 'ros__parameters' holding 'name: value' "
                             f"entries, got {body!r}")
        targets = nodes if node == "/**" else [node]
        for name, value in body["ros__parameters"].items():
            key = f"{node}.ros__parameters.{name}"
            owners = [n for n in targets if any(s.name == name for s in specs_by_node[n])]
            if not owners and name not in RCLPY_PARAMETERS:
                known = sorted({s.name for n in targets for s in specs_by_node[n]} | set(RCLPY_PARAMETERS))
                raise InputError(f"{where}: {key}: unknown parameter; allowed {', '.join(known)}")
            for n in owners:
                spec = next(s for s in specs_by_node[n] if s.name == name)
                want = type(spec.default)
                if type(value) is not want:  # rclpy refuses 15 for a double and '15' for an int
                    hint = " (quote text values)" if want is str else (" (write 15.0, not 15)" if want is float else "")
                    raise InputError(f"{where}: {key}: {value!r} is a {type(value).__name__}; expected a "
                                     f"{want.__name__}{hint}{f' in {spec.unit}' if spec.unit else ''}")
                try:
                    spec.check(value)
                    if extra_checks and (n, name) in extra_checks:
                        extra_checks[(n, name)](value)
                except InputError as exc:
                    raise InputError(f"{where}: {node}: {exc}") from None
                values[n][name] = value
            if name in RCLPY_PARAMETERS and type(value) is not RCLPY_PARAMETERS[name]:
                raise InputError(f"{where}: {key}: {value!r} is not a boolean; expected true or false")
    return values


def namespaced_params(path, namespace, dst):
    """Write ``dst``: the params file ``path`` (checked, keyed by bare node names and ``/**``) with
    every bare node name keyed by its name in ``namespace`` (``bridge`` -> ``/b3/bridge``), so that
    rcl applies each section to the namespaced node (it matches a section by the node's fully
    qualified name: a bare ``bridge`` is ``/bridge`` and would be ignored). Returns ``dst``."""
    doc = load_params_yaml(path)
    ns = namespace.rstrip("/")
    out = {(k if k.startswith("/") else f"{ns}/{k}"): v for k, v in doc.items()}
    dst.write_text(yaml.safe_dump(out, sort_keys=False))
    return dst


def unapplied_sections(doc, fqn):
    """The sections of a params file (``doc``) that name node ``fqn``'s own name (its last token)
    while rcl applies none of them to it: a bare ``bridge`` (rcl reads ``/bridge``) or
    ``/b1/bridge`` for the node ``/b3/bridge``. Empty when a section does apply to ``fqn`` (its
    exact name, or a pattern of ``*``/``**`` that matches it, as rcl matches) or none names it."""

    if not isinstance(doc, dict):
        return []
    base = fqn.rsplit("/", 1)[-1]

    def key_re(key):
        k = key if key.startswith("/") else "/" + key
        out = ""
        for part in re.split(r"(/\*\*|\*)", k):
            out += "(/[^/]+)*" if part == "/**" else "[^/]*" if part == "*" else re.escape(part)
        return re.compile(out)

    applied = [k for k in doc if isinstance(k, str) and k.rsplit("/", 1)[-1] != "**" and key_re(k).fullmatch(fqn)]
    named = [k for k in doc if isinstance(k, str) and "*" not in k and k.rsplit("/", 1)[-1] == base
             and not key_re(k).fullmatch(fqn)]
    return [] if applied else named


def parse_float_list(field, text, unit):
    """Floats from a comma list (``"0.001,0.002"``); empty text gives an empty array."""
    parts = [p.strip() for p in str(text).split(",") if p.strip()]
    try:
        return np.array([float(p) for p in parts], dtype=float)
    except ValueError:
        raise InputError(f"{field}: {text!r} is not a comma list of numbers ({unit})") from None


def format_float_list(values):
    """Comma list of floats that parses back exactly (``repr``)."""
    return ",".join(repr(float(x)) for x in np.atleast_1d(values))


def step_options(p):
    """The :class:`StepOptions` of the bridge node's parameter values ``p``."""
    return StepOptions(steps_per_period=p["steps_per_period"], free_vibration_periods=p["free_vibration_periods"],
                       ds_m=p["ds_m"] if p["ds_m"] > 0.0 else None)


def bridge_preset(text):
    """The bridge node's preset of parameter ``bridge`` (:func:`adm_sim.inputs.bridges.resolve_bridge`: a
    Table 3 name, a spec or a TOML file, a continuous deck included); raises :class:`InputError`
    (one line) for what it refuses and for a deck of more modes than the node's ``n_modes`` takes."""
    preset = resolve_bridge(text, continuous=True)
    n = fields.view("ros", "n_modes")
    if preset.n_modes > n.hi:
        raise InputError(f"bridge: {text!r} keeps {preset.n_modes} modes; the bridge node takes n_modes in "
                         f"[{n.lo}, {n.hi}] (give n_modes={n.hi} or fewer in the bridge; the rule: {RULE_TEXT})",
                         field="bridge")
    return preset


def bridge_specs(preset):
    """Parameter specs of the bridge node; numeric defaults from the preset bridge."""
    S = param

    def per_span(values):
        return format_float_list(values) if preset.is_continuous else ""

    return [
        S("span_m", float(max(preset.spans_m) if preset.is_continuous else preset.span_m),
          "span L of one simply supported span (spans_m empty; a deck preset: its longest span)"),
        S("spans_m", per_span(preset.spans_m), "spans of a continuous deck, left to right, comma list of 2 to "
          f"{fields.FIELDS['n_spans'].hi} spans (one value: the simply supported span of that length); empty = one "
          "span of span_m"),
        S("EJ_Nm2", float(preset.EJ_Nm2), "bending stiffness EJ (used when n0_hz is 0; a deck: of every span "
          "when span_EJ_Nm2 is empty)"),
        S("span_EJ_Nm2", per_span(preset.span_EJ_Nm2), "EJ of each span of the deck (spans_m), one value or one per "
          "span (used when n0_hz is 0); empty = EJ_Nm2"),
        S("n0_hz", 0.0, "first natural frequency n0; 0 = from EJ_Nm2, else EJ from Eq. (18) (a deck: one EJ for "
          "every span that gives the deck's first frequency n0)"),
        S("mu_kg_m", float(preset.mass_per_length_kg_m), "mass per length mu (a deck: of every span when "
          "span_mu_kg_m is empty)"),
        S("span_mu_kg_m", per_span(preset.span_mu_kg_m), "mu of each span of the deck (spans_m), one value or one "
          "per span; empty = mu_kg_m"),
        S("zeta_pct", view("ros", "zeta_pct").from_core(preset.damping_ratio)),
        S("n_modes", int(preset.n_modes), "retained modes (paper: 3, Section 2.3; one simply supported span: "
          f"{fields.FIELDS['n_modes'].view().range_text()}; a continuous deck: fewer than its rule asks for gives a "
          "warning)"),
        S("damping_model", preset.damping_model, "rayleigh (modes 1 and 3) | modal"),
        S("response_m", 0.0, "where the midspan topics and the run's maxima are taken, from the left abutment; "
          "0 = midspan (one span: L/2; a continuous deck: the middle of its longest span, the first of equal ones)"),
        S("delta_zeta", 0.0, "additional damping for every lane (fraction; zeta + delta_zeta >= 0)"),
        S("delta_zeta_lanes", "",
          "per-lane additional damping, comma list with one value per speed lane; empty = delta_zeta"),
        S("steps_per_period", 16.0, "RK4 steps per period of the highest mode at the slowest lane"),
        S("free_vibration_periods", 2.0),
        S("ds_m", 0.0, "train advance per step; 0 = from steps_per_period"),
        S("track_type", "ballasted", " | ".join(f"{t} ({a:g} m/s^2)" for t, a in ACC_LIMITS_M_S2.items())
          + ", EN 1990 A2.4.4.2.1"),
        S("warn_fraction", 0.8, f"{P.TOPIC_DIAGNOSTICS} WARN above this fraction of the acceleration limit"),
        S("monitor_speed_kmh", 0.0, f"lane shown on {P.TOPIC_ACCEL} and {P.BEAM_NS}/*: nearest speed; "
          "0 = first lane"),
        S("monitor_every_steps", 0, f"decimation of {P.TOPIC_ACCEL} (every n-th step); 0 = auto: "
          f"{MONITOR_SAMPLES_PER_PERIOD} samples per period of the highest mode at the monitored speed"),
        S("beam_every_steps", 0, f"decimation of {P.TOPIC_CLOCK}, {P.BEAM_NS}/* and {P.TOPIC_STATE} (every "
          "lane); 0 = auto: 4 x the monitoring step"),
        S("beam_points", 21, f"points along the deck on {P.TOPIC_BEAM} (a continuous deck: spread over the spans by "
          "length, every support one of them)"),
        S("partner_timeout_s", 5.0, "error when the train node sends nothing for this long during a run"),
    ]


def bridge_from_params(preset, p, defaults=None):
    """The :class:`Bridge` of the bridge node's parameter values ``p`` (``{name: value}``, every
    parameter of :func:`bridge_specs`): ``preset`` with the changed fields. The node checks its
    start-up values and every later set with it; a launcher checks the values it will hand to the
    node with it before starting anything.

    Raises :class:`InputError` naming the parameter, value, unit and range.
    """
    specs = {s.name: s for s in bridge_specs(preset)}
    d = {n: s.default for n, s in specs.items()} if defaults is None else defaults
    spans = _span_list(p, "spans_m")
    if spans:
        b = _deck_from_params(preset, p, d, specs, spans)
    else:
        for name in ("span_EJ_Nm2", "span_mu_kg_m"):
            if str(p[name]).strip():
                raise InputError(f"{name}: {p[name]!r} gives one value per span; per-span values need spans_m "
                                 f"(m), the spans of a continuous deck")
        b = _span_from_params(preset, p, d, specs)
    x = p["response_m"]
    if x != 0.0:
        specs["response_m"].check(x)
        if not 0.0 < x < b.span_m:
            raise InputError(f"response_m: {x:g} m is off the deck; allowed 0 (midspan) or 0 < x < {b.span_m:g} m "
                             f"(the deck's length)")
    check_delta_zeta("delta_zeta", p["delta_zeta"], b.damping_ratio)
    for x in parse_float_list("delta_zeta_lanes", p["delta_zeta_lanes"], "- (fraction)"):
        check_delta_zeta("delta_zeta_lanes", x, b.damping_ratio)
    check_track_type("track_type", p["track_type"])
    step_options(p)
    return b


def _span_from_params(preset, p, d, specs):
    """One simply supported span: ``preset`` (its one span, or a deck's length and mean EJ and mu
    when ``spans_m`` was emptied) with the changed fields."""
    base = dataclasses.replace(preset, spans_m=(), span_EJ_Nm2=(), span_mu_kg_m=()) if preset.is_continuous \
        else preset
    kw = {}
    for name in ("span_m", "mu_kg_m", "zeta_pct"):
        if p[name] != d[name] or (name == "span_m" and preset.is_continuous):
            view = specs[name].view
            kw[view.field.name] = view.to_core(view.check(p[name], name=name))
    if p["n_modes"] != d["n_modes"] or preset.is_continuous:  # one span: the registry's n_modes range
        kw["n_modes"] = fields.FIELDS["n_modes"].check(p["n_modes"], name="n_modes")
    if p["EJ_Nm2"] != d["EJ_Nm2"]:  # the core's range (> 0); the parameter's is narrower
        kw["EJ_Nm2"] = specs["EJ_Nm2"].view.field.check(p["EJ_Nm2"], name="EJ_Nm2")
    kw["damping_model"] = specs["damping_model"].view.check(p["damping_model"])
    b = dataclasses.replace(base, **kw)
    if p["n0_hz"] != 0.0:
        n0 = specs["n0_hz"].view.field.check(p["n0_hz"], name="n0_hz")
        b = Bridge.from_frequency(b.span_m, n0, b.mass_per_length_kg_m, b.damping_ratio, n_modes=b.n_modes,
                                  damping_model=b.damping_model, name=b.name, bridge_type=b.bridge_type)
    check_n0(b.n0_hz)  # span, EJ and mu together: their n0 in the registry's range
    return b


def _span_list(p, name):
    """The comma list of parameter ``name`` as text items (empty: none)."""
    return [x.strip() for x in str(p[name]).split(",") if x.strip()]


def _per_span_values(p, name, scalar, n, specs, d):
    """One value per span of ``name`` (``span_EJ_Nm2``, ``span_mu_kg_m``): its list (one value or one
    per span, each in the parameter's range) or, when empty, the scalar parameter ``scalar`` for every
    span; a changed scalar beside a list is refused (the same quantity given twice)."""
    items = _span_list(p, name)
    if not items:
        v = specs[scalar].view
        x = v.field.check(p[scalar], name=scalar) if scalar == "EJ_Nm2" else v.check(p[scalar], name=scalar)
        return [float(x)] * n
    if p[scalar] != d[scalar]:
        raise InputError(f"{scalar}: {p[scalar]!r} {specs[scalar].unit} and {name} = {p[name]!r} both give the "
                         f"{specs[scalar].view.field.doc} "
                         f"of the deck; give {scalar} for every span or {name} per span (the other as its default)")
    if len(items) not in (1, n):
        raise InputError(f"{name}: {p[name]!r} gives {len(items)} values for {n} spans; allowed one value or one "
                         f"per span ({specs[name].unit})")
    v = specs[name].view
    out = [float(v.check(x, name=name if len(items) == 1 else f"{name}[{i}]")) for i, x in enumerate(items)]
    return out * n if len(out) == 1 else out


def _deck_from_params(preset, p, d, specs, items):
    """The continuous deck of ``spans_m`` (``items``, its comma list as text; :meth:`Bridge.continuous`);
    one span in ``spans_m``: the simply supported span of that length (as ``spans = [15]`` in a
    bridge file). Every refusal names the parameter, the value, the unit and the range."""
    fspans, fcount = fields.FIELDS["deck_spans_m"], fields.FIELDS["n_spans"]
    if not fcount.lo <= len(items) <= fcount.hi:
        raise InputError(f"spans_m: {p['spans_m']!r} gives {len(items)} spans; allowed {fcount.lo}..{fcount.hi} "
                         f"spans, each in [{fspans.lo:g}, {fspans.hi:g}] m")
    spans = [check_range(f"spans_m[{i}]" if len(items) > 1 else "spans_m", x, "m", fspans.lo, fspans.hi)
             for i, x in enumerate(items)]
    if p["span_m"] != d["span_m"]:
        raise InputError(f"span_m: {p['span_m']!r} m and spans_m = {p['spans_m']!r} both give the length; give "
                         f"span_m for one span (spans_m empty) or spans_m for a continuous deck")
    n = len(spans)
    mu = _per_span_values(p, "span_mu_kg_m", "mu_kg_m", n, specs, d)
    zv = specs["zeta_pct"].view
    zeta = zv.to_core(zv.check(p["zeta_pct"], name="zeta_pct")) if p["zeta_pct"] != d["zeta_pct"] \
        else preset.damping_ratio
    damping_model = specs["damping_model"].view.check(p["damping_model"])
    source = preset.damping_source if p["zeta_pct"] == d["zeta_pct"] else "the bridge node's parameter zeta_pct"
    kw = dict(damping_model=damping_model, name=preset.name, bridge_type=preset.bridge_type, damping_source=source)
    if p["n0_hz"] != 0.0:  # one EJ for every span: omega grows as sqrt(EJ)
        n0 = specs["n0_hz"].view.field.check(p["n0_hz"], name="n0_hz")
        f1 = float(deck_modes(spans, [1.0] * n, mu, 1).frequencies_hz[0])
        EJ = [(n0 / f1) ** 2] * n
    else:
        EJ = _per_span_values(p, "span_EJ_Nm2", "EJ_Nm2", n, specs, d)
    if n == 1:
        n_modes = fields.FIELDS["n_modes"].check(p["n_modes"], name="n_modes")
        b = Bridge(span_m=spans[0], EJ_Nm2=EJ[0], mass_per_length_kg_m=mu[0], damping_ratio=zeta, n_modes=n_modes, **kw)
        check_n0(b.n0_hz)  # span, EJ and mu together: their n0 in the registry's range
        return b
    n_modes = specs["n_modes"].view.check(p["n_modes"], name="n_modes")  # the node's range, decks too
    f1 = float(deck_modes(spans, EJ, mu, 1).frequencies_hz[0])
    lo, hi = N0_RANGE_HZ
    if not lo <= f1 <= hi:
        raise InputError(f"spans_m: the deck's first frequency is {f1:.4g} Hz with spans_m = {p['spans_m']!r}; "
                         f"allowed n0 in [{lo:g}, {hi:g}] Hz (check span_EJ_Nm2 / EJ_Nm2 and span_mu_kg_m / mu_kg_m)")
    return Bridge.continuous(spans, EJ, mu, zeta, n_modes=n_modes, **kw)


#: How the bridge node's parameters name the quantities of the plausibility table.
BRIDGE_PARAM_LABELS = {"n0": "n0_hz", "mu": "mu_kg_m", "zeta_pct": "zeta_pct",
                       "zeta_light": "zeta_pct: damping of a light deck"}


def bridge_plausibility(preset, p, defaults=None):
    """The plausibility warnings (:func:`adm_sim.model.plausibility.check_bridge`) of the bridge the
    node's parameter values ``p`` give, each naming its parameter (``mu_kg_m: 150 kg/m is outside
    the plausible range ...``); a typed ``zeta_pct`` below 0.1 % is named as a fraction typed as
    percent. n0 derived from ``EJ_Nm2`` (``n0_hz`` = 0) is named so. Warnings only, never a refusal;
    ``p`` must have passed :func:`bridge_from_params`. What the preset itself gives (its own
    warnings came with it, :func:`adm_sim.inputs.bridges.resolve_bridge`) is not said again: only the
    warnings the parameter values add to those of the preset's defaults."""
    d = {sp.name: sp.default for sp in bridge_specs(preset)} if defaults is None else defaults

    def said(values):
        b = bridge_from_params(preset, values, d)
        labels = dict(BRIDGE_PARAM_LABELS)
        if values["n0_hz"] == 0.0:
            labels["n0"] = "n0 (from EJ_Nm2 and mu_kg_m)"
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PlausibilityWarning)
            if b.is_continuous:  # as a bridge file's deck: the mode count against the rule
                need = rule_mode_count(b.spans_m, b.span_EJ_Nm2, b.span_mu_kg_m)
                if b.n_modes < need:
                    warnings.warn(f"n_modes: {b.n_modes} modes is fewer than the {need} that the rule asks for on "
                                  f"this deck ({RULE_TEXT})", PlausibilityWarning, stacklevel=2)
            else:
                check_bridge(b, "bridge", zeta_pct_given=float(values["zeta_pct"]), labels=labels)
        return [str(w.message) for w in caught if issubclass(w.category, PlausibilityWarning)]

    preset_said = set(said({**p, **d}))
    for text in said(p):
        if text not in preset_said:
            warnings.warn(text, PlausibilityWarning, stacklevel=2)


TRAIN_SPECS = [
    param("train", "ICE-2", "train name (ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table) or TOML file"),
    param("model", "dim", "dim (Detailed Interaction Model) | mlm (Moving Load Model)"),
    param("speeds_kmh", DEFAULT_SPEEDS, "speed lanes: start:stop:step (stop included) or a comma list"),
    param("mlm_block_steps", 2048),
    param("partner_timeout_s", 5.0, "error when the bridge node sends nothing for this long during a run"),
    ParamSpec("run_phase", "", "", "what the next run is for, handed to the bridge with the run request: "
                + " | ".join(P.PHASES) + "; empty = named by the request (dim, mlm_zeta, mlm_zeta_dz, bracketing)"),
    ParamSpec("irregularity", "", "", "track irregularity on the deck under the DIM wheels: a profile spec "
              "(german-high:seed=3, fra-6:seed=1, file=PROFILE.csv, ramp:at=0:length=3:height=0.002, parts "
              "joined by +; docs/irregularities.md); empty = smooth track"),
]


def check_run_phase(value):
    """Raise :class:`InputError` unless ``value`` is empty or one of :data:`adm_sim.protocol.PHASES`."""
    if value and value not in P.PHASES:
        raise InputError(f"run_phase: {value!r} is not a run phase; allowed {', '.join(P.PHASES)} or empty")
    return value


def validate_train(p):
    """``(train, speeds_kmh)`` of the train node's parameter values ``p``; raises
    :class:`InputError` (train, model, phase, speed lanes)."""
    train = load_train(p["train"])
    check_model(p["model"], train)
    check_run_phase(p["run_phase"])
    speeds = parse_speeds(p["speeds_kmh"], ordered=False, field="speeds_kmh")  # lanes, not a user's grid
    if p.get("irregularity"):
        from adm_sim.inputs.track_profile import parse_irregularity  # noqa: PLC0415  scipy.interpolate only on a rough track

        parse_irregularity(p["irregularity"], 40.0)  # spectrum, class, band, file: refused before a run starts
    return train, speeds


DRIVER_SPECS = [
    ParamSpec("record_path", "", "", "MCAP file to record to; empty = no recording"),
    ParamSpec("rrd_path", "", "", "rerun .rrd file to write; empty = none"),
    ParamSpec("rerun_spawn", False, "", "spawn a rerun viewer bound to 127.0.0.1"),
    ParamSpec("rerun_connect", "", "", "stream to a rerun viewer at this loopback URL"),
    ParamSpec("summary_path", "", "", "JSON summary of the run(s); empty = none"),
    param("run_timeout_s", 900.0),
    param("wait_clients", 0),
    param("chunk_size", 65536),
    ParamSpec("overwrite", False, "", "replace existing record_path, rrd_path and summary_path files"),
]
