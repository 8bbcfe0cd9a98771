"""Spatial convergence against exact solutions beyond case 2.

* Williamson et al. (1992) case 3 (steady zonal flow with compact support;
  α = 0 and π/3): exact steady state, C∞ but not analytic. Normalized l2(h)
  after one day, rk4 at the scene's Δt scaled to the grid (the time error is
  negligible: the state is steady), np = 4, measured on Warp's CPU backend:
  α = 0: 2.528e-3, 3.086e-4, 8.076e-6 at ne = 4, 8, 16 (rates 3.03, 5.26);
  α = π/3: 2.268e-3, 2.667e-4, 7.331e-6 (3.09, 5.19).
  np = 8 (slow): see ``test_tc3_np8_converges``.
* Läuter, Handorf & Dethloff (2005) example 3: an unsteady exact solution (the
  flow turns westward once a day); errors at every output (half a day),
  rk4, np = 4: day 0.5: 6.435e-5, 3.374e-6, 1.926e-7 at ne = 4, 8, 16 (rates
  4.25, 4.13); day 1: 6.900e-5, 3.707e-6, 2.025e-7 (4.22, 4.19).
"""

from __future__ import annotations

import functools
import math

import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.simulation.simulation import Simulation


@functools.cache
def run_day(name: str, ne: int, np_: int, days: float = 1.0):
    """A scene for ``days`` with rk4 at its Δt scaled to the grid; its history."""
    scene = load_scene(name, ne=ne, np_=np_, days=days, stepper="rk4")
    result = Simulation(scene, "cpu", progress=False).run()
    assert result.blowup is None
    return scene, result.history


def rates(nes, errors):
    return [math.log(errors[i] / errors[i + 1]) / math.log(nes[i + 1] / nes[i]) for i in range(len(nes) - 1)]


@pytest.mark.parametrize("name,bound", [("tc3_compact_zonal", 1.2e-5), ("tc3_compact_zonal_alpha_pi3", 1.1e-5)])
def test_tc3_np4_converges_at_least_third_order(name, bound):
    nes = (4, 8, 16)
    errors = [run_day(name, ne, 4)[1][-1]["l2_h"] for ne in nes]
    r = rates(nes, errors)
    print(f"\n{name} np4: l2(h) {errors} rates {r}")
    assert all(q >= 3.0 for q in r), (errors, r)
    assert errors[-1] < bound, errors  # measured ≈ 2/3 of the bound


def test_lauter_errors_at_every_output_converge():
    """The unsteady solution at ne = 4, 8, 16 (np = 4): every half-day output
    has an error, and the error at each falls at rate ≥ 3 (measured ≥ 4.1)."""
    nes = (4, 8, 16)
    table = {}
    for ne in nes:
        scene, history = run_day("lauter_unsteady", ne, 4)
        table[ne] = {round(d["steps"] * scene.dt / DAY, 6): d["l2_h"] for d in history}
    days = sorted(table[4])
    assert days == [0.0, 0.5, 1.0], days
    for day in days[1:]:
        errors = [table[ne][day] for ne in nes]
        r = rates(nes, errors)
        print(f"\nlauter day {day}: l2(h) {errors} rates {r}")
        assert all(q >= 3.0 for q in r), (day, errors, r)
        assert errors[-1] < 3e-7, (day, errors)


@pytest.mark.slow
def test_tc3_np8_converges_at_least_at_order_np_minus_1():
    """np = 8, ne = 4, 8, 16 (rk4, the scene's Δt scaled to the grid):
    measured l2(h) = 3.620e-6, 5.660e-8, 1.304e-10, rates 6.0 (pre-asymptotic:
    the jet's flanks span ≈ 5 nodes at ne = 8) and 8.8."""
    nes = (4, 8, 16)
    errors = [run_day("tc3_compact_zonal", ne, 8)[1][-1]["l2_h"] for ne in nes]
    r = rates(nes, errors)
    print(f"\ntc3 np8: l2(h) {errors} rates {r}")
    assert r[-1] >= 7.0 and r[0] >= 5.5, (errors, r)
    assert errors[-1] < 2e-10, errors
