"""The adjoint tests' shared pieces: small scenes (TC5, TC4 at ne 2 np 4), continuous fields,
and Taylor tests (the remainder of J(p + εδp) − J(p) − ε⟨∇J, δp⟩ falling as ε²)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import warp as wp

from swe_sphere.adjoint import HeightMisfit, gradient
from swe_sphere.adjoint.costs import checked, run_cost
from swe_sphere.adjoint.gradient import scene_model
from swe_sphere.config.scene import load_scene
from swe_sphere.core.clock import StepTimes
from swe_sphere.core.constants import DAY
from swe_sphere.simulation.simulation import Simulation

EPS = float(np.finfo(np.float64).eps)
f64 = wp.float64


@functools.cache
def tc5(stepper="rk4"):
    """TC5 at ne 2 np 4, Δt 1800 s (its terms all, the ∇⁴ at the e-folding rule's ν)."""
    return load_scene("testcases/tc5_mountain.toml", ne=2, np_=4, dt=1800.0, stepper=stepper)


@functools.cache
def setup(stepper="rk4"):
    return scene_model(tc5(stepper))


def continuous(model, a):
    """The weighted DSS of a (3, N): a continuous state."""
    out = wp.zeros((3, model.N), dtype=f64)
    for launch in model.topology.dss(wp.array(a, dtype=f64), True, out):
        launch.launch()
    return out.numpy()


@functools.cache
def tensor_tc5():
    """TC5 at ne 2 np 4 with HOMME's tensor ∇⁴ (hypervis_scaling 3.2, Guba et al. 2014)."""
    return load_scene(
        "testcases/tc5_mountain.toml",
        ne=2,
        np_=4,
        dt=1800.0,
        stepper="rk4",
        overrides={"hyperviscosity.scaling": 3.2},
    )


def divergent_tc5(tensor=False):
    """TC5 at ne 2 np 4 with ν_div = 2.5 ν (HOMME's nu_div: the ∇δ term), constant or tensor ∇⁴."""
    scene = tensor_tc5() if tensor else tc5()
    return dataclasses.replace(scene, nu_div=2.5 * scene.nu)


def run_J(scene, steps, cost, x0=None, hs=None, history=None):
    """J of ``gradient(scene, steps, cost, x0=x0, hs=hs, history=history)`` from its run alone: the
    steps ``gradient`` takes forward (each at ``StepTimes``' Δt and clock, its phase set), the cost
    at the steps it observes summed in increasing k, without the reverse sweep (of a 4-step
    gradient on TC5's refined cube, the sweep was four fifths of its time: 2026-11-27). A Taylor
    remainder's J at the moved points and at the point itself come from here alike, the gradient
    giving ⟨∇J, δp⟩ alone: a J that were not the gradient's would not fall as ε²."""
    model, stepper, initial = scene_model(scene, hs=hs)
    x = wp.array(initial if x0 is None else x0, dtype=f64)
    stepper.prepare(x)
    clock, cost, costs = StepTimes(scene.start_day * DAY, scene.dt, history), run_cost(cost, steps), {}
    for k in range(steps + 1):
        if k in cost.at_steps:
            costs[k] = checked(cost, k, x.numpy(), model.grid.spheremp)[0]
        if k < steps:
            clock.set(stepper, k)
            stepper.set_phase(k)
            stepper.step(x)
    return sum(costs[k] for k in sorted(costs))


def taylor_slopes(stepper, steps, weights, scene=None, cost=None, **kw):
    """Remainders |J(x + εδx) − J(x) − ε⟨∇J, δx⟩| over ε = 1e-1 … 1e-5 and their log-log slopes
    (``scene`` None: ``tc5(stepper)``; ``cost`` None: a misfit to h(0) plus 50 m of noise;
    ``kw`` to each ``gradient``, J by ``run_J``)."""
    scene = tc5(stepper) if scene is None else scene
    model, _, x0 = scene_model(scene)
    rng = np.random.default_rng(0)
    if cost is None:
        cost = HeightMisfit(x0[2] + 50 * continuous(model, rng.standard_normal((3, model.N)))[2])
    g = gradient(scene, steps, cost, **kw)
    dx = continuous(model, rng.standard_normal((3, model.N)) * np.array(weights)[:, None])
    dJ = np.sum(model.grid.spheremp * g.grad * dx)
    eps = 10.0 ** -np.arange(1.0, 5.5, 1.0)
    J = run_J(scene, steps, cost, **kw)
    rest = [abs(run_J(scene, steps, cost, x0=x0 + e * dx, **kw) - J - e * dJ) for e in eps]
    return np.diff(np.log(rest)) / np.diff(np.log(eps)), rest, J


def parameter_slopes(perturbed):
    """Taylor slopes of J along a parameter direction: ``perturbed(e)`` → (J at e, its
    first-order change ε⟨∇J, δ⟩ from the gradient at 0)."""
    eps = 10.0 ** -np.arange(1.0, 3.5, 1.0)  # below 1e-3 the remainder nears J's round-off (1e-16 J)
    J0 = perturbed(0.0)[0]
    rest = []
    for e in eps:
        J, dJ = perturbed(e)
        rest.append(abs(J - J0 - dJ))
    return np.diff(np.log(rest)) / np.diff(np.log(eps)), rest, J0


def misfit(model, x0, rng):
    """A height misfit against h(0) plus 50 m of continuous noise drawn from ``rng``."""
    return HeightMisfit(x0[2] + 50 * continuous(model, rng.standard_normal((3, model.N)))[2])


def assert_initial_state_taylor(scene, stepper="rk4", steps=4, **kw):
    """The initial state's Taylor remainder (``taylor_slopes``) falls as ε², above round-off."""
    slopes, rest, J = taylor_slopes(stepper, steps, [1.0, 1.0, 10.0], scene, **kw)
    assert np.all(np.abs(slopes - 2.0) < 0.1), (slopes, rest)
    assert rest[-1] > 1e4 * EPS * J


def assert_falls_as_eps_squared(perturbed, name=""):
    """A parameter's Taylor remainder (``parameter_slopes``) falls as ε², its last above J's round-off."""
    slopes, rest, J = parameter_slopes(perturbed)
    assert np.all(np.abs(slopes - 2.0) < 0.1), (name, slopes, rest)
    assert rest[-1] > 1e3 * EPS * J, (name, rest, J)


def coefficients(scene, names, d, steps, cost, x0=None, **kw):
    """``perturbed`` for the ∇⁴ coefficients ``names`` moved together by ε · 0.2 × the first (the
    ∇⁴'s substeps the same for every ε here), ``d`` their gradient."""
    delta = 0.2 * getattr(scene, names[0])

    def perturbed(e):
        nus = {n: getattr(scene, n) + e * delta for n in names}
        return run_J(dataclasses.replace(scene, **nus), steps, cost, x0=x0, **kw), e * delta * d

    return perturbed


def planet_constant(scene, key, d, steps, cost, x0):
    """``perturbed`` for the planet's ``key`` moved by ε · 5 %, x(0) held, ``d`` its gradient."""
    delta = 0.05 * scene.planet[key]

    def perturbed(e):
        planet = {**scene.planet, key: scene.planet[key] + e * delta}
        return run_J(dataclasses.replace(scene, planet=planet), steps, cost, x0=x0), e * delta * d

    return perturbed


def topography(scene, model, d_hs, dhs, steps, cost, x0, **kw):
    """``perturbed`` for hs moved by ε·``dhs``, x(0) held, ``d_hs`` its gradient (mass form)."""
    hs0, dJ = model.operators.hs.numpy(), np.sum(model.grid.spheremp * d_hs * dhs)
    return lambda e: (run_J(scene, steps, cost, x0=x0, hs=hs0 + e * dhs, **kw), e * dJ)


@functools.cache
def tc4():
    """TC4 (the forced translating low: an analytic forcing of x and t) at ne 2 np 4, rk4 at Δt 1800 s."""
    return load_scene("tc4_forced_low", ne=2, np_=4, dt=1800.0, stepper="rk4")


def assert_replays_the_run(scene, steps, cost, tol=None, **kw):
    """The gradient (``kw`` to it), from every state, from two snapshots and from a disk tier
    of every third state: its forward run is the ``Simulation``'s to the bit, its gradients the
    same bits; returns the first. ``tol``: a stepper that solves (its CG to this relative
    residual), whose recomputed steps start their CG from the stepper's later guesses: the
    gradients the same to 1e3 ``tol`` of the largest entry, not to the bit."""
    every, few = gradient(scene, steps, cost, **kw), gradient(scene, steps, cost, snapshots=2, **kw)
    disk = gradient(scene, steps, cost, snapshots=2, disk=True, disk_interval=3, **kw)
    sim = Simulation(dataclasses.replace(scene, days=steps * scene.dt / 86400.0), "cpu", progress=False)
    sim.run(None)
    np.testing.assert_array_equal(every.final, np.stack(sim.fields()))
    for other in (few, disk):
        if tol is None:
            np.testing.assert_array_equal(other.grad, every.grad)
        else:
            assert np.abs(other.grad - every.grad).max() <= 1e3 * tol * np.abs(every.grad).max()
    return every


def assert_parameter_gradients(scene, model, g, steps, cost, x0, rng, names=("nu", "nu_s", "hs", "gravity", "omega")):
    """Each of ``names``' Taylor remainder falls as ε² (``assert_falls_as_eps_squared``) for the
    gradient ``g`` of ``scene`` run ``steps`` steps from x0 under ``cost``, x(0) held (hs moved
    along 100 m of continuous noise drawn from ``rng``)."""
    dhs = 100.0 * continuous(model, rng.standard_normal((3, model.N)))[2]
    perturbations = {
        "nu": lambda: coefficients(scene, ("nu", "nu_div"), g.d_nu, steps, cost, x0),
        "nu_s": lambda: coefficients(scene, ("nu_s",), g.d_nu_s, steps, cost, x0),
        "hs": lambda: topography(scene, model, g.d_hs, dhs, steps, cost, x0),
        "gravity": lambda: planet_constant(scene, "gravity", g.d_g, steps, cost, x0),
        "omega": lambda: planet_constant(scene, "omega", g.d_omega, steps, cost, x0),
    }
    for name in names:
        assert_falls_as_eps_squared(perturbations[name](), name)
