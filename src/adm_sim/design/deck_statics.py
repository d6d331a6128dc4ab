"""Static influence lines of a continuous beam and LM71 on them (EN 1991-2 on continuous decks).

The deck: spans ``i = 0 .. N-1`` of length ``L_i`` and bending stiffness ``EJ_i`` (Euler-Bernoulli),
continuous over pinned intermediate supports (no settlement), pinned at both abutments; the
supports stand at ``x_0 = 0 < x_1 < .. < x_N``. A unit downward force at ``u`` (m from the left
abutment).

**Support moments: the three-moment equation (Clapeyron).** Sagging positive; at every interior
support ``k = 1 .. N-1`` the slopes of the two spans meeting there agree::

    L_{k-1} / (6 EJ_{k-1}) M_{k-1} + (L_{k-1} / (3 EJ_{k-1}) + L_k / (3 EJ_k)) M_k + L_k / (6 EJ_k) M_{k+1}
        = -(theta_R0 of span k-1 + theta_L0 of span k),

``M_0 = M_N = 0``, the free end rotations of a simply supported span under a unit force at ``a``
from its left end (``b = L - a``): ``theta_L0 = a b (L + b) / (6 EJ L)``,
``theta_R0 = a b (L + a) / (6 EJ L)``. The matrix is symmetric, tridiagonal and positive definite.

**Effects by superposition** in span ``s`` (local abscissa ``xi``, length ``L``): the simply supported
span's effect of the force (if it stands in span s) plus the linear moment of the support moments:

* moment ``M(x) = M0 + M_s (1 - xi/L) + M_{s+1} xi/L``;
* shear ``V(x) = dM/dx = V0 + (M_{s+1} - M_s) / L`` (positive as the left reaction of a simply
  supported span: ``V0 = (L - a)/L`` for a force right of the section, ``-a/L`` left of it);
* reaction at support k: the right end shear of span k-1 plus the left end shear of span k;
* deflection (downward positive): the simply supported deflection plus
  ``xi (L - xi) [M_s (2 L - xi) + M_{s+1} (L + xi)] / (6 EJ L)``;
* end rotation at an abutment: ``theta_L0 + M_1 L_0 / (6 EJ_0)`` (left), likewise right.

Influence lines are cubic in ``u`` between the supports and the section (a kink or a jump at the
section), so the integrals of LM71's distributed load over their positive or negative parts are
exact by Gauss-Legendre (5 points per piece, exact to degree 9) between these breakpoints and the
roots of the line (found by bisection to 1e-13 of the span).

**LM71** (EN 1991-2 6.3.2, Fig. 6.2): four 250 kN point forces at 1.6 m and 80 kN/m distributed
outside their 6.4 m window, the distributed load only on the parts of the influence line of the
sign being maximised (the unfavourable parts; the point forces at any position of the group), times
α. The maximum over the position of the group: a grid of 0.05 m over the deck and every position
where a force or a window end crosses a breakpoint, then zoomed grids around the best grid points down to 1e-9 m.

numpy only; no ROS.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from adm_sim.design.design_loads import LM71_AXLE_LOAD_N, LM71_AXLES_M, LM71_HALF_WINDOW_M, LM71_UDL_N_M

#: Gauss-Legendre points per piece of an influence line (exact to degree 9; the pieces are cubic).
_GAUSS = np.polynomial.legendre.leggauss(5)
#: Grid step (m) of the LM71 group position before refinement.
LM71_GRID_M = 0.05


@dataclass(frozen=True)
class DeckEffect:
    """One static effect of a continuous deck: ``kind`` "M" (N m), "V" (N) at ``x_m``, "R" (N) at
    support ``support`` (0 .. N), "w" (m) at ``x_m``, "theta" (rad) at abutment ``support`` (0 or N)."""

    kind: str
    x_m: float
    support: int = -1
    label: str = ""


class ContinuousBeam:
    """Statics of a continuous beam over ``spans_m`` with ``EJ_Nm2`` per span (see the module doc)."""

    def __init__(self, spans_m, EJ_Nm2):
        self.spans = np.atleast_1d(np.asarray(spans_m, dtype=float))
        n = self.spans.size
        self.EJ = np.broadcast_to(np.asarray(EJ_Nm2, dtype=float), (n,)).astype(float)
        self.supports = np.concatenate([[0.0], np.cumsum(self.spans)])
        self.length = float(self.supports[-1])
        f = self.spans / (6.0 * self.EJ)  # L / (6 EJ) per span
        A = np.zeros((max(n - 1, 0), max(n - 1, 0)))
        for k in range(1, n):
            A[k - 1, k - 1] = 2.0 * (f[k - 1] + f[k])
            if k > 1:
                A[k - 1, k - 2] = f[k - 1]
            if k < n - 1:
                A[k - 1, k] = f[k]
        self._Ainv = np.linalg.inv(A) if n > 1 else np.zeros((0, 0))

    @property
    def n_spans(self):
        return self.spans.size

    def locate(self, x):
        """Span index and local abscissa of global positions ``x`` (the last span owns the deck's end)."""
        x = np.asarray(x, dtype=float)
        s = np.clip(np.searchsorted(self.supports, x, side="right") - 1, 0, self.n_spans - 1)
        return s, x - self.supports[s]

    def support_moments(self, u):
        """Support moments (N m per N, sagging positive), shape (len(u), N + 1), ends zero."""
        u = np.atleast_1d(np.asarray(u, dtype=float))
        s, a = self.locate(u)
        on = (u >= 0.0) & (u <= self.length)
        L, EJ = self.spans[s], self.EJ[s]
        b = L - a
        thL = np.where(on, a * b * (L + b) / (6.0 * EJ * L), 0.0)  # free rotation at the span's left end
        thR = np.where(on, a * b * (L + a) / (6.0 * EJ * L), 0.0)
        n = self.n_spans
        M = np.zeros((u.size, n + 1))
        if n == 1:
            return M
        rhs = np.zeros((u.size, n - 1))
        rows = np.arange(u.size)
        k_right = s  # the span's left support: interior index s (row s - 1) gets theta_L0
        ok = (k_right >= 1) & on
        rhs[rows[ok], k_right[ok] - 1] -= thL[ok]
        k_left = s + 1  # the span's right support gets theta_R0
        ok = (k_left <= n - 1) & on
        rhs[rows[ok], k_left[ok] - 1] -= thR[ok]
        M[:, 1:n] = rhs @ self._Ainv.T
        return M

    def moment(self, x, u):
        """Influence line of the bending moment at x (N m per N, sagging positive)."""
        return self.line(DeckEffect("M", float(x)), u)

    def shear(self, x, u):
        """Influence line of the shear at x (N per N); a force at the section counts as right of it."""
        return self.line(DeckEffect("V", float(x)), u)

    def deflection(self, x, u):
        """Influence line of the deflection at x (m per N, downward positive)."""
        return self.line(DeckEffect("w", float(x)), u)

    def reaction(self, k, u):
        """Influence line of the reaction at support k (N per N, upward positive)."""
        return self.line(DeckEffect("R", float(self.supports[k]), support=int(k)), u)

    def end_rotation(self, k, u):
        """Influence line of the rotation at abutment k (0 or N), rad per N, positive as the free span's."""
        return self.line(DeckEffect("theta", float(self.supports[k]), support=int(k)), u)

    def lines(self, effects, u):
        """Influence ordinates of every effect at force positions ``u``, shape (len(u), n_effects): the
        support moments solved once for all effects (the same formulas as :meth:`line`)."""
        u = np.atleast_1d(np.asarray(u, dtype=float))
        su, a = self.locate(u)
        on = (u >= 0.0) & (u <= self.length)
        M = self.support_moments(u)
        out = np.empty((u.size, len(effects)))
        for c, e in enumerate(effects):
            out[:, c] = self._line_from(e, su, a, on, M)
        return out

    def _line_from(self, e, su, a, on, M):
        """One effect's ordinates from the located forces and their support moments."""
        if e.kind in ("R", "theta"):
            k = e.support
            if e.kind == "R":
                out = np.zeros(a.size)
                if k < self.n_spans:
                    L = self.spans[k]
                    out += np.where(on & (su == k), (L - a) / L, 0.0) + (M[:, k + 1] - M[:, k]) / L
                if k > 0:
                    L = self.spans[k - 1]
                    out += np.where(on & (su == k - 1), a / L, 0.0) - (M[:, k] - M[:, k - 1]) / L
                return out
            i = 0 if k == 0 else self.n_spans - 1
            L, EJ = self.spans[i], self.EJ[i]
            b = L - a
            here = on & (su == i)
            if k == 0:
                return np.where(here, a * b * (L + b) / (6.0 * EJ * L), 0.0) + M[:, 1] * L / (6.0 * EJ)
            return np.where(here, a * b * (L + a) / (6.0 * EJ * L), 0.0) + M[:, -2] * L / (6.0 * EJ)
        s, xi = self.locate(np.array([e.x_m]))
        s, xi = int(s[0]), float(xi[0])
        L, EJ, Ma, Mb = self.spans[s], self.EJ[s], M[:, s], M[:, s + 1]
        here = on & (su == s)
        if e.kind == "M":
            m0 = np.where(a <= xi, a * (L - xi) / L, xi * (L - a) / L)
            return np.where(here, m0, 0.0) + Ma * (1.0 - xi / L) + Mb * xi / L
        if e.kind == "V":
            return np.where(here, np.where(a >= xi, (L - a) / L, -a / L), 0.0) + (Mb - Ma) / L
        if e.kind == "w":
            b = L - a
            w0 = np.where(a <= xi, a * (L - xi) * (L * L - a * a - (L - xi) ** 2),
                          xi * b * (L * L - xi * xi - b * b)) / (6.0 * EJ * L)
            return np.where(here, w0, 0.0) + xi * (L - xi) * (Ma * (2.0 * L - xi) + Mb * (L + xi)) / (6.0 * EJ * L)
        raise ValueError(f"effect kind {e.kind!r}")

    def line(self, effect, u):
        """Influence ordinates of a :class:`DeckEffect` at force positions ``u``, shape (len(u),)."""
        return self.lines([effect], u)[:, 0]

    def breakpoints(self, effect):
        """Abscissae where the influence line of ``effect`` is not smooth (supports, the section)."""
        bp = list(self.supports)
        if effect.kind in ("M", "V", "w"):
            bp.append(effect.x_m)
        return np.unique(bp)


# ---------------------------------------------------------------------- integrals of a line
def _roots(f, bp, n=64):
    """Roots of f between every pair of breakpoints ``bp``: the sign changes on a grid of n cells per
    piece, all bisected together to 1e-13 of the deck (one vectorised call of f per halving)."""
    a, b = bp[:-1], bp[1:]
    eps = 1e-12 * (bp[-1] - bp[0])
    x = (a[:, None] + eps) + (b - a - 2 * eps)[:, None] * np.linspace(0.0, 1.0, n + 1)[None, :]
    y = f(x.ravel()).reshape(x.shape)
    r, c = np.nonzero(np.sign(y[:, :-1]) * np.sign(y[:, 1:]) < 0.0)
    lo, hi, flo = x[r, c], x[r, c + 1], y[r, c]
    tol = 1e-13 * (bp[-1] - bp[0])
    while lo.size and np.max(hi - lo) > tol:
        mid = 0.5 * (lo + hi)
        fm = f(mid)
        same = np.sign(fm) == np.sign(flo)
        lo, flo, hi = np.where(same, mid, lo), np.where(same, fm, flo), np.where(same, hi, mid)
    return 0.5 * (lo + hi)


def signed_pieces(beam, effect):
    """The influence line of ``effect`` cut where it is not smooth or changes sign: sorted piece ends
    (m), the exact integral of every piece and its sign (+1, -1 or 0). Cached per beam and effect."""
    return _signed_pieces(beam, effect)


@functools.lru_cache(maxsize=512)
def _signed_pieces(beam, effect):
    def f(u):
        return beam.line(effect, u)

    bp = beam.breakpoints(effect)
    ends = np.unique(np.concatenate([bp, _roots(f, bp)]))
    g, w = _GAUSS
    mid = 0.5 * (ends[1:] + ends[:-1])
    half = 0.5 * (ends[1:] - ends[:-1])
    pts = mid[:, None] + half[:, None] * g[None, :]
    vals = f(pts.ravel()).reshape(pts.shape)
    integ = (vals * w[None, :]).sum(1) * half
    sign = np.sign(f(mid))
    return ends, integ, sign


def _partial_integral(beam, effect, pieces, lo, hi, sign):
    """Integral of the influence line over [lo, hi] (arrays) restricted to the pieces of ``sign`` (+1 or
    -1, or an array of them, one per interval: intervals of both signs in one call, each summed exactly
    as it would be alone).

    Each interval's sum runs over the pieces in order, adding a whole piece's integral or the
    Gauss-Legendre integral of the part of it the interval covers; the lines at the points of every
    part, of all pieces, are evaluated in one call first (a value at a point does not depend on the
    other points of the call), the sums then add them in the order of the pieces."""
    ends, integ, sgn = pieces
    lo = np.clip(np.asarray(lo, dtype=float), ends[0], ends[-1])
    hi = np.clip(np.asarray(hi, dtype=float), ends[0], ends[-1])
    sign = np.broadcast_to(np.asarray(sign), lo.shape)
    g, w = _GAUSS
    steps = []  # (intervals of the piece's sign, whole-piece mask among them, part mask, index of its points)
    points, n_points = [], 0
    for p in np.flatnonzero(sgn != 0):
        mine = sign == sgn[p]
        if not mine.any():
            continue
        a, b = ends[p], ends[p + 1]
        c0, c1 = np.maximum(lo, a), np.minimum(hi, b)
        full = (c0 <= a) & (c1 >= b)
        part = (c1 > c0) & ~full & mine
        k = int(np.count_nonzero(part))
        if k:
            m = 0.5 * (c0[part] + c1[part])
            h = 0.5 * (c1[part] - c0[part])
            points.append(m[:, None] + h[:, None] * g[None, :])
        steps.append((p, mine, full[mine], part, slice(n_points, n_points + k), h if k else None))
        n_points += k
    vals = beam.line(effect, np.concatenate(points).ravel()).reshape(-1, g.size) if points else None
    out = np.zeros(lo.shape)
    for p, mine, full, part, rows, h in steps:
        # only the intervals of this piece's sign take its integral (the others' sums are left untouched)
        out[mine] += np.where(full, integ[p], 0.0)
        if h is not None:
            out[part] += (vals[rows] * w[None, :]).sum(1) * h
    return out


@dataclass(frozen=True)
class LM71Max:
    """Largest |effect| of α x LM71 and where: ``value`` (N m, N, m or rad, α included), ``sign`` of the
    effect (+1 sagging / upward / downward as the line, -1 the other way), ``centre_m`` the position of
    the centre of the four point forces (m from the left abutment)."""

    value: float
    sign: int
    centre_m: float


def lm71_value(beam, effect, centre_m, sign, pieces=None):
    """The effect of LM71 (α = 1) with the group centred at ``centre_m`` (array), the distributed load on
    the parts of the line of ``sign`` outside the window: the signed value (times ``sign``: >= 0 when it
    acts that way). ``sign`` is +1 or -1, or an array of them, one per centre (both signs in one call)."""
    pieces = signed_pieces(beam, effect) if pieces is None else pieces
    d = np.atleast_1d(np.asarray(centre_m, dtype=float))
    sign = np.broadcast_to(np.asarray(sign), d.shape)
    c = np.asarray(LM71_AXLES_M)
    pts = LM71_AXLE_LOAD_N * beam.line(effect, (d[:, None] + c[None, :]).ravel()).reshape(d.size, c.size).sum(1)
    total = np.where(sign == 1, float(pieces[1][pieces[2] == 1].sum()), float(pieces[1][pieces[2] == -1].sum()))
    gap = _partial_integral(beam, effect, pieces, d - LM71_HALF_WINDOW_M, d + LM71_HALF_WINDOW_M, sign)
    return sign * (pts + LM71_UDL_N_M * (total - gap))


def lm71_max(beam, effect, alpha=1.0):
    """:class:`LM71Max` of ``effect``: the larger of both signs, each maximised over the group position."""
    return _lm71_max(beam, effect, float(alpha))


@functools.lru_cache(maxsize=512)
def _lm71_max(beam, effect, alpha):
    """Both signs on the grid in one evaluation, then the eight zooms (the four best grid points of
    each sign) in lockstep: one evaluation per zoom level for all of them. Every value is the one
    the search point by point (:func:`zoom_max` per best point and sign) computes, bit for bit
    (tests/design/test_deck_statics_former.py keeps that form and compares)."""
    pieces = signed_pieces(beam, effect)
    c = np.asarray(LM71_AXLES_M)
    hw = LM71_HALF_WINDOW_M
    lo, hi = -hw, beam.length + hw
    grid = np.arange(lo, hi + LM71_GRID_M, LM71_GRID_M)
    ends = pieces[0]
    cand = np.concatenate([grid, (ends[:, None] - c[None, :]).ravel(), ends - hw, ends + hw])
    cand = np.unique(np.clip(cand, lo, hi))
    signs = (1, -1)
    both = lm71_value(beam, effect, np.concatenate([cand, cand]), np.repeat(signs, cand.size), pieces)
    starts = []  # (sign, grid index, value there, zoom interval) in the order of the search point by point
    for k, sign in enumerate(signs):
        vals = both[k * cand.size:(k + 1) * cand.size]
        for i in np.argsort(vals)[-4:]:  # zoom in around the best grid points
            starts.append((sign, i, vals[i], (cand[max(i - 1, 0)], cand[min(i + 1, cand.size - 1)])))
    zoomed = zoom_max_many(lambda t, s: lm71_value(beam, effect, t, s, pieces), [z[3] for z in starts],
                           [z[0] for z in starts])
    best = None
    for (sign, i, v, _), (x, fx) in zip(starts, zoomed):
        if fx < v:
            x, fx = float(cand[i]), float(v)
        if best is None or fx > best.value:
            best = LM71Max(value=fx, sign=sign, centre_m=float(x))
    return LM71Max(value=alpha * best.value, sign=best.sign, centre_m=best.centre_m)


def zoom_max(f, a, b, n=41, tol=1e-9):
    """Maximum of a vectorised f on [a, b]: n points, then the same around the best one, until the
    points are ``tol`` apart. Returns (x, f(x))."""
    while True:
        x = np.linspace(a, b, n)
        v = f(x)
        i = int(np.argmax(v))
        if x[1] - x[0] <= tol:
            return float(x[i]), float(v[i])
        a, b = x[max(i - 1, 0)], x[min(i + 1, n - 1)]


def zoom_max_many(f, intervals, tags, n=41, tol=1e-9):
    """:func:`zoom_max` of several intervals at once: ``f(x, tag)`` takes the points of every interval
    still zooming and the tag of each point (``tags``: one per interval, e.g. the sign of the effect),
    one call per level instead of one per level and interval. Each interval follows the very steps
    of :func:`zoom_max` (its points, its best one, its end), so with an ``f`` whose values at a point do
    not depend on the other points of the call it returns what ``zoom_max`` returns for each:
    a list of (x, f(x))."""
    ab = [(a, b) for a, b in intervals]
    out = [None] * len(ab)
    live = list(range(len(ab)))
    while live:
        xs = [np.linspace(*ab[j], n) for j in live]
        v = f(np.concatenate(xs), np.repeat([tags[j] for j in live], n))
        still = []
        for k, (j, x) in enumerate(zip(live, xs)):
            vj = v[k * n:(k + 1) * n]
            i = int(np.argmax(vj))
            if x[1] - x[0] <= tol:
                out[j] = (float(x[i]), float(vj[i]))
            else:
                ab[j] = (x[max(i - 1, 0)], x[min(i + 1, n - 1)])
                still.append(j)
        live = still
    return out


def beam_of(bridge):
    """The :class:`ContinuousBeam` of a continuous :class:`adm_sim.model.bridge.Bridge` (cached per deck)."""
    return _beam(tuple(bridge.spans_m), tuple(bridge.span_EJ_Nm2))


@functools.lru_cache(maxsize=64)
def _beam(spans, EJ):
    return ContinuousBeam(spans, EJ)
