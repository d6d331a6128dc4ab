"""A report an office signs: the job's identification (options or a TOML job file with the bridge and
the trains), every input with its source (a user train file with its SHA-256, computed here with
hashlib), the program's version and commit, axis labels on every plot, the speed of each governing
effect, ``--tables DIR`` (every table as CSV, read back against the JSON), ``--report X.pdf`` without
a browser (one line, exit 1, nothing written) and the bad inputs of a job file (one line, exit 2,
nothing written)."""

import csv
import hashlib
import json
import re
import shutil
from pathlib import Path

import pytest

from adm_sim.cli.sim_commands import main
from adm_sim.inputs.job import JOB_FIELDS

ROOT = Path(__file__).resolve().parents[2]
MY_TRAIN = ROOT / "src" / "adm_sim" / "data" / "examples" / "my_train.toml"
IDENT = {"project": "High-speed line A-B", "structure": "Bridge km 12.4", "element": "Main span",
         "author": "A. Engineer", "checker": "B. Checker", "revision": "B", "date": "2026-12-06"}


def job_file(folder, trains='["HSLM-A7", "train.toml"]', extra="", job_extra="", drop=()):
    shutil.copy(MY_TRAIN, folder / "train.toml")
    lines = ['bridge = "B1"', f"trains = {trains}", extra, "", "[job]"]
    lines += [f'{k} = "{v}"' if k != "date" else f"{k} = {v}" for k, v in IDENT.items() if k not in drop]
    lines.append(job_extra)
    p = folder / "job.toml"
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("job")
    job = job_file(folder)
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "adm_sim.cli.sim_commands", "check", "--job", str(job),
                        "--max-line-speed", "250", "--report", str(folder / "r.html"), "--tables",
                        str(folder / "tables"), "--json", str(folder / "r.json")],
                       capture_output=True, text=True, timeout=600, cwd=folder)
    assert r.returncode == 0, r.stderr
    return folder, r


def test_identification_first_and_sources_with_sha256(run):
    folder, r = run
    page = (folder / "r.html").read_text()
    body = page.split("<h1>EN 1991-2 dynamic check</h1>", 1)[1]
    ident = re.findall(r"<tr><th>(\w+)</th><td>([^<]*)</td></tr>", body.split("</table>", 1)[0])
    assert ident == [(k, IDENT[k]) for k in JOB_FIELDS]  # the report's first lines, in order
    assert r.stdout.splitlines()[0] == "job: " + "; ".join(f"{k} {IDENT[k]}" for k in JOB_FIELDS)
    sha = hashlib.sha256((folder / "train.toml").read_bytes()).hexdigest()
    d = json.loads((folder / "r.json").read_text())
    assert d["job"] == IDENT
    src = {(x["input"], Path(x["value"]).name if x["value"].endswith(".toml") else x["value"]): x["source"]
           for x in d["inputs"]}
    assert src[("train", "train.toml")] == f"user file, SHA-256 {sha}"
    assert src[("train", "HSLM-A7")].startswith("EN 1991-2 Annex E")
    assert src[("bridge", "B1")] == "the paper's Table 3" and src[("zeta", "")] == "the paper's Table 3 (B1)"
    assert f"user file, SHA-256 {sha}" in page
    commit = re.search(r"adm-sim [^,<]+, commit ([0-9a-f]{40}|unknown)", page)
    assert commit and commit.start() < page.index("Inputs and their sources")


def test_every_plot_has_both_axis_labels(run):
    page = (run[0] / "r.html").read_text()
    svgs = re.findall(r"<svg.*?</svg>", page, re.S)
    assert len(svgs) == 2
    for svg, (x, y) in zip(svgs, (("speed (km/h)", "max deck acceleration (m/s²)"),
                                  ("section x / L (-)", "ratio train / (Φ α LM71) (-)"))):
        labels = re.findall(r">([^<>]+)</text>", svg)
        assert x in labels and y in labels


def test_tables_are_the_json_numbers(run):
    folder, _ = run
    d = json.loads((folder / "r.json").read_text())
    names = sorted(p.name for p in (folder / "tables").iterdir())
    assert names == sorted(f"{n}.csv" for n in ("job", "inputs", "verdict", "governing", "trains", "effects", "bounds",
                                                "defaults", "not_checked"))
    rows = list(csv.DictReader((folder / "tables" / "effects.csv").open(encoding="utf-8")))
    js = d["en1991_2_6_4_6_5_effects"]
    assert len(rows) == len(js) == 20
    for row, e in zip(rows, js):
        assert (row["effect"], row["train"]) == (e["label"], e["train"])
        assert float(row["ratio"]) == pytest.approx(e["ratio"], abs=5e-4)
        assert float(row["φ'_dyn"]) == pytest.approx(e["phi_dyn"], abs=5e-4)
        assert float(row["at (km/h)"].split()[0]) == pytest.approx(e["at_speed_kmh"], abs=0.05)
    job = dict(csv.reader((folder / "tables" / "job.csv").open(encoding="utf-8")))
    assert {k: job[k] for k in JOB_FIELDS} == IDENT
    defaults = list(csv.DictReader((folder / "tables" / "defaults.csv").open(encoding="utf-8")))
    assert [x["default"] for x in defaults] == [x["name"] for x in d["defaults"]]


@pytest.mark.parametrize("kind, message", [
    ("unknown_top", "unknown key 'speed'; allowed job, bridge, trains"),
    ("unknown_job", "[job] unknown key 'owner'; allowed project, structure"),
    ("missing", "[job] misses checker, date; a signed report names every one of"),
    ("report_is_input", "is the --job file, an input of this run"),
])
def test_bad_job_inputs(tmp_path, call_main, kind, message):
    job = job_file(tmp_path, extra='speed = 300' if kind == "unknown_top" else "",
                   job_extra='owner = "x"' if kind == "unknown_job" else "",
                   drop=("checker", "date") if kind == "missing" else ())
    report = job if kind == "report_is_input" else tmp_path / "r.html"
    before = sorted(p.name for p in tmp_path.iterdir())
    done = call_main(main, "check", "--job", str(job), "--max-line-speed", "250", "--report", str(report),
                     "--tables", str(tmp_path / "tables"))
    assert done.returncode == 2 and done.stdout == ""
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def test_pdf_without_a_browser_is_one_line_exit_1(tmp_path, call_main, monkeypatch):
    import adm_sim.design.check_report as cr

    monkeypatch.setattr(cr, "find_chromium", lambda: None)
    done = call_main(main, "check", "--bridge", "B1", "--max-line-speed", "250", "--trains", "HSLM-A7",
                     "--report", str(tmp_path / "r.pdf"), "--json", str(tmp_path / "r.json"))
    assert done.returncode == 1 and done.stdout == ""
    assert done.stderr.strip().splitlines() == [
        f"error: --report {tmp_path / 'r.pdf'}: no headless Chromium on this machine (chromium not on PATH); "
        f"write --report X.html and print it to PDF from a browser"]
    assert list(tmp_path.iterdir()) == []


def test_report_must_be_html_or_pdf(tmp_path, call_main):
    done = call_main(main, "check", "--bridge", "B1", "--max-line-speed", "250", "--trains", "HSLM-A7",
                     "--report", str(tmp_path / "r.txt"))
    assert done.returncode == 2 and "must end with .html or .pdf" in done.stderr
    assert list(tmp_path.iterdir()) == []


pytestmark = pytest.mark.slow  # the module fixture runs the check with its report (git, Chromium)
