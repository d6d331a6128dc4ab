"""Root test configuration: stable numbers and timings on a 2-core machine, local-only DDS."""

import glob
import importlib.util
import os
import subprocess
import sys

import pytest

# Pin BLAS threads before numpy is imported anywhere (numbers and timings stay stable).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# Never let DDS leave this machine: shared-memory transport only, localhost discovery.
os.environ.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "SHM")
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("MPLBACKEND", "Agg")
# No first-run compile notice on stderr in tests (they compare stderr line by line; a fresh clone
# compiles numba's kernels in whichever test comes first). tests/test_imports.py tests the notice.
os.environ.setdefault("ADM_SIM_QUIET_COMPILE", "1")


# --- optional per-test CPU cost (``ADM_SIM_TEST_CPU_LOG=path``) ----------------------------------
# Wall time on a shared machine says little; the CPU a test costs (this process and the children
# it waited for) does. Each test appends "nodeid<TAB>cpu_s<TAB>wall_s" to the file named; the
# numbers in docs/benchmarks.md ("Test suite") were gathered this way.
_CPU_LOG = os.environ.get("ADM_SIM_TEST_CPU_LOG")

if _CPU_LOG:
    import resource
    import time

    def _cpu_s():
        own = resource.getrusage(resource.RUSAGE_SELF)
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        c0, t0 = _cpu_s(), time.perf_counter()
        yield
        with open(_CPU_LOG, "a") as fh:
            fh.write(f"{item.nodeid}\t{_cpu_s() - c0:.3f}\t{time.perf_counter() - t0:.3f}\n")


# --- the suite on two workers (``python -m pytest -n 2``, .ci/run) --------------------------------
# Three things decide how long the suite takes on this 2-core machine, more than any one test:
#
# 1. Numba compiles each kernel on its first call and keeps it in ``src/adm_sim/__pycache__``. In a
#    fresh clone that is about 35 s of CPU, paid by every process that calls a kernel before the
#    cache holds it: both workers at once, and every command-line subprocess a test starts early.
#    So the controller compiles the kernels once, before the workers start, on both cores in parallel
#    (``adm-sim compile``'s code paths, split in two), and every later process loads the cache.
# 2. The order work is handed out: xdist hands it out in collection order, so a slow file that
#    comes last is the tail of the run. Files are ordered by their measured cost, the costliest
#    first (``_FILE_CPU_S``; a file not in the table comes after them, alphabetically).
# 3. A module-scoped fixture (a crossing recorded through the ROS graph, a table of calibrations)
#    is built once per worker that runs one of its tests. Scheduling by group (``--dist loadgroup``)
#    keeps every test that uses a costly module-scoped fixture of its file on one worker, and every
#    test that uses a session fixture of ``tests/conftest.py`` (in any file) on one worker; the
#    other tests are still handed out one by one.

ROOT = os.path.dirname(os.path.abspath(__file__))

#: CPU seconds of each test file run alone (cache warm, ``ADM_SIM_TEST_CPU_LOG``), measured on the
#: 2-core machine of docs/benchmarks.md ("Test suite"); used only to order the files, costliest first.
_FILE_CPU_S = {
    "test_ros_cosim.py": 29,   # with the session's calibration launch (~17 s, shared with test_ros_rerun_views.py)
    "test_batch.py": 21,       # 81, then 54, before the batch/numpy comparisons ran at 4 steps per period
    "test_hostile_inputs.py": 50,
    "test_ros_rerun_views.py": 32,
    "test_ros_faults.py": 30,
    "test_calib_study.py": 19,
    "test_replay_integrity.py": 22,
    "test_monitor_cli.py": 18,
    "test_imports.py": 14,
    "test_entry_points.py": 9,
    "test_calib_study_scheduler.py": 10,
    "test_ros_colcon.py": 20,
    "test_ros_startup_inputs.py": 5,
    "test_appendix_b_findings.py": 12,
    "test_monitor_identify.py": 10,
    "test_paper_findings.py": 8,
    "test_check_effects.py": 8,
    "test_monitor_node.py": 7,
    "test_sweep_backends.py": 8,
    "test_ros_rerun_live.py": 6,
    "test_ros_monitoring.py": 6,
    "test_ros_logging.py": 7,
    "test_kernels_uncompiled.py": 3,
    "test_inputs_cli.py": 5,
    "test_ros_nodes.py": 4,
    "test_calib_workers.py": 4,
    "test_ros_dds_profile.py": 4,
    "test_ros_exchange_errors.py": 3,
    "test_lint.py": 12,        # 2 s was ruff alone; mypy over the core: 65 s of wall in the whole suite at load 8-11
    # Files added since the table above, estimated from the whole suite at load 8-11 (-n 2,
    # --durations; wall divided by 3, the ratio of wall to CPU of the tests above at that load):
    "test_check.py": 38,
    "test_core_dim.py": 6,     # 59 before its limiting cases ran on the compiled sweep
    "test_envelope.py": 18,
    "test_calib_conservative.py": 6,  # the LP re-solved for 10 of the shipped study's 24 sets
    "test_ros_flow.py": 100,   # ~44 s of CPU with its two busy processes, 70-80 s of wall at load 4-8: first, not a tail
    "test_calib_calibrate.py": 12,  # 20 before its hooks ran the compiled sweep
    "test_check_report_browser.py": 16,
    "test_core_dense_maxima.py": 11,
    "test_calib_cli.py": 4,
    "test_core_cli.py": 3,
    "test_files.py": 1,
    "test_check_report.py": 7,
    "test_ros_namespaces.py": 6,
    "test_irregularity_ros.py": 6,
    "test_core_dim_reference.py": 6,
    "test_irregularity.py": 7,
    "test_launch_inputs.py": 2,
    "test_launch_plausibility.py": 2,
    "test_layers.py": 2,
    "test_vehicles.py": 17,
}


def _xdist_controller(config):
    return bool(getattr(config.option, "numprocesses", None)) and not hasattr(config, "workerinput")


def _default_dist(config):
    """No ``--dist`` on the command line: this file's choice (loadgroup) applies."""
    return not any(a.startswith(("--dist", "-d")) for a in config.invocation_params.args)


def pytest_cmdline_main(config):
    if _xdist_controller(config) and _default_dist(config):
        config.option.dist = "loadgroup"
        config.option.loadscopereorder = False  # keep the collection's order (costliest first)
    elif hasattr(config, "workerinput") and _default_dist(config):
        # A worker parses the command line again and does not see the controller's choice above:
        # without this it would not name its tests' groups (xdist appends ``@group`` to a test's id
        # only when ``loadgroup`` is set on the worker) and every test would be scheduled alone,
        # each worker building every module fixture it meets.
        config.option.loadgroup = True


_COMPILE_PARTS = (
    # (which of adm_sim.cli.precompile's code paths, by the start of their name): about half of the
    # compile time each on one core.
    ("exact", "EN 1991-2"),
    ("compiled",),
)
_COMPILE_PROBE = (
    "import sys\n"
    "from adm_sim.cli.precompile import _paths\n"
    "for name, run in _paths():\n"
    "    if name.startswith(tuple(sys.argv[1:])):\n"
    "        run()\n"
)


def _precompile_kernels():
    """Compile (or load) every kernel in two processes at once; a failure is left to the tests."""
    if importlib.util.find_spec("numba") is None:
        return
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (os.path.join(ROOT, "src"), env.get("PYTHONPATH")) if p)
    procs = [subprocess.Popen([sys.executable, "-c", _COMPILE_PROBE, *part], env=env, cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
             for part in _COMPILE_PARTS]
    for p in procs:
        p.wait()


def _kernels_cached():
    """True when numba's index of both kernel modules is newer than their source (nothing to compile)."""
    for mod in ("kernels", "envelope"):
        src = os.path.join(ROOT, "src", "adm_sim", f"{mod}.py")
        idx = glob.glob(os.path.join(ROOT, "src", "adm_sim", "__pycache__", f"{mod}.*.nbi"))
        if not idx or min(os.path.getmtime(i) for i in idx) < os.path.getmtime(src):
            return False
    return True


def _compile_bytecode():
    """Write the bytecode of the project's sources once (``src``, ``launch_scripts``, the test helpers).
    Python reads an up-to-date ``__pycache__`` file even when ``PYTHONDONTWRITEBYTECODE`` is set (as on
    this machine), but never writes one then: without this, each of the suite's several hundred
    subprocesses compiles every project module it imports again."""
    import compileall  # noqa: PLC0415  only in the controller of an xdist run

    for folder in ("src", "launch_scripts", "tests"):
        compileall.compile_dir(os.path.join(ROOT, folder), quiet=1, workers=1)


def pytest_configure(config):
    if _xdist_controller(config) and not config.option.collectonly:
        _compile_bytecode()
        if os.environ.get("ADM_SIM_TEST_PRECOMPILE", "1") != "0" and not _kernels_cached():
            _precompile_kernels()


#: Module-scoped fixtures too cheap to keep their file on one worker (by name, or file::name): a ROS
#: domain reservation (a lock file), a folder of small input files, a bridge and a train, imported
#: launch scripts. Grouping by the first made test_hostile_inputs.py (118 tests, about 70 s of CPU)
#: one work unit.
_CHEAP_MODULE_FIXTURES = {"ros_env", "inputs", "test_calib_grid.py::b1_ice2", "test_monitor_identify.py::ice2",
                          "test_launch_plausibility.py::scripts"}


def _group_of(item):
    """The xdist group a test must join so that a fixture it needs is built once: the name of a
    session fixture of ``tests/conftest.py`` in its closure (a recorded crossing, a calibration
    launch: its users in every file share it), else its file's name if it uses a module-scoped
    fixture of its own file, else None (handed out alone)."""
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return None
    shared, own = [], False
    for name in info.names_closure:
        defs = info.name2fixturedefs.get(name)
        if not defs or defs[-1].scope not in ("module", "package", "session"):
            continue
        where = defs[-1].baseid.split("::")[0]
        if name in _CHEAP_MODULE_FIXTURES or f"{os.path.basename(where)}::{name}" in _CHEAP_MODULE_FIXTURES:
            continue
        if where.endswith(".py"):
            own = own or item.nodeid.startswith(where)
        elif defs[-1].scope == "session" and os.path.basename(where) == "tests":
            shared.append(name)
    if shared:
        return "shared:" + min(shared)
    return os.path.basename(str(item.path)) if own else None


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    rank = {name: k for k, name in enumerate(sorted(_FILE_CPU_S, key=lambda n: -_FILE_CPU_S[n]))}
    items.sort(key=lambda it: (rank.get(os.path.basename(str(it.path)), len(rank)), str(it.path)))
    if getattr(config.option, "loadgroup", False):  # set on the workers by xdist under --dist loadgroup
        try:
            from _pytest.nodeid import NodeId  # noqa: PLC0415  pytest 9's structured test id; only under xdist
        except ImportError:  # pytest 8: xdist's own renaming of ``item._nodeid`` works
            NodeId = None  # noqa: N806

        for it in items:
            mark = it.get_closest_marker("xdist_group")
            if mark is None and (group := _group_of(it)) is not None:
                it.add_marker(pytest.mark.xdist_group(group))
                mark = it.get_closest_marker("xdist_group")
            if mark is not None and NodeId is not None and "@" not in it.nodeid:
                # Name the group in the test's id (``<id>@<group>``, what the controller schedules
                # by), as xdist's loadgroup does after this hook: it sets ``item._nodeid``, which
                # pytest 9 no longer reads (the id is ``item._id``), so without this every test
                # was scheduled alone and each worker built every module fixture it met.
                name = mark.args[0] if mark.args else mark.kwargs.get("name", "default")
                it._id = NodeId.parse(f"{it.nodeid}@{name}")
