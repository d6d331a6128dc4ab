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
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from adm_sim.errors import InputError
from adm_sim.model.vehicles import G_M_S2

#: The trains of the paper (Section 3.2), shipped as ``data/trains/*.toml``.
TRAIN_NAMES = ("ICE-2", "Eurostar", "Railjet", "ICE-4")


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


# ---------------------------------------------------------------------- composition (axle positions)
def conventional_unit(vt, front_m):
    """One conventional vehicle of type ``vt`` whose front end is ``front_m`` behind the train's: its
    pivots at ``(d - r) / 2`` and ``(d + r) / 2`` behind its front end (the documented rule, module
    docstring). Returns the :class:`Unit` and the front end of the next vehicle (m)."""
    p1 = front_m + 0.5 * (vt.d_m - vt.r_m)
    p2 = front_m + 0.5 * (vt.d_m + vt.r_m)
    loads = vt.axle_load_n if len(vt.axle_load_n) == 2 else vt.axle_load_n * 2
    unit = Unit(label=vt.name, cars=[(vt.name, (p1, p2))],
                bogies=[Bogie(vt.name, p1, loads[0]), Bogie(vt.name, p2, loads[1])], car_bogies=[(0, 1)])
    return unit, front_m + vt.d_m


def jacobs_unit(cars, bogie_types, loads_n, front_m):
    """A Jacobs trainset of the vehicle types ``cars`` (front to rear) on ``len(cars) + 1`` bogies of
    ``bogie_types`` with axle loads ``loads_n`` (N): inner bogies on the joints between cars, the end
    cars' outer bogies at ``r`` from the joint. Returns the :class:`Unit` and the front end of the
    next vehicle (m)."""
    pivots = [front_m + cars[0].d_m - cars[0].r_m]
    joint = front_m + cars[0].d_m
    for c in cars[1:]:
        pivots.append(joint)
        joint += c.d_m
    pivots.append(joint - cars[-1].d_m + cars[-1].r_m)
    unit_cars = [(c.name, (pivots[i], pivots[i + 1])) for i, c in enumerate(cars)]
    unit = Unit(label="jacobs set", cars=unit_cars,
                bogies=[Bogie(bt.name, pv, ld) for bt, pv, ld in zip(bogie_types, pivots, loads_n)],
                car_bogies=[(i, i + 1) for i in range(len(cars))])
    return unit, joint


class AxleRows(NamedTuple):
    """The axles of a composition in build order (bogie after bogie, front to rear): offsets from the
    train's front end (m), loads (N), wheelset masses (kg), unit index; lists of n_axles."""

    offsets_m: list
    loads_n: list
    wheel_mass_kg: list
    unit: list


def axle_rows(units, types):
    """The two axles of every bogie of ``units`` at ``pivot -/+ b / 2`` (:class:`AxleRows`)."""
    rows = AxleRows([], [], [], [])
    for ui, u in enumerate(units):
        for b in u.bogies:
            bt = types[b.type_name]
            for e in (-0.5 * bt.b_m, 0.5 * bt.b_m):
                rows.offsets_m.append(b.pivot_m + e)
                rows.loads_n.append(b.axle_load_n)
                rows.wheel_mass_kg.append(bt.m_w_kg)
                rows.unit.append(ui)
    return rows


def train_of_units(name, types, units, rows, *, jacobs=False, description="", source="", paper_train=""):
    """The :class:`Train` of ``units`` of vehicle ``types`` with axles ``rows`` (:func:`axle_rows`):
    the axles sorted, offsets from the first axle."""
    offs = np.asarray(rows.offsets_m)
    first = offs.min()
    order = np.argsort(offs, kind="stable")
    return Train(name=name, vehicle_types=types, units=tuple(units), description=description, source=source,
                 jacobs=jacobs, paper_train=paper_train, axle_offsets_m=offs[order] - first,
                 axle_loads_n=np.asarray(rows.loads_n)[order], wheel_mass_kg=np.asarray(rows.wheel_mass_kg)[order],
                 unit_of_axle=np.asarray(rows.unit)[order])


def train_of_vehicles(compiled, name, *, description="", source="", paper_train=""):
    """The :class:`Train` of a composition of vehicles of bodies, wheelsets and stages
    (:class:`adm_sim.model.vehicles.CompiledTrain`); each unit carries its Eq. (11) matrices."""
    units = tuple(Unit(label=u.label, cars=u.cars, bogies=[Bogie(n, x, math.nan) for n, x in u.others],
                       car_bogies=[() for _ in u.cars],
                       matrices=VehicleMatrices(M=u.M, K_s=u.K_s, C_s=u.C_s, Lw=u.Lw, k_p=u.k_p, c_p=u.c_p))
                  for u in compiled.units)
    return Train(name=name, vehicle_types={}, units=units, description=description, source=source,
                 jacobs=any(len(u.cars) > 1 for u in units), paper_train=paper_train,
                 axle_offsets_m=compiled.axle_offsets_m, axle_loads_n=compiled.axle_loads_n,
                 wheel_mass_kg=compiled.wheel_mass_kg, unit_of_axle=compiled.unit_of_axle)


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


def consistency_rows(train, rel_tol):
    """Consistency checks of a train's data (``rel_tol``: the largest relative difference of an axle
    load from the masses it carries times g, :data:`adm_sim.fields.AXLE_LOAD_REL_TOL` for files).

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
