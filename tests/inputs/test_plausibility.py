"""Plausibility warnings (issue 17, item 7): one table, each row triggers just outside its bound and
stays silent just inside; the command lines print one ``warning:`` line each and go on (exit 0);
``adm-calib recommend`` refuses outside the studied field unless ``--extrapolate``.

The bounds are recomputed here from the paper's printed constants (Section 3.1.1 power laws, Table 1
mass functions), not read from the module, so a wrong constant in the table fails the tests.
"""

import warnings

import pytest

from adm_sim.model import plausibility
from adm_sim.inputs.bridges import parse_bridge_spec
from adm_sim.errors import InputError, PlausibilityWarning
from adm_sim.model.plausibility import check_response, check_studied_field
from adm_sim.inputs.train_files import load_train
from train_files import two_car_train_file as _train_file

#: Relative step from a bound to "just inside" / "just outside".
EPS = 1e-3
L = 15.0
#: Independent bounds at L = 15 m from the printed constants.
N0_LB_15 = 82.43 * L**-0.9937        # 5.59 Hz, Fig. 8 lower bound
N0_UB_15 = 113.1 * L**-0.8312        # 11.9 Hz, Fig. 8 upper bound
MU6_15 = 1000 * (0.1214 * L + 2.1691)  # 3990 kg/m
MU3_15 = 1000 * (0.5584 * L + 6.627)   # 15003 kg/m
MU1_15 = 1000 * (0.843 * L + 10.45)    # 23095 kg/m


def _caught(fn, value):
    """Run ``fn(value)``; return the PlausibilityWarning messages it gave (all warnings shown)."""
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        fn(value)
    return [str(w.message) for w in rec if issubclass(w.category, PlausibilityWarning)]


def _bridge(**kw):
    spec = dict(L=L, n0=8.26, mu=19042, zeta_pct=1.85)
    spec.update(kw)
    return lambda v: parse_bridge_spec(",".join(f"{k}={v if x is None else x}" for k, x in spec.items()))


def _field(key, **base):
    ctx = dict(span_m=20.0, n0_hz=5.0, mu_kg_m=20000.0)
    ctx.update(base)

    def run(v):
        ctx[key] = v
        check_studied_field(ctx["span_m"], ctx["n0_hz"], ctx["mu_kg_m"], extrapolate=True)
    return run


L20 = 20.0
# (row key, entry point taking the value, bound, side): side -1 = a lower bound, +1 = an upper bound
ROWS = [
    ("n0", _bridge(n0=None), 0.5 * N0_LB_15, -1),
    ("n0", _bridge(n0=None), 2.0 * N0_UB_15, +1),
    ("mu", _bridge(mu=None), 0.5 * MU6_15, -1),
    ("mu", _bridge(mu=None), 2.0 * MU1_15, +1),
    ("zeta_pct_fraction", _bridge(zeta_pct=None), 0.1, -1),            # heavy bridge: only this row
    ("zeta_light", lambda v: parse_bridge_spec(f"L=15,n0=8.26,mu=7739,zeta={v}"), 0.001, -1),  # B3's mass < mu3
    ("zeta_light", _bridge(mu=None, zeta_pct=0), MU3_15, -1),          # zero damping: light below mu3
    ("acceleration", lambda v: check_response(L, v, 0.0), 50.0, +1),
    ("deflection", lambda v: check_response(L, 1.0, v), L / 100.0, +1),
    ("field_span", _field("span_m"), 40.0, +1),
    ("field_span", _field("span_m", n0_hz=25.0, mu_kg_m=5000.0), 4.0, -1),  # in the bands at 4 m
    ("field_n0", _field("n0_hz"), 82.43 * L20**-0.9937, -1),
    ("field_n0", _field("n0_hz"), 113.1 * L20**-0.8312, +1),
    ("field_mu", _field("mu_kg_m"), 1000 * (0.1214 * L20 + 2.1691), -1),
    ("field_mu", _field("mu_kg_m"), 1000 * (0.843 * L20 + 10.45), +1),
]


@pytest.mark.parametrize("key, fn, bound, side", ROWS, ids=[f"{r[0]}{'<' if r[3] < 0 else '>'}" for r in ROWS])
def test_row_triggers_just_outside_and_is_silent_just_inside(key, fn, bound, side):
    """Each bound: one warning at bound x (1 + side EPS), none at bound x (1 - side EPS). The field
    rows refuse without --extrapolate (tested below); here they run extrapolated, so they warn."""
    outside = _caught(fn, bound * (1 + side * EPS))
    assert len(outside) == 1, outside
    row = plausibility.ROWS[key]
    assert row.unit in outside[0] and row.reason in outside[0]
    assert _caught(fn, bound * (1 - side * EPS)) == []


def test_every_row_is_tested():
    assert {r[0] for r in ROWS} | {"axle_load", "car_body_mass"} == set(plausibility.ROWS)


@pytest.mark.parametrize("axle_kn, m_c_kg, n", [
    (300.0 * (1 + EPS), 40000.0, 1), (300.0 * (1 - EPS), 40000.0, 0),   # axle load > 300 kN
    (20.0 * (1 - EPS), 40000.0, 1), (20.0 * (1 + EPS), 40000.0, 0),     # axle load < 20 kN
    (190.0, 100000.0 * (1 + EPS), 1), (190.0, 100000.0 * (1 - EPS), 0),  # car body > 100 t
])
def test_train_file_rows(tmp_path, axle_kn, m_c_kg, n):
    got = _caught(load_train, _train_file(tmp_path, axle_kn, m_c_kg))
    assert len(got) == n, got
    if n:
        assert got[0].startswith("train file t.toml: ")


def test_fraction_in_pct_field_is_one_warning_with_the_hint():
    """0.0185 typed for zeta_pct on a light deck: the fraction row only (the rows exclude each other)."""
    with pytest.warns(PlausibilityWarning, match=r"zeta_pct: 0.0185 % .* write zeta_pct=1.85\); EN 1991-2 Table 6.6"):
        b = parse_bridge_spec("L=15,n0=8.26,mu=7739,zeta_pct=0.0185")
    assert b.damping_ratio == pytest.approx(0.0185e-2, rel=1e-12)  # computed as given: a warning, not a fix
    assert len(_caught(lambda v: parse_bridge_spec(v), "L=15,n0=8.26,mu=7739,zeta_pct=0.0185")) == 1


def test_bridge_file_warns_like_the_spec(tmp_path):
    from adm_sim.inputs.bridges import load_bridge_file

    p = tmp_path / "b.toml"
    p.write_text("L = 15.0\nn0 = 8.26\nmu = 19042.0\nzeta_pct = 0.0185\n")
    with pytest.warns(PlausibilityWarning, match=r"^bridge file b.toml.zeta_pct: 0.0185 % is outside the plausible "
                                                 r"range >= 0.1 %"):
        load_bridge_file(p)


def test_named_and_field_bridges_are_silent():
    """The paper's bridges B1-B4 and the field's corners are plausible by construction."""
    from adm_sim.inputs.bridges import resolve_bridge

    for name in ("B1", "B2", "B3", "B4"):
        assert _caught(resolve_bridge, name) == []
    for spec in ("L=4,n0=21.03,mu=2655,zeta_pct=2.5", "L=40,n0=2.13,mu=44170,zeta_pct=1.5"):
        assert _caught(parse_bridge_spec, spec) == []


def test_studied_field_refuses_without_extrapolate():
    with pytest.raises(InputError, match=r"^mu_kg_m: 60000 kg/m is outside the studied field \[4597, 27310\] kg/m "
                                         r"for L = 20 m; .*give extrapolate=True to accept"):
        check_studied_field(20.0, 5.0, 60000.0)
    with pytest.raises(InputError, match=r"^--mu: 60000 kg/m .*give --extrapolate to accept"):
        check_studied_field(20.0, 5.0, 60000.0, names={"mu_kg_m": "--mu", "extrapolate": "--extrapolate"})


# ---------------------------------------------------------------------- the command lines
def _warning_lines(err):
    return [ln for ln in err.splitlines() if ln.startswith("warning: ")]


def test_sweep_prints_one_warning_line_and_exits_0(capsys):
    from adm_sim.cli.sim_commands import main

    shown = warnings.showwarning
    assert main(["sweep", "--bridge", "L=15,n0=8.26,mu=19042,zeta_pct=0.0185", "--speeds", "250"]) == 0
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and lines == _warning_lines(err), err
    assert "0.0185 %" in lines[0] and ">= 0.1 %" in lines[0] and "EN 1991-2 Table 6.6" in lines[0]
    assert warnings.showwarning is shown  # the CLI's display is undone at its end


def test_sweep_warns_about_results_no_bridge_survives(capsys):
    """An undamped light 15 m deck at 0.6 Hz: the bridge lines (n0, damping) and the two result
    lines (acceleration > 50 m/s², deflection > L/100 = 0.15 m), still exit 0."""
    from adm_sim.cli.sim_commands import main

    assert main(["sweep", "--bridge", "L=15,n0=0.6,mu=3000,zeta_pct=0", "--speeds", "250", "--method", "rk4"]) == 0
    lines = _warning_lines(capsys.readouterr().err)
    assert len(lines) == 4, lines
    assert lines[0].startswith("warning: bridge spec: n0: 0.6 Hz is outside the plausible range")
    assert lines[1].startswith("warning: bridge spec: damping of a light deck")
    assert lines[2].startswith("warning: sweep: at 250 km/h: peak acceleration") and "<= 50 m/s²" in lines[2]
    assert lines[3].startswith("warning: sweep: at 250 km/h: peak deflection") and "<= 0.15 m for L = 15 m" in lines[3]


def test_check_warns_once_per_quantity_naming_train_and_speed(capsys):
    """adm-sim check of a light, soft 15 m deck: the largest acceleration and deflection over the
    trains, one line each, named by train and speed; the verdict is still printed (exit 0)."""
    from adm_sim.cli.sim_commands import main

    assert main(["check", "--bridge", "L=15,n0=3,mu=3000,zeta_pct=0.2", "--max-line-speed", "160",
                 "--trains", "HSLM-A1"]) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 2 and lines == _warning_lines(err), err
    assert lines[0].startswith("warning: check: HSLM-A1 at ") and "peak acceleration" in lines[0]
    assert "peak deflection" in lines[1] and "<= 0.15 m for L = 15 m" in lines[1]
    assert "FAIL" in out


@pytest.mark.parametrize("extra, code", [([], 2), (["--extrapolate"], 0)])
def test_recommend_outside_the_field(capsys, extra, code):
    from adm_calib.calib_commands import main

    argv = ["recommend", "--train", "ICE-2", "--n0", "5", "--mu", "60000", "--type", "cfb", "--span", "20"]
    assert main(argv + extra) == code
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if "study cases)" not in ln]  # the study's neighbours: test_recommend_warnings
    assert len(lines) == 1
    assert lines[0].startswith("error: --mu: 60000 kg/m is outside the studied field" if code else
                               "warning: --mu: 60000 kg/m is outside the studied field")
    assert ("dz_LB = " in out) == (code == 0)


def test_recommend_span_beyond_the_field_with_extrapolate(capsys):
    """Without --extrapolate the span refusal is unchanged; with it a 60 m span answers with one warning."""
    from adm_calib.calib_commands import main

    argv = ["recommend", "--train", "ICE-2", "--n0", "2.5", "--mu", "50000", "--type", "cfb", "--span", "60"]
    assert main(argv) == 2
    assert capsys.readouterr().err == "error: --span: 60 m is out of range; allowed [4, 40] m\n"
    assert main(argv + ["--extrapolate"]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if "study cases)" not in ln]
    assert len(err) == 1 and err[0].startswith("warning: --span: 60 m is outside the studied field [4, 40] m")


def test_docs_hold_the_table():
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "plausibility.md").read_text()
    assert text.endswith(plausibility.markdown_table())


#: Row -> bridge node parameter values (over the B3 preset's) that cross it, and how its line starts.
BRIDGE_NODE_ROWS = {
    "n0": ({"n0_hz": 100.0}, "n0_hz: 100 Hz is outside the plausible range [2.795, 23.82] Hz for L = 15 m"),
    "mu": ({"mu_kg_m": 150.0}, "mu_kg_m: 150 kg/m is outside the plausible range [1995, 46190] kg/m for L = 15 m"),
    "zeta_pct_fraction": ({"zeta_pct": 0.0185}, "zeta_pct: 0.0185 % is outside the plausible range >= 0.1 %"),
    "zeta_light": ({"zeta_pct": 0.0}, "zeta_pct: damping of a light deck (mu = 7739 kg/m < mu3(L) = 15003 kg/m): "
                                      "0 % is outside the plausible range >= 0.1 % for L = 15 m"),
}


def test_checked_in_names_the_node_parameters_and_they_warn(tmp_path):
    """The table's "checked in" column names the node parameters a row is checked on, and each of
    them warns, naming the parameter: the bridge node's check (``bridge_plausibility``, as the node
    and the launchers' pre-flight call it) on the B3 preset, and the train node's ``train``
    parameter (``validate_train``) naming a train file; no other row claims a node parameter."""
    from adm_sim.inputs.bridges import resolve_bridge
    from adm_sim.nodes.params import TRAIN_SPECS, bridge_plausibility, bridge_specs, validate_train

    claimed = {k for k, r in plausibility.ROWS.items() if "bridge node parameter" in r.checked_in}
    assert claimed == set(BRIDGE_NODE_ROWS)
    preset = resolve_bridge("B3")
    defaults = {sp.name: sp.default for sp in bridge_specs(preset)}
    assert _caught(lambda v: bridge_plausibility(preset, defaults), None) == []  # the preset itself: quiet
    for key, (values, start) in BRIDGE_NODE_ROWS.items():
        row = plausibility.ROWS[key]
        assert all(name in row.checked_in for name in values), (key, row.checked_in)
        said = [t for t in _caught(lambda v: bridge_plausibility(preset, defaults | v), values) if row.reason in t]
        assert len(said) == 1 and said[0].startswith(start), (key, said)
    train_rows = {k for k, r in plausibility.ROWS.items() if "train node parameter train" in r.checked_in}
    assert train_rows == {"axle_load", "car_body_mass"}
    values = {sp.name: sp.default for sp in TRAIN_SPECS} | {"train": str(_train_file(tmp_path, 400.0, 120000.0))}
    said = _caught(validate_train, values)
    assert [t.split(" is outside")[0] for t in said] == [
        "train file t.toml: largest axle load: 400 kN", "train file t.toml: vehicle_types.V.m_c_kg: 120 t"]


def test_calibrate_warns_about_peaks_no_bridge_survives(capsys):
    """A 4 m deck of 1.4 t/m at 0.5 % (the lightest corner of Table 1 and below): the MLM and DIM
    peaks are hundreds to thousands of m/s²; one warning per curve, named by bridge, train, model
    and speed, before the (failed) calibration's report; B1 x ICE-2 (2.25 / 1.81 m/s²) warns nothing."""
    from adm_calib.calib_commands import main

    main(["calibrate", "--bridge", "L=4,n0=11,mu=1400,zeta_pct=0.5", "--train", "ICE-2"])
    lines = [ln for ln in capsys.readouterr().err.splitlines() if "peak acceleration" in ln]
    assert len(lines) == 2, lines
    assert lines[0].startswith("warning: custom x ICE-2: MLM at ") and "<= 50 m/s²" in lines[0]
    assert lines[1].startswith("warning: custom x ICE-2: DIM at ")
    value = float(lines[1].split("peak acceleration: ")[1].split(" m/s²")[0])
    assert value > 50.0
    assert main(["calibrate", "--bridge", "B1", "--train", "ICE-2", "--speeds", "250:275:1"]) == 0
    assert "peak acceleration" not in capsys.readouterr().err
