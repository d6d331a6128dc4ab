"""The propagation from event to event computes the exponentials of an interval length once
(:func:`adm_sim.integrate.envelope.interval_exponentials`): the coefficients it gives must be those of the
former loop (one ``np.exp`` pair per interval, kept here verbatim), bit for bit, in the envelope and in
the effects' own propagation, and the exponentials must really be shared (as many distinct arrays as
distinct lengths)."""

import numpy as np
import pytest

from adm_sim.design import check_effects as ce
from adm_sim.design.check import resolve_trains
from adm_sim.integrate import envelope as env
from adm_sim.model.bridge import named_bridge


def _propagate_before(Gk, bps, v, jj, om, zeta, lam, L):
    """The former ``check_effects._propagate``, verbatim but its docstring."""
    Om = jj[None, :] * np.pi * v[:, None] / L  # (lanes, modes)
    dyn = 1.0 / (om**2 - Om**2 + 2j * zeta * om * Om)
    K = bps.size
    P = Gk[:, None, :] * dyn[None]  # (K, lanes, modes)
    H = np.empty_like(P)
    q = np.zeros((v.size, jj.size))
    dq = np.zeros_like(q)
    for k in range(K):
        p = P[k]
        hi = q - p.imag
        H[k] = (dq - Om * p.real - lam.real * hi) / lam.imag + 1j * hi
        if k < K - 1:
            T = (bps[k + 1] - bps[k]) / v[:, None]
            eW = np.exp(1j * Om * T)
            eL = np.exp(lam * T)
            q = (p * eW).imag + (H[k] * eL).imag
            dq = (1j * Om * p * eW).imag + (lam * H[k] * eL).imag
    return P, H


def _case(bridge_name, train_name, speeds_kmh):
    b = named_bridge(bridge_name)
    t = resolve_trains(train_name)[0]
    lanes = ce._lanes(b, t.axle_offsets_m, t.axle_loads_n, speeds_kmh, 0.0, ce.effects_of(b.span_m), None)
    zeta = np.asarray(b.modal_damping_ratios(0.0))
    return b, t, lanes, zeta


SPEEDS = np.concatenate([np.arange(144.0, 421.0, 7.0), [200.05, 333.3]])


@pytest.mark.parametrize("bridge_name,train_name", [("B1", "HSLM-A1"), ("B1", "ICE-2"), ("B4", "ICE-4"),
                                                    ("B2", "Railjet")])
def test_propagation_equals_its_former_form(bridge_name, train_name):
    """``P`` and ``H`` of every interval, lane and mode: the effects' propagation and the envelope's kept
    coefficients against the former loop, bit for bit."""
    b, t, lanes, zeta = _case(bridge_name, train_name, SPEEDS)
    v = SPEEDS / 3.6
    P0, H0 = _propagate_before(lanes.Gk, lanes.bps, v, lanes.jj, lanes.om, zeta, lanes.lam, b.span_m)
    assert np.array_equal(lanes.P, P0) and np.array_equal(lanes.H, H0)
    e = env.moving_load_envelope(b, t.axle_offsets_m, t.axle_loads_n, SPEEDS, where="deck", keep_intervals=True)
    assert np.array_equal(e.intervals.P, P0) and np.array_equal(e.intervals.H, H0)


def test_exponentials_are_shared_by_equal_lengths():
    """HSLM-A1 on B1: 99 intervals of 16 distinct lengths; every yielded pair equals ``np.exp`` of its own
    interval, bit for bit, and only 16 distinct pairs exist (the saving); a train of all-distinct lengths
    gets one pair per interval."""
    b, _, lanes, _ = _case("B1", "HSLM-A1", SPEEDS)
    v = SPEEDS / 3.6
    Om = lanes.jj[None, :] * np.pi * v[:, None] / b.span_m
    lengths = np.diff(lanes.bps)
    T = lengths[:, None] / v[None, :]
    out = list(env.interval_exponentials(Om, lanes.lam, T, lengths))
    assert len(out) == lengths.size == 99
    for k, (eW, eL) in enumerate(out):
        assert np.array_equal(eW, np.exp(1j * Om * T[k][:, None]))
        assert np.array_equal(eL, np.exp(lanes.lam * T[k][:, None]))
    assert len({id(eW) for eW, _ in out}) == np.unique(lengths).size == 16
    odd = np.cumsum(np.arange(1.0, 8.0) * 0.37)  # all lengths distinct
    T2 = np.diff(odd)[:, None] / v[None, :]
    distinct = list(env.interval_exponentials(Om, lanes.lam, T2, np.diff(odd)))  # kept: ids stay distinct
    assert len({id(eW) for eW, _ in distinct}) == 6
