"""The field registry (:mod:`adm_sim.fields`) is the one home of every user-facing range.

* every ROS parameter spec with a range is a view of its registry field (unit, bounds, check);
* every ``--help`` line of a registry flag states the registry's range;
* a value out of range typed as a TOML key, a CLI flag and a ROS parameter gives messages built from
  the same field (value, unit, range identical after the name);
* no surface module writes a range of a registry field as a literal (an AST scan, as
  tests/house/test_protocol.py scans for topic names), and the scan finds one planted;
* docs/fields.md's table is the registry's.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

from source_trees import tree, tree_of_text

from adm_sim import fields
from adm_sim.errors import InputError

ROOT = Path(__file__).resolve().parents[2]


def tail(message):
    """A message without the name in front (``'x: 3 steps is out of range; ...'`` -> ``'3 steps is ...'``)."""
    return message.split(": ", 1)[1] if ": " in message else message


def _has_rclpy():
    import importlib.util

    return importlib.util.find_spec("rclpy") is not None


def refusal(call):
    with pytest.raises(InputError) as info:
        call()
    return str(info.value)


# ---------------------------------------------------------------- the views themselves
def test_scaled_views_are_the_field_in_another_unit():
    """zeta in % is 100 x the fraction; axle loads in kN are the N range / 1000; the bounds are exact."""
    zeta = fields.FIELDS["damping_ratio"]
    pct = zeta.view("ros", "zeta_pct")
    assert (pct.unit, pct.lo, pct.hi) == ("%", 0.0, 20.0)  # not 20.000000000000004
    assert pct.to_core(1.85) == 1.85 / 100.0  # the spelling's conversion, the core's number bit for bit
    axle = fields.view("toml", "axle_load_kN")
    assert (axle.unit, axle.lo, axle.hi) == ("kN", 1.0, 500.0)
    assert axle.to_core(170.0) == 170.0 * 1000.0
    assert fields.view("cli", "--delta-zeta-pct").hi == 100.0 * fields.FIELDS["delta_zeta"].hi


def test_special_value_outside_the_range_is_allowed_and_stated():
    n0 = fields.view("ros", "n0_hz")
    assert n0.check(0.0) == 0.0
    assert n0.check(8.26) == 8.26
    msg = refusal(lambda: n0.check(0.3))
    assert msg == "n0_hz: 0.3 Hz is out of range; allowed 0 (from EJ_Nm2) or [0.5, 100] Hz"
    # the core spelling has no special value: 0 Hz is refused there
    assert refusal(lambda: fields.FIELDS["n0_hz"].check(0.0)) == "n0_hz: 0 Hz is out of range; allowed [0.5, 100] Hz"


def test_lower_bound_set_by_another_value():
    dz = fields.FIELDS["delta_zeta"]
    assert dz.check(-0.01, lo=-0.0185) == -0.01
    assert refusal(lambda: dz.check(-0.02, lo=-0.0185)) == \
        "delta_zeta: -0.02 - (fraction) is out of range; allowed [-0.0185, 0.2] - (fraction)"


# ---------------------------------------------------------------- ROS parameters
def all_param_specs():
    pytest.importorskip("rclpy")
    from adm_calib.nodes.calibration_node import CALIBRATION_SPECS
    from adm_sim.model.bridge import named_bridge
    from adm_sim.nodes.bridge_node import bridge_specs
    from adm_sim.nodes.driver import DRIVER_SPECS
    from adm_sim.nodes.train_node import TRAIN_SPECS

    return [*bridge_specs(named_bridge("B1")), *TRAIN_SPECS, *DRIVER_SPECS, *CALIBRATION_SPECS]


def test_every_ros_parameter_with_a_range_is_its_registry_field():
    specs = all_param_specs()
    ros = fields.spellings("ros")
    outside = []
    for s in specs:
        if s.name not in ros:
            outside.append(s.name)
            assert s.lo is None and s.hi is None, f"{s.name}: a range outside the registry"
            continue
        v = ros[s.name]
        assert s.view == v
        assert s.unit == v.unit
        if v.field.type is str or v.spelling.many:
            assert (s.lo, s.hi) == (None, None)
            assert type(s.default) is str, s.name
        else:
            assert (s.lo, s.hi) == (v.lo, v.hi), s.name
            assert type(s.default) is v.field.type, s.name
    # what stays outside: paths, switches and URLs of the driver (no range, no unit), and the train
    # node's track profile spec (checked by adm_sim.inputs.track_profile.parse_irregularity)
    assert sorted(outside) == ["irregularity", "overwrite", "record_path", "rerun_connect", "rerun_spawn", "rrd_path",
                              "run_phase", "summary_path"]


def test_parameter_refusals_are_the_registry_messages():
    """Just beyond each bound, the parameter's check refuses with the field's message."""
    checked = 0
    for s in all_param_specs():
        v = s.view
        if v is None or v.field.type not in (int, float) or v.spelling.many:
            continue
        for bad in [b for b in ((v.lo - 1) if v.lo is not None else None, (v.hi + 1) if v.hi is not None else None)
                    if b is not None and all(b != sv for sv, _ in v.special)]:
            bad = v.field.type(bad)
            assert refusal(lambda: s.check(bad)) == refusal(lambda: v.check(bad, name=s.name))
            assert v.range_text() in refusal(lambda: s.check(bad))
            checked += 1
    assert checked >= 25


# ---------------------------------------------------------------- CLI options
def parsers():
    from adm_calib.calib_commands import build_parser as calib_parser
    from adm_sim.cli.sim_commands import build_parser as sim_parser

    sys.path.insert(0, str(ROOT / "launch_scripts"))
    try:
        import replay
    finally:
        sys.path.remove(str(ROOT / "launch_scripts"))
    out = []
    for top in (sim_parser(), calib_parser()):
        for action in top._actions:
            if getattr(action, "choices", None) and isinstance(action.choices, dict):
                out += list(action.choices.values())
    return out, replay


def test_help_of_every_registry_flag_states_its_range():
    cli = fields.spellings("cli")
    subs, _ = parsers()
    seen = set()
    for p in subs:
        for action in p._actions:
            for flag in action.option_strings:
                if flag in cli and cli[flag].range_text():
                    text = (action.help or "") % {}
                    if cli[flag].field.choices:
                        assert tuple(action.choices) == cli[flag].field.choices or flag == "--track", flag
                    else:
                        shown = text.replace("[-zeta,", f"[{cli[flag].lo:g},")
                        assert f"({cli[flag].range_text()})" in shown or f"in {cli[flag].range_text()})" in shown, \
                            (p.prog, flag, text)
                    seen.add(flag)
    assert {"--steps-per-period", "--delta-zeta-pct", "--jobs", "--workers", "--max-line-speed",
            "--speed-step", "--dim-grid", "--model", "--speeds", "--limit", "--type"} <= seen


@pytest.mark.slow
def test_sweep_help_printed_shows_the_registry_range():
    r = subprocess.run([sys.executable, "-m", "adm_sim.cli.sim_commands", "sweep", "--help"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0
    text = " ".join(r.stdout.split())
    spp = fields.view("cli", "--steps-per-period")
    assert f"({spp.range_text()})" in text
    assert "([4, 10000] steps)" in text  # the number a user reads, independent of the formatting code
    assert "additional damping ([-zeta, 20] %)" in text


def test_launch_script_domain_id_help_and_check_from_the_registry():
    _, replay = parsers()
    v = fields.view("cli", "--domain-id")
    assert v.range_text() == "integer in [0, 232]"
    from adm_sim.processes.dds_env import DOMAIN_ID_MAX

    assert DOMAIN_ID_MAX == v.hi
    assert refusal(lambda: v.check("500")) == "--domain-id: 500 is out of range; allowed integer in [0, 232]"


# ---------------------------------------------------------------- one field, three surfaces
def test_span_out_of_range_same_message_from_toml_cli_and_ros(tmp_path, capsys):
    """span = 200 m as a TOML key, in a --bridge spec on the command line, and as a ROS parameter."""
    from adm_sim.inputs.bridges import load_bridge_file
    from adm_sim.cli.sim_commands import main

    toml = tmp_path / "b.toml"
    toml.write_text("L = 200.0\nn0 = 5.0\nmu = 10000.0\nzeta_pct = 1.0\n")
    m_toml = refusal(lambda: load_bridge_file(toml))
    assert main(["sweep", "--bridge", "L=200,n0=5,mu=10000,zeta_pct=1"]) == 2
    m_cli = capsys.readouterr().err.strip().removeprefix("error: ")
    m_ros = refusal(lambda: fields.view("ros", "span_m").check(200.0))
    if _has_rclpy():  # the bridge node's own check of its parameters (start-up, on-set, launchers)
        from adm_sim.model.bridge import named_bridge
        from adm_sim.nodes.bridge_node import bridge_from_params, bridge_specs

        values = {sp.name: sp.default for sp in bridge_specs(named_bridge("B1"))}
        m_node = refusal(lambda: bridge_from_params(named_bridge("B1"), dict(values, span_m=200.0)))
        spec = next(sp for sp in bridge_specs(named_bridge("B1")) if sp.name == "span_m")
        assert m_node == refusal(lambda: spec.check(200.0)) == m_ros
    assert m_toml.startswith("bridge file b.toml.L: ")
    assert m_cli.startswith("bridge spec.L: ")
    assert tail(m_toml) == tail(m_cli) == tail(m_ros) == "200 m is out of range; allowed [1, 150] m"


def test_steps_per_period_same_message_from_cli_ros_and_core(capsys):
    from adm_sim.cli.sim_commands import main
    from adm_sim.integrate.step_grid import StepOptions

    assert main(["sweep", "--model", "dim", "--speeds", "200", "--steps-per-period", "3"]) == 2
    m_cli = capsys.readouterr().err.strip().removeprefix("error: ")
    m_ros = refusal(lambda: fields.view("ros", "steps_per_period").check(3.0))
    if _has_rclpy():
        from adm_sim.model.bridge import named_bridge
        from adm_sim.nodes.bridge_node import bridge_specs

        spec = next(sp for sp in bridge_specs(named_bridge("B1")) if sp.name == "steps_per_period")
        assert refusal(lambda: spec.check(3.0)) == m_ros
    m_core = refusal(lambda: StepOptions(steps_per_period=3.0))
    assert m_cli.startswith("--steps-per-period: ")
    assert tail(m_cli) == tail(m_ros) == tail(m_core) == "3 steps is out of range; allowed [4, 10000] steps"


def test_damping_in_percent_and_as_fraction_are_one_field(tmp_path, capsys):
    """zeta_pct = 25 (TOML, %) and the bridge node's zeta_pct; zeta = 0.25 (TOML, fraction): the
    same bound, 20 % = 0.2, converted by the one table."""
    from adm_sim.inputs.bridges import load_bridge_file

    pct, frac = tmp_path / "p.toml", tmp_path / "f.toml"
    pct.write_text("L = 15.0\nn0 = 8.0\nmu = 10000.0\nzeta_pct = 25.0\n")
    frac.write_text("L = 15.0\nn0 = 8.0\nmu = 10000.0\nzeta = 0.25\n")
    m_pct = refusal(lambda: load_bridge_file(pct))
    m_frac = refusal(lambda: load_bridge_file(frac))
    m_ros = refusal(lambda: fields.view("ros", "zeta_pct").check(25.0))
    assert tail(m_pct) == tail(m_ros) == "25 % is out of range; allowed [0, 20] %"
    assert tail(m_frac) == "0.25 - (fraction) is out of range; allowed [0, 0.2] - (fraction)"


# ---------------------------------------------------------------- no range literal left in the surfaces
#: The surfaces: the modules that read what a user typed (TOML, CLI, ROS parameters, launchers).
SURFACES = [*(ROOT / "src" / "adm_sim").glob("model/bridge.py"), ROOT / "src/adm_sim/model/trains.py",
            ROOT / "src/adm_sim/integrate/step_grid.py", ROOT / "src/adm_sim/integrate/run_contract.py",
            ROOT / "src/adm_sim/integrate/rk4_sides.py", ROOT / "src/adm_sim/integrate/sweep.py", ROOT / "src/adm_sim/limits.py",
            *sorted((ROOT / "src/adm_sim/cli").glob("*.py")), ROOT / "src/adm_sim/cliutil.py", ROOT / "src/adm_sim/design/check.py",
            ROOT / "src/adm_sim/integrate/compiled_batch.py", ROOT / "src/adm_sim/processes/dds_env.py",
            *sorted((ROOT / "src/adm_sim/nodes").glob("*.py")), ROOT / "src/adm_calib/calib_commands.py",
            *sorted((ROOT / "src/adm_calib/cli").glob("*.py")),
            *sorted((ROOT / "src/adm_calib/nodes").glob("*.py")),
            *sorted((ROOT / "launch_scripts").glob("*.py"))]
CHECKS = {"check_range", "check_number", "check_int", "check_choice", "ParamSpec"}
#: Checks of a registry name by hand that stay, with the reason.
EXEMPT = {
    # adm-sim check --modes: the lower bound is the bridge's EN 1990 A2.4.4.2.1 mode count, the upper
    # the registry's (FIELDS["n_modes"].hi); its float-then-integer message is the check's documented one
    ("src/adm_sim/design/check.py", "check_range('n_modes', ...)"),
    # the monitor's track_type: empty means "the bridge description's, else ballasted"; the choices are
    # the registry's, checked by limits.check_track_type
    ("src/adm_sim/nodes/monitor_node.py", "ParamSpec('track_type', ...)"),
}


def _registry_names():
    names = set(fields.FIELDS)
    for f in fields.FIELDS.values():
        names |= {s.key for s in f.spellings}
    return names


def _ranges():
    return {(f.lo, f.hi) for f in fields.FIELDS.values() if f.lo is not None and f.hi is not None}


def range_literals(source, filename="<test>"):
    """``(line, text)`` of every check of a registry name by hand (``check_range("span_m", ...)``,
    ``ParamSpec("zeta_pct", ...)``) and every literal pair equal to a registry range."""
    names, ranges, hits = _registry_names(), _ranges(), []
    for node in ast.walk(tree_of_text(source, filename)):
        if isinstance(node, ast.Call):
            fn = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
            if fn in CHECKS and node.args and isinstance(node.args[0], ast.Constant) and node.args[0].value in names:
                hits.append((node.lineno, f"{fn}({node.args[0].value!r}, ...)"))
            nums = [a.value for a in node.args if isinstance(a, ast.Constant) and type(a.value) in (int, float)]
            if fn in CHECKS and any(nums[i:i + 2] and tuple(nums[i:i + 2]) in ranges for i in range(len(nums))):
                hits.append((node.lineno, f"{fn}(... {nums} ...)"))
        if isinstance(node, ast.Tuple) and len(node.elts) == 2 and all(
                isinstance(e, ast.Constant) and type(e.value) in (int, float) for e in node.elts):
            pair = tuple(e.value for e in node.elts)
            if pair in ranges and pair != (0.0, 1.0):
                hits.append((node.lineno, repr(pair)))
    return hits


def test_no_range_of_a_registry_field_is_written_in_a_surface():
    hits = []
    for path in SURFACES:
        for line, text in range_literals(path.read_text(), str(path)):
            if (str(path.relative_to(ROOT)), text) not in EXEMPT:
                hits.append(f"{path.relative_to(ROOT)}:{line}: {text}")
    assert hits == []


def test_the_scan_finds_a_planted_range():
    """The scan of the test above can fail: it sees the shapes the registry replaced."""
    planted = ['check_range("span_m", x, "m", 1.0, 150.0)', 'c.ParamSpec("zeta_pct", 1.0, "%", "d", 0.0, 20.0)',
               'SPAN_RANGE_M = (1.0, 150.0)', 'check_range("--foo", x, "steps", 4.0, 10000.0)',
               'check_int("n_modes", v, 1, 20)']
    assert [bool(range_literals(s)) for s in planted] == [True] * len(planted)
    assert not range_literals('fields.view("cli", "--steps-per-period").check(x)')
    assert not range_literals('check_range("tolerance", a, "-")')  # not a registry name


# ---------------------------------------------------------------- docs/fields.md
def _spelled(f, surface):
    out = []
    for s in f.spellings:
        if s.surface == surface:
            extra = [] if not s.unit or s.unit == f.unit else [s.unit]
            v = f.view(surface, s.key)
            if (s.lo, s.hi) != (None, None) or v.specials_outside():
                extra.append(v.range_text())
            out.append(f"`{s.key}`" + (f" ({'; '.join(extra)})" if extra else ""))
    return ", ".join(out) or "-"


def registry_rows():
    rows = []
    for group in fields.GROUPS:
        for f in fields.FIELDS.values():
            if f.group != group:
                continue
            v = f.view()
            rng = v.range_text() or "-"
            if f.lo_text:
                rng = rng.replace(f"[{v.lo:g},", f"[{f.lo_text},", 1)
            typ = "choice" if f.choices else {float: "float", int: "int", str: "text"}[f.type]
            keys = sorted({s.key for s in f.spellings if s.surface in ("toml", "spec")})
            toml = _spelled(f, "toml") if any(s.surface == "toml" for s in f.spellings) else \
                (", ".join(f"`{k}`" for k in keys) or "-")
            rows.append([f"`{f.name}`", f.unit or "-", rng, typ, f.group, toml, _spelled(f, "cli"),
                         _spelled(f, "ros"), f.doc])
    return rows


def doc_rows():
    text = (ROOT / "docs" / "fields.md").read_text()
    block = text.split("<!-- fields-table -->")[1]
    return [[c.strip() for c in line.strip().strip("|").split(" | ")]
            for line in block.splitlines() if line.startswith("| `")]


def test_docs_fields_table_is_the_registry():
    assert doc_rows() == registry_rows()


def test_every_field_has_a_spelling_and_a_doc():
    for f in fields.FIELDS.values():
        assert f.spellings and f.doc and f.group in fields.GROUPS, f.name
        for s in f.spellings:
            assert s.surface in fields.SURFACES
            assert s.unit in (None, f.unit) or (f.unit, s.unit) in fields.SCALES, (f.name, s)
        if f.lo is not None and f.hi is not None:
            assert f.lo <= f.hi
    assert re.fullmatch(r"\w+", "".join(fields.FIELDS))


def write_docs_table():
    """Rewrite the table of docs/fields.md from the registry (``python tests/inputs/test_fields.py``)."""
    path = ROOT / "docs" / "fields.md"
    head = ("| name | unit | range | type | group | TOML / spec key | CLI flag | ROS parameter | what |\n"
            "|---|---|---|---|---|---|---|---|---|\n")
    body = "".join("| " + " | ".join(r) + " |\n" for r in registry_rows())
    before, rest = path.read_text().split("<!-- fields-table -->\n")
    after = rest.split("<!-- /fields-table -->")[1]
    path.write_text(f"{before}<!-- fields-table -->\n{head}{body}<!-- /fields-table -->{after}")


if __name__ == "__main__":
    write_docs_table()


def test_a_key_is_spelled_by_one_field_per_surface():
    """``fields.view(surface, key)`` finds one field: no two fields share a spelling on one surface."""
    from collections import Counter

    counts = Counter((s.surface, s.key) for f in fields._FIELDS for s in f.spellings)
    assert [k for k, n in counts.items() if n > 1] == []
    assert len(fields._VIEWS) == sum(counts.values())


# ---------------------------------------------------------------- library argument -> flag
def library_arguments():
    """``{argument: [file:line, ...]}``: every library argument an :class:`InputError` names in ``src/``
    (``InputError(..., field="x")``, ``check_range("x", ..., argument=True)``,
    ``FIELDS["x"].check(..., argument=True)``); flags (``--x``) and non-literal names left out."""
    out: dict = {}
    for path in sorted((ROOT / "src").rglob("*.py")):
        for node in ast.walk(tree(path)):
            if not isinstance(node, ast.Call):
                continue
            kw = {k.arg: k.value for k in node.keywords}
            name = None
            if getattr(node.func, "id", None) == "InputError" and isinstance(kw.get("field"), ast.Constant):
                name = kw["field"].value
            elif isinstance(kw.get("argument"), ast.Constant) and kw["argument"].value is True:
                f = node.func
                if node.args and isinstance(node.args[0], ast.Constant):
                    name = node.args[0].value
                elif isinstance(f, ast.Attribute) and isinstance(f.value, ast.Subscript) \
                        and isinstance(f.value.slice, ast.Constant):
                    name = f.value.slice.value
            if isinstance(name, str) and not name.startswith("--"):
                out.setdefault(name, []).append(f"{path.relative_to(ROOT)}:{node.lineno}")
    return out


#: Library arguments with no flag of their own: the command checks them under its flag before the
#: library sees them (``--damping-model`` speaks rayleigh13|modal, the library rayleigh|modal;
#: ``--track`` is an argparse choice; ``--lateral-frequency`` is checked first in sim_commands).
CHECKED_FIRST_BY_THE_COMMAND = {"damping_model", "track", "lateral_frequency",
                                "method",  # the exact envelope on a deck: `sweep` refuses --method exact first
                                "irregularity"}  # `check --irregularity` on load trains: named as --irregularity


def test_every_library_argument_has_its_flag_in_the_registry():
    args = library_arguments()
    assert {"max_line_speed_kmh", "step_kmh", "trains", "damping", "scheduler", "n_modes"} <= set(args)
    unmapped = {a for a in args if fields.argument_flag(a) is None}
    assert unmapped == CHECKED_FIRST_BY_THE_COMMAND, {a: args[a] for a in unmapped}
    mapped = set(args) - unmapped | {"where"}  # envelope.parse_where names its argument through a variable
    assert {a: fields.argument_flag(a) for a in sorted(mapped)} == {
        "alpha": "--alpha", "bridge": "--bridge", "damping": "--damping", "max_line_speed_kmh": "--max-line-speed",
        "n_modes": "--modes", "scheduler": "--scheduler", "speeds_kmh": "--speeds", "step_kmh": "--speed-step",
        "track_maintenance": "--track-maintenance", "train": "--train", "trains": "--trains", "where": "--where"}
    # a field with two flags (--span, --spans) or none (a ROS parameter) names no flag
    assert fields.argument_flag("span_m") is None and fields.argument_flag("ds_m") is None
    assert fields.argument_flag(None) is None and fields.argument_flag("no_such_field") is None


@pytest.mark.parametrize("argv,line", [
    (["check", "--max-line-speed", "300", "--modes", "0.5"], "error: --modes: 0.5 - is out of range; allowed [3, 20] -"),
    (["check", "--max-line-speed", "300", "--alpha", "7"],
     "error: --alpha: 7 is not a classification factor of EN 1991-2 6.3.2(3); allowed 0.75, 0.83,"),
    (["check", "--max-line-speed", "300", "--track-maintenance", "poor"],
     "error: --track-maintenance: 'poor' is not one of EN 1991-2 6.4.5.2's; allowed careful, standard"),
    (["check", "--max-line-speed", "300", "--damping-model", "foo"],
     "error: --damping-model: 'foo' is not allowed; allowed rayleigh13, modal"),
])
def test_a_library_refusal_names_the_flag_on_the_command_line(argv, line, capsys):
    from adm_sim.cli import sim_commands

    assert sim_commands.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(line), err


# ---------------------------------------------------------------- the Δζ sign rule: one check, one text
def test_the_delta_zeta_sign_rule_has_one_text(capsys):
    """ζ + Δζ >= 0 is the registry's range [-ζ, 0.2]; where the exact envelope needs ζ + Δζ > 0 the
    refusal is the one text of :func:`adm_sim.fields.check_delta_zeta`, on the command line and in
    the library alike."""
    zeta = 0.01
    assert fields.check_delta_zeta("delta_zeta", -zeta, zeta) == -zeta  # total 0: allowed by the range
    assert fields.check_delta_zeta("delta_zeta", -0.009, zeta, positive_for="x") == -0.009
    with pytest.raises(InputError) as err:
        fields.check_delta_zeta("delta_zeta", -zeta, zeta, positive_for="the exact envelope")
    assert str(err.value) == ("delta_zeta: zeta + delta_zeta = 0 %; the exact envelope needs damping > 0 % "
                              "(allowed delta_zeta > -0.01 - (fraction))")
    with pytest.raises(InputError, match=r"^delta_zeta: -0\.0101 - \(fraction\) is out of range; allowed "
                                         r"\[-0\.01, 0\.2\] - \(fraction\)$"):
        fields.check_delta_zeta("delta_zeta", -0.0101, zeta, positive_for="the exact envelope")
    with pytest.raises(InputError) as err:  # a bridge without damping: no "-0" in the allowed range
        fields.check_delta_zeta_pct("delta_zeta_pct", 0.0, 0.0, positive_for="the exact envelope")
    assert str(err.value).endswith("(allowed delta_zeta_pct > 0 %)")
    from adm_sim.cli import sim_commands

    argv = ["sweep", "--bridge", "L=15,n0=8,mu=10000,zeta_pct=1", "--delta-zeta-pct", "-1"]
    assert sim_commands.main(argv) == 2
    assert capsys.readouterr().err.strip() == (
        "error: --delta-zeta-pct: zeta + delta_zeta = 0 %; the exact MLM envelope needs damping > 0 % "
        "(allowed --delta-zeta-pct > -1 %, or --method rk4)")
    from adm_sim.model.bridge import named_bridge
    from adm_sim.integrate.envelope import moving_load_envelope

    with pytest.raises(InputError) as err:  # refused before any kernel is compiled
        moving_load_envelope(named_bridge("B1").with_damping(0.0), [0.0], [1e5], [200.0])
    assert str(err.value) == ("delta_zeta: zeta + delta_zeta = 0 %; the exact envelope needs damping > 0 % "
                              "(allowed delta_zeta > 0 - (fraction))")  # the library's own name and unit
