"""Smoke test of the installed adm_sim package (run by ``colcon test``): the core against closed forms."""

import math

import numpy as np
from adm_sim.model.bridge import eurocode_damping_pct, named_bridge
from adm_sim.integrate.envelope import moving_load_envelope


def test_slow_load_gives_the_static_midspan_deflection():
    """A single 100 kN load crossing B1 at 5 km/h: the peak midspan deflection is the static one of
    the three-mode model, 2 P L^3 / (pi^4 EJ) (1 + 1/3^4) (mode 2 has a node at midspan), within
    0.1 %, and PL^3 / (48 EJ) of the Euler beam within 0.3 %."""
    b = named_bridge("B1")
    load_n, L, EJ = 1.0e5, b.span_m, b.EJ_Nm2
    env = moving_load_envelope(b, np.array([0.0]), np.array([load_n]), np.array([5.0]))
    three_modes = 2 * load_n * L**3 / (math.pi**4 * EJ) * (1 + 1 / 3**4)
    assert abs(env.max_disp_m[0] / three_modes - 1) < 1e-3, (env.max_disp_m[0], three_modes)
    assert abs(env.max_disp_m[0] / (load_n * L**3 / (48 * EJ)) - 1) < 3e-3


def test_table3_bridge_and_en1991_damping():
    """B1 (Table 3): n0 = pi / (2 L^2) sqrt(EJ / mu) = 8.26 Hz; EN 1991-2 Table 6.6 damping of a
    15 m filler-beam bridge, 1.5 + 0.07 (20 - 15) = 1.85 %."""
    b = named_bridge("B1")
    assert abs(b.n0_hz - 8.26) < 0.005
    assert abs(b.n0_hz - math.pi / (2 * 15.0**2) * math.sqrt(2.667e10 / 19042.0)) < 1e-9
    assert abs(eurocode_damping_pct(15.0, "cfb") - 1.85) < 1e-12
    assert abs(eurocode_damping_pct(25.0, "sc") - 0.5) < 1e-12
