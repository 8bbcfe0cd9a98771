"""The float32 state (``precision = "float32_state"``, ``model.precision``, ``kernels.departure``):
its conversions, a lake at rest held to the bit, TC2's error and mass against float64's and the
mixed float32's, the state kept in float32 between steps (``model.held``) and a continuation
that has the uninterrupted run's bits."""

import numpy as np
import pytest
import warp as wp

from swe_sphere import Simulation
from swe_sphere.config.scene import load_scene
from swe_sphere.kernels import departure
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.simulation.checkpoint import read
from swe_sphere.steppers import STEPPERS, make_stepper
from tests.helpers import cached_grid

EPS32 = float(np.finfo(np.float32).eps)


@pytest.mark.parametrize("per_element", [True, False])
def test_the_departure_round_trips_and_the_increment_is_added_in_float64(per_element):
    """x → y = float32(x − (0, 0, H₀)) → x' = y + H₀ → y again: the same bits (H₀ an integer
    number of metres); the compensated return x += y(n+1) − y(n) keeps x's float64 low bits that
    the float32 y rounded off, so a step that changes nothing leaves x to the bit. The same bits
    over an element's lanes (the per-element layout) as node by node."""
    grid = cached_grid(2, 4)
    model = ShallowWater(
        grid, ["continuity"], np.zeros(grid.nnodes), np.zeros(grid.nnodes), device="cpu", per_element=per_element
    )
    run = model.launches.run_lanes
    rng = np.random.default_rng(1)
    h0 = 5000.0
    x = model.new_state(
        rng.normal(0, 20, grid.nnodes), rng.normal(0, 20, grid.nnodes), h0 + rng.normal(0, 300, grid.nnodes)
    )
    y = wp.zeros(x.shape, dtype=wp.float32, device="cpu")
    run(departure.to_departure, x, wp.float64(h0), y)
    expect = x.numpy() - np.array([0.0, 0.0, h0])[:, None]
    assert np.array_equal(y.numpy(), expect.astype(np.float32))
    back = wp.zeros_like(x)
    run(departure.from_departure, y, wp.float64(h0), back)
    assert np.array_equal(back.numpy(), y.numpy().astype(np.float64) + np.array([0.0, 0.0, h0])[:, None])
    again = wp.zeros_like(y)
    run(departure.to_departure, back, wp.float64(h0), again)
    assert np.array_equal(again.numpy(), y.numpy())
    before = x.numpy().copy()
    run(departure.add_increment, y, wp.float64(h0), x)  # y = y(n): no increment
    assert np.array_equal(x.numpy(), before) and not np.array_equal(back.numpy(), before)


@pytest.mark.parametrize("per_element", [True, False])
def test_a_lake_at_rest_stays_at_rest_to_the_bit(per_element):
    """u = v = 0 and h = H₀ on a flat bottom, with the Coriolis term: every tendency term is
    zero exactly (the departure h − H₀ is 0 in float32, the continuity's flux (0 + H₀)·0), so 20
    rk4 steps of the float32 state leave the float64 state's bits as they were, both layouts."""
    grid = cached_grid(2, 4)
    terms = ["continuity", "momentum_advection", "coriolis", "pressure_gradient"]
    fcor = 2 * 7.292e-5 * np.sin(grid.lat)
    model = ShallowWater(
        grid, terms, fcor, np.zeros(grid.nnodes), device="cpu", per_element=per_element,
        precision="float32_state", depth=8000.0,
    )  # fmt: skip
    x = model.new_state(h=np.full(grid.nnodes, 8000.0))
    before = x.numpy().copy()
    stepper = make_stepper("rk4", model, 600.0)
    for _ in range(20):
        stepper.step(x)
    assert model.state_dtype == wp.float32
    assert np.array_equal(x.numpy(), before)


FLOAT32_STATE_TABLES = sorted(name for name, cls in STEPPERS.items() if cls.float32_state_refusal is None)


@pytest.mark.parametrize("per_element", [True, False])
@pytest.mark.parametrize("name", FLOAT32_STATE_TABLES)
def test_every_table_keeps_a_state_without_tendency_to_the_bit(name, per_element):
    """u = v = 0 and any depth (ne2 np4: h − H₀ normal with 300 m spread), with the continuity
    and Coriolis terms alone: the flux h·0 and f k×0 make F = 0 exactly, so each stage is a
    combination of copies of the state, and 5 steps of each explicit table under the float32
    state must give its bits back, both layouts. The chained combinations (bs32, dp54,
    rdpk3sp35: partial sums of a combination's first terms) held a part of the state, C·5/9
    say, rounded to float32, and drifted by float32 spacings (dp54 3.7e-3 m in 5 steps) until
    each partial sum held the whole (``stage_plan.stage_form``'s ``whole_partials``)."""
    grid = cached_grid(2, 4)
    model = ShallowWater(
        grid, ["continuity", "coriolis"], 1e-4 * np.sin(grid.lat), np.zeros(grid.nnodes), device="cpu",
        per_element=per_element, precision="float32_state", depth=8000.0,
    )  # fmt: skip
    h = 8000.0 + np.random.default_rng(3).normal(0, 300, grid.nnodes)
    x = model.held.new(np.stack([np.zeros(grid.nnodes), np.zeros(grid.nnodes), h]))
    before = x.numpy().copy()
    stepper = make_stepper(name, model, 600.0)
    for _ in range(5):
        stepper.step(x)
    assert x.dtype == wp.float32 and np.array_equal(x.numpy(), before)


def _tc2(precision: str, compensated: bool = False, mass_fixer: bool = False):
    numerics = {"compensated": compensated, "mass_fixer": mass_fixer} if precision == "float32_state" else {}
    sim = Simulation(
        "tc2_steady", ne=4, np=4, days=1.0, stepper="rk4", progress=False, precision=precision, numerics=numerics
    )
    return sim.run(), sim.states()[0, 2].copy()


def test_a_float32_state_run_keeps_float64_s_error_and_bounds_its_mass():
    """TC2 (steady geostrophic flow, exact solution) ne4 np4 for a day with rk4 (72 steps), without
    the mass fixer: the
    float32 state's h error within 0.1 % of float64's (measured 5.1e-5 relative, the mixed float32
    1.8e-6), its h within steps · 0.1 ε₃₂ max h of float64's (measured 0.044 ε₃₂ max h a step:
    each stage's float32 rounding of h − H₀), and its mass change within steps · 1e-3 ε₃₂
    (measured 2.5e-4 ε₃₂ a step compensated, 1.4e-4 not: the stages' float32 sums, which no
    flux cancels; 2.1e-9 and 1.2e-9 over the day, the mixed float32's 4.2e-10)."""
    r64, h64 = _tc2("float64")
    for compensated in (True, False):
        r32, h32 = _tc2("float32_state", compensated)
        d64, d32 = r64.diagnostics, r32.diagnostics
        assert r32.steps == r64.steps == 72
        assert abs(d32["l2_h"] - d64["l2_h"]) <= 1e-3 * d64["l2_h"]
        assert 0 < np.abs(h32 - h64).max() <= r32.steps * 0.1 * EPS32 * np.abs(h64).max()
        assert 0 < abs(d32["mass_change"]) <= r32.steps * 1e-3 * EPS32


@pytest.mark.parametrize("compensated", [True, False])
@pytest.mark.parametrize(
    "scene, options",
    [("tc2_steady", {"stepper": "rk4", "days": 1.0}), ("galewsky", {"np": 4, "days": 0.5})],
)
def test_the_mass_fixer_keeps_the_mass(scene, options, compensated):
    """TC2 ne4 np4 a day with rk4 (72 steps) and Galewsky ne4 np4 half a day with its ssprk3 and
    ∇⁴ (22 steps): without the fixer the float32 stages' roundings move ∫h by up to steps · 1e-3
    ε₃₂ (measured kept 1.1e-9 and −3.2e-10, compensated 1.1e-9 and 6.1e-11). With it, each
    step's end puts back the mass taken, after the ∇⁴. Compensated (a float64 state between
    steps), the run's change is float64's: within steps · 2 ε₆₄ (measured 5.9e-15 and −2.8e-15),
    and h moves by no more than the drift it undoes (TC2's l2_h within 1e-4 of its value
    without). Kept in float32 (the default), the uniform depth is rounded to h − H₀'s spacing at
    each node, and the mass it could not place is put back with the next step's: the change
    stays within half the state's own rounding of its mass, Σ spheremp · ½ spacing(h − H₀) / ∫h,
    and does not grow with the steps (measured −2.2e-9 and −4.1e-10: 0.23 and 0.15 of it; TC2
    over 5 days 3.2e-10). On a grid this small that floor is the drift's own size, so the kept
    fixer does no better here than none over a day; on the scenes' grids it does
    (docs/explanation/precision.md)."""
    runs = {}
    for fixer in (False, True):
        sim = Simulation(
            scene, ne=4, progress=False, precision="float32_state",
            numerics={"mass_fixer": fixer, "compensated": compensated}, **options,
        )  # fmt: skip
        runs[fixer] = sim.run()
    (free, fixed), steps = (runs[k].diagnostics["mass_change"] for k in (False, True)), runs[True].steps
    eps64 = float(np.finfo(np.float64).eps)
    assert steps == runs[False].steps and steps >= 22
    assert 100 * steps * eps64 < abs(free) <= steps * 1e-3 * EPS32
    if compensated:
        assert abs(fixed) <= steps * 2 * eps64
    else:
        y, w = sim.x.numpy()[2], sim.model.grid.spheremp
        rounding = np.sum(w * 0.5 * np.spacing(np.abs(y)).astype(float)) / np.sum(w * (y + sim.model.held.depth))
        assert 1e3 * steps * eps64 < abs(fixed) <= 0.5 * rounding
    if scene == "tc2_steady":  # scored against its exact solution
        l2 = [runs[k].diagnostics["l2_h"] for k in (False, True)]
        assert abs(l2[1] - l2[0]) <= 1e-4 * l2[0]


def test_the_mass_fixer_sums_and_moves_the_depth_alike_in_both_layouts():
    """The fixer's element masses (an element's lanes: one vector of np² nodes, or np² of one)
    have the same bits in both layouts, and its uniform depth gives back the mass taken to
    float64's round-off (a state whose depth lost 1e-9 of its mass, ne2 np4)."""
    grid = cached_grid(2, 4)
    h = 5000.0 + 300.0 * np.sin(grid.lat) * np.cos(3 * grid.lon)
    out = {}
    for per_element in (True, False):
        model = ShallowWater(
            grid, ["continuity"], np.zeros(grid.nnodes), np.zeros(grid.nnodes), device="cpu",
            per_element=per_element, precision="float32_state",
        )  # fmt: skip
        x = model.new_state(h=h)
        fixer = model.mass_fixer
        fixer.measure(x)
        x.assign(x.numpy() * np.array([1.0, 1.0, 1.0 - 1e-9])[:, None])  # the depth loses 1e-9 of its mass
        fixer.restore(x)
        masses = fixer.masses.numpy()
        out[per_element] = masses
        assert abs(masses[1].sum() / masses[0].sum() - (1.0 - 1e-9)) < 1e-15
        after = np.sum(grid.spheremp * x.numpy()[2])
        assert abs(after / masses[0].sum() - 1.0) < 4 * float(np.finfo(np.float64).eps)
    assert np.array_equal(out[True], out[False])


@pytest.mark.parametrize("element_rows", [True, False])
def test_float32_stage_combinations_keep_a_constant_to_the_bit(element_rows):
    """A float32 stage combination of two arrays (``kernels.dss.combination``'s float32 form:
    (c₀ + c₁)·s1 + (c₀·(s0 − s1) + c_k·k), summed in float32) with RK4's weights 1/3, 2/3 (as
    ``stage_plan.constant_keeping`` gives them) and a zero F gives back s0 = s1 to the bit, where
    the weights rounded alone (fl₃₂(1/3)·y + fl₃₂(2/3)·y) miss y at some nodes; with other
    values and an F it is the exact combination to 2 ε₃₂ of its terms, in both DSS layouts."""
    from unittest import mock

    from swe_sphere.grid.topology import Topology

    grid = cached_grid(2, 4)
    with mock.patch.object(Topology, "element_rows", element_rows):
        topo = Topology(grid, "cpu", threads=2)
    assert (topo.edges is not None) == element_rows
    rng = np.random.default_rng(7)
    y = rng.normal(0, 300, (3, grid.nnodes)).astype(np.float32)
    c0, c1, q = 0.33333333333333337, 0.6666666666666666, 100.0  # constant_keeping's rk4 weights: sum 1
    assert np.any(np.float32(c0) * y + np.float32(c1) * y != y)  # the bias the float32 form removes
    other = rng.normal(0, 300, y.shape).astype(np.float32)
    for tendency, b in ((np.zeros(y.shape), y), (rng.standard_normal(y.shape), other)):
        s0, s1, x = wp.array(y, dtype=wp.float32), wp.array(b, dtype=wp.float32), wp.array(tendency, dtype=wp.float64)
        for launch in topo.dss_update(x, [(s0, [(c0, s0), (c1, s1), (q, None)])]):
            launch.launch()
        k = wp.zeros(x.shape, dtype=wp.float64)
        for launch in topo.dss(x, True, k):
            launch.launch()
        got, k = s0.numpy(), k.numpy()
        if not tendency.any():
            assert np.array_equal(got, y)
        else:
            want = c0 * y.astype(np.float64) + c1 * b.astype(np.float64) + q * k
            scale = np.abs(y) + np.abs(b) + np.abs(q * k)
            assert 0 < np.abs(got - want).max() and np.all(np.abs(got - want) <= 2 * EPS32 * scale)


def test_the_run_keeps_the_float32_state_between_steps_and_reads_it_in_float64():
    """Under "float32_state" (not compensated, the default) the run holds u, v and h − H₀ in
    float32 from step to step (``model.held``), the compensated one the float64 state; the
    readers see the float64 state: ``states()`` is f64(y) + (0, 0, H₀) of the held bits, and
    ``set_states`` rounds h − H₀ once (TC2 ne2 np4, 6 rk4 steps)."""
    common = dict(ne=2, np=4, days=0.125, stepper="rk4", progress=False, precision="float32_state")
    kept = Simulation("tc2_steady", **common)
    plain = Simulation("tc2_steady", numerics={"compensated": True}, **common)
    assert kept.x.dtype == wp.float32 and plain.x.dtype == wp.float64
    kept.run()
    h0 = kept.model.held.depth
    y = kept.x.numpy()
    states = kept.states()[0]
    assert np.array_equal(states[:2], y[:2].astype(np.float64))
    assert np.array_equal(states[2], y[2].astype(np.float64) + h0)
    shifted = states.copy()
    shifted[2] += 0.5  # half a metre: within float32's reach of h − H₀
    kept.set_states(shifted[None])
    assert np.array_equal(kept.x.numpy()[2], (shifted[2] - h0).astype(np.float32))


@pytest.mark.parametrize("scene, options", [("tc2_steady", {"stepper": "rk4"}), ("galewsky", {"np": 4})])
def test_a_kept_float32_state_continues_to_the_bit(tmp_path, scene, options):
    """A restart file of a kept float32 state holds h − H₀'s float32 bits as they were
    (``h_departure``: f64(y) + H₀ does not round back to y where |y| < 2⁻²⁹ H₀) and the mass
    its fixer keeps, so a run stopped at day 0.25 and continued to day 0.5 has the uninterrupted
    run's bits (TC2 with rk4, Galewsky with its ssprk3 and ∇⁴ on its steps; ne3, Δt 1800 s, 24
    steps)."""
    common = dict(ne=3, dt=1800.0, progress=False, precision="float32_state", **options)
    whole = Simulation(scene, days=0.5, **common)
    result = whole.run()
    half = Simulation(scene, days=0.25, **common)
    half.run()
    half.write_checkpoint(tmp_path / "ck.nc")
    ck = read(tmp_path / "ck.nc")
    assert ck.departure.dtype == np.float32 and np.array_equal(ck.departure, half.x.numpy()[2])
    assert "mass_fixer" in ck.initial
    rest = Simulation.from_checkpoint(tmp_path / "ck.nc", "cpu", days=0.5, progress=False)
    assert rest.x.dtype == wp.float32
    rest.run()
    assert rest.step == whole.step == result.steps == 24 and np.array_equal(rest.x.numpy(), whole.x.numpy())


def test_a_restart_keeps_departures_that_h_cannot_hold(tmp_path):
    """Departures |y| < 2⁻²⁹ H₀ (here 1e-6 m and less at H₀ ≈ 2.7 km) do not survive h = f64(y) + H₀
    and back, so the restart file keeps them as ``h_departure`` and the continuation starts from
    their bits (TC2 ne2 np4, the held state's h − H₀ set to tiny departures)."""
    sim = Simulation(
        "tc2_steady", ne=2, np=4, days=0.125, stepper="rk4", progress=False, precision="float32_state",
    )  # fmt: skip
    held, y = sim.model.held, sim.x.numpy()
    y[2] = np.float32(1e-6) * np.cos(sim.model.grid.lat * 7.0).astype(np.float32)  # continuous: a function of place
    sim.x.assign(y)
    assert not np.array_equal(held.rounded(held.values(sim.x))[2], y[2])  # h's rounding loses them
    sim.write_checkpoint(tmp_path / "ck.nc")
    rest = Simulation.from_checkpoint(tmp_path / "ck.nc", "cpu", progress=False)
    assert np.array_equal(rest.x.numpy(), y)


@pytest.mark.parametrize("per_element", [True, False])
@pytest.mark.parametrize("scene", ["tc2_steady", "galewsky"])
def test_the_kept_state_steps_as_the_state_converted_at_each_step(scene, per_element):
    """Keeping the float32 state between steps leaves out conversions that give back what they
    took (y → f64(y) + H₀ → y, where no |y| < 2⁻²⁹ H₀): 8 steps (ne2 np4, Δt 1800 s, without the
    fixer, whose kept form takes the mass once) of the kept state have the bits of the same steps
    on a float64 state converted at each step's two ends (``ExplicitRK`` given a float64 x, its
    value rounded as its next step's start would), on either CPU layout, where no ∇⁴ acts (TC2);
    with Galewsky's ∇⁴, which acts on the kept state in place (its first Laplacian reads h − H₀ +
    hs, its last DSS adds to the float32 state and rounds once) and on the float64 state there,
    within steps · ε₃₂ of each row's largest value on the per-element layout (measured 0.6, 3.5,
    2.0 ε₃₂ in all), the same bits on the per-node one (measured: its ∇⁴ kernels round alike
    from either state)."""
    sim = Simulation(
        scene, ne=2, np=4, dt=1800.0, days=1.0, progress=False, precision="float32_state",
        numerics={"mass_fixer": False}, per_element=per_element,
    )  # fmt: skip
    held = sim.model.held
    x = wp.array(held.values(sim.x), dtype=wp.float64, device="cpu")
    for _ in range(8):
        sim.try_step(sim.x)
    other = make_stepper(sim.stepper.name, sim.model, 1800.0)
    for _ in range(8):
        other.step(x)
    y, z = sim.x.numpy(), held.rounded(x.numpy())  # x as its next step's start rounds it
    assert np.abs(y[2]).min() > 2.0**-29 * held.depth
    if scene == "tc2_steady":
        assert np.array_equal(z, y)
    else:
        scale = np.abs(z).max(axis=1)[:, None]
        assert np.all(np.abs(y - z) <= 8 * EPS32 * scale)
        assert np.abs(y - z).max() > 0 or not per_element  # per node: the same bits (measured)


@pytest.mark.parametrize("layout", ["shared", "in_turn"])
def test_a_kept_ensemble_has_its_members_single_run_bits_and_continues_to_the_bit(tmp_path, layout):
    """Two Galewsky members (ne2 np4, Δt 1800 s, its ssprk3 and ∇⁴, h perturbed by 5 m) keep the
    float32 state with the mass fixer: on the grid's copies ("shared") each member's mass is its
    own, taken and put back as its single run's, so each member has the bits of its single run
    started from its state (a sum over both members moved each by their mean's deficit: 1.8e-4 m
    apart in a quarter day); and the restart file keeps each member's mass to keep, so a run
    stopped at day 0.25 and continued to day 0.5 has the uninterrupted run's bits (taken again
    from the stopped states, the fixer would keep other masses)."""
    common = dict(ne=2, np=4, dt=1800.0, progress=False, precision="float32_state")
    members = dict(ensemble={"members": 2, "perturbation": 5.0}, layout=layout, **common)
    whole = Simulation("galewsky", days=0.5, **members)
    starts = whole.states()
    whole.run()
    for k in range(2):
        single = Simulation("galewsky", days=0.5, **common)
        single.set_states(starts[k][None])
        single.run()
        assert np.array_equal(single.states()[0], whole.states()[k])
    half = Simulation("galewsky", days=0.25, **members)
    half.run()
    half.write_checkpoint(tmp_path / "ck.nc")
    assert len(read(tmp_path / "ck.nc").initial["mass_fixer"]) == 2
    rest = Simulation.from_checkpoint(tmp_path / "ck.nc", "cpu", days=0.5, progress=False, members=True)
    rest.run()
    assert rest.step == whole.step == 24 and np.array_equal(rest.states(), whole.states())


def test_a_kept_state_takes_its_mass_as_it_is_set_and_never_in_a_step():
    """The kept float32 state's fixer takes the mass to keep when the run's state is set (its
    start, ``set_states``), not at a first step: a step launches the same kernels every time (a
    CUDA graph captured at the first step replays it), no measure among them (TC2 ne2 np4, rk4)."""
    from unittest import mock

    sim = Simulation("tc2_steady", ne=2, np=4, days=0.125, stepper="rk4", progress=False, precision="float32_state")
    fixer, held = sim.model.mass_fixer, sim.model.held
    start = held.values(sim.x)
    mass = np.sum(sim.model.grid.spheremp * (start[2] - held.depth))
    assert abs(fixer.targets[0] - mass) <= 1e-14 * np.sum(sim.model.grid.spheremp * start[2])
    with mock.patch.object(type(fixer), "measure", side_effect=AssertionError("a mass taken in a step")):
        sim.run()
    assert sim.step == 5
    moved = start.copy()
    moved[2] += 0.25
    sim.set_states(moved[None])  # its mass the one kept from here on
    assert fixer.targets[0] > mass + 0.2 * np.sum(sim.model.grid.spheremp)


@pytest.mark.parametrize("precision", ["float64", "float32", "float32_state"])
def test_the_cpu_layouts_agree_to_round_off_not_to_the_bit(precision):
    """The per-element and per-node CPU layouts (``ShallowWater``'s ``per_element``) give the
    same run to round-off, not to the bit, in every precision (TC5 ne3 np4 with rk4, 11 steps):
    within steps · 4 ε of the wind's and the depth's largest values (measured at most 2.3 ε a
    step in float64, 0.35 ε₃₂ in float32 and the float32 state). The per-element kernels contract
    products into FMAs (``kernels.operators.CPU_FAST``: compiled without it, float64's wind
    tendency has the per-node bits) and sum the continuity in another order (its h tendency
    still 5e-15 of its largest apart); the float32 lanes at np 4 form D⁻¹ = adj D / det D where
    the per-node tendency reads D⁻¹ rounded (apart by float32's round-off of the geostrophic
    terms, which nearly cancel). Bitwise promises (restarts, rank counts) hold within a layout."""
    out = {}
    for per_element in (True, False):
        sim = Simulation(
            "tc5_mountain", ne=3, days=0.25, stepper="rk4", progress=False, precision=precision,
            per_element=per_element,
        )  # fmt: skip
        steps = sim.run().steps
        assert sim.model.launches.per_element == per_element
        out[per_element] = sim.states()[0]
    eps = float(np.finfo(np.float64 if precision == "float64" else np.float32).eps)
    a, b = out[True], out[False]
    wind, depth = np.abs(a[:2]).max(), np.abs(a[2]).max()
    assert steps == 11 and not np.array_equal(a, b)
    assert np.abs(a[:2] - b[:2]).max() <= steps * 4 * eps * wind
    assert np.abs(a[2] - b[2]).max() <= steps * 4 * eps * depth


@pytest.mark.parametrize("per_element", [True, False])
@pytest.mark.parametrize(
    "scene, drop, kept", [("tc1_cosine_bell", (), slice(0, 2)), ("tc2_steady", ("continuity",), slice(2, 3))]
)
def test_rows_no_term_writes_keep_their_bits_in_a_float32_state(scene, drop, kept, per_element):
    """A float32 state whose terms leave rows unwritten: TC1's continuity alone (its wind) and
    TC2 without the continuity (its depth). Those rows are the stages' combinations of the state
    alone (``launches.lincomb`` in the float32 stages' arithmetic, ``blas.combined_state``; a
    float64 ``axpby`` refused the float32 arrays before), so 6 rk4 steps keep them to the bit; the
    rows the terms write stay within steps · ε₃₂ of float64's, relative to max h or max |wind|
    (measured TC1's h 1.4 and 1.5 ε₃₂, TC2's u 1.6 and 2.6, v 1.1 and 1.2: per element, per node)."""
    grid = cached_grid(2, 4)
    sc = load_scene(scene, ne=2, np_=4)
    terms = tuple(t for t in sc.terms if t not in drop)
    start = np.stack(sc.make_case().initial(grid.lat, grid.lon))
    out = {}
    for precision in ("float64", "float32_state"):
        case = sc.make_case()
        model = ShallowWater.from_case(grid, case, terms, nu=sc.nu, per_element=per_element, precision=precision)
        x = model.held.new(start) if precision == "float32_state" else model.new_state(*start)
        read = (lambda x: model.held.float64(x).numpy()) if precision == "float32_state" else (lambda x: x.numpy())
        before = read(x)  # the float32 state's start: rounded to float32
        stepper = make_stepper("rk4", model, sc.dt)
        for _ in range(6):
            stepper.step(x)
        out[precision] = read(x)
    assert np.array_equal(out["float32_state"][kept], before[kept])
    wind = np.hypot(*out["float64"][:2]).max()
    for r in (r for r in range(3) if r not in range(3)[kept]):
        apart = np.abs(out["float32_state"][r] - out["float64"][r]).max() / (wind if r < 2 else out["float64"][2].max())
        assert 0 < apart <= 6 * EPS32, (r, apart / EPS32)
