"""The EN 1991-2 check's defaults, each pinned against the code that applies it, and the table of
docs/check.md ("Defaults and their sources") kept equal to :data:`adm_sim.design.check_defaults.DEFAULTS`.

Numbers: Φ3 = 2.16 / (sqrt(L) - 0.2) + 0.73 (EN 1991-2 6.4.5.2(3) Eq. 6.5) and Φ2 = 1.44 / (sqrt(L) -
0.2) + 0.82 (Eq. 6.4) written out here; δ_H = θ h by hand; the ballast bounds from 1700 kg/m3 and
2100 kg/m3 x 1.30 by hand.
"""

import inspect
import json
import math
from pathlib import Path

import pytest

from adm_sim.cli.sim_commands import main
from adm_sim.design import check as ck
from adm_sim.design import check_sls as sls
from adm_sim.design.check_defaults import DEFAULTS, PROJECT, STANDARD, project_choices
from adm_sim.design.design_loads import ANNEX_C_FORMULA, DEFAULT_MAINTENANCE, design_comparison
from adm_sim.limits import ACC_LIMITS_M_S2
from adm_sim.model.bridge import named_bridge

ROOT = Path(__file__).resolve().parents[2]
B1 = named_bridge("B1")


def _default(name):
    return next(d for d in DEFAULTS if d.name == name)


def test_docs_table_is_the_registry():
    text = (ROOT / "docs" / "check.md").read_text()
    table = text.split("<!-- defaults:begin -->")[1].split("<!-- defaults:end -->")[0]
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in table.strip().splitlines()[2:]]
    assert rows == [[d.name, d.value, d.source, d.kind] for d in DEFAULTS]
    assert {d.kind for d in DEFAULTS} == {STANDARD, PROJECT}


@pytest.fixture(scope="module")
def b1_a7():
    """B1, V = 250 km/h, HSLM-A7, every default; and the same with careful maintenance named."""
    trains = ck.resolve_trains("HSLM-A7")
    return ck.run_check(B1, 250.0, trains), ck.run_check(B1, 250.0, trains, track_maintenance="careful")


def test_track_maintenance_default_is_phi3_with_full_phi_dd(b1_a7):
    """EN 1991-2 6.4.5.2(3)P: Φ3 where no dynamic factor is specified; Annex C's 1 + φ' + φ''."""
    res, careful = b1_a7
    assert DEFAULT_MAINTENANCE == "standard" and _default("track maintenance").kind == STANDARD
    assert inspect.signature(ck.run_check).parameters["track_maintenance"].default is None
    phi3 = 2.16 / (math.sqrt(15.0) - 0.2) + 0.73
    phi2 = 1.44 / (math.sqrt(15.0) - 0.2) + 0.82
    d = res.trains[0].design
    assert (res.track_maintenance, res.maintenance_named) == ("standard", False)
    assert d.Phi == pytest.approx(phi3, rel=1e-12) and d.phi_dd_factor == 1.0  # L_Phi = the span (Table 6.2 5.1)
    assert res.sls.Phi == pytest.approx(phi3, rel=1e-12)
    c = careful.trains[0].design
    assert (careful.track_maintenance, careful.maintenance_named) == ("careful", True)
    assert c.Phi == pytest.approx(phi2, rel=1e-12) and c.phi_dd_factor == 0.5
    text = ck.CheckResult.to_dict(res)["track_maintenance_reason"]
    assert "the default: EN 1991-2 6.4.5.2(3)P uses Phi3 where no dynamic factor is specified" in text
    assert "named with --track-maintenance careful" in careful.to_dict()["track_maintenance_reason"]
    assert ANNEX_C_FORMULA == {"standard": "1 + phi' + phi''", "careful": "1 + phi' + phi''/2"}
    # the speed of φ'' is the maximum line speed (Annex C), not 1.2 V
    assert d.speed_m_s == pytest.approx(250.0 / 3.6, rel=1e-12)


def test_run_check_defaults_pinned(b1_a7):
    res, _ = b1_a7
    p = inspect.signature(ck.run_check).parameters
    assert (p["step_kmh"].default, p["where"].default, p["damping_model"].default, p["damping"].default,
            p["alpha"].default, p["mass_bounds"].default, p["deck_end_height_m"].default) == (
        1.0, "deck", "modal", "none", 1.0, None, None)
    v = ck.check_speeds_kmh(250.0)
    assert (v[0], v[-1]) == (144.0, 300.0)  # 40 m/s .. 1.2 V
    assert ACC_LIMITS_M_S2 == {"ballasted": 3.5, "direct_fastening": 5.0} and res.limit_m_s2 == 3.5
    assert ck.REFINE_STEP_KMH == 0.1 and ck.NEAR_GOVERNING_FRACTION == 0.05
    assert res.sls.deflection_limit_m == pytest.approx(15.0 / 600.0, rel=1e-15)
    assert sls.LATERAL_FREQUENCY_MIN_HZ == 1.2
    d = design_comparison("x", 15.0, B1.EJ_Nm2, B1.n0_hz, [0.0], [1e5], 70.0, 0.1)
    assert d.L_phi_m == 15.0 and d.maintenance == "standard"


def test_end_rotation_is_an_infrastructure_managers_rule_and_delta_h(b1_a7):
    res, _ = b1_a7
    s = res.sls
    assert sls.END_ROTATION_LIMIT_RAD == 6.5e-3 and _default("deck end rotation limit").kind == PROJECT
    assert "not EN 1991-2" in sls.END_ROTATION_SOURCE and "6.5.4.5.2 limits the deck-end displacements" in \
        sls.END_ROTATION_SOURCE
    assert s.delta_h_m is None and any(x.startswith("deck-end displacement") for x in res.not_checked())
    assert any("infrastructure manager's rule" in line for line in s.lines())
    # δ_H = θ h: h = 1.2 m on the same rotation, against 8 mm and 10 mm
    with_h = sls.Serviceability(**{**s.__dict__, "deck_end_height_m": 1.2})
    assert with_h.delta_h_m == pytest.approx(s.end_rotation_rad * 1.2, rel=1e-15)
    assert sls.DELTA_H_LIMITS_M == (8e-3, 10e-3) and with_h.delta_h_ok == (True, True)
    big = sls.Serviceability(**{**s.__dict__, "deck_end_height_m": 9.5 / 1e3 / s.end_rotation_rad})
    assert big.delta_h_ok == (False, True)  # 9.5 mm: above 8, below 10
    assert "limit 8 mm FAIL, limit 10 mm PASS" in " ".join(big.lines())


def test_mass_bounds_on_where_ballast_is_given_with_labelled_project_choices():
    """--ballast 4000,2000 on B1 (19042 kg/m): lower 19042 - 4000 + 4000 x 1700/2000, upper
    19042 - 4000 + 4000 x 1.30 x 2100/2000 (kg/m); 2100 kg/m3 and +30 % printed as the project's choice."""
    assert (ck.BALLAST_DENSITY_MIN_KG_M3, ck.BALLAST_DENSITY_MAX_KG_M3, ck.BALLAST_DEPTH_FACTOR_UPPER) == (
        1700.0, 2100.0, 1.30)
    assert {d.name for d in project_choices()} >= {"upper-bound ballast density", "upper-bound ballast depth allowance"}
    assert _default("lower-bound ballast density").kind == STANDARD
    trains = ck.resolve_trains("HSLM-A7")
    res = ck.run_check(B1, 250.0, trains, ballast=(4000.0, 2000.0))
    (lo_label, lo), (hi_label, hi) = res.bounds
    assert lo.bridge.mass_per_length_kg_m == pytest.approx(19042.0 - 4000.0 + 3400.0, rel=1e-12)
    assert hi.bridge.mass_per_length_kg_m == pytest.approx(19042.0 - 4000.0 + 4000.0 * 1.3 * 2100 / 2000, rel=1e-12)
    assert "(project's choice)" in hi_label and "depth +30 % (project's choice)" in hi_label
    assert "project's choice" in res.to_dict()["bounds"][1]["case"]


@pytest.mark.parametrize("args, message", [
    (["--deck-end-height", "-1"], "error: --deck-end-height: '-1' m is out of range; allowed (0, 10] m"),
    (["--deck-end-height", "abc"], "error: --deck-end-height: 'abc' is not a height"),
    (["--ballast", "4000"], "error: --ballast: 'standard:4000' does not give the ballast"),
    (["--ballast", "4000,900"], "error: --ballast: ballast density 900 kg/m3 is out of range"),
])
def test_bad_default_inputs(tmp_path, call_main, args, message):
    out = tmp_path / "c.json"
    done = call_main(main, "check", "--bridge", "B1", "--max-line-speed", "250", "--trains", "HSLM-A7",
                     "--json", str(out), *args)
    assert done.returncode == 2 and done.stdout == "" and not out.exists()
    assert done.stderr.strip().splitlines() == [done.stderr.strip()] and done.stderr.startswith(message), done.stderr


def test_check_command_prints_the_default_and_the_project_choices(tmp_path, call_main):
    out = tmp_path / "c.json"
    done = call_main(main, "check", "--bridge", "B1", "--max-line-speed", "250", "--trains", "HSLM-A7",
                     "--deck-end-height", "1.2", "--json", str(out))
    assert done.returncode == 0, done.stderr
    assert "track maintenance: Phi3 and phi'' (standard maintenance, EN 1991-2 6.4.5.2(3); Annex C: " \
           "1 + phi' + phi''): the default" in done.stdout
    assert "project's choices (not the standard's" in done.stdout and "  upper-bound ballast density: 2100" in done.stdout
    d = json.loads(out.read_text())
    assert d["en1990_a2_4_4_serviceability"]["delta_h_m"] == pytest.approx(
        1.2 * d["en1990_a2_4_4_serviceability"]["end_rotation_rad"], rel=1e-15)
    assert [x["name"] for x in d["defaults"]] == [x.name for x in DEFAULTS]
    assert [c["name"] for c in d["project_choices"]] == [c.name for c in project_choices()]
    assert all(c["kind"] == PROJECT for c in d["project_choices"])
