"""The paper's method for any train (a train or vehicle file): study, fit, functions file, recommend.

The slice of the field used here (``SLICE``): mass function mu1 at the lower-bound frequency
(freq-index 1) on the spans 21-40 m, n0 = 2.11-4.00 Hz: 20 cases, five 0.5 Hz intervals of
Section 4.2.1 (2-2.5, ..., 4-4.5 Hz), enough for the cubic of Eq. (20). It is the cheapest part of
the field (about 0.1-0.2 s per case). The ICE-2 given as a vehicle file must reproduce the shipped
built-in ICE-2 study on it case by case.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

from adm_calib import study as st
from adm_calib.calib_commands import main
from adm_calib.study import own_train as ot
from adm_sim.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
ICE2_FILE = ROOT / "src" / "adm_sim" / "data" / "vehicles" / "ice2_vehicles.toml"
EXAMPLE_FILE = ROOT / "src" / "adm_sim" / "data" / "examples" / "my_vehicle_train.toml"
SHIPPED = ROOT / "results" / "study" / "results.jsonl.gz"
SLICE = {"mass_functions": ["mu1"], "spans_m": (21, 40), "freq_indices": [1]}
SLICE_ARGS = ["--mass-functions", "mu1", "--spans", "21:40", "--freq-index", "1"]
#: Δζ of the file train against the shipped study (%): the issue's bound; measured 1.3e-14 %.
DZ_TOL_PCT = 1e-9


@pytest.fixture(scope="module")
def ice2_file_study(tmp_path_factory):
    """The slice studied with the ICE-2 vehicle file (one worker), as ``adm-calib study`` runs it."""
    out = tmp_path_factory.mktemp("ice2_file") / "study"
    names, files = ot.study_trains([str(ICE2_FILE)])
    cases = st.select_cases(names, own=files, **SLICE)
    run = st.run_study(out, cases, workers=1, train_files=files)
    assert (run.completed, run.errors, run.interrupted) == (20, 0, False)
    return out


def _shipped_slice(train="ICE-2"):
    recs = st.read_results(SHIPPED).by_key
    keys = {(c.bridge.name, train) for c in st.select_cases(["ICE-2"], **SLICE)}
    return {k: recs[k] for k in keys}


def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(Path(folder).rglob("*")) if p.is_file()}


# ---------------------------------------------------------------------- 1. the study of a train file
def test_vehicle_file_study_reproduces_the_shipped_ice2(ice2_file_study):
    """Case by case: every status equal, Δζ_VBI within 1e-9 % (the issue's bound), the peaks' speeds equal."""
    ours = st.read_results(ice2_file_study / "results.jsonl").by_key
    ref = _shipped_slice()
    assert set(ours) == set(ref) and len(ours) == 20
    worst = 0.0
    for k, r in ref.items():
        o = ours[k]
        assert o["status"] == r["status"] and o["association_rule"] == r["association_rule"]
        assert o["mlm_peak"]["speed_kmh"] == r["mlm_peak"]["speed_kmh"]
        assert o["dim_peak"]["speed_kmh"] == r["dim_peak"]["speed_kmh"]
        assert o["dim_is_local_max"] == r["dim_is_local_max"]
        worst = max(worst, abs(o["delta_zeta_vbi_pct"] - r["delta_zeta_vbi_pct"]))
    assert worst <= DZ_TOL_PCT


def test_study_records_the_file_content_and_sha256(ice2_file_study):
    meta = json.loads((ice2_file_study / "study.json").read_text())
    rec = meta["train_files"]["ICE-2"]
    data = ICE2_FILE.read_bytes()
    assert rec["sha256"] == hashlib.sha256(data).hexdigest()
    assert rec["content"] == data.decode() and rec["kind"] == "vehicle file"
    assert rec["path"] == str(ICE2_FILE) and rec["file_name"] == "ice2_vehicles.toml"


def _resume_case(tmp_path, study, edit_meta=None):
    out = tmp_path / "study"
    shutil.copytree(study, out)
    if edit_meta:
        meta = json.loads((out / "study.json").read_text())
        edit_meta(meta)
        (out / "study.json").write_text(json.dumps(meta))
    return out


@pytest.mark.parametrize("kind", ["changed-file", "built-in-for-file", "file-for-built-in"])
def test_resume_with_another_train_is_refused_and_nothing_written(kind, ice2_file_study, tmp_path, call_main):
    other = tmp_path / "in" / "ice2_vehicles.toml"
    other.parent.mkdir()
    other.write_text(ICE2_FILE.read_text().replace('description = "ICE-2:', 'description = "ICE-2 (edited):'))
    if kind == "changed-file":
        out, train = _resume_case(tmp_path, ice2_file_study), str(other)
        line = (f"error: --trains: {str(other)!r} (train 'ICE-2', SHA-256 "
                f"{hashlib.sha256(other.read_bytes()).hexdigest()[:16]}...) is not the file the study in")
    elif kind == "built-in-for-file":
        out, train = _resume_case(tmp_path, ice2_file_study), "ICE-2"
        line = f"error: --trains: 'ICE-2': the study in {str(out)!r} computed 'ICE-2' from the file {str(ICE2_FILE)!r}"
    else:  # a study of the built-in ICE-2 (no train_files), resumed with the file named ICE-2
        out, train = _resume_case(tmp_path, ice2_file_study, lambda m: m.pop("train_files")), str(ICE2_FILE)
        line = f"error: --trains: {str(ICE2_FILE)!r} is named 'ICE-2', and the study in {str(out)!r} holds results of the built-in ICE-2"
    before = _snapshot(out)
    done = call_main(main, "study", "--out", str(out), "--trains", train, *SLICE_ARGS, "--workers", "1")
    assert done.returncode == 2 and done.stdout.count("\n") <= 1
    assert done.stderr.startswith(line) and done.stderr.count("\n") == 1, done.stderr
    assert _snapshot(out) == before


LOAD_TRAIN = 'name = "loads"\n[[axles]]\nx_m = 0.0\nload_kN = 170.0\n'


def _stiff_vehicle(k_n_m):
    """A one-body vehicle on two wheelsets: body 30 t (pitch 150 t m^2), each stage k (N/m), undamped."""
    return f'''name = "stiff"
[vehicles.v]
length_m = 10.0
[[vehicles.v.bodies]]
name = "b"
mass_kg = 30000.0
x_m = 5.0
pitch_inertia_kgm2 = 150000.0
[[vehicles.v.wheelsets]]
name = "w1"
mass_kg = 1500.0
x_m = 2.0
[[vehicles.v.wheelsets]]
name = "w2"
mass_kg = 1500.0
x_m = 8.0
[[vehicles.v.stages]]
upper = "b"
lower = "w1"
x_m = 2.0
k_N_m = {k_n_m}
c_Ns_m = 0.0
[[vehicles.v.stages]]
upper = "b"
lower = "w2"
x_m = 8.0
k_N_m = {k_n_m}
c_Ns_m = 0.0
[[composition]]
vehicle = "v"
'''


@pytest.mark.parametrize("train, text, line", [
    ("HSLM-A3", None, "error: --trains: 'HSLM-A3' is HSLM-A3, an EN 1991-2 load train (axle loads only, no vehicles): "
                      "the DIM cannot run it, so no dz_VBI"),
    ("{t}/loads.toml", LOAD_TRAIN, "error: --trains: '{t}/loads.toml': holds no vehicles (neither "
                                   "[vehicle_types.<NAME>] nor [vehicles.<NAME>]): a load train cannot run the DIM"),
    ("{t}/stiff.toml", _stiff_vehicle(1e10), "error: --trains: '{t}/stiff.toml': vehicle 'v' has a mode of "),
    ("{t}/named.toml", ICE2_FILE.read_text().replace('paper_train = "ICE-2"\n', ""),
     "error: --trains: '{t}/named.toml': name: 'ICE-2' is the name of the paper train ICE-2, but the file does not say"),
    ("{t}/twice.toml,{t}/twice.toml", ICE2_FILE.read_text(),
     "error: --trains: the file '{t}/twice.toml' is named 'ICE-2' too; allowed each train once"),
    ("ICE-2,{t}/ice2.toml", ICE2_FILE.read_text(), "error: --trains: the file '{t}/ice2.toml' is named 'ICE-2' too"),
])
def test_study_refuses_trains_the_dim_cannot_run(train, text, line, tmp_path, call_main):
    t = tmp_path / "in"
    t.mkdir()
    if text is not None:
        name = train.split(",")[-1].format(t=t)
        Path(name).write_text(text)
    before = _snapshot(t)
    out = tmp_path / "study"
    done = call_main(main, "study", "--out", str(out), "--trains", train.format(t=t), *SLICE_ARGS, "--workers", "1")
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.startswith(line.format(t=t)) and done.stderr.count("\n") == 1, done.stderr
    assert not out.exists() and _snapshot(t) == before


# ---------------------------------------------------------------------- the RK4 step check
def test_rk4_gain_closed_form():
    """|R(ix)|^2 = 1 - x^6/72 + x^8/576 (R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24): 1 at x = 2 sqrt(2), the
    undamped limit; R(z) = exp(z) + O(z^5) near 0 (|error| <= |z|^5/120 * 1.1 for |z| <= 0.1)."""
    x = np.linspace(0.0, 3.5, 351)
    assert np.allclose(ot.rk4_gain(1j * x) ** 2, 1 - x ** 6 / 72 + x ** 8 / 576, rtol=0, atol=1e-12)
    assert ot.rk4_gain(1j * ot.RK4_UNDAMPED_LIMIT) == pytest.approx(1.0, abs=1e-12)
    assert ot.rk4_gain(1j * 2.83) > 1.0 > ot.rk4_gain(1j * 2.82)
    z = 0.1 * np.exp(1j * np.linspace(0, 2 * np.pi, 37))
    r = 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24
    assert np.allclose(np.abs(r), ot.rk4_gain(z), rtol=1e-15)
    assert np.all(np.abs(r - np.exp(z)) <= 1.1 * np.abs(z) ** 5 / 120)
    # the real-axis limit of RK4's region: R(-2.785...) = 1
    assert ot.rk4_gain(-2.78) < 1.0 < ot.rk4_gain(-2.79)


def test_vehicle_eigenvalues_of_a_sprung_mass():
    """The example's test car: one mass m on k, c: lambda = -c/(2m) +/- i sqrt(k/m - (c/2m)^2); with c = 0
    (as shipped) +/- i sqrt(k/m), 2.65 Hz. A given damper moves the roots as the closed form says."""
    tf = ot.read_train_file(str(EXAMPLE_FILE))
    lam = ot.vehicle_eigenvalues(tf.train.unit_matrices(0))
    k, m = 1595e3, 5750.0
    assert sorted(lam.imag) == pytest.approx([-math.sqrt(k / m), math.sqrt(k / m)], rel=1e-12)
    assert np.allclose(lam.real, 0.0, atol=1e-9)
    damped = tomllib.loads(EXAMPLE_FILE.read_text())
    damped["vehicles"]["test car"]["stages"][0]["c_Ns_m"] = 2.0e4
    from adm_sim.model.trains import train_from_mapping
    lam = ot.vehicle_eigenvalues(train_from_mapping(damped).unit_matrices(0))
    s = 2.0e4 / (2 * m)
    assert sorted(lam.imag) == pytest.approx([-math.sqrt(k / m - s * s), math.sqrt(k / m - s * s)], rel=1e-12)
    assert lam.real == pytest.approx([-s, -s], rel=1e-12)


def test_dim_step_check_at_its_limit():
    """The one-body vehicle's stiffest mode (pitch or bounce, undamped) against the limit
    2 sqrt(2) / (2 pi dt): refused 0.1 % above it, accepted 0.1 % below."""
    from adm_sim.model.trains import train_from_mapping
    dt = 3e-3

    def top_rad_s(k):
        return max(abs(ot.vehicle_eigenvalues(train_from_mapping(tomllib.loads(_stiff_vehicle(k))).unit_matrices(0))))

    k0 = 1e7
    # bounce 2 k / m and pitch 2 k 3^2 / J: pitch is the stiffer (18 k / 150000 > 2 k / 30000)
    assert top_rad_s(k0) == pytest.approx(math.sqrt(2 * k0 * 9 / 150000), rel=1e-12)
    limit_k = (ot.RK4_UNDAMPED_LIMIT / dt) ** 2 * 150000 / 18
    for scale, refused in ((1.001, True), (0.999, False)):
        text = _stiff_vehicle(limit_k * scale)
        tf = ot.parse_train_text(text, "x", "stiff.toml")
        if refused:
            with pytest.raises(InputError, match=r"vehicle 'v' has a mode of 150\.[0-9] Hz"):
                ot.check_dim_step(tf, dt)
        else:
            ot.check_dim_step(tf, dt)


def test_paper_trains_pass_the_step_check_over_the_field():
    """The four paper trains, as vehicle files, run the whole field (largest step: L = 40 m, LB n0)."""
    cases = st.select_cases(["ICE-2"])
    dt = ot.study_step_s(cases)
    # the field's smallest n0 is 2.109 Hz (L = 40 m, LB); three modes: top 9 n0; 16 steps per period
    assert dt == pytest.approx(1.0 / (9 * 2.1092025439033097 * 16), rel=1e-9)
    for f in sorted((ROOT / "src" / "adm_sim" / "data" / "vehicles").glob("*.toml")):
        ot.check_dim_step(ot.read_train_file(str(f)), dt)
