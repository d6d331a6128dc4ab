"""adm_sim.files: the one rule for inputs and outputs (claims, locks, atomic writes)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from adm_sim.errors import InputError
from adm_sim.files import claim_output, claimed, input_file, lock_path, release, release_all, write_atomic

HOLD = ("import sys, time\nfrom adm_sim.files import claim_output\nclaim_output(sys.argv[1], 'x', True)\n"
        "print('held', flush=True)\ntime.sleep(60)\n")


@pytest.fixture(autouse=True)
def _release():
    yield
    release_all()


def test_claim_is_exclusive_across_processes_and_names_the_holder(tmp_path):
    out = tmp_path / "r.json"
    p = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "held"
        assert lock_path(out).read_text().strip() == str(p.pid)
        with pytest.raises(InputError, match=rf"^--json: '{out}' is being written by process {p.pid} "):
            claim_output(str(out), "--json")
    finally:
        p.kill()
        p.wait()
    # the holder died (SIGKILL): its lock file stays, but nobody holds it, so the next writer goes on
    assert lock_path(out).exists()
    assert claim_output(str(out), "--json") == out
    assert lock_path(out).read_text().strip() == str(os.getpid())
    release(out)
    assert not lock_path(out).exists() and not claimed(out)


def test_same_output_twice_in_one_process_is_refused(tmp_path):
    claim_output(str(tmp_path / "a.json"), "--json")
    with pytest.raises(InputError, match="already being written by this process"):
        claim_output(str(tmp_path / "." / "a.json"), "--plot")


def test_output_that_is_an_input_through_a_symlink(tmp_path):
    (tmp_path / "t.toml").write_text("x")
    (tmp_path / "link.toml").symlink_to(tmp_path / "t.toml")
    with pytest.raises(InputError, match=r"is the --train file, an input of this run"):
        claim_output(str(tmp_path / "link.toml"), "--json", overwrite=True, inputs={"--train": str(tmp_path / "t.toml")})
    # a preset name that happens to equal the output's name is no input file
    assert claim_output(str(tmp_path / "B1"), "--json", inputs={"--bridge": "B1"}) == tmp_path / "B1"


def test_failed_write_keeps_the_old_file_and_leaves_nothing(tmp_path):
    out = tmp_path / "r.json"
    out.write_text("old")
    claim_output(str(out), "--json", overwrite=True)

    def write(tmp):
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(out, write)
    assert out.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]  # no temporary, no lock file
    write_atomic(out, lambda tmp: tmp.write_text("new"))
    assert out.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


def test_unwritable_folder_is_found_before_any_work(tmp_path):
    if os.geteuid() == 0:
        folder = Path("/sys")  # root ignores permissions; sysfs refuses new files even to root
    else:
        folder = tmp_path / "ro"
        folder.mkdir()
        folder.chmod(0o555)
    with pytest.raises(InputError, match=rf"^--json: '{folder}/r.json': cannot write in the directory '{folder}' "
                                         r"\((Permission denied|Read-only file system)\)$"):
        claim_output(str(folder / "r.json"), "--json")


def test_named_pipe_is_refused_without_opening_it(tmp_path):
    os.mkfifo(tmp_path / "p")
    with pytest.raises(InputError, match=r"^--train: '.*/p' is a named pipe, not a regular file; give a train file$"):
        input_file(str(tmp_path / "p"), "--train", "train file")
    with pytest.raises(InputError, match=r"is a named pipe, not a regular file; give a file name$"):
        claim_output(str(tmp_path / "p"), "--json", overwrite=True)
    with pytest.raises(InputError, match=r"^--train: '.*' is not a file$"):
        input_file(str(tmp_path), "--train", "train file")
