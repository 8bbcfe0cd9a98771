"""The bundled scenes with tracers (issue 125 item 4): ``galewsky_marker`` and
``tc5_mountain_marker``, the bundled Galewsky jet and TC5 with a latitude marker and q = 1. The
flux form keeps q = 1 to round-off and each tracer's mass as the depth's; the marker leaves
the latitude circles where the flow carries it."""

import math

import numpy as np
import pytest
import xarray as xr

from swe_sphere.config.scene import load_scene

from helpers import make_sim
from roundoff import bound, within

SCENES = ("galewsky_marker", "tc5_mountain_marker")


def mass_drift_bound(steps: int, nnodes: int) -> float:
    """A mass's relative change over ``steps`` steps: ε/8 a step, and the two integrals' pairwise
    sums (``mass_change_bound``'s 2⌈log2 nnodes⌉ ε). Not every update's worst case added
    (``mass_change_bound``): each update rounds every node to nearest, unbiased, so their sum
    over the nodes walks at random far below ε; what adds up step by step is a bias, which the
    combinations' float weights no longer carry (``stage_plan.constant_keeping``: fl(1/3) +
    fl(2/3) = 1 − 2⁻⁵⁴ lowered h by 0.21 ε a step), nor the ∇⁴'s RKL1 stages
    (``Hyperviscosity.rkl1``: μ·t + ν·Y_{j−2} raised Galewsky's h, ne8 np8, by 0.19 ε a step).
    Measured since (native and generic CPU targets alike): TC5's h and q = 1 0.038 ε a step
    (1.38e-14 over ne8's 1650 RK4 steps), Galewsky's 0.0004 (2.0e-16 over ne8 np8's 2196): ε/8
    leaves TC5's 3.3 times room. TC5's was 0.047 ε a step (1.7e-14) while the GLL rule was a few
    ulps off (``grid.gll``): its derivative matrix's rows summed to 1.3e-15 at np 4, and the
    continuity's element tendencies integrated to a steady +0.015 ε of the mass a step (TC2 ne8
    np4; 0 with the rule correctly rounded, the DSS adding nothing). What is left is in the stage
    updates (TC2 ne8: 0.03 ± 0.016 ε a step over 100 steps, the tendency's integral 1e-4 ε), not
    traced."""
    return bound(steps / 8 + 2 * math.ceil(math.log2(nnodes)))


def checked_run(tmp_path, scene) -> xr.Dataset:
    """Run ``scene`` to a run file and check what the flux form guarantees against what the run
    accumulated: q = 1 within a rounding a stage update and ∇⁴ substep (``rhs_evals`` + steps),
    h's and each tracer's mass within ``mass_drift_bound`` of the steps, a tracer's relative to
    ∫ h |q| dA (the marker's ∫ h q dA, of both signs, nearly cancels: a relative change of it
    would count the cancellation as error). Returns the file, loaded."""
    sim = make_sim(scene)
    result = sim.run(tmp_path / "run.nc")
    with xr.open_dataset(tmp_path / "run.nc", decode_times=False) as ds:
        ds.load()
    steps = int(ds.steps[-1])
    within(float(np.abs(ds.one - 1).max()), bound(result.rhs_evals + steps), f"{scene.name}: q = 1")
    within(float(np.abs(ds.mass_change).max()), mass_drift_bound(steps, sim.grid.nnodes), f"{scene.name}: h's mass")
    for name in ("marker", "one"):
        mass = ds[f"{name}_mass"].values
        scale = float((ds.area * ds.h.isel(time=0) * np.abs(ds[name].isel(time=0))).sum())
        change = np.abs(mass - mass[0]).max() / scale
        within(change, mass_drift_bound(steps, sim.grid.nnodes), f"{scene.name}: {name}'s mass")
    return ds


def departure(ds, day: int) -> float:
    """The marker's largest departure (degrees) from the latitude the air is at, at output ``day``."""
    return float(np.abs(ds.marker.isel(time=day) - ds.lat).max())


@pytest.mark.roundoff
@pytest.mark.parametrize("name", SCENES)
def test_a_marker_scene_keeps_q_one_and_each_mass(tmp_path, name):
    """Each scene as bundled (its stepper, its ∇⁴ schedule, its tracers) on ne2 np4 for a day:
    q = 1 and both masses to round-off; the marker has moved off the latitude circles."""
    scene = load_scene(name, ne=2, np_=4, days=1.0)
    assert [t for t, _ in scene.tracers] == ["marker", "one"]
    ds = checked_run(tmp_path, scene)
    assert departure(ds, 0) < 1e-12  # it starts as the latitude
    assert departure(ds, -1) > 0.01  # and the flow has moved it


@pytest.mark.slow
@pytest.mark.roundoff
@pytest.mark.parametrize(
    "name, grid, days, moved",
    [("tc5_mountain_marker", {"ne": 8, "np_": 4}, 15.0, 5.0), ("galewsky_marker", {"ne": 8, "np_": 8}, 6.0, 10.0)],
)
def test_the_whole_runs_keep_q_one_within_the_issues_target(tmp_path, name, grid, days, moved):
    """TC5's 15 days (ne8 np4) and Galewsky's 6 (ne8 np8, the jet rolled up): q = 1 and each
    tracer's and h's relative mass change to ≤ 1e-13 (the issue's target; measured TC5 1.7e-14,
    Galewsky 2.0e-16, 9.1e-14 before RKL1's stages were unbiased), each within the steps' round-off; the marker more than ``moved`` degrees
    off the latitude somewhere (the mountain's wave train, the jet's roll-up)."""
    ds = checked_run(tmp_path, load_scene(name, days=days, **grid))
    assert float(np.abs(ds.one - 1).max()) <= 1e-13
    assert float(np.abs(ds.mass_change).max()) <= 1e-13
    for name in ("marker", "one"):
        mass = ds[f"{name}_mass"].values
        scale = float((ds.area * ds.h.isel(time=0) * np.abs(ds[name].isel(time=0))).sum())
        assert np.abs(mass - mass[0]).max() / scale <= 1e-13
    assert departure(ds, -1) > moved
