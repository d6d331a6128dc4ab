"""Lint and type checks as part of the one test command (ruff over the tree, mypy over the core).

The rule sets live in ``pyproject.toml`` (``[tool.ruff]``, ``[tool.mypy]``); the tools are pinned in
``requirements.txt``. Outside CI, a venv without them skips these tests with the reason; in CI
(``CI`` set) a missing tool fails.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # every test here starts processes

ROOT = Path(__file__).resolve().parents[2]


def _require(module):
    if importlib.util.find_spec(module) is None:
        if os.environ.get("CI"):
            pytest.fail(f"{module} is not installed (pinned in requirements.txt)")
        pytest.skip(f"{module} is not installed in this venv (pip install -r requirements.txt)")


def _run(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", *args], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_ruff_finds_nothing():
    _require("ruff")
    res = _run("ruff", "check", "--no-cache", "--output-format", "concise", ".")
    assert res.returncode == 0, res.stdout + res.stderr


def test_ruff_configuration_is_the_projects(tmp_path):
    """The project's rule set is in force: an unused import and a loop variable left unused are found."""
    _require("ruff")
    bad = tmp_path / "bad.py"
    bad.write_text("import os\n\nfor i in range(3):\n    pass\n")
    res = _run("ruff", "check", "--no-cache", "--config", str(ROOT / "pyproject.toml"),
               "--output-format", "concise", str(bad))
    assert res.returncode == 1
    assert [line.split(" ", 2)[1] for line in res.stdout.splitlines() if line.startswith(str(bad))] \
        == ["F401", "B007"]


@pytest.fixture(scope="module")
def mypy_run():
    """One ``mypy --verbose`` over the configured files for both mypy tests (from a fresh clone, with
    no cache, the run costs ~7 s of CPU, most of it reading rerun's, numpy's and numba's types; the
    verbose log goes to stderr, the findings to stdout as without it)."""
    _require("mypy")
    return _run("mypy", "--no-error-summary", "--verbose")


def test_mypy_core_finds_nothing(mypy_run):
    assert mypy_run.returncode == 0, mypy_run.stdout + "\n".join(
        line for line in mypy_run.stderr.splitlines() if not line.startswith("LOG:"))


def test_mypy_checks_the_core_and_not_the_ros_layer(mypy_run):
    """``files``/``exclude`` select exactly ``src/adm_sim`` without the ROS nodes: the core and the
    ROS-free layers on it (recording/, processes/); nodes/ (rclpy) is not checked yet."""
    res = mypy_run
    base = ROOT / "src" / "adm_sim"
    checked = sorted({Path(p).resolve().relative_to(base).as_posix()
                      for line in (res.stdout + res.stderr).splitlines()
                      if "Found source:" in line
                      for p in [line.split("path='", 1)[-1].split("'", 1)[0]]})
    expected = sorted(p.relative_to(base).as_posix() for p in base.rglob("*.py") if p.relative_to(base).parts[0] != "nodes")
    assert checked == expected
    assert {"recording/mcap_log.py", "processes/supervisor.py", "design/check.py"} <= set(checked)
