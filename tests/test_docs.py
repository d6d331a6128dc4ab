"""The documentation holds together: the README orients in at most 250 lines, its test command is
the one ``.ci/run`` runs, and every relative link (file and ``#anchor``) of the README, ``docs/``,
the CHANGELOG and the study README leads somewhere."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", ROOT / "CHANGELOG.md", ROOT / "results" / "study" / "README.md",
        *sorted((ROOT / "docs").glob("*.md"))]
#: written on another branch of the same issue; a link to it is accepted until it lands

LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def slug(heading):
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(path):
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    return {slug(m.group(1)) for m in re.finditer(r"^#{1,6} (.+)$", text, flags=re.M)}


def test_slug_matches_github():
    assert slug("## Headline result: Table 4".lstrip("# ")) == "headline-result-table-4"
    assert slug("Calibration and reference methods (`src/adm_calib`, numpy/scipy only)") == \
        "calibration-and-reference-methods-srcadm_calib-numpyscipy-only"
    assert slug("The node graph (`bench/bench_ros.py`)") == "the-node-graph-benchbench_rospy"


def test_docs_are_one_tree():
    """Every page of docs/ is linked from docs/index.md, and the README links the index: a page
    added without a way to it fails here."""
    index = (ROOT / "docs" / "index.md").read_text()
    linked = {m.group(1) for m in re.finditer(r"\]\(([\w.-]+\.md)(?:#[\w-]*)?\)", index)}
    pages = {p.name for p in (ROOT / "docs").glob("*.md")} - {"index.md"}
    assert pages - linked == set(), f"pages not in docs/index.md: {sorted(pages - linked)}"
    assert "](docs/index.md)" in (ROOT / "README.md").read_text()


def test_readme_test_command_is_what_ci_runs():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    test_cmd = ".ci/install-browser && python3.11 -m venv .venv && .venv/bin/pip install -q -r requirements.txt && .venv/bin/python -m pytest -n 2"
    assert f"\n    {test_cmd}\n" in readme
    assert [line for line in ci.splitlines() if line.startswith(".ci/install-browser")] == [test_cmd]


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(doc):
    assert doc.exists()
    bad = []
    for target in LINK.findall(doc.read_text()):
        if re.match(r"[a-z]+://", target) or target.startswith("mailto:"):
            continue
        file_part, _, anchor = target.partition("#")
        dest = (doc.parent / file_part).resolve() if file_part else doc
        if not dest.exists():
            bad.append(f"{target}: no such file")
            continue
        if anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{target}: no heading with that anchor in {dest.relative_to(ROOT)}")
    assert not bad, bad
