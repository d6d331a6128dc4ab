"""Worker processes that end with the process that started them.

A :class:`concurrent.futures.ProcessPoolExecutor` worker is a child of the command that started
it; when that command is killed with SIGKILL it has no chance to stop its pool, and the workers,
re-parented to init, compute on (seen: ``adm-calib table4 --jobs 2`` killed, both workers still
busy 200 s later). :func:`die_with_parent` is the pool's initializer: on Linux it asks the kernel
(``prctl(PR_SET_PDEATHSIG)``, prctl(2)) to send the worker SIGKILL when its parent ends, and a
worker whose parent is already gone when it starts exits at once. Pool workers hold no output of
their own (results travel back to the parent, which writes them), so SIGKILL loses nothing.

The dask workers of the study need none of this: ``distributed`` starts each worker process
with a pipe to its nanny and ends it when the pipe closes.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys

#: ``PR_SET_PDEATHSIG`` from ``<linux/prctl.h>``.
PR_SET_PDEATHSIG = 1


def die_with_parent(parent_pid: int) -> None:
    """Initializer of a pool worker: end this process with SIGKILL when ``parent_pid`` ends.

    ``parent_pid`` is the pid of the process that creates the pool (``os.getpid()`` there): if it
    is not this process's parent any more (it died before the signal was armed), exit now.
    The death signal fires when the parent *thread* that forked the worker ends, so the pool must
    be created and submitted to from a thread that lives as long as the pool (the main thread of
    a command, as in :func:`adm_calib.table4.run_table4`).
    """
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != parent_pid:
        os._exit(1)
