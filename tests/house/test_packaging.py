"""Packaging: one version number, and every third-party import of the code declared and pinned.

* The version is written once, ``adm_sim.__version__``; ``pyproject.toml`` reads it, ``adm_calib``
  re-exports it, the ROS packages' ``package.xml`` carry its release part (format 3 admits only
  X.Y.Z) and their ``setup.py`` read it from there.
* ``pip install .`` must give commands that import: every module that ``src/`` and
  ``launch_scripts/`` import from outside the standard library is a declared run-time dependency
  (``[project] dependencies``, or an extra where the feature is optional), and every declared
  distribution is pinned in ``requirements.txt`` (what CI installs).
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from source_trees import tree

import adm_calib
import adm_sim

ROOT = Path(__file__).resolve().parents[2]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())

#: top-level import name -> distribution on PyPI (common_interfaces holds every message package used)
DISTRIBUTION_OF = {
    "numpy": "numpy", "scipy": "scipy", "numba": "numba", "tqdm": "tqdm", "matplotlib": "matplotlib",
    "rclpy": "ros-jazzy-rclpy", "mcap": "mcap", "mcap_ros2": "mcap-ros2-support", "rosbags": "rosbags",
    "rerun": "rerun-sdk", "yaml": "pyyaml", "dask": "dask", "distributed": "dask",
    **{m: "ros-jazzy-common-interfaces" for m in (
        "std_msgs", "sensor_msgs", "geometry_msgs", "diagnostic_msgs", "std_srvs", "rosgraph_msgs",
        "builtin_interfaces", "rcl_interfaces")},
}
#: optional features: the import is allowed to come from this extra only
EXTRA_OF = {"dask": "study", "distributed": "study"}
#: the project's own imports: its packages and the launch scripts' shared modules (``_supervisor``, ``_republish``)
FIRST_PARTY = {"adm_sim", "adm_calib"} | {p.stem for p in (ROOT / "launch_scripts").glob("_*.py")}


def _name(requirement):
    """Normalised distribution name of a requirement string (PEP 503)."""
    return re.sub(r"[-_.]+", "-", re.match(r"[A-Za-z0-9_.-]+", requirement).group(0)).lower()


def _third_party_imports(paths, root=ROOT):
    """First file importing each top-level module that is neither standard library nor ours."""
    found = {}
    for path in paths:
        for node in ast.walk(tree(path)):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in FIRST_PARTY and top != "__future__":
                    found.setdefault(top, str(path.relative_to(root)))
    return found


def test_one_version_number():
    version = adm_sim.__version__
    release = re.fullmatch(r"(\d+\.\d+\.\d+)(?:(?:a|b|rc|\.dev|\.post)\d+)?", version)
    assert release, f"adm_sim.__version__ {version!r} is not a PEP 440 X.Y.Z[suffix] version"
    assert adm_calib.__version__ == version
    assert "version" not in PYPROJECT["project"] and "version" in PYPROJECT["project"]["dynamic"]
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "adm_sim.__version__"}
    for pkg in ("adm_sim", "adm_calib"):
        xml_version = ET.parse(ROOT / "ros_ws" / pkg / "package.xml").findtext("version")
        assert xml_version == release.group(1), pkg
        setup_py = (ROOT / "ros_ws" / pkg / "setup.py").read_text()
        assert re.search(r"""version\s*=\s*["']""", setup_py) is None, f"{pkg}/setup.py states a version literal"


@pytest.mark.slow
def test_ros_setup_py_reports_the_package_xml_version():
    """What colcon installs: ``setup.py --version`` of each ROS package gives the release part."""
    release = re.match(r"\d+\.\d+\.\d+", adm_sim.__version__).group(0)
    for pkg in ("adm_sim", "adm_calib"):
        res = subprocess.run([sys.executable, "setup.py", "--version"], cwd=ROOT / "ros_ws" / pkg,
                             capture_output=True, text=True, timeout=60)
        assert res.returncode == 0, res.stderr
        assert res.stdout.split()[-1] == release, pkg


def test_every_third_party_import_is_declared_and_pinned():
    sources = sorted((ROOT / "src").rglob("*.py")) + sorted((ROOT / "launch_scripts").glob("*.py"))
    imports = _third_party_imports(sources)
    unknown = {m: where for m, where in imports.items() if m not in DISTRIBUTION_OF}
    assert not unknown, f"imports with no declared distribution (add to pyproject.toml and this map): {unknown}"
    core = {_name(r) for r in PYPROJECT["project"]["dependencies"]}
    extras = {k: {_name(r) for r in v} for k, v in PYPROJECT["project"]["optional-dependencies"].items()}
    for module, where in imports.items():
        dist = DISTRIBUTION_OF[module]
        declared_in = extras[EXTRA_OF[module]] if module in EXTRA_OF else core
        assert dist in declared_in, f"{module} (imported by {where}) needs {dist} in pyproject.toml"
    pinned = {_name(line): line for line in (ROOT / "requirements.txt").read_text().splitlines()
              if line and not line.startswith(("#", "-"))}
    declared = core | set().union(*extras.values()) - {"adm-sim"}
    for dist in sorted(declared):
        assert dist in pinned and "==" in pinned[dist], f"{dist} is declared but not pinned in requirements.txt"


def test_the_import_scan_sees_a_missing_declaration(tmp_path):
    """The scan is not vacuous: third-party imports are found with their file, ours and stdlib's are not."""
    bad = tmp_path / "mod.py"
    bad.write_text("import numpy\nfrom pandas.io import json\nimport os.path\nfrom . import x\n"
                   "from adm_sim.errors import InputError\n")
    found = _third_party_imports([bad], root=tmp_path)
    assert found == {"numpy": "mod.py", "pandas": "mod.py"}
    assert "pandas" not in DISTRIBUTION_OF


@pytest.mark.slow
def test_study_without_dask_says_which_extra(monkeypatch, tmp_path):
    """``adm-calib study`` on a plain install (no [study] extra): one line naming the extra, nothing written."""
    from adm_calib.study import StudySettings, run_study
    from adm_sim.errors import RunError

    monkeypatch.setitem(sys.modules, "distributed", None)  # importlib.util.find_spec then returns None
    with pytest.raises(RunError, match=r"^study: dask\.distributed is not installed; install it with "
                                       r"pip install 'adm-sim\[study\]'$"):
        run_study(tmp_path / "study", [], settings=StudySettings())
    assert list(tmp_path.iterdir()) == []
