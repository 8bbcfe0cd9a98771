"""Passive tracers (issue 125): carried as hq by the depth's own continuity, in the same stages,
so that q = 1 stays 1 and each tracer's mass is conserved as the depth's; compiled only when a
scene names them; refused in one line where they cannot ride."""

import dataclasses

import numpy as np
import pytest
import warp as wp
import xarray as xr

from swe_sphere import Simulation, gradient
from swe_sphere.cases.tracers import TRACER_FIELDS
from swe_sphere.cli import main
from swe_sphere.config.scene import SceneError, load_scene, with_days
from swe_sphere.core.errors import ArgumentError
from swe_sphere.model.launches import Update
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.steppers import make_stepper

from helpers import DEFORMATIONAL_FLOW, cached_grid, cli_one_line, make_sim
from roundoff import bound, mass_change_bound, within

TRACERS = {"names": ["one", "marker"], "initial": ["constant", "latitude"]}


@pytest.mark.roundoff
@pytest.mark.parametrize("stage", [False, True])
@pytest.mark.parametrize("per_element", [True, False])
def test_q_one_stays_one_and_each_tracer_mass_is_conserved(per_element, stage):
    """TC5 on ne3 np4 with its ∇⁴ every step and topography (the ∇⁴ acts on h + hs: a tracer's on
    q(h + hs)), 12 SSP-RK3 steps, both kernel layouts, ν_s split after each step or in every stage
    (``stage_hyperviscosity``; h's there too): q = 1 rides h to the bit (hq = h: the
    continuity's and the ∇⁴'s arithmetic on the same numbers), within round-off of what the steps
    accumulate at least; each tracer's mass changes by round-off alone, as h's."""
    scene = load_scene("tc5_mountain", ne=3, np_=4, stepper="ssprk3")
    grid, case = cached_grid(3, 4), scene.make_case()
    hv = {"nu": scene.nu, "nu_div": scene.nu_div, "nu_s": scene.nu_s, "stage_hyperviscosity": stage}
    model = ShallowWater.from_case(grid, case, scene.terms, tracers=2, threads=1, per_element=per_element, **hv)
    u, v, h = case.initial(grid.lat, grid.lon)
    q = TRACER_FIELDS["gaussian_hills"](grid.lat, grid.lon)
    x = model.new_state(u, v, h, masses=np.stack([h, h * q]))
    stepper = make_stepper("ssprk3", model, scene.dt)
    mass0 = [grid.integrate(r) for r in x.numpy()[2:]]
    steps = 12
    for _ in range(steps):
        stepper.step(x)
    a = x.numpy()
    assert np.abs(a[2] - h).max() > 1.0  # the flow moved the depth
    # the same bits here; at most a rounding of q per stage update and ∇⁴ substep anywhere
    within(np.abs(a[3] / a[2] - 1.0).max(), bound(4 * steps), "q = 1 after 12 steps")
    for row, m0 in zip(a[2:], mass0, strict=True):
        within(abs(grid.integrate(row) - m0) / m0, mass_change_bound(4 * steps, grid.nnodes), "a mass's change")
    assert np.abs(a[4] / a[2] - q).max() > 1e-3  # the hills moved


def test_a_scene_without_tracers_compiles_no_tracer_code():
    """The tendency kernel holds the tracers' code only when the model has them (its key ends
    ``__q<K>``): a scene without them runs the kernel it ran before."""
    scene = load_scene("galewsky", ne=2, np_=4)
    grid, case = cached_grid(2, 4), scene.make_case()
    bare = ShallowWater.from_case(grid, case, scene.terms, threads=1)
    carried = ShallowWater.from_case(grid, case, scene.terms, threads=1, tracers=2)
    names = lambda m: [n for n in m.rhs_kernels(m.new_state(), m.new_state()) if n.startswith("tendency")]  # noqa: E731
    assert names(bare) and not any("__q" in n for n in names(bare))
    assert all(n.endswith("__q2") for n in names(carried))
    assert bare.rows == 3 and carried.rows == 5


def test_a_run_file_holds_each_tracer_as_a_cf_variable_and_its_mass(tmp_path):
    """Galewsky's jet on ne2 np4 with q = 1 and a latitude marker, to day 0.25 (rk4, its ∇⁴):
    the run file holds each tracer's q (time, ncol) with units "1", its mass series and change;
    q = 1 stays 1 within the stages' round-off, the masses' changes within theirs."""
    scene = load_scene("galewsky", ne=2, np_=4, days=0.25, output={"every_days": 0.125}, tracers=TRACERS)
    sim = make_sim(scene)
    result = sim.run(tmp_path / "run.nc", overwrite=True)
    with xr.open_dataset(tmp_path / "run.nc", decode_times=False) as ds:
        assert ds.one.dims == ("time", "ncol") and ds.one.attrs["units"] == "1"
        assert "passive tracer marker" in ds.marker.attrs["long_name"]
        steps = int(ds.steps[-1])
        within(float(np.abs(ds.one - 1.0).max()), bound(result.rhs_evals + steps), "q = 1 in the run file")
        initial = ds.marker.isel(time=0)
        assert np.allclose(initial, ds.lat, atol=1e-12)  # the latitude marker starts as the latitude
        assert float(np.abs(ds.marker.isel(time=-1) - initial).max()) > 1e-3  # and moves with the flow
        for name in ("one", "marker"):
            assert ds[f"{name}_mass"].attrs["units"] == "m3"
            change = float(np.abs(ds[f"{name}_mass_change"]).max())
            within(change, mass_change_bound(result.rhs_evals + steps, sim.grid.nnodes), f"{name}'s mass change")


@pytest.mark.parametrize(
    "tables, words",
    [
        ({"stepper": "leapfrog"}, ["stepper leapfrog", "explicit Runge-Kutta"]),
        ({"tracers": {"names": ["h"], "initial": ["constant"]}}, ["tracers.names", "distinct"]),
        ({"tracers": {"names": ["dye"], "initial": ["smoke"]}}, ["tracers.initial", "'smoke'"]),
        ({"tracers": {"names": ["a", "b"], "initial": ["constant"]}}, ["tracers.initial", "each of the 2"]),
        ({"case": {"name": "tc1_cosine_bell"}, "terms": ["continuity"]}, ["fluid depth", "tc1_cosine_bell"]),
    ],
)
def test_tracers_that_cannot_ride_are_refused_in_one_line(tables, words):
    """A scene's [tracers] refused by one line naming the key or the stepper."""
    tables = {"tracers": {"names": ["dye"], "initial": ["constant"]}} | tables
    stepper = tables.pop("stepper", None)
    with pytest.raises(SceneError) as err:
        load_scene("galewsky", ne=2, np_=4, stepper=stepper, **tables)
    line = str(err.value)
    assert "\n" not in line
    for word in words:
        assert word in line


@pytest.mark.parametrize("precision", ["float32", "float32_state"])
def test_tracers_under_float32_are_refused_in_one_line(precision, capsys, tmp_path, monkeypatch):
    """The tracers' tendency rows and ∇⁴ are float64 alone: a float32 precision with tracers is
    refused by the model at construction (not by Warp inside a step's launch), by a scene's
    [tracers] and by the command line (exit 2, nothing written), each naming the precision."""
    grid, scene = cached_grid(2, 4), load_scene("tc5_mountain", ne=2, np_=4)
    with pytest.raises(ArgumentError) as err:
        ShallowWater.from_case(grid, scene.make_case(), scene.terms, tracers=1, precision=precision, threads=1)
    assert str(err.value) == f'tracers=1 with precision "{precision}" does not carry tracers ' + (
        '(their tendency and ∇⁴ are float64 alone): use "float64"'
    )
    with pytest.raises(SceneError, match=rf'^\[tracers\] with \[numerics\] precision "{precision}" does not carry'):
        load_scene("tc5_mountain", ne=2, np_=4, precision=precision, tracers=TRACERS)
    monkeypatch.chdir(tmp_path)
    options = [
        "-s",
        f'numerics.precision="{precision}"',
        "-s",
        'tracers.names=["q0"]',
        "-s",
        'tracers.initial=["constant"]',
    ]
    line = cli_one_line(
        capsys, ["run", "tc5_mountain", "--ne", "2", *options], 2, f'precision "{precision}"', "tracers"
    )
    assert "stepper" not in line
    assert list(tmp_path.iterdir()) == []


def test_a_restart_carries_the_tracers_bitwise(tmp_path):
    """Galewsky ne2 np4 with two tracers, to day 0.25 at once and in two halves through a restart
    file: the same final state, tracer masses included, to the bit; the file holds each mass."""
    scene = load_scene("galewsky", ne=2, np_=4, days=0.25, output={"every_days": 0.125}, tracers=TRACERS)
    whole = make_sim(scene)
    whole.run(tmp_path / "whole.nc")
    half = make_sim(with_days(scene, 0.125))
    half.run(tmp_path / "half.nc", restart_every=0.125)
    with xr.open_dataset(tmp_path / "half.restart.nc") as ds:
        assert ds.one_mass.attrs["units"] == "m" and ds.marker_mass.dims == ("node",)
    rest = Simulation.from_checkpoint(tmp_path / "half.restart.nc", days=0.25, device="cpu", progress=False)
    rest.run(tmp_path / "rest.nc")
    assert whole.x.numpy().shape[0] == 5
    assert np.array_equal(rest.x.numpy(), whole.x.numpy())


def test_the_limiter_keeps_each_elements_mass_and_meets_the_bounds():
    """Guba et al. 2014's limiter on ne2 np4: the bounds of a smooth tracer taken, its masses then
    pushed out of them (a ripple of ±30 % of hq that keeps each element's mass), limited: every q
    back within the bounds (after the DSS, a convex combination of its elements' limited values)
    and the total mass kept to round-off; q = 1 stays 1 to the DSS's rounding."""
    grid, case = cached_grid(2, 4), load_scene("galewsky", ne=2, np_=4).make_case()
    model = ShallowWater.from_case(grid, case, ["continuity"], tracers=2, threads=1, limiter="optimization")
    u, v, h = case.initial(grid.lat, grid.lon)
    q = TRACER_FIELDS["gaussian_hills"](grid.lat, grid.lon) + 0.1
    x = model.new_state(u, v, h, masses=np.stack([h, h * q]))
    model.limiter.bound(x)
    lo, hi = model.limiter.near.numpy()[2:4]
    s = grid.spheremp.reshape(-1, 16)
    ripple = (0.3 * h * q * np.cos(np.arange(grid.nnodes) * 2.0)).reshape(-1, 16)
    ripple -= ((s * ripple).sum(1) / s.sum(1))[:, None]  # each element's tracer mass kept
    a = x.numpy()
    pushed = a[4] + ripple.ravel()
    assert (pushed / a[2]).min() < lo.min() - 1e-3 and (pushed / a[2]).max() > hi.max() + 1e-3
    mass0 = grid.integrate(pushed)
    tend = np.zeros_like(a)
    tend[4] = ripple.ravel()  # the stage x + the ripple, element by element (an unweighted tendency)
    tend = wp.array(tend, dtype=wp.float64, device="cpu")
    for launch in model.limiter.stage(Update(x, ((1.0, x), (1.0, None))), tend, False):
        launch.launch()
    a = x.numpy()
    within(abs(grid.integrate(a[4]) - mass0) / mass0, bound(64), "the limited tracer's mass")
    limited = a[4] / a[2]
    assert lo.min() - 1e-12 <= limited.min() and limited.max() <= hi.max() + 1e-12
    within(np.abs(a[3] / a[2] - 1).max(), bound(4), "q = 1 through the limiter")


def test_the_limiter_keeps_every_value_within_the_initial_range(tmp_path):
    """Nair & Lauritzen's deformational flow (the transport test, HOMME's ν_s) on ne4 np4 for a
    day and a half at the study's Courant number (Δt 1800 s) carrying cosine bells, slotted
    cylinders and q = 1, the limiter on each stage's element-local values before their DSS and on
    the tracers' ∇⁴ (HOMME's euler_step). With SSPRK(4,3), whose stages are forward-Euler steps
    of Δt/2 (HOMME's tracer stages are Euler steps of Δt/2 too), no tracer leaves its initial
    range beyond round-off (measured 1.0e-14 of it). With SSP-RK3, whose Euler steps are of Δt,
    an element's mean leaves its bounds where a corner node's outflow over Δt exceeds its own
    mass (the element-local update's positivity limit; at Δt 900 s the same run is within
    round-off), and the limiter, unable to keep both, keeps the mass: 4.2e-9 here, 5.5e-9 at
    ne10 over the 12 days. Without the limiter the bells and the cylinders undershoot by more
    than 1e-3. Each mass kept within what its updates round, q = 1 within round-off. (RK4, not
    SSP, ends at −2.2e-4 here: its last stage limits a combination whose element mean may lie
    beyond the bounds.)"""
    tracers = {"names": ["bells", "cylinders", "one"], "initial": ["cosine_bells", "slotted_cylinders", "constant"]}
    spans = {}
    for limiter, stepper in (("none", "ssprk3"), ("optimization", "ssprk3"), ("optimization", "ssprk43")):
        over = {**DEFORMATIONAL_FLOW, "output.every_days": 1.5, "tracers.limiter": limiter, "time.stepper": stepper}
        scene = load_scene("tc2_steady", ne=4, np_=4, days=1.5, dt=1800.0, overrides=over, tracers=tracers)
        sim = make_sim(scene)
        path = tmp_path / f"{limiter}_{stepper}.nc"
        sim.run(path)
        with xr.open_dataset(path, decode_times=False) as ds:
            steps = int(ds.steps[-1])
            for name in tracers["names"]:
                q0, q = ds[name].values[0], ds[name].values[-1]
                span = q0.max() - q0.min() or 1.0
                spans[stepper, limiter, name] = ((q.min() - q0.min()) / span, (q.max() - q0.max()) / span)
                change = float(np.abs(ds[f"{name}_mass_change"]).max())
                within(change, mass_change_bound(8 * steps, sim.grid.nnodes), f"{name}'s mass change")
    for name in ("bells", "cylinders"):
        assert spans["ssprk3", "none", name][0] < -1e-3  # the unlimited transport undershoots
        low, high = spans["ssprk3", "optimization", name]
        assert low > -2e-8 and high < 2e-8, (name, low, high)  # beyond the Euler steps' positivity limit
        low, high = spans["ssprk43", "optimization", name]
        within(max(-low, high, 0.0), bound(8 * steps), f"{name} beyond its initial range (SSPRK(4,3))")
    for stepper in ("ssprk3", "ssprk43"):
        within(
            max(map(abs, spans[stepper, "optimization", "one"])), bound(8 * steps), f"q = 1 with the limiter, {stepper}"
        )


@pytest.mark.roundoff
def test_the_limiter_meets_the_bounds_to_round_off(tmp_path):
    """The deformational flow on ne8 np4 for 3 days (Δt 900 s, SSPRK(4,3), HOMME's ν_s) carrying
    the cosine bells and their correlated partner, whose greatest value (0.892) fills most of the
    sphere and meets its bound in many elements every stage. The limiter's passes go on until one
    clips nothing, so no value leaves the initial range beyond the DSS's rounding: a step's
    limited updates (its four stages and the ∇⁴'s) each end in a DSS and a q = hq / h that round
    an in-bounds value by a few ε of |q|, and the next step takes its bounds from those values, so
    the excess may ratchet by that each step: ≤ 8 roundings of max|q| a step (measured 1.1 ε of
    max|q| a step: 8.2e-14 of the correlated tracer's range). Stopping when the mass left to spread
    was ≤ 1e-14 of the element's (the rule before) left it 1.6e-12 outside."""
    tracers = {"names": ["bells", "correlated"], "initial": ["cosine_bells", "correlated_bells"]}
    flow = {
        **DEFORMATIONAL_FLOW,
        "output.every_days": 3.0,
        "tracers.limiter": "optimization",
        "time.stepper": "ssprk43",
    }
    scene = load_scene("tc2_steady", ne=8, np_=4, days=3.0, dt=900.0, overrides=flow, tracers=tracers)
    path = tmp_path / "flow.nc"
    make_sim(scene).run(path)
    with xr.open_dataset(path, decode_times=False) as ds:
        steps = int(ds.steps[-1])
        for name in tracers["names"]:
            q0, q = ds[name].values[0], ds[name].values[-1]
            span = q0.max() - q0.min()
            outside = max(q0.min() - q.min(), q.max() - q0.max(), 0.0) / span
            within(outside, bound(8 * steps, np.abs(q0).max() / span), f"{name} beyond its initial range")


def test_a_bad_limiter_is_refused_in_one_line():
    with pytest.raises(SceneError, match=r"tracers.limiter must be one of none, optimization \(got 'fct'"):
        load_scene("galewsky", ne=2, np_=4, tracers={**TRACERS, "limiter": "fct"})
    scene = load_scene("galewsky", ne=2, np_=4, tracers={**TRACERS, "limiter": "optimization"})
    assert scene.tracer_limiter == "optimization" and scene.as_dict()["tracer_limiter"] == "optimization"
    assert "tracer_limiter" not in load_scene("galewsky", ne=2, np_=4, tracers=TRACERS).as_dict()


def test_a_gradient_refuses_tracers_in_one_line():
    """The adjoint's tapes and costs are of u, v, h: a gradient of a scene with [tracers] is refused
    in one line naming what to drop (issue 125 item 4)."""
    scene = load_scene("tc5_mountain", ne=2, np_=4, dt=1800.0, stepper="rk4", tracers=TRACERS)
    with pytest.raises(ArgumentError, match=r"\[tracers\]") as err:
        gradient(scene, 2, lambda x: float(np.sum(x[2] ** 2)))
    assert "\n" not in str(err.value) and "drop the tracers" in str(err.value)


def test_plot_and_remap_take_the_tracers(tmp_path):
    """A run file's tracers are fields of ``swe-sphere remap`` (q on the lat-lon grid, its
    attributes kept) and of ``swe-sphere plot --field`` (a map a tracer); another name is refused."""
    scene = load_scene("galewsky", ne=2, np_=4, days=0.125, output={"every_days": 0.125}, tracers=TRACERS)
    make_sim(scene).run(tmp_path / "run.nc")
    assert main(["remap", str(tmp_path / "run.nc"), "--resolution", "5", "--output", str(tmp_path / "ll.nc")]) == 0
    with xr.open_dataset(tmp_path / "ll.nc", decode_times=False) as ll:
        assert ll.marker.dims == ("time", "lat", "lon") and ll.marker.attrs["units"] == "1"
        assert np.allclose(ll.one, 1.0) and abs(float(ll.marker.isel(time=0).sel(lat=45.0)[0]) - 45.0) < 1.0
    assert main(["plot", str(tmp_path / "run.nc"), "--field", "marker", "--output", str(tmp_path / "maps")]) == 0
    assert (tmp_path / "maps" / "run_marker_day0.125.png").is_file()
    assert main(["plot", str(tmp_path / "run.nc"), "--field", "dye", "--output", str(tmp_path / "no")]) == 2


def test_the_tracers_hyperviscosity_is_a_choice():
    """[tracers] hyperviscosity = false leaves the tracers undamped: on TC5 ne3 (two of its ∇⁴
    steps) q = 1 drifts from 1 where h is damped, the masses still kept; true (the default) keeps
    q = 1 within round-off. A true without the hyperviscosity term is refused in one line."""
    base = {"names": ["one"], "initial": ["constant"]}
    drift = {}
    for choice in (True, False):
        scene = load_scene("tc5_mountain", ne=3, np_=4, stepper="ssprk3", tracers={**base, "hyperviscosity": choice})
        assert scene.tracer_hyperviscosity is choice
        days = 2 * scene.hypervis_every * scene.dt / 86400.0  # the ∇⁴ twice
        sim = make_sim(with_days(dataclasses.replace(scene, output_every_days=days), days))
        sim.run(None)
        a = sim.x.numpy()
        drift[choice] = np.abs(a[3] / a[2] - 1).max()
        within(abs(sim.grid.integrate(a[3]) / sim.grid.integrate(a[2]) - 1), bound(64), "the mass of q = 1 against h's")
    within(drift[True], bound(24), "q = 1 with the tracers' ∇⁴")
    assert drift[False] > 1e-8  # the depth's ∇⁴ moved h, not hq
    with pytest.raises(SceneError, match="needs the hyperviscosity term"):
        load_scene("tc2_steady", ne=2, tracers={**base, "hyperviscosity": True})
