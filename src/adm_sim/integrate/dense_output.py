"""Dense output of the RK4 stepper: the largest midspan acceleration between two steps."""

from __future__ import annotations

import numpy as np


def hermite_max_abs_acc(d0, v0, a0, d1, v1, a1, h):
    """Largest |acceleration| strictly inside a step from its dense output; 0 where there is none.

    Over one step ``[t_k, t_k + h]`` the midspan deflection, velocity and acceleration are known
    at both ends from the state (``d = phi q``, ``v = phi q'``, ``a = phi q''``, the stage-0
    derivative of Eq. 15 or Eq. 12). The quintic Hermite interpolant of the deflection through
    these six values (error O(h^6), so O(h^4) in its second derivative, the order of RK4 itself)
    has as second derivative the cubic in ``s = (t - t_k) / h``

        a(s) = a0 + c1 s + c2 s^2 + c3 s^3,  with D = (d1 - d0) / h^2, V0 = v0 / h, V1 = v1 / h,
        c1 =   60 D - 36 V0 - 24 V1 -  9 a0 +  3 a1,
        c2 = -180 D + 96 V0 + 84 V1 + 18 a0 - 12 a1,
        c3 =  120 D - 60 V0 - 60 V1 - 10 a0 + 10 a1,

    (a(1) = a1). Its interior extrema are the roots of ``a'(s) = c1 + 2 c2 s + 3 c3 s^2`` in
    (0, 1), found in closed form (the cancellation-free quadratic formula). The numba kernels use
    the same arithmetic (:func:`adm_sim.integrate.kernels.hermite_max_abs_acc`).

    Parameters
    ----------
    d0, v0, a0, d1, v1, a1 : ndarray (n_lanes,)
        Deflection (m), velocity (m/s), acceleration (m/s^2) at the start and the end of the step.
    h : ndarray (n_lanes,)
        Time step (s).

    Returns
    -------
    ndarray (n_lanes,)
        ``max |a(s)|`` over the interior extrema, 0 where ``a`` is monotone on the step (the ends
        are sampled anyway).
    """
    D = (d1 - d0) / (h * h)
    V0 = v0 / h
    V1 = v1 / h
    c1 = 60.0 * D - 36.0 * V0 - 24.0 * V1 - 9.0 * a0 + 3.0 * a1
    c2 = -180.0 * D + 96.0 * V0 + 84.0 * V1 + 18.0 * a0 - 12.0 * a1
    c3 = 120.0 * D - 60.0 * V0 - 60.0 * V1 - 10.0 * a0 + 10.0 * a1
    A, B, C = 3.0 * c3, 2.0 * c2, c1
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = B * B - 4.0 * A * C
        sq = np.sqrt(np.where(disc >= 0.0, disc, 0.0))
        q = np.where(B >= 0.0, -0.5 * (B + sq), -0.5 * (B - sq))
        quad = (A != 0.0) & (disc >= 0.0) & (q != 0.0)
        lin = (A == 0.0) & (B != 0.0)
        s1 = np.where(quad, q / A, np.where(lin, -C / B, -1.0))
        s2 = np.where(quad, C / q, -1.0)
    best = np.zeros(np.shape(s1))
    for s in (s1, s2):
        inside = (s > 0.0) & (s < 1.0)
        val = np.abs(a0 + s * (c1 + s * (c2 + s * c3)))
        best = np.where(inside & (val > best), val, best)
    return best
