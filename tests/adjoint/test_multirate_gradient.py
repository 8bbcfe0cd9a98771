"""Gradients of multirate runs (``adjoint.tape``, their own steps on a tape; MRAB3 ``adjoint.multirate_ab``): split_explicit (the slow tendency held
over the gravity waves' forward–backward substeps, each substep reversed), mri (the inner
solves of the linear gravity-wave system reversed through their tables) and lts (the same
engine on element levels, its fast part nonlinear)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import warp as wp

from swe_sphere.adjoint import HeightMisfit, gradient
from swe_sphere.adjoint.gradient import scene_model, step_adjoint
from swe_sphere.adjoint.tape import Smooth
from swe_sphere.config.scene import load_scene
from swe_sphere.mesh.mesh import write_exodus
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.steppers import make_stepper

import taylor
from meshes import refined_ne4


@pytest.mark.parametrize("damping", [0.1, 0.0])
def test_a_split_explicit_run_s_gradient_falls_as_eps_squared(damping):
    """TC5, 4 steps of 2, 2 and 4 substeps a stage (``substeps = 4``): the gradient's
    forward run is the ``Simulation``'s to the bit, from two snapshots alike, and the Taylor
    remainder of x(0) falls as ε², with the divergence damping β and without."""
    scene = dataclasses.replace(
        taylor.tc5("split_explicit"), stepper_options={"substeps": 4, "divergence_damping": damping}
    )
    model, stepper, x0 = scene_model(scene)
    taylor.assert_replays_the_run(scene, 4, taylor.misfit(model, x0, np.random.default_rng(17)))
    assert stepper.substeps() == 4  # 2, 2 and 4 a stage
    taylor.assert_initial_state_taylor(scene, "split_explicit")


@pytest.fixture(scope="module")
def refined_mesh(tmp_path_factory):
    """The ne4 cube refined 2× about TC5's mountain (124 elements), as a .g file."""
    return write_exodus(tmp_path_factory.mktemp("mesh") / "r4.g", refined_ne4())


@pytest.fixture(scope="module")
def refined(refined_mesh):
    """TC5 by lts (MIS4a, rk4 inside) at 600 s on ``refined_mesh``: two levels, 66 and 58 elements."""
    return load_scene("tc5_mountain", mesh=refined_mesh, dt=600.0, stepper="lts")


@pytest.mark.parametrize("options", [{}, {"method": "mis2", "inner": "ssprk3"}], ids=["mis4a-rk4", "mis2-ssprk3"])
def test_an_lts_run_on_two_levels_has_a_gradient_whose_remainder_falls_as_eps_squared(refined, options):
    """Two element levels: the coarse level's tendency the slow part, the fine levels' the fast
    (nonlinear: the inner stages' states held), each part's transpose over its own elements:
    the forward the ``Simulation``'s to the bit, and x(0)'s Taylor remainder falls as ε²."""
    scene = dataclasses.replace(refined, stepper_options=options)
    model, stepper, x0 = scene_model(scene)
    stepper.prepare(wp.array(x0, dtype=taylor.f64))
    assert stepper.levels.elements_per_level() == [66, 58]
    taylor.assert_replays_the_run(scene, 3, taylor.misfit(model, x0, np.random.default_rng(21)))
    taylor.assert_initial_state_taylor(scene, "lts", 3)


def test_an_lts_run_on_one_level_is_its_inner_table_s_gradient():
    """On the uniform cube lts has one level, the inner table's global step: its gradient is
    that table's, the same bits as rk4's."""
    scene = taylor.tc5("lts")
    model, _, x0 = scene_model(scene)
    cost = taylor.misfit(model, x0, np.random.default_rng(22))
    one = gradient(scene, 4, cost, parameters=True)
    rk4 = gradient(taylor.tc5("rk4"), 4, cost, parameters=True)
    np.testing.assert_array_equal(one.grad, rk4.grad)
    assert (one.d_nu, one.d_g) == (rk4.d_nu, rk4.d_g)


@pytest.mark.parametrize("stepper", ["split_explicit", "mri", "lts"])
def test_a_multirate_step_s_per_node_transposes_give_the_element_kernels_adjoint(stepper, refined):
    # one step reversed on the CPU's element kernels and on CUDA's per-node point and gather, here on the CPU
    scene = refined if stepper == "lts" else taylor.tc5(stepper)
    model, _, x0 = scene_model(scene)
    node = ShallowWater.from_scene(scene, model.grid, per_element=False)
    lam = taylor.continuous(model, np.random.default_rng(18).standard_normal((3, model.N)))
    out = []
    for m in (model, node):
        st = make_stepper(scene.stepper, m, scene.dt, **scene.stepper_options)
        first = wp.array(x0, dtype=taylor.f64)
        st.prepare(first)
        st.step(first)  # its first step fixes H and the substeps
        adjoint, mu = step_adjoint(m, st), wp.array(lam, dtype=taylor.f64)
        adjoint.reverse(wp.array(x0, dtype=taylor.f64), mu)
        out.append(mu.numpy())
    assert np.abs(out[0] - lam).max() > 1e-3 * np.abs(lam).max()  # the step acts
    assert np.abs(out[0] - out[1]).max() <= 64 * taylor.EPS * np.abs(out[0]).max()


@pytest.mark.parametrize(
    "options",
    [{}, {"method": "mri_gark_erk33a"}, {"method": "mis2", "inner": "rk4", "substeps": 5}],
    ids=["mis4a-ssprk3", "mri-gark-erk33a", "mis2-rk4"],
)
def test_an_mri_run_s_gradient_falls_as_eps_squared(options):
    """TC5, 4 steps: MIS4a (α and γ couple the solves) with its default inner ssprk3,
    MRI-GARK-ERK33a (solves that restart, a forcing linear in the solve's time, β¹) and MIS2
    with rk4 inside: the gradient's forward run is the ``Simulation``'s to the bit, from two
    snapshots alike, and the Taylor remainder of x(0) falls as ε²."""
    scene = dataclasses.replace(taylor.tc5("mri"), stepper_options=options)
    model, _, x0 = scene_model(scene)
    taylor.assert_replays_the_run(scene, 4, taylor.misfit(model, x0, np.random.default_rng(19)))
    taylor.assert_initial_state_taylor(scene, "mri")


@pytest.mark.parametrize("stepper", ["split_explicit", "mri"])
def test_a_multirate_run_s_parameter_gradients_fall_as_eps_squared(stepper):
    """∂J/∂ν, ∂J/∂ν_s, ∂J/∂hs, ∂J/∂g (split_explicit: the slow topography and the substeps'
    −gτ G h̃; mri: the topography and L's −g G h′ at every inner stage) and ∂J/∂Ω (the slow
    Coriolis term): each Taylor remainder falls as ε², x(0) held."""
    scene = taylor.tc5(stepper)
    if stepper == "split_explicit":
        scene = dataclasses.replace(scene, stepper_options={"substeps": 4})
    model, _, x0 = scene_model(scene)
    rng = np.random.default_rng(20)
    cost = taylor.misfit(model, x0, rng)
    g = gradient(scene, 4, cost, parameters=True)
    taylor.assert_parameter_gradients(scene, model, g, 4, cost, x0, rng)


@pytest.mark.parametrize("method", ["mis4a", "mrab3"])
def test_an_lts_run_s_parameter_gradients_fall_as_eps_squared(method, refined):
    """On two levels, ∂J/∂ν, ∂J/∂ν_s, ∂J/∂hs (each part's topography), ∂J/∂g and ∂J/∂Ω (each
    part's f_P of those terms at its own states; MRAB3's at each level's evaluations and its
    start's stages): each Taylor remainder falls as ε², x(0) held. The cost is a misfit to 1 cm
    of the run's own final height (ν moves J by a fraction of the round-off of a misfit of
    metres over a few steps)."""
    scene, steps = refined, 3
    if method == "mrab3":  # its start's two steps and three of AB3
        scene, steps = dataclasses.replace(refined, stepper_options={"method": "mrab3"}, dt=300.0), 5
    model, _, x0 = scene_model(scene)
    rng = np.random.default_rng(24)
    final = gradient(scene, steps, HeightMisfit(x0[2])).final[2]
    cost = HeightMisfit(final + 0.01 * taylor.continuous(model, rng.standard_normal((3, model.N)))[2])
    g = gradient(scene, steps, cost, parameters=True)
    taylor.assert_parameter_gradients(scene, model, g, steps, cost, x0, rng)


def test_an_mri_run_with_fbrk32_inner_solves_has_its_gradients():
    """Issue 82: what mri's own adjoint refused, the tape reverses: fbrk32 inner solves (the depth
    first, the wind with h̃, by the operators' gradient and divergence updates, each the other's
    transpose in the mass form). x(0)'s and g's Taylor remainders fall as ε² (g's through the
    substeps' −gτ G and L's −g G terms)."""
    scene = dataclasses.replace(taylor.tc5("mri"), stepper_options={"inner": "fbrk32"})
    taylor.assert_initial_state_taylor(scene, "mri", 4)
    model, _, x0 = scene_model(scene)
    rng = np.random.default_rng(29)
    cost = taylor.misfit(model, x0, rng)
    g = gradient(scene, 4, cost, parameters=True)
    taylor.assert_parameter_gradients(scene, model, g, 4, cost, x0, rng, ("gravity",))


@pytest.mark.parametrize("stepper", ["fbrk32", "split_explicit", "mri", "lts"])
def test_a_forced_run_s_gradient_takes_each_stage_at_its_time(stepper, refined_mesh):
    """TC4's forcing (a term of x and t that adds to F, not to its Jacobian) at the stepper's
    own stage times (the slow stages', and lts's fine part at its inner stages'): the forward
    the ``Simulation``'s to the bit, and x(0)'s Taylor remainder falls as ε² (lts on the
    refined cube, two levels)."""
    scene = dataclasses.replace(taylor.tc4(), stepper=stepper)
    if stepper == "lts":
        scene = load_scene("tc4_forced_low", mesh=refined_mesh, dt=600.0, stepper="lts")
    model, st, x0 = scene_model(scene)
    st.prepare(wp.array(x0, dtype=taylor.f64))
    assert stepper != "lts" or st.levels.count == 2
    taylor.assert_replays_the_run(scene, 4, taylor.misfit(model, x0, np.random.default_rng(23)))
    taylor.assert_initial_state_taylor(scene, stepper, 4)


@pytest.mark.parametrize("stepper", ["fbrk32", "split_explicit", "mri", "lts"])
def test_a_reversed_step_recomputes_the_forced_step_it_reverses(stepper, refined_mesh):
    """The stages a reversed step takes again (its linearisation point) end where the forward
    step did: step 1 of TC4 (a forcing at each stage's time) recomputed by the adjoint, its
    ∇⁴ applied, is the stepper's x(2) to round-off (measured: 0, 0, 1.7e-16 and 8.5e-16 of its
    largest entry); with the stages all at the step's start time, 5e-5, 3e-5 and 7e-6."""
    if stepper == "lts":
        scene = load_scene("tc4_forced_low", mesh=refined_mesh, dt=600.0, stepper="lts")
    else:
        scene = dataclasses.replace(taylor.tc4(), stepper=stepper)
    model, st, x0 = scene_model(scene)
    x = wp.array(x0, dtype=taylor.f64)
    st.prepare(x)
    st.step(x)
    x1 = wp.clone(x)
    st.step(x)
    adjoint = step_adjoint(model, st, parameters=stepper != "lts")
    adjoint.t0 = st.t0
    adjoint.reverse(x1, wp.zeros_like(x1), 1)
    ahead = wp.zeros_like(x1)
    before_hyperviscosity(adjoint, ahead)
    model.hyperviscosity(ahead, scene.dt)
    x2 = x.numpy()
    assert np.abs(ahead.numpy() - x2).max() <= 1e3 * taylor.EPS * np.abs(x2).max()


def before_hyperviscosity(adjoint, out) -> None:
    """out = the state the last reversed step's ∇⁴ started from (the tape's ``Smooth`` keeps it
    with ``parameters``; without the ∇⁴ the step's end, the twin's work array)."""
    smooth = [op.state for op in adjoint.tape.ops if isinstance(op, Smooth)]
    wp.copy(out, smooth[-1] if smooth else adjoint.work)


def test_an_mrab3_reversed_step_recomputes_the_step_it_reverses(refined_mesh):
    """An AB3 step (k = 2, after the start) taken again on the tape from (x, the histories) ends
    where the stepper's did: its state before the ∇⁴, the ∇⁴ applied, is x(3) to round-off (the
    histories handed to the twin in the order the state holds them, newest first)."""
    scene = load_scene("tc5_mountain", mesh=refined_mesh, dt=300.0, stepper="lts", overrides={"lts.method": "mrab3"})
    model, stepper, x0 = scene_model(scene)
    x = wp.array(x0, dtype=taylor.f64)
    stepper.prepare(x)
    for _ in range(2):
        stepper.step(x)
    adjoint = step_adjoint(model, stepper, parameters=True)
    state = np.concatenate([x.numpy(), *(a.numpy() for a in stepper.carried_arrays())])
    stepper.step(x)
    adjoint.reverse(wp.array(state, dtype=taylor.f64), wp.zeros(state.shape, dtype=taylor.f64), 2)
    ahead = wp.zeros_like(x)
    before_hyperviscosity(adjoint, ahead)
    model.hyperviscosity(ahead, scene.dt)
    x3 = x.numpy()
    assert np.abs(ahead.numpy() - x3).max() <= 1e3 * taylor.EPS * np.abs(x3).max()


@pytest.mark.parametrize("method", ["mis4a", "mrab3"])
def test_a_run_whose_hyperviscosity_takes_the_rkl1_super_step_has_its_gradients(method, refined_mesh):
    """At 1800 s on the refined cube the finest elements' ∇⁴ takes the RKL1 super-step (4
    stages, ``Hyperviscosity.plan``): its stages reversed with Eᵀ, the forward the
    ``Simulation``'s to the bit, x(0)'s Taylor remainder falling as ε², and (MIS4a) ν's, ν_s's
    and hs's (summed stage by stage) with g's too, and ν's and ν_s's with ν_div = 2.5 ν."""
    scene = load_scene("tc5_mountain", mesh=refined_mesh, dt=1800.0, stepper="lts", overrides={"lts.method": method})
    model, _, x0 = scene_model(scene)
    assert model.hv.plan(1800.0) == (4, True)
    rng = np.random.default_rng(26)
    final = taylor.assert_replays_the_run(scene, 4, taylor.misfit(model, x0, rng)).final[2]
    taylor.assert_initial_state_taylor(scene, "lts", 4)
    if method == "mrab3":  # its stages' sums are those of the MIS one's ∇⁴ below, checked there
        return
    cost = HeightMisfit(final + 0.01 * taylor.continuous(model, rng.standard_normal((3, model.N)))[2])
    g = gradient(scene, 4, cost, parameters=True)
    taylor.assert_parameter_gradients(scene, model, g, 4, cost, x0, rng, ("nu", "nu_s", "hs", "gravity"))
    divergent = dataclasses.replace(scene, nu_div=2.5 * scene.nu)  # ∂B/∂ν no longer B/ν: B₁ at unit coefficients
    g = gradient(divergent, 4, cost, parameters=True)
    taylor.assert_parameter_gradients(divergent, model, g, 4, cost, x0, rng, ("nu", "nu_s"))


def test_the_rkl1_super_step_s_hs_and_nu_adjoints_are_its_derivatives(refined_mesh):
    """One RKL1 ∇⁴ step H(Φ; hs, ν) alone (the refined cube at 1800 s, 4 stages): with μ given,
    the model's transpose (``HyperviscosityTranspose.transpose``) sums an hs adjoint that is ∂⟨μ, H⟩/∂hs (H is affine in hs: the difference
    of two steps; measured 3.2e-12 relative) and its ∂J/∂ν is the derivative along ν (central
    differences, measured 1.3e-9 relative); μ_j's weight left out of either fails."""
    scene = load_scene("tc5_mountain", mesh=refined_mesh, dt=1800.0, stepper="rk4")
    model, _, x0 = scene_model(scene)
    assert model.hv.plan(1800.0) == (4, True)
    rng = np.random.default_rng(27)
    phi = x0 + taylor.continuous(model, rng.standard_normal((3, model.N)))
    lam = taylor.continuous(model, rng.standard_normal((3, model.N)))
    tendency = model.operators.tendency_transpose(model.terms, model.g)
    d_nu, d_hs = np.zeros(2), wp.zeros((1, model.N), dtype=taylor.f64)
    mu = wp.array(lam, dtype=taylor.f64)
    model.hv.transpose(tendency, scene.dt).transpose(mu, lambda out: out.assign(phi), d_nu, d_hs)
    w = model.grid.spheremp

    def step(hs, scale=1.0):  # ⟨λ, H(Φ)⟩ in the mass form at hs and ν, ν_div scaled by ``scale``
        nus = {key: getattr(scene, key) * scale for key in ("nu", "nu_div")}
        fresh = ShallowWater.from_scene(dataclasses.replace(scene, **nus), model.grid)
        fresh.operators.hs.assign(hs)
        y = wp.array(phi, dtype=taylor.f64)
        fresh.hyperviscosity(y, scene.dt)
        return float(np.sum(w * lam * y.numpy()))

    hs = model.operators.hs.numpy()
    dhs = 10.0 * taylor.continuous(model, rng.standard_normal((3, model.N)))[2]
    change = step(hs + dhs) - step(hs)
    assert change == pytest.approx(float(np.sum(w * d_hs.numpy()[0] * dhs)), rel=1e-9)
    e = 1e-4
    along = (step(hs, 1 + e) - step(hs, 1 - e)) / (2 * e * scene.nu)
    assert along == pytest.approx(d_nu[0], rel=1e-6)


@pytest.mark.parametrize("stepper", ["split_explicit", "mri"])
def test_a_multirate_run_with_nu_div_apart_from_nu_has_its_gradients(stepper):
    """ν_div = 2.5 ν (the ∇δ term's transpose apart, the parameters summed substep by substep):
    x(0)'s and ν's Taylor remainders fall as ε² for the multirate steppers too (their ∇⁴ is
    the same split step as the tables')."""
    scene = dataclasses.replace(taylor.divergent_tc5(), stepper=stepper)
    taylor.assert_initial_state_taylor(scene, stepper, 4)
    model, _, x0 = scene_model(scene)
    rng = np.random.default_rng(28)
    cost = taylor.misfit(model, x0, rng)
    g = gradient(scene, 4, cost, parameters=True)
    taylor.assert_parameter_gradients(scene, model, g, 4, cost, x0, rng, ("nu",))
