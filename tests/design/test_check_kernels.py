"""The check's compiled kernels against their former form, kept here verbatim as plain Python.

:func:`adm_sim.design.check_effects._scan` (the effect scan) and :func:`adm_sim.integrate.envelope._prepare` (the bounds of
the exact envelope) were restructured for speed (loops reordered, shared moduli, a vectorisable loop over
the effects) with every operation of every value kept in the same order. Their uncompiled form must equal
the former code bit for bit on inputs captured from a real run (B1, 3 modes, the first 8 axles of ICE-2 and
HSLM-A7, a few speeds, the whole deck), and the compiled kernels the uncompiled ones to 1e-13 relative (the
compiled and the Python complex exponential may differ in the last bit).

The scan then took the exponentials of each distinct step once per lane (:func:`adm_sim.design.check_effects._step_plan`)
instead of at every sample where the step changes: the kernel before that, compiled, must equal the new one,
compiled, bit for bit, on whole trains.
"""

import dataclasses

import numba
import numpy as np
import pytest

from adm_sim.design import check_effects as ce
from adm_sim.integrate import envelope as env
from adm_sim.model.bridge import named_bridge
from adm_sim.design.check import resolve_trains

_EXP_MODES = ce._exp_modes  # the compiled helper, as both forms of the scan call it


def _py(f):
    return getattr(f, "py_func", f)


def _scan_before(k_of, ds, E1, P, H, lam, v, W, base, best, squares):
    """best[l, e] = max over samples i of |base[i, e] + sum_j W[e, j] q_j(i, l)|, with
    q_j = Im[P[k, l, j] E1[i, j]] + Im[H[k, l, j] e^(lam_j ds_i / v_l)], k = k_of[i]. Along the
    samples of one interval e^(lam tau) is advanced by multiplication where the step repeats
    (``squares``: :func:`_exp_modes`)."""
    ns = k_of.size
    nm = lam.size
    ne = W.shape[0]
    eLr = np.empty(nm)
    eLi = np.empty(nm)
    sr = np.empty(nm)
    si = np.empty(nm)
    qd = np.empty(nm)
    for l in range(v.size):
        inv_v = 1.0 / v[l]
        last_k = -1
        last_ds = 0.0
        last_h = -1.0
        for i in range(ns):
            k = k_of[i]
            d = ds[i]
            if k != last_k:
                _EXP_MODES(lam, d * inv_v, squares, eLr, eLi)
                last_h = -1.0
            else:
                h = d - last_ds
                if abs(h - last_h) > 1e-12 * (1.0 + abs(h)):
                    _EXP_MODES(lam, h * inv_v, squares, sr, si)
                    last_h = h
                for j in range(nm):
                    r = eLr[j] * sr[j] - eLi[j] * si[j]
                    eLi[j] = eLr[j] * si[j] + eLi[j] * sr[j]
                    eLr[j] = r
            last_k = k
            last_ds = d
            for j in range(nm):
                p = P[k, l, j]
                e1 = E1[i, j]
                hh = H[k, l, j]
                qd[j] = p.real * e1.imag + p.imag * e1.real + hh.real * eLi[j] + hh.imag * eLr[j]
            for e in range(ne):
                y = base[i, e]
                for j in range(nm):
                    y += W[e, j] * qd[j]
                y = abs(y)
                if y > best[l, e]:
                    best[l, e] = y


@numba.njit(nogil=True)
def _scan_steps_each_sample(k_of, ds, E1, P, H, lam, v, WT, base, best, squares):
    """best[l, e] = max over samples i of |base[i, e] + sum_j WT[j, e] q_j(i, l)|, with
    q_j = Im[P[k, l, j] E1[i, j]] + Im[H[k, l, j] e^(lam_j ds_i / v_l)], k = k_of[i]. Along the
    samples of one interval e^(lam tau) is advanced by multiplication where the step repeats
    (``squares``: :func:`_exp_modes`). The sum over the modes runs for all effects at once (a loop over
    the effects innermost, contiguous in ``WT`` (modes, effects), which the compiler vectorises); every
    effect's sum is still ``base + w_1 q_1 + w_2 q_2 + ...`` in that order."""
    ns = k_of.size
    nm = lam.size
    ne = WT.shape[1]
    eLr = np.empty(nm)
    eLi = np.empty(nm)
    sr = np.empty(nm)
    si = np.empty(nm)
    qd = np.empty(nm)
    y = np.empty(ne)
    top = np.empty(ne)
    for l in range(v.size):
        inv_v = 1.0 / v[l]
        last_k = -1
        last_ds = 0.0
        last_h = -1.0
        for e in range(ne):
            top[e] = best[l, e]
        for i in range(ns):
            k = k_of[i]
            d = ds[i]
            if k != last_k:
                _EXP_MODES(lam, d * inv_v, squares, eLr, eLi)
                last_h = -1.0
            else:
                h = d - last_ds
                if abs(h - last_h) > 1e-12 * (1.0 + abs(h)):
                    _EXP_MODES(lam, h * inv_v, squares, sr, si)
                    last_h = h
                for j in range(nm):
                    r = eLr[j] * sr[j] - eLi[j] * si[j]
                    eLi[j] = eLr[j] * si[j] + eLi[j] * sr[j]
                    eLr[j] = r
            last_k = k
            last_ds = d
            for j in range(nm):
                p = P[k, l, j]
                e1 = E1[i, j]
                hh = H[k, l, j]
                qd[j] = p.real * e1.imag + p.imag * e1.real + hh.real * eLi[j] + hh.imag * eLr[j]
            for e in range(ne):
                y[e] = base[i, e]
            for j in range(nm):
                w = qd[j]
                for e in range(ne):
                    y[e] += WT[j, e] * w
            for e in range(ne):
                a = abs(y[e])
                top[e] = a if a > top[e] else top[e]
        for e in range(ne):
            best[l, e] = top[e]


def _prepare_before(iv, qs):
    """Per quantity and lane: the largest value at the event instants (and its time and position),
    the amplitude bound ``sum_j w_j (|c1_j| + |c2_j|)`` and curvature bound
    ``sum_j w_j (|c1_j| Om_j^2 + |c2_j| |lam_j|^2)`` of every interval (w_j = max |weight|, 1 on the
    deck), and the amplitude bound of the free vibration. ``iv``: :class:`Intervals`, ``qs``:
    :class:`Quantities`; returns the fields of :class:`Maxima` and the free-vibration bound."""
    ca1, ca2, cd1, cd2, Om, lam2, t0 = iv.acc_c1, iv.acc_c2, iv.disp_c1, iv.disp_c2, iv.Om, iv.lam2, iv.t0
    W, xp, npos, fam, deck, odd, span = qs.W, qs.xp, qs.npos, qs.fam, qs.deck, qs.odd, qs.span_m
    K, nl, nm = ca1.shape
    nq = fam.size
    best = np.zeros((nq, nl))
    when = np.zeros((nq, nl))
    xat = np.zeros((nq, nl))
    bound = np.empty((nq, K, nl))
    curv = np.empty((nq, K, nl))
    b_free = np.zeros((nq, nl))
    g = np.empty(nm)
    amp = np.empty(nm)
    cur = np.empty(nm)
    wmax = np.empty(nm)
    for q in range(nq):
        for j in range(nm):
            wmax[j] = 1.0 if deck[q] else abs(W[q, 0, j])
        for l in range(nl):
            top = -1.0
            for k in range(K):
                for j in range(nm):
                    c1 = ca1[k, l, j] if fam[q] == 0 else cd1[k, l, j]
                    c2 = ca2[k, l, j] if fam[q] == 0 else cd2[k, l, j]
                    g[j] = (c1 + c2).imag
                    a1, a2 = abs(c1), abs(c2)
                    amp[j] = a1 + a2
                    cur[j] = a1 * Om[l, j] ** 2 + a2 * lam2[j]
                b = 0.0
                c = 0.0
                for j in range(nm):
                    b += amp[j] * wmax[j]
                    c += cur[j] * wmax[j]
                bound[q, k, l] = b
                curv[q, k, l] = c
                if k == K - 1:
                    bf = 0.0
                    for j in range(nm):
                        bf += abs(ca2[k, l, j] if fam[q] == 0 else cd2[k, l, j]) * wmax[j]
                    b_free[q, l] = bf
                for pp in range(npos[q]):
                    o = 0.0
                    e = 0.0
                    y = 0.0
                    for j in range(nm):
                        if deck[q] and not odd[j]:
                            e += g[j] * W[q, pp, j]
                        else:
                            o += g[j] * W[q, pp, j]
                    y = abs(o) + abs(e) if deck[q] else abs(o)
                    if y > top:
                        top = y
                        best[q, l] = y
                        when[q, l] = t0[k, l]
                        xat[q, l] = span - xp[q, pp] if deck[q] and abs(o + e) < abs(o - e) else xp[q, pp]
    return best, when, xat, bound, curv, b_free


def _captured(monkeypatch, module, name, call):
    """The arguments of every call of ``module.name`` during ``call()`` (arrays copied before the call)."""
    seen = []
    kernel = getattr(module, name)

    def spy(*args):
        seen.append(tuple(np.array(a) if isinstance(a, np.ndarray) else a for a in args))
        return kernel(*args)

    monkeypatch.setattr(module, name, spy)
    call()
    monkeypatch.undo()
    return seen


@pytest.fixture(scope="module")
def small_cases():
    b = named_bridge("B1")
    out = []
    for t in resolve_trains("ICE-2,HSLM-A7"):
        out.append((b, np.asarray(t.axle_offsets_m[:8], dtype=float), np.asarray(t.axle_loads_n[:8], dtype=float)))
    return out


def test_effect_scan_equals_its_former_form(monkeypatch, small_cases):
    for b, offs, loads in small_cases:
        b3 = dataclasses.replace(b, n_modes=3, damping_model="modal")
        calls = _captured(monkeypatch, ce, "_scan",
                          lambda: ce.train_effects(b3, offs, loads, np.array([150.0, 201.3, 260.0, 301.7])))
        assert len(calls) == 2  # the coarse and the fine pass
        for k_of, ds, E1, P, H, lam, v, WT, base, best, squares in calls:
            before, after, compiled = best.copy(), best.copy(), best.copy()
            _scan_before(k_of, ds, E1, P, H, lam, v, np.ascontiguousarray(WT.T), base, before, squares)
            _py(ce._scan)(k_of, ds, E1, P, H, lam, v, WT, base, after, squares)
            assert np.array_equal(before, after)
            ce._scan(k_of, ds, E1, P, H, lam, v, WT, base, compiled, squares)
            np.testing.assert_allclose(compiled, after, rtol=1e-13, atol=0)


def test_envelope_bounds_equal_their_former_form(monkeypatch, small_cases):
    for b, offs, loads in small_cases:
        for where in ("deck", "midspan", 4.0):
            calls = _captured(monkeypatch, env, "_prepare",
                              lambda: env.moving_load_envelope(b, offs, loads, np.array([150.0, 240.5, 330.0]),
                                                               where=where))
            (iv, qs), = calls
            before = _prepare_before(iv, qs)
            after = _py(env._prepare)(iv, qs)
            compiled = env._prepare(iv, qs)
            for x, y, z in zip(before, after, compiled):
                assert np.array_equal(x, y)
                np.testing.assert_allclose(z, y, rtol=1e-13, atol=0)


@pytest.mark.parametrize("delta_zeta", [0.0, 0.0047])
def test_effects_on_the_envelope_lanes_equal_their_own(delta_zeta):
    """train_effects on the coefficients the envelope kept (two envelope runs merged as the check merges its
    1 km/h grid and its refinement) gives the numbers it computes on its own, bit for bit."""
    b = named_bridge("B1")
    t = resolve_trains("HSLM-A7")[0]
    coarse, fine = np.arange(150.0, 300.0, 10.0), np.array([204.3, 238.1, 238.2])
    e1, e2 = (env.moving_load_envelope(b, t.axle_offsets_m, t.axle_loads_n, v, delta_zeta=delta_zeta, where="deck",
                                       keep_intervals=True) for v in (coarse, fine))
    v_all = np.concatenate([coarse, fine])
    order = np.argsort(v_all, kind="stable")
    lanes = e1.intervals._replace(P=np.concatenate([e1.intervals.P, e2.intervals.P], axis=1)[:, order],
                                  H=np.concatenate([e1.intervals.H, e2.intervals.H], axis=1)[:, order])
    shared = ce.train_effects(b, t.axle_offsets_m, t.axle_loads_n, v_all[order], delta_zeta=delta_zeta,
                              intervals=lanes)
    own = ce.train_effects(b, t.axle_offsets_m, t.axle_loads_n, v_all[order], delta_zeta=delta_zeta)
    for name in ("static_max", "dynamic_max", "at_speed_kmh"):
        assert np.array_equal(getattr(shared, name), getattr(own, name)), name
    # midspan skips the even modes: nothing is kept; other damping: the lanes are propagated anew
    mid = env.moving_load_envelope(b, t.axle_offsets_m, t.axle_loads_n, coarse, where="midspan", keep_intervals=True)
    assert mid.intervals is None and e1.intervals is not None and env.moving_load_envelope(
        b, t.axle_offsets_m, t.axle_loads_n, coarse, where="deck").intervals is None
    other = ce.train_effects(b, t.axle_offsets_m, t.axle_loads_n, v_all[order], delta_zeta=delta_zeta + 0.001,
                             intervals=lanes)
    assert np.array_equal(other.dynamic_max, ce.train_effects(b, t.axle_offsets_m, t.axle_loads_n, v_all[order],
                                                              delta_zeta=delta_zeta + 0.001).dynamic_max)


@pytest.mark.slow  # compiles the former kernel (about 2 s of CPU)
@pytest.mark.parametrize("bridge_name,n_modes,damping_model,trains", [
    ("B1", 3, "modal", "HSLM-A1,ICE-2,Railjet"), ("B4", 5, "rayleigh", "HSLM-A7,ICE-4")])
def test_effect_scan_equals_the_scan_that_stepped_at_every_sample(monkeypatch, bridge_name, n_modes, damping_model,
                                                                    trains):
    """Whole trains, the coarse and the fine pass, 40 speeds and three refinement speeds; one ζ on every
    mode (the exponentials as powers) and Rayleigh damping (one exponential per mode): the scan that takes
    each distinct step's exponentials once equals, compiled, the former one, compiled, bit for bit. The
    plan's steps are each sample's own step (``ds_i - ds_(i-1)``, every bit) and few: at most 100 per pass."""
    b = dataclasses.replace(named_bridge(bridge_name), n_modes=n_modes, damping_model=damping_model)
    speeds = np.concatenate([np.linspace(144.0, 420.0, 40), [238.1, 238.2, 301.05]])
    for t in resolve_trains(trains):
        calls = _captured(monkeypatch, ce, "_scan",
                          lambda: ce.train_effects(b, t.axle_offsets_m, t.axle_loads_n, speeds))
        assert len(calls) == 2
        for k_of, ds, E1, P, H, lam, v, WT, base, best, squares in calls:
            assert squares == (damping_model == "modal")
            new, old = best.copy(), best.copy()
            ce._scan(k_of, ds, E1, P, H, lam, v, WT, base, new, squares)
            _scan_steps_each_sample(k_of, ds, E1, P, H, lam, v, WT, base, old, squares)
            assert np.array_equal(new, old), t.name
            plan, steps = ce._step_plan(k_of, ds)
            taken = np.nonzero(plan >= 0)[0]
            assert np.array_equal(steps[plan[taken]].view(np.int64), (ds[taken] - ds[taken - 1]).view(np.int64))
            assert np.all(k_of[plan == -2][1:] != k_of[np.nonzero(plan == -2)[0][1:] - 1])
            assert steps.size == np.unique(steps.view(np.int64)).size <= 100 < taken.size
