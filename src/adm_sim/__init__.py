"""adm-sim: modal railway-bridge dynamics under moving loads (MLM) and detailed
vehicle-bridge interaction (DIM).

The numerical core (``bridge``, ``trains``, ``step_grid``, ``rk4_sides``, ``lockstep_runs``, ``sweep``) imports numpy and
scipy only; the ROS 2 nodes live in :mod:`adm_sim.nodes` and are a thin layer on top.
"""

import importlib as _importlib
import os as _os


def _fit_address_space(environ=_os.environ):
    """Under an address-space limit (``ulimit -v``) OpenBLAS's start-up with one thread per core
    can spin forever at 100 % CPU, deaf to Ctrl-C; with one thread it starts. So before numpy and
    scipy load, a process with a finite limit runs its BLAS on one thread (a value set by the user
    stays). Returns the limit in bytes, or ``None``."""
    try:
        import resource  # noqa: PLC0415  POSIX only

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        return None
    if soft == resource.RLIM_INFINITY:
        return None
    for key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        environ.setdefault(key, "1")
    return int(soft)


_fit_address_space()

from adm_sim.errors import AdmSimError, InputError, RunError  # noqa: E402  after the BLAS set-up above

__all__ = ["AdmSimError", "InputError", "RunError"]
#: The one version number of adm-sim: ``pyproject.toml`` reads it (``dynamic``), :mod:`adm_calib`
#: re-exports it, and ``ros_ws/*/package.xml`` carry its release part (ROS admits only X.Y.Z);
#: ``tests/house/test_packaging.py`` checks that they agree.
__version__ = "0.2.0.dev0"


def lazy_getattr(package, homes):
    """The module ``__getattr__`` (PEP 562) of a wing whose public names live in its modules:
    ``homes`` maps each name to the module of ``package`` that holds it, imported on first use, so
    importing the wing stays as cheap as importing its package (docs/python.md lists the names)."""
    def __getattr__(name):
        if name in homes:
            return getattr(_importlib.import_module(f"{package}.{homes[name]}"), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
