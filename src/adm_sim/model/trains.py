"""Trains as data: vehicle types (paper Table A1), compositions (Section 3.2) and the
multi-body vehicle model of the Detailed Interaction Model (Figs. 2, 3, 7; Eq. 11).

File schema (TOML, SI units; see ``data/trains/*.toml`` and docs/model.md, "Trains"):

``name``, ``description``, ``source``
    Labels.
``[vehicle_types.<NAME>]``
    ``m_c_kg, J_c_kgm2`` car body mass and pitch inertia; ``m_b_kg, J_b_kgm2`` bogie mass and
    pitch inertia; ``m_w_kg`` wheelset mass; ``k_s_N_m, c_s_Ns_m`` secondary suspension per bogie;
    ``k_p_N_m, c_p_Ns_m`` primary suspension per wheelset (axle); ``d_m`` vehicle length (coupler
    to coupler); ``r_m`` distance between the bogie pivots (omit for cars resting on two Jacobs
    bogies, where it equals ``d_m``); ``b_m`` bogie wheelbase; ``axle_load_kN`` static axle load
    (a list ``[front, rear]`` where the table prints two values ``a/b``).
``[[composition]]``
    Entries from the front: ``vehicle = "PC"`` with optional ``count``, or a Jacobs-bogie
    trainset ``jacobs_set = ["PC1", "PC2-8", ..., "PC9"]`` (car types, front to rear) with
    ``bogies = [...]`` (``len(cars) + 1`` vehicle-type names whose bogie data -- m_b, J_b, m_w,
    k_p, c_p, b -- each bogie uses), ``axle_loads_kN = [...]`` (one per bogie) and optional
    ``reversed = true`` (the set runs rear end first).

Axle positions (documented rule): a conventional vehicle is symmetric, its bogie pivots lie at
``(d - r) / 2`` and ``(d + r) / 2`` behind its front end and its axles at ``pivot -/+ b / 2``.
In a Jacobs set, inner bogies sit on the joints between cars; the end cars carry a conventional
bogie at ``r`` from the joint, the remaining ``d - r`` being the outer overhang. Vehicles follow
each other coupler to coupler. Offsets are measured from the first axle, backwards.

Vehicle model (Eq. 11, formulated about static equilibrium, z downwards): each car body and
bogie has bounce ``z`` and pitch ``theta``; a point at offset ``xi`` (backwards from the body
centre) moves by ``z + xi theta``. Secondary springs/dampers join a car body pivot point to its
bogie centre; primary springs/dampers join a bogie axle point to the wheelset, which stays in
contact with the rail (Section 1) so its displacement is the rail's. Adjacent cars are coupled
vertically only through shared Jacobs bogies; the car-body reference point is the middle
between its two pivots (the centre-of-gravity offset of the Eurostar end cars, visible in their
unequal axle loads, enters the static loads only).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError
from adm_sim.files import check_path, read_toml
from adm_sim.fields import VEHICLE_FIELDS, VEHICLE_OPTIONAL, check_count
from adm_sim.fields import view as field_view
from adm_sim.model.hslm import hslm_axles, hslm_name
from adm_sim.model.plausibility import check_train as check_plausible
from adm_sim.model.vehicles import check_file_fields, check_keys, compile_vehicle_file, vehicle_mapping

G_M_S2 = 9.81  # gravitational acceleration used by the paper (Section 3.2.2)

TRAIN_NAMES = ("ICE-2", "Eurostar", "Railjet", "ICE-4")
_FILES = {"ice2": "ice2.toml", "eurostar": "eurostar.toml", "railjet": "railjet.toml",
          "ice4": "ice4.toml", "eurostartable": "eurostar_table.toml"}

# vehicle-type fields of a train file (units and ranges: the field registry, :mod:`adm_sim.fields`)
_TYPE_FIELDS = VEHICLE_FIELDS


@dataclass(frozen=True)
class VehicleType:
    """One column of Table A1 (SI units; k_p, c_p per axle; k_s, c_s per bogie)."""

    name: str
    m_c_kg: float
    J_c_kgm2: float
    m_b_kg: float
    J_b_kgm2: float
    m_w_kg: float
    k_s_N_m: float
    c_s_Ns_m: float
    k_p_N_m: float
    c_p_Ns_m: float
    d_m: float
    r_m: float  # nan for cars on two Jacobs bogies
    b_m: float
    axle_load_n: tuple  # one value, or (front bogie, rear bogie)

    @property
    def bogie_frequency_hz(self):
        """Bogie bounce frequency n_p of Eq. (1): ``sqrt(2 k_p / m_b) / (2 pi)``."""
        return math.sqrt(2.0 * self.k_p_N_m / self.m_b_kg) / (2.0 * math.pi)

    @property
    def total_mass_kg(self):
        """Car body + two bogies + four wheelsets (conventional vehicle)."""
        return self.m_c_kg + 2.0 * self.m_b_kg + 4.0 * self.m_w_kg


@dataclass(frozen=True)
class Bogie:
    """A bogie in the train: its data type, pivot offset and its two axles."""

    type_name: str
    pivot_m: float  # offset from the first axle of the train, backwards
    axle_load_n: float


@dataclass
class Unit:
    """A vertically coupled group: one conventional vehicle or one Jacobs trainset.

    ``cars``: list of (type name, pivot offsets (front, rear)); ``bogies``: list of
    :class:`Bogie`; ``car_bogies``: for each car the indices of its (front, rear) bogie.
    ``matrices``: the unit's :class:`VehicleMatrices` when it comes from a vehicle file
    (:mod:`adm_sim.model.vehicles`; its ``cars`` are the bodies that carry no wheelset, its ``bogies``
    the others); None: assembled from the vehicle types (:func:`_assemble`).
    """

    label: str
    cars: list
    bogies: list
    car_bogies: list
    matrices: VehicleMatrices | None = None

    @property
    def n_dof(self):
        return 2 * (len(self.cars) + len(self.bogies))


@dataclass(frozen=True)
class VehicleMatrices:
    """Assembled vehicle system of one unit (Eq. 11), DOFs ``[z, theta]`` of cars then bogies.

    ``M`` (n_dof,) diagonal masses/inertias; ``K_s``, ``C_s`` (n_dof, n_dof) secondary stage;
    ``Lw`` (n_axles, n_dof) maps DOFs to the bogie point above each axle; ``k_p``, ``c_p``
    (n_axles,) primary stage per axle. ``K``/``C`` add the primary stage with fixed wheels.
    """

    M: np.ndarray
    K_s: np.ndarray
    C_s: np.ndarray
    Lw: np.ndarray
    k_p: np.ndarray
    c_p: np.ndarray

    @property
    def K(self):
        return self.K_s + self.Lw.T @ (self.k_p[:, None] * self.Lw)

    @property
    def C(self):
        return self.C_s + self.Lw.T @ (self.c_p[:, None] * self.Lw)


@dataclass(frozen=True)
class Train:
    """A train: vehicle types, the composition as coupled units, and its axles.

    Attributes
    ----------
    axle_offsets_m : ndarray, shape (n_axles,)
        Distance of every axle behind the first one (m), increasing.
    axle_loads_n : ndarray, shape (n_axles,)
        Static axle loads F_i (N) used by the MLM and as static part of the DIM.
    wheel_mass_kg : ndarray, shape (n_axles,)
        Wheelset masses m_w,i (kg).
    unit_of_axle : ndarray, shape (n_axles,)
        Index of the unit each axle belongs to.
    """

    name: str
    vehicle_types: dict
    units: tuple
    description: str = ""
    source: str = ""
    jacobs: bool = False
    paper_train: str = ""
    axle_offsets_m: np.ndarray = field(default=None, repr=False)  # type: ignore[arg-type]  # always given
    axle_loads_n: np.ndarray = field(default=None, repr=False)  # type: ignore[arg-type]  # always given
    wheel_mass_kg: np.ndarray = field(default=None, repr=False)  # type: ignore[arg-type]  # always given
    unit_of_axle: np.ndarray = field(default=None, repr=False)  # type: ignore[arg-type]  # always given

    @property
    def n_axles(self):
        return len(self.axle_offsets_m)

    @property
    def length_m(self):
        """First to last axle (m)."""
        return float(self.axle_offsets_m[-1])

    @property
    def n_dof(self):
        return sum(u.n_dof for u in self.units)

    def unit_axles(self, i):
        return np.flatnonzero(self.unit_of_axle == i)

    def unit_matrices(self, i):
        """:class:`VehicleMatrices` of unit ``i`` (its axles in train order)."""
        return _assemble(self, self.units[i])

    def describe(self):
        n_cars = sum(len(u.cars) or 1 for u in self.units)  # a vehicle file's unit without car body (a sprung mass) counts once
        return (f"{self.name}: {n_cars} vehicles, {self.n_axles} axles, "
                f"{self.length_m:.2f} m first to last axle, "
                f"{self.axle_loads_n.sum() / 1000:.1f} kN total")


def moving_loads(axle_offsets_m, axle_loads_n, name="load train"):
    """A load-only train (MLM): axle offsets behind the first axle (m) and loads (N).

    It has no vehicle units, so only ``model="mlm"`` can run it.
    """
    offs = np.asarray(axle_offsets_m, dtype=float)
    loads = np.asarray(axle_loads_n, dtype=float)
    if offs.ndim != 1 or offs.shape != loads.shape or offs.size == 0:
        raise InputError("moving_loads: offsets (m) and loads (N) need the same non-zero length")
    if offs[0] != 0.0 or np.any(np.diff(offs) < 0):
        raise InputError("moving_loads: offsets must start at 0 m and not decrease")
    return Train(name=name, vehicle_types={}, units=(), axle_offsets_m=offs, axle_loads_n=loads,
                 wheel_mass_kg=np.zeros_like(offs), unit_of_axle=np.full(offs.shape, -1))


# ---------------------------------------------------------------------- loading
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
        check_plausible(train, source=f"train file {p.name}")  # warnings, not refusals
        return train
    raise InputError(f"train: {text!r} is unknown; allowed {', '.join(TRAIN_NAMES)}, "
                     f"Eurostar-table, HSLM-A1 .. HSLM-A10, or a .toml train file", field="train")


def _vehicle_type(name, d, source):
    where = f"{source}: vehicle_types.{name}"
    if not isinstance(d, dict):
        raise InputError(f"{where}: {d!r} is not a table; write [vehicle_types.{name}] with its fields")
    unknown = set(d) - set(_TYPE_FIELDS) - {"axle_load_kN"}
    if unknown:
        raise InputError(f"{where}: unknown field(s) {', '.join(sorted(map(str, unknown)))}; allowed "
                         f"{', '.join(list(_TYPE_FIELDS) + ['axle_load_kN'])}")
    vals = {}
    for key in _TYPE_FIELDS:
        v = field_view("toml", key)
        if key not in d:
            if key not in VEHICLE_OPTIONAL:
                raise InputError(f"{where}.{key}: missing ({v.unit}, allowed [{v.lo:g}, {v.hi:g}])")
            vals[key] = math.nan
            continue
        vals[key] = v.check(d[key], name=f"{where}.{key}", typed=True)
    axle = field_view("toml", "axle_load_kN")
    if "axle_load_kN" not in d:
        raise InputError(f"{where}.axle_load_kN: missing ({axle.unit}, allowed [{axle.lo:g}, {axle.hi:g}])")
    raw = d["axle_load_kN"]
    raw = raw if isinstance(raw, list) else [raw]
    if not 1 <= len(raw) <= 2:
        raise InputError(f"{where}.axle_load_kN: {raw!r} must be one value or [front, rear] (kN)")
    loads = tuple(axle.to_core(axle.check(v, name=f"{where}.axle_load_kN", typed=True)) for v in raw)
    if not math.isnan(vals["r_m"]) and vals["b_m"] >= vals["r_m"]:
        raise InputError(f"{where}.b_m: bogie wheelbase {vals['b_m']:g} m is not shorter than the pivot distance "
                         f"r_m {vals['r_m']:g} m: the axles of the two bogies would interleave or coincide; "
                         f"allowed b_m < r_m")
    if not math.isnan(vals["r_m"]) and vals["r_m"] + vals["b_m"] >= vals["d_m"]:
        raise InputError(f"{where}.r_m: {vals['r_m']:g} m plus wheelbase b_m {vals['b_m']:g} m "
                         f"is not shorter than the vehicle length d_m {vals['d_m']:g} m: axles of coupled "
                         f"vehicles would coincide or overlap; allowed r_m + b_m < d_m")
    return VehicleType(name=name, axle_load_n=loads, **vals)


#: Keys of a train file and of its composition entries.
_TRAIN_KEYS = ("name", "description", "source", "paper_train", "vehicle_types", "composition",
               "loads_differ_from_masses")
_VEHICLE_ENTRY_KEYS = ("vehicle", "count")
_JACOBS_ENTRY_KEYS = ("jacobs_set", "bogies", "axle_loads_kN", "reversed")
#: Largest relative difference between an axle load and the masses it carries times g.
AXLE_LOAD_REL_TOL = 0.005


def _check_loads(train, source):
    """Refuse axle loads that disagree with the vehicle masses (the MLM and the DIM would carry
    different trains) beyond :data:`AXLE_LOAD_REL_TOL`."""
    for row in check_train(train, rel_tol=AXLE_LOAD_REL_TOL):
        if row.item.startswith("F ") and not row.ok:
            raise InputError(
                f"{source}: {row.item}: axle load {row.table_value:.4g} kN disagrees with the masses, "
                f"{row.note} = {row.computed_value:.4g} kN (allowed within {100 * AXLE_LOAD_REL_TOL:g} %); "
                f"fix the loads or masses, or set loads_differ_from_masses = true if this is meant")


def train_from_mapping(data, source="train"):
    """Build and validate a :class:`Train` from a parsed TOML mapping.

    Unknown, misspelt and conflicting keys are refused; booleans must be booleans; axle loads must
    agree with the masses within 0.5 % unless ``loads_differ_from_masses = true``. A mapping with
    ``[vehicles.<NAME>]`` instead of ``[vehicle_types.<NAME>]`` is a vehicle file of bodies,
    wheelsets and stages (:func:`adm_sim.model.vehicles.train_from_vehicle_mapping`).
    """
    if not isinstance(data, dict):
        raise InputError(f"{source}: not a table of train fields")
    if "vehicles" in data and "vehicle_types" not in data:
        return _train_from_vehicle_file(data, source)
    differ = check_file_fields(data, _TRAIN_KEYS, source, TRAIN_NAMES)
    vt_raw = data.get("vehicle_types")
    if not isinstance(vt_raw, dict) or not vt_raw:
        raise InputError(f"{source}: missing table [vehicle_types.<NAME>]")
    types = {n: _vehicle_type(n, d, source) for n, d in vt_raw.items()}
    comp = data.get("composition")
    if not isinstance(comp, list) or not comp:
        raise InputError(f"{source}: missing [[composition]] entries")

    def _type(name, where):
        if not isinstance(name, str) or name not in types:
            raise InputError(f"{source}: {where}: vehicle type {name!r} not defined; "
                             f"defined: {', '.join(types)}")
        return types[name]

    units, front = [], 0.0  # front: front end of the next vehicle, from the train's front end
    jacobs = False
    for n, entry in enumerate(comp):
        where = f"composition[{n}]"
        if not isinstance(entry, dict):
            raise InputError(f"{source}: {where}: not a table")
        if "vehicle" in entry and "jacobs_set" in entry:
            raise InputError(f"{source}: {where}: has both 'vehicle' and 'jacobs_set'; give one per entry")
        if "vehicle" in entry:
            check_keys(entry, _VEHICLE_ENTRY_KEYS, f"{source}: {where}")
            vt = _type(entry["vehicle"], where)
            if math.isnan(vt.r_m):
                raise InputError(f"{source}: {where}: vehicle type {vt.name!r} has no r_m (m) "
                                 f"and cannot run as a conventional vehicle")
            count = entry.get("count", 1)
            if isinstance(count, str):
                raise InputError(f"{source}: {where}.count: {count!r} must be an integer without quotes; "
                                 f"allowed integer in [1, 100]")
            count = field_view("toml", "count").check(count, name=f"{source}: {where}.count")
            for _ in range(count):
                p1 = front + 0.5 * (vt.d_m - vt.r_m)
                p2 = front + 0.5 * (vt.d_m + vt.r_m)
                loads = vt.axle_load_n if len(vt.axle_load_n) == 2 else vt.axle_load_n * 2
                units.append(Unit(label=vt.name, cars=[(vt.name, (p1, p2))],
                                  bogies=[Bogie(vt.name, p1, loads[0]), Bogie(vt.name, p2, loads[1])],
                                  car_bogies=[(0, 1)]))
                front += vt.d_m
        elif "jacobs_set" in entry:
            check_keys(entry, _JACOBS_ENTRY_KEYS, f"{source}: {where}")
            if not isinstance(entry["jacobs_set"], list) or not isinstance(entry.get("bogies", []), list):
                raise InputError(f"{source}: {where}: 'jacobs_set' and 'bogies' must be lists of vehicle types")
            if not isinstance(entry.get("axle_loads_kN", []), list):
                raise InputError(f"{source}: {where}.axle_loads_kN: {entry['axle_loads_kN']!r} must be a list "
                                 f"of one load per bogie (kN)")
            jacobs = True
            cars = [_type(c, where) for c in entry["jacobs_set"]]
            bogie_types = [_type(b, where) for b in entry.get("bogies", [])]
            loads_kn = entry.get("axle_loads_kN", [])
            if len(cars) < 2:
                raise InputError(f"{source}: {where}.jacobs_set: needs at least 2 cars")
            if len(bogie_types) != len(cars) + 1 or len(loads_kn) != len(cars) + 1:
                raise InputError(f"{source}: {where}: 'bogies' and 'axle_loads_kN' need "
                                 f"len(jacobs_set) + 1 = {len(cars) + 1} entries")
            axles = field_view("toml", "axle_loads_kN")
            loads = [axles.to_core(axles.check(v, name=f"{source}: {where}.axle_loads_kN", typed=True))
                     for v in loads_kn]
            rev = entry.get("reversed", False)
            if not isinstance(rev, bool):
                raise InputError(f"{source}: {where}.reversed: {rev!r} must be true or false")
            if rev:
                cars, bogie_types, loads = cars[::-1], bogie_types[::-1], loads[::-1]
            for end in (cars[0], cars[-1]):
                if math.isnan(end.r_m):
                    raise InputError(f"{source}: {where}: end car {end.name!r} needs r_m (m)")
            pivots = [front + cars[0].d_m - cars[0].r_m]
            joint = front + cars[0].d_m
            for c in cars[1:]:
                pivots.append(joint)
                joint += c.d_m
            pivots.append(joint - cars[-1].d_m + cars[-1].r_m)
            front = joint
            unit_cars = [(c.name, (pivots[i], pivots[i + 1])) for i, c in enumerate(cars)]
            units.append(Unit(label="jacobs set", cars=unit_cars,
                              bogies=[Bogie(bt.name, pv, ld) for bt, pv, ld in zip(bogie_types, pivots, loads)],
                              car_bogies=[(i, i + 1) for i in range(len(cars))]))
        else:
            raise InputError(f"{source}: {where}: needs 'vehicle' or 'jacobs_set' (keys given: "
                             f"{', '.join(repr(k) for k in entry) or 'none'})")

    offs, loads, mw, owner = [], [], [], []
    for ui, u in enumerate(units):
        for b in u.bogies:
            bt = types[b.type_name]
            for e in (-0.5 * bt.b_m, 0.5 * bt.b_m):
                offs.append(b.pivot_m + e)
                loads.append(b.axle_load_n)
                mw.append(bt.m_w_kg)
                owner.append(ui)
    check_count("n_axles", len(offs), f"{source}: composition", f"{len(units)} units")
    length = max(offs) - min(offs) if offs else 0.0
    check_count("train_length_m", round(length, 3), f"{source}: composition",
                f"{len(units)} units, {len(offs)} axles")
    offs = np.asarray(offs)
    gaps = np.diff(offs)  # in build order: bogie after bogie, front to rear
    if np.any(gaps <= 0.0):
        i = int(np.argmax(gaps <= 0.0))
        b1, b2 = [b for u in units for b in u.bogies][i // 2], [b for u in units for b in u.bogies][(i + 1) // 2]
        raise InputError(f"{source}: the axles of bogies {b1.type_name!r} (pivot {b1.pivot_m - offs[0]:.3f} m) and "
                         f"{b2.type_name!r} (pivot {b2.pivot_m - offs[0]:.3f} m) coincide or interleave "
                         f"({gaps[i]:.3f} m apart): the wheelbases b_m do not fit between the pivots (d_m, r_m); "
                         f"allowed axles strictly one after another")
    first = offs.min()
    order = np.argsort(offs, kind="stable")
    train = Train(name=str(data["name"]), vehicle_types=types, units=tuple(units),
                 description=str(data.get("description", "")), source=str(data.get("source", source)),
                 jacobs=jacobs, paper_train=str(data.get("paper_train", "")),
                 axle_offsets_m=offs[order] - first,
                 axle_loads_n=np.asarray(loads)[order], wheel_mass_kg=np.asarray(mw)[order],
                 unit_of_axle=np.asarray(owner)[order])
    if not differ:
        _check_loads(train, source)
    return train


def _train_from_vehicle_file(data, source):
    """A :class:`Train` of a vehicle file (bodies, wheelsets, stages; :mod:`adm_sim.model.vehicles`)."""
    c = compile_vehicle_file(data, source, paper_trains=TRAIN_NAMES)
    units = tuple(Unit(label=u.label, cars=u.cars, bogies=[Bogie(n, x, math.nan) for n, x in u.others],
                       car_bogies=[() for _ in u.cars],
                       matrices=VehicleMatrices(M=u.M, K_s=u.K_s, C_s=u.C_s, Lw=u.Lw, k_p=u.k_p, c_p=u.c_p))
                  for u in c.units)
    return Train(name=data["name"], vehicle_types={}, units=units, description=str(data.get("description", "")),
                 source=str(data.get("source", source)), jacobs=any(len(u.cars) > 1 for u in units),
                 paper_train=str(data.get("paper_train", "")), axle_offsets_m=c.axle_offsets_m,
                 axle_loads_n=c.axle_loads_n, wheel_mass_kg=c.wheel_mass_kg, unit_of_axle=c.unit_of_axle)


def vehicle_file_mapping(train):
    """The vehicle-file mapping of a train built from vehicle types (:func:`adm_sim.model.vehicles.vehicle_mapping`
    with its ``paper_train`` and whether its loads differ from its masses); :func:`adm_sim.model.vehicles.to_toml`
    writes it. The shipped ``data/vehicles/*.toml`` are the paper's trains written so."""
    differ = any(r.item.startswith("F ") and not r.ok for r in check_train(train, rel_tol=AXLE_LOAD_REL_TOL))
    paper = train.paper_train or (train.name if train.name in TRAIN_NAMES else "")
    return vehicle_mapping(train, paper_train=paper, loads_differ=differ)


# ---------------------------------------------------------------------- vehicle matrices
def _assemble(train, unit):
    """Mass, stiffness and damping of one unit (Eq. 11), wheels held fixed."""
    if unit.matrices is not None:  # a vehicle file's unit: compiled by adm_sim.model.vehicles
        return unit.matrices
    types = train.vehicle_types
    nc, nb = len(unit.cars), len(unit.bogies)
    n = 2 * (nc + nb)
    M = np.zeros(n)
    K = np.zeros((n, n))
    C = np.zeros((n, n))
    # bogie data and the reference point of each car (middle between its pivots)
    for ci, (tname, (p1, p2)) in enumerate(unit.cars):
        t = types[tname]
        M[2 * ci], M[2 * ci + 1] = t.m_c_kg, t.J_c_kgm2
        centre = 0.5 * (p1 + p2)
        for bi, pv in zip(unit.car_bogies[ci], (p1, p2)):
            L = np.zeros(n)  # relative displacement bogie centre - car body pivot point
            L[2 * (nc + bi)] = 1.0
            L[2 * ci] = -1.0
            L[2 * ci + 1] = -(pv - centre)
            K += t.k_s_N_m * np.outer(L, L)
            C += t.c_s_Ns_m * np.outer(L, L)
    rows, kp, cp = [], [], []
    for bi, b in enumerate(unit.bogies):
        t = types[b.type_name]
        M[2 * (nc + bi)], M[2 * (nc + bi) + 1] = t.m_b_kg, t.J_b_kgm2
        for e in (-0.5 * t.b_m, 0.5 * t.b_m):
            L = np.zeros(n)
            L[2 * (nc + bi)] = 1.0
            L[2 * (nc + bi) + 1] = e
            rows.append((b.pivot_m + e, L))
            kp.append(t.k_p_N_m)
            cp.append(t.c_p_Ns_m)
    order = np.argsort([r[0] for r in rows], kind="stable")
    Lw = np.array([rows[i][1] for i in order])
    return VehicleMatrices(M=M, K_s=K, C_s=C, Lw=Lw, k_p=np.asarray(kp)[order], c_p=np.asarray(cp)[order])


# ---------------------------------------------------------------------- checks
#: Bogie frequencies quoted in Section 4.2.2 (Hz), by train and vehicle type.
PAPER_BOGIE_FREQ_HZ = {
    "ICE-2": {"PC": 5.84},
    "Eurostar": {"PC 2-8": 3.18},
    "Railjet": {"PC": 5.53},
    "ICE-4": {"powered PC": 4.78, "unpowered PC": 16.52},
}


@dataclass(frozen=True)
class CheckRow:
    train: str
    item: str
    table_value: float
    computed_value: float
    unit: str
    ok: bool
    note: str = ""


def check_train(train, rel_tol=0.005):
    """Consistency checks of a train's data.

    * Axle loads: F of every bogie against the masses it carries times g. Conventional vehicles:
      ``(m_c + 2 m_b + 4 m_w) g / 4``. Jacobs sets: the set total ``sum F`` against the set's
      total mass times g (the split between the bogies of an end car depends on its centre of
      gravity, which Table A1 does not give).
    * Bogie frequencies of Eq. (1) against the values quoted in Section 4.2.2.
    Returns a list of :class:`CheckRow`.
    """
    rows = []
    seen = set()
    types = train.vehicle_types
    for u in train.units:
        if u.matrices is not None:  # vehicle files check their loads against statics when loaded
            continue
        if len(u.cars) == 1:
            t = types[u.cars[0][0]]
            if t.name in seen:
                continue
            seen.add(t.name)
            calc = t.total_mass_kg * G_M_S2 / 4.0 / 1000.0
            tab = np.mean(t.axle_load_n) / 1000.0
            rows.append(CheckRow(train.name, f"F {t.name} (per axle)", tab, calc, "kN",
                                 abs(tab - calc) <= rel_tol * calc,
                                 "(m_c + 2 m_b + 4 m_w) g / 4"))
        else:
            key = ("set", tuple(c[0] for c in u.cars))
            if key in seen or ("set", key[1][::-1]) in seen:
                continue
            seen.add(key)
            mass = sum(types[c[0]].m_c_kg for c in u.cars)
            mass += sum(types[b.type_name].m_b_kg + 2 * types[b.type_name].m_w_kg for b in u.bogies)
            calc = mass * G_M_S2 / 1000.0
            tab = sum(2 * b.axle_load_n for b in u.bogies) / 1000.0
            rows.append(CheckRow(train.name, f"F Jacobs set of {len(u.cars)} cars (sum of axles)",
                                 tab, calc, "kN", abs(tab - calc) <= rel_tol * calc,
                                 "sum(m_c) + sum(m_b + 2 m_w) over the set, times g"))
    quoted = PAPER_BOGIE_FREQ_HZ.get(train.paper_train or train.name, {})
    for tname, t in types.items():
        if tname in quoted:
            q = quoted[tname]
            rows.append(CheckRow(train.name, f"n_p {tname} (Eq. 1)", q, t.bogie_frequency_hz, "Hz",
                                 abs(q - t.bogie_frequency_hz) <= 0.01, "quoted in Section 4.2.2"))
    return rows
