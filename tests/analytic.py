"""Closed-form references used by the tests (independent of the solvers)."""

import math

import numpy as np


def moving_force_midspan_deflection(bridge, force_n, speed_m_s, t_s):
    """Midspan deflection (m) of the n-mode beam under one constant force crossing at speed v.

    Each mode is a damped oscillator ``M q'' + C q' + K q = F sin(j pi v t / L)`` while the force
    is on the span (Fryba, Vibration of solids and structures under moving loads, ch. 1), with
    zero initial conditions, followed by free vibration. Solved in closed form mode by mode.
    """
    q, _, _ = moving_force_modal(bridge, force_n, speed_m_s, t_s)
    return (q * np.sin(bridge.mode_numbers * math.pi / 2)[:, None]).sum(0)


def moving_force_modal(bridge, force_n, speed_m_s, t_s):
    """Modal coordinates q_j, velocities q_j' and modal forces per modal mass F_j / M_j, each of
    shape (n_modes, len(t)), of one force entering the span at t = 0 (zero before), in closed form
    (see :func:`moving_force_midspan_deflection`). ``q_j'' = F_j/M_j - 2 zeta_j omega_j q_j' - omega_j^2 q_j``.
    """
    t = np.asarray(t_s, dtype=float)
    out = np.zeros((3, bridge.n_modes) + t.shape)
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
            # each sine, cosine and exponential once: q and q' share them (the same values as each
            # written out in both, at half the cost of the transcendental functions)
            e = np.exp(-zeta * om * tt)
            so, co = np.sin(Om * tt), np.cos(Om * tt)
            sw, cw = np.sin(wd * tt), np.cos(wd * tt)
            q = A * so + B * co + e * (C1 * cw + C2 * sw)
            qd = (A * Om * co - B * Om * so
                  + e * ((-zeta * om * C1 + wd * C2) * cw + (-zeta * om * C2 - wd * C1) * sw))
            return q, qd, so

        q, qd, f = out[0, j - 1], out[1, j - 1], out[2, j - 1]
        on = (t >= 0) & (t <= t_exit)
        q[on], qd[on], so = forced(t[on])
        f[on] = force_n / m * so
        qe, qde, _ = forced(np.array(t_exit))
        off = t > t_exit
        tau = t[off] - t_exit
        e = np.exp(-zeta * om * tau)
        c1, c2 = qe, (qde + zeta * om * qe) / wd
        sw, cw = np.sin(wd * tau), np.cos(wd * tau)
        q[off] = e * (c1 * cw + c2 * sw)
        qd[off] = e * ((-zeta * om * c1 + wd * c2) * cw + (-zeta * om * c2 - wd * c1) * sw)
    return out[0], out[1], out[2]


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


def moving_forces_modal(bridge, offsets_m, forces_n, speed_m_s, t_s, chunk=16):
    """Sum over a train of forces (the first at ``offsets_m[0]`` behind t = 0's entry, each entering
    the span at ``offset / v``) of :func:`moving_force_modal`'s q_j, q_j' and F_j / M_j, each of shape
    (n_modes, len(t)). The closed form is linear in the force, so every axle is the unit force's
    response at its own shifted times scaled by its load: the same superposition as a loop over the
    axles, evaluated ``chunk`` axles at a time as one array."""
    t = np.asarray(t_s, dtype=float).ravel()
    offs = np.asarray(offsets_m, dtype=float)
    loads = np.asarray(forces_n, dtype=float)
    out = np.zeros((3, bridge.n_modes, t.size))
    for s in range(0, offs.size, chunk):
        shifted = t[None, :] - offs[s:s + chunk, None] / speed_m_s
        q, qd, f = moving_force_modal(bridge, 1.0, speed_m_s, shifted)  # (n_modes, n_axles, len(t))
        w = loads[s:s + chunk, None]
        out[0] += (q * w).sum(1)
        out[1] += (qd * w).sum(1)
        out[2] += (f * w).sum(1)
    return out[0], out[1], out[2]
