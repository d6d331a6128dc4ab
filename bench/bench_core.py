"""Speed of the core sweeps (B1 x ICE-2, 191 speeds), with convergence, against the paper's way
of working: one adaptive ODE integration per speed (scipy LSODA, the closest to ode113).

Prints times and ratios measured in this run; asserts nothing about time.
Run: .venv/bin/python bench/bench_core.py
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import math  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from adm_sim.model.bridge import named_bridge  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions, make_grid  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402


def timed(fn, repeat=1):
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def lsoda_mlm_peak(bridge, train, speed_kmh, rtol):
    """Max |midspan acceleration| of one MLM crossing integrated by LSODA (Eq. 12)."""
    v = speed_kmh / 3.6
    M, K = bridge.modal_mass_kg, bridge.modal_stiffness_N_m
    Z = bridge.modal_damping_Ns_m()
    j = bridge.mode_numbers * math.pi / bridge.span_m
    offs, F = train.axle_offsets_m, train.axle_loads_n
    n = bridge.n_modes
    phi_mid = np.sin(bridge.mode_numbers * math.pi / 2)

    def load(t):
        x = v * t - offs
        on = (x >= 0) & (x <= bridge.span_m)
        return F[on] @ np.sin(np.outer(x[on], j))

    def rhs(t, y):
        q, qd = y[:n], y[n:]
        return np.concatenate([qd, (load(t) - Z * qd - K * q) / M])

    grid = make_grid(bridge, train.length_m, np.array([v]), StepOptions())
    t_end = grid.n_steps * grid.ds_m / v
    t_eval = np.arange(grid.n_steps) * grid.ds_m / v
    sol = solve_ivp(rhs, (0, t_end), np.zeros(2 * n), method="LSODA", t_eval=t_eval, rtol=rtol,
                    atol=1e-12, max_step=grid.ds_m / v * 8)
    x = v * sol.t[:, None] - offs  # loads at all output times at once (fair to the baseline)
    p = np.where((x >= 0) & (x <= bridge.span_m), F, 0.0)[:, :, None] * np.sin(x[:, :, None] * j)
    acc = ((p.sum(1) - Z * sol.y[n:].T - K * sol.y[:n].T) / M) @ phi_mid
    return float(np.max(np.abs(acc)))


def main():
    b, t = named_bridge("B1"), load_train("ICE-2")
    speeds = np.arange(160.0, 351.0, 1.0)
    print(f"B1 x ICE-2, {len(speeds)} speeds 160..350 km/h, {os.cpu_count()} cores")

    t_mlm, mlm = timed(lambda: run_sweep(b, t, "mlm", speeds), repeat=3)
    t_mlm2, mlm2 = timed(lambda: run_sweep(b, t, "mlm", speeds, options=StepOptions().halved()))
    p1, p2 = mlm.peak(), mlm2.peak()
    print(f"MLM sweep  {t_mlm:7.3f} s  peak {p1['acc_m_s2']:.5f} m/s2 at {p1['speed_kmh']:g} km/h; "
          f"half step {p2['acc_m_s2']:.5f} (change {abs(p1['acc_m_s2'] / p2['acc_m_s2'] - 1) * 100:.4f} %)")

    t_dim, dim = timed(lambda: run_sweep(b, t, "dim", speeds))
    t_dim2, dim2 = timed(lambda: run_sweep(b, t, "dim", speeds, options=StepOptions().halved()))
    d1, d2 = dim.peak(), dim2.peak()
    print(f"DIM sweep  {t_dim:7.3f} s  peak {d1['acc_m_s2']:.5f} m/s2 at {d1['speed_kmh']:g} km/h; "
          f"half step {d2['acc_m_s2']:.5f} (change {abs(d1['acc_m_s2'] / d2['acc_m_s2'] - 1) * 100:.4f} %)")
    print(f"  targets: MLM <= 0.5 s, DIM <= 10 s; lane-steps/s MLM {len(speeds) * mlm.n_steps / t_mlm:,.0f}, "
          f"DIM {len(speeds) * dim.n_steps / t_dim:,.0f}")

    # the paper's way: one adaptive integration per speed, at equal accuracy on the peak
    probe = [200.0, 263.0, 330.0]
    ours = {s: mlm2.max_acc_m_s2[list(speeds).index(s)] for s in probe}
    rtol = 1e-4
    while True:
        t_ls, vals = timed(lambda: [lsoda_mlm_peak(b, t, s, rtol) for s in probe])
        err = max(abs(vals[i] / ours[s] - 1) for i, s in enumerate(probe))
        if err < 1e-3 or rtol < 1e-10:
            break
        rtol /= 10
    per_speed = t_ls / len(probe)
    print(f"LSODA per speed (rtol {rtol:g}, peak within {err * 100:.3f} % of ours): {per_speed:.3f} s "
          f"-> {per_speed * len(speeds):.1f} s for {len(speeds)} speeds")
    print(f"ratio MLM sweep vs LSODA per speed: {per_speed * len(speeds) / t_mlm:,.0f}x (target >= 200x)")


if __name__ == "__main__":
    main()
