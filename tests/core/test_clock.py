"""The one clock (``core.clock``): steps of a duration, the whole-step rule and its one
refusal, the day of a step, the common interval and the fitted clock, with real numbers."""

from __future__ import annotations

import pytest

from swe_sphere.core.clock import MAX_STEPS, Clock, common_interval
from swe_sphere.core.errors import SceneError


def test_a_day_at_150_s_is_576_steps():
    clock = Clock(150.0, 0.0, 1.0)
    assert (clock.nsteps, clock.steps(1.0, "x"), clock.steps(0.25, "x")) == (576, 576, 144)
    assert clock.is_whole(1.0) and not clock.is_whole(0.0001) and not clock.is_whole(-1.0)
    assert clock.day(288) == 0.5 and clock.day(576) == 1.0
    # the one rounding of days to steps, whole or not, and the intervals that end within the run
    assert (clock.steps_in(0.1), clock.steps_in(1 / 3), clock.steps_in(0.0)) == (58, 192, 0)
    assert (clock.times_in(0.25), clock.times_in(0.3), clock.times_in(1 / 3), clock.times_in(2.0)) == (4, 3, 3, 0)


def test_a_tenth_of_a_day_at_7_s_is_refused_in_one_line():
    clock = Clock(7.0, 0.0, 1.0, "the dt given")
    assert not clock.is_whole(0.1)  # 8640 s = 1234.29 steps
    with pytest.raises(SceneError) as err:
        clock.steps(0.1, "the output interval")
    assert str(err.value) == (
        "the output interval of 0.1 days is not a whole number of steps of dt = 7 s (the dt given): a run "
        "writes and ends at whole steps; whole-step intervals are the multiples of 0.0021875 days (nearest: "
        "0.0984375 or 0.100625), or set a dt that divides it"
    )
    with pytest.raises(SceneError, match=r"^the restart interval must be a number of days > 0 \(got -1\)$"):
        clock.steps(-1, "the restart interval")


def test_a_dt_of_no_decimal_unit_names_the_nearest_intervals():
    """dt = 1000·π s: no day is a rational number of steps of small denominator."""
    clock = Clock(1000 * 3.141592653589793, 0.0, 1.0)
    assert "; the nearest whole-step intervals are 0.981748 or 1.01811 days," in str(clock.refusal("x", 1.0))


def test_the_check_refuses_a_run_length_an_interval_and_too_many_steps():
    Clock(300.0, 0.0, 5.0).check({"the output interval": 0.25})  # 72 steps each: whole
    Clock(300.0, 0.0, 0.125).check({"the output interval": 0.3})  # an interval longer than the run is not checked
    with pytest.raises(
        SceneError, match=r"^the output interval of 0.3 days is not a whole number of steps of dt = 1000"
    ):
        Clock(1000.0, 0.0, 5.0).check({"the output interval": 0.3})
    with pytest.raises(SceneError, match=r"^the run length of 1.3 days is not"):
        Clock(1000.0, 0.0, 1.3).check()
    with pytest.raises(SceneError, match=r"^dt = 1e-06 s gives 8.64e\+12 steps to day 100 \(more than 1e\+09\)$"):
        Clock(1e-6, 0.0, 100.0).check()
    assert MAX_STEPS == 10**9


def test_a_branch_counts_its_days_from_its_start():
    """A branch at day 1 to day 2 with dt = 86400/408 s: 408 steps, days 1 + the multiples as typed."""
    clock = Clock(86400 / 408, 1.0, 2.0)
    assert clock.nsteps == 408 and clock.length == 1.0
    assert clock.day(51) == 1.125 and clock.day(408) == 2.0


def test_common_interval_and_the_fitted_clock():
    assert common_interval(0.5, 0.75) == 0.25 and common_interval(0.3) == 0.3 and common_interval(1.0, 0.1) == 0.1
    # Galewsky at ne = 2: 3200 s, 13.5 steps in half a day; fitted to 43200/14 s, its source saying why
    fitted = Clock(3200.0, 0.0, 1.0, "time.dt of scene galewsky").fitted(0.5, 1.0, source="fitted")
    assert fitted.dt == 43200 / 14 and fitted.nsteps == 28 and fitted.source == "fitted"
    assert Clock(3200.0, 0.0, 1.0).fitted(1.0).dt == 86400 / 27  # 27 steps a day
    assert Clock(150.0).fitted(1.0).dt == 150.0  # already whole: unchanged


def test_an_interval_past_a_floats_range_is_counted_not_overflowed():
    """`run tc2_steady --days 0.1 --restart-every 1e308` ended in "internal error: OverflowError"
    (1e308 days is more seconds than a float holds): it is whole, reached by no run; 5e-324 days
    is refused as too many times, a dt of 5e-324 s as too many steps."""
    clock = Clock(2160.0, 0.0, 0.1)
    assert clock.is_whole(1e308) and clock.steps(1e308, "the restart interval") > MAX_STEPS
    clock.check({"the output interval": 1e308})
    with pytest.raises(SceneError, match=r"^the restart interval of 4.94066e-324 days gives more than 1e\+308 times"):
        clock.check_times("the restart interval", 5e-324)
    with pytest.raises(SceneError, match=r"^dt = 4.94066e-324 s gives more than 1e\+308 steps to day 0.1"):
        Clock(5e-324, 0.0, 0.1).check()
