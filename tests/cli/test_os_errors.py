"""Every OSError line names the path (issue 38): a full device under stdout and ``ulimit -f`` in
salvage said ``error: No space left on device`` / ``File too large`` without naming where."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest

SIM = [sys.executable, "-m", "adm_sim.cli.sim_commands"]


@pytest.mark.slow
@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.parametrize("argv", [["bridges"], ["bridges", "--field"], ["trains"]])
def test_stdout_on_a_full_device_is_named(argv):
    with open("/dev/full", "w") as full:
        r = subprocess.run(SIM + argv, stdout=full, stderr=subprocess.PIPE, text=True, timeout=120)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    errors = [line for line in r.stderr.splitlines() if line.startswith("error: ")]
    assert errors == ["error: 'standard output (/dev/full)': No space left on device"], r.stderr
    assert "Exception ignored" not in r.stderr


@pytest.mark.slow
def test_salvage_beyond_ulimit_f_names_its_output(tmp_path):
    pytest.importorskip("rclpy")
    from std_msgs.msg import Float64MultiArray

    from adm_sim.recording.mcap_log import McapRecorder

    src = tmp_path / "run.mcap"
    with McapRecorder(src, chunk_size=1024) as rec:
        for i in range(600):
            m = Float64MultiArray()
            m.data = [float(i)] * 8
            rec.write("/adm/progress", m, log_time_ns=1000 * i)

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # as a shell's ulimit -f: the write fails with EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (8 * 1024, resource.RLIM_INFINITY))

    dst = tmp_path / "out.mcap"
    r = subprocess.run(SIM + ["salvage", str(src), str(dst)], capture_output=True, text=True, timeout=120,
                       preexec_fn=limit, env=dict(os.environ))
    assert r.returncode == 1 and r.stderr == f"error: '{dst}': File too large\n", r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]
