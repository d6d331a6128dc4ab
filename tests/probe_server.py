"""A server of fresh-looking Python processes for the import probes (tests/house/test_imports.py,
tests/house/test_launcher_imports.py): a probe asks which modules a command loads, so it needs a
process that has imported nothing of the project and none of the heavy libraries.

For each request line (code, argv, environment, working directory, output files) the server forks
a child that runs the code as ``python -c code *argv`` would, as ``__main__``, and answers its exit
code. The server itself imports the standard library and numpy only (every command imports numpy
first) and refuses to serve if any of the heavy modules it is given or any module of the project is
loaded: a child starts as a fresh probe interpreter would, less ~0.2 s of CPU (start-up and numpy)
each.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

FORK_SERVER = """
import json, os, sys, traceback, types
import numpy
bad = [m for m in sys.modules if m in json.loads(sys.argv[1]) or m.split('.')[0] in ('adm_sim', 'adm_calib')]
print(json.dumps(bad), flush=True)
for line in sys.stdin:
    req = json.loads(line)
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
            os.dup2(os.open(req["stdout"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC), 1)
            os.dup2(os.open(req["stderr"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC), 2)
            os.environ.clear()
            os.environ.update(req["env"])
            os.chdir(req["cwd"])
            sys.argv = ["-c", *req["argv"]]
            main = types.ModuleType("__main__")
            sys.modules["__main__"] = main
            exec(compile(req["code"], "<string>", "exec"), main.__dict__)
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:
            traceback.print_exc()
        finally:  # the end of an interpreter: non-daemon threads joined, atexit handlers run
            try:
                if "threading" in sys.modules:
                    sys.modules["threading"]._shutdown()
                import atexit
                atexit._run_exitfuncs()
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code)
    print(json.dumps(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])), flush=True)
"""


class ProbeServer:
    """One server (started at the first probe, in a session of its own) for the modules in
    ``heavy`` (none of them may be loaded in the server); :meth:`stop` it at the end of the module
    that uses it."""

    def __init__(self, heavy, src):
        self.heavy, self.src, self.proc = tuple(heavy), str(src), None

    def stop(self):
        """End the server (its stdin closed: it exits after its last child); killed if it hangs."""
        if self.proc is not None:
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
            self.proc = None

    def _answer(self, timeout):
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if not ready:
            os.killpg(self.proc.pid, signal.SIGKILL)   # the server and a probe still running
            pytest.fail(f"no answer from the probe server within {timeout} s")
        return json.loads(self.proc.stdout.readline())

    def probe(self, code, *argv, env, cwd=None, timeout=600):
        """``python -c code *argv`` with ``env`` (its PYTHONPATH must be this checkout's src) in a
        forked child of the server: ``CompletedProcess`` with the exit code and the output."""
        assert env["PYTHONPATH"] == self.src
        if self.proc is None:
            self.proc = subprocess.Popen([sys.executable, "-c", FORK_SERVER, json.dumps(self.heavy)],
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                         env=dict(os.environ, PYTHONPATH=self.src), start_new_session=True)
            bad = self._answer(120)
            if bad:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
                self.proc = None
                pytest.fail(f"the probe server started with heavy or project modules loaded: {bad}")
        with tempfile.TemporaryDirectory() as d:
            out, err = Path(d) / "stdout", Path(d) / "stderr"
            self.proc.stdin.write(json.dumps({"code": code, "argv": list(argv), "env": env,
                                              "cwd": str(cwd or os.getcwd()), "stdout": str(out),
                                              "stderr": str(err)}) + "\n")
            self.proc.stdin.flush()
            rc = self._answer(timeout)
            return subprocess.CompletedProcess([sys.executable, "-c", code, *argv], rc, out.read_text(),
                                               err.read_text())
