"""Bridge and train data: paper tables, parametric field, file schemas and their errors."""

import math

import numpy as np
import pytest

from adm_sim.model.bridge import Bridge, TABLE3, eurocode_damping_pct, named_bridge, parametric_field
from adm_sim.inputs.bridges import load_bridge_file, parse_bridge_spec, resolve_bridge
from adm_sim.errors import InputError, ModelError
from adm_sim.fields import AXLE_LOAD_REL_TOL
from adm_sim.model.parametric import field_frequencies_hz
from adm_sim.model.trains import consistency_rows
from adm_sim.inputs.train_files import load_train, train_from_mapping


@pytest.mark.parametrize("name", list(TABLE3))
def test_table3_frequency_and_damping(name):
    L, n0, mu_t, EJ, zeta_pct, btype = TABLE3[name]
    b = named_bridge(name)
    assert b.n0_hz == pytest.approx(n0, abs=0.01)  # Eq. (18) vs the printed n0
    assert eurocode_damping_pct(L, btype) == pytest.approx(zeta_pct, abs=0.005)  # Table 2


def test_eurocode_damping_table2():
    assert eurocode_damping_pct(10, "sc") == pytest.approx(0.5 + 0.125 * 10)
    assert eurocode_damping_pct(25, "sc") == 0.5
    assert eurocode_damping_pct(4, "cfb") == pytest.approx(1.5 + 0.07 * 16)
    assert eurocode_damping_pct(40, "cfb") == 1.5
    with pytest.raises(ModelError, match="bridge_type: 'steel' has no Table 6.6 damping; allowed cfb or sc"):
        eurocode_damping_pct(10, "steel")  # the model's own guard; the readers refuse a typed type first


def test_modal_properties_and_rayleigh_damping():
    b = named_bridge("B1")
    j = np.arange(1, 4)
    assert np.allclose(b.omega_rad_s, 2 * math.pi * b.n0_hz * j**2)
    assert np.allclose(b.modal_mass_kg, 19042 * 15 / 2)
    z = b.modal_damping_ratios(0.002)
    assert z[0] == pytest.approx(0.0205) and z[2] == pytest.approx(0.0205)  # anchors 1 and 3
    assert z[1] == pytest.approx(0.625 * 0.0205)  # Rayleigh between them
    modal = Bridge(15, b.EJ_Nm2, 19042, 0.0185, damping_model="modal")
    assert np.allclose(modal.modal_damping_ratios(), 0.0185)


def test_parametric_field_is_the_papers_1110_bridges():
    field = parametric_field()
    assert len(field) == 1110
    pairs = {(b.span_m, round(b.n0_hz, 9)) for b in field}
    assert len(pairs) == 185
    assert {b.span_m for b in field} == set(float(L) for L in range(4, 41))
    lb, m1, fit, m2, ub = field_frequencies_hz(15.0)
    assert fit == pytest.approx(97.76 * 15**-0.9124)
    assert lb < m1 < fit < m2 < ub and m1 == pytest.approx((lb + fit) / 2)
    b = next(x for x in field if x.name == "L15-f3-mu2")
    assert b.mass_per_length_kg_m == pytest.approx((0.7002 * 15 + 8.539) * 1000)
    assert b.damping_ratio == pytest.approx(0.0185)  # CFB, Table 2
    b = next(x for x in field if x.name == "L30-f1-mu6")
    assert b.bridge_type == "sc" and b.damping_ratio == pytest.approx(0.005)


def test_bridge_spec_and_file(tmp_path):
    b = parse_bridge_spec("L=15,n0=8.26,mu=19042,zeta_pct=1.85")
    assert b.n0_hz == pytest.approx(8.26) and b.damping_ratio == pytest.approx(0.0185)
    b = parse_bridge_spec("L=20,EJ=5e10,mu=10000,type=sc")
    assert b.damping_ratio == pytest.approx(0.005)
    f = tmp_path / "mine.toml"
    f.write_text("L = 12.0\nn0 = 9.5\nmu = 12000\nzeta_pct = 2.0\n")
    b = load_bridge_file(f)
    assert b.name == "mine" and b.n0_hz == pytest.approx(9.5)
    assert resolve_bridge(str(f)).span_m == 12.0


@pytest.mark.parametrize("spec,match", [
    ("L=-3,n0=8,mu=1000,zeta_pct=1", r"L: -3 m is out of range; allowed \[1, 150\] m"),
    ("L=15,n0=8,mu=19000,zeta_pct=25", r"zeta_pct: 25 % is out of range; allowed \[0, 20\] %"),
    ("L=15,n0=200,mu=19000,zeta_pct=1", r"n0: 200 Hz is out of range; allowed \[0.5, 100\] Hz"),
    ("L=15,n0=8,mu=abc,zeta_pct=1", r"mu: 'abc' is not a number"),
    ("L=15,mu=19000,zeta_pct=1", r"missing stiffness: give n0"),
    ("L=15,n0=8,mu=19000", r"missing damping"),
    ("L=15,n0=8,mu=19000,zeta_pct=1,foo=3", r"bridge spec: unknown key 'foo'; allowed EJ, "),
    ("nonsense", r"neither a named bridge"),
    ("L=15,L=20,n0=8,mu=19000,zeta_pct=1", r"bridge spec: 'L' is given twice \('15' and '20'\); give it once"),
    ("L=15,span_m=20,n0=8,mu=19000,zeta_pct=1", r"'L' and 'span_m' give the same quantity twice"),
    ("L=15,n0=8,mu=19000,zeta_pct=1,zeta=0.02", r"'zeta_pct' and 'zeta' both give the damping; give one"),
    ("L=15,n0=8,EJ=1e10,mu=19000,zeta_pct=1", r"give either n0 \(Hz\) or EJ \(N m\^2\), not both"),
])
def test_bridge_input_errors(spec, match):
    with pytest.raises(InputError, match=match):
        resolve_bridge(spec)


def test_train_checks_against_the_paper():
    for name in ("ICE-2", "Eurostar", "Railjet", "ICE-4"):
        rows = consistency_rows(load_train(name), rel_tol=AXLE_LOAD_REL_TOL)
        assert rows and all(r.ok for r in rows), [r for r in rows if not r.ok]
    # the printed Eurostar PC 2-8 suspension contradicts the quoted bogie frequency
    bad = [r for r in consistency_rows(load_train("Eurostar-table"), rel_tol=AXLE_LOAD_REL_TOL) if not r.ok]
    assert len(bad) == 1 and bad[0].computed_value == pytest.approx(1.869, abs=0.001)
    assert load_train("eurostar").vehicle_types["PC 2-8"].bogie_frequency_hz == pytest.approx(3.18, abs=0.005)


def test_train_geometry():
    t = load_train("ICE-2")
    assert t.n_axles == 56 and len(t.units) == 14
    # Loc: wheelbase 3 m, pivots 11.5 m apart; then the first PC starts at 20.9 m
    assert np.allclose(t.axle_offsets_m[:4], [0.0, 3.0, 11.5, 14.5])
    pc = t.axle_offsets_m[4:8] - t.axle_offsets_m[4]
    assert np.allclose(pc, [0.0, 2.5, 19.0, 21.5])
    # the first PC's first axle: loc front overhang (20.9 - 11.5 - 3)/2 = 3.2 m to its first
    # axle; the PC's (26.4 - 19 - 2.5)/2 = 2.45 m
    assert t.axle_offsets_m[4] == pytest.approx(20.9 - 3.2 + 2.45)
    e = load_train("Eurostar")
    assert e.n_axles == 4 + 20 + 20 + 4 and e.jacobs
    # Jacobs bogies of PC 2-8 are 18.7 m apart
    assert np.allclose(np.diff(e.axle_offsets_m[6:22:2]), 18.7)
    assert e.axle_loads_n.sum() == pytest.approx(1000 * (4 * 153.8 * 2 + 2 * 2810.6), rel=1e-9)
    assert len(load_train("ICE-4").units) == 12 and len(load_train("Railjet").units) == 16


@pytest.mark.parametrize("name", ["ICE-2", "Eurostar"])
def test_vehicle_matrices_rigid_body_modes(name):
    # A uniform rail lift delta under all axles of a unit lifts every body by delta without
    # pitch: K u = Lw^T k_p delta for u = delta on the bounce DOFs (assembly check).
    t = load_train(name)
    for i in (0, 1):
        m = t.unit_matrices(i)
        assert np.allclose(m.K, m.K.T) and np.all(np.linalg.eigvalsh(m.K) > 0)
        u = np.zeros(len(m.M))
        u[0::2] = 1e-3
        np.testing.assert_allclose(m.K @ u, m.Lw.T @ (m.k_p * 1e-3), rtol=1e-9, atol=1e-6)


def _minimal(**over):
    vt = dict(m_c_kg=30000, J_c_kgm2=1e6, m_b_kg=2000, J_b_kgm2=2000, m_w_kg=1500,
              k_s_N_m=3e5, c_s_Ns_m=6e3, k_p_N_m=1.6e6, c_p_Ns_m=2e4, d_m=26, r_m=19, b_m=2.5,
              axle_load_kN=98.1)  # (m_c + 2 m_b + 4 m_w) g / 4
    vt.update(over)
    return {"name": "mine", "vehicle_types": {"PC": vt}, "composition": [{"vehicle": "PC", "count": 3}]}


def test_user_train_file(tmp_path):
    import tomllib  # noqa: F401  (the schema is TOML)

    t = train_from_mapping(_minimal())
    assert t.n_axles == 12 and t.length_m == pytest.approx(2 * 26 + 19 + 2.5)


@pytest.mark.parametrize("over,match", [
    (dict(k_p_N_m=-5), r"vehicle_types.PC.k_p_N_m: -5 N/m is out of range; allowed \[1, 1e\+10\] N/m"),
    (dict(m_c_kg="heavy"), r"vehicle_types.PC.m_c_kg: 'heavy' is a string, not a number \(write it without quotes\); allowed \[1, 500000\] kg"),
    (dict(r_m=30), r"r_m: 30 m plus wheelbase b_m 2.5 m is not shorter than the vehicle length d_m 26 m"),
    (dict(axle_load_kN=900), r"axle_load_kN: 900 kN is out of range; allowed \[1, 500\] kN"),
    (dict(mass=3), r"unknown field\(s\) mass"),
])
def test_train_file_errors(over, match):
    with pytest.raises(InputError, match=match):
        train_from_mapping(_minimal(**over))


def _eurostar():
    import tomllib
    from importlib import resources

    return tomllib.loads(resources.files("adm_sim").joinpath("data/trains/eurostar.toml").read_text())


def test_train_file_keys_strict():
    """Typos and conflicts in a train file are refused, never silently resolved."""
    data = _minimal()
    data["composition"] = [{"vehicle": "PC", "cout": 8}]
    with pytest.raises(InputError, match=r"train: composition\[0\]: unknown key\(s\) 'cout'; allowed vehicle, count"):
        train_from_mapping(data)
    data = _minimal()
    data["colour"] = "red"
    with pytest.raises(InputError, match=r"train: unknown key\(s\) 'colour'; allowed name, description"):
        train_from_mapping(data)
    data = _minimal()
    data["composition"][0]["count"] = True
    with pytest.raises(InputError, match=r"^train: composition\[0\].count: true is not an integer; allowed integer in \[1, 100\]$"):
        train_from_mapping(data)
    e = _eurostar()
    jac = next(i for i, c in enumerate(e["composition"]) if "jacobs_set" in c)
    e["composition"][jac]["reversed"] = "false"
    with pytest.raises(InputError, match=rf"composition\[{jac}\].reversed: 'false' must be true or false"):
        train_from_mapping(e, source="eurostar.toml")
    e = _eurostar()
    e["composition"][jac]["vehicle"] = "Loc"
    with pytest.raises(InputError, match=rf"composition\[{jac}\]: has both 'vehicle' and 'jacobs_set'"):
        train_from_mapping(e)
    e = _eurostar()
    e["composition"][jac]["axle_load_kN"] = [1, 2]
    with pytest.raises(InputError, match=r"unknown key\(s\) 'axle_load_kN'; allowed jacobs_set, bogies, axle_loads_kN, reversed"):
        train_from_mapping(e)


def test_axle_loads_must_match_masses_unless_declared():
    with pytest.raises(InputError, match=r"mine.toml: F PC \(per axle\): axle load 300 kN disagrees with the masses, "
                                         r"\(m_c \+ 2 m_b \+ 4 m_w\) g / 4 = 98.1 kN \(allowed within 0.5 %\)"):
        train_from_mapping(_minimal(axle_load_kN=300), source="mine.toml")
    data = _minimal(axle_load_kN=300)
    data["loads_differ_from_masses"] = True
    t = train_from_mapping(data)
    assert t.axle_loads_n == pytest.approx(np.full(12, 300e3), rel=0)
    data["loads_differ_from_masses"] = "yes"
    with pytest.raises(InputError, match="loads_differ_from_masses: 'yes' must be true or false"):
        train_from_mapping(data)
    e = _eurostar()
    jac = next(i for i, c in enumerate(e["composition"]) if "jacobs_set" in c)
    e["composition"][jac]["axle_loads_kN"] = [200.0] * len(e["composition"][jac]["axle_loads_kN"])
    with pytest.raises(InputError, match=r"F Jacobs set of 9 cars \(sum of axles\): axle load 4000 kN disagrees"):
        train_from_mapping(e)


def test_train_file_missing_and_unknown(tmp_path):
    data = _minimal()
    del data["vehicle_types"]["PC"]["b_m"]
    with pytest.raises(InputError, match=r"vehicle_types.PC.b_m: missing \(m"):
        train_from_mapping(data)
    with pytest.raises(InputError, match="train: 'TGV' is unknown; allowed ICE-2, Eurostar"):
        load_train("TGV")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [\n")
    with pytest.raises(InputError, match="not valid TOML"):
        load_train(str(bad))


@pytest.mark.parametrize("change, words", [
    (lambda d: d.pop("name"), "missing field 'name'"),
    (lambda d: d.update(name=5), "name: 5 must be a non-empty string"),
    (lambda d: d.update(name="  "), "name: '  ' must be a non-empty string"),
    (lambda d: d.update(description=5), "description: 5 must be text in quotes"),
    (lambda d: d.update(paper_train="TGV"),
     "paper_train: 'TGV' is not a train of the paper; allowed ICE-2, Eurostar, Railjet, ICE-4 (or omit it)"),
    (lambda d: d.update(loads_differ_from_masses=1), "loads_differ_from_masses: 1 must be true or false"),
    (lambda d: d.update(colour="red"), "unknown key(s) 'colour'; allowed name, description, source, paper_train, "),
])
def test_both_train_file_forms_check_their_fields_alike(change, words):
    """A train file of vehicle types and a vehicle file (bodies, wheelsets, stages) share their
    top-level fields, checked by one checker: the same fault, the same line."""
    from adm_sim.inputs.train_files import vehicle_file_mapping

    forms = {"types.toml": _minimal(), "vehicles.toml": vehicle_file_mapping(load_train("ICE-2"))}
    for source, data in forms.items():
        change(data)
        with pytest.raises(InputError) as exc:
            train_from_mapping(data, source=source)
        assert str(exc.value).startswith(f"{source}: {words}"), (source, str(exc.value))
