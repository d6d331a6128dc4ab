"""Root test configuration: stable numbers and timings on a 2-core machine, local-only DDS."""

import os

# Pin BLAS threads before numpy is imported anywhere (numbers and timings stay stable).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# Never let DDS leave this machine: shared-memory transport only, localhost discovery.
os.environ.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "SHM")
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("MPLBACKEND", "Agg")
# No first-run compile notice on stderr in tests (they compare stderr line by line; a fresh clone
# compiles numba's kernels in whichever test comes first). tests/test_imports.py tests the notice.
os.environ.setdefault("ADM_SIM_QUIET_COMPILE", "1")
