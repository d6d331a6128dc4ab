"""``adm-sim``'s own command line skips the interpreter's last garbage collections at exit
(:func:`adm_sim.cliutil.freeze_at_exit`); a ``main([...])`` called inside a process that goes on does not."""

import subprocess
import sys

import pytest

#: A cyclic object whose finalizer says when the shutdown's collection reached it, then adm-sim's main.
SCRIPT = """
import sys
class Cycle:
    def __del__(self):
        print("collected", flush=True)
c = Cycle()
c.me = c
del c
import gc
gc.disable()  # only the shutdown's collections may reach the cycle
from adm_sim.cli.sim_commands import main
sys.argv = ["adm-sim", "bridges"]
code = main(None if MODE == "command line" else ["bridges"])
print("exit", code, flush=True)
"""


@pytest.mark.slow
@pytest.mark.parametrize("mode, collected", [("command line", False), ("in process", True)])
def test_the_command_line_leaves_cycles_to_the_system(mode, collected):
    """The command line (``main()`` reading ``sys.argv``): the cycle is not finalized at exit; ``main(argv)``:
    the shutdown collects it as before. Both print the bridges and exit 0."""
    p = subprocess.run([sys.executable, "-c", f"MODE = {mode!r}\n" + SCRIPT], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    assert "B1" in p.stdout and "exit 0" in p.stdout
    assert ("collected" in p.stdout) is collected, p.stdout[-300:]
