"""Exact modes of a continuous Euler-Bernoulli beam over 1-6 spans on pinned supports.

The deck is spans ``i = 0 .. N-1`` of length ``L_i``, bending stiffness ``EJ_i`` and mass per length
``mu_i``, continuous over pinned intermediate supports (no settlement), pinned at both abutments.
In span ``i`` a mode of circular frequency omega satisfies ``EJ_i w'''' = mu_i omega^2 w``, so with
``beta_i = (mu_i omega^2 / EJ_i)^(1/4)`` and the local abscissa ``xi`` (0 at the left support of the
span)::

    w(xi) = c0 sin(beta xi) + c1 cos(beta xi) + c2 exp(-beta xi) + c3 exp(-beta (L - xi))

(the hyperbolic part written with decaying exponentials, so no term overflows or cancels for large
``beta L``). This is the exact solution of the beam equation in every span: the modes are exact,
not a finite-element or series approximation.

**Frequencies: the Wittrick-Williams count.** With the translations held at every support, the
unknowns are the rotations ``theta_0 .. theta_N`` of the N + 1 supports. A span's end moments
follow from its end rotations through its exact dynamic stiffness (``lambda = beta L``)::

    k_ii = EJ beta (sin l - cos l tanh l) / (sech l - cos l)     (diagonal)
    k_ij = EJ beta (tanh l - sin l sech l) / (sech l - cos l)    (carry-over)

(4 EJ / L and 2 EJ / L at omega -> 0). The assembled tridiagonal ``K(omega)`` is singular at a
natural frequency; the number of natural frequencies below omega is ``J(omega) = sum_i J0_i +
s{K(omega)}`` (Wittrick and Williams, 1971): ``s`` the number of negative pivots of ``K``,
``J0_i`` the number of clamped-clamped frequencies of span i below omega. Bisection on ``J``
brackets every mode, however close the clusters of equal spans lie (N modes per cluster), to
1e-14 relative: no mode is missed or found twice.

**Shapes, normalisation, modal masses.** At a root, the rotations are the null vector of
``K(omega_j)``; each span's coefficients then follow from ``w = 0`` at both its ends and its two end
rotations. Every shape is scaled to ``max |phi| = 1`` over the deck with ``phi'(0) > 0`` (one span:
exactly ``sin(j pi x / L)``, paper Eq. 4). The modal mass ``M_j = sum_i mu_i int phi_j^2`` (Eq. 5)
is integrated per span by Gauss-Legendre quadrature with more points than the shape has half-waves
(exact to round-off for these smooth integrands).

**Mode count.** The rule ``adm-sim check`` applies (every mode up to 30 Hz, 1.5 n0 or the third
mode, whichever is higher; docs/check.md names its clause) or an explicit count (the readers
of :mod:`adm_sim.inputs` hold the counts a user may give to the field registry's range).

Limits: linear elastic, no shear deformation or rotary inertia, rigid point supports, pinned at
both abutments, simple (not repeated) natural frequencies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: The mode-count rule's frequency floor (Hz) and its factor on n0.
RULE_FREQ_HZ = 30.0
RULE_N0_FACTOR = 1.5
RULE_MIN_MODES = 3
#: Relative width to which bisection brackets a natural frequency.
_FREQ_RTOL = 1e-14

RULE_TEXT = "every mode up to 30 Hz, 1.5 n0 or the third mode, whichever is higher (the rule of adm-sim check)"


# ---------------------------------------------------------------------- one span
def span_rotation_stiffness(EJ_Nm2, mu_kg_m, L_m, omega_rad_s):
    """Exact dynamic stiffness of one span with its end translations held: ``(k_ii, k_ij)`` (N m/rad).

    End moments ``m_a = k_ii theta_a + k_ij theta_b``, ``m_b = k_ij theta_a + k_ii theta_b``.
    """
    beta = (mu_kg_m * omega_rad_s**2 / EJ_Nm2) ** 0.25
    lam = beta * L_m
    if lam < 1e-3:  # static limit (the closed forms cancel below this)
        return 4.0 * EJ_Nm2 / L_m, 2.0 * EJ_Nm2 / L_m
    s, c, t = math.sin(lam), math.cos(lam), math.tanh(lam)
    sech = 1.0 / math.cosh(lam) if lam < 700.0 else 0.0
    den = sech - c
    return EJ_Nm2 * beta * (s - c * t) / den, EJ_Nm2 * beta * (t - s * sech) / den


def clamped_count(lam):
    """Number of clamped-clamped frequencies of a span below ``lam = beta L`` (roots of
    ``cos l cosh l = 1``, l > 0), the ``J0`` of the Wittrick-Williams count."""
    i = int(lam // math.pi)
    sech = 1.0 / math.cosh(lam) if lam < 700.0 else 0.0
    sg = 1.0 if sech - math.cos(lam) > 0.0 else -1.0  # sign of 1 - cos l cosh l
    return i - int((1 - (-1) ** i * sg) // 2)


# ---------------------------------------------------------------------- the deck
@dataclass(frozen=True)
class DeckModes:
    """The exact modes of a continuous deck (see the module docstring).

    Attributes
    ----------
    spans_m, EJ_Nm2, mu_kg_m : ndarray (n_spans,)
    supports_m : ndarray (n_spans + 1,)
        Support abscissae from the left abutment (m).
    omega_rad_s : ndarray (n_modes,)
    modal_mass_kg : ndarray (n_modes,)
        ``sum_i mu_i int phi_j^2`` (Eq. 5) for ``max |phi_j| = 1``.
    beta_1_m : ndarray (n_modes, n_spans)
        Wave numbers ``(mu_i omega_j^2 / EJ_i)^(1/4)`` (1/m).
    coef : ndarray (n_modes, n_spans, 4)
        Coefficients of ``sin, cos, exp(-beta xi), exp(-beta (L - xi))`` per mode and span.
    """

    spans_m: np.ndarray
    EJ_Nm2: np.ndarray
    mu_kg_m: np.ndarray
    supports_m: np.ndarray
    omega_rad_s: np.ndarray
    modal_mass_kg: np.ndarray
    beta_1_m: np.ndarray
    coef: np.ndarray

    @property
    def n_modes(self):
        return self.omega_rad_s.size

    @property
    def length_m(self):
        return float(self.supports_m[-1])

    @property
    def frequencies_hz(self):
        return self.omega_rad_s / (2.0 * math.pi)

    def shapes(self, x_m):
        """``(phi, phi_x, phi_xx)`` at abscissae ``x_m`` from the left abutment, each of shape
        ``x_m.shape + (n_modes,)`` (1, 1/m, 1/m^2); zero off the deck ``[0, length]``."""
        x = np.asarray(x_m, dtype=float)
        shape = x.shape
        x = x.reshape(-1)
        out = [np.zeros((x.size, self.n_modes)) for _ in range(3)]
        span = np.searchsorted(self.supports_m, x, side="right") - 1
        span[x == self.supports_m[-1]] = self.spans_m.size - 1
        on = (x >= 0.0) & (x <= self.supports_m[-1])
        for i in range(self.spans_m.size):
            sel = np.flatnonzero(on & (span == i))
            if sel.size == 0:
                continue
            xi = (x[sel] - self.supports_m[i])[:, None]
            b, L, c = self.beta_1_m[None, :, i], self.spans_m[i], self.coef[None, :, i, :]
            sn, cs = np.sin(b * xi), np.cos(b * xi)
            e0, e1 = np.exp(-b * xi), np.exp(-b * (L - xi))
            out[0][sel] = c[..., 0] * sn + c[..., 1] * cs + c[..., 2] * e0 + c[..., 3] * e1
            out[1][sel] = b * (c[..., 0] * cs - c[..., 1] * sn - c[..., 2] * e0 + c[..., 3] * e1)
            out[2][sel] = b * b * (-c[..., 0] * sn - c[..., 1] * cs + c[..., 2] * e0 + c[..., 3] * e1)
        return tuple(o.reshape(shape + (self.n_modes,)) for o in out)

    def phi(self, x_m):
        """The mode shapes alone at abscissae ``x_m`` (n_x,) on the deck ``[0, length]``, shape
        (n_x, n_modes): :meth:`shapes`' first array, without the derivatives (the MLM's loads)."""
        x = np.asarray(x_m, dtype=float)
        span = np.clip(np.searchsorted(self.supports_m, x, side="right") - 1, 0, self.spans_m.size - 1)
        xi = (x - self.supports_m[span])[:, None]
        b = self.beta_1_m.T[span]  # (n_x, n_modes)
        c = self.coef.transpose(1, 0, 2)[span]  # (n_x, n_modes, 4)
        bx = b * xi
        e0 = np.exp(-bx)
        e1 = np.exp(-b * self.spans_m[span][:, None]) / e0  # exp(-beta (L - xi)), one exp fewer
        return c[..., 0] * np.sin(bx) + c[..., 1] * np.cos(bx) + c[..., 2] * e0 + c[..., 3] * e1

    def table(self, points_per_span=256):
        """The shapes as tables on a space grid: ``(x_m, phi, phi_x, phi_xx)``, ``x_m`` (n_x,) the
        supports and ``points_per_span - 1`` equal steps inside every span, the shapes (n_x, n_modes)."""
        xs = [self.supports_m[i] + self.spans_m[i] * np.arange(points_per_span) / points_per_span
              for i in range(self.spans_m.size)]
        x = np.concatenate(xs + [self.supports_m[-1:]])
        return (x,) + self.shapes(x)


def _global_stiffness(spans, EJ, mu, omega):
    """Diagonal (n+1,) and off-diagonal (n,) of ``K(omega)`` and the clamped count ``sum J0``."""
    n = spans.size
    diag, off, j0 = np.zeros(n + 1), np.zeros(n), 0
    for i in range(n):
        kii, kij = span_rotation_stiffness(EJ[i], mu[i], spans[i], omega)
        diag[i] += kii
        diag[i + 1] += kii
        off[i] = kij
        j0 += clamped_count((mu[i] * omega**2 / EJ[i]) ** 0.25 * spans[i])
    return diag, off, j0


def count_below(spans, EJ, mu, omega):
    """Number of natural frequencies of the deck below ``omega`` (rad/s): ``sum J0 + s{K}``."""
    diag, off, j0 = _global_stiffness(spans, EJ, mu, omega)
    neg, d = 0, diag[0]
    for i in range(off.size + 1):
        if i:
            d = diag[i] - off[i - 1] ** 2 / d
        neg += d < 0.0
    return int(j0 + neg)


def natural_frequencies_rad_s(spans, EJ, mu, n_modes):
    """The lowest ``n_modes`` circular frequencies (rad/s) by bisection on :func:`count_below`."""
    spans, EJ, mu = (np.asarray(a, dtype=float) for a in (spans, EJ, mu))
    # every mode j lies at or above the lowest simply supported frequency of the stiffest-lightest span
    w_lo = min((math.pi / L) ** 2 * math.sqrt(e / m) for L, e, m in zip(spans, EJ, mu)) * 0.5
    out = np.empty(n_modes)
    lo_prev = w_lo
    for j in range(1, n_modes + 1):
        lo, hi = lo_prev, max(lo_prev, w_lo) * 2.0
        while count_below(spans, EJ, mu, hi) < j:
            lo, hi = hi, 2.0 * hi
        while hi - lo > _FREQ_RTOL * hi:
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if count_below(spans, EJ, mu, mid) >= j:
                hi = mid
            else:
                lo = mid
        out[j - 1] = 0.5 * (lo + hi)
        lo_prev = lo
    return out


def _span_coefficients(L, beta, theta_a, theta_b):
    """Coefficients of w on one span with ``w = 0`` at both ends and end rotations theta_a, theta_b."""
    lam = beta * L
    e = math.exp(-lam)
    s, c = math.sin(lam), math.cos(lam)
    A = np.array([[0.0, 1.0, 1.0, e],
                  [beta, 0.0, -beta, beta * e],
                  [s, c, e, 1.0],
                  [beta * c, -beta * s, -beta * e, beta]])
    return np.linalg.solve(A, np.array([0.0, theta_a, 0.0, theta_b]))


def _null_rotations(spans, EJ, mu, omega):
    diag, off, _ = _global_stiffness(spans, EJ, mu, omega)
    K = np.diag(diag) + np.diag(off, 1) + np.diag(off, -1)
    scale = np.abs(diag).max()
    w, v = np.linalg.eigh(K / scale)
    return v[:, np.argmin(np.abs(w))]


def deck_modes(spans_m, EJ_Nm2, mu_kg_m, n_modes):
    """:class:`DeckModes` of the lowest ``n_modes`` modes of the deck (see the module docstring).

    ``spans_m``, ``EJ_Nm2``, ``mu_kg_m``: one value per span (the readers at the edge check them).
    """
    spans, EJ, mu = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (spans_m, EJ_Nm2, mu_kg_m))
    n = spans.size
    supports = np.concatenate([[0.0], np.cumsum(spans)])
    omega = natural_frequencies_rad_s(spans, EJ, mu, n_modes)
    beta = (mu[None, :] * omega[:, None] ** 2 / EJ[None, :]) ** 0.25
    coef = np.zeros((n_modes, n, 4))
    for j in range(n_modes):
        if n == 1:  # the one span: its rotations are equal and opposite (symmetric) or equal
            th = np.array([1.0, math.cos(beta[j, 0] * spans[0])])
        else:
            th = _null_rotations(spans, EJ, mu, omega[j])
        for i in range(n):
            coef[j, i] = _span_coefficients(spans[i], beta[j, i], th[i], th[i + 1])
    raw = DeckModes(spans, EJ, mu, supports, omega, np.ones(n_modes), beta, coef)
    scale = _max_abs(raw)
    slope0 = raw.shapes(np.array([0.0]))[1][0]
    coef *= (np.sign(slope0) / scale)[:, None, None]
    shaped = DeckModes(spans, EJ, mu, supports, omega, np.ones(n_modes), beta, coef)
    return DeckModes(spans, EJ, mu, supports, omega, _modal_masses(shaped), beta, coef)


def _max_abs(modes):
    """``max |phi_j|`` over the deck per mode: the largest of a grid (32 points per half-wave),
    refined by Newton on ``phi' = 0`` from the grid's best point."""
    half_waves = modes.beta_1_m * modes.spans_m[None, :] / math.pi
    per_span = int(32 * max(4.0, float(half_waves.max()) + 1.0))
    x, phi, _, _ = modes.table(per_span)
    best = np.empty(modes.n_modes)
    for j in range(modes.n_modes):
        k = int(np.argmax(np.abs(phi[:, j])))
        xk = x[k]
        lo, hi = x[max(k - 1, 0)], x[min(k + 1, x.size - 1)]
        for _ in range(8):
            _, p1, p2 = (a[..., j] for a in modes.shapes(np.array([xk])))
            if p2[0] == 0.0:
                break
            xn = xk - p1[0] / p2[0]
            if not lo <= xn <= hi:
                break
            xk = xn
        best[j] = max(abs(phi[k, j]), abs(modes.shapes(np.array([xk]))[0][0, j]))
    return best


def gauss_points(modes):
    """Gauss-Legendre abscissae (m) and weights times mu (kg) over the whole deck, enough points
    per span for the shapes' half-waves: ``sum w f(x)`` = ``sum_i mu_i int f``."""
    xs, ws = [], []
    for i in range(modes.spans_m.size):
        lam = float(modes.beta_1_m[:, i].max()) * modes.spans_m[i]
        g, w = np.polynomial.legendre.leggauss(int(40 + 2 * lam))
        L = modes.spans_m[i]
        xs.append(modes.supports_m[i] + 0.5 * L * (g + 1.0))
        ws.append(0.5 * L * w * modes.mu_kg_m[i])
    return np.concatenate(xs), np.concatenate(ws)


def _modal_masses(modes):
    x, w = gauss_points(modes)
    phi = modes.shapes(x)[0]
    return (w[:, None] * phi**2).sum(axis=0)


# ---------------------------------------------------------------------- mode count
def rule_limit_hz(n0_hz):
    """Frequency up to which the rule keeps every mode: ``max(30 Hz, 1.5 n0)`` (the third mode is
    kept on top, :func:`rule_mode_count`)."""
    return max(RULE_FREQ_HZ, RULE_N0_FACTOR * n0_hz)


def rule_mode_count(spans_m, EJ_Nm2, mu_kg_m):
    """Modes the rule asks for: every mode up to ``max(30 Hz, 1.5 n0)``, at least three."""
    spans, EJ, mu = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (spans_m, EJ_Nm2, mu_kg_m))
    n0 = natural_frequencies_rad_s(spans, EJ, mu, 1)[0] / (2.0 * math.pi)
    return max(RULE_MIN_MODES, int(count_below(spans, EJ, mu, 2.0 * math.pi * rule_limit_hz(n0) * (1.0 + 1e-12))))
