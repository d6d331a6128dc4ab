"""The compiled kernels run as plain Python give the compiled result (the promise of
:mod:`adm_sim.integrate.kernels`: one source, numba optional).

A subprocess with ``NUMBA_DISABLE_JIT=1`` runs :class:`adm_sim.integrate.compiled_batch.BatchRunner` (so
``kernels.dim_blocks``, ``kernels.mlm_blocks`` and the inlined ``hermite_max_abs_acc`` as plain
Python) on a small case: a 10 m bridge (f_1 = 5 Hz, two mass factors) under ICE-2 at 200 and
300 km/h, dense maxima on, advanced in blocks of 97 steps. Its per-lane maxima must equal the
compiled run's to 1e-12 relative (compiled loops may only reorder nothing: the same operation
order, so in practice they agree bit for bit).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.slow  # every test here starts processes

SCRIPT = r"""
import json
import numpy as np
from adm_calib.calibrate import batch_step
from adm_calib.study import select_cases
from adm_sim.integrate import kernels
from adm_sim.integrate.compiled_batch import BatchRunner
from adm_sim.inputs.train_files import load_train

bridges = [c.bridge for c in select_cases(["ICE-2"], ["mu1", "mu6"], (10, 10), [5])]
train = load_train("ICE-2")
runner = BatchRunner(bridges, train, 6.0 * batch_step(bridges, train).ds_m, dense_maxima=True)
out = {"compiled": hasattr(kernels.dim_blocks, "py_func")}
for model in ("mlm", "dim"):
    run = runner.start(model, [0, 1], [200.0, 300.0], [0.0, 0.002])
    while run.status == "running":
        run.advance(97)
    out[model] = [run.status, run.k, run.max_acc_m_s2.tolist(), run.max_disp_m.tolist()]
print(json.dumps(out))
"""


def _run(disable_jit):
    env = dict(os.environ)
    env["NUMBA_DISABLE_JIT"] = "1" if disable_jit else "0"
    res = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


def _run_here():
    """The same script in this process, on the compiled kernels (no second Python start for the
    compiled side: only the plain-Python side needs its own process, NUMBA_DISABLE_JIT being read
    at import)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(SCRIPT, "<compiled side>", "exec"), {"__name__": "compiled_side"})
    return json.loads(out.getvalue().strip().splitlines()[-1])


@pytest.fixture(scope="module")
def both():
    return _run_here(), _run(True)


@pytest.mark.parametrize("model", ["mlm", "dim"])
def test_plain_python_kernels_equal_the_compiled_ones(both, model):
    compiled, plain = both
    assert compiled["compiled"] and not plain["compiled"]  # the subprocess really ran plain Python
    c, p = compiled[model], plain[model]
    assert c[0] == p[0] == "finished" and c[1] == p[1] > 100
    for a, b in zip(c[2:], p[2:]):
        a, b = np.array(a), np.array(b)
        assert np.all(a > 0.0)  # a real response in every lane
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=0)
