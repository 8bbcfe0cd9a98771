"""The IMEX Runge–Kutta stepper (``stepper = "imex"``, ARS(2,3,2) and ARS(3,4,3)).

Measured on Warp's CPU backend (2 busy cores):

* Temporal order on TC6 (ne = 4, np = 4, no hyperviscosity, 0.25 day) against
  rk4 with 2048 steps, Helmholtz tol 1e-13: ARS(2,3,2) 16/32/64/128 steps:
  2.05e-4, 5.65e-5, 1.44e-5, 3.61e-6 (rates 1.86, 1.97, 2.00); ARS(3,4,3):
  1.09e-4, 1.80e-5, 2.41e-6, 3.05e-7 (rates 2.60, 2.91, 2.98). Mass change
  ≤ 2.1e-16.
* TC5 at ne = 16 for 5 days (gravity-wave limit dt_g = 505.7 s, advective
  limit 12.1 dt_g): ARS(3,4,3) stable at 7.98 and 11.86 dt_g (l2(h+hs) against
  T213 6.9e-4 and 7.5e-4), mass change 2e-15.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.model.gravity_wave import GravityWaveOperator
from swe_sphere.model.helmholtz import HelmholtzOptions, HelmholtzSolver
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers.runge_kutta import TABLES
from swe_sphere.steppers.tables import IMEX as SCHEMES

import helpers
import roundoff
from helpers import cached_grid, run


def _ars232():
    """ARS(2,3,2) (Ascher, Ruuth & Spiteri 1997, §2.5) from its closed forms: γ = 1 − 1/√2, δ = −2√2/3."""
    g, d = 1.0 - 1.0 / math.sqrt(2.0), -2.0 * math.sqrt(2.0) / 3.0
    A_exp = np.array([[0, 0, 0], [g, 0, 0], [d, 1 - d, 0]])
    A_imp = np.array([[0, 0, 0], [0, g, 0], [0, 1 - g, g]])
    return A_exp, A_imp, A_imp[-1].copy(), 2


def _ars343():
    """ARS(3,4,3) (§2.7) from its closed forms: γ the root of 6γ³ − 18γ² + 9γ − 1 = 0 near 0.436,
    Â₄₂ = Â₄₃, Â₃₁, Â₃₂ from the third-order conditions (ClimaTimeSteppers' forms)."""
    g = 0.4358665215084590
    b1, b2 = -1.5 * g * g + 4 * g - 0.25, 1.5 * g * g - 5 * g + 1.25
    a42 = a43 = 0.5529291480359398
    a31 = (1 - 4.5 * g + 1.5 * g * g) * a42 + (2.75 - 10.5 * g + 3.75 * g * g) * a43 - 3.5 + 13 * g - 4.5 * g * g
    a32 = (-1 + 4.5 * g - 1.5 * g * g) * a42 + (-2.75 + 10.5 * g - 3.75 * g * g) * a43 + 4 - 12.5 * g + 4.5 * g * g
    A_exp = np.array([[0, 0, 0, 0], [g, 0, 0, 0], [a31, a32, 0, 0], [1 - 2 * a42, a42, a43, 0]])
    A_imp = np.array([[0, 0, 0, 0], [0, g, 0, 0], [0, (1 - g) / 2, g, 0], [0, b1, b2, g]])
    return A_exp, A_imp, A_imp[-1].copy(), 3


def tableau(scheme):
    """(Â, A, b, order) of an ARS scheme from the paper's closed forms: explicit and implicit
    stage matrices (s × s) and the weights shared by both (b̂ = b)."""
    return {"ars232": _ars232, "ars343": _ars343}[scheme]()


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_ars_tables_are_the_floats_of_their_closed_forms(scheme):
    """``imex``'s tables (``steppers.tables``, entries printed to 17 digits) are bit for bit
    the float64 values of the paper's closed forms, c the explicit rows' sums, b = b_E = b_I."""
    A_exp, A_imp, b, order = tableau(scheme)
    A_E, b_E, A_I, b_I, c = TABLES[scheme].floats()
    for got, want in ((A_E, A_exp), (A_I, A_imp), (b_E, b), (b_I, b), (c, A_exp.sum(axis=1))):
        np.testing.assert_array_equal(got, want)
    assert TABLES[scheme].order == order


ORDER_DAYS = 0.25


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_ars_tableaux_satisfy_the_order_conditions(scheme):
    """Additive RK order conditions up to the scheme's order (b̂ = b and equal
    abscissae c = Â1 = A1, so the coupling conditions reduce to these), and
    ARS's structure: implicit first column zero, constant diagonal γ, explicit
    strictly lower triangular. ARS(2,3,2) must fail the third-order ones."""
    A_exp, A_imp, b, order = tableau(scheme)
    c = A_exp.sum(1)
    np.testing.assert_allclose(A_imp.sum(1), c, atol=1e-15)
    assert np.all(np.triu(A_exp) == 0) and np.all(A_imp[:, 0] == 0) and np.all(np.triu(A_imp, 1) == 0)
    assert len(set(np.diag(A_imp)[1:])) == 1
    conditions = {1: [b.sum() - 1], 2: [b @ c - 0.5]}
    conditions[3] = [b @ c**2 - 1 / 3] + [b @ A @ c - 1 / 6 for A in (A_exp, A_imp)]
    for p in range(1, order + 1):
        assert max(abs(x) for x in conditions[p]) < 1e-12, (p, conditions[p])
    if order == 2:
        assert max(abs(x) for x in conditions[3]) > 1e-3


def tc6_error(scheme, nsteps):
    return helpers.tc6_error(ORDER_DAYS, 2048, "imex", nsteps, (("scheme", scheme), ("tol", 1e-13)))[:2]


@pytest.mark.roundoff
@pytest.mark.parametrize("scheme, lo, hi", [("ars232", 1.8, 2.2), ("ars343", 2.7, 3.3)])
def test_imex_temporal_order_tc6(scheme, lo, hi):
    """TC6 inviscid, 64 -> 128 steps over 0.25 day: rate 2 (ARS(2,3,2)) and 3
    (ARS(3,4,3)); mass to round-off (``roundoff.mass_change_bound``, an update of
    the depth per RHS evaluation and Helmholtz iteration)."""
    coarse, rc = tc6_error(scheme, 64)
    fine, rf = tc6_error(scheme, 128)
    rate = math.log2(coarse / fine)
    print(
        f"\n{scheme}: error {coarse:.4e} -> {fine:.4e}, rate {rate:.3f}; {rc.iterations} / {rf.iterations}; "
        f"mass change {rf.diagnostics['mass_change']:.1e}"
    )
    assert lo <= rate <= hi
    assert fine > 1e-8  # far above the rk4 reference's own error (3.5e-12)
    roundoff.within(
        abs(rf.diagnostics["mass_change"]),
        roundoff.mass_change_bound(roundoff.operations(rf), cached_grid(4, 4).nnodes),
        "|mass change|",
    )


@pytest.mark.roundoff
@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_imex_conserves_mass_and_is_stable_at_the_advective_limit(scheme):
    """TC5 (topography, hyperviscosity) at ne = 8 for 5 days at 12x the
    gravity-wave limit dt_g (1.5x the advective Courant-1 step, 7.9 dt_g here;
    at ne = 16 12 dt_g is the advective limit): stable, l2(h+hs) against T213
    within 2x of ssprk3's at its scene step (measured 9.5e-4 and 9.4e-4 against
    6.5e-4), mass to round-off (1.3e-15)."""
    hv = {
        f"hyperviscosity.{k}": 1.5e15 for k in ("nu", "nu_div", "nu_s")
    }  # HOMME's nu at ne30 (scaled dx^3.2): the stability measured here is with it
    base = load_scene("tc5_mountain", ne=8, np_=4, days=5.0, overrides=hv)
    explicit, sim, _ = run(dataclasses.replace(base, output_every_days=5.0))
    c = sim.courant()
    dt_g = base.dt / c["courant_gravity"]
    n = math.ceil(5 * DAY / (12 * dt_g))
    scene = dataclasses.replace(
        base, stepper="imex", dt=5 * DAY / n, stepper_options={"scheme": scheme}, output_every_days=5.0
    )
    result, _, wall = run(scene)
    e, i = explicit.diagnostics["ref_l2_h_surface"], result.diagnostics.get("ref_l2_h_surface")
    print(
        f"\n{scheme}: dt {scene.dt:.0f} s = {scene.dt / dt_g:.2f} dt_g (advective limit {base.dt / c['courant_advective'] / dt_g:.2f} dt_g): "
        f"{result.blowup or f'l2(h+hs) {i:.3e}'} (ssprk3 {e:.3e}), mass change {result.diagnostics['mass_change']:.1e}, "
        f"{result.iterations}, {wall:.1f} s"
    )
    assert result.blowup is None
    assert scene.dt >= 11.5 * dt_g
    assert i < 2 * e
    roundoff.mass_kept(result.history, cached_grid(8, 4).nnodes)


def _imex_sim(scheme, ne=2):
    base = load_scene("tc5_mountain", ne=ne, np_=4)
    return Simulation(
        dataclasses.replace(base, stepper="imex", stepper_options={"scheme": scheme}, dt=base.dt * 4),
        "cpu",
        progress=False,
    )


# a step's own launches (and memsets/copies) at ne 2, the solves and the ∇⁴ apart: ARS(3,4,3) 26
# and ARS(2,3,2) 19 with plain passes; 21 and 15 with the combinations' F-holding passes in the
# RHS's DSS (``ImexRK.fused``); 18 and 13 with L Y_i written by the solve's back-substitution;
# 15 and 10 with L x(n) in one element pass and one DSS (``GravityWaveOperator``)
OWN_LAUNCHES = {"ars343": 15, "ars232": 10}


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_an_imex_step_launches_what_its_fused_passes_need(tally, scheme):
    """The launches of one TC5 ne 2 IMEX step outside its Helmholtz solves and ∇⁴ (not counted
    while they run): one product for L x(n) (one element pass and its DSS), s RHS
    (tendency and DSS: s DSS passes, the combinations' F-holding passes inside them), the
    combinations' other passes (L Y_i inside the solves), and the counters' reset; pinned, so a
    plain pass coming back fails."""
    sim = _imex_sim(scheme)
    gw, model = sim.stepper.helmholtz, sim.model
    gw.solve, model.hyperviscosity = tally.paused(gw.solve), tally.paused(model.hyperviscosity)
    for _ in range(2):
        sim.stepper.step(sim.x)
    with tally.counting():
        sim.stepper.step(sim.x)
    stages = len(SCHEMES[scheme]["b_E"])
    dss = sum(n for key, n in tally.launches.items() if key.startswith("dss"))
    assert dss == stages + 1 and tally.memops == 1, dict(tally.launches)  # the product's DSS; no copy of x(n)
    assert tally.total_launches == OWN_LAUNCHES[scheme], dict(tally.launches)


@pytest.mark.roundoff
@pytest.mark.parametrize("device", ["cpu", helpers.ON_CUDA])
@pytest.mark.parametrize("per_element", [True, False])
def test_a_solve_writes_the_stage_tendency_with_the_bits_of_its_own_pass(device, per_element):
    """``HelmholtzSolver.solve(r, a, z, s, implicit=lz)`` (an IMEX stage's L Y = (Y − rhs)/a written
    by the back-substitution: ``helmholtz_back_substitution``'s implicit variant per element,
    compiled without FMA contraction as ``blas`` is, or ``schur_wind_implicit`` per node) on TC5
    ne 2's state at a = 1800 s, lz in r's own array (as ``ImexRK`` writes it): lz bitwise
    ``blas.axpby(1/a, z, −s/a, r)``, and at s = 1 (the IMEX stages') z bitwise the plain solve's.
    On CUDA lz and axpby agree to 2ε relative, not bitwise (each kernel's FMA contraction). At
    s = 3 the per-element z may differ from the plain solve's in its last bit (s·r_v − ag·S wg
    with and without contraction; at s = 1 the plain kernel's contraction leaves z's bits, as
    checked here): ≤ 4ε relative to each row's largest value."""
    sim = Simulation(load_scene("tc5_mountain", ne=2, np_=4), device, progress=False)
    m = sim.model
    if not per_element:
        m = ShallowWater(
            sim.grid, m.terms, m.operators.fcor.numpy(), m.operators.hs.numpy(), device=device, per_element=False
        )
    gw = HelmholtzSolver(GravityWaveOperator(m, 0.0), HelmholtzOptions(1e-12, 200, guess_history=0))
    gw.operator.set_depth(sim.x)
    a = 1800.0
    for s in (1.0, 3.0):
        z, lz = wp.zeros_like(sim.x), wp.clone(sim.x)
        gw.solve(lz, a, z, s, implicit=lz)
        plain, axpby = wp.zeros_like(sim.x), wp.zeros_like(sim.x)
        gw.solve(sim.x, a, plain, s)
        m.lincomb(axpby, ((1.0 / a, z), (-s / a, sim.x))).launch()
        assert gw.iterations() > 0
        if device == "cpu":
            assert np.array_equal(lz.numpy(), axpby.numpy()), s
            if s == 1.0:
                assert np.array_equal(z.numpy(), plain.numpy())
        else:  # NVRTC contracts a·z + b·r into an FMA (Warp's fuse_fp, on for CPU and CUDA alike: turning it
            # off would move the CPU's bits) and may fuse the other product in each kernel: an ulp apart
            terms = (np.abs(z.numpy()) + s * np.abs(sim.x.numpy())) / a  # each a rounding's size, not the sum's
            d = np.abs(lz.numpy() - axpby.numpy()).max(axis=1) / terms.max(axis=1)
            roundoff.within(max(d), roundoff.bound(2), f"|lz − axpby| on CUDA at s = {s:g}")
        diff = np.abs(z.numpy() - plain.numpy()).max(axis=1)
        roundoff.within(max(diff / np.abs(plain.numpy()).max(axis=1)), roundoff.bound(4), f"|z − plain z| at s = {s:g}")
        assert np.abs(lz.numpy()).max() > 0.0
