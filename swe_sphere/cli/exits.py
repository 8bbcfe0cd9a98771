"""Exit statuses, and how the console script's process ends: SIGTERM unwound as
Ctrl-C, signals held once the outputs are closed, and ``exit_process``."""

from __future__ import annotations

import os
import sys

EXIT_INTERNAL, EXIT_BAD_INPUT, EXIT_BLOWUP = 1, 2, 3


class Terminated(KeyboardInterrupt):
    """SIGTERM outside the time loop, unwound like Ctrl-C (partial files dropped)."""

    signum = 15


def on_sigterm(signum, frame):
    raise Terminated()


_LATE: list[int] = []  # SIGINT/SIGTERM received after the console script's outputs were closed


def hold_signals() -> None:
    """From now on SIGINT/SIGTERM are noted, not raised: the outputs are closed (or a
    failure is being reported), and ``exit_process`` answers them."""
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, lambda signum, frame: _LATE.append(signum))


def exit_process(code: int):
    """End the console script with ``code``, or, after a successful command, with
    128 + signum and one line for a signal that came once its outputs were complete.
    Never returns. The interpreter's teardown is skipped (its atexit callbacks run):
    it takes about a second (garbage collection, Warp's modules) with the default
    signal dispositions back, so a Ctrl-C then ended the process silently with -2."""
    import atexit
    import signal

    def flush(stream):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (`| head`): nothing more can be said
            pass

    hold_signals()
    atexit._run_exitfuncs()
    flush(sys.stdout)  # may wait for a slow reader: a signal meanwhile is answered below
    if _LATE and code == 0:
        signum = min(_LATE)  # SIGINT before SIGTERM
        print(
            f"swe-sphere: interrupted by {signal.Signals(signum).name} after the command had finished; its output is complete",
            file=sys.stderr,
        )
        code = 128 + signum
    flush(sys.stderr)
    os._exit(code)
