"""A node killed with SIGKILL (its ``finally`` blocks never run) leaves no lock or temporary file
behind the launcher, and the recording under its final name is named whole or incomplete (and
salvageable) in the launcher's one error line (issue 38 item 5)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mcap")

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "launch_scripts"))


def _dead_pid():
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _mcap(path, n=300):
    from std_msgs.msg import Float64MultiArray

    from adm_sim.recording.mcap_log import McapRecorder

    with McapRecorder(path, chunk_size=1024, overwrite=True) as rec:
        for i in range(n):
            m = Float64MultiArray()
            m.data = [float(i)] * 8
            rec.write("/adm/progress", m, log_time_ns=1000 * i)


@pytest.mark.slow
def test_leftovers_of_a_dead_node_go_and_the_recording_is_named(tmp_path):
    from _supervisor import after_node_died

    dead, alive = _dead_pid(), os.getpid()
    for name, pid in ((".run.mcap.lock", dead), (".run.rrd.lock", dead), (".summary.json.lock", alive),
                      (".launch.lock", dead)):
        (tmp_path / name).write_text(f"{pid}\n")
    (tmp_path / f".run.tmp-{dead}.rrd").write_bytes(b"x" * 1000)
    (tmp_path / f".summary.tmp-{alive}.json").write_bytes(b"{}")
    _mcap(tmp_path / "run.mcap")
    data = (tmp_path / "run.mcap").read_bytes()
    assert after_node_died(tmp_path) == f"; {tmp_path / 'run.mcap'} is whole"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [".launch.lock", ".summary.json.lock", f".summary.tmp-{alive}.json", "run.mcap"])
    (tmp_path / "run.mcap").write_bytes(data[:len(data) // 2])  # a writer killed mid-file
    note = after_node_died(tmp_path)
    assert note.startswith(f"; {tmp_path / 'run.mcap'} is incomplete (its writer died: ")
    assert note.endswith(f"recover its intact chunks with: adm-sim salvage {tmp_path / 'run.mcap'} OUT.mcap")
    assert after_node_died(tmp_path, started_s=time.time() + 60) == ""  # an earlier run's recording: not named


@pytest.mark.slow
def test_sigkilled_calibration_node_leaves_nothing_but_a_named_recording(tmp_path):
    from adm_sim.processes.dds_env import clean_dead_shm, local_ros_env, record_shm

    out = tmp_path / "ck"
    with local_ros_env() as env:
        env = dict(env, PYTHONUNBUFFERED="1")
        p = subprocess.Popen([sys.executable, str(ROOT / "launch_scripts" / "calibrate.py"), "--bridge", "B1",
                              "--train", "ICE-2", "--out", str(out)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env)
        try:
            node = None
            t_end = time.monotonic() + 120
            while time.monotonic() < t_end:  # the node, once its recording holds a few chunks
                r = subprocess.run(["pgrep", "-P", str(p.pid), "-f", "adm_calib.nodes.calibration_node"],
                                   capture_output=True, text=True)
                pids = [int(x) for x in r.stdout.split()]
                if pids and (out / "run.mcap").exists() and (out / "run.mcap").stat().st_size > 200_000:
                    node = pids[0]
                    break
                time.sleep(0.2)
            assert node is not None, "the calibration node did not start recording"
            record_shm([node])  # its Fast DDS files, cleaned below once it is dead
            os.kill(node, 9)
            _, err = p.communicate(timeout=120)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait()
            clean_dead_shm()
    assert p.returncode == 1
    (line,) = [x for x in err.splitlines() if x.startswith("error: ")]
    assert line.startswith("error: node 'calibration' failed (exit status -9)")
    assert f"{out / 'run.mcap'} is incomplete" in line or f"{out / 'run.mcap'} is whole" in line
    left = sorted(p.name for p in out.iterdir() if p.name != "logs")
    assert left == ["run.mcap"], left
