"""adm_sim.files: the one rule for inputs and outputs (claims, locks, atomic writes)."""

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from adm_sim.errors import InputError, RunError
from adm_sim.files import (OutputSet, check_output_folder, claim_folder, claim_output, claimed, input_file, lock_path,
                           make_output_folder, release, release_all, write_atomic)

HOLD = ("import sys, time\nfrom adm_sim.files import claim_output\nclaim_output(sys.argv[1], 'x', True)\n"
        "print('held', flush=True)\ntime.sleep(60)\n")


@pytest.fixture(autouse=True)
def _release():
    yield
    release_all()


@pytest.mark.slow
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


def _strays(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_claim_whose_pid_cannot_be_written_leaves_no_lock(tmp_path, monkeypatch):
    """A full disk refuses the pid (``ulimit -f 0``, ENOSPC): the claim holds (the flock is the claim)
    and its release removes the lock file (it was recorded before the pid was written)."""
    def full(fd, data, offset):
        raise OSError(errno.EFBIG, "File too large")

    monkeypatch.setattr(os, "pwrite", full)
    out = tmp_path / "r.json"
    claim_output(str(out), "--json")
    assert claimed(out) and _strays(tmp_path) == [".r.json.lock"] and lock_path(out).read_text() == ""
    release_all()
    assert _strays(tmp_path) == []


@pytest.mark.parametrize("failure", [OSError(errno.ENOSPC, "No space left on device"),
                                     RuntimeError("Failed to encode LogMsg: Failed to write: No space left on "
                                                  "device (os error 28)")])
def test_write_refused_by_the_system_is_one_run_error_naming_the_output(tmp_path, failure):
    """An OSError (or a Rust writer's "(os error N)") during the write: RunError naming the output
    the user gave, not the temporary file; nothing left beside it."""
    out = tmp_path / "r.json"
    claim_output(str(out), "--json")

    def write(tmp):
        tmp.write_text("half")
        raise failure

    with pytest.raises(RunError, match=rf"^--json: '{out}': cannot write \(No space left on device\)$"):
        write_atomic(out, write, "--json")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_folder_without_room_is_a_failed_run_before_any_work(tmp_path):
    """The probe writes one byte: with ``ulimit -f 0`` (as on a full disk) the output is refused
    before the work, as a failed run (RunError, exit 1), not as bad input."""
    code = ("import resource, signal, sys\nfrom adm_sim.errors import RunError\n"
            "from adm_sim.files import claim_output\nsignal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
            "resource.setrlimit(resource.RLIMIT_FSIZE, (0, resource.RLIM_INFINITY))\n"
            "try:\n    claim_output(sys.argv[1], '--json')\nexcept RunError as exc:\n    print(exc)\n")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / "r.json")], capture_output=True, text=True,
                       timeout=60)
    assert r.stdout.strip() == f"--json: '{tmp_path}/r.json': cannot write in the directory '{tmp_path}' " \
                               f"(File too large)", r.stderr
    assert list(tmp_path.iterdir()) == []


def test_output_folder_rule(tmp_path):
    """One rule for a folder a run writes into: checked before the work, created after, removed
    again while empty at the end; claimed as a whole for a launch."""
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match=r"^--out: '' is empty; give a directory$"):
        check_output_folder(" ", "--out")
    with pytest.raises(InputError, match=rf"^--out: '{tmp_path}/f' is not a directory$"):
        check_output_folder(str(tmp_path / "f"), "--out")
    (tmp_path / "f").rename(tmp_path / "run.mcap")
    with pytest.raises(InputError, match=rf"^--out: '{tmp_path}/run.mcap' is the --params-file file, an input"):
        check_output_folder(str(tmp_path), "--out", ["run.mcap"], {"--params-file": tmp_path / "run.mcap"})
    out = check_output_folder(str(tmp_path / "a" / "b"), "--out", ["run.mcap"])
    assert not out.exists() and make_output_folder(out, "--out")
    assert claim_folder(out, "--out", ["run.mcap"]) == [] and (out / ".launch.lock").exists()
    release(out)
    release_all()  # the folders created above are empty: removed
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]
    old = tmp_path / "old"
    old.mkdir()
    (old / "run.mcap").write_text("x")
    with pytest.raises(InputError, match=r"holds an earlier run \(run.mcap\); choose another folder or pass --overwrite"):
        claim_folder(old, "--out", ["run.mcap"])
    assert claim_folder(old, "--out", ["run.mcap"], overwrite=True) == ["run.mcap"]
    release_all()
    assert sorted(p.name for p in old.iterdir()) == ["run.mcap"]


# ---------------------------------------------------------------- output sets: all or nothing
def test_output_set_interrupted_leaves_none_and_keeps_earlier_files(tmp_path, capsys):
    a, b = tmp_path / "a.json", tmp_path / "b.png"
    b.write_text("earlier")
    for p in (a, b):
        claim_output(p, "--x", overwrite=True)

    def interrupted(p):
        p.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        with OutputSet() as outs:
            outs.write(a, lambda p: p.write_text("{}"), "--json", note="wrote a")
            outs.write(b, interrupted, "--plot", note="wrote b")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["b.png"]  # no a.json, no tmp, no lock
    assert b.read_text() == "earlier"
    assert not claimed(a) and not claimed(b)
    assert capsys.readouterr().out == ""


def test_output_set_renames_every_output_at_the_end_then_prints(tmp_path, capsys):
    a, b = tmp_path / "a.json", tmp_path / "b.txt"
    with OutputSet() as outs:
        outs.write(a, lambda p: p.write_text("1"), "--json", note="wrote a")
        outs.write(b, lambda p: p.write_text("2"), "--csv", note="wrote b")
        assert not a.exists() and not b.exists()  # nothing under a final name before the end
        assert capsys.readouterr().out == ""
    assert (a.read_text(), b.read_text()) == ("1", "2")
    assert outs.written == [a, b]
    assert capsys.readouterr().out == "wrote a\nwrote b\n"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.json", "b.txt"]


def test_output_set_write_refused_by_the_system_is_one_run_error(tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.txt"

    def full(p):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(p))

    with pytest.raises(RunError, match=r"--csv: '.*b\.txt': cannot write \(No space left on device\)"):
        with OutputSet() as outs:
            outs.write(a, lambda p: p.write_text("1"), "--json")
            outs.write(b, full, "--csv")
    assert list(tmp_path.iterdir()) == []


def test_calibrate_json_and_plot_interrupted_while_plotting_leave_neither(tmp_path, monkeypatch, capsys):
    """adm-calib calibrate --json --plot: an interrupt in the plot leaves no JSON either (exit 130)."""
    from adm_calib import plots
    from adm_calib.calib_commands import main

    def interrupted(res, p):
        p.write_bytes(b"\x89PNG half")
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, "plot_calibration", interrupted)
    argv = ["calibrate", "--bridge", "B1", "--train", "ICE-2", "--speeds", "160:350:5",
            "--json", str(tmp_path / "c.json"), "--plot", str(tmp_path / "c.png")]
    assert main(argv) == 130
    assert capsys.readouterr().err.strip() == "error: interrupted"
    assert list(tmp_path.iterdir()) == []


def test_study_fit_interrupted_at_a_figure_leaves_no_file_in_the_way(tmp_path, monkeypatch, capsys):
    """study-fit interrupted at its last figures: no file of the fit (the re-run is not blocked) and
    the folder it created is gone; the re-run then writes every file. The figures are empty files
    and the conservative bound is left out (tests/calib/test_calib_study.py draws and checks them): what
    is under test is the set of files, not their content."""
    import json

    from adm_calib import plots
    from adm_calib.calib_commands import main
    from adm_calib.reference import lower_bound_table

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from test_calib_study import _no_figures, _synthetic

    lbs = lower_bound_table()
    recs, _ = _synthetic(lbs["ICE-2"]["mu2"].coefficients, train="ICE-2", mf="mu2", per_interval=4, seed=0)
    res = tmp_path / "results.jsonl"
    res.write_text("".join(json.dumps(r) + "\n" for r in recs))
    out = tmp_path / "fit"
    _no_figures(monkeypatch)
    real = plots.plot_lower_bounds_train

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, "plot_lower_bounds_train", interrupted)
    assert main(["study-fit", "--results", str(res), "--out", str(out)]) == 130
    assert capsys.readouterr().err.strip() == "error: interrupted"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["results.jsonl"]
    monkeypatch.setattr(plots, "plot_lower_bounds_train", real)
    assert main(["study-fit", "--results", str(res), "--out", str(out)]) == 0
    assert (out / "lower_bounds_fit.csv").exists() and (out / "fig17_lower_bound_ICE-2.png").exists()


# ---------------------------------------------------------------- text inputs and long names
def test_text_input_with_bom_is_read_and_a_binary_file_is_one_line(tmp_path):
    from adm_sim.inputs.bridges import resolve_bridge
    from adm_sim.files import read_text

    body = "L = 15\nn0 = 8.26\nmu = 19042\nzeta_pct = 1.85\n"
    (tmp_path / "bom.toml").write_bytes(b"\xef\xbb\xbf" + body.encode())
    b = resolve_bridge(str(tmp_path / "bom.toml"))
    assert b.span_m == 15.0 and b.damping_ratio == pytest.approx(0.0185, rel=1e-12)
    (tmp_path / "bin.toml").write_bytes(b"L = 15\n\xff\xfe")
    with pytest.raises(InputError, match=r"bridge file '.*bin\.toml': not UTF-8 text \(byte 0xff at offset 7\)"):
        resolve_bridge(str(tmp_path / "bin.toml"))
    assert read_text(tmp_path / "bom.toml", "x") == body


def test_existing_file_with_equals_in_its_name_is_a_file_not_a_spec(tmp_path, monkeypatch):
    from adm_sim.inputs.bridges import resolve_bridge

    monkeypatch.chdir(tmp_path)
    Path("L=15.toml").write_text("L = 20\nn0 = 6\nmu = 15000\nzeta_pct = 2\n")
    assert resolve_bridge("L=15.toml").span_m == 20.0     # the file, not the spec L=15
    assert resolve_bridge("L=15,n0=8.26,mu=19042,zeta_pct=1.85").span_m == 15.0


def test_path_component_over_255_bytes_is_refused_naming_the_option(tmp_path):
    from adm_sim.files import check_path

    assert check_path(f"{tmp_path}/{'a' * 255}.json"[:-5], "--json")
    for text in (f"{tmp_path}/{'a' * 256}", f"{tmp_path}/{'é' * 128}/x"):  # 256 bytes each
        with pytest.raises(InputError, match=r"--json: a path component \('.{24}\.\.\.'\) is 256 bytes long; "
                                             r"allowed at most 255"):
            claim_output(text, "--json")
    with pytest.raises(InputError, match="--out: a path component"):
        check_output_folder(f"{tmp_path}/{'b' * 300}", "--out")


@pytest.mark.parametrize("where", ["open", "flock"])
def test_a_signal_while_claiming_leaves_no_lock_file(tmp_path, monkeypatch, where):
    """Ctrl-C arriving between the lock file's creation and the record of its claim (sent from
    inside ``os.open`` as it returns, or from inside ``flock``): it is raised once the claim is
    recorded, and the runner's release (here ``files.release``) removes the file; before, a signal
    there left the lock file behind (seen under load with SIGTERM, once per ~50 runs).

    The signal goes to the main thread itself (``pthread_kill``), which holds it blocked there, so it
    is delivered when the claim unblocks it, every time. Sent to the process (``os.kill``), the system
    may hand it to another thread (xdist's), whose handler call reaches the main thread a moment later,
    after the claim and sometimes after the test: the interrupt then escaped and killed the worker."""
    import fcntl
    import signal
    import threading

    from adm_sim import files

    sent = []
    real = {"open": os.open, "flock": fcntl.flock}[where]

    def then_signal(*args):
        result = real(*args)
        if not sent and (where == "flock" or str(args[0]).endswith(".lock")):  # once, the lock's own call
            sent.append(signal.SIGINT)  # raise_interrupt turns it into KeyboardInterrupt
            assert signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, []), "not held back"
            signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)
        return result

    from adm_sim.interrupts import raise_interrupt

    previous = signal.signal(signal.SIGINT, raise_interrupt)  # the commands' handler (run_cli's)
    monkeypatch.setattr(files.os if where == "open" else files.fcntl, where, then_signal)
    out = tmp_path / "r.json"
    try:
        with pytest.raises(KeyboardInterrupt):
            claim_output(str(out), "--json", suffix=".json")
        monkeypatch.undo()
        assert sent == [signal.SIGINT]
        assert claimed(out) and lock_path(out).exists()  # the claim was made whole, then interrupted
    finally:
        monkeypatch.undo()
        signal.signal(signal.SIGINT, previous)
        files.release(out)
    assert not lock_path(out).exists() and not claimed(out)
