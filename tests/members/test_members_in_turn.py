"""An ensemble whose members each need a model of their own (``ensemble.members.units``, layout "in
turn"): a stepper that reduces over the grid (its solves, mean depth, Krylov bases, levels), or
members whose g or ν differ. Member k has the bits of its single run, and a restart file
continues every member bitwise, its variants' scenes with it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import xarray as xr

from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import BlowUp
from swe_sphere.ensemble import Perturbation, Variants
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS

from helpers import members_from_checkpoint, members_run, take_steps

SMALL = {"ne": 2, "np": 4, "dt": 900.0}
# every stepper whose members step in turn ("tableau" is a Butcher table's: the explicit ones' path)
IN_TURN = [name for name, cls in STEPPERS.items() if not cls.explicit and name != "tableau"]


def same_bits(a, b) -> bool:
    return np.array_equal(np.asarray(a).view(np.int64), np.asarray(b).view(np.int64))


@pytest.mark.parametrize("stepper", IN_TURN)
def test_a_solver_stepper_s_members_have_the_bits_of_their_single_runs(stepper):
    ens = members_run("galewsky", 2, Perturbation(2.0, seed=4), device="cpu", stepper=stepper, **SMALL)
    assert ens.members.layout == "in_turn" and len(ens.members.units) == 2
    starts = ens.states()
    take_steps(ens, 3)
    for k in range(2):
        sim = Simulation("galewsky", "cpu", progress=False, start=starts[k], stepper=stepper, **SMALL)
        sim.advance(3 * SMALL["dt"] / 86400)
        assert same_bits(ens.states()[k], sim.x.numpy()), k
        invariants = ens.invariants()[k]
        assert invariants == {key: sim.members.diagnose(sim.time)[key] for key in invariants}
    assert not same_bits(ens.states()[0], ens.states()[1])


def test_members_whose_g_and_nu_differ_have_the_bits_of_their_own_scenes():
    """g and ν per member (the kernels take one of each): each member its own model, the single
    run of its scene (Galewsky's balance with its g); ν_div and ν_s follow ν where the scene
    ties them."""
    values = {"planet.gravity": [9.80616, 9.5], "hyperviscosity.nu": [1e15, 4e15]}
    ens = members_run("galewsky", 2, Variants(values), device="cpu", stepper="rk4", **SMALL)
    assert ens.members.layout == "in_turn"
    take_steps(ens, 3)
    scene = load_scene("galewsky", stepper="rk4", **{"np_" if k == "np" else k: v for k, v in SMALL.items()})
    for k in range(2):
        planet, nu = {**scene.planet, "gravity": values["planet.gravity"][k]}, values["hyperviscosity.nu"][k]
        own = dataclasses.replace(scene, planet=planet, nu=nu, nu_div=nu, nu_s=nu)
        assert scene.nu_div == scene.nu == scene.nu_s and ens.members.units[k].model.g == planet["gravity"]
        sim = Simulation(own, "cpu", progress=False)
        sim.advance(3 * SMALL["dt"] / 86400)
        assert same_bits(ens.states()[k], sim.x.numpy()), k
        assert ens.invariants()[k]["total_energy"] == sim.members.diagnose(sim.time)["total_energy"]


@pytest.mark.parametrize(
    ("stepper", "initial", "layout"),
    [
        ("semi_implicit", Perturbation(2.0, seed=5), None),
        ("ark324", Variants({"planet.gravity": [9.8, 9.7]}), None),
        ("rk4", Variants({"planet.omega": [6e-5, 8e-5]}), "shared"),
    ],
)
def test_an_ensemble_continues_bitwise_from_its_restart_file_with_its_variants(tmp_path, stepper, initial, layout):
    """In turn, each member's stepper state (its mean depth, its solver's guesses) under its own
    name, the arrays side by side; the variants kept in the file, so a continuation has each
    member's g, or (in the same launches) its Ω."""
    ens = members_run("galewsky", 2, initial, device="cpu", stepper=stepper, layout=layout, **SMALL)
    take_steps(ens, 2)
    path = ens.write_checkpoint(tmp_path / "r.nc")
    take_steps(ens, 3)
    again = members_from_checkpoint(path)
    assert (
        again.members.layout == ens.members.layout == ("shared" if stepper == "rk4" else "in_turn") and again.step == 2
    )
    take_steps(again, 3)
    assert same_bits(again.states(), ens.states())


def test_an_explicit_ensemble_may_step_in_turn_but_a_solver_s_not_in_shared_launches():
    """An explicit stepper's members on a CPU: in turn by default, the bits of the shared layout
    asked; "shared" asked of members that need a model each: one line naming ``layout``."""
    shared = members_run(
        "galewsky", 2, Perturbation(1.0, seed=3), device="cpu", stepper="kgu35", layout="shared", **SMALL
    )
    in_turn = members_run(
        "galewsky", 2, Perturbation(1.0, seed=3), device="cpu", stepper="kgu35", layout="in_turn", **SMALL
    )
    assert (shared.members.layout, in_turn.members.layout, len(in_turn.members.units)) == ("shared", "in_turn", 2)
    take_steps(shared, 3)
    take_steps(in_turn, 3)
    assert same_bits(shared.states(), in_turn.states())
    with pytest.raises(ValueError, match=r"^layout: these members need a model each \(stepper imex"):
        members_run("galewsky", 2, device="cpu", stepper="imex", layout="shared", **SMALL)
    with pytest.raises(ValueError, match=r"^layout must be None, 'shared' or 'in_turn' \(got 'turns', a str\)$"):
        members_run("galewsky", 2, device="cpu", layout="turns", **SMALL)


@pytest.mark.parametrize("layout", ["shared", "in_turn"])
def test_states_set_between_steps_go_on_as_an_ensemble_started_from_them(layout):
    """``set_states`` (an ensemble filter's analysis): the next steps are those of an ensemble
    started from the states set; bad states are refused naming them, the members unchanged."""
    ens = members_run("galewsky", 2, Perturbation(1.0, seed=6), device="cpu", stepper="rk4", layout=layout, **SMALL)
    take_steps(ens, 2)
    analysis = ens.states()
    analysis[:, 2] += np.linspace(0.0, 3.0, analysis.shape[2])  # not continuous: the model's concern, not the check's
    ens.set_states(analysis)
    assert same_bits(ens.states(), analysis)
    take_steps(ens, 2)
    fresh = members_run("galewsky", 2, analysis, device="cpu", stepper="rk4", layout=layout, **SMALL)
    take_steps(fresh, 2)
    assert same_bits(ens.states(), fresh.states())
    before = ens.states()
    with pytest.raises(ValueError, match=r"^states: member 1's depth h is <= 0"):
        ens.set_states(np.where(np.arange(2)[:, None, None] == 1, -1.0, before))
    with pytest.raises(ValueError, match=r"^states must have shape \(2, 3, 384\)"):
        ens.set_states(before[:1])
    assert same_bits(ens.states(), before)


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_blow_up_in_turn_names_the_member_and_keeps_the_others():
    """In turn, one member's blow-up stops all at the step it happened, naming it (policy: stop
    all); the other members' states are finite there."""
    good = members_run("tc2_steady", 3, device="cpu", ne=2, np=4, stepper="rk4", dt=1800.0).states()
    good[1, :2] *= 8  # a wind 8 times the steady one: unstable at this dt within a few steps
    ens = members_run("tc2_steady", 3, good, device="cpu", ne=2, np=4, stepper="rk4", dt=1800.0, layout="in_turn")
    with pytest.raises(BlowUp, match=r"^member 1 of 3 blew up at step \d+ .*policy: stop all"):
        take_steps(ens, 200)
    assert ens.step > 1 and np.isfinite(ens.states()[[0, 2]]).all()


def test_the_tensor_hyperviscosity_s_members_step_in_turn_with_their_single_runs_bits():
    """The tensor ∇⁴ (its reference Δx is the grid's, not the copies'): in turn, member k the bits
    of its single run."""
    tensor = {"hyperviscosity.scaling": 3.2}
    ens = members_run("galewsky", 2, Perturbation(1.0, seed=8), device="cpu", stepper="rk4", **SMALL, **tensor)
    assert ens.members.layout == "in_turn" and ens.scene.hypervis_scaling == 3.2
    starts = ens.states()
    take_steps(ens, 2)
    for k in range(2):
        sim = Simulation("galewsky", "cpu", progress=False, start=starts[k], stepper="rk4", **SMALL, **tensor)
        sim.advance(2 * SMALL["dt"] / 86400)
        assert same_bits(ens.states()[k], sim.x.numpy()), k


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_member_that_blows_up_is_dropped_and_the_others_go_on(tmp_path):
    """``blow_up="drop"`` (in turn): member 1 blows up and is dropped at the step it did, named in
    one line; members 0 and 2 go on to the end with their single runs' bits; the run file has
    member 1 as NaN from then on, the mean and spread over the others; a restart file continues
    with the member still dropped. "drop" asked in the same launches is one line."""
    good = members_run("tc2_steady", 3, device="cpu", ne=2, np=4, stepper="rk4", dt=1800.0).states()
    bad = good.copy()
    bad[1, :2] *= 8  # a wind 8 times the steady one: unstable at this dt within a few steps
    kw = {"device": "cpu", "ne": 2, "np": 4, "stepper": "rk4", "dt": 1800.0, "days": 4.0}
    ens = members_run("tc2_steady", 3, bad, blow_up="drop", **kw)
    out = ens.run(tmp_path / "d.nc", restart_every=2.0).output
    ((k, step),) = ens.dropped.items()
    assert k == 1 and 1 < step < ens.step == ens.scene.nsteps
    assert len(ens.drops) == 1 and ens.drops[0].startswith(f"member 1 of 3 blew up at step {step} ")
    assert np.isnan(ens.states()[1]).all() and np.isfinite(ens.states()[[0, 2]]).all()
    for m in (0, 2):
        sim = Simulation(
            "tc2_steady", "cpu", progress=False, start=bad[m], **{k: v for k, v in kw.items() if k != "device"}
        )
        sim.advance(4.0)
        assert same_bits(ens.states()[m], sim.x.numpy()), m
    with xr.open_dataset(out, decode_times=False) as ds:
        assert (
            ds.attrs["blow_up_policy"] == "drop the member and go on" and "member 1 of 3" in ds.attrs["dropped_members"]
        )
        assert np.isnan(ds.h.isel(time=-1, member=1)).all() and np.isfinite(ds.h.isel(member=0)).all()
        np.testing.assert_array_equal(ds.h_mean.isel(time=-1), ds.h.isel(time=-1, member=[0, 2]).mean("member"))
    # a map of the dropped member after its blow-up is refused in one line (it drew a blank map)
    from swe_sphere.studies.plotting import plot_run

    with pytest.raises(ValueError, match=r"d\.nc: h_surface holds no number at day 4 \(a member dropped\?\)$"):
        plot_run(out, ["h_surface"], [4.0], outdir=tmp_path / "maps", member="1")
    assert not (tmp_path / "maps").exists() and plot_run(
        out, ["h_surface"], [4.0], outdir=tmp_path / "maps", member="0"
    )
    again = members_from_checkpoint(tmp_path / "d.restart.nc", days=5.0)
    assert again.dropped == {1: step} and again.members.blow_up == "drop"
    take_steps(again, 4)
    assert np.isnan(again.states()[1]).all() and np.isfinite(again.states()[[0, 2]]).all()
    with pytest.raises(ValueError, match=r"^layout: these members need a model each .*blow_up 'drop'"):
        members_run("tc2_steady", 3, good, blow_up="drop", layout="shared", **kw)
    with pytest.raises(ValueError, match=r"^blow_up must be one of 'stop', 'drop' \(got 'skip', a str\)$"):
        members_run("tc2_steady", 3, good, blow_up="skip", **kw)


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_drop_run_stopped_when_none_is_left_keeps_its_dropped_members(tmp_path):
    """``blow_up="drop"`` with every member blowing up in turn: the run stops at the last one
    (``BlowUp``, "none left"), its file closed through the run's wrapper (``simulation.loop.integrate``)
    with every good output time, why it stopped (``stopped``) and the member dropped before
    (``dropped_members``), as a file that ran to its end names them."""
    kw = {"device": "cpu", "ne": 2, "np": 4, "stepper": "rk4", "dt": 1800.0, "days": 5.0}
    bad = members_run("tc2_steady", 2, **kw).states()
    bad[0, :2] *= 8  # unstable within a few steps
    bad[1, :2] *= 4  # within a few days
    ens = members_run("tc2_steady", 2, bad, blow_up="drop", **kw)
    with pytest.raises(BlowUp, match=r"^member 1 of 2 blew up at step \d+ .*none left\)$"):
        ens.run(tmp_path / "e.nc")
    with xr.open_dataset(tmp_path / "e.nc", decode_times=False) as ds:
        assert ds.attrs["stopped"].startswith("member 1 of 2 blew up")
        assert ds.attrs["dropped_members"].startswith(f"member 0 of 2 blew up at step {ens.dropped[0]} ")
        assert np.isfinite(ds.h.isel(member=1)).all() and ds.time.size >= 2
