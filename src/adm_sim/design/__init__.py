"""The EN 1991-2 / EN 1990 dynamic design check: loads, effects, serviceability, text and report."""

import importlib

#: the public names of the wing and the module that holds each (imported on first use, PEP 562, so
#: importing the wing stays as cheap as before; docs/python.md lists them)
_HOME = {"run_check": "check", "resolve_trains": "check", "CheckResult": "check", "check_speeds_kmh": "check"}
__all__ = sorted(_HOME)


def __getattr__(name):
    if name in _HOME:
        return getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
