"""adm-calib: calibration of the additional damping of the Moving Load Model (paper Section 4).

Analysis only (numpy/scipy on top of :mod:`adm_sim`); no ROS import here.

* :mod:`adm_calib.peaks`      peak identification over speed, MLM/DIM peak association
* :mod:`adm_calib.calibrate`  Section 4 over a lane runner: one calibration, vectorised over a batch
* :mod:`adm_calib.calibration_options`  its settings and speed range
* :mod:`adm_calib.damping_root`  the root finder of Δζ_VBI (ladder bracket, Chandrupatla)
* :mod:`adm_calib.speed_grids`  DIM speeds, relocation windows, refined peaks, grid adequacy
* :mod:`adm_calib.calibration_result`  the result, its JSON and its report
* :mod:`adm_calib.lanes`      lane runners (compiled, numpy, hook) and request batching
* :mod:`adm_calib.reference`  Eurocode ADM, EADA (Yau et al.), lower-bound functions (Tables B1-B4)
* :mod:`adm_calib.table4`     the comparison of Section 4.4 (Table 4, Fig. 19)
* :mod:`adm_calib.plots`      matplotlib figures (Agg), outside the analysis
* :mod:`adm_calib.calib_commands` the ``adm-calib`` command
"""

from adm_sim import __version__ as __version__  # one version number for both packages
from adm_sim import lazy_getattr

#: the public names of the wing and the module that holds each (:func:`adm_sim.lazy_getattr`)
_HOME = {"CalibrationOptions": "calibration_options", "calibrate_batch": "calibrate", "run_table4": "table4",
         "Table4": "table4", "recommend": "reference", "Recommendation": "reference",
         "lower_bound_for": "reference", "eada_for": "reference", "lower_bound_pct": "lower_bound"}
__all__ = sorted(_HOME)

__getattr__ = lazy_getattr(__name__, _HOME)
