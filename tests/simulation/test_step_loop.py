"""The Python step loop: ``Simulation(scene, **overrides)``,
``advance``, ``steps``, ``state``, callbacks, and the run files' ``[output] fields``
and ``[[output.streams]]``."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

import swe_sphere
from swe_sphere.core.errors import SceneError
from swe_sphere.io.run_file import OUTPUT_FIELDS
from swe_sphere.simulation.simulation import Simulation

from helpers import TINY, cli_main, write_tc2_scene

DT = 1800.0  # s: 48 steps a day
KW = dict(ne=2, dt=DT, days=0.25, output={"every_days": 0.125})  # 12 steps, outputs at steps 0, 6, 12


def sim(**kw):
    return Simulation("tc2_steady_alpha_pi4", "cpu", progress=False, **{**KW, **kw})


@pytest.fixture(scope="module")
def whole_run():
    return swe_sphere.run("tc2_steady_alpha_pi4", device="cpu", **KW)


def test_advance_is_run_bitwise(whole_run):
    """``advance(days=0.25)``, or 0.125 twice, ends in the state of ``swe_sphere.run``
    for 0.25 days, bit for bit; ``state()`` is the run file's last output (every
    field, the coordinates, hs and area)."""
    once, twice = sim(), sim()
    once.advance(days=0.25)
    twice.advance(days=0.125)
    twice.advance(days=0.125)
    assert np.array_equal(once.x.numpy(), twice.x.numpy())
    st, last = once.state(), whole_run.isel(time=-1)
    assert st.time.item() == last.time.item() == 0.25
    for name in (*OUTPUT_FIELDS, "hs", "area", "lat", "lon"):
        assert np.array_equal(st[name].values, last[name].values), name
        assert st[name].attrs.get("units") == last[name].attrs.get("units"), name


def test_advance_past_the_end_lengthens_the_run():
    s = sim()
    s.advance(days=0.375)
    assert (s.step, s.time, s.scene.days) == (18, 0.375, 0.375)
    with pytest.raises(
        SceneError, match=r"^the interval days of 0.01 days is not a whole number of steps of dt = 1800 s"
    ):
        s.advance(days=0.01)


def test_a_run_at_its_end_is_refused_before_a_file_of_no_time(tmp_path):
    """``run`` after ``advance`` to the end: one line, no file (it wrote a run file with no time
    and said nothing; the deprecated ``Ensemble``'s, tests/ensemble)."""
    from swe_sphere.core.errors import ArgumentError

    s = sim()
    s.advance(days=0.375)
    with pytest.raises(ArgumentError, match=r"^Simulation\.run: at step 18 \(day 0\.375\) the run is at its end"):
        s.run(tmp_path / "a.nc")
    assert not list(tmp_path.iterdir())


def test_steps_yield_the_multiples():
    """``steps(every=1/16)``: 1/16-day multiples to the end (day 0.25); an interval
    that is not whole steps is refused."""
    s = sim()
    assert list(s.steps(every=0.0625)) == [0.0625, 0.125, 0.1875, 0.25]
    assert s.step == 12
    with pytest.raises(
        ValueError,
        match=r"^the interval every of 0.03 days is not a whole number of steps of dt = 1800 s \(the dt given\)",
    ):
        next(sim().steps(every=0.03))


def test_steps_fit_the_simulations_own_dt():
    """Without a dt the loop shortens its own Δt to divide ``every`` (as ``run`` on the
    command line does for the output interval): Galewsky at ne = 3 np = 5 has 1694.12 s,
    25.5 steps in half a day, fitted to 43200/26 s; the run is then the one given that dt, bit
    for bit, and a callback in days follows (51 steps a day before, 52 after). kgu35 changes
    its Δt in place (``set_dt``): the same stepper."""
    kw = dict(ne=3, np=5, days=1, progress=False)
    own = Simulation("galewsky", "cpu", **kw)
    assert own.scene.dt == 86400 / 51
    stepper, seen = own.stepper, []
    own.add_callback(lambda s: seen.append((s.step, s.time)), every_days=1)
    assert list(own.steps(every=0.5)) == [0.5, 1.0]
    assert own.scene.dt == 43200 / 26 and own.step == 52 and seen == [(52, 1.0)]
    assert own.stepper is stepper and stepper.dt == 43200 / 26
    assert own.scene.notes[-1] == "dt shortened from 1694.12 s to 1661.54 s to divide every = 0.5 days"
    given = Simulation("galewsky", "cpu", dt=43200 / 26, **kw)
    given.advance(days=1)
    np.testing.assert_array_equal(own.x.numpy(), given.x.numpy())
    assert own.initial == given.initial  # the start's Courant numbers are the new dt's
    late = Simulation("galewsky", "cpu", **kw)
    late.advance(days=1 / 51)  # a step taken: Δt stays
    with pytest.raises(
        ValueError,
        match=r"^the interval every of 0.5 days .* of dt = 1694.12 s \(time.dt of scene galewsky scaled to ne=3 np=5\)",
    ):
        next(late.steps(every=0.5))
    late = Simulation("galewsky", "cpu", **kw)
    late.advance(days=0.5)  # advance fits its interval alike
    assert late.scene.dt == 43200 / 26 and late.step == 26
    with pytest.raises(ValueError, match=r"every = 0.0123 days .* is 8.64 s, less than half: give a dt"):
        next(Simulation("galewsky", "cpu", **kw).steps(every=0.0123))  # 0.0001-day multiples: refused


def test_fitted_dt_writes_nothing_and_fit_dt_uses_its_pair():
    """``fitted_dt`` returns the scene with the fitted clock and the stepper for it, the
    simulation untouched (its scene, stepper and Δt as they were); ``fit_dt`` makes that pair
    the simulation's (``use_dt``) and returns it. leapfrog (``variable_dt`` False): a new
    stepper at the new Δt; kgu35: its own, its Δt set where used."""
    kw = dict(ne=2, days=0.25, stepper="leapfrog", progress=False)
    sim = Simulation("tc2_steady_alpha_pi4", "cpu", **kw)
    scene, stepper = sim.scene, sim.stepper
    fitted, new = sim.intervals.fitted_dt(0.125)
    assert (fitted.dt, new.dt, new is stepper) == (2160.0, 2160.0, False)
    assert sim.scene is scene and sim.stepper is stepper and stepper.dt == scene.dt == 2400.0
    assert sim.intervals.fit_dt(0.125) == (sim.scene, sim.stepper) and sim.scene.dt == sim.stepper.dt == 2160.0
    own = Simulation("galewsky", "cpu", ne=3, np=5, days=1, progress=False)
    fitted, same = own.intervals.fitted_dt(0.5)
    assert same is own.stepper and same.dt == own.scene.dt == 86400 / 51 and fitted.dt == 43200 / 26
    own.intervals.use_dt(fitted, same)
    assert own.scene is fitted and same.dt == 43200 / 26


def test_a_stepper_that_cannot_change_dt_is_built_anew_at_the_fitted_dt():
    """leapfrog (``variable_dt`` False: its start and filter are its Δt's) is built anew when
    its own Δt is fitted: 2400 s is 4.5 steps in 1/8 day, fitted to 2160 s (5 steps); the run is
    then the one given that dt, bit for bit."""
    kw = dict(ne=2, days=0.25, stepper="leapfrog", progress=False)
    own = Simulation("tc2_steady_alpha_pi4", "cpu", **kw)
    stepper = own.stepper
    assert (own.scene.dt, stepper.variable_dt) == (2400.0, False)
    assert list(own.steps(every=0.125)) == [0.125, 0.25]
    assert own.stepper is not stepper and own.stepper.dt == own.scene.dt == 2160.0 and own.step == 10
    given = Simulation("tc2_steady_alpha_pi4", "cpu", dt=2160.0, **kw)
    given.advance(days=0.25)
    np.testing.assert_array_equal(own.x.numpy(), given.x.numpy())


def test_callbacks_at_their_steps():
    """Callbacks run after steps that are multiples of their interval, from step 0, in
    ``steps`` and ``run`` alike, and see the state of that step."""
    s = sim()
    seen, days = [], []
    s.add_callback(lambda sim: seen.append(sim.step), every_steps=5)
    s.add_callback(lambda sim: days.append((sim.time, float(sim.state().h.mean()))), every_days=0.125)
    for _ in s.steps(every=0.0625):
        pass
    assert seen == [5, 10]
    assert [d for d, _ in days] == [0.125, 0.25]
    ref = sim()
    ref.advance(days=0.125)
    assert days[0][1] == float(ref.state().h.mean())
    r = sim()
    r.add_callback(lambda sim: seen.append(-sim.step), every_steps=4)
    r.run()
    assert seen[2:] == [-4, -8, -12]
    with pytest.raises(ValueError, match="exactly one"):
        r.add_callback(print)


class MeanDepth:
    """An output writer of one's own (docs/how-to/step-by-step.md): the global mean depth to a
    text file at the steps of its schedule."""

    def __init__(self, sim, path, every_days):
        self.schedule, self.path = sim.every(days=every_days), path

    def __call__(self, sim):
        with open(self.path, "a") as f:
            f.write(f"{sim.time} {float(sim.state().h.mean())!r}\n")


def test_an_output_writer_of_ones_own(tmp_path, whole_run):
    """A writer set in ``Simulation.activities`` is called at its steps in ``run``,
    beside the run file, after it (a block ends there), and sees the state of its step."""
    s = sim()
    s.activities["mean_depth"] = MeanDepth(s, tmp_path / "h.txt", 0.125)
    s.run(tmp_path / "run.nc")
    rows = [line.split() for line in (tmp_path / "h.txt").read_text().splitlines()]
    assert [float(t) for t, _ in rows] == [0.125, 0.25]
    for t, h in rows:
        assert float(h) == float(whole_run.h.sel(time=float(t)).mean())
    assert list(s.activities) == ["mean_depth"]  # the run's own activities are gone after it
    with pytest.raises(ValueError, match="^the interval every_days of 0.01 days is not a whole number of steps"):
        MeanDepth(s, tmp_path / "x.txt", 0.01)
    again = sim()  # ``s`` is at its end
    again.activities["log"] = MeanDepth(again, tmp_path / "x.txt", 0.125)
    with pytest.raises(ValueError, match=r"activities log: a run's own names \(choose another\)"):
        again.run(tmp_path / "again.nc")
    assert not (tmp_path / "again.nc").exists() and not (tmp_path / "x.txt").exists()


def test_state_on_a_latlon_grid():
    st = sim().state(remap=10.0)
    assert st.h_surface.dims == ("lat", "lon") and st.h_surface.shape == (19, 36)
    assert st.h.attrs["units"] == "m"


def test_output_fields(tmp_path, whole_run):
    """``[output] fields`` limits the run file's node fields; those kept are the
    default file's, bit for bit; the default file's scene attribute has no output
    choices (files as before). An unknown field is refused."""
    ds = swe_sphere.run(
        "tc2_steady_alpha_pi4", device="cpu", **{**KW, "output": {**KW["output"], "fields": ["u", "h"]}}
    )
    assert {"h", "u"} <= set(ds.data_vars) and not {"v", "vorticity", "divergence"} & set(ds.data_vars)
    for name in ("h", "u", "l2_h", "hs"):
        assert np.array_equal(ds[name].values, whole_run[name].values)
    assert "output_fields" not in json.loads(whole_run.attrs["scene"])
    assert json.loads(ds.attrs["scene"])["output_fields"] == ["h", "u"]
    with pytest.raises(SceneError, match="unknown field 'pv'"):
        sim(output={"fields": ["pv"]})


def test_two_streams(tmp_path, capsys):
    """Two ``[[output.streams]]`` write RUN.NAME.nc each at its own interval, with its
    fields, beside the main file (unchanged); through the CLI."""
    scene = write_tc2_scene(
        tmp_path / "s.toml",
        dt=DT,
        days=0.25,
        tables="""
[[output.streams]]
name = "hourly"
every_days = 0.041666666666666664
fields = ["h"]

[[output.streams]]
name = "q"
every_days = 0.0625
fields = ["vorticity", "u"]
""",
    )
    code, out, err = cli_main(capsys, "run", scene, *TINY, "--output", tmp_path / "run.nc")
    assert code == 0, err
    assert f"stream      {tmp_path / 'run.hourly.nc'} (every 0.0416667 days: h)" in out
    with (
        xr.open_dataset(tmp_path / "run.nc", decode_times=False) as main,
        xr.open_dataset(tmp_path / "run.hourly.nc", decode_times=False) as hourly,
        xr.open_dataset(tmp_path / "run.q.nc", decode_times=False) as q,
    ):
        assert list(main.time.values) == [0.0, 0.25]  # the scene's output.every_days = 1: the start and the end
        assert set(OUTPUT_FIELDS) <= set(main.data_vars)
        assert np.allclose(hourly.time.values, np.arange(7) / 24, rtol=0, atol=1e-12)
        assert list(q.time.values) == [0.0, 0.0625, 0.125, 0.1875, 0.25]
        assert "h" in hourly and not {"u", "v", "vorticity"} & set(hourly.data_vars)
        assert {"u", "vorticity"} <= set(q.data_vars) and "h" not in q
        assert np.array_equal(q.u.isel(time=-1).values, main.u.isel(time=-1).values)
        assert np.array_equal(hourly.h.isel(time=-1).values, main.h.isel(time=-1).values)
        assert np.array_equal(q.mass.values[[0, -1]], main.mass.values)


@pytest.mark.parametrize(
    "stream, words",
    [
        ({"name": "restart", "every_days": 0.125}, ["output.streams[0].name"]),
        ({"name": "a", "every_days": 0.01}, ["output.streams[0].every_days", "whole number of steps"]),
        ({"name": "a", "every_days": 0.125, "fields": ["hs"]}, ["output.streams[0].fields", "unknown field 'hs'"]),
        ({"name": "a", "every": 0.125}, ["unknown key output.streams[0].every"]),
    ],
)
def test_bad_streams_refused(stream, words):
    with pytest.raises(SceneError) as err:
        sim(output={"streams": [stream]})
    for word in words:
        assert word in str(err.value)
