"""Commands start fast: each command imports only the heavy modules its work uses.

Every case runs in a fresh process that has imported nothing of the project and none of
:data:`HEAVY` (a child forked from the server of tests/probe_server.py, an interpreter that started
as a probe's own would and imported only the standard library and numpy, which every command
imports first; it checks that of itself before serving), imports a command module and, for a subcommand, runs it
on a small case; then it lists which of :data:`HEAVY` were imported. The test asserts which are absent (and, for the numerical paths,
that the one they need is present, so the probe can fail both ways), not a time: times are in
``bench/bench_cli.py`` and docs/benchmarks.md. What each heavy module costs at the start of a
process on the 2-core machine (``python -X importtime``, quiet): scipy.signal ~1 s (it pulls
scipy.stats), numba ~0.4 s plus ~0.3 s the first time a kernel is loaded (its CPU target, which
imports scipy.linalg for BLAS), matplotlib ~0.3 s, rerun ~0.3 s, dask ~0.3 s, rclpy ~0.2 s,
scipy.optimize ~0.3 s, tqdm ~30 ms.

Also here: after :func:`adm_sim.cli.precompile.compile_kernels` (``adm-sim compile``) the sweeps, the
checks and a calibration add no signature to any kernel, so the compile step compiles everything
they need.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from probe_server import ProbeServer

pytestmark = pytest.mark.slow  # every test here starts processes

ROOT = Path(__file__).resolve().parents[2]

HEAVY = ("scipy", "scipy.signal", "scipy.stats", "scipy.optimize", "scipy.integrate", "scipy.interpolate",
         "scipy.linalg", "scipy.sparse", "numba", "matplotlib", "rerun", "dask", "distributed", "rclpy", "mcap",
         "mcap_ros2", "tqdm", "selenium", "pandas")
#: Never at the start of a command that does not draw, record, distribute or talk ROS.
NEVER = ("scipy.signal", "scipy.stats", "scipy.integrate", "scipy.interpolate", "matplotlib", "rerun", "dask",
         "distributed", "rclpy", "mcap", "mcap_ros2", "tqdm", "selenium", "pandas")

PROBE = """
import contextlib, importlib, io, json, sys
mod, argv = sys.argv[1], json.loads(sys.argv[2])
m = importlib.import_module(mod)
rc = None
if argv:
    with contextlib.redirect_stdout(io.StringIO()):
        rc = m.main(argv)
print(json.dumps({"rc": rc, "loaded": [h for h in json.loads(sys.argv[3]) if h in sys.modules]}))
"""


#: Probes run in forked children of a server that imported the standard library and numpy only
#: (tests/probe_server.py: it refuses to serve with any of :data:`HEAVY` or of the project loaded).
_SERVER = ProbeServer(HEAVY, ROOT / "src")


@pytest.fixture(scope="module", autouse=True)
def _stop_fork_server():
    yield
    _SERVER.stop()


def probe(code, *argv, env, cwd=None, timeout=600):
    """``python -c code *argv`` with ``env`` (its PYTHONPATH must be this checkout's src) in a
    forked child of the probe server: ``CompletedProcess`` with the exit code and the output."""
    return _SERVER.probe(code, *argv, env=env, cwd=cwd, timeout=timeout)


def test_the_probe_server_gives_a_fresh_process():
    """A probe sees none of the server's own state: its own ``__main__``, pid, arguments and
    environment, and no module of the project."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), PROBE_VAR="x")
    code = ("import json, os, sys; print(json.dumps([__name__, os.getpid(), sys.argv[1:], os.environ['PROBE_VAR'], "
            "sorted(m for m in sys.modules if m.split('.')[0] in ('adm_sim', 'adm_calib', 'scipy', 'numba'))]))")
    a = probe(code, "1", env=env)
    b = probe(code + "; sys.exit(3)", "2", env=dict(env, PROBE_VAR="y"))
    assert (a.returncode, b.returncode) == (0, 3), (a.stderr, b.stderr)
    pa, pb = json.loads(a.stdout), json.loads(b.stdout)
    assert pa[0] == pb[0] == "__main__" and pa[1] != pb[1] and pa[1] != os.getpid()
    assert (pa[2], pa[3], pb[2], pb[3]) == (["1"], "x", ["2"], "y") and pa[4] == pb[4] == []


def loaded(module, argv=(), cwd=None):
    """Heavy modules in ``sys.modules`` of a fresh process after importing ``module`` (and
    running ``main(argv)``); asserts exit code 0."""
    env = dict(os.environ, ADM_SIM_QUIET_COMPILE="1", PYTHONPATH=str(ROOT / "src"))
    p = probe(PROBE, module, json.dumps(list(argv)), json.dumps(HEAVY), env=env, cwd=cwd)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert out["rc"] in (None, 0), p.stderr
    return set(out["loaded"])


@pytest.mark.parametrize("module", ["adm_sim.cli.sim_commands", "adm_calib.calib_commands"])
def test_importing_a_command_module_loads_nothing_heavy(module):
    assert loaded(module) == set()


@pytest.mark.parametrize("argv", [["trains", "--check"], ["bridges"], ["bridges", "--field"]])
def test_table_commands_load_nothing_heavy(argv):
    assert loaded("adm_sim.cli.sim_commands", argv) == set()


def test_recommend_loads_nothing_heavy():
    argv = ["recommend", "--train", "ICE-2", "--n0", "6.5", "--mu", "15000", "--type", "cfb"]
    assert loaded("adm_calib.calib_commands", argv) == set()


@pytest.mark.parametrize("argv", [
    ["sweep", "--model", "mlm", "--speeds", "250:270:5"],
    ["sweep", "--model", "mlm", "--speeds", "250:270:5", "--where", "deck"],
    ["sweep", "--model", "dim", "--speeds", "250,300"],
    ["sweep", "--model", "mlm", "--method", "rk4", "--speeds", "250,300"],
    ["check", "--bridge", "B1", "--max-line-speed", "160", "--trains", "HSLM-A1,ICE-2"],
])
def test_compiled_paths_load_numba_and_nothing_else_heavy(argv):
    """The sweep (exact envelope and compiled RK4 lanes) and the check need numba (whose CPU target
    imports scipy.linalg for BLAS) and nothing else: no scipy.signal (the peak rule is written out
    in adm_sim.integrate.peaks), no optimiser, no plotting, no ROS, no progress-bar library when stderr is
    not a terminal."""
    got = loaded("adm_sim.cli.sim_commands", argv)
    assert "numba" in got
    assert got.isdisjoint(NEVER), got & set(NEVER)
    assert "scipy.optimize" not in got


def test_numpy_backend_sweep_does_not_start_numbas_cpu_target():
    """The numpy stepper (two speeds, the coarsest step the sweep takes: 4 steps per period of the
    highest mode) runs without numba's CPU target: what a run imports does not depend on its step,
    and at the default step the stepper's work was ~1.4 s of the probe's ~2 s of CPU."""
    got = loaded("adm_sim.cli.sim_commands", ["sweep", "--model", "dim", "--speeds", "250,300", "--steps-per-period", "4",
                                              "--backend", "numpy"])
    assert got.isdisjoint(NEVER) and "scipy.linalg" not in got, got


def test_calibrate_loads_the_optimiser_and_no_signal_processing():
    got = loaded("adm_calib.calib_commands", ["calibrate", "--bridge", "B1", "--train", "ICE-2"])
    assert {"numba", "scipy.optimize"} <= got
    assert got.isdisjoint(NEVER), got & set(NEVER)


def test_plot_loads_matplotlib_only_when_asked(tmp_path):
    """The one place matplotlib belongs: --plot (the probe can see it)."""
    got = loaded("adm_sim.cli.sim_commands", ["sweep", "--speeds", "250:270:5", "--plot", str(tmp_path / "s.png")])
    assert "matplotlib" in got and (tmp_path / "s.png").stat().st_size > 1000


CHECK_SIGNATURES = """
import contextlib, io, json
from adm_sim.integrate import envelope, kernels
from adm_sim.cli.precompile import compile_kernels
from adm_sim.cli.sim_commands import main

def signatures():
    out = {}
    for mod in (envelope, kernels):
        for name, f in vars(mod).items():
            if hasattr(f, "signatures") and hasattr(f, "py_func") and f.py_func.__module__ == mod.__name__:
                out[f"{mod.__name__}.{name}"] = sorted(str(s) for s in f.signatures)
    return out

compile_kernels()
before = signatures()
with contextlib.redirect_stdout(io.StringIO()):
    for argv in (["sweep", "--model", "mlm"], ["sweep", "--model", "mlm", "--where", "deck"],
                 ["sweep", "--model", "dim", "--speeds", "200:300:50"],
                 ["sweep", "--model", "mlm", "--method", "rk4", "--speeds", "200:300:50"],
                 ["sweep", "--train", "Eurostar", "--model", "dim", "--speeds", "200:300:50"],
                 ["check", "--bridge", "B3", "--max-line-speed", "160", "--trains", "hslm,ICE-2,Eurostar",
                  "--where", "midspan"],
                 ["check", "--bridge", "B1", "--max-line-speed", "160", "--trains", "HSLM-A3", "--where", "x=4"]):
        assert main(argv) == 0, argv
    from adm_calib.calib_commands import main as calib_main
    assert calib_main(["calibrate", "--bridge", "B1", "--train", "ICE-2"]) == 0
print(json.dumps({"before": before, "after": signatures()}))
"""


def test_compile_step_compiles_every_signature_the_commands_use():
    env = dict(os.environ, ADM_SIM_QUIET_COMPILE="1", PYTHONPATH=str(ROOT / "src"))
    p = probe(CHECK_SIGNATURES, env=env, timeout=900)
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout.strip().splitlines()[-1])
    assert d["after"] == d["before"]
    assert sum(len(s) for s in d["before"].values()) >= 4  # the entry kernels were compiled or loaded


NOTICE_PROBE = """
import sys
sys.path.insert(0, sys.argv[1])
import adm_sim_probe  # a module of this package's name prefix, one uncached kernel
print(adm_sim_probe.twice(2.0), adm_sim_probe.twice(3.0), adm_sim_probe.thrice(1.0))
"""
PROBE_MODULE = """
from adm_sim.integrate._jit import njit


@njit
def twice(x):
    return 2.0 * x


@njit
def thrice(x):
    return 3.0 * x
"""


@pytest.mark.parametrize("quiet", ["", "1"])
def test_a_process_that_compiles_says_so_once_on_stderr(tmp_path, quiet):
    """The first-run line comes before numba compiles a kernel of the package (here two uncached
    kernels: one line), and ADM_SIM_QUIET_COMPILE=1 silences it."""
    (tmp_path / "adm_sim_probe.py").write_text(PROBE_MODULE)
    env = dict(os.environ, ADM_SIM_QUIET_COMPILE=quiet, PYTHONPATH=str(ROOT / "src"))
    p = probe(NOTICE_PROBE, str(tmp_path), env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == ["4.0", "6.0", "3.0"]
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    if quiet:
        assert lines == []
    else:
        assert len(lines) == 1 and lines[0].startswith("compiling kernels (once): adm_sim_probe.twice and the kernels")


REFUSED = """
import contextlib, importlib, io, json, sys
m = importlib.import_module("adm_sim.cli.sim_commands")
err = io.StringIO()
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
    rc = m.main(json.loads(sys.argv[1]))
print(json.dumps({"rc": rc, "err": err.getvalue(), "numba": "numba" in sys.modules}))
"""


@pytest.mark.parametrize("argv, named", [
    (["sweep", "--speeds", "abc"], "--speeds"),
    (["sweep", "--where", "roof"], "--where"),
    (["sweep", "--bridge", "B9"], "--bridge"),
    (["check", "--bridge", "B1", "--max-line-speed", "200", "--where", "x=99"], "--where"),
    (["check", "--bridge", "B1", "--max-line-speed", "200", "--trains", "HSLM-A11"], "--trains"),
])
def test_a_refused_command_does_not_load_numba(argv, named):
    """Bad input is refused (one line naming the flag, exit 2) before the compiled kernels load:
    the user waits for the refusal, not for numba (~0.4-0.6 s of CPU a process)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    p = probe(REFUSED, json.dumps(argv), env=env)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert out["rc"] == 2, out
    lines = out["err"].strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {named}"), lines
    assert out["numba"] is False
