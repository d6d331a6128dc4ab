"""Imports inside functions stay few and each says why (issue 34, item 3): at most 40 in ``src/`` and
``launch_scripts/`` together, each with ``# noqa: PLC0415  <reason>`` on its line.

An import inside a function is kept only where a heavy library (numba, scipy's submodules, rerun,
rclpy, dask, matplotlib) must not load with the module that needs it once, or where it breaks a
cycle; the code that needs the library otherwise lives in a module that imports it at its top and is
itself imported where needed (e.g. ``launch_scripts/_monitor_live.py``,
``adm_sim.recording.live_viewer``, ``adm_sim.monitoring.decay_signal``).
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAX_DEFERRED = 40
IMPORT_IN_FUNCTION = re.compile(r"^\s+(from \S+ )?import ")
REASON = re.compile(r"PLC0415\s+\S+\s+\S+")


def deferred_imports(files):
    """``(path, line number, line)`` of every indented import line of ``files`` (as
    ``grep -rnE "^\\s+(from \\S+ )?import "`` counts them)."""
    return [(f, i, ln.strip()) for f in files
            for i, ln in enumerate(f.read_text(encoding="utf-8").splitlines(), start=1) if IMPORT_IN_FUNCTION.match(ln)]


def source_files():
    return sorted((ROOT / "src").rglob("*.py")) + sorted((ROOT / "launch_scripts").rglob("*.py"))


def test_the_count_sees_an_indented_import_and_its_reason(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("import os\n\n\ndef g():\n    import numba  # noqa: PLC0415  loads late\n"
                 "    from scipy import signal  # noqa: PLC0415\n    return os\n")
    found = deferred_imports([f])
    assert [(i, ln.split()[1]) for _, i, ln in found] == [(5, "numba"), (6, "scipy")]
    assert [bool(REASON.search(ln)) for _, _, ln in found] == [True, False]


def test_at_most_40_imports_inside_functions():
    found = deferred_imports(source_files())
    listing = "\n".join(f"{f.relative_to(ROOT)}:{i}: {ln}" for f, i, ln in found)
    assert len(found) <= MAX_DEFERRED, f"{len(found)} imports inside functions (at most {MAX_DEFERRED}):\n{listing}"


def test_every_import_inside_a_function_gives_its_reason():
    bad = [f"{f.relative_to(ROOT)}:{i}: {ln}" for f, i, ln in deferred_imports(source_files()) if not REASON.search(ln)]
    assert bad == []
