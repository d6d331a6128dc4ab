"""Hostile and borderline inputs at every entry point, table-driven (issue 17).

Every case runs one entry point as a user would (``adm-sim``, ``adm-calib``, ``replay.py``,
``crossing.py``, ``calibrate.py``, a node started by hand) in a fresh folder: a process of its own
for signals and at least one plain case per entry point (each node one); the other refusals call
the entry point's ``main(argv)`` in this process (:func:`_in_process`; a node on rclpy's default
context in the case's ROS domain, the environment of a case set for the call).
It asserts the properties every refusal must have, whatever the class:

* the exit code (2 for bad input, 130 for an interrupt);
* no ``Traceback`` on stderr, and stderr is exactly one line ``error: ...`` holding the expected
  words (naming the option or parameter and the reason);
* the folder is unchanged: every file (inputs included) has the same name, size and content, no
  run folder, temporary file or lock file is left;
* no process is left: each case's processes carry a marker in their environment, and none may
  be alive once the entry point has exited (in this process: no new child is alive).

The classes (column ``cls``) are those of issue 17; ``python tests/inputs/test_hostile_inputs.py``
prints the table of classes and counts that ``docs/bad_input.md`` holds.
"""

from __future__ import annotations

import hashlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
SIM = [PY, "-m", "adm_sim.cli.sim_commands"]
CAL = [PY, "-m", "adm_calib.calib_commands"]
REPLAY = [PY, str(ROOT / "launch_scripts" / "replay.py")]
CROSS = [PY, str(ROOT / "launch_scripts" / "crossing.py")]
CALIB = [PY, str(ROOT / "launch_scripts" / "calibrate.py")]
MARK = "ADM_HOSTILE_CASE"
TRAIN_TOML = (ROOT / "src" / "adm_sim" / "data" / "examples" / "my_train.toml").read_text()
BRIDGE_TOML = "L = 15\nn0 = 8.26\nmu = 19042\nzeta_pct = 1.85\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: The worked example's functions file and the ICE-2 vehicle file (recommend --functions FILE --train FILE).
OWN_FUNCTIONS = str(ROOT / "results" / "own_train" / "fit" / "functions_test_car___3_wagons.toml")
ICE2_VEHICLES = str(ROOT / "src" / "adm_sim" / "data" / "vehicles" / "ice2_vehicles.toml")

CLASSES = {
    "output-is-input": "an output path that is an input file of the same run",
    "output-exists": "an existing output replaced without --overwrite (CLIs) or overwrite:=true (nodes)",
    "output-not-writable": "an output in a folder that cannot be written (probed before any work)",
    "output-not-a-file": "an output that is a folder or a named pipe, or empty",
    "concurrent-writer": "an output another process is writing (lock held): refused naming its pid",
    "input-not-regular": "an input that is a named pipe or a folder (refused before opening: no hang)",
    "launch-precheck": "launcher values a node would refuse, checked before any process or folder",
    "ros-parameters": "undeclared parameters and duplicate YAML keys at node start-up",
    "scheduler": "study --scheduler at a closed port, a silent or a foreign server (loopback only): exit 1, "
                 "a server that does not answer",
    "signals": "SIGINT / SIGTERM during the work: error: interrupted, 130, no partial output",
    "damaged-input": "an MCAP cut short, with a damaged chunk, or without messages (no traceback, no empty output)",
    "bounded-work": "more speeds, lanes, trains, axles or train length than one run may take (field registry limits)",
    "output-set": "an interrupt or a refused write while a command writes its outputs: none of the set appears",
    "viewer": "--connect to a closed port, an HTTP or a silent peer, --spawn without a display: exit 1, nothing started",
    "track-profile": "a track profile the DIM cannot represent (slope, curvature, a wave shorter than the step) at "
                     "every entry: sweep, study, the train node's parameters",
    "odd-input": "binary text files, names over 255 bytes, a bad NUMBA_NUM_THREADS, a BOM, '=' in a file name, "
                 "zero damping, --comfort without vehicles",
}


@dataclass
class Case:
    cls: str
    ident: str
    argv: object            # callable(t) -> list, t the case folder
    line: str               # expected words of the one stderr line (formatted with t=..., pid=...)
    code: int = 2
    setup: object = None    # callable(t, ctx) -> None; ctx collects helper processes / values
    ros: bool = False       # needs a ROS environment (a node or a launcher)
    timeout_s: float = 60.0
    ctx: dict = field(default_factory=dict)
    env: dict = field(default_factory=dict)  # environment variables set for the case
    process: bool = False   # run as its own process even where its entry point's main could run in this one
    patches: tuple = ()     # (module, function, (name, value) or a replacement) set before the entry runs


# ---------------------------------------------------------------------- set-up helpers
def _files(t, **texts):
    for name, text in texts.items():
        p = t / name.replace("__", ".")
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(text if isinstance(text, bytes) else text.encode())


def _fifo(name):
    def setup(t, ctx):
        os.mkfifo(t / name)
    return setup


def _all(*setups):
    def setup(t, ctx):
        for s in setups:
            s(t, ctx)
    setup.starts_process = any(getattr(s, "starts_process", False) for s in setups)
    return setup


def _train(t, ctx):
    _files(t, t__toml=TRAIN_TOML)


def _bridge(t, ctx):
    _files(t, b__toml=BRIDGE_TOML)


def _existing(*names):
    def setup(t, ctx):
        for n in names:
            (t / n).parent.mkdir(parents=True, exist_ok=True)
            (t / n).write_bytes(MCAP_MAGIC + b"keep me: an earlier result" if n.endswith(".mcap") else b"keep me")
    return setup


def _mcap(t, ctx):
    (t / "run.mcap").write_bytes(MCAP_MAGIC + b"\x00" * 64)


def _holder(code, *args):
    """A helper process that holds a claim (prints 'held' once it does); killed after the case."""
    def setup(t, ctx):
        env = dict(os.environ, PYTHONPATH=os.environ.get("PYTHONPATH", str(ROOT / "src")))
        p = subprocess.Popen([PY, "-c", code] + [a.format(t=t) for a in args], stdout=subprocess.PIPE, text=True,
                             env=env, cwd=t)
        assert p.stdout.readline().strip() == "held"
        ctx.setdefault("helpers", []).append(p)
        ctx["pid"] = p.pid
    setup.starts_process = True
    return setup


HOLD_OUTPUT = ("import sys, time\nfrom adm_sim.files import claim_output\n"
               "claim_output(sys.argv[1], 'x', True)\nprint('held', flush=True)\ntime.sleep(120)\n")
HOLD_FOLDER = ("import fcntl, os, sys, time\nos.makedirs(sys.argv[1], exist_ok=True)\n"
               "fd = os.open(os.path.join(sys.argv[1], '.launch.lock'), os.O_RDWR | os.O_CREAT)\n"
               "fcntl.flock(fd, fcntl.LOCK_EX)\nos.write(fd, f'{os.getpid()}\\n'.encode())\n"
               "print('held', flush=True)\ntime.sleep(120)\n")


def _recording(kind):
    """A small MCAP of many chunks in ``run.mcap``: intact, cut in half, one chunk's bytes flipped
    (its CRC fails), or a valid file without messages."""
    def setup(t, ctx):
        from std_msgs.msg import String

        from adm_sim.recording.mcap_log import McapRecorder

        path = t / "run.mcap"
        with McapRecorder(path, chunk_size=1024) as rec:
            for k in range(0 if kind == "empty" else 400):
                rec.write("/adm/progress", String(data=f'{{"step": {k}, "text": "{"x" * 40}"}}'), k * 1_000_000)
        data = bytearray(path.read_bytes())
        if kind == "cut":
            data = data[:len(data) // 2]
        elif kind == "damaged":  # flip 16 bytes at the end of the middle Chunk record (opcode 0x06)
            chunks, pos = [], 8
            while pos + 9 <= len(data):
                length = int.from_bytes(data[pos + 1:pos + 9], "little")
                if data[pos] == 0x06:
                    chunks.append(pos + 9 + length)
                pos += 9 + length
            end = chunks[len(chunks) // 2]
            data[end - 20:end - 4] = bytes(b ^ 0x5A for b in data[end - 20:end - 4])
        path.write_bytes(bytes(data))
    return setup


def _server(reply):
    """A loopback TCP server that answers each connection with ``reply`` (None: stays silent)."""
    def setup(t, ctx):
        srv = socket.socket()
        srv.bind(("127.0.0.1", 0))
        srv.listen(8)

        def run():
            while True:
                try:
                    c, _ = srv.accept()
                except OSError:
                    return
                if reply is not None:
                    c.sendall(reply)
                time.sleep(8)
                c.close()

        threading.Thread(target=run, daemon=True).start()
        ctx["port"] = srv.getsockname()[1]
        ctx.setdefault("sockets", []).append(srv)
    return setup


def _closed_port(t, ctx):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    ctx["port"] = s.getsockname()[1]
    s.close()


def _unwritable(t):
    """A folder this process cannot write in: a read-only copy for a user, /sys for root (which
    ignores permissions)."""
    if os.geteuid() == 0:
        return Path("/sys")
    ro = t / "ro"
    return ro


def _make_ro(t, ctx):
    if os.geteuid() != 0:
        (t / "ro").mkdir()
        (t / "ro").chmod(0o555)


def _long_train(vehicles):
    """The example train with ``vehicles`` more coaches (100 per composition entry)."""
    def setup(t, ctx):
        extra = "".join(f'[[composition]]\nvehicle = "Coach"\ncount = {min(100, vehicles - k)}\n'
                        for k in range(0, vehicles, 100))
        _files(t, long__toml=TRAIN_TOML + "\n" + extra)
    return setup


def _profile(name, kind):
    """A profile file every row of which lies within |elevation| <= 0.1 m: ``alt`` +-90 mm alternating
    every 0.3 mm, ``saw`` a +-99 mm saw-tooth of 2 mm wavelength (issue 38), ``kink`` a 40 mm rise
    over 1 m (slope 0.04) whose corners no wheel follows, ``wavy`` a 0.2 mm sine of 0.1 m wavelength
    (legal slope and curvature, shorter than 4 steps of a coarse run)."""
    def setup(t, ctx):
        if kind == "alt":
            rows = [(i * 0.0003, 0.09 if i % 2 == 0 else -0.09) for i in range(50000)]
        elif kind == "saw":
            rows = [(i * 0.0005, 0.099 * (2.0 * ((i * 0.0005 / 0.002) % 1.0) - 1.0)) for i in range(30000)]
        elif kind == "kink":
            rows = [(i * 0.01, 0.04 * min(max((i * 0.01 - 2.0) / 1.0, 0.0), 1.0)) for i in range(1501)]
        else:
            import math
            rows = [(i * 0.005, 0.0002 * math.sin(2 * math.pi * i * 0.005 / 0.1)) for i in range(3001)]
        _files(t, **{name.replace(".", "__"): "position_m,elevation_m\n" + "".join(f"{x:.6f},{e:.6f}\n" for x, e in rows)})
    return setup


def _foreign_mcap(t, ctx):
    """A recording whose /adm/midspan/accel carries std_msgs/Float64 (the nodes publish AccelStamped)."""
    from std_msgs.msg import Float64

    from adm_sim.recording.mcap_log import McapRecorder

    with McapRecorder(t / "f.mcap") as rec:
        for i in range(20):
            rec.write("/adm/midspan/accel", Float64(data=float(i)), log_time_ns=1000 * i)


def _failing(module, name, exc="KeyboardInterrupt"):
    """A patch: ``module.name`` (a writer of one output of the set) replaced by one that writes half
    a file (``p``: the path among its arguments) and then raises ``exc``."""
    return (module, name, ("failing", exc))


def _failing_writer(exc):
    def failing(*a, **k):
        p = next((x for x in a if hasattr(x, "write_bytes")), None)
        if p is not None:
            p.write_bytes(b"half a file")
        raise eval(exc, {"p": p})  # noqa: S307  the exception of the table, "KeyboardInterrupt" or NO_ROOM
    return failing


def _shorter_wait(module, name, shipped_s, short_s):
    """A patch: the default wait ``timeout_s`` (the last default) of ``module.name`` shortened from
    ``shipped_s`` (asserted: the default the product ships) to ``short_s``. For a peer that never
    answers, any bound proves the same refusal; the wait itself is the only cost."""
    return (module, name, ("wait", shipped_s, short_s))


def _returning(module, name, value):
    """A patch: ``module.name`` replaced by a function that returns ``value`` whatever its arguments
    (a costly step before the one under test, whose output the case does not read)."""
    return (module, name, ("returning", value))


def _apply(patch, setattr_):
    """Apply one patch of :attr:`Case.patches` with ``setattr_(obj, name, value)`` (monkeypatch's)."""
    import importlib

    module, name, (kind, *args) = patch
    m = importlib.import_module(module)
    if kind == "failing":
        setattr_(m, name, _failing_writer(args[0]))
    elif kind == "returning":
        assert callable(getattr(m, name)), f"{module}.{name}"
        setattr_(m, name, lambda *a, value=args[0], **k: value)
    else:
        f = getattr(m, name)
        assert f.__defaults__[-1] == args[0], f"{module}.{name}: shipped wait {f.__defaults__[-1]!r} s"
        setattr_(f, "__defaults__", f.__defaults__[:-1] + (args[1],))


NO_ROOM = "OSError(28, 'No space left on device', str(p))"


def _fit_results(t, ctx):
    """A study results file of 4 cases per frequency interval (ICE-2, mu2), on the paper's fit."""
    import json

    sys.path.insert(0, str(ROOT / "tests"))
    from test_calib_study import _synthetic

    from adm_calib.reference import lower_bound_table

    recs, _ = _synthetic(lower_bound_table()["ICE-2"]["mu2"].coefficients, train="ICE-2", mf="mu2",
                         per_interval=4, seed=0)
    _files(t, r__jsonl="".join(json.dumps(r) + "\n" for r in recs))


LONG = "a" * 300  # one file name of 300 bytes (the system allows 255)
BINARY = bytes(range(256)) * 4
BOM = b"\xef\xbb\xbf"


def _params(text):
    def setup(t, ctx):
        (t / "p.yaml").write_text(text)
    return setup


def node(module, *params):
    return lambda t: [PY, "-m", module, "--ros-args"] + [x for p in params for x in ("-p", p.format(t=t))]


# ---------------------------------------------------------------------- the table
CASES = [
    # --- output = input
    Case("output-is-input", "sweep-json-is-train",
         lambda t: SIM + ["sweep", "--train", f"{t}/t.toml", "--json", f"{t}/t.toml", "--overwrite"],
         "--json: '{t}/t.toml' is the --train file, an input of this run", setup=_train),
    Case("output-is-input", "sweep-json-is-bridge",
         lambda t: SIM + ["sweep", "--bridge", f"{t}/b.toml", "--json", f"{t}/./b.toml", "--overwrite"],
         "is the --bridge file, an input of this run", setup=_bridge),
    Case("output-is-input", "check-csv-is-train",
         lambda t: SIM + ["check", "--max-line-speed", "200", "--trains", f"{t}/t.csv", "--csv", f"{t}/t.csv",
                          "--overwrite"],
         "--csv: '{t}/t.csv' is the --trains file", setup=lambda t, ctx: _files(t, t__csv=TRAIN_TOML)),
    Case("output-is-input", "calibrate-json-is-train",
         lambda t: CAL + ["calibrate", "--bridge", "B1", "--train", f"{t}/t.json", "--json", f"{t}/t.json", "--force"],
         "--json: '{t}/t.json' is the --train file", setup=lambda t, ctx: _files(t, t__json=TRAIN_TOML),
         process=True),
    Case("output-is-input", "salvage-dst-is-src",
         lambda t: SIM + ["salvage", f"{t}/run.mcap", f"{t}/run.mcap", "--overwrite"],
         "salvage DST: '{t}/run.mcap' is SRC", setup=_mcap),
    Case("output-is-input", "study-fit-out-holds-results",
         lambda t: CAL + ["study-fit", "--results", f"{t}/lower_bounds_fit.csv", "--out", str(t), "--force"],
         "is the --results file, an input of this run",
         setup=lambda t, ctx: _files(t, lower_bounds_fit__csv='{"bridge": "x", "train": "ICE-2"}\n')),
    Case("output-is-input", "crossing-out-holds-params",
         lambda t: CROSS + ["--out", str(t), "--params-file", f"{t}/summary.json", "--overwrite"],
         "is the --params-file file, an input of this run", ros=True,
         setup=lambda t, ctx: _files(t, summary__json="train:\n  ros__parameters:\n    model: mlm\n")),
    # --- existing outputs
    Case("output-exists", "driver-record-path", node("adm_sim.nodes.driver", "record_path:=keep.mcap"),
         "error: driver: record_path: 'keep.mcap' exists; set -p overwrite:=true to replace it",
         setup=_existing("keep.mcap"), ros=True, process=True),
    Case("output-exists", "driver-rrd-path", node("adm_sim.nodes.driver", "rrd_path:=keep.rrd"),
         "rrd_path: 'keep.rrd' exists; set -p overwrite:=true", setup=_existing("keep.rrd"), ros=True),
    Case("output-exists", "driver-summary-path", node("adm_sim.nodes.driver", "summary_path:=keep.json"),
         "summary_path: 'keep.json' exists", setup=_existing("keep.json"), ros=True),
    Case("output-exists", "calibration-node-record-path",
         node("adm_calib.nodes.calibration_node", "record_path:=keep.mcap"),
         "error: calibration: record_path: 'keep.mcap' exists", setup=_existing("keep.mcap"), ros=True, process=True),
    Case("output-exists", "driver-record-path-txt", node("adm_sim.nodes.driver", "record_path:=keep.txt"),
         "record_path: 'keep.txt' must end in .mcap", setup=_existing("keep.txt"), ros=True),
    Case("output-exists", "driver-two-outputs-one-file",
         node("adm_sim.nodes.driver", "record_path:=a.mcap", "summary_path:=./a.mcap"),
         "summary_path: './a.mcap' is the record_path file; give different files", ros=True),
    Case("output-exists", "sweep-json", lambda t: SIM + ["sweep", "--json", f"{t}/r.json"],
         "--json: '{t}/r.json' exists; use --overwrite", setup=_existing("r.json"), process=True),
    Case("output-exists", "replay-rrd", lambda t: REPLAY + [f"{t}/run.mcap", "--rrd", f"{t}/o.rrd"],
         "--rrd: '{t}/o.rrd' exists", setup=_all(_mcap, _existing("o.rrd"))),
    Case("output-exists", "crossing-out-earlier-run", lambda t: CROSS + ["--out", str(t)],
         "holds an earlier run (run.mcap)", setup=_existing("run.mcap"), ros=True, process=True),
    # --- not writable (probed before the work)
    Case("output-not-writable", "sweep-json", lambda t: SIM + ["sweep", "--json", f"{_unwritable(t)}/r.json"],
         "--json: '{ro}/r.json': cannot write in the directory '{ro}'", setup=_make_ro),
    Case("output-not-writable", "check-plot",
         lambda t: SIM + ["check", "--max-line-speed", "200", "--plot", f"{_unwritable(t)}/r.png"],
         "--plot: '{ro}/r.png': cannot write in the directory", setup=_make_ro),
    Case("output-not-writable", "calibrate-json",
         lambda t: CAL + ["calibrate", "--bridge", "B1", "--train", "ICE-2", "--json", f"{_unwritable(t)}/r.json"],
         "--json: '{ro}/r.json': cannot write in the directory", setup=_make_ro),
    Case("output-not-writable", "table4-out", lambda t: CAL + ["table4", "--out", f"{_unwritable(t)}/sub"],
         "--out: '{ro}/sub': cannot write in the directory", setup=_make_ro),
    Case("output-not-writable", "salvage-dst",
         lambda t: SIM + ["salvage", f"{t}/run.mcap", f"{_unwritable(t)}/s.mcap"],
         "salvage DST: '{ro}/s.mcap': cannot write in the directory", setup=_all(_mcap, _make_ro)),
    Case("output-not-writable", "replay-rrd", lambda t: REPLAY + [f"{t}/run.mcap", "--rrd", f"{_unwritable(t)}/o.rrd"],
         "--rrd: '{ro}/o.rrd': cannot write in the directory", setup=_all(_mcap, _make_ro)),
    Case("output-not-writable", "driver-record-path", lambda t: node("adm_sim.nodes.driver",
                                                                     f"record_path:={_unwritable(t)}/r.mcap")(t),
         "error: driver: record_path: '{ro}/r.mcap': cannot write in the directory", setup=_make_ro, ros=True),
    Case("output-not-writable", "crossing-out", lambda t: CROSS + ["--out", f"{_unwritable(t)}/run"],
         "--out: '{ro}/run': cannot write in the directory", setup=_make_ro, ros=True),
    # --- not a regular file
    Case("output-not-a-file", "sweep-json-fifo", lambda t: SIM + ["sweep", "--json", f"{t}/p", "--overwrite"],
         "--json: '{t}/p' is a named pipe, not a regular file", setup=_fifo("p")),
    Case("output-not-a-file", "sweep-json-dir", lambda t: SIM + ["sweep", "--json", str(t)],
         "--json: '{t}' is a directory; give a file name"),
    Case("output-not-a-file", "sweep-json-empty", lambda t: SIM + ["sweep", "--json", ""],
         "--json: '' is empty; give a file name"),
    Case("output-not-a-file", "driver-record-fifo", node("adm_sim.nodes.driver", "record_path:=p.mcap",
                                                         "overwrite:=true"),
         "record_path: 'p.mcap' is a named pipe, not a regular file", setup=_fifo("p.mcap"), ros=True),
    Case("output-not-a-file", "crossing-out-empty", lambda t: CROSS + ["--out", ""],
         "--out: '' is empty", ros=True),
    Case("output-not-a-file", "calibrate-out-is-file", lambda t: CALIB + ["--out", f"{t}/f"],
         "--out: '{t}/f' is not a directory", setup=lambda t, ctx: _files(t, f="x"), ros=True, process=True),
    # --- a second writer
    Case("concurrent-writer", "sweep-json", lambda t: SIM + ["sweep", "--json", f"{t}/r.json"],
         "--json: '{t}/r.json' is being written by process {pid}",
         setup=_holder(HOLD_OUTPUT, "{t}/r.json")),
    Case("concurrent-writer", "salvage-dst", lambda t: SIM + ["salvage", f"{t}/run.mcap", f"{t}/s.mcap"],
         "salvage DST: '{t}/s.mcap' is being written by process {pid}",
         setup=_all(_mcap, _holder(HOLD_OUTPUT, "{t}/s.mcap"))),
    Case("concurrent-writer", "calibrate-plot",
         lambda t: CAL + ["calibrate", "--bridge", "B1", "--train", "ICE-2", "--plot", f"{t}/c.png"],
         "--plot: '{t}/c.png' is being written by process {pid}", setup=_holder(HOLD_OUTPUT, "{t}/c.png")),
    Case("concurrent-writer", "driver-record-path", node("adm_sim.nodes.driver", "record_path:=r.mcap"),
         "error: driver: record_path: 'r.mcap' is being written by process {pid}",
         setup=_holder(HOLD_OUTPUT, "{t}/r.mcap"), ros=True),
    Case("concurrent-writer", "crossing-same-out", lambda t: CROSS + ["--out", f"{t}/run"],
         "--out: '{t}/run' is being written by another launch (process {pid})",
         setup=_holder(HOLD_FOLDER, "{t}/run"), ros=True),
    Case("concurrent-writer", "calibrate-same-out", lambda t: CALIB + ["--out", f"{t}/run"],
         "is being written by another launch (process {pid})", setup=_holder(HOLD_FOLDER, "{t}/run"), ros=True),
    # --- inputs that are not regular files (a pipe would block open() for ever)
    Case("input-not-regular", "sweep-train-fifo", lambda t: SIM + ["sweep", "--train", f"{t}/t.toml"],
         "train file '{t}/t.toml': is a named pipe, not a regular file", setup=_fifo("t.toml")),
    Case("input-not-regular", "sweep-bridge-fifo", lambda t: SIM + ["sweep", "--bridge", f"{t}/b.toml"],
         "bridge: '{t}/b.toml' is neither a named bridge", setup=_fifo("b.toml")),
    Case("input-not-regular", "check-train-fifo",
         lambda t: SIM + ["check", "--max-line-speed", "200", "--trains", f"{t}/t.toml"],
         "train file '{t}/t.toml': is a named pipe", setup=_fifo("t.toml")),
    Case("input-not-regular", "calibrate-bridge-fifo",
         lambda t: CAL + ["calibrate", "--bridge", f"{t}/b.toml", "--train", "ICE-2"],
         "bridge: '{t}/b.toml' is neither a named bridge", setup=_fifo("b.toml")),
    Case("input-not-regular", "salvage-src-fifo", lambda t: SIM + ["salvage", f"{t}/p.mcap", f"{t}/s.mcap"],
         "salvage SRC: '{t}/p.mcap' is a named pipe, not a regular file", setup=_fifo("p.mcap")),
    Case("input-not-regular", "replay-mcap-fifo", lambda t: REPLAY + [f"{t}/p.mcap", "--rrd", f"{t}/o.rrd"],
         "RUN.mcap: '{t}/p.mcap' is a named pipe", setup=_fifo("p.mcap")),
    Case("input-not-regular", "study-fit-results-fifo", lambda t: CAL + ["study-fit", "--results", f"{t}/r.jsonl"],
         "--results: '{t}/r.jsonl' is a named pipe", setup=_fifo("r.jsonl")),
    Case("input-not-regular", "trains-train-dir", lambda t: SIM + ["trains", "--train", f"{t}/d.toml"],
         "train file '{t}/d.toml': cannot read", setup=lambda t, ctx: (t / "d.toml").mkdir()),
    Case("input-not-regular", "crossing-params-fifo", lambda t: CROSS + ["--out", f"{t}/o", "--params-file",
                                                                         f"{t}/p.yaml"],
         "--params-file: '{t}/p.yaml' is a named pipe", setup=_fifo("p.yaml"), ros=True),
    Case("input-not-regular", "node-params-fifo",
         lambda t: [PY, "-m", "adm_sim.nodes.train_node", "--ros-args", "--params-file", f"{t}/p.yaml"],
         "error: train: --params-file '{t}/p.yaml': is a named pipe", setup=_fifo("p.yaml"), ros=True),
    Case("input-not-regular", "crossing-train-fifo", lambda t: CROSS + ["--out", f"{t}/o", "--train", f"{t}/t.toml"],
         "train file '{t}/t.toml': is a named pipe", setup=_fifo("t.toml"), ros=True),
    # --- launchers: every value checked before a process starts or a folder exists
    Case("launch-precheck", "crossing-load-train-dim", lambda t: CROSS + ["--out", f"{t}/o", "--train", "HSLM-A1"],
         "train node: model: 'dim' needs a train with vehicles; 'HSLM-A1' is a load train", ros=True),
    Case("launch-precheck", "calibrate-load-train", lambda t: CALIB + ["--out", f"{t}/o", "--train", "HSLM-A1"],
         "train node: model: 'dim' needs a train with vehicles", ros=True),
    Case("launch-precheck", "crossing-domain-999", lambda t: CROSS + ["--out", f"{t}/o", "--domain-id", "999"],
         "--domain-id: 999 is out of range; allowed integer in [0, 232]", ros=True),
    Case("launch-precheck", "calibrate-domain-text", lambda t: CALIB + ["--out", f"{t}/o", "--domain-id", "x"],
         "--domain-id: 'x' is not an integer", ros=True),
    Case("launch-precheck", "crossing-wait-clients-101", lambda t: CROSS + ["--out", f"{t}/o", "--wait-clients", "101"],
         "--wait-clients: 101 is out of range; allowed integer in [0, 100]", ros=True),
    Case("launch-precheck", "calibrate-namespace-digit", lambda t: CALIB + ["--out", f"{t}/o", "--namespace", "/3b"],
         "--namespace: '/3b' is not a valid ROS 2 namespace", ros=True),
    Case("launch-precheck", "crossing-params-delta-zeta",
         lambda t: CROSS + ["--out", f"{t}/o", "--params-file", f"{t}/p.yaml"],
         "bridge node: delta_zeta: -0.19 - (fraction) is out of range; allowed [-0.0185, 0.2]",
         setup=_params("bridge:\n  ros__parameters:\n    delta_zeta: -0.19\n"), ros=True),
    Case("launch-precheck", "calibrate-params-model-for-hslm",
         lambda t: CALIB + ["--out", f"{t}/o", "--params-file", f"{t}/p.yaml"],
         "train node: model: 'dim' needs a train with vehicles",
         setup=_params("train:\n  ros__parameters:\n    train: HSLM-A3\n    model: mlm\n"), ros=True),
    Case("launch-precheck", "crossing-spawn-and-connect",
         lambda t: CROSS + ["--out", f"{t}/o", "--spawn", "--connect", "rerun+http://127.0.0.1:9876/proxy"],
         "give --spawn or --connect, not both", ros=True),
    Case("launch-precheck", "calibrate-connect-not-loopback",
         lambda t: CALIB + ["--out", f"{t}/o", "--connect", "rerun+http://viewer.invalid:9876/proxy"],
         "--connect: host 'viewer.invalid' is not on this machine", ros=True),
    Case("launch-precheck", "crossing-empty-speeds", lambda t: CROSS + ["--out", f"{t}/o", "--speeds", ""],
         "--speeds: '' is empty", ros=True),
    Case("launch-precheck", "calibrate-one-speed", lambda t: CALIB + ["--out", f"{t}/o", "--speeds", "300"],
         "error: --speeds: '300': need at least 3 speeds (km/h), got 1", ros=True),
    Case("launch-precheck", "calibrate-params-two-speeds",
         lambda t: CALIB + ["--out", f"{t}/o", "--params-file", f"{t}/p.yaml"],
         "calibration: speeds_kmh: '200,300': need at least 3 speeds (km/h), got 2", ros=True,
         setup=_params('calibration:\n  ros__parameters:\n    speeds_kmh: "200,300"\n')),
    Case("launch-precheck", "calibrate-empty-train", lambda t: CALIB + ["--out", f"{t}/o", "--train", " "],
         "--train: '' is empty", ros=True),
    # --- ROS parameters at node start-up
    Case("ros-parameters", "bridge-undeclared", node("adm_sim.nodes.bridge_node", "span:=20.0"),
         "error: bridge: span: unknown parameter of node 'bridge'; allowed EJ_Nm2", ros=True, process=True),
    Case("ros-parameters", "train-undeclared", node("adm_sim.nodes.train_node", "trian:=ICE-2"),
         "error: train: trian: unknown parameter of node 'train'", ros=True, process=True),
    Case("ros-parameters", "driver-undeclared", node("adm_sim.nodes.driver", "record:=x.mcap"),
         "error: driver: record: unknown parameter of node 'driver'", ros=True),
    Case("ros-parameters", "node-params-duplicate-key",
         lambda t: [PY, "-m", "adm_sim.nodes.bridge_node", "--ros-args", "--params-file", f"{t}/p.yaml"],
         "key 'span_m' is given twice (lines 3 and 4)",
         setup=_params("bridge:\n  ros__parameters:\n    span_m: 20.0\n    span_m: 30.0\n"), ros=True),
    Case("ros-parameters", "launch-params-duplicate-node",
         lambda t: CALIB + ["--out", f"{t}/o", "--params-file", f"{t}/p.yaml"],
         "key 'train' is given twice",
         setup=_params("train:\n  ros__parameters:\n    model: mlm\ntrain:\n  ros__parameters:\n    model: dim\n"),
         ros=True),
    Case("ros-parameters", "launch-params-undeclared",
         lambda t: CROSS + ["--out", f"{t}/o", "--params-file", f"{t}/p.yaml"],
         "train.ros__parameters.span_m: unknown parameter",
         setup=_params("train:\n  ros__parameters:\n    span_m: 20.0\n"), ros=True),
    # --- the study's scheduler (loopback only)
    # --- damaged files
    Case("damaged-input", "replay-damaged-chunk", lambda t: REPLAY + [f"{t}/run.mcap", "--rrd", f"{t}/o.rrd"],
         "RUN.mcap: '{t}/run.mcap' is damaged (1 of", setup=_recording("damaged"), process=True),
    Case("damaged-input", "replay-convert-damaged",
         lambda t: REPLAY + [f"{t}/run.mcap", "--rrd", f"{t}/o.rrd", "--via-convert"],
         "is damaged", setup=_recording("damaged")),
    Case("damaged-input", "replay-cut-short", lambda t: REPLAY + [f"{t}/run.mcap", "--rrd", f"{t}/o.rrd"],
         "RUN.mcap: '{t}/run.mcap' is not a complete MCAP file", setup=_recording("cut")),
    Case("damaged-input", "replay-convert-cut-short",
         lambda t: REPLAY + [f"{t}/run.mcap", "--rrd", f"{t}/o.rrd", "--via-convert"],
         "is not a complete MCAP file", setup=_recording("cut")),
    Case("damaged-input", "replay-empty", lambda t: REPLAY + [f"{t}/run.mcap", "--rrd", f"{t}/o.rrd"],
         "RUN.mcap: '{t}/run.mcap' holds no message; nothing to replay", setup=_recording("empty")),
    Case("damaged-input", "salvage-empty", lambda t: SIM + ["salvage", f"{t}/run.mcap", f"{t}/s.mcap"],
         "holds no complete message to recover", setup=_recording("empty")),
    # --- bounded work: the limits of the field registry, refused before any array is allocated
    Case("bounded-work", "check-speed-step-1e-4",
         lambda t: SIM + ["check", "--max-line-speed", "300", "--speed-step", "1e-4", "--json", f"{t}/c.json"],
         "error: --speed-step: 0.0001 km/h from 144 to 360 km/h gives 2160001 speeds; allowed at most 20000 speeds"),
    Case("bounded-work", "sweep-speeds-60k",
         lambda t: SIM + ["sweep", "--speeds", "1:600:0.01", "--json", f"{t}/r.json"],
         "'1:600:0.01' gives 59901 speeds; allowed at most 20000 speeds"),
    Case("bounded-work", "calibrate-speeds-30k",
         lambda t: CAL + ["calibrate", "--bridge", "B1", "--train", "ICE-2", "--speeds", "1:600:0.02", "--json", f"{t}/c.json"],
         "'1:600:0.02' gives 29951 speeds; allowed at most 20000 speeds"),
    Case("bounded-work", "check-trains-50",
         lambda t: SIM + ["check", "--max-line-speed", "300", "--trains", "hslm,hslm,hslm,hslm,hslm"],
         "error: --trains: 'hslm,hslm,hslm,hslm,hslm' gives 50 trains; allowed at most 40 trains"),
    Case("bounded-work", "sweep-train-10000-vehicles",
         lambda t: SIM + ["sweep", "--train", f"{t}/long.toml", "--json", f"{t}/r.json"],
         "long.toml: composition: 10010 units gives 40040 axles; allowed at most 400 axles", setup=_long_train(10000)),
    Case("bounded-work", "check-train-1300-m",
         lambda t: SIM + ["check", "--max-line-speed", "200", "--trains", f"{t}/long.toml"],
         "long.toml: composition: 50 units, 200 axles gives 1282.75 m; allowed at most 1000 m",
         setup=_long_train(40)),
    Case("bounded-work", "train-node-lanes", node("adm_sim.nodes.train_node", "speeds_kmh:=1:600:0.01"),
         "speeds_kmh: '1:600:0.01' gives 59901 lanes; allowed at most 20000 lanes", ros=True),
    Case("bounded-work", "crossing-speeds", lambda t: CROSS + ["--out", f"{t}/o", "--speeds", "1:600:0.02"],
         "'1:600:0.02' gives 29951", ros=True),
    Case("bounded-work", "sweep-work-600-lanes-13M-steps",
         lambda t: SIM + ["sweep", "--bridge", "L=150,n0=0.5,mu=1e5,zeta_pct=1,n_modes=20", "--model", "dim",
                          "--speeds", "1:600:1", "--json", f"{t}/r.json"],
         "error: work: 600 lanes x 13.5 M steps x 20 modes = 1.62e+11 is beyond the work limit 1e+10 (the project's "
         "choice; raise it with --max-work or ADM_SIM_MAX_WORK); large because 600 speeds x"),
    Case("bounded-work", "sweep-memory-beyond-the-machine",
         lambda t: SIM + ["sweep", "--bridge", "L=150,n0=0.5,mu=1e5,zeta_pct=1,n_modes=20", "--model", "dim",
                          "--speeds", "1:600:1", "--max-work", "1e12", "--json", f"{t}/r.json"],
         "error: memory: the DIM tables of 13465344 steps would take 174 GiB; this machine has"),
    Case("bounded-work", "sweep-max-work-negative", lambda t: SIM + ["sweep", "--max-work", "-3"],
         "error: --max-work: '-3' is not allowed; allowed a finite number >= 1"),
    Case("bounded-work", "sweep-max-work-env-text", lambda t: SIM + ["sweep"],
         "error: ADM_SIM_MAX_WORK: 'lots' is not allowed; allowed a finite number >= 1", env={"ADM_SIM_MAX_WORK": "lots"}),
    Case("bounded-work", "check-speed-step-1e-300",
         lambda t: SIM + ["check", "--max-line-speed", "200", "--speed-step", "1e-300"],
         "error: --speed-step: 1e-300 km/h from 144 to 240 km/h gives 9.6e+301 speeds; allowed at most 20000 speeds"),
    Case("bounded-work", "calibrate-work", lambda t: CAL + ["calibrate", "--train", "ICE-2", "--bridge", "L=150,n0=0.5,mu=1e5,zeta_pct=1,n_modes=20",
                                                            "--speeds", "1:600:1", "--json", f"{t}/c.json"],
         "error: work: 600 lanes x"),
    Case("bounded-work", "study-work", lambda t: CAL + ["study", "--out", f"{t}/s", "--speeds", "1:600:1",
                                                         "--steps-per-period", "10000"],
         "error: work: 600 lanes x 2.51e+09 steps x 3 modes = 4.51e+12 is beyond the work limit 1e+10"),
    Case("bounded-work", "crossing-work", lambda t: CROSS + ["--out", f"{t}/o", "--bridge", "B1", "--model", "dim",
                                                             "--speeds", "1:600:1", "--params-file", f"{t}/p.yaml"],
         "error: bridge node: work: 600 lanes x", ros=True,
         setup=lambda t, ctx: _files(t, p__yaml="bridge:\n  ros__parameters:\n    n_modes: 20\n"
                                               "    steps_per_period: 10000.0\n")),
    # --- track profiles the model cannot represent
    Case("input-not-regular", "sweep-irregularity-fifo",
         lambda t: SIM + ["sweep", "--model", "dim", "--irregularity", f"file={t}/p.csv"],
         "error: irregularity: file = '{t}/p.csv': is a named pipe, not a regular file", setup=_fifo("p.csv")),
    Case("input-not-regular", "study-irregularity-fifo",
         lambda t: CAL + ["study", "--out", f"{t}/s", "--spans", "15", "--irregularity", f"file={t}/p.csv"],
         "is a named pipe, not a regular file", setup=_fifo("p.csv")),
    Case("damaged-input", "replay-foreign-type", lambda t: REPLAY + [f"{t}/f.mcap", "--rrd", f"{t}/o.rrd"],
         "error: RUN.mcap: topic '/adm/midspan/accel' in '{t}/f.mcap' has type std_msgs/msg/Float64, not "
         "geometry_msgs/msg/AccelStamped", setup=_foreign_mcap),
    Case("track-profile", "sweep-alternating-90mm",
         lambda t: SIM + ["sweep", "--model", "dim", "--irregularity", f"file={t}/alt.csv", "--json", f"{t}/r.json"],
         "error: irregularity: file={t}/alt.csv has slope", setup=_profile("alt.csv", "alt")),
    Case("track-profile", "sweep-saw-tooth-2mm",
         lambda t: SIM + ["sweep", "--model", "dim", "--irregularity", f"file={t}/saw.csv"],
         "allowed |slope| <= 0.05 (the project's small-slope bound", setup=_profile("saw.csv", "saw")),
    Case("track-profile", "sweep-kink",
         lambda t: SIM + ["sweep", "--model", "dim", "--irregularity", f"file={t}/kink.csv"],
         "has curvature", setup=_profile("kink.csv", "kink")),
    Case("track-profile", "sweep-wave-shorter-than-2-steps",
         lambda t: SIM + ["sweep", "--model", "dim", "--speeds", "300", "--steps-per-period", "4",
                          "--irregularity", f"file={t}/w.csv"],
         "allowed >= 2 steps per wave", setup=_profile("w.csv", "wavy")),
    Case("track-profile", "sweep-profile-with-mlm",
         lambda t: SIM + ["sweep", "--model", "mlm", "--irregularity", "german-low"],
         "error: --irregularity: 'german-low' acts on the DIM's wheels; the MLM has none"),
    Case("track-profile", "study-alternating-90mm",
         lambda t: CAL + ["study", "--out", f"{t}/s", "--spans", "15", "--irregularity", f"file={t}/alt.csv"],
         "has slope", setup=_profile("alt.csv", "alt")),
    Case("track-profile", "train-node-saw-tooth",
         node("adm_sim.nodes.train_node", "model:=dim", "irregularity:=file={t}/saw.csv"),
         "has slope", ros=True, setup=_profile("saw.csv", "saw")),
    # --- output sets: written beside, all renamed at the end, or none
    Case("output-set", "calibrate-json-plot-interrupted-in-plot",
         lambda t: CAL + ["calibrate", "--bridge", "B1", "--train", "ICE-2", "--speeds", "160:350:5", "--json",
                          f"{t}/c.json", "--plot", f"{t}/c.png"],
         "error: interrupted", code=130, patches=(_failing("adm_calib.plots", "plot_calibration"),)),
    Case("output-set", "calibrate-json-plot-disk-full-in-plot",
         lambda t: CAL + ["calibrate", "--bridge", "B1", "--train", "ICE-2", "--speeds", "160:350:5", "--json",
                          f"{t}/c.json", "--plot", f"{t}/c.png"],
         "error: --plot: '{t}/c.png': cannot write (No space left on device)", code=1,
         patches=(_failing("adm_calib.plots", "plot_calibration", exc=NO_ROOM),)),
    # the process: the way out of a real process after the interrupt (the rest in this process)
    Case("output-set", "sweep-json-plot-interrupted-in-plot",
         lambda t: SIM + ["sweep", "--speeds", "200:300:5", "--json", f"{t}/r.json", "--plot", f"{t}/r.png"],
         "error: interrupted", code=130, patches=(_failing("adm_sim.cli.figures", "plot_sweep"),), process=True),
    Case("output-set", "check-four-outputs-interrupted-in-report",
         lambda t: SIM + ["check", "--max-line-speed", "160", "--trains", "HSLM-A1", "--json", f"{t}/c.json",
                          "--csv", f"{t}/c.csv", "--plot", f"{t}/c.png", "--report", f"{t}/c.html"],
         "error: interrupted", code=130, patches=(_failing("adm_sim.design.check_report", "write_report"),)),
    Case("output-set", "table4-interrupted-in-figure",
         lambda t: CAL + ["table4", "--bridges", "B1", "--trains", "ICE-2", "--out", f"{t}/t4"],
         "error: interrupted", code=130, timeout_s=120, patches=(_failing("adm_calib.plots", "plot_total_damping"),)),
    Case("output-set", "study-fit-interrupted-in-figure",
         lambda t: CAL + ["study-fit", "--results", f"{t}/r.jsonl", "--out", f"{t}/fit"],
         "error: interrupted", code=130, setup=_fit_results,
         # the conservative bound's linear programmes (no set: its two files are written empty) come
         # before the figure that is interrupted; tests/calib/test_calib_study.py checks them
         patches=(_returning("adm_calib.cli.study_fit", "conservative_study", []),
                  _failing("adm_calib.plots", "plot_lower_bounds_train"))),
    # --- odd inputs: one line, exit 2
    Case("odd-input", "study-train-hslm", lambda t: CAL + ["study", "--out", f"{t}/st", "--trains", "HSLM-A1"],
         "error: --trains: 'HSLM-A1' is HSLM-A1, an EN 1991-2 load train (axle loads only, no vehicles)"),
    Case("odd-input", "study-train-file-without-vehicles",
         lambda t: CAL + ["study", "--out", f"{t}/st", "--trains", f"{t}/loads.toml"],
         "error: --trains: '{t}/loads.toml': holds no vehicles", setup=lambda t, ctx: _files(t, loads__toml='name = "x"\n')),
    Case("odd-input", "recommend-functions-of-another-train",
         lambda t: CAL + ["recommend", "--functions", OWN_FUNCTIONS, "--train", ICE2_VEHICLES, "--n0", "5", "--mu",
                          "30000", "--type", "cfb"],
         "was made for train 'test car + 3 wagons' (file 'my_vehicle_train.toml', SHA-256"),
    Case("odd-input", "recommend-functions-of-another-format",
         lambda t: CAL + ["recommend", "--functions", f"{t}/f.toml", "--train", ICE2_VEHICLES, "--n0", "5", "--mu",
                          "30000", "--type", "cfb"],
         "error: --functions: '{t}/f.toml': format None is not a functions file of one train",
         setup=lambda t, ctx: _files(t, f__toml='columns = ["a"]\n')),
    Case("odd-input", "node-params-binary",
         lambda t: [PY, "-m", "adm_sim.nodes.train_node", "--ros-args", "--params-file", f"{t}/p.yaml"],
         "--params-file '{t}/p.yaml': not UTF-8 text (byte 0x80 at offset 128)", ros=True,
         setup=lambda t, ctx: _files(t, p__yaml=BINARY)),
    Case("odd-input", "crossing-params-binary",
         lambda t: CROSS + ["--out", f"{t}/o", "--params-file", f"{t}/p.yaml"],
         "not UTF-8 text (byte 0x80 at offset 128)", ros=True, setup=lambda t, ctx: _files(t, p__yaml=BINARY)),
    Case("odd-input", "train-file-binary", lambda t: SIM + ["sweep", "--train", f"{t}/t.toml"],
         "train file '{t}/t.toml': not UTF-8 text (byte 0x80 at offset 128)",
         setup=lambda t, ctx: _files(t, t__toml=BINARY)),
    Case("odd-input", "sweep-json-name-300-bytes", lambda t: SIM + ["sweep", "--json", f"{t}/{LONG}.json"],
         "error: --json: a path component ('aaaaaaaaaaaaaaaaaaaaaaaa...') is 305 bytes long; allowed at most 255"),
    Case("odd-input", "calibrate-bridge-name-300-bytes",
         lambda t: CAL + ["calibrate", "--bridge", f"{t}/{LONG}.toml", "--train", "ICE-2"],
         "is 305 bytes long; allowed at most 255 bytes per file or folder name"),
    Case("odd-input", "crossing-out-name-300-bytes", lambda t: CROSS + ["--out", f"{t}/{LONG}"],
         "error: --out: a path component ('aaaaaaaaaaaaaaaaaaaaaaaa...') is 300 bytes long", ros=True),
    Case("odd-input", "numba-threads-0", lambda t: SIM + ["sweep", "--json", f"{t}/r.json"],
         "error: NUMBA_NUM_THREADS: '0' is not allowed; allowed an integer >= 1", env={"NUMBA_NUM_THREADS": "0"}),
    Case("odd-input", "numba-threads-text", lambda t: CAL + ["calibrate", "--bridge", "B1", "--train", "ICE-2"],
         "error: NUMBA_NUM_THREADS: 'all' is not allowed", env={"NUMBA_NUM_THREADS": "all"}),
    Case("odd-input", "bridge-file-named-with-equals", lambda t: SIM + ["sweep", "--bridge", "L=15.toml"],
         "error: bridge file L=15.toml.L: 200 m is out of range; allowed [1, 150] m",
         setup=lambda t, ctx: _files(t, **{"L=15__toml": BRIDGE_TOML.replace("L = 15", "L = 200")})),
    Case("odd-input", "bridge-file-with-bom", lambda t: SIM + ["sweep", "--bridge", f"{t}/b.toml"],
         "L: 200 m is out of range; allowed [1, 150] m",
         setup=lambda t, ctx: _files(t, b__toml=BOM + BRIDGE_TOML.replace("L = 15", "L = 200").encode())),
    Case("odd-input", "spec-zeta-pct-0", lambda t: SIM + ["sweep", "--bridge", "L=15,n0=8.26,mu=19042,zeta_pct=0"],
         "error: --bridge: 'L=15,n0=8.26,mu=19042,zeta_pct=0' has zeta_pct = 0 %"),
    Case("odd-input", "check-comfort-hslm-only",
         lambda t: SIM + ["check", "--max-line-speed", "200", "--comfort", "--json", f"{t}/c.json"],
         "error: --comfort: the trains checked (HSLM-A1, HSLM-A2"),
    # --- a live viewer that is not there: refused before any process starts or any folder is created
    Case("viewer", "crossing-connect-closed-port",
         lambda t: CROSS + ["--out", f"{t}/o", "--connect", "rerun+http://127.0.0.1:{port}/proxy"],
         "error: --connect: no viewer at rerun+http://127.0.0.1:{port}/proxy (Connection refused)", code=1,
         setup=_closed_port, ros=True),
    Case("viewer", "crossing-connect-http-server",
         lambda t: CROSS + ["--out", f"{t}/o", "--connect", "rerun+http://127.0.0.1:{port}/proxy"],
         "error: --connect: rerun+http://127.0.0.1:{port}/proxy is not a rerun viewer (it answered b'HTTP/1.1 '",
         code=1, setup=_server(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n"), ros=True),
    # a silent peer: the launchers' shipped wait (5 s) here, a shorter one for calibrate.py and the
    # study (the same refusal, 0.5 s of waiting in place of 5)
    Case("viewer", "crossing-connect-silent-server",
         lambda t: CROSS + ["--out", f"{t}/o", "--connect", "rerun+http://127.0.0.1:{port}/proxy"],
         "error: --connect: the viewer at rerun+http://127.0.0.1:{port}/proxy does not answer (no HTTP/2 answer "
         "within 5 s)", code=1, setup=_server(None), ros=True, process=True),
    Case("viewer", "calibrate-connect-closed-port",
         lambda t: CALIB + ["--out", f"{t}/o", "--connect", "rerun+http://127.0.0.1:{port}/proxy"],
         "error: --connect: no viewer at rerun+http://127.0.0.1:{port}/proxy", code=1, setup=_closed_port, ros=True),
    Case("viewer", "calibrate-connect-silent-server",
         lambda t: CALIB + ["--out", f"{t}/o", "--connect", "rerun+http://127.0.0.1:{port}/proxy"],
         "does not answer (no HTTP/2 answer within 0.5 s)", code=1, setup=_server(None), ros=True,
         patches=(_shorter_wait("adm_sim.recording.viewer_process", "handshake", 5.0, 0.5),)),
    Case("viewer", "crossing-spawn-no-display", lambda t: CROSS + ["--out", f"{t}/o", "--spawn"],
         "error: --spawn: the rerun viewer exited at once (exit status 1: ", code=1, ros=True,
         env={"DISPLAY": "", "WAYLAND_DISPLAY": "", "WAYLAND_SOCKET": ""}, process=True),
    Case("scheduler", "closed-port",
         lambda t: CAL + ["study", "--out", f"{t}/st", "--scheduler", "tcp://127.0.0.1:{port}"],
         "--scheduler: cannot connect to 'tcp://127.0.0.1:{port}'", setup=_closed_port, code=1),
    Case("scheduler", "http-server",
         lambda t: CAL + ["study", "--out", f"{t}/st", "--scheduler", "tcp://127.0.0.1:{port}"],
         "is not a dask scheduler (its first bytes b'HTTP/1.1' are not a dask message)",
         setup=_server(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n"), code=1),
    Case("scheduler", "silent-server",
         lambda t: CAL + ["study", "--out", f"{t}/st", "--scheduler", "tcp://127.0.0.1:{port}"],
         "is not a dask scheduler (no dask handshake within 0.5 s)", setup=_server(None),
         patches=(_shorter_wait("adm_calib.study.execution", "check_scheduler", 5.0, 0.5),), code=1),
    Case("scheduler", "huge-frame-length",
         lambda t: CAL + ["study", "--out", f"{t}/st", "--scheduler", "tcp://127.0.0.1:{port}"],
         "is not a dask scheduler", setup=_server(b"\xff" * 64), code=1),
    Case("scheduler", "existing-study-folder-untouched",
         lambda t: CAL + ["study", "--out", str(t), "--scheduler", "tcp://127.0.0.1:{port}"],
         "--scheduler: cannot connect", setup=_all(_closed_port, lambda t, ctx: _files(t, results__jsonl="")), code=1),
]


# ---------------------------------------------------------------------- the properties
def snapshot(folder):
    """``{relative path: (kind, size, sha256)}`` of everything under ``folder`` (hidden files too)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = str(p.relative_to(folder))
            st = p.lstat()
            if p.is_fifo() or p.is_dir():
                out[rel] = ("fifo" if p.is_fifo() else "dir", 0, "")
            else:
                out[rel] = ("file", st.st_size, hashlib.sha256(p.read_bytes()).hexdigest())
    return out


def marked_processes(marker):
    """Pids of live processes whose environment holds ``MARK=marker``."""
    needle = f"{MARK}={marker}".encode()
    found = []
    for e in os.scandir("/proc"):
        if not e.name.isdigit():
            continue
        try:
            if needle in Path(f"/proc/{e.name}/environ").read_bytes().split(b"\0"):
                stat = Path(f"/proc/{e.name}/stat").read_text()
                if stat.rsplit(")", 1)[1].split()[0] != "Z":
                    found.append(int(e.name))
        except OSError:
            continue
    return found


@pytest.fixture(scope="module")
def ros_env():
    from adm_sim.processes.dds_env import local_ros_env

    env = local_ros_env()
    yield env
    env.release()


def _env(base, marker):
    env = dict(base)
    env[MARK] = marker
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    env["PYTHONPATH"] = str(ROOT / "src")
    return env


def _words(case, t):
    ro = _unwritable(t)
    return case.line.format(t=t, pid=case.ctx.get("pid"), port=case.ctx.get("port"), ro=ro)


def _cleanup(ctx):
    for p in ctx.get("helpers", []):
        p.kill()
        p.wait(5)
    for s in ctx.get("sockets", []):
        s.close()


#: The entry points whose ``main(argv)`` a case may call in this process: the command line's prefix
#: in the table and the module that holds the ``main`` its console script or ``__main__`` calls.
ENTRY_MODULES = [(SIM, "adm_sim.cli.sim_commands"), (CAL, "adm_calib.calib_commands"), (REPLAY, "replay"),
                 (CALIB, "calibrate"), (CROSS, "crossing")]
#: The nodes started by hand (``python -m <module> --ros-args ...``): their ``main(args)`` is the one
#: ``__main__`` calls (``sys.exit(main())``), the arguments after the module's name.
NODE_MODULES = {"adm_sim.nodes.driver", "adm_sim.nodes.bridge_node", "adm_sim.nodes.train_node",
                "adm_calib.nodes.calibration_node"}
IN_PROCESS = {"adm_sim.cli.sim_commands", "adm_calib.calib_commands", "replay", "crossing", "calibrate"} | NODE_MODULES


def _entry_of(argv):
    """``(module, arguments)`` of a command line of the table, or (None, argv) for another (a node)."""
    for prefix, module in ENTRY_MODULES:
        if argv[:len(prefix)] == prefix:
            return module, argv[len(prefix):]
    if argv[:2] == [PY, "-m"] and argv[2] in NODE_MODULES:
        return argv[2], argv[3:]
    return None, argv


def _in_process(case, argv):
    """Whether the case calls its entry point's ``main`` in this process: an ``adm-sim``,
    ``adm-calib``, ``replay.py``, ``crossing.py``, ``calibrate.py`` or node refusal, unless it is
    kept as a process (:attr:`Case.process`: each of these entry points, each node included, keeps
    at least one plain case, ``output-set`` one: exit code, one stderr line, the way out of a real
    process; the launchers' silent viewer at its shipped wait; a viewer spawned without a display).
    A case that sets the environment sets it in this one for the call: the variables of the table
    are read when the command runs (``adm_sim.cliutil.check_environment``, first in ``run_cli``),
    not at start-up."""
    return not case.process and _entry_of(argv)[0] in IN_PROCESS


def _patched_argv(argv, patches):
    """A process that applies ``patches`` and then runs the entry point of ``argv`` (``python -c``)."""
    import inspect

    module, args = _entry_of(argv)
    code = ("import sys\n"
            f"sys.path.insert(0, {str(ROOT / 'launch_scripts')!r})\n"
            + inspect.getsource(_failing_writer) + inspect.getsource(_apply)
            + f"for patch in {patches!r}:\n"
            "    _apply(patch, setattr)\n"
            f"from {module} import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    return [PY, "-c", code] + args


def _children():
    """Pids of the live (not zombie) child processes of this process."""
    me, found = str(os.getpid()), []
    for e in os.scandir("/proc"):
        if e.name.isdigit():
            try:
                fields = Path(f"/proc/{e.name}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if fields[1] == me and fields[0] != "Z":
                found.append(int(e.name))
    return found


@dataclass
class Result:
    returncode: int
    stdout: str
    stderr: str


def _run_in_process(case, argv, t, monkeypatch, capfd, ros_env):
    """The entry point's ``main(argv)`` in this process, in folder ``t``, as its process would call it
    (stdout and stderr read at the file descriptors: a line written past ``sys.stderr`` or by rcl
    counts too). A node runs in the case's ROS environment (its own domain, shared memory only) on
    rclpy's default context, which its ``main`` shuts down however it ends; the signal handlers
    rclpy's init installed are taken out after it, as this process had them before. A node that
    took its input would wait for a run for good: after :attr:`Case.timeout_s` (the bound of a
    case's process) an alarm raises ``TimeoutError`` in it, and the test fails instead of hanging."""
    import importlib

    module, args = _entry_of(argv)
    monkeypatch.syspath_prepend(str(ROOT / "launch_scripts"))
    for patch in case.patches:
        _apply(patch, monkeypatch.setattr)
    node = module in NODE_MODULES
    if node:  # the variables local_ros_env set (the domain, shared memory, localhost)
        for k, v in ros_env.items():
            if os.environ.get(k) != v:
                monkeypatch.setenv(k, v)
    for k, v in case.env.items():
        monkeypatch.setenv(k, v)
    main = importlib.import_module(module).main
    monkeypatch.chdir(t)
    capfd.readouterr()
    if node:
        def overdue(signum, frame):
            raise TimeoutError(f"{module}: no refusal within {case.timeout_s} s")

        alarm = signal.signal(signal.SIGALRM, overdue)
        signal.setitimer(signal.ITIMER_REAL, case.timeout_s)
    try:
        code = main(args)
    except SystemExit as exc:
        code = exc.code
    finally:
        if node:
            import rclpy

            signal.setitimer(signal.ITIMER_REAL, 0.0)
            signal.signal(signal.SIGALRM, alarm)
            rclpy.signals.uninstall_signal_handlers()
            assert not rclpy.ok(), "the node's main left rclpy's default context running"
    out, err = capfd.readouterr()
    return Result(code, out, err)


def _starts_process(case):
    """Whether the case runs its entry point as a process or its set-up starts one (a claim holder):
    such a case is marked ``slow``; the others run in this process, in the developer's loop."""
    argv = case.argv(Path("/nonexistent/case"))
    return getattr(case.setup, "starts_process", False) or not _in_process(case, argv)


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if _starts_process(c) else c for c in CASES],
                         ids=[f"{c.cls}:{c.ident}" for c in CASES])
def test_refused_cleanly(case, tmp_path, ros_env, monkeypatch, capfd, signal_handlers):
    """The case's refusal: in its own process, or (:func:`_in_process`) by its entry point's ``main``
    in this one (then "no process left" means no child of this process is left)."""
    t = tmp_path / "case"
    t.mkdir()
    ctx = case.ctx = {}
    try:
        if case.setup is not None:
            case.setup(t, ctx)
        argv = [a.format(port=ctx.get("port")) if "{port}" in a else a for a in case.argv(t)]
        before = snapshot(t)
        if _in_process(case, argv):
            kids = set(_children())
            r = _run_in_process(case, argv, t, monkeypatch, capfd, ros_env)
            left = sorted(set(_children()) - kids)
        else:
            marker = uuid.uuid4().hex
            base = ros_env if case.ros else os.environ
            if case.patches:
                argv = _patched_argv(argv, case.patches)
            r = subprocess.run(argv, capture_output=True, text=True, timeout=case.timeout_s, cwd=t,
                               env=_env(base, marker) | case.env, stdin=subprocess.DEVNULL)
            left = marked_processes(marker)
        after = snapshot(t)
    finally:
        _cleanup(ctx)
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode == case.code, r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    assert _words(case, t) in lines[0]
    assert after == before  # inputs, outputs and the folder unchanged; no run folder, tmp or lock file
    assert left == []
    assert "ROS_DOMAIN_ID=" not in r.stdout  # no launch started


# ---------------------------------------------------------------------- signals
@dataclass
class SignalCase:
    ident: str
    argv: object   # callable(t) -> list
    ready: object  # text on stdout once the work is under way ("" any line; None: see _computing)
    ros: bool = False
    settle_s: float = 1.0  # wall time after the ready line before the signal (inside the computation)


SIGNAL_ENTRIES = [
    # the compiled DIM sweep ends within the 5 s before the signal: the numpy stepper keeps it busy (~10 s)
    SignalCase("adm-sim-sweep", lambda t: SIM + ["sweep", "--model", "dim", "--backend", "numpy", "--speeds",
                                                 "200:300:1", "--json",
                                                 f"{t}/r.json", "--plot", f"{t}/r.png"], ""),
    # the compiled calibration takes 0.2 s: a fine step and the refined mode keep it busy for ~15 s
    SignalCase("adm-calib-calibrate", lambda t: CAL + ["calibrate", "--bridge", "B4", "--train", "Eurostar",
                                                       "--steps-per-period", "512", "--refine-speed",
                                                       "--dense-maxima", "--json", f"{t}/c.json"], None),
    # the driver's first progress line comes ~10 % into the run (its exchange with the bridge and
    # train nodes sets the pace): the graph is computing, signalled at once; three speeds (lanes) in
    # place of 21 (200:300:5) take the same steps at less CPU a step
    SignalCase("crossing.py", lambda t: CROSS + ["--out", f"{t}/run", "--speeds", "200:210:5"], "step", ros=True,
               settle_s=0.0),
    # the calibration node's first line: the graph is up and the calibration under way, signalled at once
    SignalCase("calibrate.py", lambda t: CALIB + ["--out", f"{t}/run", "--bridge", "B3", "--speeds", "240:300:2",
                                                  "--no-rrd", "--quiet"], "calibrating", ros=True, settle_s=0.0),
    SignalCase("adm-calib-table4", lambda t: CAL + ["table4", "--out", f"{t}/t4", "--steps-per-period", "64",
                                                    "--refine-speed", "--dense-maxima"], None),
]
SIGNAL_CASES = [(e, s) for e in SIGNAL_ENTRIES for s in (signal.SIGTERM, signal.SIGINT)]


#: CPU a command without a ready line spends after its interrupt handling is in place, before it is
#: signalled: past its deferred imports and loads (scipy.optimize, the kernels: 1.4-1.6 s of CPU for
#: ``adm-calib calibrate``, measured), inside the work. A fixed 4 s + 1 s of wall (the former wait)
#: was 5 s of the command's CPU on a quiet machine and about 1 s, still in the imports, at load 9.
WORKING_CPU_S = 2.0


def _signals_caught(pid):
    """The signals process ``pid`` has a handler for (``SigCgt`` of ``/proc/<pid>/status``)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                mask = int(line.split()[1], 16)
                return {s for s in range(1, 65) if mask >> (s - 1) & 1}
    except OSError:
        pass
    return set()


def _cpu_s(pid):
    """User + system CPU seconds of process ``pid`` so far (``/proc/<pid>/stat``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _computing(p, timeout_s=120.0):
    """Wait until the command ``p`` catches SIGTERM (``adm_sim.cliutil.run_command`` has set its
    interrupt handling: the process is past its start-up) and has then spent :data:`WORKING_CPU_S`
    of CPU: an event, not a fixed time, so a loaded machine delays the signal as much as the work."""
    t_end = time.monotonic() + timeout_s
    while signal.SIGTERM not in _signals_caught(p.pid):
        assert p.poll() is None and time.monotonic() < t_end, p.stderr.read() if p.poll() is not None else "no handler"
        time.sleep(0.02)
    cpu0 = _cpu_s(p.pid)
    while _cpu_s(p.pid) - cpu0 < WORKING_CPU_S:
        assert p.poll() is None and time.monotonic() < t_end, p.stderr.read() if p.poll() is not None else "no work"
        time.sleep(0.05)


@pytest.mark.slow
@pytest.mark.parametrize("entry,sig", SIGNAL_CASES,
                         ids=[f"signals:{e.ident}-{signal.Signals(s).name}" for e, s in SIGNAL_CASES])
def test_interrupted_cleanly(entry, sig, tmp_path, ros_env):
    t = tmp_path / "case"
    t.mkdir()
    before = snapshot(t)
    marker = uuid.uuid4().hex
    p = subprocess.Popen(entry.argv(t), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=t,
                         env=_env(ros_env if entry.ros else os.environ, marker), stdin=subprocess.DEVNULL)
    try:
        if entry.ready is None:
            _computing(p)
        else:
            t_end = time.monotonic() + 60
            while time.monotonic() < t_end:
                line = p.stdout.readline()
                assert line, p.stderr.read()
                if entry.ready in line:
                    break
            time.sleep(entry.settle_s)  # inside the computation
        assert p.poll() is None, p.stderr.read()
        p.send_signal(sig)
        out, err = p.communicate(timeout=30)
        t_end = time.monotonic() + 5
        while marked_processes(marker) and time.monotonic() < t_end:
            time.sleep(0.05)
        left = marked_processes(marker)
    finally:
        if p.poll() is None:
            p.kill()
    assert "Traceback" not in err, err
    assert p.returncode == 130, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: interrupted"), err
    assert snapshot(t) == before  # no partial output, no run folder
    assert left == []


# ---------------------------------------------------------------------- the table itself
def class_counts():
    counts = Counter(c.cls for c in CASES)
    counts["signals"] += len(SIGNAL_CASES)
    return counts


def test_every_class_is_covered():
    counts = class_counts()
    print(f"\n{sum(counts.values())} hostile-input cases in {len(counts)} classes: "
          + ", ".join(f"{k} {v}" for k, v in counts.items()))
    assert set(counts) == set(CLASSES)
    assert min(counts.values()) >= 5
    assert len({(c.cls, c.ident) for c in CASES}) == len(CASES)


def test_docs_table_is_this_table():
    assert markdown_table() in (ROOT / "docs" / "bad_input.md").read_text()


def markdown_table():
    counts = class_counts()
    rows = ["| class | what | cases |", "|---|---|---:|"]
    rows += [f"| `{k}` | {CLASSES[k]} | {counts[k]} |" for k in CLASSES]
    rows.append(f"| **total** | | **{sum(counts.values())}** |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(markdown_table())
