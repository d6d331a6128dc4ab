"""Synthetic accelerometer records with known modes, for the monitor's tests.

A simply supported span's first two symmetric modes (f1 and 9 f1, one damping ratio) under a train
of moving axle loads (modal force ``P sin(pi v t / L)`` per axle on the span, the moving-load model),
integrated exactly by :func:`scipy.signal.lsim` at 8 kHz and sampled at ``fs_hz``; then what a real
sensor adds: gravity (z up: +g), a slow linear drift, white noise, dropouts (samples removed). The
dynamic acceleration at each sample is returned beside, so a test knows the true dynamic peak.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

G = 9.80665


@dataclass
class SensorRecord:
    t_s: np.ndarray          # (n,) sample stamps kept (dropouts removed)
    a_m_s2: np.ndarray       # (n,) what the sensor gives: gravity + drift + dynamic + noise
    dyn_m_s2: np.ndarray     # (n,) the dynamic acceleration alone at the same stamps
    passages: list = field(default_factory=list)  # per passage: dict(t_enter, t_left, peak)
    f1_hz: float = 0.0
    zeta: float = 0.0


def mode_response(t, force, f_hz, zeta):
    """Acceleration ``y''`` of ``y'' + 2 zeta w y' + w^2 y = force(t)`` from rest, on the uniform
    grid ``t``: the exact discretisation for a force linear between samples (first-order hold,
    :func:`scipy.signal.cont2discrete`), run as a second-order recursive filter."""
    from scipy.signal import cont2discrete, lfilter, ss2tf

    w = 2 * math.pi * f_hz
    # state-space with output y'' = force - 2 zeta w y' - w^2 y
    A = np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[-w * w, -2 * zeta * w]])
    D = np.array([[1.0]])
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, D), t[1] - t[0], method="foh")
    num, den = ss2tf(Ad, Bd, Cd, Dd)
    return lfilter(num[0], den, force)


def sensor_record(fs_hz=500.0, *, f1_hz=5.0, zeta=0.02, passages=(5.0, 45.0, 85.0), duration_s=125.0,
                  span_m=20.0, speed_m_s=40.0, n_axles=8, axle_spacing_m=17.0, peak_m_s2=1.2, third=0.05,
                  offset_m_s2=G, drift_m_s3=2e-4, noise_m_s2=0.004, dropouts=(), seed=1):
    """A record of train passages (``passages``: the times the first axle enters) as a z-up sensor
    gives it; ``dropouts``: ``(t_s, duration_s)`` stretches with no sample. The dynamic signal is
    scaled so that its largest ``|a|`` over the record is ``peak_m_s2`` for the first passage."""
    fine = 8000.0
    tf = np.arange(0.0, duration_s, 1.0 / fine)
    force = np.zeros_like(tf)
    t_cross = span_m / speed_m_s
    info = []
    for t_in in passages:
        for k in range(n_axles):
            tk = t_in + k * axle_spacing_m / speed_m_s
            on = (tf >= tk) & (tf <= tk + t_cross)
            force[on] += np.sin(math.pi * (tf[on] - tk) / t_cross)
        info.append({"t_enter_s": t_in, "t_left_s": t_in + (n_axles - 1) * axle_spacing_m / speed_m_s + t_cross})
    dyn = mode_response(tf, force, f1_hz, zeta) + third * mode_response(tf, force, 9 * f1_hz, zeta)
    step = int(round(fine / fs_hz))
    ts, ds = tf[::step], dyn[::step]
    p0 = info[0]
    first = (ts >= p0["t_enter_s"]) & (ts < p0["t_left_s"] + 10.0)
    ds = ds * (peak_m_s2 / np.max(np.abs(ds[first])))
    keep = np.ones(ts.size, bool)
    for t_d, dur in dropouts:
        keep &= ~((ts > t_d) & (ts < t_d + dur))
    ts, ds = ts[keep], ds[keep]
    rng = np.random.default_rng(seed)
    a = offset_m_s2 + drift_m_s3 * ts + ds + noise_m_s2 * rng.standard_normal(ts.size)
    for p in info:
        sel = (ts >= p["t_enter_s"]) & (ts < p["t_left_s"] + 20.0)
        p["peak_m_s2"] = float(np.max(np.abs(ds[sel])))
    return SensorRecord(ts, a, ds, info, f1_hz, zeta)


def check_passages(passages, rec):
    """Each passage of ``rec`` found once (:class:`adm_sim.monitoring.modal_id.Passage`), its dynamic
    peak within 1 %, f1 within 0.5 %, ζ1 within 5 % of the set values, 10 cycles of decay or more."""
    assert len(passages) == len(rec.passages)
    for p, true in zip(passages, rec.passages):
        assert p.t_start_s <= true["t_enter_s"] + 0.1 and p.t_end_s > true["t_left_s"]
        assert p.peak_acc_m_s2 == pytest.approx(true["peak_m_s2"], rel=0.01)
        assert p.identified, p.reason
        assert p.fit.f1_hz == pytest.approx(rec.f1_hz, rel=0.005)
        assert p.fit.zeta1 == pytest.approx(rec.zeta, rel=0.05)
        assert p.fit.n_cycles >= 10
