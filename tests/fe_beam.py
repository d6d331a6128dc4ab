"""An independent reference for continuous decks, written for the tests: a finite-element beam.

Hermite cubic Euler-Bernoulli elements (two DOFs per node, deflection and rotation), each with its
consistent mass matrix ``mu h / 420 [...]`` and stiffness ``EJ / h^3 [...]``, assembled over every
span and pinned (deflection held) at every support. No modes, no modal truncation: the tests use
its eigenvalues (:func:`fe_frequencies_rad_s`) and its direct time integration under moving loads
(:func:`fe_moving_loads`, Newmark average acceleration on the full system with Rayleigh damping).
Nothing here comes from :mod:`adm_sim`.
"""

from __future__ import annotations

import bisect

import numpy as np
import scipy.linalg


def element_matrices(EJ, mu, h):
    """Stiffness and consistent mass of one Hermite cubic element of length h."""
    k = EJ / h**3 * np.array([[12, 6 * h, -12, 6 * h],
                              [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                              [-12, -6 * h, 12, -6 * h],
                              [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    m = mu * h / 420.0 * np.array([[156, 22 * h, 54, -13 * h],
                                   [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                   [54, 13 * h, 156, -22 * h],
                                   [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    return k, m


class FEBeam:
    """The deck of spans ``spans`` (m), ``EJ`` (N m^2), ``mu`` (kg/m), ``n_el`` elements per span."""

    def __init__(self, spans, EJ, mu, n_el):
        spans, EJ, mu = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (spans, EJ, mu))
        nodes = [0.0]
        el_EJ, el_mu = [], []
        for L, e, m in zip(spans, EJ, mu):
            nodes += list(nodes[-1] + L * np.arange(1, n_el + 1) / n_el)
            el_EJ += [e] * n_el
            el_mu += [m] * n_el
        self.x = np.array(nodes)
        self._nodes = self.x.tolist()  # for bisect in load_vector
        n = 2 * self.x.size
        K, M = np.zeros((n, n)), np.zeros((n, n))
        for e in range(self.x.size - 1):
            k, m = element_matrices(el_EJ[e], el_mu[e], self.x[e + 1] - self.x[e])
            d = slice(2 * e, 2 * e + 4)
            K[d, d] += k
            M[d, d] += m
        supports = np.concatenate([[0], np.cumsum(np.full(spans.size, n_el))])
        held = 2 * supports
        self.free = np.setdiff1d(np.arange(n), held)
        self.K = K[np.ix_(self.free, self.free)]
        self.M = M[np.ix_(self.free, self.free)]
        self.n_dof_all = n

    def frequencies_rad_s(self, n):
        d = 1.0 / np.sqrt(np.diag(self.K))  # scaled to a unit diagonal: fewer digits lost
        w2 = scipy.linalg.eigh(self.K * np.outer(d, d), self.M * np.outer(d, d), eigvals_only=True,
                               subset_by_index=[0, n - 1])
        return np.sqrt(w2)

    def load_vector(self, x_load, forces):
        """Consistent nodal loads (free DOFs) of point forces ``forces`` at ``x_load`` (off deck: none)."""
        f = np.zeros(self.n_dof_all)
        x = self.x
        for xp, p in zip(x_load, forces):
            if not (x[0] <= xp <= x[-1]):
                continue
            e = min(bisect.bisect_right(self._nodes, xp) - 1, x.size - 2)  # np.searchsorted(x, xp, "right") - 1
            h = x[e + 1] - x[e]
            s = (xp - x[e]) / h
            f[2 * e] += p * (1 - 3 * s**2 + 2 * s**3)
            f[2 * e + 1] += p * (h * (s - 2 * s**2 + s**3))
            f[2 * e + 2] += p * (3 * s**2 - 2 * s**3)
            f[2 * e + 3] += p * (h * (-s**2 + s**3))
        return f[self.free]

    def deflection_at(self, u_free, x):
        """Deflection (m) at ``x`` from the free DOF vector (Hermite interpolation)."""
        u = np.zeros(self.n_dof_all)
        u[self.free] = u_free
        e = min(int(np.searchsorted(self.x, x, side="right")) - 1, self.x.size - 2)
        h = self.x[e + 1] - self.x[e]
        s = (x - self.x[e]) / h
        N = np.array([1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3, h * (-s**2 + s**3)])
        return N @ u[2 * e:2 * e + 4]

    def interp_row(self, x):
        """Row vector r with ``r @ u_free`` the deflection at x."""
        r = np.zeros(self.n_dof_all)
        e = min(int(np.searchsorted(self.x, x, side="right")) - 1, self.x.size - 2)
        h = self.x[e + 1] - self.x[e]
        s = (x - self.x[e]) / h
        r[2 * e:2 * e + 4] = [1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3, h * (-s**2 + s**3)]
        return r[self.free]


def fe_moving_loads(beam, axle_offsets_m, axle_loads_n, speed_m_s, dt_s, t_end_s, rayleigh_ab, x_out_m):
    """Direct Newmark (average acceleration) integration of ``M u'' + C u' + K u = f(t)``,
    ``C = a M + b K``, the deck at rest at t = 0 with the first axle at the left abutment; axle i at
    ``v t - offset_i``. Returns ``(t, w, acc)`` at ``x_out_m``: deflection (m) and acceleration (m/s^2)."""
    a, b = rayleigh_ab
    M, K = beam.M, beam.K
    C = a * M + b * K
    n_steps = int(round(t_end_s / dt_s))
    gamma, beta = 0.5, 0.25
    Keff = K + gamma / (beta * dt_s) * C + M / (beta * dt_s**2)
    lu, piv = scipy.linalg.lu_factor(Keff)
    # LAPACK's getrs, as scipy.linalg.lu_solve calls it, without that wrapper's per-call checks
    # (the same arithmetic; the loop below runs some 10^4-10^5 times)
    getrs = scipy.linalg.get_lapack_funcs("getrs", (lu,))
    offs, loads = np.asarray(axle_offsets_m, float), np.asarray(axle_loads_n, float)
    r = beam.interp_row(x_out_m)
    u = np.zeros(M.shape[0])
    v = np.zeros_like(u)
    f0 = beam.load_vector(-offs, loads)
    acc = scipy.linalg.solve(M, f0 - C @ v - K @ u, assume_a="pos")
    t = np.arange(n_steps + 1) * dt_s
    w_out, a_out = np.empty(n_steps + 1), np.empty(n_steps + 1)
    w_out[0], a_out[0] = r @ u, r @ acc
    bdt2, bdt, c_acc = beta * dt_s**2, beta * dt_s, 0.5 / beta - 1  # Newmark's constants, once
    g_bdt, c_v, c_a = gamma / (beta * dt_s), gamma / beta - 1, dt_s * (0.5 * gamma / beta - 1)
    for k in range(1, n_steps + 1):
        f = beam.load_vector(speed_m_s * t[k] - offs, loads)
        rhs = f + M @ (u / bdt2 + v / bdt + c_acc * acc) + C @ (g_bdt * u + c_v * v + c_a * acc)
        un, info = getrs(lu, piv, rhs)
        assert info == 0
        an = (un - u) / bdt2 - v / bdt - c_acc * acc
        vn = v + dt_s * ((1 - gamma) * acc + gamma * an)
        u, v, acc = un, vn, an
        w_out[k], a_out[k] = r @ u, r @ acc
    return t, w_out, a_out


def _hermite(beam, x):
    """Free-DOF rows of the deflection, slope and curvature at x (Hermite cubic of its element)."""
    rows = np.zeros((3, beam.n_dof_all))
    e = min(int(np.searchsorted(beam.x, x, side="right")) - 1, beam.x.size - 2)
    h = beam.x[e + 1] - beam.x[e]
    s = (x - beam.x[e]) / h
    rows[0, 2 * e:2 * e + 4] = [1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3, h * (-s**2 + s**3)]
    rows[1, 2 * e:2 * e + 4] = np.array([-6 * s + 6 * s**2, h * (1 - 4 * s + 3 * s**2), 6 * s - 6 * s**2,
                                         h * (-2 * s + 3 * s**2)]) / h
    rows[2, 2 * e:2 * e + 4] = np.array([-6 + 12 * s, h * (-4 + 6 * s), 6 - 12 * s, h * (-2 + 6 * s)]) / h**2
    return rows[:, beam.free]


def fe_moving_masses(beam, axle_offsets_m, axle_loads_n, masses_kg, speed_m_s, dt_s, t_end_s, rayleigh_ab, x_out_m):
    """Direct Newmark integration of the deck carrying moving masses in permanent contact: each mass
    m_i rides at ``v t - offset_i`` with its static load P_i and acts on the deck with
    ``P_i - m_i (w'' t-derivatives along its path) = P_i - m_i (w_tt + 2 v w_xt + v^2 w_xx)``, so the
    coupled system ``(M + sum m n n^T) u'' + (C + sum 2 m v n n'^T) u' + (K + sum m v^2 n n''^T) u =
    sum P n`` changes with the positions (assembled and solved at every step). Returns ``(t, w, acc)``
    at ``x_out_m``."""
    a_r, b_r = rayleigh_ab
    M, K = beam.M, beam.K
    C = a_r * M + b_r * K
    n_steps = int(round(t_end_s / dt_s))
    gamma, beta = 0.5, 0.25
    offs, loads, ms = (np.asarray(a, float) for a in (axle_offsets_m, axle_loads_n, masses_kg))
    v = speed_m_s
    r_out = beam.interp_row(x_out_m)

    def matrices(t):
        Mw, Cw, Kw, f = M.copy(), C.copy(), K.copy(), np.zeros(M.shape[0])
        for off, p, m in zip(offs, loads, ms):
            x = v * t - off
            if not (beam.x[0] <= x <= beam.x[-1]):
                continue
            n, n1, n2 = _hermite(beam, x)
            Mw += m * np.outer(n, n)
            Cw += 2 * m * v * np.outer(n, n1)
            Kw += m * v * v * np.outer(n, n2)
            f += p * n
        return Mw, Cw, Kw, f

    u = np.zeros(M.shape[0])
    ud = np.zeros_like(u)
    Mw, Cw, Kw, f = matrices(0.0)
    acc = np.linalg.solve(Mw, f - Cw @ ud - Kw @ u)
    t = np.arange(n_steps + 1) * dt_s
    w_out, a_out = np.empty(n_steps + 1), np.empty(n_steps + 1)
    w_out[0], a_out[0] = r_out @ u, r_out @ acc
    for k in range(1, n_steps + 1):
        Mw, Cw, Kw, f = matrices(t[k])
        A = Kw + gamma / (beta * dt_s) * Cw + Mw / (beta * dt_s**2)
        rhs = (f + Mw @ (u / (beta * dt_s**2) + ud / (beta * dt_s) + (0.5 / beta - 1) * acc)
               + Cw @ (gamma / (beta * dt_s) * u + (gamma / beta - 1) * ud + dt_s * (0.5 * gamma / beta - 1) * acc))
        un = np.linalg.solve(A, rhs)
        an = (un - u) / (beta * dt_s**2) - ud / (beta * dt_s) - (0.5 / beta - 1) * acc
        ud = ud + dt_s * ((1 - gamma) * acc + gamma * an)
        u, acc = un, an
        w_out[k], a_out[k] = r_out @ u, r_out @ acc
    return t, w_out, a_out
