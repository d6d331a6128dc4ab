"""Work bounded before it starts (issue 38 item 1): the work limit, the memory estimate, a
MemoryError and an address-space limit as one line each.

The estimates are checked against closed forms: the work is lanes x steps x modes with the steps
of :func:`adm_sim.integrate.step_grid.make_grid` (travel / ds); the DIM tables of a
:class:`~adm_sim.integrate.compiled_batch.BatchRunner` against the bytes its tables really take.
"""

from __future__ import annotations

import math
import os
import resource
import subprocess
import sys

import numpy as np
import pytest

from adm_sim import limits
from adm_sim.cliutil import run_cli
from adm_sim.errors import EXIT_RUN, InputError
from adm_sim.integrate.compiled_batch import BatchRunner
from adm_sim.integrate.step_grid import make_grid
from adm_sim.model.bridge import named_bridge
from adm_sim.inputs.train_files import load_train


def test_work_is_lanes_times_steps_times_modes(monkeypatch):
    """The work of a grid is n_lanes x n_steps x n_modes, refused one unit beyond the limit and
    accepted at it (the limit from ADM_SIM_MAX_WORK)."""
    b, t = named_bridge("B1"), load_train("ICE-2")
    v = np.array([200.0, 250.0, 300.0]) / 3.6
    grid = make_grid(b, t.length_m, v)
    work = 3 * grid.n_steps * b.n_modes
    t_top = 2 * math.pi / b.omega_rad_s[-1]
    ds = v.min() * t_top / 16.0
    assert grid.n_steps == math.ceil((t.length_m + b.span_m + 2.0 / b.n0_hz * v.max()) / ds)
    monkeypatch.setenv(limits.WORK_ENV, str(work))
    make_grid(b, t.length_m, v)
    monkeypatch.setenv(limits.WORK_ENV, str(work - 1))
    with pytest.raises(InputError, match=rf"^work: 3 lanes x {grid.n_steps} steps x 3 modes = {work} is beyond "
                                         rf"the work limit {work - 1} \(the project's choice; raise it with "
                                         r"--max-work or ADM_SIM_MAX_WORK\); large because 3 speeds x"):
        make_grid(b, t.length_m, v)


def test_dim_table_estimate_bounds_the_tables_built():
    """The estimate of the DIM tables is an upper bound of what they take, within 2.5x (measured 2.04x
    on B1 x ICE-2: every row is counted with its Eq. 13 inverses, and rows share them)."""
    b, t = named_bridge("B1"), load_train("ICE-2")
    r = BatchRunner([b, b], t, 0.05)
    n = 3000
    r._dim_tables(n)
    real = sum(a.nbytes for a in r._axle_rows) + sum(a.nbytes for a in r._track)
    est = r.table_bytes("dim", n)
    assert real <= est <= 2.5 * real, (real, est)


def test_tables_beyond_the_memory_are_refused(monkeypatch):
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 1e6)
    r = BatchRunner([named_bridge("B1")], load_train("ICE-2"), 0.05)
    with pytest.raises(InputError, match=r"^memory: the DIM tables of 3000 steps would take [0-9.]+ MiB; this machine "
                                         r"has 977 KiB available \(a run may take 80% of it\); large because 3000 "
                                         r"steps of ds = 50 mm x 3 modes x 1 bridges"):
        r._dim_tables(3000)


def test_memory_error_is_one_line_exit_1(capsys):
    def work():
        raise MemoryError("Unable to allocate 28.8 GiB for an array with shape (3, 1290000000)")
    assert run_cli(work) == EXIT_RUN
    err = capsys.readouterr().err
    assert err.startswith("error: out of memory: Unable to allocate 28.8 GiB for an array") and err.count("\n") == 1


def _under_address_space(kib):
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (kib * 1024, resource.RLIM_INFINITY))
    return limit


@pytest.mark.slow
@pytest.mark.parametrize("kib,code,words", [
    (400_000, 0, "status ok: every wheel stays on the rail"),  # spun forever in OpenBLAS's start-up before
    (300_000, 1, "error: out of memory: Unable to allocate"),
])
def test_a_small_address_space_says_so_in_one_line(tmp_path, kib, code, words):
    """``ulimit -v 400000``: the DIM sweep runs (one BLAS thread); ``ulimit -v 300000``: one line
    naming the limit, exit 1; never a spin (the timeout) or a traceback."""
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    r = subprocess.run([sys.executable, "-m", "adm_sim.cli.sim_commands", "sweep", "--model", "dim", "--speeds",
                        "200,250", "--steps-per-period", "8"], capture_output=True, text=True, timeout=120,
                       preexec_fn=_under_address_space(kib), env=env, cwd=tmp_path)
    assert r.returncode == code, r.stderr
    assert "Traceback" not in r.stderr
    if code == 0:
        assert words in r.stdout
    else:
        lines = r.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith(words), r.stderr
        assert f"address-space limit of {kib * 1024 / 2**20:.0f} MB (ulimit -v {kib})" in lines[0]


def test_counts_are_printed_with_a_sensible_precision():
    from adm_sim.fields import count_text

    assert count_text(2160001) == "2160001"
    assert count_text(9.6e301) == "9.6e+301"
    assert count_text(96 * 10**300) == "9.6e+301"  # a 302-digit int, as --speed-step 1e-300 gave
    assert count_text(1282.75) == "1282.75"
