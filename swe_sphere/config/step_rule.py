"""The scene's step rule: ``scene_dt``, the one function that decides a scene's Δt (the run's, and
the scene file's own for its default file names, ``Scene.own_dt``), given the grid's spacing,
the times Δt must land on and the ∇⁴'s span as a number (``hyperviscosity.every_span``). The
running policy (a fixed Δt, one fitted to a driver's output times, a controlled one) decides
every later Δt; nothing else does.

Every problem raises ``SceneError`` (a ValueError) with a one-line message naming the key.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ..core.arguments import got
from ..core.clock import MAX_STEPS, Clock, common_interval, count_text
from ..core.constants import DAY
from ..core.errors import SceneError
from ..model.hyperviscosity_plan import evaluations
from .hyperviscosity import Span, auto_every
from .resolve import Spacing
from .schema import SceneGrid, is_number

# the starts of the step rule's notes on how it scaled (and cut) dt: stale once a dt is given (a branch's)
DT_NOTES = ("dt scaled", "warning: dt cut")

# A ∇⁴ evaluation's cost against the rest of a step (one thread, CPU clock, medians of 9
# interleaved rounds, benchmarks/micro/step/hyperviscosity_every.py, results sparse_every_*.json): 0.76 for TC5 ne8
# np4 rk4, 1.04 for galewsky ne12 np8 kgu35, 1.08 at ne22 np6
HV_SHARE = 0.9
# A dt shortened for a sparser ∇⁴ only where that saves more than the cost model's own error: 2 %
SPARSE_GAIN = 0.98
# the most step counts past n that ``sparse_dt`` prices (the gains measured took 1 to 9 more)
SPARSE_SEARCH = 10**4


class Times(NamedTuple):
    """The times a scene's fixed Δt lands on (days): the run's last day ``days``, the output
    interval ``every``, the ``[[output.streams]]`` intervals that are numbers > 0 (``streams``,
    checked later), the run's restart interval (``restart``; None: none) and the day of its step
    0 (``start``: a branch's)."""

    days: float
    every: float
    streams: tuple = ()
    restart: float | None = None
    start: float = 0.0


def scene_dt(
    scene_dt: float | None,
    dt: float | None,
    scene: str,
    grid: SceneGrid,
    spacing: Spacing,
    times: Times,
    np_factor: float = 1.0,
    controlled: bool = False,
    span: Span | None = None,
) -> tuple[float, str, tuple]:
    """(Δt (s), where it comes from for messages, notes): the scene's step rule. ``dt`` as given;
    else scene ``scene``'s time.dt (``scene_dt``, for the scene file's grid, np and planet)
    times ``spacing.smallest`` (the run's smallest node spacing on ``grid`` over the scene
    file's) and ``np_factor`` (``resolve_dt_np``), shortened to divide the output interval, the
    streams' and the run (``Clock.fitted``; a note where that cuts it more than 2x), then the
    restart interval (a note), then where the ∇⁴'s ``span`` is given with its stiffness, to
    the count of steps that costs least a day with the ∇⁴ every ``auto_every`` steps
    (``sparse_dt``; a run of more than ``MAX_STEPS`` steps is not priced: it is refused). The
    schedule is checked (``Clock.check``; with ``controlled`` steps, Δt is the first and need
    not divide it). Raises ``SceneError``: no time.dt, one ≤ 0, one that scales past a float's
    range, a run of too many steps, a run or output interval of no whole steps."""
    if dt is not None:
        source, notes = "the dt given", ()
    elif scene_dt is None:
        raise SceneError("time.dt is missing")
    elif not scene_dt > 0:
        raise SceneError(f"time.dt must be > 0 (got {scene_dt})")
    elif spacing.smallest == 1.0 and np_factor == 1.0:
        dt, source, notes = scene_dt, f"time.dt of scene {scene}", ()
    else:
        dt, source, notes = _scaled_dt(scene_dt, times, scene, grid, spacing, np_factor)
        dt, notes = _restart_cut(dt, times, notes)
        if span is not None and span.stiffness is not None and Clock(dt, 0.0, times.days).nsteps <= MAX_STEPS:
            shorter = sparse_dt(dt, _landings(times), times.every, times.days, span)
            if shorter != dt:
                notes = (
                    *notes,
                    f"dt {dt:g} s shortened to {shorter:g} s: more steps, the ∇⁴ less often (cheaper a day)",
                )
                dt = shorter
    if not (is_number(dt) and math.isfinite(dt) and dt > 0):
        raise SceneError(f"dt must be > 0 (got {got(dt)})")
    Clock(dt, times.start, times.days, source, controlled).check(
        {"the output interval (output.every_days)": times.every}
    )
    return dt, source, notes


def _landings(times: Times) -> tuple:
    """The intervals (days) a Δt shortened for the ∇⁴ still divides: the run, and the output,
    stream and restart intervals shorter than it."""
    within = [d for d in (*times.streams, times.restart) if d is not None and d < times.days]
    return (times.days, *within, *([times.every] if times.every < times.days else []))


def _restart_cut(dt: float, times: Times, notes: tuple) -> tuple[float, tuple]:
    """(Δt, notes) of a scaled ``dt`` cut to divide the restart interval too (a note says so);
    too many restart files refused first (``Clock.check_times``)."""
    restart, days = times.restart, times.days
    if restart is None:
        return dt, notes
    clock = Clock(dt, 0.0, days)
    clock.check_times("the restart interval", restart)
    if clock.is_whole(restart):
        return dt, notes
    cut = clock.fitted(days, restart, *(e for e in (times.every, *times.streams) if e < days)).dt
    return cut, (*notes, f"dt cut from {dt:g} s to {cut:g} s to divide the restart interval of {restart:g} days")


def _scaled_dt(scene_dt: float, times: Times, scene: str, grid: SceneGrid, spacing: Spacing, np_factor: float):
    """``scene_dt``'s (dt, source, notes) of a scene's dt scaled to another spacing (and np,
    ``np_factor``): the longest that divides the run and, where shorter, the output interval and
    the streams'. Raises ``SceneError`` where the scaled dt is 0 or past a float's range."""
    days, every = times.days, times.every
    spans = (days,) if days <= every else (every, days)
    shorter = tuple(e for e in times.streams if e < days)  # a stream's interval writes within the run
    if shorter and common_interval(*spans, *shorter) != common_interval(*spans):
        spans, every = (*spans, *shorter), min(every, *shorter)  # the message names the shortest
    scaled = scene_dt * spacing.smallest * np_factor
    radius, file_radius = spacing.radii
    moved = spacing.scale != 1.0  # the planet's radius; file_radius is a number then
    where = grid.record.description(grid.np) + (f" radius={radius:g} m" if moved else "")
    # what the smallest node spacing changed with: the grid, the planet's radius or both
    changes = ["the smallest node spacing"] if spacing.smallest != spacing.scale else []
    if moved:
        changes.append(f"the planet's radius ({radius:g} m against the scene's {file_radius:g} m)")
    if np_factor != 1.0:
        changes.append(f"time.dt_np ({np_factor:g}x at np {grid.np})")
    why = " and ".join(changes)
    if not (math.isfinite(scaled) and scaled > 0):
        raise SceneError(
            f"time.dt = {scene_dt:g} s of scene {scene} scaled with {why} to {where} is {scaled:g} s, "
            f"{'past' if scaled else 'below'} a float's range: give a {'shorter' if scaled else 'longer'} "
            "time.dt, or a --dt"
        )
    dt = Clock(scaled, 0.0, days).fitted(*spans).dt
    source = f"time.dt of scene {scene} scaled to {where}"
    if scaled / dt <= 2:
        return dt, source, (f"dt scaled with {why} to {dt:g} s",)
    # one line for both: "scaled to" the cut dt read as if the grid had asked for it
    if days <= every:
        what = f"the run length of {days:g} days"
    elif common_interval(*spans) == every:
        what = f"the output interval of {every:g} days"
    else:
        what = f"both the output interval of {every:g} and the run length of {days:g} days"
    cut = f"warning: dt cut {count_text(scaled / dt)}x (from {scaled:g} s, scaled with {why}) to {dt:g} s to divide {what}"
    return dt, source, (cut,)


def sparse_dt(dt: float, intervals: tuple, every: float, days: float, span: Span) -> float:
    """The Δt (s) no longer than ``dt`` that costs least a day with the ∇⁴ every ``auto_every``
    steps: C/n' for n' ≥ n = C/Δt whole steps of C, the ``common_interval`` of ``intervals``
    (days: the run and the intervals that Δt divides), minimising n'(1 + ``HV_SHARE`` e(n')/k(n')),
    e the ∇⁴'s evaluations over kΔt (``evaluations`` at ν λ kΔt = ``span.stiffness`` kΔt, with
    ``span.subcycle``), k within ``span.span``, the fewest steps where two cost the same, n'
    at most ``SPARSE_SEARCH`` past n; ``dt`` itself where it is not C/n or that saves less than
    ``SPARSE_GAIN``. A count of steps with few divisors takes a small k: TC5 ne8 np4's odd 109 a
    day k = 1, its 110 k = 2 (a step 0.785x, a day 0.79x); galewsky ne24 np6's 499, a prime,
    k = 6 in 2 RKL1 stages, its 508 k = 8 in 2 (0.333 to 0.25 evaluations a step, a day 0.865x;
    docs/explanation/efficiency.md, "A Δt for a sparser ∇⁴")."""
    common = common_interval(*intervals) * DAY
    n = round(common / dt)
    if n < 1 or abs(common / n - dt) > 1e-9 * dt:
        return dt

    def cost(m: int) -> float:
        step = common / m
        clock = Clock(step)
        k = auto_every(span.span, step, (clock.steps_in(every), clock.steps_in(days)))
        return m * (1 + HV_SHARE * evaluations(span.stiffness * k * step, span.subcycle)[0] / k)

    # k(m) ≤ span·m/C and a ∇⁴ takes one evaluation at least: no more steps than this can pay
    top = min(math.floor(cost(n) - HV_SHARE * common / (span.span * (1 + 1e-9))), n + SPARSE_SEARCH)
    best = min(range(n, max(n, top) + 1), key=cost)  # the first, the fewest steps, of equal costs
    return common / best if cost(best) <= SPARSE_GAIN * cost(n) else dt
