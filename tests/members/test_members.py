"""An ensemble (``swe_sphere.ensemble.Ensemble``): member k after n steps has the bits of the
single run from its initial state, on both kernel layouts; bad input is refused before anything
is built, naming the argument; a blow-up names its member."""

from __future__ import annotations

import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import ArgumentError, BlowUp
from swe_sphere.ensemble import MemberGrid, Perturbation
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS

from helpers import ON_CUDA, members_run, take_steps

SMALL = {"ne": 2, "np": 4, "dt": 900.0}


def same_bits(a, b) -> bool:
    return np.array_equal(np.asarray(a).view(np.int64), np.asarray(b).view(np.int64))


# every stepper an ensemble steps (``Ensemble``: the registry's explicit ones), a newly registered one too
EXPLICIT = [name for name, cls in STEPPERS.items() if cls.explicit]


@pytest.mark.parametrize("stepper", EXPLICIT)
def test_each_member_has_the_bits_of_its_single_run(stepper):
    ens = members_run("galewsky", 3, Perturbation(2.0, seed=4), device="cpu", stepper=stepper, layout="shared", **SMALL)
    starts = ens.states()
    assert not same_bits(starts[0], starts[1])  # the members differ
    take_steps(ens, 4)
    for k in range(3):
        sim = Simulation("galewsky", "cpu", progress=False, start=starts[k], stepper=stepper, **SMALL)
        sim.advance(4 * SMALL["dt"] / 86400)
        assert same_bits(ens.states()[k], sim.x.numpy()), k
        assert ens.model.hv.biharmonic_radius() == sim.model.hv.biharmonic_radius()  # the one grid's: its ∇⁴ plan
        assert same_bits(np.stack(ens.states()[k]), sim.x.numpy())
        invariants = ens.invariants()[k]
        assert invariants == {key: sim.members.diagnose(sim.time)[key] for key in invariants}


@pytest.mark.parametrize(("scene", "stepper"), [("galewsky", "rk4"), ("tc5_mountain", "kgu35")])
def test_the_per_node_layout_too(scene, stepper):
    """CUDA's layout (one thread a node), here on the CPU: member k against N = 1."""
    states = members_run(scene, 2, Perturbation(1.0, seed=2), device="cpu", stepper=stepper, **SMALL).states()
    ens = members_run(scene, 2, states, device="cpu", per_element=False, stepper=stepper, layout="shared", **SMALL)
    take_steps(ens, 3)
    for k in range(2):
        one = members_run(scene, 1, states[k : k + 1], device="cpu", per_element=False, stepper=stepper, **SMALL)
        take_steps(one, 3)
        assert same_bits(ens.states()[k], one.states()[0]), k


@pytest.mark.parametrize("device", ["cpu", ON_CUDA])
@pytest.mark.parametrize("layout", ["shared", "in_turn"])
def test_graphed_steps_have_the_bits_of_plain_ones(one_thread, device, layout):
    """Each step a graph (on a CPU: one thread, graphs "on"; CUDA's default): the bits of the
    same ensemble launched step by step, with its graphs kept (in turn, one a member): with the
    scene's ∇⁴ every k steps (``hyperviscosity.every``), a graph of the steps without it and one
    of those that end with it."""
    states = members_run("galewsky", 2, Perturbation(1.0, seed=3), device="cpu", **SMALL).states()
    runs = [members_run("galewsky", 2, states, device=device, graphs=g, layout=layout, **SMALL) for g in ("off", "on")]
    every = load_scene("galewsky", ne=2, np_=4, dt=900.0).hypervis_every
    assert 1 < every <= 5  # both kinds of step in the five
    for ens in runs:
        take_steps(ens, 5)
    assert (runs[0].graphs_kept, runs[1].graphs_kept) == (0, 2 if layout == "shared" else 4)
    assert same_bits(runs[0].states(), runs[1].states())


def test_the_member_grid_offsets_each_member():
    grid = CubedSphere(1, 3)
    copies = MemberGrid(grid, 2)
    n, u = grid.nnodes, grid.first.size
    assert copies.nnodes == 2 * n and copies.nunique == 2 * grid.nunique == 2 * u
    assert same_bits(copies.member(copies.spheremp, 1), grid.spheremp)
    assert np.array_equal(copies.gid[n:], grid.gid + u)
    table = copies.dss_table[n:]
    assert np.array_equal(table, np.where(grid.dss_table >= 0, grid.dss_table + n, -1))
    assert np.array_equal(copies.first[u:], grid.first + n)


@pytest.mark.parametrize(
    ("members", "initial", "named"),
    [
        (0, None, "members"),
        (-2, None, "members"),
        (2.5, None, "members"),
        ("2", None, "members"),
        (2, np.zeros((3, 3, 5)), "initial"),
        (2, "case", "initial"),
        (2, Perturbation(1e5, seed=0), "initial: member"),  # h <= 0 somewhere
    ],
)
def test_bad_input_names_the_argument(members, initial, named):
    with pytest.raises(ArgumentError, match=named):
        members_run("galewsky", members, initial, device="cpu", **SMALL)


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_bad_perturbation_and_scene_are_refused():
    with pytest.raises(ArgumentError, match="amplitude"):
        Perturbation(-1.0)
    with pytest.raises(ArgumentError, match="seed"):
        Perturbation(1.0, seed=0.5)
    with pytest.raises(ArgumentError, match=r"scene: its dt is controlled .* not each on a model of its own$"):
        members_run("galewsky", 2, device="cpu", stepper="bs32", layout="in_turn", **SMALL, **{"time.control": "error"})


def test_a_perturbation_of_a_band_of_degrees_holds_those_degrees_alone():
    """``Perturbation(..., degrees=(l_min, l_max))``: degree 1 alone is a linear function of the
    unit position (x, y, z) on the sphere to round-off; any band's field has the stated
    area-weighted RMS and no mean (l = 0) to the grid's quadrature; continuous (one value a unique
    node); the same seed the same bits; bad bands refused naming them."""
    grid = CubedSphere(6, 4, 6.37122e6)
    state = np.zeros((3, grid.nnodes))
    state[2] = 1000.0
    first = grid.first
    xyz = np.stack([np.cos(grid.lat) * np.cos(grid.lon), np.cos(grid.lat) * np.sin(grid.lon), np.sin(grid.lat)], 1)
    linear = Perturbation(2.0, seed=3, degrees=(1, 1)).apply(grid, state, 3)[:, 2] - 1000.0
    for h in linear:
        fit = np.linalg.lstsq(xyz[first], h[first], rcond=None)[0]
        assert np.abs(xyz @ fit - h).max() < 1e-9 * np.abs(h).max()  # every copy of a node too
    band = Perturbation(2.0, seed=3, degrees=(4, 12))
    h = band.apply(grid, state, 2)[:, 2][:, first] - 1000.0
    area = grid.area
    np.testing.assert_allclose(np.sqrt(np.sum(area * h**2, axis=1) / area.sum()), 2.0, rtol=1e-13)
    assert np.abs(np.sum(area * h, axis=1) / area.sum()).max() < 1e-4 * 2.0  # no l = 0 but the quadrature's
    assert same_bits(band.apply(grid, state, 2), band.apply(grid, state, 2))
    assert not np.array_equal(h[0], h[1])
    for bad in ((0, 3), (5, 4), (1, 10**4), (1.0, 3), (2,)):
        with pytest.raises(
            ArgumentError, match=r"perturbation degrees must be \[l_min, l_max\], integers 1 <= l_min <= l_max <= 2048"
        ):
            Perturbation(1.0, degrees=bad)


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_blow_up_names_the_member():
    good = members_run("tc2_steady", 3, device="cpu", ne=2, np=4, stepper="rk4", dt=1800.0).states()
    good[2, :2] *= 8  # a wind 8 times the steady one: unstable at this dt within a few steps
    ens = members_run("tc2_steady", 3, good, device="cpu", ne=2, np=4, stepper="rk4", dt=1800.0)
    with pytest.raises(BlowUp, match=r"^member 2 of 3 blew up at step \d+ .*policy: stop all"):
        take_steps(ens, 200)
    assert ens.step > 1  # the block re-run step by step to name the step
    assert np.isfinite(ens.states()[:2]).all()


def test_variants_have_the_bits_of_their_own_scenes_single_runs():
    """``Variants``: Galewsky's bump moved and resized, Ω per member (its Coriolis parameter
    and balance): member k against the single run of its scene."""
    import dataclasses

    from swe_sphere.config.scene import load_scene
    from swe_sphere.ensemble import Variants

    values = {"case.hhat": [60.0, 180.0], "case.lon2": [1.0, -2.0], "planet.omega": [6e-5, 8e-5]}
    ens = members_run("galewsky", 2, Variants(values), device="cpu", **SMALL)
    take_steps(ens, 4)
    base = load_scene("galewsky", ne=2, np_=4, dt=900.0)
    for k in range(2):
        scene = dataclasses.replace(
            base,
            case_params={"perturbed": True, "hhat": values["case.hhat"][k], "lon2": values["case.lon2"][k]},
            planet={**base.planet, "omega": values["planet.omega"][k]},
        )
        sim = Simulation(scene, "cpu", progress=False)
        sim.advance(4 * SMALL["dt"] / 86400)
        assert same_bits(ens.states()[k], sim.x.numpy()), k
        invariants = ens.invariants()[k]
        assert invariants == {key: sim.members.diagnose(sim.time)[key] for key in invariants}
    assert not same_bits(ens.states()[0], ens.states()[1])


@pytest.mark.parametrize(
    ("values", "says"),
    [
        ({"planet.radius": [6e6, 7e6]}, "'planet.radius' cannot differ between members"),
        ({"hyperviscosity.subcycle": [1, 2]}, "cannot differ between members"),
        ({"planet.gravity": [9.8, 0.0]}, r"member 1: planet.gravity must be > 0 \(got 0.0\)"),
        ({"hyperviscosity.nu": [1e14, float("nan")]}, r"member 1: hyperviscosity.nu must be >= 0 \(got nan\)"),
        ({"case.hhat": [1.0, 2.0, 3.0]}, "case.hhat needs 2 values, one a member"),
        ({"case.depth": [1.0, 2.0]}, "member 0: unknown parameter case.depth for galewsky"),
        ({}, "values must be a dict of keys to N values"),
    ],
)
def test_variants_refuse_what_members_cannot_take_apart(values, says):
    from swe_sphere.ensemble import Variants

    with pytest.raises(ArgumentError, match=says):
        members_run("galewsky", 2, Variants(values), device="cpu", **SMALL)


def test_galewsky_s_own_values_keep_their_bits_and_reference():
    """The bump's longitude 0 and Galewsky's values: the case as before (its T213 reference);
    another value: no reference (the bundled one holds Galewsky's)."""
    import math

    from swe_sphere.cases.library import make_case

    grid = CubedSphere(2, 4)
    own, explicit = make_case("galewsky"), make_case("galewsky", {"lon2": 0.0, "hhat": 120.0, "lat2": math.pi / 4})
    assert same_bits(np.stack(own.initial(grid.lat, grid.lon)), np.stack(explicit.initial(grid.lat, grid.lon)))
    assert own.reference_file == explicit.reference_file == "galewsky_T213.nc"
    assert make_case("galewsky", {"lon2": 1.0}).reference_file is None
