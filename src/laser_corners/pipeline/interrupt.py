"""Ctrl-C as a request to stop between two pieces of work.

A ``KeyboardInterrupt`` raised while numba's dispatcher or gtsam is running Python code can be
lost or turned into a ``SystemError`` ("returned a result with an exception set"): measured on
``laser-corners detect``, about one Ctrl-C in three was ignored and the run went on to its end.
So while a long loop runs in the main thread with Python's own SIGINT handler, SIGINT only
sets an event; the loop checks it between two scans or chunks and stops there. The handler is
put back at the first Ctrl-C, so a second one interrupts at once.

With ``terminate``, SIGTERM (a service manager stopping the run, ``kill``) is a stop request
too, when it has its default action; the event's ``signum`` tells which signal came first and
:data:`STOP_REASONS` names it.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["STOP_REASONS", "StopRequest", "stop_requests"]

STOP_REASONS = {signal.SIGINT: "interrupted (Ctrl-C)", signal.SIGTERM: "terminated (SIGTERM)"}
"""Why a run stopped early, by the signal that asked it to."""
_DEFAULTS = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}


class StopRequest(threading.Event):
    """An event set by a stop request; ``signum``: the first signal that set it."""

    def __init__(self) -> None:
        super().__init__()
        self.signum: int | None = None


@contextmanager
def stop_requests(terminate: bool = False) -> Iterator[StopRequest]:
    """An event set by Ctrl-C (and SIGTERM with ``terminate``) while the block runs (see the
    module notes).

    Outside the main thread, or for a signal with another handler (ignored, or the caller's
    own), nothing is installed for it and it does not set the event.
    """
    stop = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return
    signals = (signal.SIGINT, signal.SIGTERM) if terminate else (signal.SIGINT,)
    previous = {s: _DEFAULTS[s] for s in signals if signal.getsignal(s) is _DEFAULTS[s]}

    def request_stop(signum: int, frame: object) -> None:
        if stop.signum is None:
            stop.signum = signum
        stop.set()
        signal.signal(signum, previous[signum])  # a second one acts at once

    for signum in previous:
        signal.signal(signum, request_stop)
    try:
        yield stop
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
