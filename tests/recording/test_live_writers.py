"""The live recorder's outputs are whole or absent: a refused write is the run's failure.

rerun's file sink reports a refused write (a file larger than ``ulimit -f``, a full disk) only in its
own log; the driver node reads the ``.rrd`` back with rerun's reader before it gets its final name
(:func:`adm_sim.recording.rrd_check.check_rrd`), and a recording that is not whole fails the run:
exit 1, one line naming the run and the file, no output of the set under its final name, no lock
or temporary file left.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from adm_sim.errors import RunError
from adm_sim.recording.rrd_check import check_rrd
from ros_fixtures import driver_node, ros_domain  # noqa: F401  (fixture)

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable


@pytest.fixture(scope="module")
def whole_rrd(tmp_path_factory):
    """A small recording written by rerun's file sink (2000 scalars, about 64 KB)."""
    path = tmp_path_factory.mktemp("rrd") / "whole.rrd"
    code = ("import sys, rerun as rr\nrr.init('t', spawn=False)\nrr.save(sys.argv[1])\n"
            "for i in range(2000):\n    rr.set_time('s', duration=i * 0.01)\n    rr.log('a', rr.Scalars(float(i)))\n"
            "rr.disconnect()\n")
    subprocess.run([PY, "-c", code, str(path)], check=True, timeout=120, env=dict(os.environ, CI="1"))
    return path


@pytest.mark.slow
def test_check_rrd_whole(whole_rrd):
    assert check_rrd(whole_rrd) >= 1


@pytest.mark.slow
@pytest.mark.parametrize("keep", [0.5, 0.999, 0.01])
def test_check_rrd_cut(whole_rrd, tmp_path, keep):
    """A file cut at half its length (a frame runs past the end), just before its footer (every
    frame decodes, the footer is missing) or after its first frames: each is refused."""
    data = whole_rrd.read_bytes()
    cut = tmp_path / "cut.rrd"
    n = int(len(data) * keep) if keep != 0.999 else len(data) - 10
    cut.write_bytes(data[:n])
    with pytest.raises(RunError, match=r"^--rrd: rerun could not write '.*final\.rrd' whole \(.*"
                                       rf"{n} bytes written; is the disk full or a file size limit set\?\)$"):
        check_rrd(cut, tmp_path / "final.rrd", option="--rrd")


def test_check_rrd_missing(tmp_path):
    with pytest.raises(RunError, match="no file was written"):
        check_rrd(tmp_path / "none.rrd")


def _limit(kib):
    def set_limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (kib * 1024, kib * 1024))
    return set_limit


@pytest.mark.slow
def test_crossing_under_file_size_limit(tmp_path):
    """``crossing.py`` (B3 x ICE-2, MLM, 300 km/h: run.mcap ~350 KB, run.rrd ~730 KB) under
    ``ulimit -f 600`` (KiB): the MCAP is written whole, the .rrd is cut by the limit. Exit 1, one
    ``error:`` line naming run 1 and run.rrd, and no output of the run (nor a lock or a temporary
    file) in the folder: the .rrd is not left cut under its name, the MCAP and the summary of a
    run that failed are not left either."""
    from adm_sim.processes.dds_env import local_ros_env

    out = tmp_path / "run"
    env = local_ros_env()
    try:
        r = subprocess.run([PY, str(ROOT / "launch_scripts" / "crossing.py"), "--out", str(out), "--model", "mlm",
                            "--speeds", "300"], capture_output=True, text=True, timeout=300, cwd=tmp_path,
                           env=dict(env) | {"PYTHONPATH": str(ROOT / "src")}, stdin=subprocess.DEVNULL,
                           preexec_fn=_limit(600))
    finally:
        env.release()
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode == 1, r.stderr
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1, r.stderr
    assert "run 1: rrd_path: rerun could not write" in errors[0] and "run.rrd' whole" in errors[0], errors[0]
    assert "is the disk full or a file size limit set?" in errors[0]
    left = sorted(p.name for p in out.iterdir() if p.name != "logs")
    assert left == [], left  # no run.rrd cut at the limit, no run.mcap or summary.json, no .lock, no .tmp


def test_driver_recorder_failure_is_the_run_failure(ros_domain, tmp_path):
    """A write the MCAP recorder refuses inside a subscription callback (here: a file size limit)
    is not an exception escaping the executor: it fails the run in progress (``run 3: ...``),
    ends the node's job, and :meth:`RunDriver.end` reports it (exit 1 in :func:`run_node`)."""
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock

    from adm_sim import protocol as P

    with driver_node(ros_domain.domain_id, record_path=str(tmp_path / "r.mcap")) as d:
        def refused(*_a, **_k):
            raise RunError(f"recording '{tmp_path / 'r.mcap'}': cannot write (File too large); the incomplete "
                           "file was removed")

        d.rec.mcap.write = d.rec.mcap.write_serialized = refused
        d._current = (3, "mlm", "MLM run 3")
        cb = d._make_cb(P.TOPIC_CLOCK, Clock)  # the driver takes monitoring messages serialised
        cb(serialize_message(Clock()))
        cb(serialize_message(Clock()))  # the next message: still the first failure
        assert d.finished
        assert str(d.error) == (f"run 3: recording '{tmp_path / 'r.mcap'}': cannot write (File too large); the "
                                "incomplete file was removed")

        class NoSpin:
            def spin_once(self, timeout_sec=0.0):
                pass

        with pytest.raises(RunError, match=r"^run 3: recording '.*r\.mcap': cannot write \(File too large\)"):
            d.end(NoSpin())
