"""Closed-form references used by the tests (independent of the solvers)."""

import math

import numpy as np


def moving_force_midspan_deflection(bridge, force_n, speed_m_s, t_s):
    """Midspan deflection (m) of the n-mode beam under one constant force crossing at speed v.

    Each mode is a damped oscillator ``M q'' + C q' + K q = F sin(j pi v t / L)`` while the force
    is on the span (Fryba, Vibration of solids and structures under moving loads, ch. 1), with
    zero initial conditions, followed by free vibration. Solved in closed form mode by mode.
    """
    t = np.asarray(t_s, dtype=float)
    w = np.zeros_like(t)
    zetas = bridge.modal_damping_ratios(0.0)
    t_exit = bridge.span_m / speed_m_s
    for j, (om, m, zeta) in enumerate(zip(bridge.omega_rad_s, bridge.modal_mass_kg, zetas), start=1):
        k = m * om**2
        c = 2 * zeta * m * om
        Om = j * math.pi * speed_m_s / bridge.span_m
        D = (k - m * Om**2) ** 2 + (c * Om) ** 2
        A = force_n * (k - m * Om**2) / D
        B = -force_n * c * Om / D
        wd = om * math.sqrt(1 - zeta**2)
        C1 = -B
        C2 = (zeta * om * C1 - A * Om) / wd

        def forced(tt):
            e = np.exp(-zeta * om * tt)
            q = A * np.sin(Om * tt) + B * np.cos(Om * tt) + e * (C1 * np.cos(wd * tt) + C2 * np.sin(wd * tt))
            qd = (A * Om * np.cos(Om * tt) - B * Om * np.sin(Om * tt)
                  + e * ((-zeta * om * C1 + wd * C2) * np.cos(wd * tt) + (-zeta * om * C2 - wd * C1) * np.sin(wd * tt)))
            return q, qd

        q = np.empty_like(t)
        on = t <= t_exit
        q[on] = forced(t[on])[0]
        qe, qde = forced(np.array(t_exit))
        tau = t[~on] - t_exit
        q[~on] = np.exp(-zeta * om * tau) * (qe * np.cos(wd * tau) + (qde + zeta * om * qe) / wd * np.sin(wd * tau))
        w += q * math.sin(j * math.pi / 2)
    return w


def static_midspan_deflection(bridge, force_n, x_m):
    """Static midspan deflection (m) of the Bernoulli-Euler beam, force at x (exact, all modes)."""
    x = np.minimum(np.asarray(x_m, dtype=float), bridge.span_m - np.asarray(x_m, dtype=float))
    L, EJ = bridge.span_m, bridge.EJ_Nm2
    return force_n * x * (3 * L**2 - 4 * x**2) / (48 * EJ)


def static_midspan_deflection_modal(bridge, force_n, x_m):
    """The same, truncated to the bridge's retained modes."""
    x = np.asarray(x_m, dtype=float)[..., None]
    j = bridge.mode_numbers
    k = bridge.modal_stiffness_N_m
    return (force_n * np.sin(j * math.pi * x / bridge.span_m) / k * np.sin(j * math.pi / 2)).sum(-1)
