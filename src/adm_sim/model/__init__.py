"""The model: the bridge, the trains and their vehicles, the track, the parametric field and the plausibility bounds (data and formulas)."""

from adm_sim import lazy_getattr

#: the public names of the wing and the module that holds each (:func:`adm_sim.lazy_getattr`)
_HOME = {"Bridge": "bridge", "named_bridge": "bridge", "parametric_field": "bridge",
         "eurocode_damping_pct": "bridge", "Train": "trains", "moving_loads": "trains"}
__all__ = sorted(_HOME)

__getattr__ = lazy_getattr(__name__, _HOME)
