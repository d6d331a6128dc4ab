"""``adm-sim sweep`` on its two RK4 backends: the compiled kernels (default) and the numpy stepper.

The compiled sweep (:func:`adm_sim.integrate.sweep.run_sweep_compiled`) runs every speed as a lane of one
:class:`adm_sim.integrate.compiled_batch.BatchRun` on the grid :func:`adm_sim.integrate.sweep.run_sweep` makes; the
maxima agree with the numpy stepper (the reference) to 1e-12 relative (measured: ~1e-14; the
summation order of a few small dot products differs), with the same step and number of steps.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from adm_sim.model.bridge import named_bridge
from adm_sim.cli.sim_commands import main
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import BACKENDS, run_sweep, run_sweep_compiled
from adm_sim.inputs.train_files import load_train

#: a quarter of the default step count: the same code, cheaper; the two backends are compared on one ds,
#: which need not be accurate for them to agree (RK4 is stable up to h omega = 2.8, here pi / 2), as in
#: test_batch.py and test_irregularity.py
COARSE = StepOptions(steps_per_period=4.0)


# B1 x ICE-2 DIM without damping is no case here: test_cli_dim_sweep_defaults_to_the_compiled_backend_and_equals_numpy
# runs that pair through run_sweep_compiled and run_sweep (max acceleration and deflection to 1e-12, n_steps, ds,
# peak); the progress calls and the peak's index are checked by the cases below.
@pytest.mark.parametrize("bridge,train,model,dz", [
    ("B3", "Eurostar", "dim", 0.004),   # Jacobs bogies, additional damping
    ("B1", "ICE-2", "mlm", 0.0),        # MLM on the RK4 lanes (--method rk4)
])
def test_compiled_sweep_equals_the_numpy_stepper(bridge, train, model, dz):
    b, t = named_bridge(bridge), load_train(train)
    speeds = np.array([250.0, 262.0, 300.0, 350.0])
    ref = run_sweep(b, t, model, speeds, delta_zeta=dz, options=COARSE)
    calls = []
    got = run_sweep_compiled(b, t, model, speeds, delta_zeta=dz, options=COARSE,
                             progress=lambda done, n: calls.append((done, n)))
    np.testing.assert_allclose(got.max_acc_m_s2, ref.max_acc_m_s2, rtol=1e-12, atol=0)
    np.testing.assert_allclose(got.max_disp_m, ref.max_disp_m, rtol=1e-12, atol=0)
    assert (got.ds_m, got.n_steps) == (ref.ds_m, ref.n_steps)
    pg, pr = got.peak(), ref.peak()
    assert (pg["speed_kmh"], pg["index"]) == (pr["speed_kmh"], pr["index"])
    assert pg["acc_m_s2"] == pytest.approx(pr["acc_m_s2"], rel=1e-12, abs=0)
    assert calls[-1] == (ref.n_steps, ref.n_steps) and 50 <= len(calls) <= 101
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


def _sweep_json(tmp_path, capsys, *extra):
    out = tmp_path / f"s{len(list(tmp_path.iterdir()))}.json"
    argv = ["sweep", "--model", "dim", "--speeds", "250,262,300", "--steps-per-period", "8", "--json", str(out)]
    assert main(argv + list(extra)) == 0
    return json.loads(out.read_text()), capsys.readouterr().out


def test_cli_dim_sweep_defaults_to_the_compiled_backend_and_equals_numpy(tmp_path, capsys):
    comp, text = _sweep_json(tmp_path, capsys)
    assert comp["backend"] == "compiled" and "compiled backend" in text
    ref, text = _sweep_json(tmp_path, capsys, "--backend", "numpy")
    assert ref["backend"] == "numpy" and "numpy backend" in text
    for key in ("max_acc_m_s2", "max_disp_m"):
        np.testing.assert_allclose(comp[key], ref[key], rtol=1e-12, atol=0)
    assert (comp["n_steps"], comp["ds_m"], comp["peak"]["speed_kmh"]) == (ref["n_steps"], ref["ds_m"], 262.0)
    assert comp["peak"]["acc_m_s2"] == pytest.approx(ref["peak"]["acc_m_s2"], rel=1e-12)


def test_backend_numpy_is_refused_with_the_exact_envelope(tmp_path, capsys):
    assert main(["sweep", "--model", "mlm", "--speeds", "250", "--backend", "numpy",
                 "--json", str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --backend: 'numpy' is the RK4 stepper's") and err.count("\n") == 1
    assert not (tmp_path / "x.json").exists()
    assert main(["sweep", "--model", "mlm", "--speeds", "250", "--backend", "compiled"]) == 0  # the one it has


def test_parser_offers_the_sweep_backends():
    from adm_sim.cli.sim_commands import build_parser

    sweep = build_parser()._subparsers._group_actions[0].choices["sweep"]
    action = next(a for a in sweep._actions if a.dest == "backend")
    assert tuple(action.choices) == BACKENDS
