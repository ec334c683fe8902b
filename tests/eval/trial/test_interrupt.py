"""eval.trial.interrupt: the first Ctrl-C asks, check() raises between frames, a second raises at once."""

import signal
import threading

import pytest

from eval.trial.interrupt import DeferredInterrupt


def test_the_first_ctrl_c_waits_for_check_and_a_second_raises_at_once():
    before = signal.getsignal(signal.SIGINT)
    with DeferredInterrupt() as stop:
        stop.check()
        signal.raise_signal(signal.SIGINT)  # nothing raised here: the trial finishes its frame
        assert stop.requested
        with pytest.raises(KeyboardInterrupt):
            stop.check()
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is before


def test_outside_the_main_thread_it_leaves_the_handler_alone():
    seen = []

    def worker():
        with DeferredInterrupt() as stop:
            seen.append(signal.getsignal(signal.SIGINT))
            stop.check()

    before = signal.getsignal(signal.SIGINT)
    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert seen == [before]
