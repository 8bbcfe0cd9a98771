"""Gradients of IMEX additive Runge–Kutta runs (``adjoint.tape``, their own steps on a tape: ``imex``'s ARS pairs, ``ark324``,
``ark436``, an IMEX ``tableau``): the reversed step against the pair's linear step at rest by a dot product, the whole
by Taylor tests, the forward the ``Simulation``'s to the bit."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
import warp as wp

from swe_sphere.adjoint import gradient
from swe_sphere.adjoint.gradient import scene_model, step_adjoint
from swe_sphere.config.scene import load_scene
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers.tables import IMEX

import taylor

TOL, H = 1e-12, 5700.0  # the Helmholtz CG's relative residual and the mean depth: see ``imex_tc5``


@functools.cache
def imex_tc5(stepper="imex", scheme=None, terms=None):
    """TC5 at ne 2 np 4 by ``stepper`` at Δt 1800 s (``scheme``: imex's pair; ``terms``: these
    alone). The CG's ``tol`` near round-off (1e-12, ``model.helmholtz.TIGHTEST``): a step is
    linear in its solves only to that tolerance, as ``semi_implicit``'s (at its default the
    Taylor remainder below ε = 1e-3 is the solves'). H given: from x(0) it is rounded to 6 digits,
    and a perturbed x(0) could round to another (a jump in J)."""
    over = {f"{stepper}.tol": TOL, f"{stepper}.mean_depth": H}
    if scheme is not None:
        over["imex.scheme"] = scheme
    scene = load_scene("testcases/tc5_mountain.toml", ne=2, np_=4, dt=1800.0, stepper=stepper, overrides=over)
    return scene if terms is None else dataclasses.replace(scene, terms=terms)  # (TC5's checks need its terms)


@pytest.mark.parametrize(
    ("stepper", "scheme", "steps"), [("imex", None, 3), ("imex", "ars232", 2), ("ark324", None, 2), ("ark436", None, 1)]
)
def test_an_imex_run_s_gradient_falls_as_eps_squared(stepper, scheme, steps):
    """The remainder of J(x + εδx) − J(x) − ε⟨∇J, δx⟩ falls as ε² over ε = 1e-1 … 1e-5 (measured
    slopes 2.0000 ± 2e-4: ARS(3,4,3) 3 steps, ARS(2,3,2) 2, ark324 2, ark436 1), above the
    cost's round-off."""
    slopes, rest, J = taylor.taylor_slopes(stepper, steps, [1.0, 1.0, 10.0], imex_tc5(stepper, scheme))
    assert np.all(np.abs(slopes - 2.0) < 0.05), (slopes, rest)
    assert rest[-1] > 1e4 * taylor.EPS * J


def unweighted_dss(model, a):
    out = wp.zeros((3, model.N), dtype=taylor.f64)
    for launch in model.topology.dss(wp.array(a, dtype=taylor.f64), False, out):
        launch.launch()
    return out.numpy()


@pytest.mark.parametrize("stepper", ["imex", "ark324"])
def test_a_reversed_imex_step_at_rest_is_the_transpose_of_the_pair_s_linear_step(stepper):
    """With the continuity and pressure gradient alone, F's Jacobian at rest x_H = (0, 0, H) is L,
    so the step's Jacobian there is the pair's step of L alone (r_i = δ + Δt Σ a^I_ij L Y_j,
    Y_i = (I − Δt a^I_ii L)⁻¹ r_i, then Φ and the ∇⁴), formed here from the stepper's own L and
    solve: ⟨J δ, λ⟩ = Σ spheremp·δ·(the reversed step of R Q λ) for continuous δ, to the
    products' round-off and the solves' tolerance (measured 1.8e-16 and 5.3e-15 of the scale;
    6e-4 with Lᵀ's sign flipped)."""
    scene = imex_tc5(stepper, terms=("continuity", "pressure_gradient"))
    model, st, _ = scene_model(scene)
    N, dt, w = model.N, st.dt, model.grid.spheremp
    A_E, b_E, A_I, b_I, c = st.table().floats()
    rng = np.random.default_rng(5)
    delta = taylor.continuous(model, rng.standard_normal((3, N)) * np.array([[10.0], [10.0], [100.0]]))
    lam = rng.standard_normal((3, N))

    def applied(op, a, *args):
        out = wp.zeros((3, N), dtype=taylor.f64)
        op(wp.array(a, dtype=taylor.f64), *args, out)
        return out.numpy().copy()

    def hyperviscosity(a):
        x = wp.array(a, dtype=taylor.f64)
        model.hyperviscosity(x, dt)
        return x.numpy()

    LY = []
    for i in range(len(b_I)):
        r = delta + sum(dt * A_I[i, j] * LY[j] for j in range(i))
        Y = applied(st.helmholtz.solve, r, dt * A_I[i, i]) if A_I[i, i] else r
        LY.append(applied(st.linear.apply, Y))
    zero = np.zeros((3, N))
    Jd = hyperviscosity(delta + sum(dt * b * l for b, l in zip(b_I, LY))) - hyperviscosity(zero)  # ∇⁴ of h + hs: affine

    rest = np.stack([zero[0], zero[0], np.full(N, H)])
    adjoint, mu = step_adjoint(model, st), wp.array(unweighted_dss(model, lam), dtype=taylor.f64)
    adjoint.reverse(wp.array(rest, dtype=taylor.f64), mu, 0)
    Jt = mu.numpy()
    left, right = np.sum(Jd * lam), np.sum(w * delta * Jt)
    assert np.abs(Jd - delta).max() > 0.1 * np.abs(delta).max()  # the step acts
    scale = np.sum(np.abs(Jd * lam)) + np.sum(np.abs(w * delta * Jt))
    # round-off: per stage a product's (np terms, the metric, the DSS's ≤ 4 copies) and the
    # ∇⁴'s; the solves' error ≤ κ(A) tol relative (κ a few tens); np.sum's pairwise sum
    count = len(b_I) * (2 * 4 + 8) + np.log2(3 * N)
    assert abs(left - right) <= (count * taylor.EPS + 100 * TOL) * scale, (left, right, abs(left - right) / scale)


def test_an_imex_gradient_replays_its_run():
    """The gradient's forward run is the ``Simulation``'s to the bit (every state held, each step
    taken once in order); from two snapshots or a disk tier the recomputed steps start their CG
    from the stepper's later guesses, so the gradient is the same to the CG's tolerance, not to
    the bit. ``parameters`` refused (L holds g, H)."""
    scene, steps = imex_tc5(), 4
    model, _, x0 = scene_model(scene)
    cost = taylor.misfit(model, x0, np.random.default_rng(13))
    taylor.assert_replays_the_run(scene, steps, cost, tol=TOL)
    with pytest.raises(ValueError, match="parameters must be False with imex"):
        gradient(scene, 1, cost, parameters=True)


def test_an_error_controlled_ark324_run_s_gradient_follows_the_steps_it_took():
    """ark324 under error control (rtol 1e-4, 6 hours from Δt 1800 s) is differentiated along its
    history: the gradient's forward run is the ``Simulation``'s to the bit over Δt that vary
    (measured 7 of 11 steps distinct), and the Taylor remainder falls as ε² (measured 2.0000 ± 1e-3)."""
    over = {"time.control": "error", "time.rtol": 1e-4, "ark324.tol": TOL, "ark324.mean_depth": H}
    scene = load_scene("tc5_mountain", ne=2, np_=4, dt=1800.0, stepper="ark324", overrides=over)
    sim = Simulation(dataclasses.replace(scene, days=0.25), "cpu", progress=False)
    sim.run(None)
    history = tuple(sim.control.history)
    assert len({dt for _, dt, _ in history}) >= 3, history
    model, _, x0 = scene_model(scene)
    g = gradient(scene, len(history), taylor.misfit(model, x0, np.random.default_rng(12)), history=history)
    np.testing.assert_array_equal(g.final, np.stack(sim.fields()))
    taylor.assert_initial_state_taylor(scene, "ark324", len(history), history=history)


def test_a_users_imex_tableau_has_the_built_in_pair_s_gradient():
    """A scene's own IMEX table (``stepper = "tableau"``, the ``ImexRK`` engine) differentiates
    by the same adjoint, from its table: ARS(2,3,2) written as a tableau has ``imex``'s gradient
    to the bit."""
    scene = imex_tc5("imex", "ars232")
    table = {k: v for k, v in IMEX["ars232"].items() if k != "name"}
    options = {"name": "ars232", **table, "tol": TOL, "mean_depth": H}
    written = dataclasses.replace(scene, stepper="tableau", stepper_options=options)
    model, _, x0 = scene_model(scene)
    cost = taylor.misfit(model, x0, np.random.default_rng(1))
    built_in, user = gradient(scene, 3, cost), gradient(written, 3, cost)
    np.testing.assert_array_equal(user.grad, built_in.grad)
    assert user.cost == built_in.cost
