"""Gradients of a run (``swe_sphere.adjoint``): dot-product tests of each adjoint piece, Taylor
tests of the whole n-step gradient, and binomial checkpointing (counts and bits)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
import warp as wp

from swe_sphere.adjoint import HeightMisfit, gradient
from swe_sphere.adjoint.gradient import scene_model, step_adjoint
from swe_sphere.adjoint.revolve import griewank_steps, split, sweep
from swe_sphere.config.scene import load_scene
from swe_sphere.core.backend import Backend
from swe_sphere.core.errors import ArgumentError, BlowUp
from swe_sphere.kernels import tendencies, tendency_adjoint
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.simulation.simulation import Simulation

from helpers import requires_cuda
from taylor import (
    EPS,
    assert_falls_as_eps_squared,
    assert_initial_state_taylor,
    assert_parameter_gradients,
    coefficients,
    continuous,
    divergent_tc5,
    f64,
    misfit,
    planet_constant,
    setup,
    taylor_slopes,
    tc4,
    tc5,
    tensor_tc5,
    topography,
)


def unweighted_dss(model, a):
    out = wp.zeros((3, model.N), dtype=f64)
    for launch in model.topology.dss(wp.array(a, dtype=f64), False, out):
        launch.launch()
    return out.numpy()


def test_tendency_adjoint_is_the_derivative_of_the_per_node_kernel():
    model, _, x0 = setup()
    terms = tuple(t for t in tendencies.TENDENCY_TERMS if t in model.terms)
    args = [
        model.operators.Dinv,
        model.operators.metdet,
        model.operators.fcor,
        model.topo_forcing,
        model.spheremp,  # read by the mass-weighted kernel only
        model.operators.dvv,
        4,
        model.g,
        0.0,  # h0, unread in float64
    ]

    def tendency(x):
        out = wp.zeros((3, model.N), dtype=f64)
        wp.launch(tendencies.tendency(terms), model.N, [wp.array(x, dtype=f64), *args, out, 0])
        return out.numpy()

    rng = np.random.default_rng(1)
    y, dx = rng.standard_normal((2, 3, model.N))
    w = model.grid.spheremp
    xbar, adj, fbar = (
        wp.zeros((3, model.N), dtype=f64),
        wp.zeros((5, model.N), dtype=f64),
        wp.zeros((2, model.N), dtype=f64),
    )
    x, m = wp.array(x0, dtype=f64), model
    point = [
        x,
        m.operators.D,
        m.operators.Dinv,
        m.operators.metdet,
        m.operators.fcor,
        wp.array(w, dtype=f64),
        m.operators.dvv,
        wp.array(y / w, dtype=f64),
        adj,
        xbar,
        fbar,
        0,
    ]
    wp.launch(tendency_adjoint.point(terms, 4), model.N, point)
    wp.launch(
        tendency_adjoint.gather(terms, 4),
        model.N,
        [x, m.operators.D, m.operators.Dinv, m.operators.metdet, m.operators.dvv, m.g, adj, xbar, 0],
    )
    adjoint = np.sum(xbar.numpy() * dx)
    e = 1e-4  # central differences: error e² · (third derivative) ≈ 1e-10 relative here
    fd = np.sum(y * (tendency(x0 + e * dx) - tendency(x0 - e * dx))) / (2 * e)
    assert abs(fd - adjoint) <= 1e-8 * abs(adjoint)
    np.testing.assert_allclose(fbar.numpy(), y[:2], rtol=1e-15)  # the forcing enters the wind rows as is


def test_dss_transpose_is_the_mass_times_the_unweighted_dss():
    # K = R Q W t (weighted DSS): for any t, λ: ⟨K t, λ⟩ = ⟨t, W R Q λ⟩
    model, _, _ = setup()
    rng = np.random.default_rng(2)
    t, lam = rng.standard_normal((2, 3, model.N))
    w = model.grid.spheremp
    left = np.sum(continuous(model, t) * lam)
    right = np.sum(t * w * unweighted_dss(model, lam))
    # each side a sum of 3N products of ≤ 8 roundings each (copies ≤ 4, weight, inverse mass)
    assert abs(left - right) <= 8 * 3 * model.N * EPS * np.sum(np.abs(t * w * unweighted_dss(model, np.abs(lam))))


@pytest.mark.parametrize(
    "kind", ["constant", "tensor", "divergent", "divergent_tensor"], ids=lambda k: k.replace("_", "-")
)
@pytest.mark.parametrize("per_element", [True, False], ids=["element", "node"])
def test_hyperviscosity_step_s_transpose_in_the_mass_form(kind, per_element):
    """H₀ δ = δ − (Δt) B₀ δ: for continuous δ and any λ, ⟨H₀ δ, λ⟩ = Σ spheremp·δ·H₀ᵀ(R Q λ),
    H₀ᵀ the transposed substeps (the constant ∇⁴ its own; the tensor's with its Laplacians'
    metrics swapped; with ν_div ≠ ν the ∇δ term's transpose added, through the pressure
    gradient's and the continuity's), on the CPU's element layout and CUDA's per-node one."""
    scene = {
        "constant": tc5,
        "tensor": tensor_tc5,
        "divergent": divergent_tc5,
        "divergent_tensor": lambda: divergent_tc5(True),
    }[kind]()
    model, stepper, _ = scene_model(scene)
    if not per_element:
        model = ShallowWater.from_scene(scene, model.grid, per_element=False)
    tendency = model.operators.tendency_transpose(model.terms, model.g)
    adjoint = model.hv.transpose(tendency, stepper.dt)  # the model's (``HyperviscosityTranspose``)
    rng = np.random.default_rng(3)
    delta = continuous(model, rng.standard_normal((3, model.N)) * np.array([[10.0], [10.0], [100.0]]))
    lam = rng.standard_normal((3, model.N))
    hd = wp.array(delta, dtype=f64)
    mu = wp.array(unweighted_dss(model, lam), dtype=f64)
    for _ in range(adjoint.substeps):
        adjoint.substep(hd)
        adjoint.substep(mu, transposed=True)
    left = np.sum(hd.numpy() * lam)
    right = np.sum(model.grid.spheremp * delta * mu.numpy())
    assert np.abs(hd.numpy() - delta).max() > 1e-3 * np.abs(delta).max()  # the ∇⁴ acts
    scale = np.sum(np.abs(hd.numpy() * lam)) + np.sum(np.abs(delta * lam))
    # measured 1e-16 relative (ne 2 np 4); the tensor ∇⁴ as its own transpose: 3.4e-5, ν_div ≠ ν's 5.4e-5
    assert abs(left - right) <= 1e-12 * scale


@functools.cache
def other_case(name):
    """TC2 (with a ∇⁴ at the e-folding rule's ν, which its scene leaves out) and Galewsky at ne 2
    np 4, rk4 at Δt 1800 s."""
    over = None
    if name == "tc2_steady":
        terms = [*load_scene(name).terms, "hyperviscosity"]
        over = {"terms": terms, "hyperviscosity.efold_hours": 3.0}
    return load_scene(name, ne=2, np_=4, dt=1800.0, stepper="rk4", overrides=over)


@pytest.mark.parametrize("case", ["tc2_steady", "galewsky"])
def test_taylor_remainders_of_the_initial_state_and_nu_gradients_on_tc2_and_galewsky(case):
    """Issue 66's Taylor tests beyond TC5: the initial state's and ν's remainders fall as ε²."""
    scene = other_case(case)
    assert_initial_state_taylor(scene)
    model, _, x0 = scene_model(scene)
    cost = misfit(model, x0, np.random.default_rng(6))
    g = gradient(scene, 4, cost, parameters=True)
    assert_falls_as_eps_squared(coefficients(scene, ("nu", "nu_div"), g.d_nu, 4, cost))


@pytest.mark.parametrize("stepper", ["rk4", "ssprk3", "kgu35", "dp54", "fbrk32"])
def test_taylor_remainder_of_the_initial_state_gradient_falls_as_eps_squared(stepper):
    slopes, rest, J = taylor_slopes(stepper, 4, [1.0, 1.0, 10.0])
    # measured (rk4, 6 steps): 2.00002, 2.000006, 2.000002, 2.0000006, 2.00000003, … down to 2.0004 at 1e-5
    assert np.all(np.abs(slopes - 2.0) < 0.1), (slopes, rest)
    assert rest[-1] > 1e4 * EPS * J  # the last remainder still above the cost's round-off


def test_taylor_remainder_with_the_hyperviscosity_every_two_steps_falls_as_eps_squared():
    """``[hyperviscosity] every = 2``: the gradient's steps taken again know their phase (the
    step's index), the ∇⁴ over 2Δt after the second and fourth steps alone."""
    scene = dataclasses.replace(tc5(), hypervis_every=2)
    slopes, rest, _ = taylor_slopes("rk4", 4, [1.0, 1.0, 10.0], scene=scene)
    assert np.all(np.abs(slopes - 2.0) < 0.1), (slopes, rest)


@pytest.mark.parametrize("stepper", ["kgu35", "dp54", "fbrk32"])
def test_the_per_node_transposes_give_the_element_kernels_adjoint(stepper):
    # the CPU's element kernel (k̄ read as a combination; dp54's first stages combine it first)
    # against CUDA's per-node point and gather, run here on the CPU: one step's adjoint
    model, stepper_, x0 = setup(stepper)
    scene = tc5(stepper)
    node = ShallowWater.from_scene(scene, model.grid, per_element=False)
    lam = continuous(model, np.random.default_rng(6).standard_normal((3, model.N)))
    out = []
    for m in (model, node):
        adjoint, mu = step_adjoint(m, stepper_), wp.array(lam, dtype=f64)
        adjoint.reverse(wp.array(x0, dtype=f64), mu)
        out.append(mu.numpy())
    assert np.abs(out[0] - lam).max() > 1e-3 * np.abs(lam).max()  # the step acts
    # measured 0.9 and 1.3 eps of the largest entry (kgu35, dp54; TC5 ne 2): sums in another order
    assert np.abs(out[0] - out[1]).max() <= 64 * EPS * np.abs(out[0]).max()


def test_a_reversed_step_is_the_same_bits_on_two_threads():
    # the transposes launch over the forward's element ranges (``LaunchRecorder``), split on two threads
    model, stepper, x0 = setup("kgu35")
    lam = continuous(model, np.random.default_rng(7).standard_normal((3, model.N)))
    out = []
    for threads in (1, 2):
        m = ShallowWater.from_scene(tc5("kgu35"), model.grid, threads=threads)
        adjoint, mu = step_adjoint(m, stepper), wp.array(lam, dtype=f64)
        adjoint.reverse(wp.array(x0, dtype=f64), mu)
        out.append(mu.numpy())
    np.testing.assert_array_equal(out[0], out[1])


@functools.cache
def forward_steps(l: int, c: int) -> int:
    """T(l, c), the fewest forward steps that reverse l steps from a held state with c snapshots
    free, by Griewank & Walther's (2000) recursion: the oracle of ``revolve``'s closed form."""
    if l <= 1:
        return 0
    if c == 0:
        return l * (l - 1) // 2
    return min(m + forward_steps(l - m, c - 1) + forward_steps(m, c) for m in range(1, l))


def test_revolve_counts_are_griewank_and_walthers():
    for l in range(1, 60):
        for c in range(5):
            assert forward_steps(l, c) == griewank_steps(l, c + 1)
    assert griewank_steps(10, 3) == 15 and forward_steps(10, 9) == 9
    for l in range(2, 40):  # the sweep's closed-form split achieves the recursion's minimum
        for c in range(1, 5):
            m = split(l, c)
            assert m + forward_steps(l - m, c - 1) + forward_steps(m, c) == forward_steps(l, c)


@pytest.mark.parametrize(("n", "snapshots"), [(10, 3), (7, 1), (12, 4), (5, 9), (60, 5)])
def test_sweep_reverses_every_step_once_in_order_with_the_predicted_recomputation(n, snapshots):
    held, seen = [], []

    def copy(x):
        held.append(1)
        return list(x)

    def advance(x, k, steps):
        assert steps >= 1 and x[0] == k
        x[0] += steps

    taken = sweep(n, snapshots, [0], advance, lambda x, k: seen.append((k, x[0])), copy)
    assert seen == [(k, k) for k in reversed(range(n))]
    assert taken == forward_steps(n, snapshots - 1)


@pytest.mark.parametrize("snapshots", [3000, 2000])
def test_a_sweep_longer_than_pythons_recursion_limit_reverses_every_step(snapshots):
    """Every state held (``gradient``'s default) splits at each step: 2999 nested splits, which
    a recursive sweep could not take (a 15-day TC5 run at ne8 is 1636 steps)."""
    seen = []

    def advance(x, k, steps):
        x[0] += steps

    taken = sweep(3000, snapshots, [0], advance, lambda x, k: seen.append((k, x[0])), list)
    assert seen == [(k, k) for k in reversed(range(3000))]
    assert taken == griewank_steps(3000, snapshots)  # 2999 with every state, 3998 with 2000


def test_a_checkpointed_gradient_is_the_same_bits_as_one_that_stores_every_state():
    model, _, x0 = setup()
    cost = HeightMisfit(x0[2] + 10.0)
    every = gradient(tc5(), 8, cost)
    few = gradient(tc5(), 8, cost, snapshots=2)
    np.testing.assert_array_equal(every.grad, few.grad)
    assert every.cost == few.cost
    assert (every.forward_steps, few.forward_steps) == (8, 1 + griewank_steps(8, 2))  # 7 + 1, 20 + 1


def test_gradient_refuses_an_implicit_stepper_and_bad_sizes():
    model, _, x0 = setup()
    cost = HeightMisfit(x0[2])
    with pytest.raises(ValueError, match="has no gradient: gradients need an explicit stepper"):
        gradient(tc5("implicit"), 1, cost)
    controlled = load_scene("tc5_mountain", ne=2, stepper="bs32", overrides={"time.control": "error"})
    with pytest.raises(ValueError, match="give history="):  # not silently a fixed-Δt run's gradient
        gradient(controlled, 1, cost)
    with pytest.raises(ValueError, match="history holds 1 steps, fewer than the 2"):
        gradient(controlled, 2, cost, history=[(1800.0, 1800.0, 0.5)])
    with pytest.raises(ValueError, match="history step 1: dt -5.0 s must be > 0"):
        gradient(controlled, 2, cost, history=[(1800.0, 1800.0, 0.5), (1795.0, -5.0, 0.5)])
    with pytest.raises(ArgumentError, match=r"^steps must be an integer >= 1 \(got 0\)$"):
        gradient(tc5(), 0, cost)
    with pytest.raises(ValueError, match=r"x0 has shape \(2, 384\), the grid needs \(3, 384\)"):
        gradient(tc5(), 1, cost, x0=x0[:2])
    with pytest.raises(ValueError, match=r"^x0 holds a NaN or an infinity$"):
        gradient(tc5(), 1, cost, x0=np.where(np.arange(x0.size).reshape(x0.shape) == 7, np.nan, x0))
    with pytest.raises(ValueError, match=r"^hs has shape \(383,\), the grid needs \(1, 384\)$"):
        gradient(tc5(), 1, cost, hs=x0[2, :-1])
    with pytest.raises(ArgumentError, match=r"^x0: its depth h is <= 0 somewhere \(min -5 m\)$"):
        gradient(tc5(), 1, cost, x0=np.where(np.arange(x0.size).reshape(x0.shape) == 2 * x0.shape[1] + 5, -5.0, x0))


@pytest.mark.parametrize("snapshots", [None, 2])
def test_a_run_that_blows_up_stops_the_gradient_at_its_step_as_a_run_does(snapshots):
    """Δt = 12 h is far past RK4's limit on TC5 ne2: the depth goes negative in the first step.
    The gradient stops there with a run's blow-up line, whatever the checkpointing, instead of a
    derivative of a dry state (or the cost's non-finite J steps later)."""
    scene = load_scene("tc5_mountain", ne=2, np_=4, dt=43200.0, stepper="rk4")
    cost = HeightMisfit(0.0)
    lines = []
    for steps in (1, 3):
        with pytest.raises(BlowUp) as err:
            gradient(scene, steps, cost, snapshots=snapshots)
        lines.append(str(err.value))
    with pytest.raises(BlowUp) as run:  # the run's own guard, at that step
        Simulation(scene, "cpu", progress=False).run(None, until_step=1)
    where = str(run.value).removeprefix("blow-up at step 1 (model time 0.5000 days): ")
    assert where.startswith("depth h = -") and " m <= 0 at lat " in where, str(run.value)
    assert lines == [f"blow-up at step 1 (model time 0.5000 days) of the gradient's run: {where}"] * 2


@pytest.mark.parametrize("rows", ["nu", "nu_s"])
def test_taylor_remainder_of_the_hyperviscosity_gradient_falls_as_eps_squared(rows):
    scene, steps = tc5(), 4
    model, _, x0 = setup()
    cost = misfit(model, x0, np.random.default_rng(4))
    g = gradient(scene, steps, cost, parameters=True)
    names, d = (("nu", "nu_div"), g.d_nu) if rows == "nu" else (("nu_s",), g.d_nu_s)
    # measured (ν, TC5): the last remainder 7.9e5 against the bound's 1.35e5
    assert_falls_as_eps_squared(coefficients(scene, names, d, steps, cost), rows)


def test_with_nu_div_apart_from_nu_the_gradients_fall_as_eps_squared():
    """ν_div = 2.5 ν (the ∇δ term's transpose in the reverse sweep): the Taylor remainders of
    x(0), of ν (ν and ν_div moved together, ``Gradient.d_nu``: summed substep by substep) and of
    ν_s fall as ε²."""
    scene = divergent_tc5()
    assert_initial_state_taylor(scene)
    model, _, x0 = scene_model(scene)
    cost = misfit(model, x0, np.random.default_rng(11))
    g = gradient(scene, 4, cost, parameters=True)
    for names, d in ((("nu", "nu_div"), g.d_nu), (("nu_s",), g.d_nu_s)):
        assert_falls_as_eps_squared(coefficients(scene, names, d, 4, cost), names)


def test_the_tensor_hyperviscosity_s_gradients_fall_as_eps_squared():
    """The tensor ∇⁴ (its transpose the Laplacians swapped): the initial state's, ν's and hs's
    Taylor remainders fall as ε²."""
    scene, steps = tensor_tc5(), 4
    assert_initial_state_taylor(scene)
    model, _, x0 = scene_model(scene)
    rng = np.random.default_rng(7)
    cost = misfit(model, x0, rng)
    g = gradient(scene, steps, cost, parameters=True)
    dhs = 100.0 * continuous(model, rng.standard_normal((3, model.N)))[2]
    assert_falls_as_eps_squared(coefficients(scene, ("nu", "nu_div"), g.d_nu, steps, cost), "nu")
    assert_falls_as_eps_squared(topography(scene, model, g.d_hs, dhs, steps, cost, x0), "hs")


@pytest.mark.parametrize("constant", ["gravity", "omega"])
def test_taylor_remainders_of_the_planet_s_gravity_and_rotation_fall_as_eps_squared(constant):
    """∂J/∂g and ∂J/∂Ω with x(0) and hs held fixed (TC5: its mountain does not depend on them):
    the remainder of J(p + εδp) − J(p) − εδp ∂J/∂p falls as ε², kgu35 (a table whose k̄ reads Ȳ)."""
    scene, steps = tc5("kgu35"), 4
    model, _, x0 = setup("kgu35")
    cost = misfit(model, x0, np.random.default_rng(8))
    g = gradient(scene, steps, cost, parameters=True)
    d = g.d_g if constant == "gravity" else g.d_omega
    assert_falls_as_eps_squared(planet_constant(scene, constant, d, steps, cost, x0), constant)


def test_fbrk32_s_parameter_gradients_fall_as_eps_squared():
    """FB-RK(3,2) (its own step on the tape, ``adjoint.tape``): ∂J/∂ν, ∂J/∂hs, ∂J/∂g and ∂J/∂Ω, each Taylor
    remainder falling as ε², x(0) held."""
    scene, steps = tc5("fbrk32"), 4
    model, _, x0 = setup("fbrk32")
    rng = np.random.default_rng(9)
    cost = misfit(model, x0, rng)
    g = gradient(scene, steps, cost, parameters=True)
    assert_parameter_gradients(scene, model, g, steps, cost, x0, rng, ("nu", "hs", "gravity", "omega"))


def test_taylor_remainder_of_the_topography_gradient_falls_as_eps_squared():
    scene, steps = tc5(), 4
    model, _, x0 = setup()
    rng = np.random.default_rng(5)
    cost = misfit(model, x0, rng)
    g = gradient(scene, steps, cost, parameters=True)
    dhs = 100.0 * continuous(model, rng.standard_normal((3, model.N)))[2]
    assert_falls_as_eps_squared(topography(scene, model, g.d_hs, dhs, steps, cost, x0), "hs")


def test_a_forced_run_s_gradient_steps_at_the_run_s_times():
    """A time-dependent forcing (TC4's) moves the stages, not the transposes: the gradient's
    forward run is the ``Simulation``'s to the bit, recomputed from two snapshots too (each
    step at its own time), and the initial state's Taylor remainder falls as ε²."""
    scene = tc4()
    model, _, x0 = scene_model(scene)
    cost = HeightMisfit(x0[2] + 50 * continuous(model, np.random.default_rng(8).standard_normal((3, model.N)))[2])
    every, few = gradient(scene, 6, cost), gradient(scene, 6, cost, snapshots=2)
    sim = Simulation(dataclasses.replace(scene, days=6 * 1800.0 / 86400.0), "cpu", progress=False)
    sim.run(None)
    np.testing.assert_array_equal(every.final, np.stack(sim.fields()))
    np.testing.assert_array_equal(few.grad, every.grad)
    slopes, rest, J = taylor_slopes("rk4", 6, [1.0, 1.0, 10.0], scene)
    assert np.all(np.abs(slopes - 2.0) < 0.1), (slopes, rest)
    assert rest[-1] > 1e4 * EPS * J


def test_a_run_on_a_mesh_file_has_a_gradient_whose_taylor_remainder_falls_as_eps_squared():
    """A scene on an Exodus mesh (``grid.mesh_file``: TempestRemap's ne2 cube) is differentiated on
    that mesh's grid, as its run steps it."""
    from meshes import TEMPEST_NE2

    scene = load_scene("tc5_mountain", dt=1800.0, stepper="rk4", overrides={"grid.mesh_file": str(TEMPEST_NE2)})
    assert scene.ne == 0 and scene_model(scene)[0].grid.mesh is not None
    slopes, rest, J = taylor_slopes("rk4", 4, [1.0, 1.0, 10.0], scene)
    assert np.all(np.abs(slopes - 2.0) < 0.1), (slopes, rest)
    assert rest[-1] > 1e4 * EPS * J


@functools.cache
def controlled_run(case, stepper, mode):
    """``case`` at ne 2 np 4 under ``mode`` control (rtol 1e-4 under error) for 3 hours from a
    first Δt of 1800 s, run as a ``Simulation``: (its scene, its steps' history, its final state).
    3 hours, not 6: 15, 6 and 14 steps (bs32, fbrk32, TC4's rk43) instead of 37, 9 and 28, each
    Δt still its own but TC4's four; a gradient's cost is its steps'."""
    over = {"time.control": mode} | ({"time.rtol": 1e-4} if mode == "error" else {})
    scene = load_scene(case, ne=2, np_=4, dt=1800.0, stepper=stepper, overrides=over)
    sim = Simulation(dataclasses.replace(scene, days=0.125), "cpu", progress=False)
    sim.run(None)
    return scene, tuple(sim.control.history), np.stack(sim.fields())


@pytest.mark.parametrize(
    ("case", "stepper", "mode"),
    [("tc5_mountain", "bs32", "error"), ("tc5_mountain", "fbrk32", "cfl"), ("tc4_forced_low", "rk43", "error")],
)
def test_a_controlled_run_s_gradient_follows_the_steps_it_took(case, stepper, mode):
    """A run whose steps its controller chose (an error-controlled pair; fbrk32 under a CFL
    target; TC4's forcing at the steps' times) is differentiated along its history: the
    gradient's forward run is the ``Simulation``'s to the bit, from every state, from three
    snapshots and from a disk tier alike, over Δt that vary, and with the steps held the Taylor
    remainders of x(0) and ν fall as ε²."""
    scene, history, final = controlled_run(case, stepper, mode)
    steps = len(history)
    assert len({dt for _, dt, _ in history}) >= 3, history  # measured: 15 (bs32), 6 (fbrk32), 4 (TC4 rk43)
    model, _, x0 = scene_model(scene)
    cost = misfit(model, x0, np.random.default_rng(12))
    every = gradient(scene, steps, cost, history=history, parameters=True)
    few = gradient(scene, steps, cost, history=history, parameters=True, snapshots=3)
    disk = gradient(scene, steps, cost, history=history, parameters=True, snapshots=3, disk=True, disk_interval=4)
    np.testing.assert_array_equal(every.final, final)
    np.testing.assert_array_equal(few.grad, every.grad)
    np.testing.assert_array_equal(disk.grad, every.grad)  # a disk tier's states carry their step index too
    assert_initial_state_taylor(scene, stepper, steps, history=history)
    if "hyperviscosity" in scene.terms:
        nu = coefficients(scene, ("nu", "nu_div"), every.d_nu, steps, cost, history=history)
        assert_falls_as_eps_squared(nu, "nu")


def test_the_gradients_model_is_built_on_the_device_it_launches_on(monkeypatch):
    """``scene_model`` builds its model on its topology's device: the model's arrays had been
    the constructor's default CPU ones while the topology recorded its launches on CUDA, an
    illegal memory access in every CUDA gradient (issue 83; ``parallel.record`` now refuses
    a launch of arrays on another device)."""
    options = {}
    from_scene = ShallowWater.from_scene.__func__

    def spy(cls, scene, grid, case=None, **kw):
        options.update(kw)
        return from_scene(cls, scene, grid, case, **kw)

    monkeypatch.setattr(ShallowWater, "from_scene", classmethod(spy))
    model, _, _ = scene_model(tc5("kgu35"), "cpu")
    assert options.get("device") == model.topology.backend.device == model.device == "cpu"


ON_CUDA = ["kgu35", "fbrk32", "leapfrog_trapezoidal", "split_explicit", "mri"]


def assert_gradients_agree(stepper, device, monkeypatch=None):
    """The gradient of TC5 ne2 on ``device`` equals the CPU's per-element one to round-off (sums in
    another order): cost, ∂J/∂x(0) and the parameters'. With ``monkeypatch``, ``device`` "cpu" with
    CUDA's per-node layout (its transposes, DSS and ∇⁴ kernels)."""
    scene = tc5(stepper)
    model, _, x0 = setup(stepper)
    cost = HeightMisfit(x0[2] + 50 * continuous(model, np.random.default_rng(10).standard_normal((3, model.N)))[2])
    cpu = gradient(scene, 4, cost, snapshots=2, parameters=True, device="cpu")
    if monkeypatch is not None:
        monkeypatch.setattr(Backend, "per_element", property(lambda self: False))
        monkeypatch.setattr(Backend, "nodes_per_thread", lambda self, np_: 1)
    other = gradient(scene, 4, cost, snapshots=2, parameters=True, device=device)
    assert other.cost == pytest.approx(cpu.cost, rel=1e-12)
    assert np.abs(other.grad - cpu.grad).max() <= 1e-10 * np.abs(cpu.grad).max()
    assert np.abs(other.d_hs - cpu.d_hs).max() <= 1e-10 * np.abs(cpu.d_hs).max()
    for name in ("d_nu", "d_nu_s", "d_g", "d_omega"):
        assert getattr(other, name) == pytest.approx(getattr(cpu, name), rel=1e-10), name


@pytest.mark.parametrize("stepper", ON_CUDA)
def test_a_gradient_in_the_cuda_layout_is_the_cpu_s(monkeypatch, stepper):
    """The CUDA test's gradients with CUDA's per-node kernels run on the CPU: the per-node
    transposes checked without a card (issue 83)."""
    assert_gradients_agree(stepper, "cpu", monkeypatch)


@requires_cuda
@pytest.mark.parametrize("stepper", ON_CUDA)
def test_a_gradient_on_cuda_is_the_cpu_s(stepper):
    """On CUDA (the per-node transposes; their element twins checked on the CPU above) the cost,
    ∂J/∂x(0) and the parameters' gradients are the CPU's to round-off: sums in another order."""
    assert_gradients_agree(stepper, "cuda")


def tableau_tc5(options):
    """TC5 ne 2 (``tc5``) with ``stepper = "tableau"`` and the table ``options``."""
    scene = load_scene("testcases/tc5_mountain.toml", ne=2, np_=4, dt=1800.0, stepper="tableau")
    return dataclasses.replace(scene, stepper_options=options)


# Heun's third-order method (Heun 1900): an explicit table no stepper is registered for
HEUN3 = dict(A=[[0, 0, 0], ["1/3", 0, 0], [0, "2/3", 0]], b=["1/4", 0, "3/4"], c=[0, "1/3", "2/3"], order=3)
RK4 = dict(
    A=[[0, 0, 0, 0], ["1/2", 0, 0, 0], [0, "1/2", 0, 0], [0, 0, 1, 0]],
    b=["1/6", "1/3", "1/3", "1/6"],
    c=[0, "1/2", "1/2", 1],
)


def test_a_users_explicit_butcher_table_has_its_gradient_with_no_adjoint_code():
    """Issue 82: a scene's own explicit table (``stepper = "tableau"``) differentiates as the
    registry's tables do, from its own step with no adjoint code (``adjoint.gradient``'s default
    for an explicit stepper: ``reverse.TapeAdjoint``): Heun's third-order method's initial-state Taylor remainder falls as ε²; RK4
    written as a tableau has the built-in ``rk4``'s gradient to the bit. A stepper without an
    adjoint is refused naming those that have one."""
    heun = tableau_tc5({"name": "heun3", **HEUN3})
    assert_initial_state_taylor(heun)
    model, _, x0 = setup()
    cost = HeightMisfit(x0[2] + 10.0)
    built_in = gradient(tc5(), 3, cost)
    written = gradient(tableau_tc5({"name": "rk4", "order": 4, **RK4}), 3, cost)
    np.testing.assert_array_equal(written.grad, built_in.grad)
    assert written.cost == built_in.cost
    with pytest.raises(
        ValueError,
        match=r"'epi2' has no gradient: gradients need an explicit stepper, .*semi_implicit, an IMEX table.*split_explicit, mri or lts",
    ):
        gradient(tc5("epi2"), 1, cost)
