"""Time integration: the lockstep stepper, its compiled twin, the exact envelope, the sweeps and the peak rule."""

from adm_sim import lazy_getattr

#: the public names of the wing and the module that holds each (:func:`adm_sim.lazy_getattr`)
_HOME = {"run_sweep": "sweep", "run_sweep_compiled": "sweep", "sweep_exact": "sweep", "SweepResult": "sweep", "StepOptions": "step_grid",
         "moving_load_envelope": "envelope", "Envelope": "envelope", "local_maxima": "peaks"}
__all__ = sorted(_HOME)

__getattr__ = lazy_getattr(__name__, _HOME)
