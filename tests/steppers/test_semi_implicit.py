"""The semi-implicit leapfrog stepper (``stepper = "semi_implicit"``) and its
Helmholtz solver.

Measured on Warp's CPU backend (2 busy cores):

* TC2, ne = 4, np = 4, 5 days. Explicit gravity-wave limit dt_limit = the
  Courant-1 step min Δx / max sqrt(g h) = 2856.7 s (ssprk3's own limit, by
  bisection: 0.975 and 0.905 dt_limit for alpha = 0 and pi/4). Semi-implicit,
  default options (H = initial mean depth, Robert–Asselin 0.05), over 5 days:

      dt / dt_limit   1.00   1.39   1.78   1.87   1.91   1.94   1.99   2.19
      alpha = 0 l2    1.76   1.79   1.81   1.87   2.71   4.21   12.7   979   (1e-4)
      alpha = pi/4    3.08   3.07   3.07   3.24   4.89   8.47   27.2   blow-up
      (ssprk3 at its scene step 1200 s: 1.970e-4 and 3.170e-4)

  so the largest step that stays stable is ~1.85 dt_limit (~1.9x ssprk3's
  limit); the test uses 1.78 dt_limit (85 steps of 5082 s): l2(h) ratio to the
  explicit 0.921 / 0.969. The step is limited by the explicitly leapfrogged
  advection (advective Courant number ~0.42 there, leapfrog's limit being ~0.5
  of a Courant-1 step), not by gravity waves. A deeper reference depth
  (mean_depth = 3000 m, the maximum) moves the limit to ~2.2 dt_limit
  (1.99 dt_limit: 1.750e-4, ratio 0.888).
* Mass (TC5 ne = 4, one day): 1.1e-15 at the scene step (675 s), -3.6e-16 at 3600 s.
* The Helmholtz solve (shared ``helmholtz.HelmholtzSolver``, the compiled CG): its
  operator equals the assembled matrix, a solve equals a direct sparse solve,
  the same bits on 1 and 2 threads.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import re

import numpy as np
import pytest
import warp as wp

from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.core.backend import Backend
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import StepFailure
from swe_sphere.model.gravity_wave import GravityWaveOperator, reference_depth
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.solvers.helmholtz import HelmholtzOptions, HelmholtzSolver
from swe_sphere.solvers.helmholtz_matrix import helmholtz_matrix
from swe_sphere.steppers import STEPPERS

import roundoff
from helpers import make_sim, requires_cuda, run, write_tc2_scene
from numpy_ops import NumpyOps

DEVICE = "cpu"
STEADY_DAYS = 5.0
SI_FACTOR = 1.78  # the SI step in units of dt_limit (largest stable: ~1.85)
UNSTABLE_FACTOR = 2.2


def at_multiple(base, stepper, factor, limit, **options):
    """``base`` with ``stepper`` at the longest step <= factor·limit dividing the run;
    one output at the end, so the step need not divide a day."""
    n = math.ceil(base.days * DAY / (factor * limit))
    return dataclasses.replace(
        base, stepper=stepper, dt=base.days * DAY / n, stepper_options=options, output_every_days=base.days
    )


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# -- TC2 at the largest stable semi-implicit step ----------------------------------------


@pytest.mark.parametrize("name", ["tc2_steady", "tc2_steady_alpha_pi4"])
def test_semi_implicit_keeps_tc2_steady_at_its_largest_stable_step(name):
    """5 days at ne = 4, np = 4. dt_limit = Δx_min / max sqrt(g h), the Courant-1
    step (ssprk3 blows up there and at the SI step). SI at 1.78 dt_limit keeps
    l2(h) within 2x of ssprk3 at the scene's step; at 2.2 dt_limit it does not
    (blow-up or l2(h) > 10x), so 1.78 is near its largest stable step."""
    base = load_scene(name, ne=4, np_=4, days=STEADY_DAYS)
    limit = base.dt / make_sim(base).courant()["courant_gravity"]
    explicit, _, t_exp = run(dataclasses.replace(base, output_every_days=STEADY_DAYS))
    assert explicit.blowup is None
    e = explicit.diagnostics["l2_h"]

    scene = at_multiple(base, "semi_implicit", SI_FACTOR, limit)
    si, sim, t_si = run(scene)
    assert si.blowup is None, si.blowup
    s = si.diagnostics["l2_h"]
    explicit_there, _, _ = run(at_multiple(base, "ssprk3", SI_FACTOR, limit))
    too_long, _, _ = run(at_multiple(base, "semi_implicit", UNSTABLE_FACTOR, limit))
    print(
        f"\n{name}: dt_limit {limit:.1f} s; ssprk3 dt {base.dt:g} s: l2(h) {e:.4e} ({t_exp:.2f} s); "
        f"SI dt {scene.dt:.1f} s = {scene.dt / limit:.3f} dt_limit, {scene.nsteps} steps: l2(h) {s:.4e}, "
        f"ratio {s / e:.3f}, l2(wind) {si.diagnostics['l2_wind']:.4e} (explicit {explicit.diagnostics['l2_wind']:.4e}), "
        f"mass change {si.diagnostics['mass_change']:.1e}, {si.iterations}, {t_si:.2f} s; "
        f"ssprk3 at that step: {explicit_there.blowup or explicit_there.diagnostics['l2_h']}; "
        f"SI at {UNSTABLE_FACTOR} dt_limit: {too_long.blowup or too_long.diagnostics['l2_h']}"
    )
    assert scene.dt >= 1.75 * limit
    assert 0.5 * e <= s <= 2.0 * e
    assert si.diagnostics["l2_wind"] <= 2.0 * explicit.diagnostics["l2_wind"]
    roundoff.within(
        abs(si.diagnostics["mass_change"]),
        roundoff.mass_change_bound(2 * roundoff.operations(si), sim.grid.nnodes),
        "|mass change|",
    )
    assert explicit_there.blowup is not None
    assert too_long.blowup is not None or too_long.diagnostics["l2_h"] > 10 * e


def test_mean_depth_option_reaches_the_stepper():
    """TC2 (alpha = 0) at 1.99 dt_limit: with the default H (the initial mean depth
    rounded to 6 digits, 2363.02 m) the wave starts to go unstable (l2(h) 1.27e-3, 6.5x ssprk3); with
    mean_depth = 3000 m (the deepest point) it stays steady (1.750e-4)."""
    base = load_scene("tc2_steady", ne=4, np_=4, days=STEADY_DAYS)
    limit = base.dt / make_sim(base).courant()["courant_gravity"]
    e = run(dataclasses.replace(base, output_every_days=STEADY_DAYS))[0].diagnostics["l2_h"]
    default, sim_d, _ = run(at_multiple(base, "semi_implicit", 2.0, limit))
    deep, sim_h, _ = run(at_multiple(base, "semi_implicit", 2.0, limit, mean_depth=3000.0))
    print(
        f"\nH = {sim_d.stepper.H:.1f} m: {default.blowup or default.diagnostics['l2_h']}; "
        f"H = {sim_h.stepper.H:.1f} m: {deep.blowup or deep.diagnostics['l2_h']}; ssprk3 {e:.4e}"
    )
    h0 = make_sim(base).fields()[2]  # the initial depth
    w = sim_d.grid.spheremp
    assert sim_h.stepper.H == 3000.0
    mean = float(w @ h0 / w.sum())  # the initial mean depth, rounded to 6 digits (the same on any ranks)
    assert sim_d.stepper.H == reference_depth(mean) and abs(sim_d.stepper.H - mean) <= 0.005
    assert deep.blowup is None and deep.diagnostics["l2_h"] < 2 * e
    assert default.blowup is not None or default.diagnostics["l2_h"] > 2 * e


# -- mass ---------------------------------------------------------------------------------


@pytest.mark.roundoff
@pytest.mark.parametrize("dt", [None, 3600.0], ids=["scene_dt", "dt3600"])
def test_semi_implicit_conserves_mass_to_round_off(dt):
    """TC5 (with topography and hyperviscosity), ne = 4, one day: mass to round-off,
    two updates of the depth (the leapfrog step and its time filter) per RHS evaluation
    and Helmholtz iteration (``roundoff.mass_kept``)."""
    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper="semi_implicit", dt=dt)
    result, sim, wall = run(scene)
    assert result.blowup is None
    changes = [h["mass_change"] for h in result.history]
    print(
        f"\ndt {scene.dt:g} s ({scene.nsteps} steps, gravity-wave Courant {result.courant['courant_gravity']:.2f}): "
        f"mass change {changes}, {result.iterations}, {wall:.2f} s"
    )
    roundoff.mass_kept(result.history, sim.grid.nnodes, lambda d: 2 * roundoff.operations(d))


# -- the shared gravity-wave operator and its Helmholtz solvers ------------------------


def _gw(tol=1e-13, ne=2):
    scene = load_scene("tc5_mountain", ne=ne, np_=4, days=1.0, stepper="semi_implicit", dt=1800.0)
    sim = make_sim(scene)
    gw = HelmholtzSolver(GravityWaveOperator(sim.model, 0.0), HelmholtzOptions(tol, 1000, guess_history=0))
    gw.operator.set_depth(sim.x)
    return sim, gw, NumpyOps(sim.grid)


@pytest.mark.roundoff
def test_helmholtz_matrix_equals_the_matrix_free_operator(rng):
    """K = −M D G assembled from the model's element kernels (ne = 2) against the
    matrix-free product with the model's operators and against the numpy reference;
    K·1 = 0 (no mass source) to round-off: a row's entries each rounded and then summed,
    2 ε a nonzero of the largest entry. Measured: 3e-16, 3e-16 and 1e-15 relative."""
    sim, gw, ops = _gw()
    grid, K = sim.grid, helmholtz_matrix(sim.model)
    y = rng.standard_normal(grid.nunique)
    DG = ops.dss(ops.divergence(*ops.dss(ops.gradient(y[grid.gid]))))
    ref = -np.bincount(grid.gid, weights=grid.spheremp * DG)  # −M D G y on unique nodes
    c = 1e14  # (M + cK) y / c − M y / c: large c keeps the cancellation at round-off
    yw = wp.array(y, dtype=wp.float64, device=DEVICE)
    matrix_free = {}
    per_node = ShallowWater(
        grid, sim.model.terms, sim.model.fcor.numpy(), sim.model.hs.numpy(), device=DEVICE, per_element=False
    )
    for layout, model in (("per element", sim.model), ("per node", per_node)):  # the CPU's and CUDA's operator
        out = wp.zeros(grid.nunique, dtype=wp.float64, device=DEVICE)
        HelmholtzSolver(GravityWaveOperator(model, gw.H), HelmholtzOptions(1e-10, 10, guess_history=0)).apply(
            yw, out, c
        )
        matrix_free[layout] = (out.numpy() - grid.area * y) / c
    ones = np.abs(K @ np.ones(grid.nunique)).max() / np.abs(K).max()
    print(
        f"\nnnz/row {K.nnz / grid.nunique:.1f}; |Ky - numpy| {rel(K @ y, ref):.1e}, |K 1| {ones:.1e}, |Ky - matrix-free| "
        + ", ".join(f"{k} {rel(K @ y, v):.1e}" for k, v in matrix_free.items())
    )
    # K y: a gradient and a divergence, each with its DSS, in another order (assembled
    # entries, kernels, numpy): four passes of roundoff.operator_roundings
    limit = roundoff.bound(roundoff.operator_roundings(grid.np, 4))
    roundoff.within(rel(K @ y, ref), limit, "|K y − numpy| / |K y|")
    for layout, v in matrix_free.items():
        roundoff.within(rel(K @ y, v), limit, f"|K y − matrix-free ({layout})| / |K y|")
    roundoff.within(ones, roundoff.bound(2 * np.diff(K.indptr).max()), "max |K 1| / max |K|")
    assert abs(K - K.T).max() == 0.0


@pytest.mark.roundoff
def test_schur_solve_inverts_i_minus_a_l(rng):
    """z = (I − aL)⁻¹ (s·r) on random continuous r (ne = 2) at a = 1800 s and
    18000 s (gravity-wave Courant ~4 and ~40): z − aLz = s·r to 1e-10 with the
    numpy L, and ∫z_h = s∫r_h to round-off (relative to ∫|s r_h|: each CG iteration
    updates z, r and p, ≤ 3 ε of it, and the integrals round ⌈log2 N⌉ ε each)."""
    sim, gw, ops = _gw()
    m, w = sim.model, sim.grid.spheremp
    r = ops.dss(rng.standard_normal((3, m.N)) * np.array([[10.0], [10.0], [100.0]]))
    z = wp.zeros((3, m.N), dtype=wp.float64, device=DEVICE)
    for a, s in ((1800.0, 1.0), (18000.0, 3.0)):
        gw.solve(wp.array(r, dtype=wp.float64, device=DEVICE), a, z, scale=s)
        its = gw.iterations()
        zn = z.numpy()
        resid = rel(zn - a * ops.gravity_wave(zn, m.g, gw.H), s * r)
        mass = (np.sum(w * zn[2]) - s * np.sum(w * r[2])) / np.sum(w * np.abs(s * r[2]))
        print(
            f"\na = {a:g}: {its} iterations, relative residual {resid:.1e}, mass {mass:.1e}, |z - r| / |r| {rel(zn, s * r):.2f}",
            end="",
        )
        assert resid < 1e-10
        roundoff.within(abs(mass), roundoff.mass_change_bound(3 * its, m.N), f"|mass| a = {a:g}")
        assert rel(zn, s * r) > 0.1  # a real correction, not the identity


def _pcg_solve(monkeypatch, threads, ne, c, b, tol=1e-11, precision="double"):
    """(M + cK) y = b by the compiled CG on ``threads`` CPU threads (TC5 grid at ne): (y, iterations, solver)."""
    monkeypatch.setenv("SWE_SPHERE_THREADS", str(threads))
    scene = load_scene("tc5_mountain", ne=ne, np_=4, days=1.0, stepper="semi_implicit", dt=1800.0)
    sim = make_sim(scene)
    gw = HelmholtzSolver(
        GravityWaveOperator(sim.model, 5000.0), HelmholtzOptions(tol, 2000, precision=precision, guess_history=0)
    )
    gw.b.assign(b)
    gw.solve_height(c)
    its = gw.iterations()
    return gw.y.numpy().copy(), its, gw


# precision, tol, the bound on |y − spsolve| / |spsolve| (measured: 2e-12; 1.3e-11 and 3e-12
# for the refined float32 solves; 2.4e-3 and 1.6e-3 for the float32 solve alone to 1e-2)
SOLVES = [("double", 1e-11, 1e-9), ("mixed", 1e-11, 1e-9), ("mixed", 1e-2, 3e-2)]


@pytest.mark.parametrize("precision, tol, bound", SOLVES)
def test_pcg_equals_a_direct_sparse_solve(rng, monkeypatch, precision, tol, bound):
    """The compiled CG on (M + cK) y = b (ne = 4, c = 4e9 m² and 4e10 m², about 4x and 13x
    the gravity-wave limit) against scipy's spsolve of the assembled matrix with the same
    mean fix, in float64, in float32 refined in float64 to 1e-11 (far below float32's
    reach), and in float32 alone to the JFNK preconditioner's 1e-2; and the float64 residual
    of the solution within tol (the mixed solve's own test is on it)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper="semi_implicit", dt=1800.0)
    sim = make_sim(scene)
    area, K = sim.grid.area, helmholtz_matrix(sim.model)
    b = rng.standard_normal(area.size) * area
    for c in (4e9, 4e10):
        y, its, _ = _pcg_solve(monkeypatch, 1, 4, c, b, tol, precision)
        A = (sp.diags(area) + c * K).tocsc()
        x = spla.spsolve(A, b)
        x += (b.sum() - area @ x) / area.sum()
        resid = rel(A @ y, b)
        print(f"\nc = {c:g}: {its} iterations, |y - spsolve| / |spsolve| {rel(y, x):.1e}, residual {resid:.1e}", end="")
        assert rel(y, x) < bound
        assert resid < 1.1 * tol  # the mean fix moves y along M·1, within round-off of the residual
        assert its > 1  # a real iteration, not a converged start


@pytest.mark.parametrize("precision", ["double", "mixed"])
def test_a_history_start_gives_the_answers_in_fewer_iterations(rng, precision):
    """Six solves (ne = 4, c = 4e10 m²) of right-hand sides on a quadratic in time,
    b(t) = area·(f₀ + t f₁ + t² f₂), from the last solution (``guess_history`` 0) and from
    the projection onto the past solutions (k = 8, ``GuessHistory``): each answer of the one
    within 4 tol‖b‖/min(area) of the other's (A = M + cK ≥ M: each is 2‖r‖/min(area) from
    the exact one, its mean shift included), in no more iterations, and once three solutions
    span the quadratic
    in at most two a solve (measured: 9, then 8 a solve warm; 9, 8, 7, 0, 1, 0 projected,
    9, 8, 7, 1, 0, 0 in "mixed" precision; a solution already in the span adds nothing); the basis
    A-orthonormal, A applied anew, in the three vectors spanning the quadratic within 1e-13
    (measured 1e-15; the later ones, increments of the residual's size whose products carry
    the CG's round-off ε‖b‖, 1e-7 in float64 and 3e-6 in "mixed": the guess's accuracy;
    the answer's residual gets their errors times the coefficients, round-off of ‖b‖)."""
    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper="semi_implicit", dt=1800.0)
    sim = make_sim(scene)
    area, tol, c = sim.grid.area, 1e-8, 4e10
    f = rng.standard_normal((3, area.size))
    bs = [area * (f[0] + t * f[1] + t * t * f[2]) for t in np.linspace(0.0, 0.5, 6)]
    answers, counts = {}, {}
    for k in (0, 8):
        gw = HelmholtzSolver(
            GravityWaveOperator(sim.model, 5000.0),
            HelmholtzOptions(tol, 2000, precision=precision, guess_history=k),
            warm=True,
        )
        gw.operator.set_depth(sim.x)
        ys, its = [], []
        for b in bs:
            gw.b.assign(b)
            gw.solve_height(c, history=c if k else None)  # one sequence, under c (``solve``'s would be its a)
            ys.append(gw.y.numpy().copy()), its.append(gw.iterations())
        answers[k], counts[k] = ys, its
    print(f"\niterations from the last solution {counts[0]}, from the projection {counts[8]}", end="")
    for b, y0, y8 in zip(bs, answers[0], answers[8]):
        assert np.linalg.norm(y8 - y0) <= 4 * tol * np.linalg.norm(b) / area.min()
    assert min(counts[0]) > 5 and all(p <= w for p, w in zip(counts[8], counts[0])) and max(counts[8][3:]) <= 2
    h = gw.histories[c]
    n = h.count()
    X, AX = h.X.numpy()[:n], np.empty((n, area.size))
    out = wp.zeros(area.size, dtype=wp.float64, device=DEVICE)
    for j in range(n):
        gw.apply(h.X[j], out, c)
        AX[j] = out.numpy()
    G = np.abs(X @ AX.T - np.eye(n))
    assert n >= 3 and G[:3, :3].max() < 1e-13


@pytest.mark.parametrize("precision", ["double", "mixed"])
def test_pcg_has_the_same_bits_on_one_and_two_threads(rng, monkeypatch, precision):
    """The compiled CG at ne = 16 (enough nodes that launches split): the same
    iterations and the same bits on 1 and 2 CPU threads, in either precision."""
    b = rng.standard_normal(6 * 16 * 16 * 9 + 2)
    y1, it1, _ = _pcg_solve(monkeypatch, 1, 16, 1e10, b, precision=precision)
    y2, it2, gw2 = _pcg_solve(monkeypatch, 2, 16, 1e10, b, precision=precision)
    assert gw2.model.threads == 2 and gw2.cg.parts > 1  # the launches really split
    assert it1 == it2 > 5
    assert np.array_equal(y1, y2)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("precision, tol", [("double", 1e-10), ("mixed", 1e-10), ("mixed", 1e-2)])
def test_a_helmholtz_solve_reads_nothing_back(rng, monkeypatch, tally, precision, tol, threads):
    """A Helmholtz solve (ne = 4, one rank) reads nothing back to the host: the CG's
    recurrences, its convergence test, the refinement's and the area shift run on the
    device, in a CPU graph (one thread) or host loops that test the flag in place without
    a copy (two). ``iterations`` is the one read, and a second call finds the counters
    zeroed. (Before: b·b, the start's sums, the area shift and one read an iteration.)"""
    monkeypatch.setenv("SWE_SPHERE_THREADS", str(threads))
    sim, _, ops = _gw(ne=4)
    m = sim.model
    gw = HelmholtzSolver(GravityWaveOperator(m, 0.0), HelmholtzOptions(tol, 1000, precision=precision, guess_history=0))
    gw.operator.set_depth(sim.x)
    r = wp.array(
        ops.dss(rng.standard_normal((3, m.N)) * np.array([[10.0], [10.0], [100.0]])), dtype=wp.float64, device=DEVICE
    )
    z = wp.zeros((3, m.N), dtype=wp.float64, device=DEVICE)
    gw.solve(r, 1800.0, z)  # records
    gw.iterations()
    with tally.counting():
        gw.solve(r, 3600.0, z)
        gw.solve(r, 1800.0, z)
    assert tally.syncs == 0
    with tally.counting():
        its = gw.iterations()
    assert tally.syncs == 1 and its > 8  # both solves ran
    assert gw.iterations() == 0


@pytest.mark.parametrize("precision, tol", [("double", 1e-10), ("mixed", 1e-10), ("mixed", 1e-2)])
def test_an_unconverged_solve_fails_at_the_read(rng, precision, tol):
    """Past ``maxiter`` a solve (ne = 2) counts a failure on the device; ``iterations``
    raises ``StepFailure`` naming the iterations and the residual, and the counters start
    again from zero."""
    sim, _, ops = _gw()
    m = sim.model
    gw = HelmholtzSolver(GravityWaveOperator(m, 0.0), HelmholtzOptions(tol, 2, precision=precision, guess_history=0))
    gw.operator.set_depth(sim.x)
    r = wp.array(
        ops.dss(rng.standard_normal((3, m.N)) * np.array([[10.0], [10.0], [100.0]])), dtype=wp.float64, device=DEVICE
    )
    gw.solve(r, 18000.0, wp.zeros((3, m.N), dtype=wp.float64, device=DEVICE))
    with pytest.raises(StepFailure, match=r"^Helmholtz CG did not converge in 2 iterations \(residual [0-9.e+-]+ > "):
        gw.iterations()
    assert gw.stats.numpy().tolist() == [0.0, 0.0, 0.0]


def _steps(monkeypatch, stepper, device="cpu", threads=1, precision="double", tally=None):
    """Three steps of ``stepper`` (TC5, ne = 4, 8x the scene step, one rank): (final state,
    Helmholtz iterations a step, host reads in the third step (``tally``), the solves'
    graphs after the second and the third step)."""
    monkeypatch.setenv("SWE_SPHERE_THREADS", str(threads))
    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper=stepper)
    scene = dataclasses.replace(scene, dt=8 * scene.dt, stepper_options={"precision": precision})
    sim = Simulation(scene, device, progress=False)
    gw = sim.stepper.helmholtz
    its = [sim.stepper.step(sim.x).iterations["helmholtz"] for _ in range(2)]  # records and captures, fixes H (a read)
    graphs = gw.graph_count
    with tally.counting() if tally else contextlib.nullcontext():
        its.append(sim.stepper.step(sim.x).iterations["helmholtz"])
    return sim.x.numpy(), its, tally.syncs if tally else None, (graphs, gw.graph_count)


# the solve graphs after ``_steps``' second and third step with one rank where the solver may capture
# (one CPU thread; CUDA with conditional nodes): a solve is captured at its second call, so
# leapfrog's start at dt/2, called once, never; the semi-implicit step's solve at the third step,
# the ARS steps' three at the second (issue 83: the CUDA test still asked for a graph after the
# second step, as before a876498, and read the semi-implicit step's (0, 1) as "no graph")
CAPTURED = {"semi_implicit": (0, 1), "imex": (3, 3)}


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("stepper", ["semi_implicit", "imex"])
def test_a_solver_step_reads_the_host_once(monkeypatch, tally, stepper, threads):
    """A semi-implicit and an IMEX ARS(3,4,3) step on the CPU read the device once: the
    step's Helmholtz iteration count and failure flag (``HelmholtzSolver.iterations``); its 1
    or 3 solves none, as replayed CPU graphs (one thread) or host loops (two). (Before:
    3 + 1 a CG iteration a solve, 36 and 57 a step here.)"""
    _, its, reads, graphs = _steps(monkeypatch, stepper, threads=threads, tally=tally)
    assert reads == 1 and min(its) > 5
    assert graphs == (CAPTURED[stepper] if threads == 1 else (0, 0))


@pytest.mark.parametrize("stepper", ["semi_implicit", "imex"])
def test_the_per_node_layouts_solves_are_captured_as_the_cpus(monkeypatch, stepper):
    """The CUDA layout's solve (the per-node kernels: ``HelmholtzSolver._solve``'s other branch)
    run on one CPU thread is captured at the same calls as the per-element layout's, with its
    iterations: the capture decision a card makes, checked without one."""
    _, its, _, graphs = _steps(monkeypatch, stepper)
    monkeypatch.setattr(Backend, "per_element", property(lambda self: False))
    monkeypatch.setattr(Backend, "nodes_per_thread", lambda self, np_: 1)
    _, per_node, _, per_node_graphs = _steps(monkeypatch, stepper)
    assert per_node_graphs == graphs == CAPTURED[stepper]
    assert per_node == its and min(its) > 5


@pytest.mark.parametrize("precision", ["double", "mixed"])
@pytest.mark.parametrize("stepper", ["semi_implicit", "imex", "implicit"])
def test_graphed_solves_have_the_bits_of_host_loops(monkeypatch, stepper, precision):
    """The solves as Warp CPU graphs (one thread: ``wp.capture_while`` loops, nested for
    the refinement) and as host loops (two threads, the same kernels): the same
    iterations and the same bits after three steps (JFNK: its preconditioner's solves)."""
    x1, its1, _, graphs1 = _steps(monkeypatch, stepper, threads=1, precision=precision)
    x2, its2, _, graphs2 = _steps(monkeypatch, stepper, threads=2, precision=precision)
    assert graphs1[1] > 0 and graphs2[1] == 0
    assert its1 == its2 and min(its1) > 5
    assert np.array_equal(x1, x2)


@pytest.mark.parametrize("warm", [False, True])
def test_pcg_products_and_the_ranks_order(rng, tally, warm):
    """A solve of k iterations (ne = 4, from zero or warm) costs k products (k + 1 warm) with
    the test between the update and the product (one rank), and one more in Chronopoulos–
    Gear's order (update, product, one reduction: how it runs over ranks), with the same
    iterations and bits. (Before: k + 1 and k + 2.)"""
    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper="semi_implicit", dt=1800.0)
    sim = make_sim(scene)
    b = rng.standard_normal(sim.grid.nunique) * sim.grid.area
    out = {}
    for ranks_order in (False, True):
        gw = HelmholtzSolver(
            GravityWaveOperator(sim.model, 5000.0), HelmholtzOptions(1e-10, 1000, guess_history=0), warm=warm
        )
        gw.cg.one_reduction = ranks_order
        gw.b.assign(b)
        gw.y.assign(0.5 * b / sim.grid.area)  # a warm start's guess (ignored from zero)
        with tally.counting():
            gw.solve_height(4e10)
        products = tally.launches["helmholtz_assemble"]
        out[ranks_order] = (gw.y.numpy(), gw.iterations(), products)
    (y1, k, p1), (y2, k2, p2) = out[False], out[True]
    assert k == k2 > 5 and np.array_equal(y1, y2)
    assert (p1, p2) == (k + warm, k + 1 + warm)


@pytest.mark.parametrize("warm", [False, True])
def test_a_whole_solve_is_its_products_and_four_passes(rng, tally, warm):
    """A whole Schur-complement solve (ne = 4, one rank, the CPU's per-element layout) of k CG
    iterations launches its k products (k + 1 warm: the residual of the guess) and, around
    them, four passes: the right-hand side (``helmholtz_rhs`` and one assembly) and the
    back-substitution (one gradient and ``helmholtz_back_substitution``); nothing of the
    per-node form's seven passes (the model's divergence and gradient with their DSS, the
    assembly, the scatter and the pointwise Schur parts). Besides those, only the CG's
    one-node and chunked vector kernels run. (Before: the seven passes, 3.0-5.4 CG
    iterations' time at ne30.)"""
    sim, _, ops = _gw(ne=4)
    gw = HelmholtzSolver(GravityWaveOperator(sim.model, 0.0), HelmholtzOptions(1e-10, 1000, guess_history=0), warm=warm)
    gw.operator.set_depth(sim.x)
    r1, r2 = (
        wp.array(
            ops.dss(rng.standard_normal((3, sim.model.N)) * np.array([[10.0], [10.0], [100.0]])),
            dtype=wp.float64,
            device=DEVICE,
        )
        for _ in range(2)
    )
    z = wp.zeros((3, sim.model.N), dtype=wp.float64, device=DEVICE)
    gw.graphable = False  # the solve's launches, not a graph's replay, counted
    gw.solve(r1, 1800.0, z)  # records; with ``warm``, the guess of the next solve
    gw.iterations()
    with tally.counting():
        gw.solve(r2, 1800.0, z)
    k = gw.iterations()
    products = k + warm
    launched = dict(tally.launches)
    assert k > 5
    assert {
        key: launched.pop(key, 0)
        for key in (
            "helmholtz_rhs",
            "helmholtz_back_substitution",
            "helmholtz_gradient",
            "helmholtz_divergence",
            "helmholtz_assemble",
        )
    } == {
        "helmholtz_rhs": 1,
        "helmholtz_back_substitution": 1,
        "helmholtz_gradient": products + 1,
        "helmholtz_divergence": products,
        "helmholtz_assemble": products + 1,
    }
    assert set(launched) <= {"cg_update", "cg_check", "cg_alpha", "inner3", "add_mean_difference", "row_totals"}, (
        launched
    )


@requires_cuda
@pytest.mark.parametrize("stepper", ["semi_implicit", "imex"])
def test_a_solver_step_on_cuda_replays_graphs_and_reads_once(monkeypatch, tally, stepper):
    """On CUDA (one rank) the step's solves are CUDA graphs captured at their second call
    (the CG's loop a conditional node) and replayed: the step reads the device once."""
    _, its, reads, graphs = _steps(monkeypatch, stepper, "cuda", tally=tally)
    assert reads == 1 and min(its) > 5 and graphs == CAPTURED[stepper]


# -- bad options ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "option, needle",
    [
        ('helmholtz_solver = "cusparse"', "semi_implicit.helmholtz_solver"),
        ('helmholtz_solver = "pcg"', "semi_implicit.helmholtz_solver was removed"),
        ("tol = 1.5", "semi_implicit.tol"),
        ("maxiter = 0", "semi_implicit.maxiter"),
        ("mean_depth = -1.0", "semi_implicit.mean_depth"),
        ("robert_asselin = 0.5", "semi_implicit.robert_asselin"),
        ('tol = "tight"', "semi_implicit.tol"),
        ('precision = "single"', "semi_implicit.precision"),
        ("guess_history = -1", "semi_implicit.guess_history"),
        ("guess_history = 33", "semi_implicit.guess_history"),
        ("guess_history = 2.5", "semi_implicit.guess_history"),
        ("theta = 0.5", "semi_implicit.theta"),
    ],
)
def test_bad_semi_implicit_option_exits_2(option, needle, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "scene.toml"
    write_tc2_scene(path, stepper="semi_implicit", tables=f"[semi_implicit]\n{option}\n")
    output = tmp_path / "bad.nc"
    try:
        code = main(["run", str(path), "--device", "cpu", "--output", str(output), "--no-progress"])
    except SystemExit as exc:
        code = exc.code
    _, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    print(f"\n{option!r}: exit {code}: {err.strip()}")
    assert code == 2
    assert len(lines) == 1 and needle in lines[0]
    assert not list(tmp_path.glob("*.nc*"))


@pytest.mark.parametrize("stepper", ["semi_implicit", "imex", "tableau"])
def test_the_helmholtz_options_are_one_declaration(stepper):
    """The [semi_implicit], [imex] and [tableau] tables take the Helmholtz solve's options
    from ``HelmholtzOptions`` (semi_implicit with its own tighter tol): the same keys and
    defaults, the same one-line errors."""
    cls = STEPPERS[stepper]
    assert issubclass(cls.Options, HelmholtzOptions)
    o = cls.make_options()
    assert (o.maxiter, o.mean_depth, o.precision, o.guess_history) == (500, 0.0, "double", 8)
    assert o.tol == (1e-7 if stepper == "semi_implicit" else 1e-6)
    for key, value, message in (
        ("tol", 1.0, "tol must be in (0, 1)"),
        ("maxiter", 0, "maxiter must be >= 1"),
        ("mean_depth", -5.0, "mean_depth must be >= 0"),
        ("precision", "single", "precision must be one of double, mixed"),
        ("guess_history", 33, "guess_history must be in 0..32"),
    ):
        with pytest.raises(ValueError, match=re.escape(f"{message} (got {value!r})")):
            cls.make_options(**{key: value})
