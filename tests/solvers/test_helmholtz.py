"""The Helmholtz solver (``model.helmholtz.HelmholtzSolver``, the compiled CG) on the shared
gravity-wave operator, apart from any stepper: the assembled matrix equals the matrix-free
operator, the Schur solve inverts I − aL, a solve equals a direct sparse solve (float64, float32
refined, float32 alone), the guess history's start, the same bits on 1 and 2 threads, nothing read
back but the iteration count, an unconverged solve's failure, and the launches a solve makes.
(A stepper's solves in its steps: tests/steppers/test_semi_implicit.py.)"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import StepFailure
from swe_sphere.model.gravity_wave import GravityWaveOperator
from swe_sphere.model.helmholtz import HelmholtzOptions, HelmholtzSolver
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.solvers.helmholtz_matrix import helmholtz_matrix

import roundoff
from helpers import make_sim
from numpy_ops import NumpyOps

DEVICE = "cpu"


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


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
        grid,
        sim.model.terms,
        sim.model.operators.fcor.numpy(),
        sim.model.operators.hs.numpy(),
        device=DEVICE,
        per_element=False,
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


def _pcg_solve(monkeypatch, threads, ne, c, b, tol=1e-11, precision="float64"):
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
SOLVES = [("float64", 1e-11, 1e-9), ("float32", 1e-11, 1e-9), ("float32", 1e-2, 3e-2)]


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


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_history_start_gives_the_answers_in_fewer_iterations(rng, precision):
    """Six solves (ne = 4, c = 4e10 m²) of right-hand sides on a quadratic in time,
    b(t) = area·(f₀ + t f₁ + t² f₂), from the last solution (``guess_history`` 0) and from
    the projection onto the past solutions (k = 8, ``GuessHistory``): each answer of the one
    within 4 tol‖b‖/min(area) of the other's (A = M + cK ≥ M: each is 2‖r‖/min(area) from
    the exact one, its mean shift included), in no more iterations, and once three solutions
    span the quadratic
    in at most two a solve (measured: 9, then 8 a solve warm; 9, 8, 7, 0, 1, 0 projected,
    9, 8, 7, 1, 0, 0 in "float32" precision; a solution already in the span adds nothing); the basis
    A-orthonormal, A applied anew, in the three vectors spanning the quadratic within 1e-13
    (measured 1e-15; the later ones, increments of the residual's size whose products carry
    the CG's round-off ε‖b‖, 1e-7 in float64 and 3e-6 in "float32": the guess's accuracy;
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


@pytest.mark.parametrize("precision", ["float64", "float32"])
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
@pytest.mark.parametrize("precision, tol", [("float64", 1e-10), ("float32", 1e-10), ("float32", 1e-2)])
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


@pytest.mark.parametrize("precision, tol", [("float64", 1e-10), ("float32", 1e-10), ("float32", 1e-2)])
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
