"""The tiers of the suite: an unmarked test that starts a process fails, naming itself and the process.

The root ``conftest.py`` and ``pyproject.toml`` (copied as they are) run a small suite
in a fresh pytest process: each way of starting a process from an unmarked test (subprocess in its
body, multiprocessing, ``os.fork``, ``os.system``, a fixture's set-up, a thread of the test that the
test waits on) must fail that test with the message once it ends. The start itself is never refused
(a marker file each child writes is there): a refusal raised in the thread that starts the process
left a test waiting on that thread asleep for good. A test marked ``slow`` starts its process and
passes, and a numerical test passes.
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SUITE = '''
import multiprocessing
import os
import queue
import subprocess
import sys
import threading

import pytest

TOUCH = [sys.executable, "-c", "import pathlib, sys; pathlib.Path(sys.argv[1]).touch()"]


def _touch(path):
    open(path, "w").close()


@pytest.fixture
def server(tmp_path):
    subprocess.Popen([*TOUCH, str(tmp_path.parent / "fixture.started")]).wait()
    yield


def test_subprocess(tmp_path):
    subprocess.run([*TOUCH, str(tmp_path.parent / "subprocess.started")], check=True)


def test_multiprocessing(tmp_path):
    p = multiprocessing.get_context("spawn").Process(target=_touch, args=(str(tmp_path.parent / "mp.started"),))
    p.start()
    p.join()


def test_fork():
    pid = os.fork()
    if pid == 0:
        os._exit(0)
    os.waitpid(pid, 0)


def test_system(tmp_path):
    os.system(f"touch {tmp_path.parent / 'system.started'}")


def test_fixture(server):
    pass


def test_thread(tmp_path):
    done = queue.Queue()

    def start():
        subprocess.run([*TOUCH, str(tmp_path.parent / "thread.started")], check=True)
        done.put("started")

    threading.Thread(target=start, daemon=True).start()
    assert done.get(timeout=120) == "started"  # the thread was not interrupted: no wait for ever


@pytest.mark.slow
def test_marked(tmp_path):
    subprocess.run([*TOUCH, str(tmp_path.parent / "marked.started")], check=True)


def test_numbers():
    assert sum(range(5)) == 10
'''


@pytest.mark.slow
def test_unmarked_process_fails_after_the_test_never_in_its_thread(pytester):
    pytester.makeconftest((ROOT / "conftest.py").read_text())
    pytester.makepyprojecttoml((ROOT / "pyproject.toml").read_text())  # the marker's registration
    pytester.makepyfile(test_suite=SUITE)
    base = pytester.path / "tmp"
    # without hypothesis' plugin: the small suite has no property-based test, and importing hypothesis
    # was ~1.2 s of the fresh pytest's ~2 s of CPU
    r = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-p", "no:hypothesispytest", f"--basetemp={base}",
                                      "-rfE", timeout=600)
    out = r.stdout.str()
    r.assert_outcomes(passed=2, failed=5, errors=1)
    for name, what in [("test_subprocess", "subprocess: "), ("test_multiprocessing", "multiprocessing: "),
                       ("test_fork", "os.fork"), ("test_system", "os.system: touch"),
                       ("test_fixture", "subprocess: "), ("test_thread", "subprocess: ")]:
        assert f"test_suite.py::{name} started a child process ({what}" in out, (name, out)
    assert "ERROR test_suite.py::test_fixture" in out, out  # the set-up that started it errs
    assert out.count("is not marked slow: add @pytest.mark.slow") >= 6
    started = sorted(p.name for p in base.glob("*.started"))
    assert started == ["fixture.started", "marked.started", "mp.started", "subprocess.started", "system.started",
                       "thread.started"], started


class _Item:
    """What the root conftest's ordering reads of a collected test: its file and its ``slow`` mark."""

    def __init__(self, path, k, slow):
        self.path, self.k, self.slow = path, k, slow

    def get_closest_marker(self, name):
        return object() if name == "slow" and self.slow else None


def _root_conftest():
    import importlib.util

    spec = importlib.util.spec_from_file_location("root_conftest_under_test", ROOT / "conftest.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


#: file -> (number of tests, holds a slow test), in collection order
FILES = {"a": (5, False), "b": (40, True), "c": (3, False), "d": (17, False), "e": (8, True), "f": (30, False),
         "g": (1, True), "h": (22, False), "i": (12, False)}


@pytest.mark.parametrize("workers, expected", [
    # dealt by hand: the slow files b, e, g, then the others, each to the share with fewest tests so far
    (1, "b e g a c d f h i"),
    (2, "b h i  e g a c d f"),      # shares of 74 and 68 tests
    (3, "b  e d h  g a c f i"),     # shares of 40, 47 and 51 tests
])
def test_order_deals_whole_files_slow_first_in_equal_shares(monkeypatch, workers, expected):
    """xdist's worksteal hands each worker a contiguous share of the list first: the order deals the
    files whole into one share per worker (the next file to the share with fewest tests), the files
    holding a ``slow`` test first; within a file, collection order."""
    items = [_Item(Path(f"tests/test_{name}.py"), k, slow and k % 2 == 0)
             for name, (n, slow) in FILES.items() for k in range(n)]
    monkeypatch.setenv("PYTEST_XDIST_WORKER_COUNT", str(workers))
    _root_conftest().pytest_collection_modifyitems(None, items)
    order = [it.path.stem[5:] for it in items]
    assert order == [f for f in expected.split() for _ in range(FILES[f][0])]
    assert all(items[j].k == items[j - 1].k + 1 for j in range(1, len(items)) if items[j].path == items[j - 1].path)
