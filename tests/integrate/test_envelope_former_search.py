"""The exact envelope's search against its former form, kept here verbatim as plain Python.

:func:`adm_sim.integrate.envelope._newton` forms the derivative coefficients once per refinement instead of
at every iteration, and :func:`adm_sim.integrate.envelope._search_kernel` was split in steps (issue 34: no
function over 80 lines), every operation of every value in the same order. The former Newton, compiled,
must equal the new one bit for bit (and uncompiled, the uncompiled one); the former search, run as plain
Python with the former Newton, must give the same maxima, times, positions and counts as the new one run
as plain Python, bit for bit, on inputs captured from real runs (B1, the first 8 axles of ICE-2 and
HSLM-A7, a few speeds, the whole deck, midspan and x = 4 m); the compiled search the same values as the
uncompiled one to 1e-13 relative (the compiled and the Python complex powers may differ in the last bit).
The whole-deck refinement (:func:`adm_sim.integrate.envelope._refine_deck`) starts Newton from the field it
has already evaluated at the side it takes, and :func:`adm_sim.integrate.envelope._field` takes
``e^(i om t)`` as ``cos + i sin``: its former form, compiled, must give the same maxima, times and
positions bit for bit on every candidate of the captured searches and on random ones.
"""

import cmath  # the former code's
import math

import numba
import numpy as np
import pytest

from adm_sim.design.check import resolve_trains
from adm_sim.integrate import envelope as env
from adm_sim.model.bridge import named_bridge

NEWTON_ITERATIONS = env.NEWTON_ITERATIONS


def _py(f):
    return getattr(f, "py_func", f)


def _newton_before(c1, c2, w, om, lam, x, lo, hi):
    """Local extremum of the function of (c1, c2, w) near x inside [lo, hi] (Newton on its derivative)."""
    for _ in range(NEWTON_ITERATIONS):
        g2 = env._eval(c1, c2, w, om, lam, x, 2)
        if g2 == 0.0:
            break
        x = min(hi, max(lo, x - env._eval(c1, c2, w, om, lam, x, 1) / g2))
    return x, abs(env._eval(c1, c2, w, om, lam, x, 0))


_NEWTON_BEFORE = numba.njit(_newton_before)  # compiled as the module compiles its own


@numba.njit
def _field_before(c1, c2, om, lam, kw, t, x):
    """F = sum_j sin(k_j x) g_j(t) and its derivatives (F, F_t, F_x, F_tt, F_tx, F_xx), with
    g_j(t) = Im[c1_j e^(i om_j t) + c2_j e^(lam_j t)]."""
    F = Ft = Fx = Ftt = Ftx = Fxx = 0.0
    for j in range(c1.size):
        z = 1j * om[j]
        z1 = c1[j] * cmath.exp(z * t)
        z2 = c2[j] * cmath.exp(lam[j] * t)
        g0 = (z1 + z2).imag
        g1 = (z1 * z + z2 * lam[j]).imag
        g2 = (z1 * z * z + z2 * lam[j] * lam[j]).imag
        k = kw[j]
        s = math.sin(k * x)
        c = math.cos(k * x)
        F += s * g0
        Ft += s * g1
        Ftt += s * g2
        Fx += k * c * g0
        Ftx += k * c * g1
        Fxx -= k * k * s * g0
    return F, Ft, Fx, Ftt, Ftx, Fxx


@numba.njit
def _newton2_before(c1, c2, om, lam, kw, t, x, tlo, thi, xlo, xhi, t_scale, x_scale):
    """Joint (t, x) Newton on grad F = 0 towards the local maximum of |F| inside the box (see the
    module doc); returns (t, x, |F|), never lower than the start."""
    F, Ft, Fx, Ftt, Ftx, Fxx = _field_before(c1, c2, om, lam, kw, t, x)
    for _ in range(env.NEWTON_ITERATIONS_2D):
        sg = 1.0 if F >= 0.0 else -1.0  # maximise sg F: its Hessian must be negative definite
        gt, gx, a, b, c = sg * Ft, sg * Fx, sg * Ftt, sg * Ftx, sg * Fxx
        t_stuck = (t <= tlo and gt < 0.0) or (t >= thi and gt > 0.0)
        det = a * c - b * b
        if not t_stuck and a < 0.0 and det > 0.0:
            dt = -(c * gt - b * gx) / det
            dx = -(a * gx - b * gt) / det
        else:
            dt = -gt / a if (not t_stuck and a < 0.0) else 0.0
            dx = -gx / c if c < 0.0 else 0.0
        if dt == 0.0 and dx == 0.0:
            break
        y0 = abs(F)
        ok = False
        tn, xn = t, x
        Fn = Ftn = Fxn = Fttn = Ftxn = Fxxn = 0.0
        for _h in range(6):  # a step that lowers |F| is halved
            tn = min(thi, max(tlo, t + dt))
            xn = min(xhi, max(xlo, x + dx))
            Fn, Ftn, Fxn, Fttn, Ftxn, Fxxn = _field_before(c1, c2, om, lam, kw, tn, xn)
            if abs(Fn) >= y0:
                ok = True
                break
            dt *= 0.5
            dx *= 0.5
        if not ok:
            break
        step_t, step_x = abs(tn - t), abs(xn - x)
        t, x = tn, xn
        F, Ft, Fx, Ftt, Ftx, Fxx = Fn, Ftn, Fxn, Fttn, Ftxn, Fxxn
        if step_t <= 1e-12 * t_scale and step_x <= 1e-12 * x_scale:
            break
    return t, x, abs(F)


@numba.njit
def _refine_deck_before(q, pp, t, h, T_, k, l, iv, qs, mx):
    """Refine a deck candidate of quantity ``q`` at time ``t`` of interval ``k``, lane ``l`` (step ``h``,
    length ``T_``) and position x_p or L - x_p (the larger) jointly in (t, x); into ``mx`` in place."""
    c1 = iv.acc_c1[k, l] if qs.fam[q] == 0 else iv.disp_c1[k, l]
    c2 = iv.acc_c2[k, l] if qs.fam[q] == 0 else iv.disp_c2[k, l]
    om, lam, kw, span, hx = iv.Om[l], iv.lam, qs.kw, qs.span_m, qs.hx_m
    best, when, xat, t0 = mx.best, mx.when, mx.xat, iv.t0
    xs = qs.xp[q, pp]
    if abs(_field_before(c1, c2, om, lam, kw, t, span - xs)[0]) > abs(_field_before(c1, c2, om, lam, kw, t, xs)[0]):
        xs = span - xs
    t, xs, y = _newton2_before(c1, c2, om, lam, kw, t, xs, max(0.0, t - h), min(T_, t + h),
                               max(0.0, xs - 2.0 * hx), min(span, xs + 2.0 * hx), max(T_, 1e-300), span)
    if y > best[q, l]:
        best[q, l] = y
        when[q, l] = t0[k, l] + t
        xat[q, l] = xs
    return 1


def _refine_t_before(q, pp, x, h, T_, k, l, iv, qs, mx):
    """Refine a candidate of quantity ``q`` at position ``pp`` (one position, not the deck) at time ``x``
    of interval ``k``, lane ``l`` (step ``h``, length ``T_``) by Newton in t; into ``mx`` in place."""
    c1 = iv.acc_c1[k, l] if qs.fam[q] == 0 else iv.disp_c1[k, l]
    c2 = iv.acc_c2[k, l] if qs.fam[q] == 0 else iv.disp_c2[k, l]
    x, y = _NEWTON_BEFORE(c1, c2, qs.W[q, pp], iv.Om[l], iv.lam, x, max(0.0, x - h), min(T_, x + h))
    if y > mx.best[q, l]:
        mx.best[q, l] = y
        mx.when[q, l] = iv.t0[k, l] + x
        mx.xat[q, l] = qs.xp[q, pp]
    return 1


def _search_before(pairs, iv, qs, mx):
    """The former ``_search_kernel``, verbatim but its docstring and the names of the helpers it calls."""
    kk, ll, m = pairs.k, pairs.l, pairs.m
    ca1, ca2, cd1, cd2, Om, lam, T, t0 = iv.acc_c1, iv.acc_c2, iv.disp_c1, iv.disp_c2, iv.Om, iv.lam, iv.T, iv.t0
    fam, deck, npos, W, xp, odd, kw, span, hx = qs.fam, qs.deck, qs.npos, qs.W, qs.xp, qs.odd, qs.kw, qs.span_m, qs.hx_m
    bound, curv, best, when, xat = mx.bound, mx.curv, mx.best, mx.when, mx.xat
    nm = lam.size
    nq = fam.size
    pmax = W.shape[1]
    refined = 0
    ya = np.zeros((nq, 3, pmax))
    va = np.empty(nm)
    vd = np.empty(nm)
    r1 = np.empty(nm, dtype=np.complex128)
    r2 = np.empty(nm, dtype=np.complex128)
    e1 = np.empty(nm, dtype=np.complex128)
    e2 = np.empty(nm, dtype=np.complex128)
    active = np.zeros(nq, dtype=np.bool_)
    slack = np.zeros(nq)
    cf = np.empty((1024, 5))
    ci = np.empty((1024, 4), dtype=np.int64)
    nc = 0
    sx = np.zeros((2, 3))  # x-curvature slack hx^2/8 sum_j k_j^2 |v_j| of the last three samples (per family)
    for p in range(kk.size):
        k, l = kk[p], ll[p]
        need_a = False
        need_d = False
        for q in range(nq):
            active[q] = bound[q, k, l] > best[q, l]
            if active[q]:
                if fam[q] == 0:
                    need_a = True
                else:
                    need_d = True
        if not (need_a or need_d):
            continue
        T_ = T[k, l]
        h = T_ / m[p]
        om = Om[l]
        for q in range(nq):
            slack[q] = curv[q, k, l] * h * h / 4.0
        for j in range(nm):
            r1[j] = cmath.exp(1j * om[j] * h)
            r2[j] = cmath.exp(lam[j] * h)
            e1[j] = 1.0
            e2[j] = 1.0
        for i in range(m[p] + 1):
            sx[0, 0], sx[0, 1], sx[1, 0], sx[1, 1] = sx[0, 1], sx[0, 2], sx[1, 1], sx[1, 2]
            sx[0, 2] = 0.0
            sx[1, 2] = 0.0
            for j in range(nm):
                if need_a:
                    va[j] = (ca1[k, l, j] * e1[j] + ca2[k, l, j] * e2[j]).imag
                    sx[0, 2] += kw[j] * kw[j] * abs(va[j])
                if need_d:
                    vd[j] = (cd1[k, l, j] * e1[j] + cd2[k, l, j] * e2[j]).imag
                    sx[1, 2] += kw[j] * kw[j] * abs(vd[j])
                e1[j] *= r1[j]
                e2[j] *= r2[j]
            sx[0, 2] *= hx * hx / 8.0
            sx[1, 2] *= hx * hx / 8.0
            for q in range(nq):
                if not active[q]:
                    continue
                v = va if fam[q] == 0 else vd
                for pp in range(npos[q]):
                    o = 0.0
                    e = 0.0
                    if deck[q]:
                        o = 0.0
                        e = 0.0
                        for j in range(nm):
                            if odd[j]:
                                o += W[q, pp, j] * v[j]
                            else:
                                e += W[q, pp, j] * v[j]
                        y = abs(o) + abs(e)
                    else:
                        y = 0.0
                        for j in range(nm):
                            y += W[q, pp, j] * v[j]
                        y = abs(y)
                    ya[q, 0, pp], ya[q, 1, pp], ya[q, 2, pp] = ya[q, 1, pp], ya[q, 2, pp], y
                    if y > best[q, l]:
                        best[q, l] = y
                        when[q, l] = t0[k, l] + i * h
                        if deck[q] and abs(o + e) < abs(o - e):
                            xat[q, l] = span - xp[q, pp]
                        else:
                            xat[q, l] = xp[q, pp]
                if i == 0:
                    continue
                # sample i-1 is a local maximum (the first sample compares with its right side only)
                for pp in range(npos[q]):
                    y1 = ya[q, 1, pp]
                    s1 = slack[q] + (sx[fam[q], 1] if deck[q] else 0.0)
                    if y1 >= ya[q, 2, pp] and (i == 1 or y1 >= ya[q, 0, pp]) and y1 + s1 >= best[q, l]:
                        if deck[q]:
                            if env._x_local(ya, q, 1, pp, npos[q]):
                                cf, ci, nc = env._push(cf, ci, nc, y1, y1 + s1, (i - 1) * h, h, T_, q, pp, k, l)
                        else:
                            refined += _refine_t_before(q, pp, (i - 1) * h, h, T_, k, l, iv, qs, mx)
        for q in range(nq):  # the last sample
            if not active[q]:
                continue
            for pp in range(npos[q]):
                s2 = slack[q] + (sx[fam[q], 2] if deck[q] else 0.0)
                if ya[q, 2, pp] >= ya[q, 1, pp] and ya[q, 2, pp] + s2 >= best[q, l]:
                    if deck[q]:
                        if env._x_local(ya, q, 2, pp, npos[q]):
                            cf, ci, nc = env._push(cf, ci, nc, ya[q, 2, pp], ya[q, 2, pp] + s2, m[p] * h, h, T_, q, pp, k, l)
                    else:
                        refined += _refine_t_before(q, pp, m[p] * h, h, T_, k, l, iv, qs, mx)
    # deck candidates, deferred until every pair is sampled (the best is then near the maximum), the
    # largest sample first
    for c in np.argsort(-cf[:nc, 0]):
        q, pp, k, l = ci[c, 0], ci[c, 1], ci[c, 2], ci[c, 3]
        if cf[c, 1] < best[q, l]:
            continue
        refined += env._refine_deck(q, pp, cf[c, 2], cf[c, 3], cf[c, 4], k, l, iv, qs, mx)
    return refined, nc


def _captured_searches(b, offs, loads, where):
    """The arguments of every search of an envelope run (the maxima copied before the search)."""
    seen = []
    kernel = env._search_kernel

    def spy(pairs, iv, qs, mx):
        seen.append((pairs, iv, qs, env.Maxima(*(np.array(a) for a in mx))))
        return kernel(pairs, iv, qs, mx)

    env._search_kernel = spy
    try:
        env.moving_load_envelope(b, offs, loads, np.array([150.0, 240.5, 330.0]), where=where)
    finally:
        env._search_kernel = kernel
    return seen


@pytest.fixture(scope="module")
def searches():
    b = named_bridge("B1")
    out = []
    for t in resolve_trains("ICE-2,HSLM-A7"):
        offs, loads = (np.asarray(a[:8], dtype=float) for a in (t.axle_offsets_m, t.axle_loads_n))
        for where in ("deck", "midspan", 4.0):
            out += _captured_searches(b, offs, loads, where)
    return out


def test_newton_equals_its_former_form(searches):
    """Compiled and uncompiled, on the coefficients of real intervals and on random ones, every start."""
    rng = np.random.default_rng(7)
    work = np.empty((4, 3), dtype=np.complex128)
    cases = []
    for _, iv, qs, _ in searches[:6]:
        for k in range(0, iv.acc_c1.shape[0], 3):
            cases.append((iv.acc_c1[k, 0], iv.acc_c2[k, 0], qs.W[0, 0], iv.Om[0], iv.lam, iv.T[k, 0]))
    for _ in range(50):
        c = rng.normal(size=(4, 3))
        cases.append((c[0] + 1j * c[1], c[2] + 1j * c[3], rng.normal(size=3), np.array([30.0, 60.0, 90.0]),
                      np.array([-0.5 + 40j, -2.0 + 160j, -4.5 + 360j]), 0.02))
    n = 0
    for c1, c2, w, om, lam, T in cases:
        for x in np.linspace(0.0, T, 5):
            lo, hi = max(0.0, x - T / 4), min(T, x + T / 4)
            assert env._newton(c1, c2, w, om, lam, x, lo, hi, work) == _NEWTON_BEFORE(c1, c2, w, om, lam, x, lo, hi)
            assert _py(env._newton)(c1, c2, w, om, lam, x, lo, hi, work) == _newton_before(c1, c2, w, om, lam, x,
                                                                                           lo, hi)
            n += 1
    assert n > 300


def test_search_equals_its_former_form(searches, monkeypatch):
    """Every captured search, the former and the new form as plain Python (the steps that were in the former
    kernel too, the rest compiled in both: refinement, deck candidates): the same maxima, times, positions,
    refinements and deck candidates, bit for bit; compiled, the same to 1e-13 relative."""
    refined = 0
    for pairs, iv, qs, mx0 in searches:
        before, after, compiled = (env.Maxima(*(np.array(a) for a in mx0)) for _ in range(3))
        r_before = _search_before(pairs, iv, qs, before)
        with monkeypatch.context() as m:
            for name in ("_start_pair", "_last_sample"):
                m.setattr(env, name, _py(getattr(env, name)))
            r_after = _py(env._search_kernel)(pairs, iv, qs, after)
        assert r_after == r_before
        for x, y in zip(before, after):
            assert np.array_equal(x, y)
        env._search_kernel(pairs, iv, qs, compiled)
        for name in ("best", "when", "xat"):
            np.testing.assert_allclose(getattr(compiled, name), getattr(after, name), rtol=1e-13, atol=0)
        refined += r_after[0]
    assert len(searches) == 6 and refined > 100  # the refinements ran, deck and one-position alike


@pytest.mark.slow  # compiles the former refinement and runs it on every candidate (about 5 s of CPU)
def test_deck_refinement_equals_its_former_form(searches):
    """Every deck interval of the captured searches, every lane, both deck quantities and positions, starts
    across the interval (the ends included, where Newton pushes against a time bound), each from a best
    of zero (the refinement always lands) and from the search's best (it lands only when it rises): the new
    refinement, compiled, gives the same maxima, times and positions as the former one, bit for bit; and
    the field itself the same six values at random (t, x) on random coefficients."""
    n = 0
    for _, iv, qs, mx0 in searches:
        if not qs.deck.any():
            continue
        K, nl, _ = iv.acc_c1.shape
        for k in range(K - 1):
            for l in range(nl):
                T_ = iv.T[k, l]
                h = T_ / 4.0
                for q in np.nonzero(qs.deck)[0]:
                    for pp in range(qs.npos[q]):
                        for t in (0.0, 0.3 * h, 2.0 * h, T_):
                            for start in (np.zeros_like(mx0.best), mx0.best):
                                new, old = (env.Maxima(np.array(start), np.zeros_like(start), np.zeros_like(start),
                                                       mx0.bound, mx0.curv) for _ in range(2))
                                env._refine_deck(q, pp, t, h, T_, k, l, iv, qs, new)
                                _refine_deck_before(q, pp, t, h, T_, k, l, iv, qs, old)
                                for a, b in zip(new[:3], old[:3]):
                                    assert np.array_equal(a, b), (k, l, q, pp, t)
                                n += 1
    assert n > 2000
    rng = np.random.default_rng(11)
    for _ in range(2000):
        c = rng.normal(size=(4, 3))
        c1, c2 = c[0] + 1j * c[1], c[2] + 1j * c[3]
        om, kw = np.array([30.0, 60.0, 90.0]) * rng.uniform(0.5, 2.0), np.pi * np.arange(1, 4) / 15.0
        lam = np.array([-0.5 + 40j, -2.0 + 160j, -4.5 + 360j])
        t, x = rng.uniform(0.0, 0.5), rng.uniform(0.0, 15.0)
        assert env._field(c1, c2, om, lam, kw, t, x) == _field_before(c1, c2, om, lam, kw, t, x)


@numba.njit
def _cexp_i(om, t):
    return cmath.exp(1j * om * t)


def test_cis_is_the_complex_exponential_bit_for_bit():
    """``_cis(om, t)`` against ``cmath.exp(1j * om * t)``, both compiled: every bit of both parts, the signs
    of zeros too (t = +0 and -0), on 10000 random (om, t) over the ranges of the search."""
    rng = np.random.default_rng(5)
    cases = [(30.0, 0.0), (30.0, -0.0), (1e-3, 1e-300)]
    cases += list(zip(rng.uniform(1.0, 2000.0, 10000), rng.uniform(0.0, 5.0, 10000)))
    for om, t in cases:
        a, b = env._cis(om, t), _cexp_i(om, t)
        for x, y in ((a.real, b.real), (a.imag, b.imag)):
            assert x == y and math.copysign(1.0, x) == math.copysign(1.0, y), (om, t)
