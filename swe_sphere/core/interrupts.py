"""SIGINT and SIGTERM during a run: stop after a complete step, or abandon a step that goes on."""

from __future__ import annotations

import signal
import threading
import time

ABANDON_AFTER = 1.0  # s a step may go on after SIGINT/SIGTERM before it is abandoned


class StepAbandoned(BaseException):
    """Raised from the signal handlers into a step that goes on ``ABANDON_AFTER``
    s after a stop was asked (a BaseException, so no solver's ``except`` keeps it)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


class StopSignals:
    """While entered (``catch``, main thread only): SIGINT and SIGTERM are noted,
    not raised, and the loop stops at the next step all ranks agree on (``asked``);
    a step still going on ``ABANDON_AFTER`` s after the signal (one process only:
    ranks must stop at the same step) gets ``StepAbandoned`` raised into it. A
    parent's "ignore" (nohup, ``&``) is respected. The loop sets ``in_step`` to
    ``time.perf_counter()`` at the start of a step and to None after it."""

    def __init__(self, topology, catch: bool):
        self.topology, self.catch = topology, catch
        self.stop: list[int] = []
        self.in_step: float | None = None
        self._handlers = {}

    def __enter__(self) -> StopSignals:
        if self.catch and threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                if signal.getsignal(sig) is not signal.SIG_IGN:
                    self._handlers[sig] = signal.signal(sig, self._on_signal)
            if self._handlers:
                self._handlers[signal.SIGALRM] = signal.signal(signal.SIGALRM, self._abandon)
        return self

    def __exit__(self, *exc) -> None:
        if self._handlers:
            signal.setitimer(signal.ITIMER_REAL, 0)
        for sig, handler in self._handlers.items():
            signal.signal(sig, handler)

    def asked(self) -> int:
        """The signal that asked the run to stop on any rank, else 0 (call on every rank)."""
        return int(self.topology.max(self.stop[0] if self.stop else 0))

    def _abandon(self, signum, frame):  # SIGALRM: a stop was asked ABANDON_AFTER s ago and the step goes on
        if self.in_step is not None and self.stop:
            self.in_step = None
            raise StepAbandoned(self.stop[0])

    def _on_signal(self, signum, frame):
        self.stop.append(signum)
        if self.in_step is not None and self.topology.comm.size == 1:  # ranks must stop at the same step
            if time.perf_counter() - self.in_step > ABANDON_AFTER:
                self._abandon(signum, frame)
            signal.setitimer(signal.ITIMER_REAL, ABANDON_AFTER)
