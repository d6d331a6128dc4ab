"""`adm-sim check --report F.html`: one self-contained page (no network) with the verdict per clause."""

import subprocess
import sys
from html.parser import HTMLParser

import pytest

from adm_sim.model.bridge import named_bridge
from adm_sim.design.check import resolve_trains, run_check
from adm_sim.design.check_report import report_html

CLI = [sys.executable, "-m", "adm_sim.cli.sim_commands"]


class Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.tags, self.text, self.refs = [], [], []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        self.refs += [v for k, v in attrs if k in ("src", "href")]

    def handle_data(self, data):
        self.text.append(data)


@pytest.fixture(scope="module")
def page():
    res = run_check(named_bridge("B1"), 250.0, resolve_trains("HSLM-A7,HSLM-A1"), lateral_frequency_hz=2.0)
    p = Page()
    doc = report_html(res, version="9.9.9", commit="abc123")
    p.feed(doc)
    return res, doc, p


def test_report_is_self_contained(page):
    """No script, no stylesheet link, no image or anchor that could fetch anything; two inline SVG figures."""
    _, doc, p = page
    assert not {"script", "link", "img", "iframe", "object"} & set(p.tags)
    assert p.refs == [] and "url(" not in doc and "@import" not in doc
    assert p.tags.count("svg") == 2 and p.tags.count("polyline") == 2 + 2  # one per train, M and V over the deck


def test_report_reads_back_the_verdict_and_the_numbers(page):
    """The verdict and every clause row as the text of the page says them: B1, V = 250 km/h, HSLM-A7
    3.3932 m/s2 PASS, deflection 4.180 mm (Φ3, the default) against 25 mm, end rotation 0.884 mrad
    against the infrastructure manager's 6.5 mrad, δ_H not checked (no h), lateral 2 Hz; the
    not-checked list; the defaults with their sources; version and commit."""
    res, _, p = page
    text = " ".join(" ".join(p.text).split())
    assert "Verdict: PASS" in text
    assert "EN 1990 A2.4.4.2.1 peak deck acceleration (HSLM-A7, 238.1 km/h) 3.3932 m/s² 3.5 m/s² PASS" in text
    assert "EN 1990 A2.4.4.2.3(1) vertical deflection under Φ α LM71 4.180 mm L/600 = 25.000 mm PASS" in text
    assert ("infrastructure manager's rule (project's choice; not EN 1991-2) deck end rotation under Φ α LM71 "
            "0.884 mrad 6.5 mrad PASS") in text
    assert "EN 1991-2 6.5.4.5.2 deck-end displacement δ_H = θ h h not given 8 / 10 mm not checked" in text
    assert "upper-bound ballast density 2100 kg/m3 saturated dirty ballast; no number found in the standard's " \
           "text project's choice" in text
    assert "track maintenance Phi3 and phi'' (standard maintenance, EN 1991-2 6.4.5.2(3)" in text
    assert "first lateral frequency 2 Hz >= 1.2 Hz PASS" in text
    assert "EN 1991-2 6.4.6.5(3) largest train / (Φ α LM71) ratio" in text
    for item in res.not_checked():
        assert item in text
    assert "adm-sim 9.9.9, commit abc123" in text
    assert "HSLM-A1 3.3220 267.7" in text  # within 5 % of the governing value


@pytest.mark.slow
def test_report_cli_and_refusals(tmp_path):
    out = tmp_path / "r.html"
    r = subprocess.run(CLI + ["check", "--max-line-speed", "250", "--trains", "HSLM-A7", "--report", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert out.read_text().startswith("<!DOCTYPE html>") and "Verdict: PASS" in out.read_text()
    before = out.read_text()
    r = subprocess.run(CLI + ["check", "--max-line-speed", "250", "--trains", "HSLM-A7", "--report", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and r.stderr == f"error: --report: {str(out)!r} exists; use --overwrite to replace it\n"
    assert out.read_text() == before
    bad = tmp_path / "r.txt"
    r = subprocess.run(CLI + ["check", "--max-line-speed", "250", "--trains", "HSLM-A7", "--report", str(bad)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and "must end with .html or .pdf" in r.stderr and not bad.exists()
