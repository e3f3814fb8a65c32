"""Ctrl-C as a request to stop between two pieces of work.

A ``KeyboardInterrupt`` raised while numba's dispatcher or gtsam is running Python code can be
lost or turned into a ``SystemError`` ("returned a result with an exception set"): measured on
``laser-corners detect``, about one Ctrl-C in three was ignored and the run went on to its end.
So while a long loop runs in the main thread with Python's own SIGINT handler, SIGINT only
sets an event; the loop checks it between two scans or chunks and stops there. The handler is
put back at the first Ctrl-C, so a second one interrupts at once.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["stop_requests"]


@contextmanager
def stop_requests() -> Iterator[threading.Event]:
    """An event set by Ctrl-C while the block runs (see the module notes).

    Outside the main thread, or when SIGINT has another handler (ignored, or the caller's
    own), nothing is installed and the event is never set.
    """
    stop = threading.Event()
    in_main = threading.current_thread() is threading.main_thread()
    if not in_main or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield stop
        return
    previous = signal.getsignal(signal.SIGINT)

    def request_stop(signum: int, frame: object) -> None:
        stop.set()
        signal.signal(signal.SIGINT, previous)

    signal.signal(signal.SIGINT, request_stop)
    try:
        yield stop
    finally:
        signal.signal(signal.SIGINT, previous)
