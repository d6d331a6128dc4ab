"""The documentation holds together: the README is a front door (at most 150 lines, the two set-up
commands within its first 40 and no timings beside them), its test command is the one ``.ci/run``
runs, every relative link (file and ``#anchor``) of the README, ``docs/``, the CHANGELOG and the
study README leads somewhere, cli.md
lists every option of every command, and python.md's examples run and print what it shows."""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
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


MAIN_JOB = ("python3.11 -m venv .venv && .venv/bin/pip install -q -r requirements.txt && "
            ".venv/bin/python launch_scripts/calibrate.py")
#: a time or a duration as the README's set-up once gave them ("14.6-19 s", "4 min 11 s", "13:26 UTC")
TIMING = re.compile(r"\d\s*(?:s|ms|min|minutes|seconds|h)\b|\d\d:\d\d|\bUTC\b")


def test_timing_pattern_finds_what_it_should():
    assert TIMING.search("14.6-19 s after the install") and TIMING.search("4 min 11 s")
    assert TIMING.search("(13:26 UTC)") and not TIMING.search("B1 x ICE-2, 160..350 km/h, 4440 cases")


def test_readme_is_a_front_door():
    """At most 150 lines; both set-up commands (the main job, the whole suite) as indented command
    lines within the first 40; no time or duration in the set-up section."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 150, f"README.md has {len(lines)} lines; at most 150"
    first = lines[:40]
    test_cmd = ".ci/install-browser && python3.11 -m venv .venv && .venv/bin/pip install -q -r requirements.txt && .venv/bin/python -m pytest -n 2"
    assert f"    {MAIN_JOB}" in first and f"    {test_cmd}" in first
    start = lines.index("## Set-up: two commands")
    end = next(i for i in range(start + 1, len(lines)) if lines[i].startswith("## "))
    timed = [line for line in lines[start:end] if TIMING.search(line)]
    assert not timed, f"timings in the README's set-up section: {timed}"


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


# ---------------------------------------------------------------- docs/cli.md: every option of every command
CLI_MD = ROOT / "docs" / "cli.md"


def cli_commands():
    """Every subcommand of ``adm-sim`` and ``adm-calib`` (read from their parsers) and every launch script."""
    from adm_calib.calib_commands import build_parser as calib_parser
    from adm_sim.cli.sim_commands import build_parser as sim_parser

    out = []
    for prog, build in (("adm-sim", sim_parser), ("adm-calib", calib_parser)):
        sub = next(a for a in build()._actions if isinstance(a, argparse._SubParsersAction))
        out += [f"{prog} {name}" for name in sub.choices]
    scripts = sorted((ROOT / "launch_scripts").glob("*.py"))
    return out + [f"launch_scripts/{p.name}" for p in scripts if not p.name.startswith("_")]


#: The ``main`` each console script calls (``adm-sim``, ``adm-calib``; a launch script's is its own).
CONSOLE_MAINS = {"adm-sim": "adm_sim.cli.sim_commands", "adm-calib": "adm_calib.calib_commands"}


@pytest.fixture
def help_text(monkeypatch, capfd, launcher):
    """``help_text(cmd)``: what ``cmd --help`` prints, by the ``main`` its console script or ``python
    launch_scripts/<name>.py`` calls, in this process (stdout read at the file descriptor), at 80
    columns: the width argparse takes when stdout is not a terminal, as in a process whose output
    is captured. The text is the same, byte for byte, as the command's own process prints (the
    help is argparse's, built by the same parser; checked for all 16 commands when the test moved
    in here), without a Python start-up per command (~0.15 s of CPU each)."""
    import importlib

    monkeypatch.setenv("COLUMNS", "80")

    def run(cmd):
        if cmd.startswith("launch_scripts/"):
            code, out, err = launcher(cmd, ["--help"])
        else:
            prog, sub = cmd.split()
            main = importlib.import_module(CONSOLE_MAINS[prog]).main
            capfd.readouterr()
            try:
                code = main([sub, "--help"])
            except SystemExit as exc:
                code = exc.code
            out, err = capfd.readouterr()
        assert code == 0, f"{cmd} --help: exit {code}\n{err}"
        return out

    return run


OPTION_LINE = re.compile(r"^  (-\S.*?)(?:\s{2,}(\S.*))?$")


def help_options(text):
    """``{option: help}`` of an argparse help text (``--help`` itself left out; an option's aliases
    each get the same text; a help that is empty stays empty)."""
    body = text.split("\noptions:\n", 1)[-1]
    opts, cur = {}, []
    for line in body.splitlines():
        m = OPTION_LINE.match(line)
        if m:
            cur = [n.split()[0] for n in m.group(1).split(", ")]
            cur = [n for n in cur if n.startswith("--") and n != "--help"]
            for n in cur:
                opts[n] = (m.group(2) or "").strip()
        elif cur and line.startswith(" " * 10) and line.strip():
            for n in cur:
                opts[n] = (opts[n] + " " + line.strip()).strip()
        else:
            cur = []
    return opts


def doc_options(text):
    """``{command: {option, ...}}`` of docs/cli.md's "Every option" section: one ``### `command```
    heading per command, the options in backticks in the first column of its table."""
    block = text.split("\n## Every option\n", 1)[1].split("\n## ", 1)[0]
    out = {}
    for part in re.split(r"^### ", block, flags=re.M)[1:]:
        head, _, body = part.partition("\n")
        cmd = head.strip().strip("`")
        rows = re.findall(r"^\| ([^|]*) \|", body, flags=re.M)
        out[cmd] = {o for r in rows for o in re.findall(r"`(--[\w-]+)`", r)}
    return out


def option_row(options, text):
    return "| " + ", ".join(f"`{o}`" for o in options) + " | " + text.replace("|", "\\|") + " |"


def test_help_parser_reads_aliases_and_continuation_lines():
    text = ("usage: x\n\noptions:\n  -h, --help            show this help message and exit\n"
            "  --overwrite, --force  replace\n  --long-option-name LONG_OPTION_NAME\n"
            "                        first part\n                        second part\n  --bare\n")
    assert help_options(text) == {"--overwrite": "replace", "--force": "replace",
                                  "--long-option-name": "first part second part", "--bare": ""}


def test_cli_md_lists_every_option_of_every_command(help_text):
    """docs/cli.md has a section per subcommand and launch script and a row for each of its options,
    and no row for an option that is gone; every option has a help text. The failure names the
    command, the option and the row to add."""
    commands = cli_commands()
    assert len(commands) >= 16
    helps = {cmd: help_text(cmd) for cmd in commands}
    documented = doc_options(CLI_MD.read_text(encoding="utf-8"))
    problems = []
    for cmd in commands:
        opts = help_options(helps[cmd])
        problems += [f"`{cmd} --help`: {o} has no help text" for o, h in opts.items() if not h]
        if cmd not in documented:
            problems.append(f"docs/cli.md: no section '### `{cmd}`' under '## Every option'")
            continue
        problems += [f"docs/cli.md, section `{cmd}`: {o} is missing; add the row  {option_row([o], h)}"
                     for o, h in opts.items() if o not in documented[cmd]]
        problems += [f"docs/cli.md, section `{cmd}`: {o} is listed but `{cmd} --help` has no such option"
                     for o in sorted(documented[cmd] - set(opts))]
    problems += [f"docs/cli.md: section `{c}` is not a command" for c in sorted(set(documented) - set(commands))]
    assert not problems, "\n".join(problems)


# ---------------------------------------------------------------- docs/python.md: the examples and the public names
PYTHON_MD = ROOT / "docs" / "python.md"
EXAMPLE = re.compile(r"```python\n(.*?)```\n+(?:```text\n(.*?)```)?", flags=re.S)
#: the library wings: each names its public API in ``__all__``
LIBRARY_WINGS = ("adm_sim", "adm_sim.model", "adm_sim.inputs", "adm_sim.integrate", "adm_sim.design", "adm_sim.monitoring",
                 "adm_calib", "adm_calib.study")


def run_examples(text):
    """``[(code, shown output, printed output)]`` of every ``python`` block of ``text``: all run in one
    fresh interpreter from the repository root, in page order, each in its own namespace."""
    blocks = EXAMPLE.findall(text)
    marker = "----- example {} -----"
    script = "".join(f"print({marker.format(i)!r})\nexec({code!r}, {{}})\n" for i, (code, _) in enumerate(blocks))
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=900, cwd=ROOT,
                          env={**os.environ, "ADM_SIM_QUIET_COMPILE": "1"})
    assert done.returncode == 0, done.stderr
    printed = re.split(r"----- example \d+ -----\n", done.stdout)[1:]
    return [(code, shown, out) for (code, shown), out in zip(blocks, printed, strict=True)]


@pytest.mark.slow
def test_python_md_examples_run_and_print_what_the_page_shows():
    """A sweep, a calibration, a check and the study's fit, as a researcher types them: each runs
    and prints exactly the output the page shows below it, and the page's B1 x ICE-2 numbers are the
    README's headline (DIM peak, Δζ_VBI; the exact envelope's MLM peak 2.2472 m/s² lies above the RK4
    samples' 2.2465 m/s² there, tests/integrate/test_envelope.py)."""
    runs = run_examples(PYTHON_MD.read_text(encoding="utf-8"))
    assert len(runs) >= 4
    for code, shown, out in runs:
        assert shown, f"docs/python.md: no ```text block with the output after\n{code}"
        assert out == shown, f"docs/python.md: the example\n{code}\nprints\n{out}\nbut the page shows\n{shown}"
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    dz = re.search(r"Δζ_VBI = (\d\.\d{3}) %", readme).group(1)
    dim = re.search(r"DIM peak (\d\.\d{4}) m/s² at\s+(\d+) km/h", readme).groups()
    printed = "".join(out for _, _, out in runs)
    assert f"ok {dz} %" in printed and f"DIM peak {dim[0]} m/s2 at {dim[1]} km/h" in printed


def public_names(text):
    """``{wing: [names]}`` of the "Public names" tables of docs/python.md."""
    block = text.split("\n## Public names\n", 1)[1].split("\n## ", 1)[0]
    out = {}
    for part in re.split(r"^### ", block, flags=re.M)[1:]:
        head, _, body = part.partition("\n")
        out[head.strip().strip("`")] = re.findall(r"^\| `(\w+)` \|", body, flags=re.M)
    return out


def test_python_md_lists_each_wings_public_names():
    """Each library wing has an ``__all__``; the page lists exactly its names, and each resolves
    (a wing imports the module of a name on first use)."""
    import importlib

    listed = public_names(PYTHON_MD.read_text(encoding="utf-8"))
    assert set(listed) == set(LIBRARY_WINGS)
    for wing in LIBRARY_WINGS:
        module = importlib.import_module(wing)
        assert sorted(listed[wing]) == sorted(module.__all__), wing
        for name in module.__all__:
            assert getattr(module, name) is not None
    # a name no wing offers is refused as Python refuses it
    with pytest.raises(AttributeError, match="has no attribute 'nothing_here'"):
        _ = importlib.import_module("adm_sim.model").nothing_here
