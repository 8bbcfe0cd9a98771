"""``swe-sphere`` as its console script runs it, held at a point a test names, so
that the test's signal comes at that point by construction, not after a guessed
sleep (a faster or busier machine changes nothing):

    python paused_run.py WHERE MARKER swe-sphere-arguments...

WHERE is one of

``start-up``     inside the import of Warp (``warp`` half initialised, ten of its
                 modules loaded), before any of the command's work;
``step:N``       after step N's check, between steps (every rank under mpiexec);
``inside-step``  inside step 1, which never ends: real steps of the scene's
                 stepper repeated on its state until the run abandons it.

The process writes MARKER (its pid) when it gets there, then waits (but for
``inside-step``) until SIGINT or SIGTERM has been handled by the handler in
place, or until MARKER with the suffix ``.go`` exists; then it goes on.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

WHERE, MARKER = sys.argv[1], Path(sys.argv[2])
SIGNALS = (signal.SIGINT, signal.SIGTERM)
_got: list[int] = []


def _note_signals():
    """From now on a SIGINT/SIGTERM is noted, then handled by the handler in place."""
    for sig in SIGNALS:
        handler = signal.getsignal(sig)
        if callable(handler) and getattr(handler, "__name__", "") != "noted":

            def noted(signum, frame, handler=handler):
                _got.append(signum)
                handler(signum, frame)  # may raise (KeyboardInterrupt at start-up)

            signal.signal(sig, noted)


def _arrive_and_wait():
    MARKER.write_text(str(os.getpid()))
    deadline = time.monotonic() + 300  # a test that never signals fails instead of hanging
    while not _got and not MARKER.with_suffix(".go").exists():
        if time.monotonic() > deadline:
            raise RuntimeError(f"paused_run.py: nothing came at {WHERE}")
        time.sleep(0.01)


if WHERE == "start-up":

    class _HoldInWarp:  # deep inside Warp's import: `warp` half initialised, ten of its modules loaded
        def find_spec(self, name, path=None, target=None):
            if name.startswith("warp.") and sum(m.startswith("warp.") for m in sys.modules) >= 10:
                sys.meta_path.remove(self)
                _note_signals()
                _arrive_and_wait()
            return None

    sys.meta_path.insert(0, _HoldInWarp())
else:
    from swe_sphere.simulation import simulation

    run = simulation.Simulation.run

    def held_run(self, *args, **kwargs):
        step, check, watch, calls = self.stepper.step, self.model.bad_nodes.first, self.model.bad_nodes.watch, [0]
        if WHERE == "inside-step":

            def endless_step(x):
                MARKER.write_text(str(os.getpid()))
                while True:
                    step(x)

            self.stepper.step = endless_step
        else:

            def held(check):  # every step is checked once, at once or on the device (``Simulation.check_every``)
                def held_check(x):
                    calls[0] += 1
                    if calls[0] == 1:
                        _note_signals()  # the run's handlers are in place: a signal from now on is noted
                    if calls[0] == int(WHERE.removeprefix("step:")):
                        _arrive_and_wait()
                    return check(x)

                return held_check

            self.model.bad_nodes.first, self.model.bad_nodes.watch = held(check), held(watch)
        return run(self, *args, **kwargs)

    simulation.Simulation.run = held_run

sys.argv = ["swe-sphere", *sys.argv[3:]]
from swe_sphere.cli import main  # noqa: E402

sys.exit(main())
