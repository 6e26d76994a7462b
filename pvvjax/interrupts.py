"""Ctrl-C that always stops a command.

Python raises `KeyboardInterrupt` wherever the main thread happens to be. Raised inside an
object's finalizer or a library's callback, it is printed as "Exception ignored in …" and
lost, and the command would run on to exit 0. While `interruptible()` is active, a Ctrl-C
both interrupts at once (as usual) and is remembered, so that `check_interrupt()` at the
next safe point (a finished training segment, a pipeline stage, the command's end) raises
it again.
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["check_interrupt", "interruptible"]

_requested = [False]


def _handler(signum, frame):
    _requested[0] = True
    raise KeyboardInterrupt


@contextlib.contextmanager
def interruptible():
    """Remember every Ctrl-C while active (from the main thread; elsewhere a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, _handler)
    _requested[0] = False
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        _requested[0] = False


def check_interrupt() -> None:
    """Raise `KeyboardInterrupt` if a Ctrl-C came while `interruptible()` was active, even
    one that was swallowed where it landed; otherwise do nothing."""
    if _requested[0]:
        raise KeyboardInterrupt
