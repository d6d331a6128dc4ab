"""Time integration: the lockstep stepper, its compiled twin, the exact envelope, the sweeps and the peak rule."""

import importlib

#: the public names of the wing and the module that holds each (imported on first use, PEP 562, so
#: importing the wing stays as cheap as before; docs/python.md lists them)
_HOME = {"run_sweep": "sweep", "sweep_exact": "sweep", "SweepResult": "sweep", "StepOptions": "step_grid",
         "moving_load_envelope": "envelope", "Envelope": "envelope", "local_maxima": "peaks"}
__all__ = sorted(_HOME)


def __getattr__(name):
    if name in _HOME:
        return getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
