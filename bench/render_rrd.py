#!/usr/bin/env python3
"""Render a rerun recording as a new user sees it: rerun's web viewer in headless Chromium -> PNG.

Usage::

    .venv/bin/python bench/render_rrd.py RUN.rrd --out DIR [--tabs Runs "Speed sweep" Calibration]
        [--size 1600x1000] [--wait 90]

It starts ``rerun --serve-web`` with the recording, bound to 127.0.0.1 on free ports (analytics
off, ``CI=1``), opens the viewer in headless Chromium (software WebGL, SwiftShader) through
chromedriver (selenium), waits (at least 30 s) until four screenshots taken 5 s apart are identical (software rendering
on a loaded 2-core machine takes minutes for a calibration recording), and writes
``DIR/<recording>_<tab>.png`` for every tab of ``--tabs``. The first tab of the default blueprint
(``Runs``) is the recording as it opens; for any other tab the same default blueprint, with that
tab active and the time panel on its timeline, is sent to the viewer (as a user clicks the tab and
picks the timeline).

Needs the Debian packages ``chromium`` and ``chromium-driver`` (``apt-get install chromium
chromium-driver``) and selenium (requirements.txt). Nothing listens on other than 127.0.0.1;
chromedriver is given explicitly, so selenium's driver manager never runs.
Exit status 0, or 2 with one line ``error: ...``.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from urllib.parse import quote

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from adm_sim.errors import InputError  # noqa: E402
from adm_sim.recording import rerun_blueprint as bp  # noqa: E402
from adm_sim.recording.viewer_process import (ensure_analytics_disabled, free_port,  # noqa: E402
                                             rerun_cli, rerun_cli_env, wait_for_port)

CHROME_FLAGS = ["--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                "--no-first-run", "--no-default-browser-check", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--disable-domain-reliability",
                "--metrics-recording-only", "--hide-scrollbars", "--force-device-scale-factor=1"]


def _which(name: str, package: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise InputError(f"{name}: not found on PATH; install the Debian package '{package}' "
                         f"(apt-get install {package})")
    return path


def recording_layout(rrd: Path) -> tuple[str, float | None, float]:
    """Application id, span (m) and beam exaggeration of an adm-sim recording (for a tab blueprint)."""
    from rerun.chunk import RrdReader

    reader = RrdReader(rrd)
    recs = reader.recordings()
    if not recs:
        raise InputError(f"RUN.rrd: '{rrd}' holds no recording")
    app_id = recs[0].application_id
    span = None
    for chunk in reader.stream():
        if chunk.entity_path == "/runs/beam/axis":
            rb = chunk.to_record_batch()
            col = [n for n in rb.schema.names if n.endswith("LineStrips2D:strips")]
            if col:
                strip = rb.column(col[0]).to_pylist()[-1][0]
                span = max(p[0] for p in strip)
    exaggeration = bp.BEAM_EXAGGERATION
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            rb = chunk.to_record_batch()
            for name in rb.schema.names:
                if name.endswith("ViewBlueprint:display_name"):
                    for value in rb.column(name).to_pylist():
                        m = re.search(r"deflection ×([0-9.eE+-]+)", str(value))
                        if m:
                            exaggeration = float(m.group(1))
    return app_id, span, exaggeration


def _start_viewer(rrd: Path) -> tuple[subprocess.Popen, str, str]:
    """``rerun --serve-web`` on 127.0.0.1 with the recording; returns it, the page URL and the gRPC URL."""
    web, grpc = free_port(), free_port()
    proc = subprocess.Popen(
        [rerun_cli(), "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web), "--port", str(grpc),
         str(rrd)],
        env=rerun_cli_env(), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True)
    if not (wait_for_port(web, 30.0) and wait_for_port(grpc, 30.0)):
        _stop(proc)
        raise InputError("rerun --serve-web did not listen on 127.0.0.1 within 30 s")
    proxy = f"rerun+http://127.0.0.1:{grpc}/proxy"
    return proc, f"http://127.0.0.1:{web}/?url={quote(proxy, safe='')}", proxy


def _stop(proc: subprocess.Popen) -> None:
    """Stop the viewer's whole process group (``bin/rerun`` is a wrapper around the binary)."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(10)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    except ProcessLookupError:
        proc.wait()


def _browser(size: tuple[int, int], profile: Path):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = _which("chromium", "chromium")
    for flag in CHROME_FLAGS + [f"--window-size={size[0]},{size[1]}", f"--user-data-dir={profile}"]:
        opts.add_argument(flag)
    # chromedriver listens on the loopback only by default (--allowed-ips would open it to all interfaces)
    service = Service(executable_path=_which("chromedriver", "chromium-driver"), port=free_port())
    driver = webdriver.Chrome(service=service, options=opts)
    driver.set_window_size(*size)
    return driver


def settled_screenshot(driver, out: Path, wait_s: float, min_wait_s: float) -> float:
    """Save a PNG once the page stops changing (4 identical screenshots 5 s apart); returns the wait."""
    from selenium.common.exceptions import TimeoutException

    def shot():  # a renderer busy compiling or drawing (software GL) may not answer in time
        try:
            return driver.get_screenshot_as_png()
        except TimeoutException:
            return None

    t0 = time.monotonic()
    time.sleep(min_wait_s)
    last, same = shot(), 0
    while time.monotonic() - t0 < wait_s and same < 3:
        time.sleep(5.0)
        png = shot()
        same = same + 1 if png is not None and png == last else 0
        last = png or last
    if last is None:
        raise InputError(f"chromium: no screenshot within {wait_s:g} s")
    out.write_bytes(last)
    return time.monotonic() - t0


def parse_args(argv=None):
    class _P(argparse.ArgumentParser):
        def error(self, message):
            self.exit(2, f"error: {message}\n")

    p = _P(prog="render_rrd.py", description=__doc__.split("\n\n")[0])
    p.add_argument("rrd", metavar="RUN.rrd", type=Path)
    p.add_argument("--out", type=Path, required=True, help="directory for the PNGs")
    p.add_argument("--tabs", nargs="+", default=list(bp.TABS), help=f"tabs to render (of {', '.join(bp.TABS)})")
    p.add_argument("--size", default="1600x1000", help="window size WxH in px (default 1600x1000)")
    p.add_argument("--wait", type=float, default=600.0, help="longest wait per screenshot in s (default 600)")
    args = p.parse_args(argv)
    for tab in args.tabs:
        if tab not in bp.TABS:
            p.error(f"--tabs: {tab!r} is not a tab; allowed {', '.join(repr(t) for t in bp.TABS)}")
    m = re.fullmatch(r"(\d+)x(\d+)", args.size)
    if not m or not (320 <= int(m.group(1)) <= 4000 and 240 <= int(m.group(2)) <= 4000):
        p.error(f"--size: {args.size!r} is not WxH px with W, H in [320, 4000] x [240, 4000]")
    args.size = (int(m.group(1)), int(m.group(2)))
    if not args.wait >= 10:
        p.error(f"--wait: {args.wait:g} s is out of range; allowed >= 10 s")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        if not args.rrd.is_file():
            raise InputError(f"RUN.rrd: '{args.rrd}' does not exist")
        ensure_analytics_disabled()
        app_id, span, exaggeration = recording_layout(args.rrd)
        args.out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix="render_rrd_") as tmp:
            proc, url, proxy = _start_viewer(args.rrd)
            driver = None
            try:
                driver = _browser(args.size, Path(tmp) / "profile")
                driver.set_page_load_timeout(args.wait)
                driver.get(url)
                for i, tab in enumerate(args.tabs):
                    if i > 0 or tab != bp.TABS[0]:  # the same default blueprint, this tab active
                        bp.default_blueprint(span, exaggeration, active_tab=tab).connect_grpc(
                            app_id, url=proxy, make_active=True, make_default=False)
                    out = args.out / f"{args.rrd.stem}_{tab.lower().replace(' ', '_')}.png"
                    waited = settled_screenshot(driver, out, args.wait, 30.0 if i == 0 else 10.0)
                    print(f"{tab}: wrote {out} ({waited:.0f} s)", flush=True)
            finally:
                if driver is not None:
                    driver.quit()
                _stop(proc)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    os.environ.setdefault("SE_AVOID_STATS", "true")  # selenium manager never runs; say no anyway
    sys.exit(main())
