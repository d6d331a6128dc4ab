"""SIGINT and SIGTERM as one ``KeyboardInterrupt`` raised where it can reach the runner (core, no rclpy).

Python runs a signal's handler in the main thread at the next line it executes, wherever that is.
Raised inside a weakref callback (the import machinery's module locks have one), a ``__del__`` or
a garbage-collector callback, the ``KeyboardInterrupt`` cannot propagate: Python prints "Exception
ignored in ... Traceback" and the interrupt is lost, the command runs on. Here the handler
(:func:`raise_interrupt`) remembers which signal it turned into the interrupt, and the
``sys.unraisablehook`` installed with it (:func:`armed`) takes such a lost interrupt and has the
same signal tripped again a moment later (``_thread.interrupt_main`` from a helper thread, no second
OS signal): it is raised at the next line that can pass it on, or, lost again, tripped again. Exactly one interrupt reaches the caller per signal.

:func:`held` is a block where a signal does not raise (the renames of an output set): one that
arrives meanwhile is raised at the end of the block. It holds the signals back for the main
thread's own handler, whichever thread the system delivered them to (a thread's signal mask holds
back only what is delivered to that thread).
"""

from __future__ import annotations

import _thread
import contextlib
import signal
import sys
import threading
import time


class _State:
    armed = 0        # depth of :func:`armed` blocks
    last = None      # the signal the handler last turned into a KeyboardInterrupt, until it is seen through
    in_hook = False  # the unraisable hook is running (an interrupt raised there would be lost too)
    held = 0         # depth of :func:`held` blocks
    pending = None   # a signal that came during a held block


_STATE = _State()
#: How long the helper thread waits before it trips a lost signal again (the main thread leaves
#: the hook meanwhile; if it has not, the trip is put off again).
AGAIN_S = 0.001


def raise_interrupt(signum, frame):
    """The handler of SIGINT and SIGTERM while a command runs: ``KeyboardInterrupt`` (or, within
    :func:`held`, the signal kept for the block's end)."""
    if _STATE.held:
        _STATE.pending = signum
        return
    if _STATE.in_hook:  # raised here it would be lost as well: later
        _trip_later(signum)
        return
    _STATE.last = signum
    raise KeyboardInterrupt


def _trip_later(signum):
    """Trip ``signum`` again from a helper thread once this line of the main thread is left: Python
    then runs its handler at the main thread's next line (``_thread.interrupt_main``; no OS signal)."""
    def trip():
        time.sleep(AGAIN_S)
        _thread.interrupt_main(signum)

    threading.Thread(target=trip, name="adm-sim interrupt", daemon=True).start()


def _unraisable(previous):
    def hook(unraisable):
        signum = _STATE.last
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and signum is not None:
            _STATE.last = None
            _STATE.in_hook = True
            try:
                _trip_later(signum)
            finally:
                _STATE.in_hook = False
            return
        previous(unraisable)

    return hook


@contextlib.contextmanager
def armed():
    """Within the block a ``KeyboardInterrupt`` of :func:`raise_interrupt` that lands where Python
    cannot pass it on is raised again at the next line that can. Off the main thread: nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = sys.unraisablehook
    sys.unraisablehook = _unraisable(previous)
    _STATE.armed += 1
    try:
        yield
    finally:
        _STATE.armed -= 1
        sys.unraisablehook = previous
        if not _STATE.armed:
            _STATE.last = None


@contextlib.contextmanager
def held():
    """Within the block SIGINT and SIGTERM do not raise; one that came is raised as
    ``KeyboardInterrupt`` at its end. For the main thread's handler :func:`raise_interrupt`, and,
    where Python's own handlers are set (library use), by the main thread's signal mask."""
    on_main = threading.current_thread() is threading.main_thread()
    sigs = {signal.SIGINT, signal.SIGTERM}
    old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, sigs) if on_main else None
    _STATE.held += 1
    try:
        yield
    finally:
        _STATE.held -= 1
        if old_mask is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)
        if not _STATE.held and _STATE.pending is not None:
            signum, _STATE.pending = _STATE.pending, None
            raise_interrupt(signum, None)
