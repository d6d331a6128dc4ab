"""Vehicles as data: any planar vehicle of rigid bodies, wheelsets and linear spring-damper stages.

A vehicle file (TOML, SI units; see docs/vehicles.md and ``data/vehicles/*.toml``) describes each
vehicle as a vertically coupled group -- one coach, or a whole trainset whose cars share (Jacobs)
bogies -- and a composition of such groups. It compiles to the same structures as the paper's
trains (:class:`adm_sim.model.trains.Train` of :class:`~adm_sim.model.trains.Unit` s whose
:class:`~adm_sim.model.trains.VehicleMatrices` are Eq. (11)'s mass, stiffness and damping), so the numpy
stepper and the numba kernels run it unchanged.

File schema
-----------
``name``, ``description``, ``source``, ``loads_differ_from_masses``
    As in a train file (:mod:`adm_sim.model.trains`).
``[vehicles.<NAME>]``
    ``length_m``: coupler to coupler (the next vehicle's front is this far behind this one's);
    ``[[vehicles.<NAME>.bodies]]``: ``name``, ``mass_kg``, ``x_m`` (centre of gravity, behind the
    vehicle's front) and ``pitch_inertia_kgm2`` (about the centre of gravity; omit it for a body
    that does not pitch, e.g. a point mass);
    ``[[vehicles.<NAME>.wheelsets]]``: ``name``, ``x_m``, ``mass_kg`` (unsprung, moves with the
    rail) and optional ``static_load_kN`` (else from statics);
    ``[[vehicles.<NAME>.stages]]``: ``upper`` (a body), ``lower`` (a body or a wheelset),
    ``x_m`` (where it acts on both), ``k_N_m``, ``c_Ns_m``. Each wheelset hangs on one stage.
``[[composition]]``
    ``vehicle = "<NAME>"``, optional ``count`` (1..100) and ``reversed`` (the vehicle runs rear
    end first: ``x -> length_m - x``).

Model (paper Eq. 11, about static equilibrium, z downwards). Each body has bounce ``z`` and pitch
``theta`` about its centre of gravity ``x_b``; a point at ``x`` moves by ``z + (x - x_b) theta``.
A stage between bodies ``u`` (upper) and ``l`` (lower) at ``x`` adds ``k L L^T`` to the stiffness
and ``c L L^T`` to the damping with ``L = e_l(x) - e_u(x)``; a stage to a wheelset is the primary
stage of that axle: ``Lw`` row ``e_u(x)``, ``k_p = k``, ``c_p = c``. The wheelset follows the rail
(Section 1) and its mass acts on the bridge (Eq. 13). DOFs: bodies that carry no wheelset first
(the car bodies, in file order), then the others (bogies, file order), ``[z, theta]`` each.
Static wheel loads from statics (wheels held): ``K x = M g`` on the bounce DOFs,
``F_i = k_i Lw_i x + m_w,i g``; a wheelset may give ``static_load_kN`` instead (the paper's tables
print loads for the Eurostar end cars whose centre of gravity is off the pivots' middle); then
the group's total must equal its weight within 0.5 % unless ``loads_differ_from_masses = true``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from adm_sim.errors import InputError
from adm_sim.fields import check_int, check_number

G_M_S2 = 9.81  # the paper's g (Section 3.2.2), as adm_sim.model.trains

#: ``key: (unit, lo, hi, required)`` of each table of a vehicle (ranges in SI, closed).
BODY_KEYS = {"name": ("", None, None, True), "mass_kg": ("kg", 1.0, 5.0e5, True),
             "pitch_inertia_kgm2": ("kg m^2", 1.0, 1.0e8, False), "x_m": ("m", -100.0, 1000.0, True)}
WHEELSET_KEYS = {"name": ("", None, None, True), "mass_kg": ("kg", 0.0, 1.0e4, True),
                 "x_m": ("m", -100.0, 1000.0, True), "static_load_kN": ("kN", 1.0, 500.0, False)}
STAGE_KEYS = {"upper": ("", None, None, True), "lower": ("", None, None, True),
              "x_m": ("m", -100.0, 1000.0, True), "k_N_m": ("N/m", 1.0, 1.0e10, True),
              "c_Ns_m": ("N s/m", 0.0, 1.0e8, True)}
VEHICLE_KEYS = ("length_m", "bodies", "wheelsets", "stages")
LENGTH_RANGE_M = (0.0, 1000.0)
FILE_KEYS = ("name", "description", "source", "paper_train", "vehicles", "composition",
             "loads_differ_from_masses")
ENTRY_KEYS = ("vehicle", "count", "reversed")
#: Largest relative difference between given static loads and the group's weight.
LOAD_REL_TOL = 0.005


def check_keys(d, allowed, where):
    """Refuse the keys of ``d`` not in ``allowed`` (a misspelt key is never ignored), naming them
    and the allowed ones after ``where``."""
    extra = [k for k in d if k not in allowed]
    if extra:
        raise InputError(f"{where}: unknown key(s) {', '.join(repr(k) for k in extra)}; "
                         f"allowed {', '.join(allowed)}")


def check_file_fields(data, allowed, source, paper_trains=()):
    """The top-level fields both train file forms share, checked once for both (the form with
    ``[vehicle_types.<NAME>]`` of :func:`adm_sim.model.trains.train_from_mapping` and the vehicle file of
    :func:`compile_vehicle_file`): no key outside ``allowed``, a non-empty ``name``, text in
    ``description``, ``source`` and ``paper_train`` (one of ``paper_trains`` or empty), a boolean
    ``loads_differ_from_masses``; returns that boolean (default ``False``)."""
    check_keys(data, allowed, source)
    if "name" not in data:
        raise InputError(f"{source}: missing field 'name'")
    if not isinstance(data["name"], str) or not data["name"].strip():
        raise InputError(f"{source}: name: {data['name']!r} must be a non-empty string")
    for key in ("description", "source", "paper_train"):
        if key in data and not isinstance(data[key], str):
            raise InputError(f"{source}: {key}: {data[key]!r} must be text in quotes")
    if data.get("paper_train", "") not in ("",) + tuple(paper_trains):
        raise InputError(f"{source}: paper_train: {data['paper_train']!r} is not a train of the paper; "
                         f"allowed {', '.join(paper_trains)} (or omit it)")
    differ = data.get("loads_differ_from_masses", False)
    if not isinstance(differ, bool):
        raise InputError(f"{source}: loads_differ_from_masses: {differ!r} must be true or false")
    return differ


def _table(d, spec, where):
    """Checked values of one body/wheelset/stage table (``None`` for an omitted optional key)."""
    if not isinstance(d, dict):
        raise InputError(f"{where}: {d!r} is not a table; allowed keys {', '.join(spec)}")
    check_keys(d, tuple(spec), where)
    out = {}
    for key, (unit, lo, hi, required) in spec.items():
        if key not in d:
            if required:
                rng = f" ({unit}, allowed [{lo:g}, {hi:g}])" if unit else " (text)"
                raise InputError(f"{where}.{key}: missing{rng}")
            out[key] = None
            continue
        if not unit:
            if not isinstance(d[key], str) or not d[key].strip():
                raise InputError(f"{where}.{key}: {d[key]!r} must be a non-empty name in quotes")
            out[key] = d[key]
        else:
            out[key] = check_number(f"{where}.{key}", d[key], unit, lo, hi)
    return out


class _Group:
    """One vehicle definition, checked and reduced to local matrices (x from its front)."""

    def __init__(self, name, d, source):
        where = f"{source}: vehicles.{name}"
        if not isinstance(d, dict):
            raise InputError(f"{where}: {d!r} is not a table; write [vehicles.{name}] with "
                             f"{', '.join(VEHICLE_KEYS)}")
        check_keys(d, VEHICLE_KEYS, where)
        self.name = name
        if "length_m" not in d:
            raise InputError(f"{where}.length_m: missing (m, allowed [{LENGTH_RANGE_M[0]:g}, {LENGTH_RANGE_M[1]:g}])")
        self.length_m = check_number(f"{where}.length_m", d["length_m"], "m", *LENGTH_RANGE_M)
        lists = {}
        for key in ("bodies", "wheelsets", "stages"):
            v = d.get(key)
            if not isinstance(v, list) or not v:
                raise InputError(f"{where}.{key}: missing or empty; allowed a list of tables "
                                 f"([[vehicles.{name}.{key}]])")
            lists[key] = v
        bodies = [_table(b, BODY_KEYS, f"{where}.bodies[{i}]") for i, b in enumerate(lists["bodies"])]
        wheels = [_table(w, WHEELSET_KEYS, f"{where}.wheelsets[{i}]") for i, w in enumerate(lists["wheelsets"])]
        stages = [_table(s, STAGE_KEYS, f"{where}.stages[{i}]") for i, s in enumerate(lists["stages"])]
        names = [b["name"] for b in bodies] + [w["name"] for w in wheels]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise InputError(f"{where}: name(s) {', '.join(map(repr, dup))} used twice; allowed one name per "
                             f"body and wheelset")
        body_ix = {b["name"]: i for i, b in enumerate(bodies)}
        wheel_ix = {w["name"]: i for i, w in enumerate(wheels)}
        for i, s in enumerate(stages):
            if s["upper"] not in body_ix:
                raise InputError(f"{where}.stages[{i}].upper: {s['upper']!r} is not a body; allowed "
                                 f"{', '.join(map(repr, body_ix))}")
            if s["lower"] not in body_ix and s["lower"] not in wheel_ix:
                raise InputError(f"{where}.stages[{i}].lower: {s['lower']!r} is not a body or wheelset; allowed "
                                 f"{', '.join(map(repr, list(body_ix) + list(wheel_ix)))}")
            if s["lower"] == s["upper"]:
                raise InputError(f"{where}.stages[{i}]: joins body {s['upper']!r} to itself; allowed two "
                                 f"different bodies, or a body and a wheelset")
        for w in wheels:
            n = sum(s["lower"] == w["name"] for s in stages)
            if n != 1:
                raise InputError(f"{where}: wheelset {w['name']!r} hangs on {n} stages; allowed exactly 1 "
                                 f"(stages with lower = {w['name']!r})")
        self._connected(bodies, wheels, stages, where)
        # DOF order: bodies that carry no wheelset (car bodies) first, then the others, file order each
        on_wheel = {s["upper"] for s in stages if s["lower"] in wheel_ix}
        order = [i for i, b in enumerate(bodies) if b["name"] not in on_wheel]
        order += [i for i, b in enumerate(bodies) if b["name"] in on_wheel]
        self.bodies = [bodies[i] for i in order]
        self.n_cars = sum(b["name"] not in on_wheel for b in bodies)
        dof = {b["name"]: 2 * k for k, b in enumerate(self.bodies)}
        n = 2 * len(self.bodies)
        xb = {b["name"]: b["x_m"] for b in self.bodies}
        M = np.zeros(n)
        for b in self.bodies:
            M[dof[b["name"]]] = b["mass_kg"]
            J = b["pitch_inertia_kgm2"]
            M[dof[b["name"]] + 1] = math.inf if J is None else J  # no inertia given: the body does not pitch
        K, C = np.zeros((n, n)), np.zeros((n, n))
        rows = []
        for s in stages:
            u, x = s["upper"], s["x_m"]
            if s["lower"] in wheel_ix:
                L = np.zeros(n)
                L[dof[u]] = 1.0
                L[dof[u] + 1] = x - xb[u]
                rows.append((wheels[wheel_ix[s["lower"]]], L, s["k_N_m"], s["c_Ns_m"]))
                continue
            lo = s["lower"]
            L = np.zeros(n)  # relative displacement lower - upper at x
            L[dof[lo]] = 1.0
            L[dof[lo] + 1] = x - xb[lo]
            L[dof[u]] = -1.0
            L[dof[u] + 1] = -(x - xb[u])
            K += s["k_N_m"] * np.outer(L, L)
            C += s["c_Ns_m"] * np.outer(L, L)
        rows.sort(key=lambda r: r[0]["x_m"])
        xs = [r[0]["x_m"] for r in rows]
        if np.any(np.diff(xs) <= 0.0):
            i = int(np.argmax(np.diff(xs) <= 0.0))
            raise InputError(f"{where}: wheelsets {rows[i][0]['name']!r} and {rows[i + 1][0]['name']!r} stand at "
                             f"the same x_m = {xs[i]:g} m; allowed one wheelset per position")
        for r in rows:
            if not 0.0 <= r[0]["x_m"] <= self.length_m:
                raise InputError(f"{where}: wheelset {r[0]['name']!r} x_m = {r[0]['x_m']:g} m lies outside the "
                                 f"vehicle; allowed [0, length_m = {self.length_m:g}] m")
        self.wheels = [r[0] for r in rows]
        self.M, self.K_s, self.C_s = M, K, C
        self.Lw = np.array([r[1] for r in rows])
        self.k_p = np.array([r[2] for r in rows])
        self.c_p = np.array([r[3] for r in rows])
        self.loads_n = self._static_loads(where)

    @staticmethod
    def _connected(bodies, wheels, stages, where):
        """Every body reaches a wheelset through stages (one rigid group per vehicle)."""
        adj = {b["name"]: set() for b in bodies} | {w["name"]: set() for w in wheels}
        for s in stages:
            adj[s["upper"]].add(s["lower"])
            adj[s["lower"]].add(s["upper"])
        seen, todo = set(), [w["name"] for w in wheels][:1]
        while todo:
            k = todo.pop()
            if k not in seen:
                seen.add(k)
                todo.extend(adj[k] - seen)
        lost = [n for n in adj if n not in seen]
        if lost:
            raise InputError(f"{where}: bodies/wheelsets {', '.join(map(repr, lost))} are not connected to the "
                             f"rest by stages; allowed one connected vehicle (split it into two vehicles, or add "
                             f"the stage that joins them)")

    def _static_loads(self, where):
        """Static wheel loads (N): given ones, or from statics with the wheels held."""
        K = self.K_s + self.Lw.T @ (self.k_p[:, None] * self.Lw)
        free = np.isfinite(self.M)
        Kf = K[np.ix_(free, free)]
        if np.linalg.matrix_rank(Kf) < Kf.shape[0]:
            pitch = [b["name"] for b in self.bodies if b["pitch_inertia_kgm2"] is not None
                     and not np.any(K[2 * self.bodies.index(b) + 1] != 0.0)]
            what = (f"body {pitch[0]!r} has a pitch inertia but no stage that resists pitching; allowed: omit "
                    f"pitch_inertia_kgm2 or add stages at two x_m") if pitch else \
                "the stages leave a mechanism (a body free to move without deforming a stage)"
            raise InputError(f"{where}: {what}")
        f = np.zeros(len(self.M))
        for k, b in enumerate(self.bodies):
            f[2 * k] = b["mass_kg"] * G_M_S2
        x = np.zeros(len(self.M))
        x[free] = np.linalg.solve(Kf, f[free])
        statics = self.k_p * (self.Lw @ x) + np.array([w["mass_kg"] for w in self.wheels]) * G_M_S2
        given = [w["static_load_kN"] for w in self.wheels]
        if any(g is not None for g in given) and not all(g is not None for g in given):
            miss = [w["name"] for w in self.wheels if w["static_load_kN"] is None]
            raise InputError(f"{where}: static_load_kN given for some wheelsets but not for "
                             f"{', '.join(map(repr, miss))}; allowed all or none")
        if given[0] is not None:
            return np.array(given, dtype=float) * 1000.0
        for w, F in zip(self.wheels, statics):
            if not F > 0.0:
                raise InputError(f"{where}: wheelset {w['name']!r}: static wheel load {F / 1000:.4g} kN from the "
                                 f"masses and positions is not positive (the vehicle would tip); allowed > 0 kN: "
                                 f"move the bodies' x_m between the wheelsets")
        return statics

    @property
    def weight_n(self):
        return G_M_S2 * (sum(b["mass_kg"] for b in self.bodies) + sum(w["mass_kg"] for w in self.wheels))


class CompiledUnit(NamedTuple):
    """One vehicle of the composition: ``label``; ``cars`` [(body, (first, last stage point))] for
    the bodies that carry no wheelset, ``others`` [(body, x)] for the rest (m behind the train's
    front end); Eq. (11) matrices ``M`` (n_dof,), ``K_s``, ``C_s`` (n_dof, n_dof), ``Lw``
    (n_axles, n_dof), ``k_p``, ``c_p`` (n_axles,), axles in train order."""

    label: str
    cars: list
    others: list
    M: np.ndarray
    K_s: np.ndarray
    C_s: np.ndarray
    Lw: np.ndarray
    k_p: np.ndarray
    c_p: np.ndarray


class CompiledTrain(NamedTuple):
    """A vehicle file compiled (:func:`compile_vehicle_file`); :func:`adm_sim.model.trains.train_from_mapping`
    makes the :class:`~adm_sim.model.trains.Train` of it. Arrays (n_axles,): offsets behind the first
    axle (m), static loads (N), wheelset masses (kg), index of each axle's unit."""

    units: list
    axle_offsets_m: np.ndarray
    axle_loads_n: np.ndarray
    wheel_mass_kg: np.ndarray
    unit_of_axle: np.ndarray


def compile_vehicle_file(data, source="vehicle file", paper_trains=()):
    """A parsed vehicle file (the ``[vehicles.<NAME>]`` schema) checked and compiled to
    :class:`CompiledTrain`; ``paper_trains``: the names ``paper_train`` may take."""
    differ = check_file_fields(data, FILE_KEYS, source, paper_trains)
    raw = data.get("vehicles")
    if not isinstance(raw, dict) or not raw:
        raise InputError(f"{source}: vehicles: missing table [vehicles.<NAME>]")
    groups = {n: _Group(n, d, source) for n, d in raw.items()}
    if not differ:
        for g in groups.values():
            if g.wheels[0]["static_load_kN"] is not None and abs(g.loads_n.sum() - g.weight_n) > LOAD_REL_TOL * g.weight_n:
                raise InputError(f"{source}: vehicles.{g.name}: static loads sum to {g.loads_n.sum() / 1000:.4g} kN, "
                                 f"the masses weigh {g.weight_n / 1000:.4g} kN (allowed within "
                                 f"{100 * LOAD_REL_TOL:g} %); fix them or set loads_differ_from_masses = true")
    comp = data.get("composition")
    if not isinstance(comp, list) or not comp:
        raise InputError(f"{source}: composition: missing [[composition]] entries")
    units, offs, loads, mw, owner = [], [], [], [], []
    front = 0.0
    for n, entry in enumerate(comp):
        where = f"{source}: composition[{n}]"
        if not isinstance(entry, dict):
            raise InputError(f"{where}: not a table")
        check_keys(entry, ENTRY_KEYS, where)
        name = entry.get("vehicle")
        if name not in groups:
            raise InputError(f"{where}.vehicle: {name!r} is not defined; defined: {', '.join(groups)}")
        count = entry.get("count", 1)
        if isinstance(count, (str, bool)):
            raise InputError(f"{where}.count: {count!r} must be an integer without quotes; allowed integer in [1, 100]")
        count = check_int(f"{where}.count", count, 1, 100)
        rev = entry.get("reversed", False)
        if not isinstance(rev, bool):
            raise InputError(f"{where}.reversed: {rev!r} must be true or false")
        g = groups[name]
        for _ in range(count):
            pos = (lambda x, g=g: front + (g.length_m - x)) if rev else (lambda x: front + x)
            wheel_order = range(len(g.wheels) - 1, -1, -1) if rev else range(len(g.wheels))
            perm = np.array(list(wheel_order))
            cars, others = [], []
            for k, b in enumerate(g.bodies):
                pts = [pos(s) for s in _points(raw[name], b["name"])]
                if k < g.n_cars:
                    cars.append((b["name"], (min(pts), max(pts))))
                else:
                    others.append((b["name"], pos(b["x_m"])))
            Lw = g.Lw[perm].copy()
            M = g.M
            if rev:  # mirror: pitch coordinates change sign
                flip = np.ones(len(M))
                flip[1::2] = -1.0
                Lw = Lw * flip
                units.append(CompiledUnit(name, cars, others, M, g.K_s * np.outer(flip, flip),
                                          g.C_s * np.outer(flip, flip), Lw, g.k_p[perm], g.c_p[perm]))
            else:
                units.append(CompiledUnit(name, cars, others, M, g.K_s, g.C_s, Lw, g.k_p, g.c_p))
            for i in perm:
                offs.append(pos(g.wheels[i]["x_m"]))
                loads.append(g.loads_n[i])
                mw.append(g.wheels[i]["mass_kg"])
                owner.append(len(units) - 1)
            front += g.length_m
    from adm_sim.fields import check_count  # noqa: PLC0415  beside its use

    check_count("n_axles", len(offs), f"{source}: composition", f"{len(units)} vehicles")
    offs = np.asarray(offs)
    check_count("train_length_m", round(float(offs.max() - offs.min()), 3), f"{source}: composition",
                f"{len(units)} vehicles, {len(offs)} axles")
    gaps = np.diff(offs)
    if np.any(gaps <= 0.0):
        i = int(np.argmax(gaps <= 0.0))
        raise InputError(f"{source}: composition: axles {i} and {i + 1} are {gaps[i]:.3f} m apart (vehicles "
                         f"{units[owner[i]].label!r}, {units[owner[i + 1]].label!r}); allowed axles strictly one "
                         f"after another: check length_m and the wheelsets' x_m")
    return CompiledTrain(units=units, axle_offsets_m=offs - offs[0], axle_loads_n=np.asarray(loads),
                         wheel_mass_kg=np.asarray(mw, dtype=float), unit_of_axle=np.asarray(owner))


def _points(d, body):
    """x of every stage acting on ``body`` (its extreme points: where comfort is read)."""
    pts = [s["x_m"] for s in d["stages"] if body in (s["upper"], s["lower"])]
    return pts or [next(b["x_m"] for b in d["bodies"] if b["name"] == body)]


# ---------------------------------------------------------------------- the paper's trains as vehicle files
def _unit_front(train, unit):
    """Front end of a unit (m from the train's front end, as :func:`adm_sim.model.trains.train_from_mapping`
    places it) and its coupler-to-coupler length."""
    types = train.vehicle_types
    first = types[unit.cars[0][0]]
    if len(unit.cars) == 1:
        return unit.cars[0][1][0] - 0.5 * (first.d_m - first.r_m), first.d_m
    return unit.cars[0][1][0] - (first.d_m - first.r_m), sum(types[c[0]].d_m for c in unit.cars)


def vehicle_mapping(train, paper_train="", loads_differ=False):
    """The vehicle-file mapping of a train built from vehicle types (Table A1): one vehicle per
    distinct unit, bodies (car bodies, then bogies), wheelsets with the train's static loads and
    the secondary and primary stages in the order :func:`adm_sim.model.trains._assemble` sums them, so
    that the file gives the same matrices (to rounding of the positions, ~1e-15 relative).
    ``paper_train``, ``loads_differ``: the file's keys of these names
    (:func:`adm_sim.model.trains.vehicle_file_mapping` fills them from the train)."""
    types = train.vehicle_types
    vehicles, comp, seen = {}, [], {}
    for unit in train.units:
        front, length = _unit_front(train, unit)
        key = (tuple(c[0] for c in unit.cars), tuple(b.type_name for b in unit.bogies),
               tuple(round(b.axle_load_n, 6) for b in unit.bogies),
               tuple(round(b.pivot_m - front, 9) for b in unit.bogies))
        if key not in seen:
            name = unit.label if len(unit.cars) == 1 else f"Jacobs set {len(seen) + 1}"
            name = name if name not in vehicles else f"{name} {len(seen) + 1}"
            seen[key] = name
            bodies, wheels, stages = [], [], []
            for ci, (tname, (p1, p2)) in enumerate(unit.cars):
                t = types[tname]
                bodies.append({"name": f"car {ci + 1}", "mass_kg": t.m_c_kg, "pitch_inertia_kgm2": t.J_c_kgm2,
                               "x_m": 0.5 * (p1 + p2) - front})
            for bi, b in enumerate(unit.bogies):
                t = types[b.type_name]
                bodies.append({"name": f"bogie {bi + 1}", "mass_kg": t.m_b_kg, "pitch_inertia_kgm2": t.J_b_kgm2,
                               "x_m": b.pivot_m - front})
            for ci, (tname, pivots) in enumerate(unit.cars):
                t = types[tname]
                for bi, pv in zip(unit.car_bogies[ci], pivots):
                    stages.append({"upper": f"car {ci + 1}", "lower": f"bogie {bi + 1}", "x_m": pv - front,
                                   "k_N_m": t.k_s_N_m, "c_Ns_m": t.c_s_Ns_m})
            for bi, b in enumerate(unit.bogies):
                t = types[b.type_name]
                for ei, e in enumerate((-0.5 * t.b_m, 0.5 * t.b_m)):
                    w = f"wheelset {2 * bi + ei + 1}"
                    wheels.append({"name": w, "mass_kg": t.m_w_kg, "x_m": b.pivot_m + e - front,
                                   "static_load_kN": b.axle_load_n / 1000.0})
                    stages.append({"upper": f"bogie {bi + 1}", "lower": w, "x_m": b.pivot_m + e - front,
                                   "k_N_m": t.k_p_N_m, "c_Ns_m": t.c_p_Ns_m})
            vehicles[name] = {"length_m": length, "bodies": bodies, "wheelsets": wheels, "stages": stages}
        name = seen[key]
        if comp and comp[-1]["vehicle"] == name:
            comp[-1]["count"] = comp[-1].get("count", 1) + 1
        else:
            comp.append({"vehicle": name})
    out = {"name": train.name, "description": train.description,
           "source": f"{train.source}; bodies, wheelsets and stages written from the vehicle types by "
                     f"adm_sim.model.vehicles.vehicle_mapping",
           "paper_train": paper_train}
    if loads_differ:
        out["loads_differ_from_masses"] = True
    out["vehicles"] = vehicles
    out["composition"] = comp
    return {k: v for k, v in out.items() if v != ""}


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, int):
        return str(v)
    return repr(float(f"{v:.12g}"))  # 12 digits: the positions without their binary noise (4.7, not 4.699999999999999)


def to_toml(mapping, header=""):
    """TOML text of a vehicle-file mapping (floats written so they read back bit for bit)."""
    lines = [f"# {h}" if h else "#" for h in header.splitlines()]
    for k, v in mapping.items():
        if k not in ("vehicles", "composition"):
            lines.append(f"{k} = {_toml_value(v)}")
    for name, veh in mapping["vehicles"].items():
        lines += ["", f'[vehicles."{name}"]', f"length_m = {_toml_value(veh['length_m'])}"]
        for key in ("bodies", "wheelsets", "stages"):
            for row in veh[key]:
                lines += ["", f'[[vehicles."{name}".{key}]]'] + [f"{a} = {_toml_value(b)}" for a, b in row.items()]
    for entry in mapping["composition"]:
        lines += ["", "[[composition]]"] + [f"{a} = {_toml_value(b)}" for a, b in entry.items()]
    return "\n".join(lines) + "\n"
