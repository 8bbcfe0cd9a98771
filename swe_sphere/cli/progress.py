"""A run's progress as a line every so many seconds of wall time, for a log where no bar is
drawn (a pipe, ``nohup``, CI: stderr not a terminal), as HOMME, Oceananigans and SpeedyWeather
print theirs: ``ProgressLines``, the console script's (``run --progress-every``), handed to
``Simulation.run``, which calls its ``start`` and ``tick`` alone."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

PROGRESS_SECONDS = 30.0  # the console script's interval off a terminal (``run --progress-every``)


clock = time.monotonic  # seconds of wall time; a test replaces it


class ProgressLines:
    """``write(line)`` of the model day reached, the share of the run done, the wall time so far
    and an estimate of what is left, at the first step that ends ``every`` seconds (wall time,
    not steps: a line as often whatever the grid) after the run's start or the last line.
    ``start(day, end_day)`` when the loop begins, then ``tick(step, day)`` after its steps.
    The estimate is the pace since the first tick, not the start: the first block of steps
    compiles the stepper's kernels (a few seconds on a CPU, a first line 5 s into a 30 s run said
    "about 4 min left"); a line at the first tick has none."""

    def __init__(self, write: Callable[[str], None], every: float = PROGRESS_SECONDS):
        if not (isinstance(every, (int, float)) and not isinstance(every, bool) and every > 0):
            raise ValueError(f"a progress line's interval must be a number of seconds > 0 (got {every!r})")
        self.write, self.every = write, float(every)

    def start(self, day: float, end_day: float) -> None:
        self.day0, self.end = day, end_day
        self.t0 = self.last = clock()
        self.day1 = self.t1 = math.nan

    def tick(self, step: int, day: float) -> None:
        now = clock()
        if math.isnan(self.t1):  # the first block's end, its compiling behind it: the pace's origin
            self.day1, self.t1 = day, now
        if now - self.last < self.every:
            return
        self.last = now
        done = (day - self.day0) / (self.end - self.day0) if self.end > self.day0 else 1.0
        left = ""
        if 0 < done < 1 and day > self.day1:
            left = f", about {_span((now - self.t1) * (self.end - day) / (day - self.day1))} left"
        self.write(
            f"day {day:.4g} of {self.end:g} ({100 * done:.0f} %), step {step}, {_span(now - self.t0)} of wall time{left}"
        )


def _span(seconds: float) -> str:
    """``seconds`` as 42 s, 3 min 20 s or 2 h 05 min."""
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"
