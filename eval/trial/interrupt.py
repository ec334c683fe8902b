"""Ctrl-C that ends a trial between two frames, not in the middle of one.

Python raises ``KeyboardInterrupt`` wherever the main thread happens to be: inside a lock
of the render and sensor thread pools, half-way through a write to the video encoder's pipe.
A trial interrupted there can be left waiting on a lock it never released. Inside
:class:`DeferredInterrupt` the first Ctrl-C only asks the trial to stop; :meth:`check`,
called once a frame, raises ``KeyboardInterrupt`` at that safe point. A second Ctrl-C
raises at once, for a trial stuck inside one frame.
"""

from __future__ import annotations

import signal
import threading


class DeferredInterrupt:
    """A context in which SIGINT sets :attr:`requested` and :meth:`check` raises on it.

    Outside the main thread (where Python cannot handle signals) it changes nothing and
    :meth:`check` never raises.

    >>> with DeferredInterrupt() as stop:
    ...     stop.check()  # nothing asked yet
    ...     signal.raise_signal(signal.SIGINT)
    ...     stop.requested
    True
    """

    def __init__(self) -> None:
        self.requested = False
        self._installed = False
        self._previous = None  # the handler before ours (None if not set from Python: then Python's own)

    def _on_sigint(self, signum, frame) -> None:
        if self.requested:  # the second Ctrl-C: at once
            raise KeyboardInterrupt
        self.requested = True

    def check(self) -> None:
        """Raise ``KeyboardInterrupt`` if a Ctrl-C came since the context began."""
        if self.requested:
            raise KeyboardInterrupt

    def __enter__(self) -> DeferredInterrupt:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._on_sigint)
            self._installed = True
        return self

    def __exit__(self, *exc) -> None:
        if self._installed:
            previous = signal.default_int_handler if self._previous is None else self._previous
            signal.signal(signal.SIGINT, previous)
            self._installed = False
