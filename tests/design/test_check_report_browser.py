"""The `check --report` page in a real browser: headless Chromium (Debian's `chromium` and
`chromium-driver`, installed by `.ci/install-browser` before the suite) renders it to PNG and to a
PDF, and the verdict is read back from the text the browser rendered.

No network: the page is a local file and the browser runs with networking of its own disabled
(no component updates, no metrics, no sync); the page itself fetches nothing
(tests/design/test_check_report.py checks that it holds no link, script or image).
"""

from __future__ import annotations

import base64
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

CLI = [sys.executable, "-m", "adm_sim.cli.sim_commands"]
CHROMIUM, DRIVER = shutil.which("chromium"), shutil.which("chromedriver")
pytestmark = [pytest.mark.slow, pytest.mark.skipif(CHROMIUM is None or DRIVER is None,
                                reason="no headless Chromium (.ci/install-browser installs Debian's chromium "
                                       "and chromium-driver)")]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """The B1 report at V = 250 km/h (HSLM-A7, HSLM-A1, lateral 2 Hz) as Chromium renders it:
    (page text, PNG bytes, PDF bytes, page height in CSS px)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By

    out = tmp_path_factory.mktemp("report") / "b1.html"
    r = subprocess.run(CLI + ["check", "--bridge", "B1", "--max-line-speed", "250", "--trains", "HSLM-A7,HSLM-A1",
                              "--lateral-frequency", "2", "--report", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--disable-background-networking", "--disable-component-update", "--disable-sync",
              "--no-first-run", "--metrics-recording-only", "--window-size=1200,900"):
        opts.add_argument(a)
    driver = webdriver.Chrome(service=Service(DRIVER), options=opts)
    try:
        driver.set_page_load_timeout(120)
        driver.get(out.as_uri())
        text = driver.find_element(By.TAG_NAME, "body").text
        png = driver.get_screenshot_as_png()
        pdf = base64.b64decode(driver.print_page())
        height = driver.execute_script("return document.documentElement.scrollHeight")
    finally:
        driver.quit()
    return text, png, pdf, height


def test_browser_renders_the_verdict(rendered):
    """The rendered text (what a reader sees, after layout) says the verdict and the clause rows
    with the same numbers as the text output: HSLM-A7 3.3932 m/s² PASS, deflection 4.180 mm (Φ3, the default)."""
    text = " ".join(rendered[0].split())
    assert "Verdict: PASS" in text
    assert "peak deck acceleration (HSLM-A7, 238.1 km/h) 3.3932 m/s² 3.5 m/s² PASS" in text
    assert "vertical deflection under Φ α LM71 4.180 mm L/600 = 25.000 mm PASS" in text
    assert "first lateral frequency 2 Hz >= 1.2 Hz PASS" in text
    assert "not checked" in text.lower()


def test_browser_png_and_pdf(rendered, tmp_path):
    """The screenshot is the page (a white page with dark text and figures: between 1 % and 60 % of
    its pixels are not white) and the print is a PDF of at least one page."""
    import matplotlib.image as mpimg

    _, png, pdf, height = rendered
    f = tmp_path / "page.png"
    f.write_bytes(png)
    img = mpimg.imread(f)
    assert img.shape[1] == 1200  # the window's width
    ink = np.mean(np.min(img[..., :3], axis=2) < 0.9)
    assert 0.01 < ink < 0.6, ink
    assert height > 900  # the report is longer than one screen
    assert pdf.startswith(b"%PDF-") and pdf.rstrip().endswith(b"%%EOF")
    assert len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", pdf)) >= 1


PDFTOTEXT = shutil.which("pdftotext")


@pytest.mark.skipif(PDFTOTEXT is None, reason="no pdftotext (.ci/install-browser installs Debian's poppler-utils)")
def test_report_pdf_reads_back_verdict_identification_and_an_effect_row(tmp_path):
    """`check --report X.pdf` (headless Chromium): the PDF's text, read back with pdftotext, says the
    verdict, the job's identification and the governing effect rows with their speed."""
    out = tmp_path / "b1.pdf"
    js = tmp_path / "b1.json"
    r = subprocess.run(CLI + ["check", "--bridge", "B1", "--max-line-speed", "250", "--trains", "HSLM-A7",
                              "--project", "Line A-B", "--structure", "Bridge km 12.4", "--author", "A. Engineer",
                              "--checker", "B. Checker", "--revision", "C", "--date", "2026-12-06",
                              "--report", str(out), "--json", str(js)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:5] == b"%PDF-"
    text = subprocess.run([PDFTOTEXT, "-layout", str(out), "-"], capture_output=True, text=True, timeout=60).stdout
    flat = " ".join(text.split())
    assert "Verdict: PASS" in flat
    for k, v in (("project", "Line A-B"), ("structure", "Bridge km 12.4"), ("author", "A. Engineer"),
                 ("checker", "B. Checker"), ("revision", "C"), ("date", "2026-12-06"), ("element", "not given")):
        assert re.search(rf"^\s*{k}\s+{re.escape(v)}\s*$", text, re.M), k
    import json

    e = max(json.loads(js.read_text())["en1991_2_6_4_6_5_effects"], key=lambda e: e["ratio"])
    row = f"{e['label']} {e['train']} {e['phi_dyn']:.3f} {e['at_speed_kmh']:.1f}"
    assert row in flat and f"{e['ratio']:.3f}" in flat
