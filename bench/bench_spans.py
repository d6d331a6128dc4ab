"""Speed of continuous decks against one simply supported span of the same total length.

A two-span deck 2 x 15 m (EJ 2e10 N m^2, mu 15 t/m, zeta 1.5 %, every mode up to 30 Hz by the rule)
beside the single span of 30 m with the same EJ and mu and the same mode count: the MLM RK4 sweep of
ICE-2 over 191 speeds (160..350 km/h every 1 km/h) and the DIM sweep over 39 speeds (every 5 km/h),
both on the compiled kernels. The deck's highest mode is higher than the single span's mode of the
same index, so its step is shorter: the ratios are printed per run and per lane-step-mode.
Also the single span through the deck's mode tables (spans = (30,)) against its sine path, the same
numbers by another road: the cost of the tables alone.

Prints times (the best of ROUNDS alternating rounds) and ratios measured in this run; asserts
nothing about time.
Run: .venv/bin/python bench/bench_spans.py
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import math  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from adm_sim.integrate.sweep import run_sweep_compiled  # noqa: E402
from adm_sim.model.bridge import Bridge  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402

EJ, MU, ZETA = 2.0e10, 15000.0, 0.015


#: Rounds per case (the MLM's sweeps of 10-20 ms: three times as many); the cases alternate within a round (single, deck, tables, single, ...), so a change
#: of load on the shared machine falls on every case alike, and the best of the rounds is kept.
ROUNDS = 5


def timed_rounds(fns, rounds=ROUNDS):
    """``{name: (best wall time s, result)}`` of the callables ``fns`` (``{name: fn}``), run in
    alternation ``rounds`` times."""
    best = {name: (math.inf, None) for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            out = fn()
            t = time.perf_counter() - t0
            if t < best[name][0]:
                best[name] = (t, out)
    return best


def main():
    train = load_train("ICE-2")
    deck = Bridge.continuous((15.0, 15.0), EJ, MU, ZETA, name="2x15")
    n = deck.n_modes
    single = Bridge(span_m=30.0, EJ_Nm2=EJ, mass_per_length_kg_m=MU, damping_ratio=ZETA, n_modes=n, name="1x30")
    tables = Bridge(span_m=30.0, EJ_Nm2=EJ, mass_per_length_kg_m=MU, damping_ratio=ZETA, n_modes=n, name="1x30 tables",
                    spans_m=(30.0,), span_EJ_Nm2=(EJ,), span_mu_kg_m=(MU,))
    print(f"{deck.describe()}\n{single.describe()}")
    for b in (deck, single, tables):  # compile and warm up
        run_sweep_compiled(b, train, "mlm", [200.0])
        run_sweep_compiled(b, train, "dim", [200.0])
    rows = []
    for model, speeds in (("mlm", np.arange(160.0, 350.0 + 1e-9, 1.0)), ("dim", np.arange(160.0, 350.0 + 1e-9, 5.0))):
        res = timed_rounds({b.name: (lambda b=b: run_sweep_compiled(b, train, model, speeds))
                            for b in (single, deck, tables)}, rounds=3 * ROUNDS if model == "mlm" else ROUNDS)
        for b in (single, deck, tables):
            t, r = res[b.name]
            per = t / (speeds.size * r.n_steps * b.n_modes) * 1e9
            rows.append((model, b.name, speeds.size, r.n_steps, b.n_modes, t, per))
            print(f"{model.upper()} {b.name:12s} {speeds.size:4d} speeds {r.n_steps:6d} steps {b.n_modes:2d} modes "
                  f"{t:7.3f} s  {per:6.2f} ns per lane-step-mode")
        (ts, rs), (td, rd), (tt, rt) = res["1x30"], res["2x15"], res["1x30 tables"]
        per_s = ts / (rs.n_steps * n)
        per_d = td / (rd.n_steps * n)
        print(f"  {model.upper()} ratio deck / single span: {td / ts:.2f} per run, {per_d / per_s:.2f} per step and mode "
              f"(steps {rd.n_steps} vs {rs.n_steps})")
        dev = float(np.max(np.abs(rt.max_acc_m_s2 / rs.max_acc_m_s2 - 1)))
        print(f"  {model.upper()} ratio single span through the tables / sine path: {tt / ts:.2f} "
              f"(same maxima to {dev:.1e})")


if __name__ == "__main__":
    main()
