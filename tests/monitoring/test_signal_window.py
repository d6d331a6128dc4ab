"""A signal at the end of a command is never a death by the signal nor a traceback.

:func:`adm_sim.cliutil.run_cli` maps SIGINT/SIGTERM during the work to ``error: interrupted``, 130.
At the end of the work (its last line, the release of its claims) and on the way out of the process
(after ``run_cli`` returned) a signal is still ``error: interrupted`` and 130, or the run's own
result when the signal came too late to matter: never ``-15`` (the default SIGTERM death) and never
a ``KeyboardInterrupt`` traceback. Each case runs a small command in a subprocess and signals it
as its work ends, many times over.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: The command: its work prints 'done' and returns; then 'returned' once run_cli is back, and a
#: slow way out (threads joined, modules torn down). The way out lasts EXIT_S: a signal that reaches
#: the interpreter's own finalization (after Python's handlers are gone) is a death by it, which no
#: Python code can prevent; a loaded machine delays the test's signal by seconds (a run of the suite
#: at load 10-16 took 3.4 s to deliver it, past a 3 s way out). The signal ends the way out (short
#: sleeps: Python runs a handler between them, where a signal taken just before one long sleep
#: began waited for its end, about 1 run in 200), so a long way out costs nothing when the signal is on time.
EXIT_S = 20.0
#: The command starts as a terminal starts it, SIGINT raising KeyboardInterrupt: a run of the suite
#: in the background of a non-interactive shell (``pytest ... &``) hands its children SIGINT
#: ignored, and a way out that honours that ignores the test's SIGINT (exit 0 after the whole way
#: out). When the signal was already taken (the run ends 130), there is no way out to wait through.
_CMD = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)
from adm_sim.cliutil import run_cli

def work():
    print("done", flush=True)
    return 0

code = run_cli(work)
print("returned", flush=True)
if code == 0:  # in short sleeps: a signal taken just before a long sleep began would wait for its end
    for _ in range(int(float(sys.argv[1]) / 0.05)):
        time.sleep(0.05)
sys.exit(code)
"""


def _run(sig, wait_for, exit_s):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    p = subprocess.Popen([sys.executable, "-c", _CMD, str(exit_s)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=env)
    try:
        while True:
            line = p.stdout.readline()
            assert line, p.stderr.read()
            if line.strip() == wait_for:
                break
        p.send_signal(sig)
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    return p.returncode, err


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_after_run_cli_returned(sig):
    """On the way out (run_cli returned, the process not yet gone): 130 and one line."""
    code, err = _run(sig, "returned", EXIT_S)
    assert "Traceback" not in err, err
    assert code == 130, (code, err)
    assert err.splitlines() == ["error: interrupted"], err


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_as_the_work_ends(sig):
    """Signalled the moment the work printed its last line: the signal lands in the end of the
    work, in run_cli's release of the claims or on the way out; 8 times each. Wherever it lands the
    process is still running (its way out lasts EXIT_S), so it is always 130 and one line: never
    -15 (death by SIGTERM) nor -2, and never 0 (a signal lost: it once landed between run_cli's
    reading of the deferred mark and the end of its block, about 1 run in 40)."""
    for _ in range(8):
        code, err = _run(sig, "done", EXIT_S)
        assert "Traceback" not in err, err
        assert (code, err.splitlines()) == (130, ["error: interrupted"]), (code, err)


#: The command's work meets the signal inside a weakref callback (as the import machinery's module
#: locks have one): the handler's KeyboardInterrupt cannot propagate from there (Python prints
#: "Exception ignored ... Traceback" and runs on). ``landings`` callbacks in a row each take the
#: signal (sent from within the callback, so it lands there every time); the work then loops on
#: until it is interrupted, or says it was not within 30 s.
_LOST_CMD = """
import os, signal, sys, time, weakref
from adm_sim.cliutil import run_cli

class Thing:
    pass

landings = int(sys.argv[1])

def cb(ref):
    global landings
    if landings > 0:
        landings -= 1
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # the handler runs here, inside the callback
            pass

def work():
    t_end = time.monotonic() + 30
    while time.monotonic() < t_end:
        thing = Thing()
        ref = weakref.ref(thing, cb)
        del thing
    print("not interrupted", file=sys.stderr)
    return 0

sys.exit(run_cli(work))
"""


@pytest.mark.slow
@pytest.mark.parametrize("landings", [1, 3])
def test_signal_landing_in_a_weakref_callback_still_interrupts_once(landings):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    r = subprocess.run([sys.executable, "-c", _LOST_CMD, str(landings)], capture_output=True, text=True, env=env,
                       timeout=120)
    assert (r.returncode, r.stderr) == (130, "error: interrupted\n")


def test_signal_within_a_held_block_is_raised_at_its_end():
    """A signal that the main thread's handler meets inside :func:`adm_sim.interrupts.held` (here
    tripped as if another thread had taken it, which a thread's signal mask cannot stop) does not
    cut the block: every step runs, then the one ``KeyboardInterrupt``."""
    import _thread

    from adm_sim.interrupts import held, raise_interrupt

    steps = []
    old = signal.signal(signal.SIGTERM, raise_interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            with held():
                _thread.interrupt_main(signal.SIGTERM)
                for i in range(1000):
                    steps.append(i)
        assert len(steps) == 1000
        with held():  # nothing pending is left: a later block ends quietly
            steps.append("later")
    finally:
        signal.signal(signal.SIGTERM, old)
    assert steps[-1] == "later"
