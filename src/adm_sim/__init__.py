"""adm-sim: modal railway-bridge dynamics under moving loads (MLM) and detailed
vehicle-bridge interaction (DIM).

The numerical core (``bridge``, ``trains``, ``step_grid``, ``rk4_sides``, ``lockstep_runs``, ``sweep``) imports numpy and
scipy only; the ROS 2 nodes live in :mod:`adm_sim.nodes` and are a thin layer on top.
"""

from adm_sim.errors import AdmSimError, InputError, RunError

__all__ = ["AdmSimError", "InputError", "RunError"]
#: The one version number of adm-sim: ``pyproject.toml`` reads it (``dynamic``), :mod:`adm_calib`
#: re-exports it, and ``ros_ws/*/package.xml`` carry its release part (ROS admits only X.Y.Z);
#: ``tests/test_packaging.py`` checks that they agree.
__version__ = "0.2.0.dev0"
