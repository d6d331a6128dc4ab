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
import json
import math
import re
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from adm_sim.errors import InputError
from adm_sim.files import input_file, read_text
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.model.hslm import hslm_name
from adm_sim.model.parametric import mass_function_t_m
from adm_sim.inputs.train_files import load_train, train_from_mapping, vehicle_file_mapping
from adm_sim.model.plausibility import warn_implausible_train
from adm_sim.model.trains import G_M_S2

from adm_calib.lower_bound import LOWER_LIMIT_HZ
from adm_calib.recommend_warnings import parse_cases
from adm_calib.reference import STUDY_TRAINS, LowerBound, lower_bound_table
from adm_calib.study.cases import MASS_FUNCTION_NAMES, TRAIN_VARIANTS, canonical_trains
from adm_calib.study.store import read_meta

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
        return {"path": self.path, "resolved_path": str(Path(self.path).resolve()), "file_name": Path(self.path).name,
                "sha256": self.sha256, "kind": self.kind, "content": self.content}

    def __repr__(self):
        return f"TrainFile({self.name!r} from {self.path!r}, sha256 {self.sha256[:12]}...)"


def sha256_hex(data):
    return hashlib.sha256(data).hexdigest()


def parse_train_text(text, sha256, path, option="--trains"):
    """A :class:`TrainFile` from the text of a train or vehicle file (``path`` names it in messages)."""

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

    p = input_file(text, option, "train or vehicle file")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(f"{option}: {str(text)!r}: cannot read ({exc.strerror})") from None
    body = read_text(p, f"{option}: train file")  # UTF-8 (a byte order mark dropped), one line if not
    tf = parse_train_text(body, sha256_hex(data), text, option)
    warn_implausible_train(tf.train, source=f"train file {p.name}")  # warnings, not refusals
    if not tf.train.units:
        raise InputError(f"{option}: {str(text)!r}: train {tf.name!r} has no vehicles; the DIM cannot run it")
    return tf


def check_train_name(train, where):
    """The train's name as a study train: printable, at most :data:`NAME_MAX_CHARS` characters, and
    not a paper train's name where the file says it is another paper train (``paper_train``). A
    file named like a paper train is compared with that train's Table B by ``study-fit``."""

    name = str(train.name)
    if not name.strip() or len(name) > NAME_MAX_CHARS or not name.isprintable() or name != name.strip():
        raise InputError(f"{where}: name: {name!r} is not a train name; allowed 1-{NAME_MAX_CHARS} printable "
                         f"characters without leading or trailing blanks")
    key = re.sub(r"[^a-z0-9]", "", name.lower())
    for t in (*STUDY_TRAINS, *TRAIN_VARIANTS):
        if re.sub(r"[^a-z0-9]", "", t.lower()) == key and train.paper_train not in ("", TRAIN_VARIANTS.get(t, t)):
            raise InputError(f"{where}: name: {name!r} is the name of the paper train {t}, but the file says it is "
                             f"paper_train = {train.paper_train!r}; allowed another name, or paper_train = "
                             f"{TRAIN_VARIANTS.get(t, t)!r} (or none)")
    return name


def study_trains(items, option="--trains"):
    """Resolve ``--trains`` items: ``(names, files)``, ``names`` in the order given (the study's
    ``train`` keys), ``files`` ``{name: TrainFile}`` for the items that are files.

    A built-in name (ICE-2, Eurostar, Railjet, ICE-4, the variant Eurostar-table) is taken as such;
    an HSLM-A name is refused (a load train: no vehicles, no DIM); anything else is read as a file.
    """


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
def check_resume(meta, result_trains, *, names, files, out):
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


def study_train_files(results_path, option="--results"):
    """The train files a study ran (``study.json`` beside ``results_path``), checked for the fit:
    ``{name: (record, TrainFile)}``; the TrainFile is rebuilt from the recorded content.

    Raises :class:`InputError` (one line) when a recorded content does not hash to its SHA-256 (a
    damaged ``study.json``) or when the file still at the recorded path has changed since the study
    (the fit would describe a train that is no longer the file's). A file no longer there is fine:
    the study's copy is the train.
    """

    folder = Path(results_path).parent
    meta = read_meta(folder)
    out = {}
    for name, rec in ((meta or {}).get("train_files") or {}).items():
        where = f"{option}: the study in {str(folder)!r}: train {name!r}"
        content, sha = rec.get("content"), rec.get("sha256")
        if not isinstance(content, str) or not isinstance(sha, str) or sha256_hex(content.encode()) != sha:
            raise InputError(f"{where}: the recorded file content does not hash to its recorded SHA-256 "
                             f"{str(sha)[:16]}... (study.json damaged?); allowed study.json as the study wrote it")
        path = Path(str(rec.get("resolved_path") or rec.get("path", "")))  # a relative path: the study's cwd
        if path.is_file():
            now = sha256_hex(path.read_bytes())
            if now != sha:
                raise InputError(f"{where}: the train file {str(path)!r} has changed since the study (SHA-256 "
                                 f"{sha[:16]}... then, {now[:16]}... now); allowed the file as the study ran it: "
                                 f"restore it, or run the study again into another --out")
        out[name] = (rec, parse_train_text(content, sha, rec.get("path", name), option))
    return out


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
    vehicle_lengths_m: dict  # car (train file: vehicle type, d) or vehicle (vehicle file: length_m) -> length (m)
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
        lines.append("  car lengths: " + ", ".join(f"{v} {d:g} m" for v, d in self.vehicle_lengths_m.items()))
        return "\n".join(lines)


def train_quantities(train):
    """:class:`TrainQuantities` of a :class:`adm_sim.model.trains.Train` (train or vehicle file):
    each distinct wheel-carrying body with its Eq. (1) frequency, the vehicle lengths, the mass."""

    if not train.vehicle_types:
        raise InputError("train_quantities: give the mapping of a vehicle file (train_quantities_of_mapping)")
    q = train_quantities_of_mapping(vehicle_file_mapping(train), train, G_M_S2)
    # a train file's cars have their own length d (Table A1), also inside a Jacobs set
    cars = dict.fromkeys(c[0] for u in train.units for c in u.cars)
    return replace(q, vehicle_lengths_m={n: float(train.vehicle_types[n].d_m) for n in cars})


def train_quantities_of_mapping(mapping, train, g=9.81):
    """:class:`TrainQuantities` from a vehicle-file mapping (``[vehicles.<NAME>]``) and its train."""
    bodies, lengths, known = [], {}, set()
    for vname, v in mapping["vehicles"].items():
        lengths[vname] = float(v["length_m"])
        wheel_names = {w["name"] for w in v["wheelsets"]}
        seen = {}
        for s in v["stages"]:
            if s["lower"] in wheel_names:
                k, n = seen.get(s["upper"], (0.0, 0))
                seen[s["upper"]] = (k + float(s["k_N_m"]), n + 1)
        masses = {b["name"]: float(b["mass_kg"]) for b in v["bodies"]}
        for body, (k, n) in seen.items():
            key = (round(masses[body], 6), n, round(k, 3))
            if key in known:
                continue  # the same bogie again (in this vehicle or an earlier one)
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


# ====================================================================== the functions file
#: Format of the functions file ``study-fit`` writes for a train of a file and ``recommend --functions`` reads.
FUNCTIONS_FORMAT = "adm-calib-train-functions/1"
#: Columns of a function row (Appendix B: coefficients, upper limit, R², residuals).
COLUMNS = ("a", "b", "c", "d", "upper_limit_hz", "r2", "max_res_pct", "min_res_pct")
#: The two sets of a functions file and what ``recommend`` prints for each.
FUNCTION_SETS = {"least_squares": "least-squares cubic through the interval minima (Section 4.2.1, Appendix B form)",
                 "conservative": "conservative: the largest cubic below every retained case (linear programme)"}


def functions_toml(name, file_record, study_fit, conservative_rows, *, cases_csv, quantities=None, command="",
                   study_dir=""):
    """The functions file of one train of a file: its least-squares functions (Eq. 20 in the form
    of Appendix B), its conservative bounds, the study's cases (for ``recommend``'s warnings) and
    the SHA-256 of the train file the study ran."""

    hi = study_fit.fit_range_hz[1]
    used = sum(1 for r in study_fit.records_used if r["train"] == name)
    lines = ["# Lower-bound functions of one train (adm-calib study-fit on a study of its train file), Appendix B form:",
             "#   delta_zeta(n0) = a n0^3 + b n0^2 + c n0 + d   Eq. (20); delta_zeta in %, n0 in Hz; from 2.1 Hz to the",
             f"#   first root ('upper limit'), 0 beyond (and above {hi:g} Hz, the end of the fitted range, where no root comes first)",
             "# read by: adm-calib recommend --functions THIS_FILE --train THE_TRAIN_FILE (the train file's SHA-256 must match)",
             *([f"# Section 4.2.2 quantities: {q}" for q in quantities.to_text().splitlines()] if quantities else []),
             f'format = "{FUNCTIONS_FORMAT}"', f"train = {json.dumps(name)}",
             f'train_sha256 = "{file_record["sha256"]}"', f"train_file = {json.dumps(file_record.get('file_name', ''))}",
             f"train_kind = {json.dumps(file_record.get('kind', ''))}", f"study = {json.dumps(str(study_dir))}",
             f"command = {json.dumps(command)}", f'exclusion_rule = "{study_fit.rule}"', f"cases_used = {used}",
             f"lower_limit_hz = {LOWER_LIMIT_HZ}", f"fit_range_max_hz = {hi}",
             f"columns = [{', '.join(json.dumps(c) for c in COLUMNS)}]", "", "[least_squares]",
             f'source = "least-squares cubic through the interval minima, rule {study_fit.rule}"']
    for (t, m), f in study_fit.fits.items():
        if t == name and f.fit is not None:
            c = f.fit
            vals = [*c.coefficients, c.upper_limit_hz, c.r2, c.max_res_pct, c.min_res_pct]
            lines.append(f"{m} = [{', '.join(repr(float(v)) for v in vals)}]")
    lines += ["", "[conservative]", f'source = "linear programme below every retained case, rule {study_fit.rule}"']
    for r in conservative_rows:
        if r.train == name:
            slack = r.fit.delta_zeta_pct - np.polyval(r.fit.coefficients, r.fit.n0_hz)
            vals = [*r.fit.coefficients, r.fit.upper_limit_hz, float("nan"), float(slack.max()), float(slack.min())]
            lines.append(f"{r.mass_function} = [{', '.join(repr(float(v)) for v in vals)}]")
    lines += ["", "[cases]", "# the study's cases with a dz_VBI (adm_calib.recommend_warnings.study_cases_csv): recommend's warnings",
              _toml_text("csv", cases_csv)]
    return "\n".join(lines) + "\n"


def _toml_text(key, text):
    """``key = <text>``: a TOML multi-line literal string (one line of the text per line) where the
    text allows it, else a basic string."""
    quotes = "'" * 3
    if quotes in text or text.endswith("'"):
        return f"{key} = {json.dumps(text)}"
    return f"{key} = {quotes}\n{text}{quotes}"


@dataclass(frozen=True, repr=False)
class TrainFunctions:
    """A functions file read back: ``sets[set_name][mass_function]`` are
    :class:`adm_calib.reference.LowerBound` s; ``cases`` the study's cases (recommend's warnings)."""

    path: str
    train: str
    train_sha256: str
    train_file: str
    rule: str
    sets: dict
    cases: tuple

    def __repr__(self):
        return f"TrainFunctions({self.train!r}, {', '.join(f'{k}: {len(v)}' for k, v in self.sets.items())})"


def read_functions(text, option="--functions"):
    """Read a functions file of :func:`functions_toml` (one-line errors naming ``option`` and the file)."""


    p = input_file(text, option, "functions file")
    where = f"{option}: {str(text)!r}"
    body = read_text(p, f"{option}: functions file")
    try:
        data = tomllib.loads(body)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{where}: not valid TOML ({exc}); allowed a functions file of adm-calib study-fit "
                         f"(format {FUNCTIONS_FORMAT!r})") from None
    fmt = data.get("format")
    if fmt != FUNCTIONS_FORMAT:
        raise InputError(f"{where}: format {fmt!r} is not a functions file of one train; allowed format "
                         f"{FUNCTIONS_FORMAT!r} (written by adm-calib study-fit beside a study of a train file)")
    for key in ("train", "train_sha256", "exclusion_rule"):
        if not isinstance(data.get(key), str):
            raise InputError(f"{where}: {key}: {data.get(key)!r} is missing or not text")
    if not re.fullmatch(r"[0-9a-f]{64}", data["train_sha256"]):
        raise InputError(f"{where}: train_sha256: {data['train_sha256']!r} is not a SHA-256; allowed 64 hex digits")
    if list(data.get("columns", [])) != list(COLUMNS):
        raise InputError(f"{where}: columns: {data.get('columns')!r}; allowed {list(COLUMNS)!r}")
    nums = {}
    for key in ("lower_limit_hz", "fit_range_max_hz"):
        v = data.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 2.0 <= v <= 21.0:
            raise InputError(f"{where}: {key}: {v!r} Hz is out of range; allowed a number in [2, 21] Hz")
        nums[key] = float(v)
    sets = {}
    for name in FUNCTION_SETS:
        tab = data.get(name)
        if not isinstance(tab, dict):
            raise InputError(f"{where}: [{name}]: missing; allowed the table study-fit writes")
        out = {}
        for m, row in tab.items():
            if m == "source":
                continue
            if m not in MASS_FUNCTION_NAMES:
                raise InputError(f"{where}: {name}.{m}: unknown mass function; allowed {', '.join(MASS_FUNCTION_NAMES)}")
            ok = (isinstance(row, list) and len(row) == len(COLUMNS)
                  and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in row)
                  and all(math.isfinite(v) for v in row[:4]))
            if not ok:
                raise InputError(f"{where}: {name}.{m}: {row!r} is not a function row; allowed {len(COLUMNS)} numbers "
                                 f"({', '.join(COLUMNS)}), a..d finite")
            out[m] = LowerBound(train=data["train"], mass_function=m, source=str(tab.get("source", "")),
                                lower_limit_hz=nums["lower_limit_hz"], fit_range_max_hz=nums["fit_range_max_hz"],
                                **dict(zip(COLUMNS, (float(v) for v in row))))
        sets[name] = out
    csv_text = (data.get("cases") or {}).get("csv")
    if not isinstance(csv_text, str):
        raise InputError(f"{where}: cases.csv: missing; allowed the study's cases as study-fit writes them")
    try:
        cases = parse_cases(csv_text)
    except (ValueError, TypeError):
        raise InputError(f"{where}: cases.csv: not the study's cases (train, mass_function, bridge, n0_hz, "
                         f"delta_zeta_vbi_pct, excluded, detail)") from None
    return TrainFunctions(path=str(text), train=data["train"], train_sha256=data["train_sha256"],
                          train_file=str(data.get("train_file", "")), rule=data["exclusion_rule"], sets=sets,
                          cases=cases)


#: n0 (Hz) at which :func:`trains_comparison_markdown` compares the lower bounds.
COMPARE_N0_HZ = (2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0)
#: Span (m) of the reference bridges of the mass ratio in :func:`trains_comparison_markdown` (the
#: project's choice, not the paper's: Section 4.2.2 names the ratio, not a bridge).
MASS_RATIO_SPAN_M = 20.0


def trains_comparison_markdown(functions, records, tf, paper_records=None):
    """Markdown: a train of a file beside the four paper trains.

    ``functions``: its :class:`TrainFunctions`; ``records``: its study's result lines; ``tf``: its
    :class:`TrainFile`; ``paper_records``: the shipped study's lines (the four trains' Δζ_VBI
    statistics). Three tables: the Section 4.2.2 quantities (Eq. (1) frequencies of the bodies on
    wheelsets, their masses and the bridge-to-bogie mass ratio ``mu L / m`` of the Table 1 mass
    functions mu1 and mu6 at :data:`MASS_RATIO_SPAN_M`, the car lengths, the train's mass per
    length); the least-squares lower bounds (Eq. 20 as applied) at :data:`COMPARE_N0_HZ` for mu1,
    mu3, mu4, mu6 (the paper's Tables B1-B4 for the four trains); the Δζ_VBI of the studies.
    """


    L = MASS_RATIO_SPAN_M
    mu1, mu6 = mass_function_t_m("mu1", L) * 1000.0 * L, mass_function_t_m("mu6", L) * 1000.0 * L
    rows = [(t, train_quantities(load_train(t))) for t in STUDY_TRAINS] + [(tf.name, quantities_of_file(tf))]
    out = [f"Section 4.2.2 quantities. n_p: Eq. (1), sqrt(sum k_p / m) / (2 pi) of each distinct body that rests on "
           f"wheelsets (a bogie on two: sqrt(2 k_p / m_b) / (2 pi)); mass ratio: bridge mass mu L over that body's "
           f"mass for the heaviest (mu1) and lightest (mu6) mass function of Table 1 at L = {L:g} m (the reference "
           f"span is the project's choice). Generated by `adm_calib.study.own_train.trains_comparison_markdown`.", "",
           "| train | body on wheelsets | m (kg) | n_p (Hz) | mu1 L / m | mu6 L / m | car lengths (m) | mass (t/m) |",
           "|---|---|---|---|---|---|---|---|"]
    for t, q in rows:
        cars = ", ".join(f"{k} {v:g}" for k, v in q.vehicle_lengths_m.items())
        for i, w in enumerate(q.wheel_bodies):
            out.append(f"| {t if i == 0 else ''} | {w.vehicle} / {w.body} ({w.wheelsets} wheelsets) | {w.mass_kg:.0f} | "
                       f"{w.bounce_frequency_hz:.2f} | {mu1 / w.mass_kg:.0f} | {mu6 / w.mass_kg:.0f} | "
                       f"{cars if i == 0 else ''} | {f'{q.mass_per_length_t_m:.3f}' if i == 0 else ''} |")
    paper = lower_bound_table("paper")
    n0 = COMPARE_N0_HZ
    out += ["", f"Lower bounds Δζ_LB (%) as applied (Eq. 20 from 2.1 Hz to the first root, 0 beyond): the paper's "
                f"Tables B1-B4 for the four trains, the least-squares functions of its own study (rule "
                f"{functions.rule}) for {tf.name}.", "",
            "| set | " + " | ".join(f"{x:g} Hz" for x in n0) + " | first root (Hz) |",
            "|---|" + "---|" * (len(n0) + 1)]
    for m in ("mu1", "mu3", "mu4", "mu6"):
        for t in (*STUDY_TRAINS, tf.name):
            f = paper[t][m] if t in STUDY_TRAINS else functions.sets["least_squares"].get(m)
            if f is None:
                continue
            vals = " | ".join(f"{float(f.value_pct(x)):.3f}" for x in n0)
            out.append(f"| {t} {m} | {vals} | {f.zero_from_hz:.2f} |")
    out += ["", "Δζ_VBI of the studies (every case with a Δζ_VBI; the four trains: the shipped study "
                "results/study; percentiles over the 1110 bridges):", "",
            "| train | cases with Δζ_VBI | Δζ_VBI < 0 | 10 % | median | 90 % | largest |", "|---|---|---|---|---|---|---|"]
    groups = {t: [r for r in (paper_records or []) if r["train"] == t] for t in STUDY_TRAINS}
    groups[tf.name] = [r for r in records if r["train"] == tf.name]
    for t, recs in groups.items():
        dz = np.array([r["delta_zeta_vbi_pct"] for r in recs if r.get("delta_zeta_vbi_pct") is not None])
        if not dz.size:
            continue
        p10, p50, p90 = np.percentile(dz, [10, 50, 90])
        out.append(f"| {t} | {dz.size} | {int((dz < 0).sum())} | {p10:.3f} | {p50:.3f} | {p90:.3f} | {dz.max():.3f} |")
    return "\n".join(out) + "\n"


def safe_name(name):
    """``name`` as a file-name part: letters, digits, ``.``, ``_`` and ``-``; others become ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


__all__ = ["TrainFile", "read_train_file", "parse_train_text", "study_trains", "check_dim_step", "study_step_s",
           "vehicle_eigenvalues", "rk4_gain", "check_resume", "TrainQuantities", "WheelBody", "train_quantities",
           "train_quantities_of_mapping", "quantities_of_file", "safe_name", "sha256_hex", "check_train_name",
           "study_train_files", "trains_comparison_markdown", "FUNCTIONS_FORMAT", "FUNCTION_SETS", "functions_toml", "read_functions", "TrainFunctions"]
