"""Output times are the multiples of the output interval exactly (``Scene.day``),
so ``ds.h.sel(time=k)`` finds every output day, in a run and in its continuation."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from swe_sphere.cli import main
from swe_sphere.core.constants import DAY

STEPS_PER_DAY = 84  # dt = 86400/84 s: step * dt / 86400 misses 0.25, 0.5, 0.75, 1, ... by an ulp
DT = DAY / STEPS_PER_DAY
EVERY = 0.25


def _run(*args):
    code = main(["run", "tc2_steady", "--ne", "2", "--np", "4", "--device", "cpu", "--no-progress", *map(str, args)])
    assert code == 0


def test_the_step_of_this_test_misses_the_output_days_in_floating_point():
    """The case below would fail without exact times: step * dt / 86400 is not k/4."""
    steps = np.arange(1, 9) * STEPS_PER_DAY // 4
    assert np.count_nonzero(steps * DT / DAY != np.arange(1, 9) * EVERY) >= 6


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A 1-day run with a restart file, its continuation to day 2, and a straight 2-day run."""
    d = tmp_path_factory.mktemp("times")
    common = ("--dt", repr(DT), "-s", f"output.every_days={EVERY}")
    _run("--days", 1, *common, "--restart-every", 1, "--output", d / "first.nc")
    main(
        [
            "run",
            "--continue",
            str(d / "first.restart.nc"),
            "--days",
            "2",
            "--device",
            "cpu",
            "--no-progress",
            "--output",
            str(d / "cont.nc"),
        ]
    )
    _run("--days", 2, *common, "--output", d / "whole.nc")
    return d


def test_every_output_day_is_selectable(runs):
    with xr.open_dataset(runs / "first.nc", decode_times=False) as ds:
        assert ds.time.values.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
        for day in (0, 0.25, 0.5, 0.75, 1, 1.0):
            assert ds.h.sel(time=day).shape == (ds.sizes["ncol"],)
        assert ds.steps.sel(time=0.75) == 63


def test_a_continued_run_keeps_exact_times_and_bits(runs):
    with (
        xr.open_dataset(runs / "cont.nc", decode_times=False) as cont,
        xr.open_dataset(runs / "whole.nc", decode_times=False) as whole,
    ):
        assert cont.time.values.tolist() == [1.25, 1.5, 1.75, 2.0]  # day 1 is first.nc's last: not repeated
        assert cont.attrs["continued_from_day"] == 1.0
        assert whole.time.values.tolist() == [k * EVERY for k in range(9)]
        for day in (1.25, 1.5, 1.75, 2):
            np.testing.assert_array_equal(cont.h.sel(time=day).values, whole.h.sel(time=day).values)
