"""The study's local cluster runs its workers without dask's task profiler and with glibc's malloc defaults.

dask's defaults cost a study of long compute tasks CPU it does not need: the workers' statistical
profiler (a sample of the running task every 10 ms), 20 ms event-loop ticks, and
``MALLOC_TRIM_THRESHOLD_=65536`` from the nanny, which makes every large table of a batch come from
fresh pages (``bench/bench_study_cluster.py``). These tests read what a worker of
:func:`adm_calib.study.local_cluster` actually runs with, and that a batch's tables no longer
fault their pages in again under the study's malloc settings.
"""

import importlib.util
import os
import resource
import subprocess
import sys

import pytest

# skipped without distributed, which is imported by the tests themselves (0.35 s, not at collection)
pytestmark = [pytest.mark.slow, pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="distributed is not installed")]

from adm_calib.study import execution  # noqa: E402


def test_local_cluster_workers_run_without_profiler_and_with_glibc_malloc_defaults(monkeypatch):
    from distributed import Client

    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    cluster = execution.local_cluster(1)
    try:
        with Client(cluster, set_as_default=False) as client:
            seen = list(client.run(execution._worker_settings).values())
            env = list(client.run(execution._worker_env).values())
    finally:
        cluster.close(timeout=20)
    assert len(seen) == 1
    assert seen[0] == {"distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "1s",
                       "distributed.admin.system-monitor.interval": "5s",
                       "distributed.worker.memory.monitor-interval": "1s", "MALLOC_TRIM_THRESHOLD_": None}
    assert env == [{"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}]


_FAULTS = """
import resource
import numpy as np
a = None
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):  # a 1 MB table built and dropped, as a batch's tables are
    a = np.ones(1 << 17)
    del a
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _faults(env):
    out = subprocess.run([sys.executable, "-c", _FAULTS], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return int(out.stdout.split()[-1])


@pytest.mark.slow
def test_dask_trim_threshold_faults_every_table_in_again_and_the_default_does_not():
    base = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    trimmed = _faults({**base, "MALLOC_TRIM_THRESHOLD_": "65536"})
    default = _faults(base)
    # 20 tables of 256 pages: with the trim threshold every one is mapped and faulted in anew
    # (5140 faults measured), with glibc's defaults the first one only (501)
    assert trimmed >= 10 * 256
    assert default < trimmed / 4
    assert resource.getpagesize() in (4096, 16384, 65536)
