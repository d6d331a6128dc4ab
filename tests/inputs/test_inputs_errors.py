"""The exception root and its exit codes (adm_sim.errors): bad input 2, a failed run 1, Ctrl-C 130."""

from __future__ import annotations


import numpy as np
import pytest

from adm_sim import cliutil, errors
from adm_sim.errors import AdmSimError, InputError, RunError
from adm_sim.fields import check_choice, check_int, check_number, check_range
from adm_sim.cliutil import run_cli



def _raise(exc):
    def call():
        raise exc
    return call


@pytest.mark.parametrize("exc,code,line", [
    (InputError("--rate: 'nan' x simulated time is not finite; allowed [0, 1e+06] x simulated time"), 2,
     "error: --rate: 'nan' x simulated time is not finite; allowed [0, 1e+06] x simulated time\n"),
    (RunError("solution is not finite at step 3 of 9\n(stage 0)"), 1, "error: solution is not finite at step 3 of 9 (stage 0)\n"),
    (AdmSimError("node 'train' died"), 1, "error: node 'train' died\n"),
    (KeyboardInterrupt(), 130, "error: interrupted\n"),
    # the system refuses a write (full disk, ulimit -f, a folder made read-only during the run)
    (OSError(28, "No space left on device", "/data/out/r.json"), 1, "error: '/data/out/r.json': No space left on device\n"),
    (OSError(27, "File too large"), 1, "error: File too large\n"),
    (PermissionError(13, "Permission denied", "/data/out/run.mcap"), 1,
     "error: '/data/out/run.mcap': Permission denied\n"),
])
def test_run_cli_maps_the_root_to_one_line_and_an_exit_code(capsys, exc, code, line):
    assert run_cli(_raise(exc)) == code
    assert capsys.readouterr().err == line


def test_run_cli_keeps_a_bug_a_bug():
    with pytest.raises(ZeroDivisionError):
        run_cli(lambda: 1 / 0)


def _import_failed(cause, explicit=True):
    """An ``ImportError`` as a pybind11 module's failed initialisation raises it: ``raise ... from cause``
    (``explicit``), or raised while ``cause`` was being handled (its context only)."""
    def call():
        try:
            raise cause
        except BaseException as exc:
            if explicit:
                raise ImportError("initialization failed") from exc
            raise ImportError("initialization failed")  # noqa: B904  the context only, on purpose
    return call


def test_run_cli_an_error_raised_from_an_interrupt_is_the_interrupt(capsys):
    """A Ctrl-C landing in a library's first import (seen in CI: SIGINT within ``scipy.optimize``'s
    import, ``ImportError: initialization failed`` from the ``KeyboardInterrupt``): 130, one line."""
    assert run_cli(_import_failed(KeyboardInterrupt())) == 130
    assert capsys.readouterr().err == "error: interrupted\n"


@pytest.mark.parametrize("cause,explicit", [(ZeroDivisionError("x"), True), (KeyboardInterrupt(), False)],
                         ids=["from-a-bug", "during-an-interrupt-not-from-it"])
def test_run_cli_an_error_not_caused_by_an_interrupt_stays_a_bug(cause, explicit):
    with pytest.raises(ImportError):
        run_cli(_import_failed(cause, explicit))


def test_classes():
    assert issubclass(InputError, AdmSimError) and issubclass(InputError, ValueError)
    assert issubclass(RunError, AdmSimError) and issubclass(RunError, RuntimeError)
    assert not issubclass(RunError, InputError)
    assert (errors.EXIT_OK, errors.EXIT_RUN, errors.EXIT_INPUT, errors.EXIT_INTERRUPTED) == (0, 1, 2, 130)


def test_unstable_integration_is_a_run_error_not_bad_input():
    """ds = 5 m is far beyond RK4's stability limit for B1's third mode: the sweep fails as a run."""
    from adm_sim.model.bridge import named_bridge
    from adm_sim.integrate.step_grid import StepOptions
    from adm_sim.integrate.sweep import run_sweep
    from adm_sim.inputs.train_files import load_train

    with np.errstate(all="ignore"), pytest.raises(RunError, match=r"^solution is not finite at step \d+ of \d+"):
        run_sweep(named_bridge("B1"), load_train("ICE-2"), "mlm", [300.0], options=StepOptions(ds_m=5.0))


@pytest.mark.parametrize("call,line", [
    (lambda: check_range("L", True, "m", 1, 150), "L: true is a boolean, not a number; allowed [1, 150] m"),
    (lambda: check_range("L", "nan", "m", 1, 150), "L: 'nan' m is not finite; allowed [1, 150] m"),
    (lambda: check_range("L", float("-inf"), "m", 1, 150), "L: -inf m is not finite; allowed [1, 150] m"),
    (lambda: check_range("EJ", 0, "N m^2", 0, None, lo_open=True), "EJ: 0 N m^2 is out of range; allowed > 0 N m^2"),
    (lambda: check_range("x", 2, "s", None, 1, hi_open=True), "x: 2 s is out of range; allowed < 1 s"),
    (lambda: check_number("m_c_kg", "30000", "kg", 1, 5e5),
     "m_c_kg: '30000' is a string, not a number (write it without quotes); allowed [1, 500000] kg"),
    (lambda: check_int("count", 3.0, 1, 100), "count: 3.0 is not an integer; allowed integer in [1, 100]"),
    (lambda: check_int("count", False, 1, 100), "count: false is not an integer; allowed integer in [1, 100]"),
    (lambda: check_int("--jobs", " 65 ", 1, 64, "processes"), "--jobs: 65 processes is out of range; allowed integer in [1, 64] processes"),
    (lambda: check_choice("class", "steel", ("cfb", "sc")), "class: 'steel' is not allowed; allowed 'cfb' or 'sc'"),
])
def test_checks_name_value_unit_and_range(call, line):
    with pytest.raises(InputError) as exc:
        call()
    assert str(exc.value) == line


def test_checks_return_the_value():
    assert check_range("L", "15", "m", 1, 150) == 15.0
    assert check_number("L", 15, "m", 1, 150) == 15.0
    assert check_int("n", "7", 1, 20) == 7 and check_int("n", 7, 1, 20) == 7
    assert check_choice("c", "sc", ("cfb", "sc")) == "sc"


def test_bridge_class_and_type():
    """``type`` gives the Table 2 damping and the class; ``class`` only the class (measured damping kept)."""
    from adm_sim.inputs.bridges import parse_bridge_spec

    b = parse_bridge_spec("L=15,n0=8.26,mu=19042,zeta_pct=1.2,class=sc")
    assert (b.bridge_type, b.damping_ratio) == ("sc", pytest.approx(0.012, abs=1e-15))
    t = parse_bridge_spec("L=15,n0=8.26,mu=19042,type=sc")
    assert t.bridge_type == "sc" and t.damping_ratio == pytest.approx((0.5 + 0.125 * (20 - 15)) / 100, abs=1e-15)
    # n0 at the top of its range survives the Eq. 18 round trip (n0 -> EJ -> n0)
    # (a 150 m span at 100 Hz is far off the Fig. 8 band: allowed, with a plausibility warning)
    with pytest.warns(errors.PlausibilityWarning, match=r"n0: 100 Hz is outside the plausible range"):
        assert parse_bridge_spec("L=150,n0=100,mu=19042,zeta_pct=1").n0_hz == pytest.approx(100.0, rel=1e-12)


def test_one_line_warnings_as_the_nodes_print_them(capsys):
    """The nodes' display (``run_node``): every warning one line ``warning: <node>: ...`` (a
    plausibility warning bare, any other with its category), Python's filters deduplicating; the
    previous display comes back at the end."""
    import warnings

    from adm_sim.errors import PlausibilityWarning
    from adm_sim.cliutil import one_line_warnings

    before = warnings.showwarning
    with one_line_warnings(prefix="bridge: ", categories=(Warning,), repeat=False):
        for _ in range(2):  # one place, one message: shown once (the default filter)
            warnings.warn("mu: 1e+06 kg/m is outside\n the plausible range", PlausibilityWarning, stacklevel=1)
        warnings.warn("overflow in exp", RuntimeWarning, stacklevel=1)
    assert warnings.showwarning is before
    assert capsys.readouterr().err.splitlines() == [
        "warning: bridge: mu: 1e+06 kg/m is outside the plausible range",
        "warning: bridge: RuntimeWarning: overflow in exp"]
    with cliutil.plausibility_warnings():  # the CLIs': every occurrence, no prefix
        for _ in range(2):
            warnings.warn("n0: 90 Hz is outside", PlausibilityWarning, stacklevel=1)
    assert capsys.readouterr().err.splitlines() == ["warning: n0: 90 Hz is outside"] * 2
