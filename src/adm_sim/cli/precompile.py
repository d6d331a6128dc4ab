"""Compile every numba kernel of the package once, ahead of the first real run (``adm-sim compile``).

The kernels (:mod:`adm_sim.integrate.envelope`: the exact MLM envelope of ``sweep`` and ``check``;
:mod:`adm_sim.integrate.kernels`: the compiled RK4 lanes of the DIM and MLM sweeps, of the calibration and
of the study) carry ``cache=True``: numba compiles a kernel on its first call for the argument
types it meets and keeps the machine code in ``__pycache__`` beside the source. A fresh checkout
therefore pays the compiler (15-60 s on a 2-core machine) in its first command. :func:`compile_kernels`
pays it at set-up instead: it runs each code path on a tiny case (two speeds, one short train
where the physics allows), so every kernel meets the argument types of the real runs and the
next command only loads the cache. Where numba has the cache already, this loads it (well under
a second per path) and compiles nothing.

The tiny cases are the commands' own code paths (:func:`adm_sim.integrate.sweep.sweep_exact`,
:func:`adm_sim.integrate.sweep.run_sweep_compiled`, :func:`adm_sim.design.check.run_check`), not hand-built
signatures, so a kernel whose arguments change is still compiled here; ``tests/house/test_imports.py``
checks that a sweep and a check after :func:`compile_kernels` add no signature to any kernel.
"""

from __future__ import annotations

import time

import numpy as np

from adm_sim.model.bridge import named_bridge
from adm_sim.design.check import resolve_trains, run_check
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep_compiled, sweep_exact
from adm_sim.inputs.train_files import load_train


def _paths():
    """(name, callable) of every code path that calls a kernel, each on a tiny case."""
    b1 = named_bridge("B1")
    ice2 = load_train("ICE-2")
    speeds = np.array([250.0, 300.0])
    coarse = StepOptions(steps_per_period=4.0, free_vibration_periods=0.5)
    return [
        ("exact MLM envelope, midspan and a point", lambda: (sweep_exact(b1, ice2, speeds),
                                                             sweep_exact(b1, ice2, speeds, where=5.0))),
        ("exact MLM envelope, whole deck", lambda: sweep_exact(b1, ice2, speeds, where="deck")),
        ("compiled DIM lanes", lambda: run_sweep_compiled(b1, ice2, "dim", speeds, options=coarse)),
        ("compiled MLM lanes", lambda: run_sweep_compiled(b1, ice2, "mlm", speeds, options=coarse)),
        ("EN 1991-2 check", lambda: run_check(b1, 150.0, resolve_trains("HSLM-A1,ICE-2"), step_kmh=1.0)),
    ]


def compile_kernels(report=None):
    """Compile (or load from numba's cache) every kernel the commands call.

    Parameters
    ----------
    report : callable(name, seconds), optional
        Called after each code path with its name and wall time.

    Returns
    -------
    float
        Total wall time (s).
    """
    t_all = time.perf_counter()
    for name, run in _paths():
        t0 = time.perf_counter()
        run()
        if report is not None:
            report(name, time.perf_counter() - t0)
    return time.perf_counter() - t_all
