"""The scene's step rule (``config.step_rule.scene_dt``) at the ends of a float's range: no
internal error, no hang and no "inf" in a line for any finite number a user can type; one line,
exit 2, where a value cannot be honoured (issue 116 item 3)."""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import pytest

from swe_sphere.config.hyperviscosity import auto_every
from swe_sphere.config.scene import load_scene
from swe_sphere.core.clock import MAX_STEPS, Clock
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import SceneError

from helpers import cli_main, one_line


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def test_a_run_and_an_output_interval_of_1e308_days_are_refused_in_one_line(capsys):
    """`run tc2_steady --ne 4 --days 1e308 -s output.every_days=1e308` ended in "internal error:
    OverflowError" in ``Clock.fitted`` (1e308 days in seconds); now the run's steps are counted
    exactly and refused as too many."""
    args = ("run", "tc2_steady", "--ne", "4", "--days", "1e308", "-s", "output.every_days=1e308")
    code, out, err = cli_main(capsys, *args, "--output", "c.nc")
    one_line(code, err, 2, "dt = 1200 s gives more than 1e+308 steps to day 1e+308 (more than 1e+09)")
    assert not list(Path().iterdir())


def test_a_clock_fits_intervals_past_a_floats_range_exactly():
    """span / ⌈span / Δt⌉ in exact arithmetic where span / Δt overflows, rounded once."""
    span = Fraction(10**308) * 86400
    assert Clock(1200.0).fitted(1e308).dt == float(span / math.ceil(span / 1200))
    assert Clock(1e-300).fitted(1.0).dt == float(Fraction(86400) / math.ceil(Fraction(86400) / Fraction(1e-300)))
    assert Clock(300.0).fitted(1.0, 5.0).dt == 300.0  # in a float's range as before


@pytest.mark.parametrize(
    "ne, value, words",
    [(4, "1e308", "is inf s, past a float's range"), (64, "5e-324", "is 0 s, below a float's range")],
)
def test_a_time_dt_scaled_past_a_floats_range_is_refused(capsys, ne, value, words):
    """`-s time.dt=1e308 --ne 4` printed "warning: dt cut infx (from inf s ...)" and ran at one
    step a day; `-s time.dt=5e-324` scaled to a finer grid divided by zero."""
    code, out, err = cli_main(capsys, "run", "tc5_mountain", "--ne", ne, "-s", f"time.dt={value}", "--days", "0.1")
    line = one_line(code, err, 2, "time.dt = ", "s of scene tc5_mountain scaled with the smallest node spacing", words)
    assert "--dt" in line and not list(Path().iterdir())


def test_a_cut_past_a_floats_range_says_so():
    """A run of 5e-324 days is one step of a dt 1200 s over 2.4e321 times as short: the note
    says "more than 1e+308x", not "infx"."""
    s = load_scene("tc2_steady", ne=4, days=5e-324)
    assert s.nsteps == 1 and s.dt == 5e-324 * DAY
    assert s.notes[0].startswith("warning: dt cut more than 1e+308x (from 1200 s, scaled with the smallest node")


def test_a_hyperviscosity_past_a_floats_range_is_refused():
    """galewsky at an e-folding time of 1e-300 h: ν ∝ a⁴ / τ raised OverflowError (a planet of
    1e308 m did too; [planet] now refuses it, core/constants PLANET_RANGE)."""
    with pytest.raises(
        SceneError, match=r"^hyperviscosity.nu on ne=12 np=8 and a planet of radius 6.37122e\+06 m is past"
    ):
        load_scene("galewsky", overrides={"hyperviscosity.efold_hours": 1e-300})


def test_the_auto_schedule_of_tiny_steps_or_a_weak_hyperviscosity_ends():
    """``every = "auto"`` searched k from span / Δt down to half of it, one by one: a Δt of 1e-9 s
    (galewsky at ne4), a run of 1e-9 days or a 1e20 h e-folding hung ``load_scene``. The search
    takes the fewer of the divisors and cofactors, k is at most the run's steps (the ∇⁴ once, at
    its end, where the span holds more), and a Δt priced for a sparser ∇⁴ is one of a run within
    ``MAX_STEPS``."""
    with pytest.raises(SceneError, match=r"^dt = 3e-09 s gives 1.73e\+14 steps to day 6 \(more than 1e\+09\)$"):
        load_scene("galewsky", ne=4, overrides={"time.dt": 1e-9})
    weak = load_scene("galewsky", overrides={"hyperviscosity.efold_hours": 1e20})
    assert (weak.dt, weak.nsteps, weak.hypervis_every) == (load_scene("galewsky").dt, 3288, 3288)
    short = load_scene("galewsky", ne=4, days=1e-9)  # 28.8 min of 8.64e-5 s steps: k was 2e7
    assert (short.nsteps, short.hypervis_every) == (1, 1)
    # the largest k in 5..10 that divides 499 (prime) or 2994 = 2·3·499: 6; as the search one by one
    assert auto_every(1800.0, DAY / 499, (499, 2994)) == 6
    # span / Δt = 1e7: k in 5e6..1e7; 14e6's largest divisor there is 7e6 (its cofactor 2, found first)
    assert auto_every(1e7, 1.0, (3, 14_000_000)) == 7_000_000
    # none within (20_000_003 is odd, and neither 3 nor 4 divides it): span / Δt itself
    assert auto_every(1e7, 1.0, (4_999_999, 20_000_003)) == 10_000_000
    # a count beyond the search's reach (10⁴⁰⁰ steps: an output interval past any run) is not searched
    # (one by one down from 999_999_999, its first divisor there, 2²·5¹², lies 2.3e7 candidates away)
    assert auto_every(1800.0, 1e-300, (10**400, MAX_STEPS - 1)) == MAX_STEPS - 1


def test_a_dt_np_ratio_past_a_floats_range_is_refused():
    """tc5_mountain (np 4) with ``time.dt_np = {4 = 5e-324}`` at np 6: the factor 1 / 5e-324 is
    inf, and its scaled dt ran into ``Clock.fitted``'s overflow."""
    with pytest.raises(
        SceneError, match=r"^time.dt_np: the factor at np 6 over np 4's is inf, out of a float's range$"
    ):
        load_scene("tc5_mountain", np_=6, overrides={"time.dt_np": {"4": 5e-324}})
