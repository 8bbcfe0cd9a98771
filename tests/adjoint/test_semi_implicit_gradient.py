"""Gradients of semi-implicit leapfrog runs (``adjoint.tape``: its own step on a tape): the gravity-wave
operator's transpose and the transposed Helmholtz solve by dot products, the whole by Taylor
tests, the forward the ``Simulation``'s to the bit."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import warp as wp

from swe_sphere.adjoint import gradient
from swe_sphere.adjoint.gradient import scene_model
from swe_sphere.config.scene import load_scene
from swe_sphere.core.backend import Backend
from swe_sphere.model.helmholtz import HelmholtzSolver

import taylor
from helpers import requires_cuda

TOL = 1e-12  # the Helmholtz CG's relative residual: see ``si_tc5``


@functools.cache
def si_tc5(ne=2):
    """TC5 at ne 2 np 4 by the semi-implicit leapfrog at Δt 1800 s. The CG's ``tol`` near
    round-off (1e-12, ``model.helmholtz.TIGHTEST``): a step is linear in its solve only to that
    tolerance, and at the default 1e-7 the Taylor remainder below ε = 1e-3 is the solve's
    (measured slopes 1.70 and 2.08 at 1e-4 … 1e-5, 2 and 6 steps). H given (the gravity waves' mean depth): from x(0)
    it is rounded to 6 digits, and a perturbed x(0) could round to another."""
    over = {"semi_implicit.tol": TOL, "semi_implicit.mean_depth": 5700.0}
    return load_scene("testcases/tc5_mountain.toml", ne=ne, np_=4, dt=1800.0, stepper="semi_implicit", overrides=over)


def unweighted_dss(model, a):
    out = wp.zeros((3, model.N), dtype=taylor.f64)
    for launch in model.topology.dss(wp.array(a, dtype=taylor.f64), False, out):
        launch.launch()
    return out.numpy()


def test_the_gravity_wave_operator_and_its_solve_transpose_in_the_mass_form():
    """The derivation's premise: L = (−g G h, −H D v) is skew in the mass form up to the scaling
    S = diag(1, 1, g/H), ⟨L δ, λ⟩ = −Σ spheremp·δ·S L S⁻¹ (R Q λ) for continuous δ, to round-off;
    and the model's A⁻ᵀ (``GravityTranspose.solve``, the adjoint's) against the stepper's own solve A⁻¹ = (I − ΔtL)⁻¹:
    ⟨A⁻¹ δ, λ⟩ = Σ spheremp·δ·A⁻ᵀ(R Q λ), to the CG's tolerance."""
    model, stepper, x0 = scene_model(si_tc5(3))
    w, N, g, H = model.grid.spheremp, model.N, model.g, stepper.H
    rng = np.random.default_rng(3)
    delta = taylor.continuous(model, rng.standard_normal((3, N)) * np.array([[10.0], [10.0], [100.0]]))
    lam = rng.standard_normal((3, N))
    mu = unweighted_dss(model, lam)
    s = np.array([[1.0], [1.0], [g / H]])

    def applied(op, a):
        out = wp.zeros((3, N), dtype=taylor.f64)
        op(wp.array(a, dtype=taylor.f64), out)
        return out.numpy().copy()

    Ld, Lt = applied(stepper.linear.apply, delta), -s * applied(stepper.linear.apply, mu / s)
    left, right = np.sum(Ld * lam), np.sum(w * delta * Lt)
    scale = np.sum(np.abs(Ld * lam)) + np.sum(np.abs(w * delta * Lt))
    # a product's roundings: the derivative's np terms, the metric, the DSS's ≤ 4 copies and
    # weights; np.sum's pairwise sum; measured 0.06 eps of the scale (ne 3 np 4)
    assert abs(left - right) <= (2 * 4 + 8 + np.log2(3 * N)) * taylor.EPS * scale, (left, right)

    def solve(r, z):
        stepper.helmholtz.solve(r, stepper.dt, z)

    Ad = applied(solve, delta)
    m = wp.array(mu, dtype=taylor.f64)
    stepper.linear.transpose(HelmholtzSolver(stepper.linear, stepper.options, warm=True)).solve(m, stepper.dt)
    At = m.numpy()
    left, right = np.sum(Ad * lam), np.sum(w * delta * At)
    assert np.abs(Ad - delta).max() > 0.5 * np.abs(delta).max()  # the solve acts (measured 1.5×)
    scale = np.sum(np.abs(Ad * lam)) + np.sum(np.abs(w * delta * At))
    # each solve's error ≤ κ(A) tol relative (κ of M + Δt²gH K here a few tens); measured 5e-15
    assert abs(left - right) <= 100 * TOL * scale, (left, right, abs(left - right) / scale)


@pytest.mark.parametrize("steps", [1, 6])
def test_a_semi_implicit_run_s_gradient_falls_as_eps_squared(steps):
    """TC5 ne 2: the first step alone (its half step from x(−1) = x(0)) and six steps. The
    remainder of J(x + εδx) − J(x) − ε⟨∇J, δx⟩ falls as ε² over ε = 1e-1 … 1e-5 (measured slopes
    2.0000 ± 6e-4), above the cost's round-off."""
    slopes, rest, J = taylor.taylor_slopes("semi_implicit", steps, [1.0, 1.0, 10.0], si_tc5())
    assert np.all(np.abs(slopes - 2.0) < 0.05), (slopes, rest)
    assert rest[-1] > 1e4 * taylor.EPS * J


def test_a_semi_implicit_gradient_replays_its_run():
    """The gradient's forward run is the ``Simulation``'s to the bit (every state held, each step
    taken once in order); from two snapshots or a disk tier the recomputed steps start their CG
    from the stepper's later guesses, so the gradient is the same to the CG's tolerance, not to
    the bit (measured 7e-14 and 2e-13 of the largest entry). ``parameters`` refused (L holds g, H)."""
    scene, steps = si_tc5(), 6
    model, _, x0 = scene_model(scene)
    cost = taylor.misfit(model, x0, np.random.default_rng(13))
    taylor.assert_replays_the_run(scene, steps, cost, tol=TOL)
    with pytest.raises(ValueError, match="parameters must be False with semi_implicit"):
        gradient(scene, 1, cost, parameters=True)


def assert_layouts_agree(device, monkeypatch=None):
    """The gradient on ``device`` (with ``monkeypatch``: the CPU in CUDA's per-node layout)
    equals the CPU's per-element one to the CG's tolerance (sums in another order, and each
    solve's to tol)."""
    scene = si_tc5()
    model, _, x0 = scene_model(scene)
    cost = taylor.misfit(model, x0, np.random.default_rng(10))
    cpu = gradient(scene, 4, cost, device="cpu")
    if monkeypatch is not None:
        monkeypatch.setattr(Backend, "per_element", property(lambda self: False))
        monkeypatch.setattr(Backend, "nodes_per_thread", lambda self, np_: 1)
    other = gradient(scene, 4, cost, device=device)
    assert other.cost == pytest.approx(cpu.cost, rel=1e-10)
    assert np.abs(other.grad - cpu.grad).max() <= 1e3 * TOL * np.abs(cpu.grad).max()


def test_a_semi_implicit_gradient_in_the_cuda_layout_is_the_cpu_s(monkeypatch):
    assert_layouts_agree("cpu", monkeypatch)


@requires_cuda
def test_a_semi_implicit_gradient_on_cuda_is_the_cpu_s():
    assert_layouts_agree("cuda")
