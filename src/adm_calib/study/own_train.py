"""The paper's method for any train: a train file or a vehicle file as a study train.

The paper ends by restricting its lower-bound functions to the four trains it studied (Section 4.3:
the functions "should only be used for the analysed train types"). For any other train the whole
method runs again: the parametric study of Section 3.3 (1110 bridges, the same speeds, grids, rules
and statuses), the lower-bound fit of Section 4.2.1 (Eq. 20, Appendix B) and the rules of Section 4.3.
This module holds what a train *file* adds to that:

* :func:`read_train_file`: the file read once, its SHA-256 taken over the bytes read, parsed as a
  train file (``[vehicle_types]``, :mod:`adm_sim.model.trains`) or a vehicle file (``[vehicles]``,
  :mod:`adm_sim.model.vehicles`); a file without vehicles (a load train) is refused: the DIM, and
  with it Δζ_VBI, needs vehicles.
* :func:`check_dim_step`: the vehicles must be integrable by the DIM's explicit RK4 at the study's
  time step (the step follows the bridge, :func:`adm_sim.integrate.step_grid.make_grid`). Every
  eigenvalue ``lambda`` of a vehicle group with its wheels held (Eq. 11: ``M x'' + C x' + K x = 0``)
  must satisfy ``|R(lambda dt)| <= 1`` with RK4's amplification ``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24``
  at the largest time step of the selected cases (their slowest lane).
* :func:`study_trains`: the ``--trains`` items resolved: built-in names, or files; HSLM-A (load
  trains) refused with the reason.
* :func:`check_resume`: the study directory records each file's name, content and SHA-256
  (``study.json`` ``train_files``); a resume with another file under the same train name, or a
  built-in train where the study ran a file (and the reverse), is refused.
* :func:`train_quantities`: the quantities Section 4.2.2 reads the results by (bogie frequency
  Eq. (1), masses, car lengths) for any train.
"""

from __future__ import annotations

import hashlib
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError
from adm_sim.files import input_file

#: Largest |R(z)| accepted (RK4 amplification of an eigenvalue); 1 up to rounding.
RK4_GAIN_MAX = 1.0 + 1e-9
#: Largest |omega dt| of an undamped mode within RK4's stability region: 2 sqrt(2).
RK4_UNDAMPED_LIMIT = 2.0 * math.sqrt(2.0)
#: Train names: printable, as record keys, TOML keys and (made safe) file names.
NAME_MAX_CHARS = 60


@dataclass(frozen=True, repr=False)
class TrainFile:
    """A train read from a file: its name (the study's ``train`` key), the path as typed, the
    SHA-256 of its bytes, its text, its kind (``train file`` or ``vehicle file``) and the
    :class:`adm_sim.model.trains.Train`."""

    name: str
    path: str
    sha256: str
    content: str
    kind: str
    train: object = field(compare=False)

    def record(self):
        """What ``study.json`` keeps of the file (``train_files[name]``)."""
        return {"path": self.path, "file_name": Path(self.path).name, "sha256": self.sha256, "kind": self.kind,
                "content": self.content}

    def __repr__(self):
        return f"TrainFile({self.name!r} from {self.path!r}, sha256 {self.sha256[:12]}...)"


def sha256_hex(data):
    return hashlib.sha256(data).hexdigest()


def parse_train_text(text, sha256, path, option="--trains"):
    """A :class:`TrainFile` from the text of a train or vehicle file (``path`` names it in messages)."""
    from adm_sim.model.trains import train_from_mapping  # noqa: PLC0415  numpy models: only when a file is read

    where = f"{option}: {str(path)!r}"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{where}: not valid TOML ({exc})") from None
    if not ("vehicle_types" in data or "vehicles" in data):
        raise InputError(f"{where}: holds no vehicles (neither [vehicle_types.<NAME>] nor [vehicles.<NAME>]): a "
                         f"load train cannot run the DIM, so no dz_VBI can be computed for it; allowed a train file "
                         f"or a vehicle file (docs/vehicles.md)")
    kind = "vehicle file" if "vehicles" in data and "vehicle_types" not in data else "train file"
    train = train_from_mapping(data, source=where)
    name = check_train_name(train, where)
    return TrainFile(name=name, path=str(path), sha256=sha256, content=text, kind=kind, train=train)


def read_train_file(text, option="--trains"):
    """Read a train or vehicle file once: SHA-256 of its bytes, parsed, checked (one-line errors)."""
    from adm_sim.files import read_text  # noqa: PLC0415  beside its use
    from adm_sim.model.plausibility import check_train as check_plausible  # noqa: PLC0415  as above

    p = input_file(text, option, "train or vehicle file")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(f"{option}: {str(text)!r}: cannot read ({exc.strerror})") from None
    body = read_text(p, f"{option}: train file")  # UTF-8 (a byte order mark dropped), one line if not
    tf = parse_train_text(body, sha256_hex(data), text, option)
    check_plausible(tf.train, source=f"train file {p.name}")  # warnings, not refusals
    if not tf.train.units:
        raise InputError(f"{option}: {str(text)!r}: train {tf.name!r} has no vehicles; the DIM cannot run it")
    return tf


def check_train_name(train, where):
    """The train's name as a study train: printable, at most :data:`NAME_MAX_CHARS` characters, and
    not a paper train's name unless the file says it is that train (``paper_train``)."""
    from adm_calib.study.cases import TRAIN_VARIANTS  # noqa: PLC0415  cycle: cases imports nothing of this
    from adm_calib.reference import STUDY_TRAINS  # noqa: PLC0415  as above

    name = str(train.name)
    if not name.strip() or len(name) > NAME_MAX_CHARS or not name.isprintable() or name != name.strip():
        raise InputError(f"{where}: name: {name!r} is not a train name; allowed 1-{NAME_MAX_CHARS} printable "
                         f"characters without leading or trailing blanks")
    key = re.sub(r"[^a-z0-9]", "", name.lower())
    for t in (*STUDY_TRAINS, *TRAIN_VARIANTS):
        if re.sub(r"[^a-z0-9]", "", t.lower()) == key and (train.paper_train or "") != (TRAIN_VARIANTS.get(t, t)):
            raise InputError(f"{where}: name: {name!r} is the name of the paper train {t}, but the file does not "
                             f"say it is that train (paper_train = {train.paper_train or ''!r}); allowed another "
                             f"name, or paper_train = {TRAIN_VARIANTS.get(t, t)!r}")
    return name


def study_trains(items, option="--trains"):
    """Resolve ``--trains`` items: ``(names, files)``, ``names`` in the order given (the study's
    ``train`` keys), ``files`` ``{name: TrainFile}`` for the items that are files.

    A built-in name (ICE-2, Eurostar, Railjet, ICE-4, the variant Eurostar-table) is taken as such;
    an HSLM-A name is refused (a load train: no vehicles, no DIM); anything else is read as a file.
    """
    from adm_sim.model.hslm import hslm_name  # noqa: PLC0415  beside its use

    from adm_calib.study.cases import canonical_trains  # noqa: PLC0415  cycle: cases imports nothing of this

    names, files = [], {}
    for item in items:
        hslm = hslm_name(item)
        if hslm is not None:
            raise InputError(f"{option}: {item!r} is {hslm}, an EN 1991-2 load train (axle loads only, no "
                             f"vehicles): the DIM cannot run it, so no dz_VBI; allowed ICE-2, Eurostar, Railjet, "
                             f"ICE-4, Eurostar-table or a train or vehicle file")
        try:
            name, tf = canonical_trains([item], field=option)[0], None
        except InputError:
            if not (str(item).endswith(".toml") or "/" in str(item) or Path(str(item)).is_file()):
                raise
            tf = read_train_file(item, option)
            name = tf.name
        if name in names:
            what = f"the file {tf.path!r} is named {name!r} too" if tf is not None else f"{item!r} names {name} twice"
            raise InputError(f"{option}: {what}; allowed each train once (trains are told apart by name)")
        names.append(name)
        if tf is not None:
            files[name] = tf
    return names, files


# ====================================================================== the DIM's step
def rk4_gain(z):
    """|R(z)| of the classical Runge-Kutta method, R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24, any shape."""
    z = np.asarray(z, dtype=complex)
    return np.abs(1.0 + z * (1.0 + z / 2.0 * (1.0 + z / 3.0 * (1.0 + z / 4.0))))


def vehicle_eigenvalues(matrices):
    """Eigenvalues (1/s) of one vehicle group with its wheels held, Eq. (11) in first-order form.

    DOFs of infinite inertia (a body given without pitch inertia) do not move and are left out.
    """
    M = np.asarray(matrices.M, dtype=float)
    free = np.isfinite(M)
    K = matrices.K[np.ix_(free, free)]
    C = matrices.C[np.ix_(free, free)]
    n = int(free.sum())
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -K / M[free][:, None]
    A[n:, n:] = -C / M[free][:, None]
    return np.linalg.eigvals(A)


def study_step_s(cases, steps_per_period=None):
    """Largest DIM time step (s) of the selected cases: their slowest lane takes ``steps_per_period``
    steps per period of the highest retained bridge mode (:func:`adm_sim.integrate.step_grid.make_grid`)."""
    from adm_sim.integrate.step_grid import StepOptions  # noqa: PLC0415  beside its use

    spp = StepOptions.steps_per_period if steps_per_period is None else float(steps_per_period)
    return max(2.0 * math.pi / float(c.bridge.omega_rad_s[-1]) for c in cases) / spp


def check_dim_step(tf, dt_s, option="--trains"):
    """Refuse a train whose vehicles the DIM's RK4 cannot follow at time step ``dt_s`` (one line)."""
    train = tf.train
    for i, unit in enumerate(train.units):
        lam = vehicle_eigenvalues(train.unit_matrices(i))
        gain = rk4_gain(lam * dt_s)
        k = int(np.argmax(gain))
        if gain[k] > RK4_GAIN_MAX:
            f_hz = abs(lam[k]) / (2.0 * math.pi)
            raise InputError(
                f"{option}: {tf.path!r}: vehicle {unit.label!r} has a mode of {f_hz:.4g} Hz (eigenvalue "
                f"{lam[k].real:.4g}{lam[k].imag:+.4g}j 1/s, wheels held) that the DIM's RK4 step of this study "
                f"({1000 * dt_s:.3g} ms, the slowest lane of the stiffest bridge selected) cannot follow "
                f"(|R(lambda dt)| = {gain[k]:.6g} > 1); allowed modes inside RK4's stability region at that step "
                f"(an undamped mode up to {RK4_UNDAMPED_LIMIT / (2 * math.pi * dt_s):.4g} Hz): soften the stage "
                f"or give the body more mass")


# ====================================================================== resuming a study
def check_resume(meta, result_trains, names, files, out):
    """Refuse a resumed study whose trains are not the ones it ran (before anything is written).

    ``meta``: the study's ``study.json`` (or None); ``result_trains``: the train names that have
    result lines; ``names``/``files``: this run's trains (:func:`study_trains`).
    """
    recorded = (meta or {}).get("train_files") or {}
    for name in names:
        old = recorded.get(name)
        tf = files.get(name)
        if tf is not None and old is not None and old.get("sha256") != tf.sha256:
            raise InputError(f"--trains: {tf.path!r} (train {name!r}, SHA-256 {tf.sha256[:16]}...) is not the file the "
                             f"study in {str(out)!r} computed {name!r} with ({old.get('path')!r}, SHA-256 "
                             f"{str(old.get('sha256'))[:16]}...); allowed that file unchanged, or another --out")
        if tf is not None and old is None and name in result_trains:
            raise InputError(f"--trains: {tf.path!r} is named {name!r}, and the study in {str(out)!r} holds results "
                             f"of the built-in {name}; allowed another --out")
        if tf is None and old is not None:
            raise InputError(f"--trains: {name!r}: the study in {str(out)!r} computed {name!r} from the file "
                             f"{old.get('path')!r} (SHA-256 {str(old.get('sha256'))[:16]}...), not the built-in "
                             f"train; allowed that file, or another --out")


# ====================================================================== Section 4.2.2 quantities
@dataclass(frozen=True)
class WheelBody:
    """A body that rests on wheelsets (a bogie, or the body of a two-axle wagon)."""

    vehicle: str
    body: str
    mass_kg: float
    wheelsets: int
    primary_k_N_m: float  # sum over its wheelsets

    @property
    def bounce_frequency_hz(self):
        """Eq. (1) for a bogie on two wheelsets, ``sqrt(2 k_p / m_b) / (2 pi)``; in general
        ``sqrt(sum k_p / m) / (2 pi)`` over the primary stages the body rests on."""
        return math.sqrt(self.primary_k_N_m / self.mass_kg) / (2.0 * math.pi)


@dataclass(frozen=True)
class TrainQuantities:
    """The quantities Section 4.2.2 reads the study by, for one train (SI)."""

    name: str
    wheel_bodies: tuple  # WheelBody, one per distinct (vehicle, body)
    vehicle_lengths_m: dict  # vehicle -> coupler-to-coupler length (m)
    mass_kg: float
    length_m: float  # first to last axle
    n_axles: int

    @property
    def mass_per_length_t_m(self):
        return self.mass_kg / 1000.0 / self.length_m

    def to_text(self):
        lines = [f"{self.name}: {self.n_axles} axles, {self.length_m:.2f} m first to last axle, {self.mass_kg / 1000:.1f} t "
                 f"({self.mass_per_length_t_m:.3f} t/m)"]
        for w in self.wheel_bodies:
            lines.append(f"  {w.vehicle} / {w.body}: m = {w.mass_kg:g} kg on {w.wheelsets} wheelsets, "
                         f"n_p = {w.bounce_frequency_hz:.2f} Hz (Eq. 1)")
        lines.append("  vehicle lengths: " + ", ".join(f"{v} {d:g} m" for v, d in self.vehicle_lengths_m.items()))
        return "\n".join(lines)


def train_quantities(train):
    """:class:`TrainQuantities` of a :class:`adm_sim.model.trains.Train` (train or vehicle file):
    each distinct wheel-carrying body with its Eq. (1) frequency, the vehicle lengths, the mass."""
    from adm_sim.model.trains import G_M_S2, vehicle_file_mapping  # noqa: PLC0415  beside its use

    if train.vehicle_types:
        mapping = vehicle_file_mapping(train)
    else:
        raise InputError("train_quantities: give the mapping of a vehicle file (train_quantities_of_mapping)")
    return train_quantities_of_mapping(mapping, train, G_M_S2)


def train_quantities_of_mapping(mapping, train, g=9.81):
    """:class:`TrainQuantities` from a vehicle-file mapping (``[vehicles.<NAME>]``) and its train."""
    bodies, lengths = [], {}
    for vname, v in mapping["vehicles"].items():
        lengths[vname] = float(v["length_m"])
        wheel_names = {w["name"] for w in v["wheelsets"]}
        seen = {}
        for s in v["stages"]:
            if s["lower"] in wheel_names:
                k, n = seen.get(s["upper"], (0.0, 0))
                seen[s["upper"]] = (k + float(s["k_N_m"]), n + 1)
        masses = {b["name"]: float(b["mass_kg"]) for b in v["bodies"]}
        known = set()
        for body, (k, n) in seen.items():
            key = (round(masses[body], 6), n, round(k, 3))
            if key in known:
                continue  # the same bogie twice in one vehicle
            known.add(key)
            bodies.append(WheelBody(vehicle=vname, body=body, mass_kg=masses[body], wheelsets=n, primary_k_N_m=k))
    mass = float(np.sum(train.axle_loads_n)) / g
    return TrainQuantities(name=train.name, wheel_bodies=tuple(bodies), vehicle_lengths_m=lengths, mass_kg=mass,
                           length_m=train.length_m, n_axles=train.n_axles)


def quantities_of_file(tf):
    """:class:`TrainQuantities` of a :class:`TrainFile`."""
    if tf.kind == "vehicle file":
        return train_quantities_of_mapping(tomllib.loads(tf.content), tf.train)
    return train_quantities(tf.train)


def safe_name(name):
    """``name`` as a file-name part: letters, digits, ``.``, ``_`` and ``-``; others become ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


__all__ = ["TrainFile", "read_train_file", "parse_train_text", "study_trains", "check_dim_step", "study_step_s",
           "vehicle_eigenvalues", "rk4_gain", "check_resume", "TrainQuantities", "WheelBody", "train_quantities",
           "train_quantities_of_mapping", "quantities_of_file", "safe_name", "sha256_hex", "check_train_name"]
