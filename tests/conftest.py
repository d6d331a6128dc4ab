"""Fixtures shared by test modules (one instance per session, so they live in a conftest: a fixture
imported into several modules is a new fixture in each)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def recording(tmp_path_factory):
    """``run.mcap`` of one crossing (B3, ICE-2, MLM at 300 km/h) recorded by ``launch_scripts/crossing.py``,
    once per session; the tests read it and write only into their own folders."""
    out = tmp_path_factory.mktemp("crossing") / "run"
    r = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "crossing.py"), "--bridge", "B3", "--train",
                        "ICE-2", "--model", "mlm", "--speeds", "300", "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return out / "run.mcap"
