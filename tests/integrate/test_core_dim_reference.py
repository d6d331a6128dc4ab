"""DIM against an independent monolithic integration of Eq. (16)/(17) by scipy's DOP853.

The reference writes the coupled equations of the paper once more, for one lane, as a single
first-order system (no stage exchange, no active-unit bookkeeping), and integrates it with a
tight adaptive tolerance. Agreement of the midspan acceleration history checks the exchange,
the convective terms of Eq. (9) and the modified mass matrix of Eq. (13).
"""

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import adm_sim
from adm_sim.model.bridge import named_bridge
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import run_sweep
from adm_sim.inputs.train_files import train_from_mapping

pytestmark = pytest.mark.slow  # each test costs seconds of CPU (a monolithic reference solve)


def _one_vehicle_train():
    vt = dict(m_c_kg=33930, J_c_kgm2=2.115e6, m_b_kg=2373, J_b_kgm2=1832, m_w_kg=1728,
              k_s_N_m=3e5, c_s_Ns_m=6e3, k_p_N_m=1.6e6, c_p_Ns_m=2e4, d_m=26.4, r_m=19.0, b_m=2.5,
              axle_load_kN=112)
    return train_from_mapping({"name": "one PC", "vehicle_types": {"PC": vt},
                               "composition": [{"vehicle": "PC", "count": 2}]})


def _monolithic_midspan_acc(bridge, train, speed_kmh, t_eval):
    v = speed_kmh / 3.6
    n = bridge.n_modes
    M, K, Z = bridge.modal_mass_kg, bridge.modal_stiffness_N_m, bridge.modal_damping_Ns_m()
    mats = [train.unit_matrices(i) for i in range(len(train.units))]
    nd = [len(m.M) for m in mats]
    Mv = np.concatenate([m.M for m in mats])
    D = len(Mv)
    Ks = np.zeros((D, D))
    Cs = np.zeros((D, D))
    Lw = np.zeros((train.n_axles, D))
    kp, cp = np.zeros(train.n_axles), np.zeros(train.n_axles)
    r = 0
    for i, m in enumerate(mats):
        ax = train.unit_axles(i)
        Ks[r:r + nd[i], r:r + nd[i]] = m.K_s
        Cs[r:r + nd[i], r:r + nd[i]] = m.C_s
        Lw[ax, r:r + nd[i]] = m.Lw
        kp[ax], cp[ax] = m.k_p, m.c_p
        r += nd[i]
    F, mw, offs = train.axle_loads_n, train.wheel_mass_kg, train.axle_offsets_m
    jk = bridge.mode_numbers * math.pi / bridge.span_m
    phi_mid = np.sin(bridge.mode_numbers * math.pi / 2)

    def parts(t, y):
        q, u, qd, ud = y[:n], y[n:n + D], y[n + D:2 * n + D], y[2 * n + D:]
        x = v * t - offs
        on = ((x >= 0) & (x <= bridge.span_m)).astype(float)
        ph = np.sin(np.outer(x, jk)) * on[:, None]
        phx = jk * np.cos(np.outer(x, jk)) * on[:, None]
        phxx = -(jk**2) * ph
        w = ph @ q
        wd = ph @ qd + v * (phx @ q)
        f = kp * (w - Lw @ u) + cp * (wd - Lw @ ud)
        udd = (Lw.T @ f - Ks @ u - Cs @ ud) / Mv  # Eq. (11)
        Mmod = np.diag(M) + (ph.T * mw) @ ph  # Eq. (13)
        P = ((F - f) * on - mw * (2 * v * (phx @ qd) + v**2 * (phxx @ q))) @ ph  # Eq. (14)
        qdd = np.linalg.solve(Mmod, P - Z * qd - K * q)  # Eq. (15)
        return qd, ud, qdd, udd

    def rhs(t, y):
        qd, ud, qdd, udd = parts(t, y)
        return np.concatenate([qd, ud, qdd, udd])

    sol = solve_ivp(rhs, (0, t_eval[-1]), np.zeros(2 * (n + D)), method="DOP853", t_eval=t_eval,
                    rtol=1e-10, atol=1e-13, max_step=(t_eval[1] - t_eval[0]) * 4)
    return np.array([parts(t, sol.y[:, i])[2] @ phi_mid for i, t in enumerate(sol.t)])


# Pointwise agreement of whole time histories, 0.1 % of the peak, at twice the default
# resolution: the axles entering and leaving make the right-hand side non-smooth, so the
# pointwise history error of RK4 falls from ~0.6 % (default step) to ~0.06 % (half) to
# ~0.006 % (quarter); the peaks themselves converge faster (see test_core_dim.py).
FINE = StepOptions(steps_per_period=32)


# One case: faults injected into the reference (error / peak, tolerance 1e-3) are each caught by
# B3 at 268 km/h with a wider margin than by B1 at 200 km/h, which was dropped: no convective terms
# 5.6e-2 (B1 9.1e-3), no centripetal term 2.9e-2 (5.6e-3), no Eq. (13) modified mass 2.3e-1 (1.1e-1),
# no v w' term 1.9e-2 (4.2e-3), c_p x1.2 2.2e-2 (8.6e-3), c_s x1.2 2.6e-3 (1.0e-3), bridge damping
# x1.2 4.7e-2 (8.0e-2, the one fault B1 shows more, still caught 47x over by B3).
@pytest.mark.parametrize("bridge_name,speed_kmh", [("B3", 268.0)])
def test_dim_matches_monolithic_reference(bridge_name, speed_kmh):
    b, tr = named_bridge(bridge_name), _one_vehicle_train()
    r = run_sweep(b, tr, "dim", [speed_kmh], histories=True, options=FINE)
    ref = _monolithic_midspan_acc(b, tr, speed_kmh, r.time_s[0])
    ours = r.midspan_acc_m_s2[0]
    assert np.abs(ref).max() > 0.05  # a real response (m/s2)
    assert np.abs(ours - ref).max() <= 1e-3 * np.abs(ref).max()


def _eurostar_front():
    """The Eurostar's leading locomotive and first Jacobs set (its first two of four units)."""
    text = (Path(adm_sim.__file__).parent / "data" / "trains" / "eurostar.toml").read_text(encoding="utf-8")
    data = tomllib.loads(text)
    assert [("vehicle" in c, c.get("reversed", False)) for c in data["composition"]] == [
        (True, False), (False, False), (False, True), (True, False)]
    data["composition"] = data["composition"][:2]
    data["name"] = "Eurostar front"
    return train_from_mapping(data)


def test_jacobs_set_matches_monolithic_reference():
    """The first 70 m of the Eurostar (Loc + PC 1..3 of a Jacobs set) over B3 at 280 km/h. The
    train is its Loc and first Jacobs set only: units couple only through the bridge, and the
    mirrored set and the rear Loc have no axle within the first 70 m, so they are at rest off the
    bridge until then (the history compared is the whole train's bit for bit, measured: 0.0
    difference; the run takes 6931 steps in place of 12934)."""
    b, tr = named_bridge("B3"), _eurostar_front()
    assert tr.n_axles == 24 and tr.axle_offsets_m[-1] > 70.0
    r = run_sweep(b, tr, "dim", [280.0], histories=True, options=FINE)
    t = r.time_s[0]
    keep = t <= 70.0 / (280.0 / 3.6)
    ref = _monolithic_midspan_acc(b, tr, 280.0, t[keep])
    ours = r.midspan_acc_m_s2[0][keep]
    assert np.abs(ours - ref).max() <= 1e-3 * np.abs(ref).max()
