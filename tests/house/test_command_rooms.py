"""The rooms stay small: no function of ``src/`` (both packages, the numba kernels included) is over 80
lines, and every import inside a function of the command lines and of ``adm_calib`` says why on its line."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from source_trees import tree

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted((ROOT / "src" / "adm_sim" / "cli").glob("*.py")) + sorted((ROOT / "src" / "adm_calib").rglob("*.py"))
ALL_SRC = sorted((ROOT / "src").rglob("*.py"))
MAX_LINES = 80


def long_functions(path, limit=MAX_LINES):
    """``(name, lines)`` of every function of ``path`` longer than ``limit`` lines (docstring included)."""
    return [(n.name, n.end_lineno - n.lineno + 1) for n in ast.walk(tree(path))
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.end_lineno - n.lineno + 1 > limit]


def test_the_scan_sees_the_files_and_measures_lines(tmp_path):
    assert {"sweep.py", "check.py", "calibrate.py", "damping_root.py", "study_fit.py"} <= {f.name for f in FILES}
    assert {"kernels.py", "envelope.py", "bridge_node.py"} <= {f.name for f in ALL_SRC}
    f = tmp_path / "f.py"
    f.write_text("def short():\n    return 1\n\n\ndef long():\n" + "    x = 1\n" * 80 + "    return x\n")
    assert long_functions(f) == [("long", 82)]


@pytest.mark.parametrize("path", ALL_SRC, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_function_over_80_lines(path):
    assert long_functions(path) == []


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_an_import_inside_a_function_gives_its_reason(path):
    """``# noqa: PLC0415  <reason>``: the rule's code and a reason of at least two words after it."""
    lines = path.read_text(encoding="utf-8").splitlines()
    bad = [f"{i}: {ln.strip()}" for i, ln in enumerate(lines, start=1)
           if re.match(r"^\s+(from \S+ )?import ", ln) and not re.search(r"PLC0415\s+\S+\s+\S+", ln)]
    assert bad == []
