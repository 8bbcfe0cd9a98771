"""The run's clock: Δt, the day of step 0 and the last day, and the one whole-step rule; and
the clock of a run replayed step by step (``StepTimes``: a gradient's, a controlled run's).

A scene's ``Clock`` holds the Δt of its step rule (``config.step_rule.scene_dt``) and is
asked by everything that counts steps: the scene's schedule checks, the output and restart
steps (``simulation.schedules``), the Python drive's intervals and its fitted Δt
(``integrator.core.FixedDt.fitted``: a new clock, made the run's by ``Intervals.use_dt`` alone), the run file's
times (``day``). Δt is decided in two places: the scene's step rule, and the one loop's Δt
policy (``integrator.core.FixedDt``, the plan's Δt, one fitted, or a run's replayed, ``StepTimes``;
``integrator.core.ControlledDt``, a step control's accepted steps); ``fitted`` here is the
arithmetic both use for a Δt that divides given intervals (the step rule, ``FixedDt.fitted``, the
sweep's ``dt_for_day``), deciding nothing alone. Oceananigans' ``Clock`` (time,
iteration, last Δt) and HOMME's ``timestep_make_parameters_consistent`` are the models.

The clock is the plan of a fixed-Δt run: step n is at ``start + n Δt``. An adaptive run (a
controller choosing Δt step to step) keeps this plan as its first Δt and its schedule, and
the loop owns the running state (step, time reached, last Δt): the fixed Δt is the special
case where that state is ``day(step)``. So nothing here assumes that Δt is the stepper's for
the whole run; only ``nsteps`` and ``day`` do, and they are the fixed plan's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from fractions import Fraction

from .constants import DAY
from .errors import ArgumentError, SceneError

MAX_STEPS = 10**9  # a run longer than this is a typo in dt, not a plan
MAX_TIMES = 10**5  # outputs or restart files in one run: more is a typo in the interval (1e-9 days)


def is_interval(days) -> bool:
    """Whether ``days`` is a number > 0 and finite."""
    return isinstance(days, (int, float)) and not isinstance(days, bool) and math.isfinite(days) and days > 0


def common_interval(*days: float) -> float:
    """The longest interval (days) that divides each of ``days``: their greatest common divisor
    as the decimals they are written as (0.5 and 0.75: 0.25; one interval: itself)."""
    parts = [Fraction(repr(float(d))) for d in days]
    denominator = math.lcm(*(p.denominator for p in parts))
    return float(Fraction(math.gcd(*(int(p * denominator) for p in parts)), denominator))


def count_text(n: float) -> str:
    """A count of steps or times (or a ratio) for a message: 3 digits, or "more than 1e+308" past a float's
    range (a run of 0.1 days with an interval of 5e-324 days)."""
    return f"{n:.3g}" if math.isfinite(n) else "more than 1e+308"


def _whole_step_days(dt: float) -> Fraction | None:
    """The shortest decimal number of days that is a whole number of steps of ``dt`` (s), when a
    day is a rational number of them with a denominator up to 1000 (dt = 86400/408 s: 0.125
    days, 51 steps); None otherwise."""
    per_day = Fraction(DAY / dt).limit_denominator(1000)
    if abs(per_day - DAY / dt) > 1e-9 * DAY / dt:
        return None
    twos_fives = math.gcd(per_day.numerator, 10**30)  # the 2s and 5s of the numerator: a decimal unit absorbs them
    return Fraction(per_day.denominator, twos_fives)


@dataclass(frozen=True)
class Clock:
    """A fixed-Δt run's clock.

    Attributes
    ----------
    dt : float
        The step (s), > 0.
    start : float
        The model day of step 0 (0, or the day a run branched at).
    end : float
        The last model day (from t = 0); the run is ``start`` to ``end``.
    source : str
        Where dt comes from, for the refusals: "the dt given", "time.dt of scene tc5_mountain", ...
    controlled : bool
        Δt chosen step to step (``Scene.control``): dt is the first step, and the run and its
        intervals need not be whole steps of it (``check``); steps land on their times.
    """

    dt: float
    start: float = 0.0
    end: float = 1.0
    source: str = "the dt given"
    controlled: bool = False

    @property
    def length(self) -> float:
        """The run's length (days): ``end`` − ``start``."""
        return self.end - self.start

    @property
    def nsteps(self) -> int:
        """The steps from ``start`` to ``end``."""
        return self.steps_in(self.length)

    def steps_in(self, days: float) -> int:
        """The one rounding of days to steps: the nearest whole number of steps in ``days``
        (whole or not: ``is_whole``); exact past a float's range (an interval of 1e308 days)."""
        steps = days * DAY / self.dt
        return round(steps) if math.isfinite(steps) else round(Fraction(days) * Fraction(DAY) / Fraction(self.dt))

    def times_in(self, every: float) -> int:
        """How many intervals of ``every`` days (> 0) end within the run (its length; a hair
        short counts): the outputs after step 0 (``schedules.output_marks``), ``check_times``'."""
        return math.floor(self.length / every + 1e-9)

    def is_whole(self, days) -> bool:
        """The one whole-step rule: ``days`` is a number > 0 and within 1e-6 of a step of a
        positive whole number of steps; or of more steps than a run takes (``MAX_STEPS``: no run
        reaches its end, and past 1e303 days a float cannot tell)."""
        if not is_interval(days):
            return False
        n = self.steps_in(days)
        return n > MAX_STEPS or n >= 1 and abs(n * self.dt - days * DAY) <= 1e-6 * self.dt

    def steps(self, days, what: str) -> int:
        """The whole number of steps in ``days``. Raises ``SceneError`` naming ``what``: an
        interval not > 0, or not whole steps (``refusal``)."""
        if not is_interval(days):
            raise SceneError(f"{what} must be a number of days > 0 (got {days!r})")
        if not self.is_whole(days):
            raise self.refusal(what, days)
        return self.steps_in(days)

    def refusal(self, what: str, days: float) -> SceneError:
        """The one refusal of an interval (``what`` of ``days`` days) that is not a whole number
        of steps: where dt comes from and the nearest intervals that are."""
        dt = self.dt
        unit = _whole_step_days(dt)
        if unit is not None:
            below = math.floor(Fraction(repr(days)) / unit) * unit
            near = " or ".join(f"{float(x):.10g}" for x in (below, below + unit) if x > 0)
            fits = f"whole-step intervals are the multiples of {float(unit):.10g} days (nearest: {near})"
        else:
            n = days * DAY / dt
            near = " or ".join(f"{k * dt / DAY:.6g}" for k in sorted({max(1, math.floor(n)), math.ceil(n)}))
            fits = f"the nearest whole-step intervals are {near} days"
        return SceneError(
            f"{what} of {days:g} days is not a whole number of steps of dt = {dt:g} s ({self.source}): "
            f"a run writes and ends at whole steps; {fits}, or set a dt that divides it"
        )

    def check_times(self, what: str, every: float) -> None:
        """Refuse (``SceneError`` naming ``what``) an interval of ``every`` days (> 0) that gives
        more than ``MAX_TIMES`` times (outputs, restart files) over the run: O(1), before any
        schedule is listed (a dt cut to divide 1e-9 days made 1e8 of them)."""
        times = self.length / every + 1e-9  # ``times_in`` unrounded: inf past a float's range (5e-324 days)
        if times >= MAX_TIMES + 1:
            raise SceneError(
                f"{what} of {every:g} days gives {count_text(times)} times over the run of "
                f"{self.length:g} days (more than {MAX_TIMES:.0e}): give a longer interval"
            )

    def check(self, intervals: dict[str, float] | None = None) -> None:
        """Refuse (``SceneError``) a run of more than ``MAX_STEPS`` steps, any of ``intervals``
        ({what: days}; output intervals) that gives more than ``MAX_TIMES`` times
        (``check_times``), a run length of no whole steps and any of ``intervals`` shorter than
        the run that is not whole steps; the first refusal wins. A ``controlled`` clock's steps
        land on the times: the whole-step refusals do not apply."""
        for what, every in (intervals or {}).items():
            self.check_times(what, every)
        if self.nsteps > MAX_STEPS:
            steps = count_text(self.length * DAY / self.dt)
            raise SceneError(
                f"dt = {self.dt:g} s gives {steps} steps to day {self.length:g} (more than {MAX_STEPS:.0e})"
            )
        if self.controlled:
            return
        if not self.is_whole(self.length):
            raise self.refusal("the run length", self.length)
        for what, every in (intervals or {}).items():
            if self.length > every and not self.is_whole(every):
                raise self.refusal(what, every)

    def day(self, step: int) -> float:
        """The model time of ``step`` in days: start + step × (length / nsteps), in exact
        rational arithmetic from the days as written (their shortest decimals), rounded once.
        So the output times are the multiples of the output interval as typed (3.0, where
        step × dt / 86400 gives 3.0000000000000004 for dt = 86400/408 s); a run continued to
        another length of whole steps gives the same times, and a branch at day 10 with
        another dt gives 10 + the multiples."""
        start = Fraction(repr(self.start))
        return float(start + (Fraction(repr(self.end)) - start) * int(step) / self.nsteps)

    def fitted(self, *intervals: float, source: str | None = None) -> Clock:
        """The clock with the longest Δt no longer than this one's that divides each of
        ``intervals`` (days; their ``common_interval``): span / ⌈span / Δt⌉, in exact arithmetic
        where span / Δt passes a float's range. ``source`` the new Δt's, for the refusals
        (default this one's)."""
        common = common_interval(*intervals)
        span = common * DAY
        steps = span / self.dt
        if math.isfinite(steps):
            dt = span / max(1, math.ceil(steps - 1e-9))
        else:  # past a float's range (an interval of 1e308 days; a Δt of 1e-300 s): exact, rounded once
            span = Fraction(repr(common)) * Fraction(DAY)
            dt = float(span / max(1, math.ceil(span / Fraction(self.dt))))
        return dataclasses.replace(self, dt=dt, source=self.source if source is None else source)


class StepTimes:
    """The steps' Δt and model times: step k (from x(k)) takes Δt_k, its stages at
    t0_k + (k + c)·Δt_k (a stepper's ``_at`` with ``t0`` and ``steps`` = k), as the run took them.
    Fixed (``history`` None): Δt_k = ``dt``, t0_k = ``start`` (s). Otherwise ``history`` a
    controlled run's accepted steps from ``start`` (``StepControl.history``: (time reached (s),
    Δt (s), error norm) each): Δt_k its k-th Δt, t0_k = t_k − k·Δt_k with t_k the time step k
    started at (``StepControl.step`` sets the stepper's clock so). ``ArgumentError`` for rows
    that are not numbers, a Δt that is not a positive finite number or times that do not
    increase, naming the step."""

    def __init__(self, start: float, dt: float, history=None):
        self.start, self.dt, self.steps = float(start), float(dt), None
        if history is None:
            return
        try:
            rows = [tuple(map(float, row[:2])) for row in history]
            assert all(len(row) == 2 for row in rows)
        except (TypeError, ValueError, IndexError, AssertionError):
            raise ArgumentError(
                f"history must be rows (time reached (s), dt (s), ...), a run's control.history (got {history!r:.60})"
            ) from None
        t, self.steps = self.start, []
        for k, (reached, step) in enumerate(rows):
            if not (math.isfinite(step) and step > 0 and math.isfinite(reached) and reached > t):
                raise ArgumentError(
                    f"history step {k}: dt {step!r} s must be > 0 and its time {reached!r} s after {t!r}"
                )
            self.steps.append((t - k * step, step))
            t = reached

    def __call__(self, k: int) -> tuple[float, float]:
        """(t0_k, Δt_k) of step k."""
        return (self.start, self.dt) if self.steps is None else self.steps[k]

    def set(self, stepper, k: int) -> None:
        """``stepper`` (or an adjoint: ``set_dt``, ``t0``) at step k's Δt and clock."""
        t0, dt = self(k)
        if dt != stepper.dt:  # a three-level stepper keeps one Δt; a controlled run's change step to step
            stepper.set_dt(dt)
        stepper.t0 = t0
