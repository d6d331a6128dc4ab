"""Continuous decks as a user gives them: ``spans = [..]`` in a bridge TOML and ``spans=a/b/c`` in a
spec; the refusals (one line ``error: ...`` naming the key, the value, the unit and the allowed range,
exit 2, nothing written); the single span unchanged; ``frequencies_hz`` and ``modal_masses_kg`` in
every sweep JSON; ``--where x=<m>`` from the left abutment over the whole deck."""

import json

import numpy as np
import pytest

from adm_sim.cli.sim_commands import main
from adm_sim.errors import InputError
from adm_sim.model.bridge import Bridge, TABLE3, named_bridge
from adm_sim.inputs.bridges import load_bridge_file, parse_bridge_spec, resolve_bridge
from adm_sim.integrate.sweep import run_sweep_compiled
from adm_sim.model.spans import deck_modes
from adm_sim.inputs.train_files import load_train

GOOD = "spans=12/16/12,EJ=2e10,mu=15000/18000/15000,zeta_pct=1.5"


def _sweep(call_main, tmp_path, bridge, *extra):
    out = tmp_path / "r.json"
    done = call_main(main, "sweep", "--bridge", bridge, "--train", "ICE-2", "--speeds", "200:260:20",
                     "--json", str(out), *extra)
    return done, out


def test_toml_and_spec_give_the_same_deck(tmp_path):
    """A TOML list and a spec give the same deck; per-span EJ and mu, one value broadcast; the modes are
    the model's for those per-span values."""
    f = tmp_path / "d.toml"
    f.write_text("spans = [12.0, 16.0, 12.0]\nEJ = 2.0e10\nmu = [15000.0, 18000.0, 15000.0]\nzeta_pct = 1.5\n")
    a = load_bridge_file(f)
    b = parse_bridge_spec(GOOD)
    assert a.spans_m == b.spans_m == (12.0, 16.0, 12.0) and a.span_m == 40.0
    assert a.span_EJ_Nm2 == (2e10,) * 3 and a.span_mu_kg_m == (15000.0, 18000.0, 15000.0)
    np.testing.assert_array_equal(a.omega_rad_s, b.omega_rad_s)
    ref = deck_modes([12.0, 16.0, 12.0], [2e10] * 3, [15000.0, 18000.0, 15000.0], a.n_modes)
    np.testing.assert_array_equal(a.omega_rad_s, ref.omega_rad_s)
    assert a.mass_per_length_kg_m == pytest.approx((12 * 15000 + 16 * 18000 + 12 * 15000) / 40, rel=1e-15)


def test_n0_sets_one_EJ_for_every_span():
    """``n0`` with spans: one EJ for all spans such that the deck's first frequency is n0 (1e-12)."""
    b = parse_bridge_spec("spans=20/25,n0=4.5,mu=12000,zeta_pct=1")
    assert b.n0_hz == pytest.approx(4.5, rel=1e-12)
    assert len(set(b.span_EJ_Nm2)) == 1


def test_mode_count_rule_by_default_and_below_it_a_warning():
    """No n_modes: the rule's count (modes up to max(30 Hz, 1.5 n0), at least 3); fewer: a warning
    naming the rule, not a refusal."""
    b = parse_bridge_spec("spans=25/25,EJ=2e10,mu=15000,zeta_pct=1.5")
    f = b.frequencies_hz
    assert b.n_modes == 5 and f[-1] <= 30.0
    assert deck_modes([25, 25], [2e10] * 2, [15000] * 2, 6).frequencies_hz[5] > 30.0
    with pytest.warns(UserWarning, match=r"n_modes: 2 modes is fewer than the 5 that the rule asks for on this deck "
                                         r"\(every mode up to 30 Hz, 1.5 n0 or the third mode"):
        parse_bridge_spec("spans=25/25,EJ=2e10,mu=15000,zeta_pct=1.5,n_modes=2")


def test_one_span_given_as_spans_is_todays_bridge(tmp_path):
    """``spans = [15]`` is the simply supported span of ``L = 15`` (equal dataclasses, sine modes), and
    the named bridges B1-B4 keep their fields (no span list)."""
    assert resolve_bridge("spans=15,EJ=2.667e10,mu=19042,zeta_pct=1.85") == \
        resolve_bridge("L=15,EJ=2.667e10,mu=19042,zeta_pct=1.85")
    f = tmp_path / "one.toml"
    f.write_text("spans = [30.0]\nn0 = 3.6\nmu = 29545\nzeta_pct = 1.5\n")
    g = tmp_path / "one_L.toml"
    g.write_text("L = 30.0\nn0 = 3.6\nmu = 29545\nzeta_pct = 1.5\n")
    assert load_bridge_file(f) == Bridge(**{**load_bridge_file(g).__dict__, "name": "one"})
    for name in TABLE3:
        b = named_bridge(name)
        assert not b.is_continuous and b.spans_m == ()


def test_sweep_json_holds_frequencies_and_modal_masses(call_main, tmp_path):
    """Every sweep JSON: ``frequencies_hz`` and ``modal_masses_kg``, one per mode. B1 (exact envelope):
    n0 j^2 and mu L / 2; a two-span deck (RK4): the deck's modes."""
    done, out = _sweep(call_main, tmp_path, "B1")
    assert done.returncode == 0, done.stderr
    d = json.loads(out.read_text())
    b = named_bridge("B1")
    assert d["frequencies_hz"] == pytest.approx([b.n0_hz * j * j for j in (1, 2, 3)], rel=1e-12)
    assert d["modal_masses_kg"] == pytest.approx([19042.0 * 15 / 2] * 3, rel=1e-15)
    out.unlink()
    done, out = _sweep(call_main, tmp_path, "spans=15/15,EJ=2e10,mu=15000,zeta_pct=1.5")
    assert done.returncode == 0, done.stderr
    d = json.loads(out.read_text())
    m = deck_modes([15.0, 15.0], [2e10, 2e10], [15000.0, 15000.0], 3)
    assert d["method"] == "rk4" and d["spans_m"] == [15.0, 15.0]
    assert d["frequencies_hz"] == pytest.approx(m.frequencies_hz.tolist(), rel=1e-14)
    assert d["modal_masses_kg"] == pytest.approx(m.modal_mass_kg.tolist(), rel=1e-14)
    assert "modes: 8.061 Hz" in done.stdout


def test_where_counts_from_the_left_abutment_over_the_whole_deck(call_main, tmp_path):
    """``--where x=22.5`` on 15 + 15 m is x = 22.5 m from the left abutment (the middle of the second
    span): the JSON equals the library's run at that point (1e-15) and differs from midspan (the
    middle of the first span, 7.5 m; the train enters there first, so the two differ); x beyond the
    deck length (30 m) is refused naming 0 < x < 30 m. The FE comparison of tests/integrate/test_spans_mlm.py
    takes its response in the second span (x = 20 m of 12 + 16 + 12 m) the same way."""
    deck = "spans=15/15,EJ=2e10,mu=15000,zeta_pct=1.5"
    a = {}
    for where in ("midspan", "x=22.5"):
        done, out = _sweep(call_main, tmp_path, deck, "--where", where)
        assert done.returncode == 0, done.stderr
        a[where] = json.loads(out.read_text())["max_acc_m_s2"]
        out.unlink()
    lib = run_sweep_compiled(parse_bridge_spec(deck), load_train("ICE-2"), "mlm", [200.0, 220.0, 240.0, 260.0],
                             where=22.5)
    assert a["x=22.5"] == pytest.approx(lib.max_acc_m_s2.tolist(), rel=1e-15)
    assert np.abs(np.array(a["x=22.5"]) / np.array(a["midspan"]) - 1).max() > 0.05
    done, out = _sweep(call_main, tmp_path, deck, "--where", "x=31")
    assert done.returncode == 2 and not out.exists()
    assert done.stderr.strip().splitlines() == ["error: --where: 31 m is out of range; allowed (0, 30) m"]


BAD = [
    ("spans=15/x,EJ=2e10,mu=15000,zeta_pct=1.5", "error: bridge spec.spans[1]: 'x' is not a number; allowed [1, 150] m"),
    ("spans=15/160,EJ=2e10,mu=15000,zeta_pct=1.5", "error: bridge spec.spans[1]: 160 m is out of range; allowed [1, 150] m"),
    ("spans=0.5/15,EJ=2e10,mu=15000,zeta_pct=1.5", "error: bridge spec.spans[0]: 0.5 m is out of range; allowed [1, 150] m"),
    ("spans=10/10/10/10/10/10/10,EJ=2e10,mu=15000,zeta_pct=1.5",
     "error: bridge spec.spans: 7 spans is out of range; allowed 1..6 spans, each in [1, 150] m"),
    ("spans=15/15,EJ=2e10/3e10/2e10,mu=15000,zeta_pct=1.5",
     "error: bridge spec.EJ: 3 values for 2 spans; allowed one value or one per span (N m^2)"),
    ("spans=15/15,EJ=2e10,mu=15000/0,zeta_pct=1.5",
     "error: bridge spec.mu[1]: 0 kg/m is out of range; allowed [100, 1e+06] kg/m"),
    ("spans=15/15,EJ=-2e10,mu=15000,zeta_pct=1.5", "error: bridge spec.EJ: -2e+10 N m^2 is out of range; allowed > 0 N m^2"),
    ("spans=15/15,EJ=2e10,mu=15000,zeta_pct=1.5,n_modes=51",
     "error: bridge spec.n_modes: 51 is out of range; allowed integer in [1, 50]"),
    ("spans=15/15,EJ=2e10,mu=15000,type=steel", "error: bridge spec.type: 'steel' is not allowed; allowed 'cfb' or 'sc'"),
    ("L=30,spans=15/15,EJ=2e10,mu=15000,zeta_pct=1.5", "error: bridge spec: 'L' and 'spans' both give the length"),
    ("L=15,EJ=2e10/3e10,mu=15000,zeta_pct=1.5",
     "error: bridge spec.EJ: '2e10/3e10' gives one value per span; per-span values need spans = [..] (m)"),
    ("spans=2/15,EJ=2e10,mu=15000,zeta_pct=1.5",
     "error: spans[0]: 2 m is shorter than the longest axle group of ICE-2 (bogie wheelbase 3 m); allowed spans >= 3 m"),
]


@pytest.mark.parametrize("spec,line", BAD, ids=[b[0] for b in BAD])
def test_bad_deck_is_one_line_exit_2_nothing_written(call_main, tmp_path, spec, line):
    done, out = _sweep(call_main, tmp_path, spec)
    assert done.returncode == 2
    assert not out.exists() and list(tmp_path.iterdir()) == []
    assert done.stdout == ""  # refused before the first line of output (the axle group too)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(line), lines
    assert "Traceback" not in done.stderr


def test_bad_toml_deck(call_main, tmp_path):
    """A TOML deck: spans not a list, a span as text, a per-span list of the wrong length."""
    cases = {"spans = 15\n": "bridge file d.toml.spans: 15 is not a list of spans",
             "spans = [15, \"16\"]\n": "bridge file d.toml.spans[1]: '16' is a string, not a number",
             "spans = [15, 16]\nEJ = [2e10, 2e10, 2e10]\n": "bridge file d.toml.EJ: 3 values for 2 spans"}
    for head, line in cases.items():
        f = tmp_path / "d.toml"
        f.write_text(head + ("EJ = 2e10\n" if "EJ" not in head else "") + "mu = 15000\nzeta_pct = 1.5\n")
        done = call_main(main, "sweep", "--bridge", str(f), "--speeds", "200")
        assert done.returncode == 2
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {line}"), lines


def test_exact_method_refused_on_a_deck(call_main, tmp_path):
    deck = "spans=15/15,EJ=2e10,mu=15000,zeta_pct=1.5"
    done, out = _sweep(call_main, tmp_path, deck, "--method", "exact")
    assert done.returncode == 2 and not out.exists()
    assert done.stderr.startswith("error: --method: 'exact' is the closed-form MLM envelope of one simply supported span")


def test_entries_not_wired_refuse_a_deck():
    """A caller that takes one simply supported span (``resolve_bridge``'s default) refuses a deck in
    one line naming the entries that take continuous decks: every entry that reads a bridge (adm-sim
    check: tests/design/test_check_deck.py; adm-calib calibrate: tests/calib/test_calib_decks.py; the
    ROS graph: tests/ros/test_ros_decks.py)."""
    deck = "spans=15/15,EJ=2e10,mu=15000,zeta_pct=1.5"
    with pytest.raises(InputError) as exc:
        resolve_bridge(deck)
    assert str(exc.value) == (
        f"bridge: '{deck}' is a continuous deck of 2 spans; this entry takes one simply supported span "
        f"(allowed: L=..., B1..B4; continuous decks: adm-sim sweep (RK4), adm-sim check, adm-calib calibrate, "
        f"adm-calib study --spans-layout and the ROS graph (the bridge node, crossing.py, calibrate.py))")
    assert resolve_bridge(deck, continuous=True).spans_m == (15.0, 15.0)


def test_sweep_modes_and_damping_model(call_main, tmp_path):
    """``--modes`` and ``--damping-model`` on a sweep: the JSON holds one frequency and modal mass per
    mode asked (a deck: its first 7 modes; B1: n0 j^2 for j = 1..5), modal damping is zeta on every
    mode; fewer modes than the deck's rule: a warning naming the rule; out of range: one line, exit 2."""
    deck = "spans=25/25,EJ=2e10,mu=15000,zeta_pct=1.5"
    done, out = _sweep(call_main, tmp_path, deck, "--modes", "7", "--damping-model", "modal")
    assert done.returncode == 0, done.stderr
    d = json.loads(out.read_text())
    m = deck_modes([25.0, 25.0], [2e10, 2e10], [15000.0, 15000.0], 7)
    assert d["frequencies_hz"] == pytest.approx(m.frequencies_hz.tolist(), rel=1e-14)
    assert d["damping_model"] == "modal" and d["zeta_per_mode_pct"] == pytest.approx([1.5] * 7, rel=1e-14)
    out.unlink()
    done, out = _sweep(call_main, tmp_path, "B1", "--modes", "5")
    assert done.returncode == 0, done.stderr
    b = named_bridge("B1")
    assert json.loads(out.read_text())["frequencies_hz"] == pytest.approx([b.n0_hz * j * j for j in range(1, 6)],
                                                                          rel=1e-12)
    out.unlink()
    done, out = _sweep(call_main, tmp_path, deck, "--modes", "3")
    assert done.returncode == 0
    assert done.stderr.strip().splitlines() == [
        "warning: --modes: 3 modes is fewer than the 5 that the rule asks for on this deck (every mode up to 30 Hz, "
        "1.5 n0 or the third mode, whichever is higher (the rule of adm-sim check))"]
    out.unlink()
    for bridge, modes, line in ((deck, "51", "error: --modes: 51 is out of range; allowed integer in [1, 50]"),
                                ("B1", "21", "error: --modes: 21 is out of range; allowed integer in [1, 20]")):
        done, out = _sweep(call_main, tmp_path, bridge, "--modes", modes)
        assert done.returncode == 2 and not out.exists()
        assert done.stderr.strip().splitlines() == [line]
