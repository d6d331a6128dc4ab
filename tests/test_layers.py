"""The house's import structure, measured: every arrow points down, no module imports itself back
through others, and the README draws what exists.

Every ``import`` of ``adm_sim``/``adm_calib`` in ``src/`` and ``launch_scripts/`` (module level or inside a
function: every Import/ImportFrom node of the AST) is mapped to the layer of the importer and of the
imported module. Ranks, lowest first:

0. ``adm_sim`` core (physics, one-home modules, ``cliutil``), never rclpy;
1. ``adm_sim.recording`` (MCAP, rerun), ``adm_sim.processes`` (DDS environment, supervisor), ``adm_calib``
   (analysis);
2. ``adm_sim.commands`` / ``adm_calib.commands`` (``sim_commands.py``, ``calib_commands.py``: the two
   command lines), ``adm_sim.nodes`` / ``adm_calib.nodes`` (rclpy);
3. ``launch_scripts``.

An arrow may run to a lower rank, or inside one rank from an ``adm_calib`` layer to its ``adm_sim`` twin
(``adm-calib check`` extends ``adm-sim check``; the calibration node drives the simulation nodes).

The same scan at module granularity (every module of ``src/`` and ``launch_scripts/``, imports inside
functions included) finds no circle: the modules can be read bottom-up.
"""

from __future__ import annotations

import ast
import collections
import functools
import pathlib
import re
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

RANK = {
    "adm_sim": 0,
    "adm_sim.recording": 1, "adm_sim.processes": 1, "adm_calib": 1,
    "adm_sim.commands": 2, "adm_calib.commands": 2, "adm_sim.nodes": 2, "adm_calib.nodes": 2,
    "launch_scripts": 3,
}
COMMANDS = {"adm_sim.cli.sim_commands": "adm_sim.commands", "adm_calib.calib_commands": "adm_calib.commands"}


def module_name(path):
    rel = path.relative_to(ROOT)
    if rel.parts[0] == "launch_scripts":
        return "launch_scripts." + path.stem
    parts = list(rel.parts[1:])
    parts[-1] = parts[-1][:-3]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer(module):
    if module.startswith("launch_scripts"):
        return "launch_scripts"
    for name, lay in COMMANDS.items():
        if module == name or module.startswith(name + "."):
            return lay
    for sub in ("adm_sim.nodes", "adm_calib.nodes", "adm_sim.recording", "adm_sim.processes"):
        if module == sub or module.startswith(sub + "."):
            return sub
    return "adm_calib" if module.split(".")[0] == "adm_calib" else "adm_sim"


@functools.cache
def _imports(path):
    """Every module name an import of ``path`` names (parsed once per process: four scans read it)."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            names += (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            # ``from adm_sim import recording`` imports the subpackage: count the names too
            names.append(node.module)
            names += (f"{node.module}.{a.name}" for a in node.names)
    return tuple(names)


def measured_arrows():
    files = sorted((ROOT / "src").rglob("*.py")) + sorted((ROOT / "launch_scripts").glob("*.py"))
    arrows = collections.defaultdict(set)
    for f in files:
        src = layer(module_name(f))
        for target in _imports(f):
            if target.split(".")[0] not in ("adm_sim", "adm_calib"):
                continue
            dst = layer(target)
            if dst != src:
                arrows[src].add(dst)
    return arrows


def _twin(src, dst):
    return src.startswith("adm_calib") and dst == "adm_sim" + src[len("adm_calib"):]


def test_layers_cover_every_module():
    seen = {layer(module_name(f)) for f in (ROOT / "src").rglob("*.py")}
    assert seen == set(RANK) - {"launch_scripts"}


def test_every_arrow_points_down():
    arrows = measured_arrows()
    up = [(s, d) for s, ds in arrows.items() for d in ds
          if not (RANK[d] < RANK[s] or (RANK[d] == RANK[s] and _twin(s, d)))]
    assert not up, f"arrows that do not point down: {up}"
    # the scan sees what it should: the launch scripts reach every rank
    assert {"adm_sim", "adm_sim.nodes", "adm_calib.nodes", "adm_sim.processes"} <= arrows["launch_scripts"]


def readme_arrows():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text.split("<!-- import-arrows -->")[1]
    table = {}
    for row in re.findall(r"^\| `([^`]+)` \| (.+?) \|$", block, flags=re.M):
        table[row[0]] = set(re.findall(r"`([^`]+)`", row[1]))
    return table


def module_graph():
    """``{module: {project modules it imports}}`` over every module of ``src/`` and ``launch_scripts/``;
    an import names the longest module that exists (``from adm_sim.files import claim_output`` ->
    ``adm_sim.files``; ``from adm_sim import recording`` -> ``adm_sim.recording``)."""
    files = sorted((ROOT / "src").rglob("*.py")) + sorted((ROOT / "launch_scripts").glob("*.py"))
    modules = {module_name(f): f for f in files}

    def resolve(name):
        if name.split(".")[0] == "_supervisor":  # the launch scripts import their helper by its file name
            name = "launch_scripts." + name
        parts = name.split(".")
        for i in range(len(parts), 0, -1):
            if ".".join(parts[:i]) in modules:
                return ".".join(parts[:i])
        return None

    graph = {}
    for mod, f in modules.items():
        graph[mod] = {t for t in map(resolve, _imports(f)) if t is not None and t != mod}
    return graph


def circles(graph):
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _up(src, dst):
    s, d = layer(src), layer(dst)
    return not (s == d or RANK[d] < RANK[s] or (RANK[d] == RANK[s] and _twin(s, d)))


def test_modules_form_no_circle_and_no_arrow_runs_up():
    """Module granularity: no circle (imports inside functions close circles too), no arrow to a
    higher rank of the README's drawing."""
    graph = module_graph()
    found = circles(graph)
    arrows = [(s, d) for s, ds in graph.items() for d in ds]
    up = sorted((s, d) for s, d in arrows if _up(s, d))
    print(f"{len(graph)} modules, {len(arrows)} arrows: {len(found)} circles, {len(up)} arrows up")
    assert not found, f"module circles: {found}"
    assert not up, f"arrows to a higher rank: {up}"
    # the scan sees what it should: the bottom of the core, and the launch scripts' helper
    assert graph["adm_sim.errors"] == set()
    assert {"adm_sim.errors", "adm_sim.fields", "adm_sim.files"} <= graph["adm_sim.cliutil"]
    assert "launch_scripts._supervisor" in graph["launch_scripts.calibrate"]


def test_the_scan_finds_a_circle_closed_inside_a_function():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert circles(graph) == [["a", "b", "c"]]
    assert _up("adm_sim.fields", "adm_sim.nodes.common") and not _up("adm_sim.nodes.common", "adm_sim.fields")


def test_readme_table_is_the_measured_one():
    measured = {k: v for k, v in measured_arrows().items() if v}
    assert readme_arrows() == measured


#: the only modules that draw: the progress bar of the command line and the figure modules
DRAWING = {"adm_sim.cliutil", "adm_sim.cli.figures", "adm_calib.plots"}


def test_only_the_command_layer_draws():
    """The computations report (``progress(done, total)`` callbacks, result objects); only the
    command-line layer and the figure modules import tqdm, matplotlib or the progress bar."""
    drawers = set()
    for f in sorted((ROOT / "src").rglob("*.py")):
        for target in _imports(f):
            if target.split(".")[0] in ("tqdm", "matplotlib") or target.endswith("progress_bar"):
                drawers.add(module_name(f))
    assert drawers == DRAWING


@pytest.mark.slow
def test_nothing_below_the_nodes_loads_rclpy():
    """The one run-time check beside the static scan: every module of ``adm_sim`` and ``adm_calib``
    outside their ``nodes`` packages, imported together in a fresh interpreter, leaves ``rclpy``
    (and every ROS message package) out of ``sys.modules``."""
    import pkgutil
    import subprocess
    import sys

    import adm_calib
    import adm_sim

    names = [m.name for pkg in (adm_sim, adm_calib) for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + ".")
             if ".nodes" not in m.name]
    assert len(names) > 50
    code = ("import sys\n" + "".join(f"import {n}\n" for n in names) +
            "ros = sorted(m for m in sys.modules if m == 'rclpy' or m.startswith(('rclpy.', 'std_msgs', "
            "'geometry_msgs', 'diagnostic_msgs', 'rosgraph_msgs', 'std_srvs')))\nprint(ros)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]", out.stdout
