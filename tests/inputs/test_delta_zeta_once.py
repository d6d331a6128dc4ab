"""Δζ is checked once on every sweep path, where the sweep is built, and the refusal names the value
as its caller named it: a library caller's ``delta_zeta`` is a fraction, the command line's
``--delta-zeta-pct`` is in % (before, a library ``delta_zeta=0.5`` was refused as
``delta_zeta_pct: 50 %``, a name the caller never typed)."""

from __future__ import annotations

import numpy as np
import pytest

from adm_sim import fields
from adm_sim.errors import InputError
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.integrate.sweep import lane_damping, run_sweep, run_sweep_compiled, sweep_exact
from adm_sim.model.bridge import named_bridge
from adm_sim.model.trains import moving_loads

B1 = named_bridge("B1")  # zeta = 1.85 %
ONE_AXLE = moving_loads([0.0], [1.0e5], name="one axle")
COARSE = StepOptions(steps_per_period=4.0)
SWEEPS = {
    "numpy": lambda **kw: run_sweep(B1, ONE_AXLE, "mlm", [200.0, 250.0], options=COARSE, **kw),
    "compiled": lambda **kw: run_sweep_compiled(B1, ONE_AXLE, "mlm", [200.0, 250.0], options=COARSE, **kw),
    "exact": lambda **kw: sweep_exact(B1, ONE_AXLE, [200.0, 250.0], **kw),
}


@pytest.mark.parametrize("path", sorted(SWEEPS))
def test_library_caller_is_told_about_delta_zeta_as_a_fraction(path):
    with pytest.raises(InputError) as err:
        SWEEPS[path](delta_zeta=0.5)
    assert str(err.value) == ("delta_zeta: 0.5 - (fraction) is out of range; allowed [-0.0185, 0.2] - (fraction)")


@pytest.mark.parametrize("path", sorted(SWEEPS))
def test_the_option_is_told_about_in_percent(path):
    """The command line passes its option's name: the same fraction 0.5 is refused as ``50 %``."""
    with pytest.raises(InputError) as err:
        SWEEPS[path](delta_zeta=0.5, delta_zeta_name="--delta-zeta-pct")
    assert str(err.value) == "--delta-zeta-pct: 50 % is out of range; allowed [-1.85, 20] %"


def test_command_line_refusal_names_the_option_in_percent(capsys):
    from adm_sim.cli import sim_commands

    for backend in (["--method", "exact"], ["--method", "rk4", "--backend", "numpy"], ["--method", "rk4"]):
        argv = ["sweep", "--bridge", "B1", "--speeds", "200,250", "--delta-zeta-pct", "50", *backend]
        assert sim_commands.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err == "error: --delta-zeta-pct: 50 % is out of range; allowed [-1.85, 20] %", backend
    assert sim_commands.main(["sweep", "--bridge", "B1", "--delta-zeta-pct", "abc"]) == 2  # not a number: at once
    assert capsys.readouterr().err.strip() == "error: --delta-zeta-pct: 'abc' is not a number; allowed [-1.85, 20] %"


@pytest.mark.parametrize("path", sorted(SWEEPS))
def test_each_path_checks_each_distinct_delta_zeta_once(path, monkeypatch):
    """One call of the registry's Δζ check per distinct value on each backend (three before:
    the command line, the sweep and the compiled lanes or the envelope)."""
    calls = []
    real = fields.check_delta_zeta

    def counting(field, value, damping_ratio, **kw):
        calls.append((field, value))
        return real(field, value, damping_ratio, **kw)

    monkeypatch.setattr(fields, "check_delta_zeta", counting)
    dz = 0.01 if path == "exact" else np.array([0.01, 0.01])  # the envelope takes one Δζ
    res = SWEEPS[path](delta_zeta=dz)
    res = res[0] if isinstance(res, tuple) else res
    assert calls == [("delta_zeta", 0.01)]
    assert np.all(np.isfinite(res.max_acc_m_s2)) and res.max_acc_m_s2.shape == (2,)


def test_the_command_line_checks_once_before_it_prints(capsys, monkeypatch):
    """``adm-sim sweep`` checks its Δζ once (in %), before its first line, and tells the sweep so."""
    from adm_sim.cli import sim_commands

    calls = []
    real = fields.check_delta_zeta
    monkeypatch.setattr(fields, "check_delta_zeta", lambda f, v, z, **kw: calls.append((f, v)) or real(f, v, z, **kw))
    assert sim_commands.main(["sweep", "--bridge", "B1", "--train", "HSLM-A1", "--speeds", "200,250",
                              "--delta-zeta-pct", "1", "--method", "rk4", "--backend", "numpy",
                              "--steps-per-period", "4"]) == 0
    assert calls == [("--delta-zeta-pct", pytest.approx(1.0, rel=1e-15))]
    assert sim_commands.main(["sweep", "--delta-zeta-pct", "-5"]) == 2
    out, err = capsys.readouterr()
    assert err.strip().endswith("error: --delta-zeta-pct: -5 % is out of range; allowed [-1.85, 20] %")
    assert out.count("damping per mode") == 1  # the refused run printed nothing


def test_lane_damping_returns_the_fractions_unchanged():
    """No unit round trip: the lanes get the caller's numbers bit for bit (0.007 through % is not 0.007)."""
    assert 0.007 * 100.0 / 100.0 != 0.007  # why the check works on a copy in the caller's unit
    dz = lane_damping(B1, [0.007, -0.0185], (2,), "--delta-zeta-pct")
    assert dz.tolist() == [0.007, -0.0185]
    with pytest.raises(InputError, match=r"^--delta-zeta-pct: -1\.86 % is out of range; allowed \[-1\.85, 20\] %$"):
        lane_damping(B1, -0.0186, (1,), "--delta-zeta-pct")
