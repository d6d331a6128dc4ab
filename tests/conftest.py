"""Fixtures shared by test modules (one instance per session, so they live in a conftest: a fixture
imported into several modules is a new fixture in each)."""

from __future__ import annotations

import fcntl
import importlib
import os
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def signal_handlers():
    """SIGINT and SIGTERM handlers as they were before each test: a command's ``main`` called in the
    test process (``run_cli``) sets its own on the way out (:class:`adm_sim.cliutil.interrupt_signals`)."""
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    for s, h in old.items():
        signal.signal(s, h)


@dataclass
class Done:
    """What a command's ``main`` called in the test process gave: exit code, stdout, stderr."""

    returncode: int
    stdout: str
    stderr: str


@pytest.fixture
def call_main(capsys):
    """``call_main(main, *args)``: a command's ``main`` in this process, as its console script calls
    it (:class:`Done`); each file keeps one test of the command's own process."""
    def call(main, *args):
        capsys.readouterr()
        code = main(list(args))
        out, err = capsys.readouterr()
        return Done(code, out, err)
    return call


@pytest.fixture
def launcher(monkeypatch, capfd):
    """``run(script, argv) -> (exit code, stdout, stderr)``, read at the file descriptors: a launch
    script's ``main(argv)`` in this process (its signal handlers are put back by
    :func:`signal_handlers`)."""
    monkeypatch.syspath_prepend(str(ROOT / "launch_scripts"))

    def run(script, argv):
        main = importlib.import_module(Path(script).stem).main
        capfd.readouterr()
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
        out, err = capfd.readouterr()
        return code, out, err

    return run


def once_per_run(tmp_path_factory, name, build):
    """``build(folder)`` once per run, not once per xdist worker: the recipe of xdist's documentation
    ("Making session-scoped fixtures execute only once"). Under ``-n`` the first worker to ask builds
    into the folder every worker of this run shares, under a file lock, and marks it done; the other
    waits on the lock and reads the same folder. Without xdist it is a plain ``mktemp``. Returns
    ``build``'s result (built anew by a worker whose sibling's build failed)."""
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        return build(tmp_path_factory.mktemp(name))
    shared = tmp_path_factory.getbasetemp().parent  # .../pytest-N: this run's, common to its workers
    folder, done = shared / name, shared / f"{name}.done"
    with open(shared / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            folder.mkdir(exist_ok=True)
            result = build(folder)
            done.write_text(str(result))
        return Path(done.read_text())


@pytest.fixture(scope="session")
def recording(tmp_path_factory):
    """``run.mcap`` of one crossing (B3, ICE-2, MLM at 300 km/h) recorded by ``launch_scripts/crossing.py``,
    once per run (:func:`once_per_run`); the tests read it and write only into their own folders."""
    return once_per_run(tmp_path_factory, "crossing", _record_crossing)


def _record_crossing(folder):
    out = folder / "run"
    r = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "crossing.py"), "--bridge", "B3", "--train",
                        "ICE-2", "--model", "mlm", "--speeds", "300", "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return out / "run.mcap"


#: The small co-simulated calibration: B3 x ICE-2 at 250..290 km/h every 2 km/h, 4 steps per period
#: of mode 3 and one fundamental period of free vibration (coarse steps: the launch, not the numbers'
#: accuracy, is under test). The range holds the resonance with room on both sides (MLM peak 262 km/h,
#: DIM 256 km/h) and the calibration runs the same 8 runs and phases as on 230..290 km/h (MLM, DIM,
#: the ladder, the root search, MLM + Δζ; status grid_too_coarse); it starts at 250 km/h, not 230:
#: the slowest speed sets the step, so 21 lanes of fewer steps (the launch 1.8 s of CPU less, the
#: numpy reference of test_ros_cosim.py 0.8 s less).
CALIBRATION_SPEEDS = "250:290:2"
#: The bridge publishes the monitoring topics every 4th step (beam and clock every 16th, automatically),
#: not every step (automatic at 4 steps per period): the recorder takes ~1/4 of the ~27,600 messages.
#: The tests using it read the per-run results, phases, run ids and summaries and that every view has
#: data from run time 0, none of which thins; a run's results are of every step whatever is published.
#: Exactness while publishing every step, DIM included: test_ros_decks.py's deck calibration launch.
CALIBRATION_PARAMS = ("bridge:\n  ros__parameters:\n    bridge: B3\n    steps_per_period: 4.0\n"
                      "    free_vibration_periods: 1.0\n    monitor_every_steps: 4\n"
                      "train:\n  ros__parameters:\n    train: ICE-2\n")


@pytest.fixture(scope="session")
def calibration_launch(tmp_path_factory):
    """The output folder (``summary.json``, ``run.mcap``, ``run.rrd``) of ``launch_scripts/calibrate.py``
    (the bridge and train nodes in one process, the calibration node in another) on the small case
    above, launched once per run (:func:`once_per_run`) on its own ROS domain: ``test_ros_cosim.py``
    checks its numbers against the in-process calibration, ``test_ros_rerun_views.py`` its recording
    as a user opens it. The tests read it and write only into their own folders."""
    return once_per_run(tmp_path_factory, "calibration", _launch_calibration)


def _launch_calibration(base):
    from adm_sim.processes.dds_env import local_ros_env

    params = base / "case.yaml"
    params.write_text(CALIBRATION_PARAMS)
    out = base / "out"
    env = local_ros_env()
    try:
        r = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "calibrate.py"), "--params-file",
                            str(params), "--speeds", CALIBRATION_SPEEDS, "--out", str(out), "--quiet",
                            "--domain-id", str(env.domain_id)],
                           env=dict(env), capture_output=True, text=True, timeout=600, cwd=ROOT)
    finally:
        env.release()
    assert r.returncode == 0, r.stderr
    assert "dz iteration" in r.stdout and "dz_VBI" in r.stdout
    return out
