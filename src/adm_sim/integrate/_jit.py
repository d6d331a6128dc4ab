"""What the numpy stepper and the numba kernels share, written once.

* The classical RK4 tableau (nodes ``c`` and weights ``b`` of the explicit fourth-order
  Runge-Kutta method used for Eq. (17), see :mod:`adm_sim.integrate.rk4_sides`), as tuples for the numpy
  stepper and as arrays for the compiled kernels (:mod:`adm_sim.integrate.kernels`), and the half-step row
  of each stage point on the shared space grid.
* :func:`njit`: numba's ``njit`` when numba is installed, else a decorator that returns the
  function unchanged, so the same source runs as plain Python (slow, for debugging). numba is
  imported only when a module decorates a function with it (:mod:`adm_sim.integrate.kernels`,
  :mod:`adm_sim.integrate.envelope`), not by importing this module: the numpy stepper and the ROS nodes
  start without loading numba. A compiled function whose on-disk cache cannot be written (a full
  disk, ``ulimit -f``) runs from memory and is compiled again next time; the run goes on.
* The first-run notice: every kernel is compiled with ``cache=True``, so numba compiles it once
  (15-60 s for all of them on a 2-core machine) and keeps the machine code in ``__pycache__``
  beside the source; later processes load it (well under a second). Before a process compiles a
  kernel of this package (no cache yet, or the source changed), it prints :data:`COMPILE_NOTICE`
  on stderr, once per process, so a user is not left waiting in silence; ``adm-sim compile``
  (:mod:`adm_sim.cli.precompile`) compiles everything ahead, at set-up. ``ADM_SIM_QUIET_COMPILE=1``
  silences the line (the test suite sets it: tests compare stderr line by line).
"""

from __future__ import annotations

import importlib.util
import os
import sys

import numpy as np

#: RK4 nodes c_i (fraction of the step at which stage i is evaluated).
RK4_C = (0.0, 0.5, 0.5, 1.0)
#: RK4 weights b_i.
RK4_W = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)
#: The same tables as arrays (numba reads global arrays as constants).
RK4_C_ARRAY = np.array(RK4_C)
RK4_W_ARRAY = np.array(RK4_W)
#: Half-step row offset of each RK stage: stage points s_k, s_k + ds/2 (twice), s_k + ds.
STAGE_ROW = np.array([int(round(2.0 * c)) for c in RK4_C])


#: What a process prints on stderr before it compiles the first kernel of this package.
COMPILE_NOTICE = ("compiling kernels (once): {name} and the kernels it calls; numba keeps them in its cache "
                  "(__pycache__ beside the source) and later runs load them (all kernels: 15-60 s on a quiet 2-core "
                  "machine; 'adm-sim compile' does it ahead)")
#: Environment variable that silences :data:`COMPILE_NOTICE` (any value but "" and "0").
QUIET_ENV = "ADM_SIM_QUIET_COMPILE"
_LISTENERS: list = []  # the one compile listener of this process, once registered
_SAID: list[bool] = []  # not empty once the notice has been given in this process


def notice_given():
    """Mark the first-run notice as given (``adm-sim compile`` prints its own line first)."""
    _SAID.append(True)


def numba_available():
    """Whether numba is installed (else :func:`njit` leaves functions as plain Python); found
    without importing it."""
    return importlib.util.find_spec("numba") is not None


def njit(*args, **kwargs):
    """``numba.njit`` if numba is installed, else the identity decorator (same arguments)."""
    try:
        import numba.core.event  # noqa: PLC0415  numba loads only with the kernels that need it
    except ImportError:  # pragma: no cover - numba is a declared dependency
        if args and callable(args[0]):
            return args[0]
        return lambda f: f
    _listen_for_compiles(numba.core.event)
    if args and callable(args[0]):
        return _cache_may_fail(numba.njit(*args, **kwargs))
    decorate = numba.njit(*args, **kwargs)
    return lambda f: _cache_may_fail(decorate(f))


def _cache_may_fail(dispatcher):
    """``dispatcher`` whose cache, when it cannot be saved (OSError: no space, file too large, a
    read-only folder), is skipped: the compiled code is used from memory."""
    cache = getattr(dispatcher, "_cache", None)
    save = getattr(cache, "save_overload", None)
    if save is not None:
        def save_overload(sig, data):
            try:
                save(sig, data)
            except OSError:
                pass

        cache.save_overload = save_overload
    return dispatcher


def _listen_for_compiles(event):
    """Register (once) the numba event listener that prints :data:`COMPILE_NOTICE` (``event``:
    the module ``numba.core.event``).

    numba fires ``numba:compile`` only when it compiles, after a cache miss (loading a cached kernel
    fires nothing), so the line appears exactly when a user waits for the compiler.
    """
    if _LISTENERS:
        return

    class _CompileNotice(event.Listener):
        def on_start(self, ev):
            py_func = getattr(ev.data.get("dispatcher"), "py_func", None)
            module = getattr(py_func, "__module__", "") or ""
            if _SAID or not module.startswith("adm_sim") or os.environ.get(QUIET_ENV, "") not in ("", "0"):
                return
            notice_given()
            print(COMPILE_NOTICE.format(name=f"{module}.{py_func.__name__}"), file=sys.stderr, flush=True)

        def on_end(self, ev):
            pass

    _LISTENERS.append(_CompileNotice())
    event.register("numba:compile", _LISTENERS[0])
