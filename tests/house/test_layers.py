"""The house's import structure, measured: the wings are the folders, every arrow between wings points
down, no module imports itself back through others, and the README and docs/architecture.md draw what
exists.

A module's *wing* is its folder: ``adm_sim/<folder>/`` (``model``, ``integrate``, ...), the one-home
modules at the root of ``adm_sim`` (``errors``, ``fields``, ``files``, ``limits``, ``protocol``,
``interrupts``, ``cliutil``), ``adm_calib`` with its ``study/`` (the analysis and the ``adm-calib``
command), the nodes of both packages, and ``launch_scripts/``. Every ``import`` of ``adm_sim`` /
``adm_calib`` in ``src/`` and ``launch_scripts/`` (module level or inside a function: every
Import/ImportFrom node of the AST) is mapped to the wing of the importer and of the imported module.
Ranks, lowest first, as the imports order them (:data:`RANK`); an arrow between two wings runs to a
strictly lower rank, inside a wing anywhere. A folder that is not in :data:`RANK` fails the scan.

The same scan at module granularity (imports inside functions included) finds no circle: the
modules can be read bottom-up.
"""

from __future__ import annotations

import ast
import collections
import pathlib
import re
import shutil

import pytest

from source_trees import tree, tree_of_text

ROOT = pathlib.Path(__file__).resolve().parents[2]

#: the wings and their ranks, lowest first (the README's drawing and docs/architecture.md say the same)
RANK = {
    "adm_sim": 0,
    "adm_sim.model": 1, "adm_sim.recording": 1, "adm_sim.processes": 1,
    "adm_sim.integrate": 2, "adm_sim.inputs": 2, "adm_sim.monitoring": 2,
    "adm_sim.design": 3,
    "adm_sim.cli": 4,
    "adm_calib": 5,
    "nodes": 6,
    "launch_scripts": 7,
}
#: what each wing holds, one line each (drawn in the README and docs/architecture.md)
WING_DIR = {"adm_sim": "src/adm_sim/*.py", "nodes": "src/adm_sim/nodes/, src/adm_calib/nodes/",
            "adm_calib": "src/adm_calib/", "launch_scripts": "launch_scripts/"}


def module_name(path, root=ROOT):
    rel = path.relative_to(root)
    if rel.parts[0] == "launch_scripts":
        return "launch_scripts." + path.stem
    parts = list(rel.parts[1:])
    parts[-1] = parts[-1][:-3]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer(module):
    """The wing of a module name: its folder (``adm_sim.model.bridge`` -> ``adm_sim.model``)."""
    parts = module.split(".")
    if parts[0] in ("launch_scripts", "_supervisor"):
        return "launch_scripts"
    if len(parts) > 1 and parts[1] == "nodes":
        return "nodes"
    if parts[0] == "adm_calib":
        return "adm_calib"
    if len(parts) > 1 and (ROOT / "src" / "adm_sim" / parts[1] / "__init__.py").exists():
        return "adm_sim." + parts[1]
    return "adm_sim"


def source_files(root=ROOT):
    return sorted((root / "src").rglob("*.py")) + sorted((root / "launch_scripts").glob("*.py"))


#: ``{source text: the module names its imports name}``: a text is parsed once per process, also when
#: a copy of the tree holds it under another path (the planted-import scan reads every file anew
#: and parses only the one it changed).
_NAMES_OF_TEXT = {}


def _parsed(path, text):
    if text not in _NAMES_OF_TEXT:  # a text that does not parse raises here, naming this path
        names = []
        for node in ast.walk(tree_of_text(text, str(path))):
            if isinstance(node, ast.Import):
                names += (a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                # ``from adm_sim import recording`` imports the subpackage: count the names too
                names.append(node.module)
                names += (f"{node.module}.{a.name}" for a in node.names)
        _NAMES_OF_TEXT[text] = tuple(names)
    return _NAMES_OF_TEXT[text]


def _imports(path):
    """Every module name an import of ``path`` names (read each time; parsed once per text: several
    scans read it)."""
    return _parsed(path, path.read_text(encoding="utf-8"))


def measured_arrows(root=ROOT):
    """``{wing: {wings it imports}}`` (arrows inside a wing left out)."""
    arrows = collections.defaultdict(set)
    for f in source_files(root):
        src = layer(module_name(f, root))
        for target in _imports(f):
            if target.split(".")[0] not in ("adm_sim", "adm_calib"):
                continue
            dst = layer(target)
            if dst != src:
                arrows[src].add(dst)
    return arrows


def upward(arrows):
    """The arrows between wings that do not run to a strictly lower rank."""
    return sorted((s, d) for s, ds in arrows.items() for d in ds if not RANK[d] < RANK[s])


def test_layers_cover_every_module():
    """Every folder of the packages is a wing with a rank: a new folder must be placed."""
    seen = {layer(module_name(f)) for f in source_files()}
    assert seen <= set(RANK), f"folders without a rank in RANK: {sorted(seen - set(RANK))}"
    missing = set(RANK) - seen - {"adm_sim.inputs"}  # inputs/: the readers' home, placed before it fills
    assert not missing, f"ranks of folders that do not exist: {sorted(missing)}"


def test_every_arrow_points_down():
    arrows = measured_arrows()
    assert not upward(arrows), f"arrows that do not point down: {upward(arrows)}"
    # the scan sees what it should: the launch scripts reach across the ranks
    assert {"adm_sim", "nodes", "adm_calib", "adm_sim.processes", "adm_sim.recording"} <= arrows["launch_scripts"]
    assert "adm_sim.cli" in arrows["adm_calib"]  # ``adm-calib check`` extends ``adm-sim check``


def test_the_scan_catches_a_planted_upward_import(tmp_path):
    """A copy of the tree with one import inside a function of the model that reaches the command
    line: the wing scan and the module scan both report exactly that arrow."""
    for f in source_files():
        dest = tmp_path / f.relative_to(ROOT)
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(f, dest)
    assert not upward(measured_arrows(tmp_path))
    planted = tmp_path / "src" / "adm_sim" / "model" / "bridge.py"
    planted.write_text(planted.read_text(encoding="utf-8") +
                       "\n\ndef _planted():\n    from adm_sim.cli import sim_commands  # noqa\n", encoding="utf-8")
    assert upward(measured_arrows(tmp_path)) == [("adm_sim.model", "adm_sim.cli")]
    graph = module_graph(tmp_path)
    assert sorted((s, d) for s, ds in graph.items() for d in ds if _up(s, d)) == \
        [("adm_sim.model.bridge", "adm_sim.cli"), ("adm_sim.model.bridge", "adm_sim.cli.sim_commands")]


def module_graph(root=ROOT):
    """``{module: {project modules it imports}}`` over every module of ``src/`` and ``launch_scripts/``;
    an import names the longest module that exists (``from adm_sim.files import claim_output`` ->
    ``adm_sim.files``; ``from adm_sim import recording`` -> ``adm_sim.recording``)."""
    modules = {module_name(f, root): f for f in source_files(root)}

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
    return s != d and not RANK[d] < RANK[s]


def test_modules_form_no_circle_and_no_arrow_runs_up():
    """Module granularity: no circle (imports inside functions close circles too), no arrow to a
    wing of the same or a higher rank."""
    graph = module_graph()
    found = circles(graph)
    arrows = [(s, d) for s, ds in graph.items() for d in ds]
    up = sorted((s, d) for s, d in arrows if _up(s, d))
    print(f"{len(graph)} modules, {len(arrows)} arrows: {len(found)} circles, {len(up)} arrows up")
    assert not found, f"module circles: {found}"
    assert not up, f"arrows to a wing of the same or a higher rank: {up}"
    # the scan sees what it should: the bottom of the core, and the launch scripts' helper
    assert graph["adm_sim.errors"] == set()
    assert {"adm_sim.errors", "adm_sim.fields", "adm_sim.files"} <= graph["adm_sim.cliutil"]
    assert "launch_scripts._supervisor" in graph["launch_scripts.calibrate"]


def test_the_model_knows_no_input_rules():
    """Issue 34, "inputs out of the physics": no module of the model wing imports the field registry
    (adm_sim.fields) or a reader (adm_sim.inputs); the model checks its invariants only (finite,
    positive, counts: adm_sim.errors.ModelError), the readers apply the registry's ranges."""
    graph = module_graph()
    model = [m for m in graph if layer(m) == "adm_sim.model"]
    assert "adm_sim.model.bridge" in model and "adm_sim.model.spans" in model
    bad = sorted((m, d) for m in model for d in graph[m] if d == "adm_sim.fields" or d.startswith("adm_sim.inputs"))
    assert bad == []


def test_the_scan_finds_a_circle_closed_inside_a_function():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert circles(graph) == [["a", "b", "c"]]
    assert _up("adm_sim.fields", "adm_sim.nodes.common") and not _up("adm_sim.nodes.common", "adm_sim.fields")
    # two wings of one rank may not import each other
    assert _up("adm_sim.model.bridge", "adm_sim.recording.mcap_log")


# ---------------------------------------------------------------- the drawings: README, docs/architecture.md
ARCH = ROOT / "docs" / "architecture.md"
RANK_LINE = re.compile(r"^\s*rank (\d+)\s+(.+?)(?:\s+#.*)?$")


def drawn_ranks(text):
    """``{wing: rank}`` from the lines ``rank N  wing wing ...  # what`` between ``<!-- import-ranks -->``
    markers."""
    block = text.split("<!-- import-ranks -->")[1].split("<!-- /import-ranks -->")[0]
    ranks = {}
    for m in filter(None, map(RANK_LINE.match, block.splitlines())):
        for wing in m.group(2).split():
            ranks[wing] = int(m.group(1))
    return ranks


def test_readme_and_architecture_draw_the_ranks():
    for page in (ROOT / "README.md", ARCH):
        assert drawn_ranks(page.read_text(encoding="utf-8")) == RANK, page.name


def drawn_arrows():
    block = ARCH.read_text(encoding="utf-8").split("<!-- import-arrows -->")[1].split("<!-- /import-arrows -->")[0]
    table = {}
    for row in re.findall(r"^\| `([^`]+)` \| (.+?) \|$", block, flags=re.M):
        table[row[0]] = set(re.findall(r"`([^`]+)`", row[1]))
    return table


def arrows_markdown():
    measured = measured_arrows()
    rows = [f"| `{s}` | " + ", ".join(f"`{d}`" for d in sorted(measured[s], key=lambda d: (-RANK[d], d))) + " |"
            for s in sorted(measured, key=lambda s: (-RANK[s], s)) if measured[s]]
    return "\n".join(["| from | imports |", "|---|---|", *rows])


def test_architecture_table_is_the_measured_one():
    measured = {k: v for k, v in measured_arrows().items() if v}
    assert drawn_arrows() == measured, "rewrite it with: .venv/bin/python tests/house/test_layers.py\n" + arrows_markdown()


def module_row(path):
    """The row of docs/architecture.md's module table for ``path``: the first sentence of its docstring."""
    doc = (ast.get_docstring(tree(path)) or "").split("\n\n")[0].replace("\n", " ")
    first = re.split(r"(?<=[a-z)`]\.)\s", doc)[0].rstrip(".").replace("``", "`")
    wing = layer(module_name(path))
    return f"| `{path.relative_to(ROOT)}` | {wing} ({RANK.get(wing, '?')}) | {first} |"


MODULE_ROW = re.compile(r"^\| `((?:src/|launch_scripts/)[\w/]+\.py)` \|", flags=re.M)


def test_architecture_lists_every_module():
    """docs/architecture.md's "Every module" table has one row per module of ``src/`` and
    ``launch_scripts/`` (``__init__.py`` aside), and no row for a file that is gone."""
    listed = set(MODULE_ROW.findall(ARCH.read_text(encoding="utf-8")))
    files = {str(f.relative_to(ROOT)) for f in source_files() if f.name != "__init__.py"}
    assert not files - listed, "modules missing from docs/architecture.md's \"Every module\"; add the rows\n" + \
        "\n".join(module_row(ROOT / f) for f in sorted(files - listed))
    assert not listed - files, f"docs/architecture.md lists modules that do not exist: {sorted(listed - files)}"


#: the only modules that draw: the progress bar of the command line and the figure modules
DRAWING = {"adm_sim.cliutil", "adm_sim.cli.figures"}  # adm_calib.plots draws through cli.figures.pyplot


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


if __name__ == "__main__":
    print(arrows_markdown())
