"""What the numpy stepper and the numba kernels share, written once.

* The classical RK4 tableau (nodes ``c`` and weights ``b`` of the explicit fourth-order
  Runge-Kutta method used for Eq. (17), see :mod:`adm_sim.rk4_sides`), as tuples for the numpy
  stepper and as arrays for the compiled kernels (:mod:`adm_sim.kernels`), and the half-step row
  of each stage point on the shared space grid.
* :func:`njit`: numba's ``njit`` when numba is installed, else a decorator that returns the
  function unchanged, so the same source runs as plain Python (slow, for debugging). numba is
  imported only when a module decorates a function with it (:mod:`adm_sim.kernels`,
  :mod:`adm_sim.envelope`), not by importing this module: the numpy stepper and the ROS nodes
  start without loading numba.
"""

from __future__ import annotations

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


def njit(*args, **kwargs):
    """``numba.njit`` if numba is installed, else the identity decorator (same arguments)."""
    try:
        from numba import njit as numba_njit
    except ImportError:  # pragma: no cover - numba is a declared dependency
        if args and callable(args[0]):
            return args[0]
        return lambda f: f
    return numba_njit(*args, **kwargs)
