"""The one reader of train files: a train by name (the paper's, HSLM-A) or a TOML file of either form.

Both forms share their top-level keys, their composition's ``count`` and ``reversed``, the axle
load tolerance and the bounded work of a train (axles, length); keys, ranges and tolerances are the
field registry's (:mod:`adm_sim.fields`: :data:`~adm_sim.fields.TRAIN_FILE_KEYS`,
:data:`~adm_sim.fields.COMPOSITION_KEYS`, :data:`~adm_sim.fields.VEHICLE_TABLE_KEYS`,
:data:`~adm_sim.fields.AXLE_LOAD_REL_TOL`). Every refusal is one line naming the file, the key as
typed, the value, the unit and the allowed range. The model (:mod:`adm_sim.model.trains`,
:mod:`adm_sim.model.vehicles`) takes the checked numbers and places the axles.

File schema (TOML, SI units; see ``data/trains/*.toml``, ``data/vehicles/*.toml``, docs/model.md
"Trains" and docs/vehicles.md):

``name``, ``description``, ``source``, ``paper_train``, ``loads_differ_from_masses``
    Labels; ``paper_train`` one of the paper's trains (for the bogie frequencies it quotes);
    ``loads_differ_from_masses = true`` lifts the check of the axle loads against the masses.
``[vehicle_types.<NAME>]`` (the form of paper Table A1)
    ``m_c_kg, J_c_kgm2`` car body mass and pitch inertia; ``m_b_kg, J_b_kgm2`` bogie mass and
    pitch inertia; ``m_w_kg`` wheelset mass; ``k_s_N_m, c_s_Ns_m`` secondary suspension per bogie;
    ``k_p_N_m, c_p_Ns_m`` primary suspension per wheelset (axle); ``d_m`` vehicle length (coupler
    to coupler); ``r_m`` distance between the bogie pivots (omit for cars resting on two Jacobs
    bogies, where it equals ``d_m``); ``b_m`` bogie wheelbase; ``axle_load_kN`` static axle load
    (a list ``[front, rear]`` where the table prints two values ``a/b``).
    ``[[composition]]``: ``vehicle = "PC"`` with optional ``count``, or a Jacobs-bogie trainset
    ``jacobs_set = ["PC1", "PC2-8", ..., "PC9"]`` (car types, front to rear) with ``bogies = [...]``
    (``len(cars) + 1`` vehicle-type names whose bogie data each bogie uses), ``axle_loads_kN = [...]``
    (one per bogie) and optional ``reversed = true`` (the set runs rear end first).
``[vehicles.<NAME>]`` (a vehicle file: any planar vehicle)
    ``length_m``; ``[[vehicles.<NAME>.bodies]]`` ``name, mass_kg, x_m`` and optional
    ``pitch_inertia_kgm2``; ``[[vehicles.<NAME>.wheelsets]]`` ``name, mass_kg, x_m`` and optional
    ``static_load_kN``; ``[[vehicles.<NAME>.stages]]`` ``upper, lower, x_m, k_N_m, c_Ns_m`` (each
    wheelset hangs on one stage). ``[[composition]]``: ``vehicle``, optional ``count`` and ``reversed``.
"""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError
from adm_sim.fields import (AXLE_LOAD_REL_TOL, COMPOSITION_KEYS, TRAIN_FILE_KEYS, VEHICLE_FIELDS, VEHICLE_KEYS,
                            VEHICLE_OPTIONAL, VEHICLE_TABLE_KEYS, check_count)
from adm_sim.fields import view as field_view
from adm_sim.files import check_path, read_toml
from adm_sim.model.hslm import hslm_axles, hslm_name
from adm_sim.model.plausibility import warn_implausible_train
from adm_sim.model.trains import (TRAIN_NAMES, VehicleType, axle_rows, consistency_rows, conventional_unit,
                                  jacobs_unit, moving_loads, train_of_units, train_of_vehicles)
from adm_sim.model.vehicles import VehicleGroup, compose, vehicle_mapping

#: The shipped train files, by normalised name.
_FILES = {"ice2": "ice2.toml", "eurostar": "eurostar.toml", "railjet": "railjet.toml",
          "ice4": "ice4.toml", "eurostartable": "eurostar_table.toml"}


def _normalise(name):
    return "".join(ch for ch in name.lower() if ch.isalnum())


def load_train(name_or_path):
    """Load a train by name (ICE-2, Eurostar, Railjet, ICE-4, Eurostar-table, HSLM-A1 .. HSLM-A10) or TOML path."""
    text = str(name_or_path)
    key = _normalise(text)
    canonical = hslm_name(text)
    if canonical is not None:  # EN 1991-2 universal trains HSLM-A1 .. A10 (load trains)
        return moving_loads(*hslm_axles(canonical), name=canonical)
    if key in _FILES:
        data = tomllib.loads(resources.files("adm_sim").joinpath("data/trains", _FILES[key]).read_text())
        return train_from_mapping(data, source=_FILES[key])
    p = Path(check_path(text, "train"))
    if p.suffix == ".toml" or p.is_file():
        train = train_from_mapping(read_toml(p, "train file"), source=p.name)
        warn_implausible_train(train, source=f"train file {p.name}")  # warnings, not refusals
        return train
    raise InputError(f"train: {text!r} is unknown; allowed {', '.join(TRAIN_NAMES)}, "
                     f"Eurostar-table, HSLM-A1 .. HSLM-A10, or a .toml train file", field="train")


def train_from_mapping(data, source="train"):
    """Build and validate a :class:`~adm_sim.model.trains.Train` from a parsed train file of either form.

    Unknown, misspelt and conflicting keys are refused; booleans must be booleans; axle loads must
    agree with the masses within :data:`~adm_sim.fields.AXLE_LOAD_REL_TOL` unless
    ``loads_differ_from_masses = true``. A mapping with ``[vehicles.<NAME>]`` instead of
    ``[vehicle_types.<NAME>]`` is a vehicle file of bodies, wheelsets and stages.
    """
    if not isinstance(data, dict):
        raise InputError(f"{source}: not a table of train fields")
    if "vehicles" in data and "vehicle_types" not in data:
        return _train_of_vehicle_file(data, source)
    differ = _file_fields(data, "vehicle_types", source)
    types = _vehicle_types(data.get("vehicle_types"), source)
    units, jacobs = _composition_units(data.get("composition"), types, source)
    rows = axle_rows(units, types)
    _check_axles(rows.offsets_m, source, f"{len(units)} units")
    _check_order(rows.offsets_m, [b for u in units for b in u.bogies], source)
    train = train_of_units(str(data["name"]), types, units, rows, jacobs=jacobs,
                           description=str(data.get("description", "")), source=str(data.get("source", source)),
                           paper_train=str(data.get("paper_train", "")))
    if not differ:
        _check_loads(train, source)
    return train


def vehicle_file_mapping(train):
    """The vehicle-file mapping of a train built from vehicle types (:func:`adm_sim.model.vehicles.vehicle_mapping`
    with its ``paper_train`` and whether its loads differ from its masses); :func:`adm_sim.model.vehicles.to_toml`
    writes it. The shipped ``data/vehicles/*.toml`` are the paper's trains written so."""
    differ = any(r.item.startswith("F ") and not r.ok for r in consistency_rows(train, rel_tol=AXLE_LOAD_REL_TOL))
    paper = train.paper_train or (train.name if train.name in TRAIN_NAMES else "")
    return vehicle_mapping(train, paper_train=paper, loads_differ=differ)


# ---------------------------------------------------------------------- both forms
def check_keys(d, allowed, where):
    """Refuse the keys of ``d`` not in ``allowed`` (a misspelt key is never ignored), naming them
    and the allowed ones after ``where``."""
    extra = [k for k in d if k not in allowed]
    if extra:
        raise InputError(f"{where}: unknown key(s) {', '.join(repr(k) for k in extra)}; "
                         f"allowed {', '.join(allowed)}")


def _file_fields(data, table, source):
    """The top-level fields of a train file whose vehicles are in ``table`` (``vehicle_types`` or
    ``vehicles``): no key outside :data:`~adm_sim.fields.TRAIN_FILE_KEYS`, a non-empty ``name``, text
    in ``description``, ``source`` and ``paper_train`` (one of the paper's trains or empty), a
    boolean ``loads_differ_from_masses``; returns that boolean (default ``False``)."""
    check_keys(data, TRAIN_FILE_KEYS[table], source)
    if "name" not in data:
        raise InputError(f"{source}: missing field 'name'")
    if not isinstance(data["name"], str) or not data["name"].strip():
        raise InputError(f"{source}: name: {data['name']!r} must be a non-empty string")
    for key in ("description", "source", "paper_train"):
        if key in data and not isinstance(data[key], str):
            raise InputError(f"{source}: {key}: {data[key]!r} must be text in quotes")
    if data.get("paper_train", "") not in ("",) + TRAIN_NAMES:
        raise InputError(f"{source}: paper_train: {data['paper_train']!r} is not a train of the paper; "
                         f"allowed {', '.join(TRAIN_NAMES)} (or omit it)")
    differ = data.get("loads_differ_from_masses", False)
    if not isinstance(differ, bool):
        raise InputError(f"{source}: loads_differ_from_masses: {differ!r} must be true or false")
    return differ


def _reversed(entry, where):
    rev = entry.get("reversed", False)
    if not isinstance(rev, bool):
        raise InputError(f"{where}.reversed: {rev!r} must be true or false")
    return rev


def _check_axles(offsets_m, source, units_text):
    """The bounded work of one train: its axles and its length (registry group ``limits``)."""
    check_count("n_axles", len(offsets_m), f"{source}: composition", units_text)
    length = max(offsets_m) - min(offsets_m) if offsets_m else 0.0
    check_count("train_length_m", round(length, 3), f"{source}: composition",
                f"{units_text}, {len(offsets_m)} axles")


# ---------------------------------------------------------------------- vehicle types (Table A1)
def _vehicle_types(raw, source):
    if not isinstance(raw, dict) or not raw:
        raise InputError(f"{source}: missing table [vehicle_types.<NAME>]")
    return {n: _vehicle_type(n, d, source) for n, d in raw.items()}


def _vehicle_type(name, d, source):
    where = f"{source}: vehicle_types.{name}"
    if not isinstance(d, dict):
        raise InputError(f"{where}: {d!r} is not a table; write [vehicle_types.{name}] with its fields")
    unknown = set(d) - set(VEHICLE_FIELDS) - {"axle_load_kN"}
    if unknown:
        raise InputError(f"{where}: unknown field(s) {', '.join(sorted(map(str, unknown)))}; allowed "
                         f"{', '.join(list(VEHICLE_FIELDS) + ['axle_load_kN'])}")
    vals = {}
    for key in VEHICLE_FIELDS:
        v = field_view("toml", key)
        if key not in d:
            if key not in VEHICLE_OPTIONAL:
                raise InputError(f"{where}.{key}: missing ({v.unit}, allowed [{v.lo:g}, {v.hi:g}])")
            vals[key] = math.nan
            continue
        vals[key] = v.check(d[key], name=f"{where}.{key}", typed=True)
    loads = _type_axle_loads(d, where)
    if not math.isnan(vals["r_m"]) and vals["b_m"] >= vals["r_m"]:
        raise InputError(f"{where}.b_m: bogie wheelbase {vals['b_m']:g} m is not shorter than the pivot distance "
                         f"r_m {vals['r_m']:g} m: the axles of the two bogies would interleave or coincide; "
                         f"allowed b_m < r_m")
    if not math.isnan(vals["r_m"]) and vals["r_m"] + vals["b_m"] >= vals["d_m"]:
        raise InputError(f"{where}.r_m: {vals['r_m']:g} m plus wheelbase b_m {vals['b_m']:g} m "
                         f"is not shorter than the vehicle length d_m {vals['d_m']:g} m: axles of coupled "
                         f"vehicles would coincide or overlap; allowed r_m + b_m < d_m")
    return VehicleType(name=name, axle_load_n=loads, **vals)


def _type_axle_loads(d, where):
    """``axle_load_kN``: one value or ``[front, rear]`` (kN), in N."""
    axle = field_view("toml", "axle_load_kN")
    if "axle_load_kN" not in d:
        raise InputError(f"{where}.axle_load_kN: missing ({axle.unit}, allowed [{axle.lo:g}, {axle.hi:g}])")
    raw = d["axle_load_kN"]
    raw = raw if isinstance(raw, list) else [raw]
    if not 1 <= len(raw) <= 2:
        raise InputError(f"{where}.axle_load_kN: {raw!r} must be one value or [front, rear] (kN)")
    return tuple(axle.to_core(axle.check(v, name=f"{where}.axle_load_kN", typed=True)) for v in raw)


def _composition_units(comp, types, source):
    """The units of ``[[composition]]`` front to rear and whether one is a Jacobs set."""
    if not isinstance(comp, list) or not comp:
        raise InputError(f"{source}: missing [[composition]] entries")
    units, front, jacobs = [], 0.0, False  # front: front end of the next vehicle, from the train's front end
    for n, entry in enumerate(comp):
        where = f"composition[{n}]"
        if not isinstance(entry, dict):
            raise InputError(f"{source}: {where}: not a table")
        if "vehicle" in entry and "jacobs_set" in entry:
            raise InputError(f"{source}: {where}: has both 'vehicle' and 'jacobs_set'; give one per entry")
        if "vehicle" in entry:
            vt, count = _vehicle_entry(entry, types, source, where)
            for _ in range(count):
                unit, front = conventional_unit(vt, front)
                units.append(unit)
        elif "jacobs_set" in entry:
            unit, front = jacobs_unit(*_jacobs_entry(entry, types, source, where), front)
            units.append(unit)
            jacobs = True
        else:
            raise InputError(f"{source}: {where}: needs 'vehicle' or 'jacobs_set' (keys given: "
                             f"{', '.join(repr(k) for k in entry) or 'none'})")
    return units, jacobs


def _type(types, name, source, where):
    if not isinstance(name, str) or name not in types:
        raise InputError(f"{source}: {where}: vehicle type {name!r} not defined; defined: {', '.join(types)}")
    return types[name]


def _count(entry, where):
    """``count`` of a composition entry (1..100, an integer without quotes)."""
    count = entry.get("count", 1)
    if isinstance(count, str):
        raise InputError(f"{where}.count: {count!r} must be an integer without quotes; allowed integer in [1, 100]")
    return field_view("toml", "count").check(count, name=f"{where}.count")


def _vehicle_entry(entry, types, source, where):
    """A conventional vehicle entry: its type and count."""
    check_keys(entry, COMPOSITION_KEYS["vehicle_types"]["vehicle"], f"{source}: {where}")
    vt = _type(types, entry["vehicle"], source, where)
    if math.isnan(vt.r_m):
        raise InputError(f"{source}: {where}: vehicle type {vt.name!r} has no r_m (m) "
                         f"and cannot run as a conventional vehicle")
    return vt, _count(entry, f"{source}: {where}")


def _jacobs_entry(entry, types, source, where):
    """A Jacobs set entry: car types, bogie types and axle loads (N), front to rear as it runs."""
    check_keys(entry, COMPOSITION_KEYS["vehicle_types"]["jacobs_set"], f"{source}: {where}")
    if not isinstance(entry["jacobs_set"], list) or not isinstance(entry.get("bogies", []), list):
        raise InputError(f"{source}: {where}: 'jacobs_set' and 'bogies' must be lists of vehicle types")
    if not isinstance(entry.get("axle_loads_kN", []), list):
        raise InputError(f"{source}: {where}.axle_loads_kN: {entry['axle_loads_kN']!r} must be a list "
                         f"of one load per bogie (kN)")
    cars = [_type(types, c, source, where) for c in entry["jacobs_set"]]
    bogie_types = [_type(types, b, source, where) for b in entry.get("bogies", [])]
    loads_kn = entry.get("axle_loads_kN", [])
    if len(cars) < 2:
        raise InputError(f"{source}: {where}.jacobs_set: needs at least 2 cars")
    if len(bogie_types) != len(cars) + 1 or len(loads_kn) != len(cars) + 1:
        raise InputError(f"{source}: {where}: 'bogies' and 'axle_loads_kN' need "
                         f"len(jacobs_set) + 1 = {len(cars) + 1} entries")
    axles = field_view("toml", "axle_loads_kN")
    loads = [axles.to_core(axles.check(v, name=f"{source}: {where}.axle_loads_kN", typed=True)) for v in loads_kn]
    if _reversed(entry, f"{source}: {where}"):
        cars, bogie_types, loads = cars[::-1], bogie_types[::-1], loads[::-1]
    for end in (cars[0], cars[-1]):
        if math.isnan(end.r_m):
            raise InputError(f"{source}: {where}: end car {end.name!r} needs r_m (m)")
    return cars, bogie_types, loads


def _check_order(offsets_m, bogies, source):
    """Refuse axles that coincide or interleave (in build order: bogie after bogie, front to rear)."""
    offs = np.asarray(offsets_m)
    gaps = np.diff(offs)
    if np.any(gaps <= 0.0):
        i = int(np.argmax(gaps <= 0.0))
        b1, b2 = bogies[i // 2], bogies[(i + 1) // 2]
        raise InputError(f"{source}: the axles of bogies {b1.type_name!r} (pivot {b1.pivot_m - offs[0]:.3f} m) and "
                         f"{b2.type_name!r} (pivot {b2.pivot_m - offs[0]:.3f} m) coincide or interleave "
                         f"({gaps[i]:.3f} m apart): the wheelbases b_m do not fit between the pivots (d_m, r_m); "
                         f"allowed axles strictly one after another")


def _check_loads(train, source):
    """Refuse axle loads that disagree with the vehicle masses (the MLM and the DIM would carry
    different trains) beyond :data:`~adm_sim.fields.AXLE_LOAD_REL_TOL`."""
    for row in consistency_rows(train, rel_tol=AXLE_LOAD_REL_TOL):
        if row.item.startswith("F ") and not row.ok:
            raise InputError(
                f"{source}: {row.item}: axle load {row.table_value:.4g} kN disagrees with the masses, "
                f"{row.note} = {row.computed_value:.4g} kN (allowed within {100 * AXLE_LOAD_REL_TOL:g} %); "
                f"fix the loads or masses, or set loads_differ_from_masses = true if this is meant")


# ---------------------------------------------------------------------- vehicle files (bodies, wheelsets, stages)
def _train_of_vehicle_file(data, source):
    """A :class:`~adm_sim.model.trains.Train` of a vehicle file (bodies, wheelsets, stages)."""
    differ = _file_fields(data, "vehicles", source)
    raw = data.get("vehicles")
    if not isinstance(raw, dict) or not raw:
        raise InputError(f"{source}: vehicles: missing table [vehicles.<NAME>]")
    groups = {n: _vehicle_group(n, d, f"{source}: vehicles.{n}") for n, d in raw.items()}
    if not differ:
        for g in groups.values():
            if g.wheels[0]["static_load_kN"] is not None and \
                    abs(g.loads_n.sum() - g.weight_n) > AXLE_LOAD_REL_TOL * g.weight_n:
                raise InputError(f"{source}: vehicles.{g.name}: static loads sum to {g.loads_n.sum() / 1000:.4g} kN, "
                                 f"the masses weigh {g.weight_n / 1000:.4g} kN (allowed within "
                                 f"{100 * AXLE_LOAD_REL_TOL:g} %); fix them or set loads_differ_from_masses = true")
    compiled = compose(groups, _vehicle_file_entries(data.get("composition"), groups, source))
    offs = list(compiled.axle_offsets_m)
    _check_axles(offs, source, f"{len(compiled.units)} vehicles")
    gaps = np.diff(compiled.axle_offsets_m)
    if np.any(gaps <= 0.0):
        i = int(np.argmax(gaps <= 0.0))
        owner, units = compiled.unit_of_axle, compiled.units
        raise InputError(f"{source}: composition: axles {i} and {i + 1} are {gaps[i]:.3f} m apart (vehicles "
                         f"{units[owner[i]].label!r}, {units[owner[i + 1]].label!r}); allowed axles strictly one "
                         f"after another: check length_m and the wheelsets' x_m")
    return train_of_vehicles(compiled, data["name"], description=str(data.get("description", "")),
                             source=str(data.get("source", source)), paper_train=str(data.get("paper_train", "")))


def _vehicle_file_entries(comp, groups, source):
    """``[(vehicle, count, reversed)]`` of a vehicle file's ``[[composition]]``."""
    if not isinstance(comp, list) or not comp:
        raise InputError(f"{source}: composition: missing [[composition]] entries")
    out = []
    for n, entry in enumerate(comp):
        where = f"{source}: composition[{n}]"
        if not isinstance(entry, dict):
            raise InputError(f"{where}: not a table")
        check_keys(entry, COMPOSITION_KEYS["vehicles"]["vehicle"], where)
        name = entry.get("vehicle")
        if name not in groups:
            raise InputError(f"{where}.vehicle: {name!r} is not defined; defined: {', '.join(groups)}")
        if isinstance(entry.get("count", 1), bool):
            raise InputError(f"{where}.count: {entry['count']!r} must be an integer without quotes; allowed "
                             f"integer in [1, 100]")
        out.append((name, _count(entry, where), _reversed(entry, where)))
    return out


def _vehicle_group(name, d, where):
    """One ``[vehicles.<NAME>]`` table checked (keys, ranges, names and references) and compiled
    (:class:`~adm_sim.model.vehicles.VehicleGroup`)."""
    if not isinstance(d, dict):
        raise InputError(f"{where}: {d!r} is not a table; write [vehicles.{name}] with {', '.join(VEHICLE_KEYS)}")
    check_keys(d, VEHICLE_KEYS, where)
    length = field_view("toml", "length_m")
    if "length_m" not in d:
        raise InputError(f"{where}.length_m: missing ({length.unit}, allowed [{length.lo:g}, {length.hi:g}])")
    length_m = length.check(d["length_m"], name=f"{where}.length_m", typed=True)
    tables = {}
    for key in ("bodies", "wheelsets", "stages"):
        v = d.get(key)
        if not isinstance(v, list) or not v:
            raise InputError(f"{where}.{key}: missing or empty; allowed a list of tables ([[vehicles.{name}.{key}]])")
        tables[key] = [_table(t, key, f"{where}.{key}[{i}]") for i, t in enumerate(v)]
    _check_references(tables["bodies"], tables["wheelsets"], tables["stages"], where)
    return VehicleGroup(name, length_m, tables["bodies"], tables["wheelsets"], tables["stages"], where)


def _table(d, kind, where):
    """Checked values of one body/wheelset/stage table (``None`` for an omitted optional key)."""
    spec = VEHICLE_TABLE_KEYS[kind]
    keys = tuple(k for k, _, _ in spec)
    if not isinstance(d, dict):
        raise InputError(f"{where}: {d!r} is not a table; allowed keys {', '.join(keys)}")
    check_keys(d, keys, where)
    out = {}
    for key, spelling, required in spec:
        v = None if spelling is None else field_view("toml", spelling)
        if key not in d:
            if required:
                rng = f" ({v.unit}, allowed [{v.lo:g}, {v.hi:g}])" if v is not None else " (text)"
                raise InputError(f"{where}.{key}: missing{rng}")
            out[key] = None
        elif v is None:
            if not isinstance(d[key], str) or not d[key].strip():
                raise InputError(f"{where}.{key}: {d[key]!r} must be a non-empty name in quotes")
            out[key] = d[key]
        else:
            out[key] = v.check(d[key], name=f"{where}.{key}", typed=True)
    return out


def _check_references(bodies, wheels, stages, where):
    """One name per body and wheelset; every stage joins two different known parts; every wheelset
    hangs on exactly one stage."""
    names = [b["name"] for b in bodies] + [w["name"] for w in wheels]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"{where}: name(s) {', '.join(map(repr, dup))} used twice; allowed one name per "
                         f"body and wheelset")
    body_names, wheel_names = [b["name"] for b in bodies], [w["name"] for w in wheels]
    for i, s in enumerate(stages):
        if s["upper"] not in body_names:
            raise InputError(f"{where}.stages[{i}].upper: {s['upper']!r} is not a body; allowed "
                             f"{', '.join(map(repr, body_names))}")
        if s["lower"] not in body_names and s["lower"] not in wheel_names:
            raise InputError(f"{where}.stages[{i}].lower: {s['lower']!r} is not a body or wheelset; allowed "
                             f"{', '.join(map(repr, body_names + wheel_names))}")
        if s["lower"] == s["upper"]:
            raise InputError(f"{where}.stages[{i}]: joins body {s['upper']!r} to itself; allowed two "
                             f"different bodies, or a body and a wheelset")
    for w in wheels:
        n = sum(s["lower"] == w["name"] for s in stages)
        if n != 1:
            raise InputError(f"{where}: wheelset {w['name']!r} hangs on {n} stages; allowed exactly 1 "
                             f"(stages with lower = {w['name']!r})")
