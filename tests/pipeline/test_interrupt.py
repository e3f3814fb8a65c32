"""Ctrl-C as a stop request (laser_corners.pipeline.interrupt)."""

from __future__ import annotations

import os
import signal
import time

import pytest

from laser_corners.pipeline.interrupt import stop_requests


@pytest.fixture
def python_sigint():
    """Python's own SIGINT handler for the test (a background parent may have ignored it)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_first_ctrl_c_sets_the_event_second_interrupts(python_sigint) -> None:
    with stop_requests() as stop:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
        assert stop.is_set()  # no KeyboardInterrupt: the loop stops where it chooses
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_handler_of_the_caller_is_left_alone(python_sigint) -> None:
    calls = []
    signal.signal(signal.SIGINT, lambda *_: calls.append(1))
    with stop_requests() as stop:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
    assert calls == [1] and not stop.is_set()


def test_sigterm_is_a_stop_request_when_asked_for(python_sigint) -> None:
    previous = signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        with stop_requests() as stop:  # not asked for: SIGTERM keeps its handler
            assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
        with stop_requests(terminate=True) as stop:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)
            assert stop.is_set() and stop.signum == signal.SIGTERM
            assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # a second one kills
            os.kill(os.getpid(), signal.SIGINT)  # a later Ctrl-C does not change the reason
            time.sleep(0.05)
            assert stop.signum == signal.SIGTERM
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    finally:
        signal.signal(signal.SIGTERM, previous)
