"""The MCAP recorder's write failure is the run's failure: nothing under the final name, one line.

Under ``ulimit -f`` (set in the child through ``preexec_fn``) and on a small tmpfs mounted here
(root only), a child process records Float64 messages until the writer fails.
"""

import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # every test here starts processes

pytest.importorskip("mcap")
pytest.importorskip("std_msgs")

PY = sys.executable
CHILD = """
import sys
from std_msgs.msg import Float64
from adm_sim.errors import RunError
from adm_sim.recording.mcap_log import McapRecorder
try:
    with McapRecorder(sys.argv[1], chunk_size=4096, compression="") as rec:
        for i in range(200000):
            rec.write("/probe", Float64(data=float(i)), log_time_ns=i)
except RunError as exc:
    print(f"error: {exc}", file=sys.stderr)
    sys.exit(1)
"""


def _run(path, preexec=None):
    return subprocess.run([PY, "-c", CHILD, str(path)], capture_output=True, text=True, timeout=120,
                          preexec_fn=preexec)


def test_ulimit_f_removes_the_file_and_says_so(tmp_path):
    out = tmp_path / "run.mcap"

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, 64 * 1024))

    r = _run(out, limit)
    assert r.returncode == 1, r.stderr
    assert r.stderr.splitlines() == [f"error: recording '{out}': cannot write (File too large); the incomplete file was removed"]
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("mount") is None, reason="mounting a tmpfs needs root")
def test_full_tmpfs_removes_the_file_and_says_so(tmp_path):
    mnt = tmp_path / "small"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mnt)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here")
    try:
        out = mnt / "run.mcap"
        r = _run(out)
        assert r.returncode == 1, r.stderr
        assert r.stderr.splitlines() == [f"error: recording '{out}': cannot write (No space left on device); "
                                         f"the incomplete file was removed"]
        assert list(Path(mnt).iterdir()) == []
    finally:
        subprocess.run(["umount", str(mnt)], check=False)
