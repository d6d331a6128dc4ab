"""Root test configuration: stable numbers and timings on a 2-core machine, local-only DDS."""

import glob
import importlib.util
import os
import subprocess
import sys

import pytest

pytest_plugins = ("pytester",)  # tests/house/test_tiers.py runs the root conftest on a small suite

# Pin BLAS threads before numpy is imported anywhere (numbers and timings stay stable).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# Never let DDS leave this machine: shared-memory transport only, localhost discovery.
os.environ.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "SHM")
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("MPLBACKEND", "Agg")
# No first-run compile notice on stderr in tests (they compare stderr line by line; a fresh clone
# compiles numba's kernels in whichever test comes first). tests/house/test_imports.py tests the notice.
os.environ.setdefault("ADM_SIM_QUIET_COMPILE", "1")


# --- tiers: a test that starts a process is marked ``slow`` ---------------------------------------
# ``pytest -m "not slow"`` is the developer's loop (the numerical and input tests). A test without the
# marker that starts a child process (subprocess, multiprocessing, os.fork/system/posix_spawn), in its
# body, in a thread of it, or in the set-up or tear-down of a fixture it uses, fails with a message
# naming the test and the process. The start itself is never refused: the guard only records it, and
# the test's report is failed after the phase ends (``pytest_runtest_makereport``). Raising inside
# the call that starts the process would land in whatever thread made it (a dask cluster starting its
# workers, a launcher's reader thread), and a test waiting on that thread could hang its worker.
# Marked tests and the collection's own hooks are not watched.

_watched = None  # node id of the unmarked test in its set-up, call or tear-down, else None
_started = {}    # node id -> the first process it started while unmarked


def _record(what):
    nodeid = _watched
    if nodeid is None:
        return
    _started.setdefault(nodeid, (f"{nodeid} started a child process ({what}) but is not marked slow: add "
                                 "@pytest.mark.slow to the test (or pytestmark = pytest.mark.slow to its file) "
                                 "so that 'pytest -m \"not slow\"' keeps to the numerical and input tests"))


def _describe(args):
    if isinstance(args, (str, bytes, os.PathLike)):
        return os.fsdecode(args)[:200]
    return " ".join(os.fsdecode(a) if isinstance(a, (str, bytes, os.PathLike)) else str(a) for a in args)[:200]


_wrapped = []   # (owner, attribute, original): what the guard replaced, put back at the end


def _wrap(owner, name, describe):
    orig = getattr(owner, name)

    def guarded(*args, **kw):
        if _watched is not None:
            try:
                what = describe(*args, **kw)
            except Exception:  # an unusual call form: name the function alone
                what = name
            _record(what)
        return orig(*args, **kw)

    setattr(owner, name, guarded)
    _wrapped.append((owner, name, orig))


def _install_process_guard():
    """Wrap every way a test can start a process so that :func:`_record` sees it first."""
    import multiprocessing.process  # noqa: PLC0415  only to wrap its start
    import multiprocessing.util  # noqa: PLC0415  only to wrap its spawn

    if _wrapped:
        return
    _wrap(subprocess.Popen, "_execute_child", lambda self, args, *_, **__: f"subprocess: {_describe(args)}")
    _wrap(multiprocessing.process.BaseProcess, "start",
          lambda self: f"multiprocessing: {self.name}, target {getattr(self, '_target', None)!r}")
    # the helpers multiprocessing starts without a Process (its resource tracker, a forkserver)
    _wrap(multiprocessing.util, "spawnv_passfds", lambda path, args, *_: f"multiprocessing: {_describe(args)}")
    _wrap(os, "fork", lambda: "os.fork")
    _wrap(os, "forkpty", lambda: "os.forkpty")
    _wrap(os, "system", lambda command: f"os.system: {_describe(command)}")
    _wrap(os, "posix_spawn", lambda path, argv, *_, **__: f"os.posix_spawn: {_describe(argv)}")
    _wrap(os, "posix_spawnp", lambda path, argv, *_, **__: f"os.posix_spawnp: {_describe(argv)}")


def pytest_unconfigure(config):
    while _wrapped:
        owner, name, orig = _wrapped.pop()
        setattr(owner, name, orig)


def _watch(item):
    global _watched
    _watched = None if item is None or item.get_closest_marker("slow") else item.nodeid


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item):
    _watch(item)
    yield
    _watch(None)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    _watch(item)
    yield
    _watch(None)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item, nextitem):
    _watch(item)
    yield
    _watch(None)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """The phase that started a process unmarked fails (a passed set-up becomes an error, a passed
    call or tear-down a failure); a phase that failed already carries the message as a section."""
    report = (yield).get_result()
    msg = _started.pop(item.nodeid, None)
    if msg is None:
        return
    if report.passed:
        report.outcome = "failed"
        report.longrepr = msg
    else:
        report.sections.append(("slow marker", msg))


# --- optional per-test CPU cost (``ADM_SIM_TEST_CPU_LOG=path``) ----------------------------------
# Wall time on a shared machine says little; the CPU a test costs (this process and the children
# it waited for) does. Each test appends "nodeid<TAB>cpu_s<TAB>wall_s<TAB>worker<TAB>start_s" (the xdist
# worker, "main" without one; the start in seconds since the epoch, for a timeline of the workers:
# idle gaps, waits on a shared fixture, the tail) to the file named; the
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
        c0, t0, start = _cpu_s(), time.perf_counter(), time.time()
        yield
        with open(_CPU_LOG, "a") as fh:
            fh.write(f"{item.nodeid}\t{_cpu_s() - c0:.3f}\t{time.perf_counter() - t0:.3f}\t"
                     f"{os.environ.get('PYTEST_XDIST_WORKER', 'main')}\t{start:.3f}\n")


# --- the suite on two workers (``python -m pytest -n 2``, .ci/run) --------------------------------
# Public pytest and xdist options only:
#
# 1. ``--dist worksteal`` (``addopts`` in pyproject.toml): each worker starts with its share of the
#    tests (a contiguous run of the list) and, when it runs dry, takes the later half of what another
#    still has queued. A file mostly stays on one worker (its module fixtures are built once), and no cost
#    table is needed to keep a worker from idling at the end.
# 2. The order (``pytest_collection_modifyitems``): the files are dealt into one share per worker,
#    of about equal numbers of tests, and in each share the files that hold ``slow`` tests (processes,
#    waits on the ROS graph) come first. So each worker starts on its costly files, and the end of the
#    run, where the workers steal from each other's tails, is made of short tests. Files stay whole:
#    a module-scoped fixture is built once.
# 3. A session fixture that starts processes (a recorded crossing, a calibration launch) is built
#    once per run, not once per worker (tests/conftest.py, ``once_per_run``: the recipe of xdist's
#    documentation, a file lock in the folder the workers share).
# 4. Numba compiles each kernel on its first call and keeps it in ``src/adm_sim/integrate/__pycache__``.
#    In a fresh clone that is about 35 s of CPU, paid by every process that calls a kernel before
#    the cache holds it: both workers at once, and every command-line subprocess a test starts
#    early. So the controller compiles the kernels once, before the workers start, on both cores
#    in parallel (``adm-sim compile``'s code paths, split in two), and every later process loads
#    the cache.

ROOT = os.path.dirname(os.path.abspath(__file__))


def _xdist_controller(config):
    return bool(config.getoption("numprocesses", None)) and not hasattr(config, "workerinput")


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
_KERNEL_DIR = os.path.join(ROOT, "src", "adm_sim", "integrate")


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
        src = os.path.join(_KERNEL_DIR, f"{mod}.py")
        idx = glob.glob(os.path.join(_KERNEL_DIR, "__pycache__", f"{mod}.*.nbi"))
        if not os.path.exists(src) or not idx or min(os.path.getmtime(i) for i in idx) < os.path.getmtime(src):
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


def _warm_font_cache():
    """Build matplotlib's font list once, before any test runs, when it is not there (a fresh machine).

    matplotlib builds it at its first font lookup and runs ``fc-list`` to do so: in whichever test
    plots first, which the process guard above then reports as that test starting a process. The
    cache's folder is matplotlib's own rule (``MPLCONFIGDIR``, else ``$XDG_CACHE_HOME`` or ``~/.cache``,
    then ``matplotlib``); when in doubt the list is built (about a second, once)."""
    if importlib.util.find_spec("matplotlib") is None:
        return
    folder = os.environ.get("MPLCONFIGDIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "matplotlib")
    if glob.glob(os.path.join(folder, "fontlist-v*.json")):
        return
    subprocess.run([sys.executable, "-c", "import matplotlib.font_manager"], cwd=ROOT, stdin=subprocess.DEVNULL,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)


def pytest_configure(config):
    _install_process_guard()
    if not hasattr(config, "workerinput") and not config.getoption("collectonly"):
        _warm_font_cache()  # the controller of an xdist run, or the one process of a plain run
    if _xdist_controller(config) and not config.getoption("collectonly"):
        _compile_bytecode()
        if os.environ.get("ADM_SIM_TEST_PRECOMPILE", "1") != "0" and not _kernels_cached():
            _precompile_kernels()


@pytest.hookimpl(wrapper=True)
def pytest_collection(session):
    """Let pytest keep its assertion-rewritten test modules (``__pycache__/*-pytest-*.pyc``) while it
    collects. It writes them only when ``sys.dont_write_bytecode`` is off (``PYTHONDONTWRITEBYTECODE``, set
    on this machine, turns it on) but reads them either way: without them every worker rewrites the asserts
    of all 144 test modules at each run (a collecting process took 9.4-11.6 s without them and 3.6-4.6 s
    reading them, measured 2026-12-07). pytest writes them atomically, for concurrent runs; the flag is put back
    after the collection, so the tests run under the user's setting."""
    before = sys.dont_write_bytecode
    sys.dont_write_bytecode = False
    try:
        return (yield)
    finally:
        sys.dont_write_bytecode = before


def pytest_collection_modifyitems(config, items):
    """Deal the files into one share per worker (``--dist worksteal`` hands each worker one
    contiguous share of the list first), of about equal numbers of tests, the files holding ``slow``
    tests first in each share; files stay whole and in collection order otherwise. Without xdist:
    one share, the ``slow`` files first."""
    files = {}
    for it in items:
        files.setdefault(it.path, []).append(it)
    slow = [f for f in files.values() if any(it.get_closest_marker("slow") for it in f)]
    fast = [f for f in files.values() if not any(it.get_closest_marker("slow") for it in f)]
    n = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
    shares = [[[], [], 0] for _ in range(n)]  # (slow files, other files, number of tests)
    for kind, group in ((0, slow), (1, fast)):
        for f in group:
            share = min(shares, key=lambda s: s[2])
            share[kind].append(f)
            share[2] += len(f)
    items[:] = [it for s in shares for f in s[0] + s[1] for it in f]
