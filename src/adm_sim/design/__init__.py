"""The EN 1991-2 / EN 1990 dynamic design check: loads, effects, serviceability, text and report."""

from adm_sim import lazy_getattr

#: the public names of the wing and the module that holds each (:func:`adm_sim.lazy_getattr`)
_HOME = {"run_check": "check", "resolve_trains": "check", "CheckResult": "check", "check_speeds_kmh": "check"}
__all__ = sorted(_HOME)

__getattr__ = lazy_getattr(__name__, _HOME)
