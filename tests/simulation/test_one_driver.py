"""One driver (issue 116): ``Simulation`` steps one member or N; a continued run, of one member or
many, at a fixed Δt or under step control, keeps what its checkpoint holds (its restart interval,
its control, its output times) and is bitwise the uninterrupted run (issue 117 items 1, 3, 4)."""

from __future__ import annotations

from pathlib import Path

import netCDF4
import numpy as np
import pytest

from swe_sphere.core.errors import ArgumentError
from swe_sphere.ensemble import Perturbation
from swe_sphere.simulation.simulation import Simulation

from helpers import TINY, cli_main, one_line

SMALL = {"ne": 2, "np": 4, "dt": 900.0}


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def last_h(path) -> np.ndarray:
    with netCDF4.Dataset(path) as ds:
        return np.asarray(ds["h"][-1])


@pytest.mark.parametrize("members", [(), ("--members", "2", "--perturbation", "1")], ids=["one", "members"])
@pytest.mark.parametrize("control", [(), ("--stepper", "bs32", "-s", "time.control=error")], ids=["fixed", "error"])
def test_a_continuation_keeps_its_restart_interval_and_is_the_uninterrupted_run(capsys, members, control):
    """Item 1: an ensemble's continuation wrote no restart file and, under time.control=error,
    landed on other times than the run never stopped (not bitwise). Now each of the four keeps
    its checkpoint's restart interval: its restart file written, its last state the bits of
    the uninterrupted run's."""
    run = ("run", "tc2_steady", *TINY, "--dt", "900", *members, *control, "--restart-every", "0.25")
    assert cli_main(capsys, *run, "--days", "0.5", "--output", "a.nc")[0] == 0
    code, out, err = cli_main(capsys, "run", "--continue", "a.restart.nc", "--days", "1", "--no-progress")
    assert code == 0, err
    assert "restart     a_continued.restart.nc (every 0.25 days" in out
    assert Path("a_continued.restart.nc").exists()
    assert cli_main(capsys, *run, "--days", "1", "--output", "w.nc")[0] == 0
    assert np.array_equal(last_h("a_continued.nc"), last_h("w.nc"))


def test_a_continued_ensemble_refuses_s_and_says_since_the_day_it_restarts(capsys):
    """Items 3 and 4: `--continue E -s time.rtol=1e-6` was accepted and ignored for an ensemble
    (a single run's continuation refuses -s in one line); a controlled ensemble's continuation
    said "relative change ... since day 0.944444" (its steps × the first Δt) for a restart at
    day 1."""
    run = ("run", "tc2_steady", *TINY, "--dt", "900", "--members", "2", "--perturbation", "1")
    run += ("--stepper", "bs32", "-s", "time.control=error", "--days", "0.5")
    assert cli_main(capsys, *run, "--restart-every", "0.5", "--output", "e.nc")[0] == 0
    code, out, err = cli_main(capsys, "run", "--continue", "e.restart.nc", "--days", "1", "-s", "time.rtol=1e-6")
    one_line(code, err, 2, "-s time.rtol=1e-6: a checkpointed scene continues as it was written")
    code, out, err = cli_main(capsys, "run", "--continue", "e.restart.nc", "--days", "1", "--no-progress")
    assert code == 0, err
    assert "relative change" in out and all("since day 0.5," in line for line in out.splitlines() if "since" in line)


def test_an_s_ensemble_table_takes_the_member_count_of_members(capsys):
    """`-s ensemble.degrees=[1,2]` with `--members 2` was refused as "ensemble.members is
    missing": the table's members are --members'."""
    band = ("--members", "2", "--perturbation", "1", "-s", "ensemble.degrees=[1, 2]", "--dt", "900")
    code, out, err = cli_main(capsys, "run", "tc2_steady", *TINY, "--days", "0.125", *band, "--output", "b.nc")
    assert code == 0, err
    with netCDF4.Dataset("b.nc") as ds:
        assert ds.dimensions["member"].size == 2


def test_one_driver_for_one_member_and_many():
    """``Simulation(scene, members=N)`` is the ensemble: member k the bits of the single run;
    ``advance`` and ``add_callback`` the same for one and many (the old class: tests/ensemble)."""
    many = Simulation("galewsky", "cpu", members=2, initial=Perturbation(1.0, seed=2), progress=False, **SMALL)
    starts = many.states()
    seen = []
    many.add_callback(lambda sim: seen.append(sim.step), every_steps=2)
    many.advance(4 * 900 / 86400)
    one = Simulation("galewsky", "cpu", start=starts[1], progress=False, **SMALL)
    one.advance(4 * 900 / 86400)
    assert many.step == one.step == 4 and seen == [2, 4] and len(many.members) == 2 and len(one.members) == 1
    assert np.array_equal(many.states()[1], one.states()[0])
    with pytest.raises(ArgumentError, match=r"^states must have shape \(1, 3, 384\) \(got \(2, 3, 384\)\)$"):
        one.set_states(starts)  # a single run is one member: (1, 3, n)
    one.set_states(starts[1:])
    assert np.array_equal(one.states(), starts[1:])


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
@pytest.mark.parametrize("stepper", ["kgu35", "leapfrog"])
def test_members_in_turn_fit_their_own_dt_alike(stepper):
    """Fitting Δt to ``advance``'s interval (the running policy's, ``FixedDt.fitted``) set it on
    the first unit alone: members in turn (a model and stepper each) then stepped at two Δt and
    differed by 10 m. Now every unit steps at the fitted Δt (kgu35's set in place, leapfrog's
    built anew), each member the bits of the single run given that Δt."""
    kw = dict(ne=2, np=4, days=0.25, stepper=stepper, progress=False)
    many = Simulation("tc2_steady_alpha_pi4", "cpu", members=2, layout="in_turn", **kw)
    assert many.scene.dt == 2400.0 and len(many.core.units) == 2
    many.advance(days=0.125)  # 4.5 steps of 2400 s: fitted to 2160 s
    assert many.scene.dt == 2160.0 and [u.stepper.dt for u in many.core.units] == [2160.0, 2160.0]
    one = Simulation("tc2_steady_alpha_pi4", "cpu", dt=2160.0, **kw)
    one.advance(days=0.125)
    for state in many.states():
        np.testing.assert_array_equal(state, one.states()[0])


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_dropped_members_invariants_and_errors_are_nan_as_its_state():
    """``blow_up="drop"``: ``invariants()`` took a dropped member's from its frozen, blown-up state
    (finite numbers) where ``states()`` and ``errors()`` gave NaN. Now every per-member figure of a
    dropped member is NaN, and the others' are their single runs' (mass to the bit)."""
    kw = {"ne": 2, "np": 4, "stepper": "rk4", "dt": 1800.0, "days": 4.0, "progress": False}
    good = Simulation("tc2_steady", "cpu", members=3, **kw).states()
    bad = good.copy()
    bad[1, :2] *= 8  # a wind 8 times the steady one: unstable at this dt within a few steps
    many = Simulation("tc2_steady", "cpu", members=3, initial=bad, blow_up="drop", layout="in_turn", **kw)
    many.run()
    assert list(many.dropped) == [1]
    invariants, errors = many.invariants(), many.errors()
    assert set(invariants[1]) == {"mass", "total_energy", "potential_enstrophy"}
    assert all(np.isnan(v) for v in (*invariants[1].values(), *errors[1].values())) and errors[1]
    one = Simulation("tc2_steady", "cpu", start=bad[2], **kw)
    one.run()
    mass = one.members.diagnose(one.scene.days * 86400.0)["mass"]
    assert invariants[2]["mass"] == mass and np.isfinite([*invariants[0].values(), *errors[0].values()]).all()


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
@pytest.mark.parametrize("members", [None, 2], ids=["one", "members"])
def test_threads_and_the_layout_reach_the_model_of_one_member_and_many(members):
    """``Simulation(threads=, per_element=)`` build the models (their launches and topology) with
    them, a single run's as the members' (a single run ignored ``threads`` before: the backend's
    count); a launch split over more threads steps the same bits."""
    base = Simulation("galewsky", "cpu", members=members, progress=False, **SMALL)
    threads = base.model.threads + 1  # not the default, whatever SWE_SPHERE_THREADS says
    sim = Simulation("galewsky", "cpu", members=members, threads=threads, per_element=False, progress=False, **SMALL)
    m = sim.model
    assert m.threads == m.topology.threads == m.launches.threads == threads and not m.launches.per_element
    assert base.model.launches.per_element  # the CPU's default layout
    per_node = Simulation("galewsky", "cpu", members=members, per_element=False, progress=False, **SMALL)
    for run in (sim, per_node):
        run.advance(2 * 900 / 86400)
    assert np.array_equal(sim.states(), per_node.states())
