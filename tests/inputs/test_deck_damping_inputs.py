"""``type=cfb|sc`` on a continuous deck: EN 1991-2 Table 6.6 with L the longest span (the project's
choice, adm_sim.model.bridge.deck_damping_pct), the bridge classed, the source named; the same deck from
a spec, a TOML file and a job file's ``[bridge]`` table; the damping still given once."""

import json

import pytest

from adm_sim.cli.sim_commands import main
from adm_sim.errors import InputError
from adm_sim.inputs.bridges import bridge_from_mapping, load_bridge_file, parse_bridge_spec
from adm_sim.model.bridge import eurocode_damping_pct

DECK = "spans=12/16/12,EJ=2.5e10,mu=15000,type=cfb"


def test_type_gives_table_6_6_at_the_longest_span(tmp_path):
    """12+16+12 m CFB: zeta = 1.5 + 0.07 (20 - 16) = 1.78 % (the 16 m span's value, below the 12 m
    spans' 2.06 %), classed cfb, the source names L and the rule; TOML and spec give the same bridge."""
    b = parse_bridge_spec(DECK)
    assert b.damping_ratio == pytest.approx(0.0178, abs=1e-15)
    assert eurocode_damping_pct(12.0, "cfb") == pytest.approx(2.06, abs=1e-12)
    assert b.bridge_type == "cfb"
    assert b.damping_source.startswith("EN 1991-2 Table 6.6 lower limit for CFB (paper Table 2) with L = 16 m, "
                                       "L the longest span: the project's choice")
    f = tmp_path / "d.toml"
    f.write_text('spans = [12.0, 16.0, 12.0]\nEJ = 2.5e10\nmu = 15000.0\ntype = "cfb"\nname = "custom"\n')
    assert load_bridge_file(f) == b
    s = parse_bridge_spec("spans=9/7.5,EJ=1e10,mu=9000,type=sc")
    assert s.damping_ratio == pytest.approx((0.5 + 0.125 * 11.0) / 100.0, abs=1e-15)


def test_user_value_is_named_and_one_span_is_the_span():
    b = parse_bridge_spec("spans=12/16/12,EJ=2.5e10,mu=15000,zeta_pct=2,class=sc")
    assert b.damping_ratio == 0.02 and b.bridge_type == "sc" and b.damping_source == "the user's value (zeta_pct)"
    one = parse_bridge_spec("spans=15,EJ=2.667e10,mu=19042,type=cfb")
    assert not one.is_continuous and one.damping_ratio == pytest.approx(eurocode_damping_pct(15.0, "cfb") / 100,
                                                                       abs=1e-15)


@pytest.mark.parametrize("spec,line", [
    ("spans=12/16,EJ=2.5e10,mu=15000,type=cfb,zeta_pct=2", "bridge spec: 'zeta_pct' and 'type' both give the damping"),
    ("spans=12/16,EJ=2.5e10,mu=15000,type=cfb,class=sc", "bridge spec: 'type' already classes the bridge"),
    ("spans=12/16,EJ=2.5e10,mu=15000,type=steel", "bridge spec.type: 'steel'"),
    ("spans=12/16,EJ=2.5e10,mu=15000", "bridge spec: missing damping of the continuous deck: give zeta_pct (%, 0..20), "
                                       "zeta (fraction) or type=cfb|sc (EN 1991-2 Table 6.6 with L the longest span)"),
])
def test_refusals(spec, line):
    with pytest.raises(InputError) as exc:
        parse_bridge_spec(spec)
    assert str(exc.value).startswith(line)
    assert "\n" not in str(exc.value)


def test_the_checks_defaults_name_the_rule_as_the_projects_choice():
    """The check's list of defaults (docs/check.md's table) holds the rule as the project's choice."""
    from adm_sim.design.check_defaults import DEFAULTS, PROJECT

    row = next(d for d in DEFAULTS if d.name == "Table 6.6 length L of a continuous deck")
    assert row.kind == PROJECT and row.value.startswith("the longest span")
    assert parse_bridge_spec("spans=30/10,EJ=5e10,mu=15000,type=sc").damping_ratio == 0.005  # L = 30 m, not 10 m


def test_job_bridge_table_is_the_deck_of_the_spec():
    """A job file's [bridge] table (a TOML mapping) gives the same deck as the spec."""
    table = {"spans": [12.0, 16.0, 12.0], "EJ": 2.5e10, "mu": 15000.0, "type": "cfb", "name": "custom"}
    assert bridge_from_mapping(table, source="--job j.toml: [bridge]", typed=True) == parse_bridge_spec(DECK)


@pytest.mark.slow
def test_check_job_file_deck_prints_and_writes_the_damping_source(call_main, tmp_path):
    """``adm-sim check --job`` with a deck in the job file's [bridge] table and type=cfb: the damping
    line names zeta 1.78 % and its source, the JSON holds ``zeta_pct`` and ``damping_source``, the
    inputs' zeta row names the longest span."""
    job = tmp_path / "job.toml"
    job.write_text('trains = ["HSLM-A1"]\n\n[bridge]\nspans = [12.0, 16.0, 12.0]\nEJ = 2.5e10\nmu = 15000.0\n'
                   'type = "cfb"\n\n[job]\nproject = "P"\nstructure = "S"\nelement = "E"\nauthor = "A"\n'
                   'checker = "C"\nrevision = "1"\ndate = 2026-12-06\n')
    out = tmp_path / "r.json"
    done = call_main(main, "check", "--job", str(job), "--max-line-speed", "200", "--json", str(out))
    assert done.returncode == 0, done.stderr
    line = next(s for s in done.stdout.splitlines() if s.startswith("damping: "))
    assert line.startswith("damping: zeta = 1.78 % (EN 1991-2 Table 6.6 lower limit for CFB (paper Table 2) with "
                           "L = 16 m, L the longest span: the project's choice")
    d = json.loads(out.read_text())
    assert d["continuous_deck"] and d["spans_m"] == [12.0, 16.0, 12.0]
    assert d["zeta_pct"] == pytest.approx(1.78, abs=1e-12)
    assert d["damping_source"].startswith("EN 1991-2 Table 6.6 lower limit for CFB (paper Table 2) with L = 16 m")
    assert "L_phi_source" in d and d["L_phi_m"] == pytest.approx(1.3 * 40.0 / 3.0, rel=1e-15)
    zeta_row = next(r for r in d["inputs"] if r["input"] == "zeta")
    assert zeta_row["source"].startswith("EN 1991-2 Table 6.6 lower limit by type (paper Table 2) with L the longest "
                                         "span: the project's choice")
