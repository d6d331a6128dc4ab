"""The model: the bridge, the trains and their vehicles, the track, the parametric field and the plausibility bounds (data and formulas)."""

import importlib

#: the public names of the wing and the module that holds each (imported on first use, PEP 562, so
#: importing the wing stays as cheap as before; docs/python.md lists them)
_HOME = {"Bridge": "bridge", "named_bridge": "bridge", "parametric_field": "bridge",
         "eurocode_damping_pct": "bridge", "Train": "trains", "load_train": "trains",
         "moving_loads": "trains"}
__all__ = sorted(_HOME)


def __getattr__(name):
    if name in _HOME:
        return getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
