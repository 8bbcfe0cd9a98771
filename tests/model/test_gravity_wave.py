"""The linear gravity-wave operator L = (−g G h, −H D v) (``model.gravity_wave``): against
the numpy reference on both kernel layouts, its combinations through the DSS, and its one
mean-depth rule (the area mean rounded to 6 digits)."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.model.gravity_wave import GravityWaveOperator, reference_depth
from swe_sphere.model.launches import Update
from swe_sphere.model.shallow_water import ShallowWater

import roundoff
from helpers import make_sim
from numpy_ops import NumpyOps


@pytest.fixture(scope="module")
def sim():
    return make_sim(load_scene("tc5_mountain", ne=2, np_=4, days=1.0))


def continuous_state(sim, rng):
    """TC5's initial state plus a continuous random disturbance (3, N), numpy."""
    grid = sim.grid
    noise = rng.standard_normal((3, grid.nunique)) * np.array([[5.0], [5.0], [50.0]])
    return sim.x.numpy() + noise[:, grid.gid]


@pytest.mark.roundoff
@pytest.mark.parametrize("per_element", [True, False], ids=["per element", "per node"])
def test_the_operator_is_the_numpy_l(sim, rng, per_element):
    """L x on a continuous state (ne 2) against the numpy operators, each row relative to its
    largest value: a derivative with its metric and a DSS each side, two passes of
    ``roundoff.operator_roundings`` (the CPU's layout, and CUDA's run on the CPU)."""
    m = sim.model
    if not per_element:
        m = ShallowWater(
            sim.grid, m.terms, m.operators.fcor.numpy(), m.operators.hs.numpy(), device="cpu", per_element=False
        )
    x = continuous_state(sim, rng)
    L = GravityWaveOperator(m, 5000.0)
    out = wp.zeros((3, m.N), dtype=wp.float64, device="cpu")
    L.apply(wp.array(x, dtype=wp.float64, device="cpu"), out)
    want = NumpyOps(sim.grid).gravity_wave(x, m.g, 5000.0)
    limit = roundoff.bound(roundoff.operator_roundings(sim.grid.np, 2))
    for r, what in enumerate(("u", "v", "h")):
        err = np.abs(out.numpy()[r] - want[r]).max() / np.abs(want[r]).max()
        roundoff.within(err, limit, f"|L x − numpy| / max |L x| ({what})")


def test_an_update_is_the_stored_l_then_its_combination(sim, rng):
    """``update`` writes a·src + c·L x from L's DSS with the bits of L x stored (``apply``)
    and then combined (``lincomb``), its output aliasing its input; a plain tuple is refused."""
    m = sim.model
    L = GravityWaveOperator(m, 5000.0)
    x, a = (wp.array(continuous_state(sim, rng), dtype=wp.float64, device="cpu") for _ in range(2))
    stored, want = wp.zeros_like(x), wp.zeros_like(x)
    L.apply(x, stored)
    m.lincomb(want, ((0.5, a), (-30.0, stored))).launch()
    L.update(x, [Update(x, ((0.5, a), (-30.0, None)))])
    assert np.array_equal(x.numpy(), want.numpy())
    with pytest.raises(TypeError, match="Update"):
        L.update(x, [(x, ((1.0, None),))])


def test_the_mean_depth_is_the_area_mean_rounded_to_6_digits(sim):
    """H from the first state: the spheremp-weighted mean depth rounded to 6 significant
    digits, then fixed; a given H is kept. Bad input: one line naming the term or value."""
    w, h = sim.grid.spheremp, sim.x.numpy()[2]
    mean = float(w @ h / w.sum())
    L = GravityWaveOperator(sim.model)
    assert L.H == 0.0
    L.set_depth(sim.x)
    assert L.H == reference_depth(mean) == float(f"{mean:.6g}") and L.H != mean and abs(L.H - mean) <= 0.005
    L.set_depth(wp.zeros_like(sim.x))
    assert L.H == reference_depth(mean)
    given = GravityWaveOperator(sim.model, 4321.5)
    given.set_depth(sim.x)
    assert given.H == 4321.5
    assert reference_depth(5619.955914745194) == 5619.96
    with pytest.raises(ValueError, match="mean_depth must be >= 0"):
        GravityWaveOperator(sim.model, -1.0)
    continuity = ShallowWater(
        sim.grid, ["continuity"], sim.model.operators.fcor.numpy(), sim.model.operators.hs.numpy(), device="cpu"
    )
    with pytest.raises(ValueError, match="needs the pressure_gradient term"):
        GravityWaveOperator(continuity)
