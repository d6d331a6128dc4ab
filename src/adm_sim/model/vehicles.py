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

G_M_S2 = 9.81  # gravitational acceleration used by the paper (Section 3.2.2)


class VehicleGroup:
    """One vehicle definition reduced to local matrices (x from its front), from the checked tables
    of a vehicle file (:mod:`adm_sim.inputs.train_files`): ``bodies``, ``wheels``, ``stages`` are
    lists of mappings of the file's keys (SI; ``None`` for an omitted optional key), the stages'
    bodies and wheelsets named in them. ``where`` names the vehicle in messages.

    Refused here (the model's own conditions): bodies or wheelsets not connected to the rest, two
    wheelsets at one x or one outside the vehicle, stages that leave a mechanism, a static wheel
    load that is not positive, static loads given for some wheelsets only.
    """

    def __init__(self, name, length_m, bodies, wheels, stages, where):
        self.name, self.length_m, self.stages = name, length_m, stages
        self._connected(bodies, wheels, stages, where)
        # DOF order: bodies that carry no wheelset (car bodies) first, then the others, file order each
        wheel_names = {w["name"] for w in wheels}
        on_wheel = {s["upper"] for s in stages if s["lower"] in wheel_names}
        self.bodies = [b for b in bodies if b["name"] not in on_wheel] + [b for b in bodies if b["name"] in on_wheel]
        self.n_cars = sum(b["name"] not in on_wheel for b in bodies)
        rows = self._assemble({w["name"]: w for w in wheels})
        self._place_wheels(rows, where)
        self.loads_n = self._static_loads(where)

    def _assemble(self, wheels):
        """Mass ``M``, secondary ``K_s``, ``C_s`` (Eq. 11); returns the primary stages
        ``[(wheelset, Lw row, k, c)]`` sorted by the wheelsets' x."""
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
        for s in self.stages:
            u, x = s["upper"], s["x_m"]
            if s["lower"] in wheels:
                L = np.zeros(n)
                L[dof[u]] = 1.0
                L[dof[u] + 1] = x - xb[u]
                rows.append((wheels[s["lower"]], L, s["k_N_m"], s["c_Ns_m"]))
                continue
            lo = s["lower"]
            L = np.zeros(n)  # relative displacement lower - upper at x
            L[dof[lo]] = 1.0
            L[dof[lo] + 1] = x - xb[lo]
            L[dof[u]] = -1.0
            L[dof[u] + 1] = -(x - xb[u])
            K += s["k_N_m"] * np.outer(L, L)
            C += s["c_Ns_m"] * np.outer(L, L)
        self.M, self.K_s, self.C_s = M, K, C
        rows.sort(key=lambda r: r[0]["x_m"])
        return rows

    def _place_wheels(self, rows, where):
        """The wheelsets front to rear, one per position, inside the vehicle; ``Lw``, ``k_p``, ``c_p``."""
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
        self.Lw = np.array([r[1] for r in rows])
        self.k_p = np.array([r[2] for r in rows])
        self.c_p = np.array([r[3] for r in rows])

    def points_m(self, body):
        """x of every stage acting on ``body`` (its extreme points: where comfort is read), or its
        centre of gravity when no stage acts on it."""
        pts = [s["x_m"] for s in self.stages if body in (s["upper"], s["lower"])]
        return pts or [next(b["x_m"] for b in self.bodies if b["name"] == body)]

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
    """A composition of vehicles (:func:`compose`); :func:`adm_sim.model.trains.train_of_vehicles`
    makes the :class:`~adm_sim.model.trains.Train` of it. Arrays (n_axles,): offsets behind the first
    axle (m), static loads (N), wheelset masses (kg), index of each axle's unit."""

    units: list
    axle_offsets_m: np.ndarray
    axle_loads_n: np.ndarray
    wheel_mass_kg: np.ndarray
    unit_of_axle: np.ndarray


def compose(groups, entries):
    """The composition ``entries`` ``[(vehicle name, count, reversed)]`` (front to rear) of the
    vehicles ``groups`` (:class:`VehicleGroup` by name), coupler to coupler, as a
    :class:`CompiledTrain`. A reversed vehicle runs rear end first: ``x -> length_m - x``, and its
    pitch coordinates change sign."""
    units, offs, loads, mw, owner = [], [], [], [], []
    front = 0.0
    for name, count, rev in entries:
        g = groups[name]
        for _ in range(count):
            units.append(_placed_unit(g, front, rev))
            perm = range(len(g.wheels) - 1, -1, -1) if rev else range(len(g.wheels))
            for i in perm:
                offs.append(front + (g.length_m - g.wheels[i]["x_m"]) if rev else front + g.wheels[i]["x_m"])
                loads.append(g.loads_n[i])
                mw.append(g.wheels[i]["mass_kg"])
                owner.append(len(units) - 1)
            front += g.length_m
    offs = np.asarray(offs)
    return CompiledTrain(units=units, axle_offsets_m=offs - offs[0], axle_loads_n=np.asarray(loads),
                         wheel_mass_kg=np.asarray(mw, dtype=float), unit_of_axle=np.asarray(owner))


def _placed_unit(g, front, rev):
    """Vehicle ``g`` with its front end ``front`` m behind the train's (:class:`CompiledUnit`)."""
    pos = (lambda x: front + (g.length_m - x)) if rev else (lambda x: front + x)
    perm = np.array(list(range(len(g.wheels) - 1, -1, -1) if rev else range(len(g.wheels))))
    cars, others = [], []
    for k, b in enumerate(g.bodies):
        pts = [pos(x) for x in g.points_m(b["name"])]
        if k < g.n_cars:
            cars.append((b["name"], (min(pts), max(pts))))
        else:
            others.append((b["name"], pos(b["x_m"])))
    Lw = g.Lw[perm].copy()
    if not rev:
        return CompiledUnit(g.name, cars, others, g.M, g.K_s, g.C_s, Lw, g.k_p, g.c_p)
    flip = np.ones(len(g.M))  # mirror: pitch coordinates change sign
    flip[1::2] = -1.0
    return CompiledUnit(g.name, cars, others, g.M, g.K_s * np.outer(flip, flip), g.C_s * np.outer(flip, flip),
                        Lw * flip, g.k_p[perm], g.c_p[perm])


# ---------------------------------------------------------------------- the paper's trains as vehicle files
def _unit_front(train, unit):
    """Front end of a unit (m from the train's front end, as :func:`adm_sim.model.trains.conventional_unit`
    and :func:`adm_sim.model.trains.jacobs_unit` place it) and its coupler-to-coupler length."""
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
    (:func:`adm_sim.inputs.train_files.vehicle_file_mapping` fills them from the train)."""
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
