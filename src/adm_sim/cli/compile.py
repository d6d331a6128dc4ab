"""``adm-sim compile``: compile every numba kernel once, at set-up rather than in the first real command."""

from __future__ import annotations

import sys

from adm_sim.cli.precompile import compile_kernels
from adm_sim.integrate import _jit


def add_arguments(parser):
    """``adm-sim compile`` takes no option."""


def run(args):
    """Compile every numba kernel once (:mod:`adm_sim.cli.precompile`), at set-up rather than in the first
    real command; with numba's cache in place it only loads the kernels."""
    if not _jit.numba_available():
        print("numba is not installed: the kernels run as plain Python, nothing to compile")
        return 0
    print("compiling kernels (once): every code path on a tiny case; numba keeps the machine code in __pycache__ "
          "beside the source (15-60 s the first time on a quiet 2-core machine, a few seconds once cached)",
          file=sys.stderr, flush=True)
    _jit.notice_given()
    total = compile_kernels(report=lambda name, s: print(f"  {name}: {s:.2f} s", flush=True))
    print(f"kernels ready in {total:.2f} s; later runs load them from the cache")
    return 0
