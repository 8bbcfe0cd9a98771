"""One run of any size (issue 124): every public name of ``Simulation`` called on a single run and
on runs of N = 1 and N = 3 members laid out "shared" and "in_turn". Each name means the same for
every N: N = 1 answers with a single run's shapes and dicts (the squeeze rule), N = 3 with the
member axis first, each member's answer the single run's to the bit (the members start alike, so
each steps the single run's bits: issue 85), or a documented ``ArgumentError`` naming
``states()`` (or ``members.units``) where one member's value has no meaning for N members."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

from swe_sphere import Simulation
from swe_sphere.core.errors import ArgumentError, OutputError
from swe_sphere.members.initial import MembersAlike
from swe_sphere.simulation.checkpoint import read

SMALL = {"device": "cpu", "ne": 2, "days": 0.5, "progress": False}
RUNS = {
    "single": {},
    "1 shared": {"members": 1, "layout": "shared"},
    "1 in_turn": {"members": 1, "layout": "in_turn"},
    "3 shared": {"members": 3, "layout": "shared"},
    "3 in_turn": {"members": 3, "layout": "in_turn"},
}
# the names whose answer is each member's (N > 1: the member axis first)
EACH = ("fields", "divergence", "courant", "stability_warning", "largest_dt_within_limit", "invariants", "errors")
# one member's own state or step: for N > 1 the error names where the members' are
ONE = {"x": "states", "last_good": "states", "try_step": "states"}


def _calls(sim, tmp_path) -> dict:
    """Every public name of ``sim`` called in one order (the run's reads at t = 0, its intervals,
    its steps, its files), by name: the answer, or the exception raised."""
    out = {}

    def call(name, fn):
        try:
            out[name] = fn()
        except Exception as err:  # noqa: BLE001 - recorded, asserted by the test
            out[name] = err

    for name in (*EACH, "states", "h_spread_rms", "scene", "control", "initial", "counters", "time", "step"):
        call(name, lambda n=name: getattr(sim, n)() if callable(getattr(type(sim), n, None)) else getattr(sim, n))
    for name in ("event_day", "check_every", "inputs", "restart_every", "dropped", "drops", "graphs"):
        call(name, lambda n=name: getattr(sim, n))
    for name in ("x", "last_good"):
        call(name, lambda n=name: getattr(sim, n).numpy().copy())
    call("stepper", lambda: type(sim.stepper).__name__)
    call("state", lambda: sim.state())
    call("every", lambda: sim.every(days=0.25).steps)
    call("fitted_dt", lambda: sim.intervals.fitted_dt(0.25)[0].dt)
    call("use_dt", lambda: sim.intervals.use_dt(*sim.intervals.fitted_dt(0.25)))
    call("fit_dt", lambda: sim.intervals.fit_dt(0.25)[0].dt)
    start = sim.states()
    seen = []
    call("add_callback", lambda: sim.add_callback(lambda s: seen.append(s.step), every_steps=1))
    call("steps", lambda: next(sim.steps(every=0.25)))
    call("set_states", lambda: (sim.set_states(sim.states()), sim.states())[1])
    call("run", lambda: sim.run(tmp_path / "run.nc").steps)
    call("advance", lambda: sim.advance(0.25).steps)
    call("graphs_checked", lambda: sim.graphs_checked)
    call("graphs_kept", lambda: sim.graphs_kept)
    out["seen"] = seen
    out["after"] = sim.states()
    call("write_checkpoint", lambda: sim.write_checkpoint(tmp_path / "ck.nc").name)
    call("write_again", lambda: sim.write_checkpoint(tmp_path / "ck.nc"))  # nothing replaced unless asked
    with_members = sim.members.members is not None  # N, or None: a single run's files
    call(
        "from_checkpoint",
        lambda: Simulation.from_checkpoint(tmp_path / "ck.nc", "cpu", progress=False, members=with_members).step,
    )
    ck = read(tmp_path / "ck.nc")
    sim.set_states(start)
    call("restore", lambda: (sim.restore(ck), sim.states())[1])
    call("restore_state_kept", lambda: (sim.restore(ck, state=False), sim.step)[1])
    call("try_step", lambda: sim.try_step(sim.x).rhs_evals)
    return out


@pytest.fixture(scope="module")
def answers(tmp_path_factory) -> dict:
    """Every run's ``_calls`` by its name in ``RUNS``."""
    out = {}
    for name, kw in RUNS.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MembersAlike)  # members alike on purpose: each the single run's bits
            sim = Simulation("tc2_steady", **SMALL, **kw)
            out[name] = _calls(sim, tmp_path_factory.mktemp(name.replace(" ", "_")))
    return out


def _same(a, b) -> None:
    """``a`` and ``b`` equal to the bit, alike in type and shape (dicts key by key, NaN as NaN)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b)
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, (tuple, list)):
        assert type(a) is type(b) and len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    elif isinstance(a, float):
        assert isinstance(b, float) and (a == b or (np.isnan(a) and np.isnan(b)))
    else:
        assert a == b


NAMES = sorted(n for n in dir(Simulation) if not n.startswith("_"))


def test_every_public_name_is_called(answers):
    # a public name added later joins ``_calls``, so that it too is held to one meaning for every N
    assert set(NAMES) - set(answers["single"]) == set()


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")
@pytest.mark.parametrize("run", [r for r in RUNS if r != "single"])
@pytest.mark.parametrize("name", NAMES)
def test_a_public_name_means_the_same_for_every_n(answers, run, name):
    one, got, n = answers["single"], answers[run], int(run[0])
    if name in ONE and n > 1:  # one member's state or step: refused, naming where every member's are
        assert isinstance(got[name], ArgumentError) and f"{ONE[name]}()" in str(got[name])
        return
    if name == "stepper" and run == "3 in_turn":  # a stepper a member
        assert isinstance(got[name], ArgumentError) and "members.units" in str(got[name])
        return
    assert not isinstance(one[name], Exception), one[name]
    if name == "write_checkpoint":
        assert got[name] == "ck.nc" and isinstance(got["write_again"], OutputError)
        return
    assert not isinstance(got[name], Exception), got[name]
    if name in EACH and n > 1:  # the member axis first, each member the single run's
        each = list(zip(*got[name])) if name == "fields" else got[name]
        assert len(each) == n
        for k in range(n):
            _same(tuple(one[name]) if name == "fields" else one[name], tuple(each[k]) if name == "fields" else each[k])
    elif name in ("states", "set_states", "restore"):  # (N, 3, n): each member the single run's
        assert got[name].shape == (n, *one[name].shape[1:])
        for k in range(n):
            _same(one[name][0], got[name][k])
    elif name == "state":
        ds = [got[name]] if n == 1 else [got[name].isel(member=k, drop=True) for k in range(n)]
        for d in ds:
            xr.testing.assert_equal(d[list(one[name].data_vars)], one[name][list(one[name].data_vars)])
    elif name == "h_spread_rms":
        assert got[name] == one[name] == 0.0  # members alike: no spread
    elif name in ("initial", "counters", "scene", "control"):
        assert type(got[name]) is type(one[name])
    elif name in ("inputs", "restart_every"):
        _same(one[name], got[name])
    else:
        _same(one[name], got[name])


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")
@pytest.mark.parametrize("run", [r for r in RUNS if r != "single"])
def test_members_step_the_single_runs_bits_through_every_call(answers, run):
    one, got = answers["single"], answers[run]
    assert got["seen"] == one["seen"] and len(one["seen"]) > 2
    for member in got["after"]:
        np.testing.assert_array_equal(member, one["after"][0])


def test_members_and_an_ensemble_table_as_load_scene_takes_them():
    # issue 124: "ensemble.members is missing" before, where load_scene took the same words
    sim = Simulation("galewsky", members=3, ensemble={"perturbation": 1.0}, **SMALL)
    assert len(sim.members) == 3 and sim.scene.ensemble == {"members": 3, "perturbation": 1.0, "seed": 0}
    assert sim.members.initial_states == "perturbed: h + 1 m white noise, seed 0"
    assert np.ptp(sim.states()[:, 2], axis=0).max() > 0.5  # the table's perturbation, each member its own
    with pytest.raises(Exception, match=r"^members = 3 and ensemble.members = 2: give one of them$"):
        Simulation("galewsky", members=3, ensemble={"members": 2}, **SMALL)
    with pytest.warns(DeprecationWarning, match=r"^Simulation.ensemble is deprecated: Simulation.members$"):
        assert sim.ensemble is sim.members


def test_the_intervals_old_names_are_their_owners_after_a_warning():
    # issue 124: forwarders give way to their owner, ``sim.intervals``; the old names warn in one line
    sim = Simulation("tc2_steady", "cpu", ne=2, days=1.0, progress=False)
    with pytest.warns(
        DeprecationWarning, match=r"^Simulation.fitted_dt is deprecated: Simulation.intervals.fitted_dt$"
    ):
        scene, _ = sim.fitted_dt(0.125)
    assert scene.dt == sim.intervals.fitted_dt(0.125)[0].dt == 2160.0 and sim.scene.dt != 2160.0
