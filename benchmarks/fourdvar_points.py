"""4D-Var from sparse, noisy point observations over a day: Galewsky's height perturbation
recovered by L-BFGS on ``swe_sphere.gradient`` with a cost of the run (issue 66's example).

    python benchmarks/fourdvar_points.py [--ne 16] [--np 4] [--hours 24] [--every 3] [--points 200]
                                         [--sigma 0.1] [--seed 0] [--length 1000] [--sigma-b 3]
                                         [--h-scale 100] [--iterations 150] [--results NAME]

The truth: Galewsky's jet with its 120 m height bump (the ``galewsky`` scene, kgu35, at the ne
and np given, Δt its own at that grid shortened to divide ``--every``), run ``--hours``. The
observations: h at ``--points`` fixed points (uniform on the sphere, seeded) every ``--every``
hours from t = 0 to the end, each with Gaussian noise of σ = ``--sigma`` m (seeded), read off
the truth by ``PointHeights`` (the element's own GLL polynomial). The first guess: the balanced
jet without the bump, also the background h_b of the cost. The unknowns: h(0) at the grid's
unique nodes (a continuous field), as h0 = h_b + G z (the control-variable transform of
variational assimilation, B = G Gᵀ the background error covariance): G_ij = σ_b c
exp(−d_ij²/L²) exp(−(h_b,i − h_b,j)²/L_h²) over the unique nodes' chord distances d_ij < 3L
(L = ``--length`` km, σ_b = ``--sigma-b`` m, L_h = ``--h-scale`` m, c such that the mean of
diag(B) is σ_b²): correlations that follow the background's height contours, as a balanced
flow's streamlines do (Riishøjgaard 1998, Tellus 50A, 42), long along the jet and short across
it (``--h-scale 0``: the isotropic Gaussian of length L√2). The wind is held at the jet's,
which is the truth's (Galewsky's perturbation is in h alone). L-BFGS-B (scipy) minimises over z

    J(z) = ½ zᵀz + Σ_k ½ Σ_m ((H h(t_k; h0))_m − y_km)² / σ²    (dimensionless; J_o ≈ M·K/2 at the truth)

with J_o and dJ_o/dh0 from one ``gradient`` call (a ``HeightObservations`` cost; a forward and a
reverse sweep, every state held), dJ/dz = Gᵀ dJ_o/dh0 + z; ``--sigma-b 0``: no background
term, z = h0 itself (the problem is then underdetermined: M·K observations, more unknowns,
and L-BFGS fits the noise). Printed: J and the l2 error of h(0) relative to the
perturbation, ‖h0 − h_t(0)‖ / ‖h_t(0) − h_b(0)‖ (area-weighted over the unique nodes), at the
first guess (1 by construction) and at the end, J_o of the truth itself (the noise's share), the
iterations, the gradients, the CPU s of the minimisation and one gradient's CPU against a
forward run's (its model built, as each ``gradient`` call builds one). One thread
(``SWE_SPHERE_THREADS=1`` unless set).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import time
from typing import NamedTuple

import numpy as np
import scipy.optimize
import scipy.sparse
import scipy.spatial
import warp as wp

import swe_sphere
from swe_sphere.adjoint.gradient import scene_model


class Setting(NamedTuple):
    """The problem: ``scene`` run ``steps`` steps; ``cost`` the ``HeightObservations`` (steps
    every ``every``); ``grid``; x(0) of the truth and the first guess (3, N) numpy; a forward
    run's CPU s (its model built)."""

    scene: swe_sphere.Scene
    steps: int
    cost: swe_sphere.HeightObservations
    grid: swe_sphere.CubedSphere
    truth: np.ndarray
    guess: np.ndarray
    forward_cpu: float


def observed_run(scene, steps: int, x0, every: int):
    """(states at steps 0, every, 2·every, … ≤ ``steps`` as {k: x(k)}, CPU s) of ``scene`` run
    from x0 (3, N): its model built, then the steps, as a ``gradient`` call's forward pass."""
    clock = time.process_time()
    model, stepper, _ = scene_model(scene)
    x = wp.array(x0, dtype=wp.float64, device=model.device)
    stepper.prepare(x)
    states = {0: x0.copy()}
    for k in range(1, steps + 1):
        stepper.advance(x)
        if k % every == 0:
            states[k] = x.numpy().copy()
    return states, time.process_time() - clock


def setting(
    ne: int, np_: int, hours: float, every_hours: float, points: int, sigma: float, seed: int, dt: float | None = None
) -> Setting:
    """The truth run, its observations and the first guess (module docstring); ``dt`` (s) the
    step before it is shortened to divide the observation interval (None: the scene's)."""
    own = dt or swe_sphere.load_scene("galewsky", ne=ne, np_=np_, days=hours / 24.0).dt
    every = math.ceil(every_hours * 3600.0 / own)  # steps between observations
    scene = swe_sphere.load_scene("galewsky", ne=ne, np_=np_, days=hours / 24.0, dt=every_hours * 3600.0 / every)
    steps = round(hours / every_hours) * every
    model, _, truth = scene_model(scene)
    grid = model.grid
    case = scene.make_case()
    guess = np.stack(dataclasses.replace(case, perturbed=False).initial(grid.lat, grid.lon))
    rng = np.random.default_rng(seed)
    H = swe_sphere.PointHeights(grid, np.arcsin(rng.uniform(-1.0, 1.0, points)), rng.uniform(-np.pi, np.pi, points))
    runs = [observed_run(scene, steps, truth, every) for _ in range(3)]  # the first warms Warp's caches
    states = runs[-1][0]
    values = {k: H(x[2]) + sigma * rng.standard_normal(points) for k, x in states.items()}
    cost = swe_sphere.HeightObservations(H, values, sigma)
    return Setting(scene, steps, cost, grid, truth, guess, min(r[1] for r in runs[1:]))


def background_root(grid, length: float, sigma_b: float, h_b=None, h_scale: float = 0.0):
    """G (n, n) scipy CSR over the grid's unique nodes, symmetric: σ_b c exp(−d²/L²) for chord
    distances d < 3L (``length`` L m, ``sigma_b`` σ_b m), c such that the mean of diag(G Gᵀ)
    is σ_b² (module docstring). With ``h_scale`` L_h > 0 (m) each entry also takes the factor
    exp(−(h_b,i − h_b,j)²/L_h²) of the background's heights ``h_b`` (n,) m: correlations that
    follow the background's height contours, which a balanced flow's streamlines follow
    (Riishøjgaard 1998, Tellus 50A, 42, eq. 5, with the background field h_b)."""
    lat, lon = grid.lat[grid.first], grid.lon[grid.first]
    xyz = grid.radius * np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)
    near = scipy.spatial.cKDTree(xyz).query_ball_point(xyz, 3.0 * length)
    rows = np.repeat(np.arange(len(near)), [len(j) for j in near])
    cols = np.concatenate(near)
    w = np.exp(-np.sum((xyz[rows] - xyz[cols]) ** 2, axis=1) / length**2)
    if h_scale > 0:
        w *= np.exp(-((h_b[rows] - h_b[cols]) ** 2) / h_scale**2)
    c = 1.0 / np.sqrt(np.sum(w**2) / len(near))
    return scipy.sparse.csr_matrix((sigma_b * c * w, (rows, cols)), shape=(len(near),) * 2)


class Recovery(NamedTuple):
    """What ``recover`` returns: J (dimensionless) at the first guess and at the end, J_o at the
    end and at the truth; the l2 error of h(0) relative to the perturbation at the first guess
    and at the end; scipy's result (``nit``, ``nfev``, ``x`` the unknowns z); the recovered
    h(0) at the unique nodes (m); the minimisation's CPU s."""

    cost0: float
    cost: float
    observed: float
    cost_truth: float
    error0: float
    error: float
    result: scipy.optimize.OptimizeResult
    h0: np.ndarray
    cpu: float


def observation_cost(s: Setting):
    """h0 (n,) m at the unique nodes ↦ (J_o, dJ_o/dh0 (n,) m⁻¹), the wind held at the guess's:
    the gradient is in the mass inner product, so a unique node's derivative sums its copies'
    spheremp · grad[2]."""
    grid = s.grid

    def cost(h0):
        x = s.guess.copy()
        x[2] = h0[grid.gid]
        g = swe_sphere.gradient(s.scene, s.steps, s.cost, x0=x)
        return g.cost, np.bincount(grid.gid, grid.spheremp * g.grad[2], minlength=grid.nunique)

    return cost


def unknowns_cost(s: Setting, G):
    """(z ↦ (J, dJ/dz), z ↦ h0): J = ½ zᵀz + J_o(h_b + G z) (G None: J_o(z), z = h0)."""
    observed, h_b = observation_cost(s), s.guess[2][s.grid.first]
    if G is None:
        return observed, lambda z: z

    def cost(z):
        J, dh = observed(h_b + G @ z)
        return J + 0.5 * float(z @ z), G.T @ dh + z

    return cost, lambda z: h_b + G @ z


def recover(s: Setting, iterations: int, length: float, sigma_b: float, h_scale: float = 0.0) -> Recovery:
    """L-BFGS-B from the first guess (z = 0), at most ``iterations`` iterations; ``length`` (m),
    ``sigma_b`` (m, 0: no background term) and ``h_scale`` (m, 0: none) the background's
    (``background_root``, on the first guess's heights)."""
    grid, first = s.grid, s.grid.first
    h_true, h_guess = s.truth[2][first], s.guess[2][first]

    def error(h0):
        return float(np.sqrt(np.sum(grid.area * (h0 - h_true) ** 2) / np.sum(grid.area * (h_guess - h_true) ** 2)))

    G = background_root(grid, length, sigma_b, h_guess, h_scale) if sigma_b > 0 else None
    cost, state = unknowns_cost(s, G)
    z0 = h_guess.copy() if G is None else np.zeros(grid.nunique)
    observed = observation_cost(s)
    cost0 = cost(z0)[0]
    clock = time.process_time()
    result = scipy.optimize.minimize(
        cost, z0, jac=True, method="L-BFGS-B", options={"maxiter": iterations, "ftol": 1e-12, "gtol": 1e-12}
    )
    cpu = time.process_time() - clock
    h0 = state(result.x)
    fit, truth = observed(h0)[0], observed(h_true)[0]
    return Recovery(cost0, result.fun, fit, truth, error(h_guess), error(h0), result, h0, cpu)


def main() -> None:
    from results import positive, recorded  # benchmarks/ is first on the path of a script run from it

    os.environ.setdefault("SWE_SPHERE_THREADS", "1")  # read when the model is built

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ne", type=int, default=16)
    parser.add_argument("--np", type=int, default=4)
    parser.add_argument("--hours", type=positive(float), default=24.0, help="the window")
    parser.add_argument("--every", type=positive(float), default=3.0, help="hours between observations")
    parser.add_argument("--points", type=int, default=200, help="observed points (fixed, uniform, seeded)")
    parser.add_argument("--sigma", type=float, default=0.1, help="the observations' noise (m)")
    parser.add_argument("--seed", type=int, default=0, help="of the points and the noise")
    parser.add_argument("--length", type=float, default=1000.0, help="the background's correlation length L (km)")
    parser.add_argument("--sigma-b", type=float, default=3.0, help="the background's σ_b (m; 0: no background term)")
    parser.add_argument(
        "--h-scale", type=float, default=100.0, help="L_h (m): correlations follow the background's heights (0: none)"
    )
    parser.add_argument("--iterations", type=positive(int), default=150, help="L-BFGS iterations at most")
    parser.add_argument("--results", help="the results file's name (default fourdvar_points)")
    parser.add_argument("--dt", type=float, help="the step (s) before it divides --every (default: the scene's)")
    args = parser.parse_args()
    with recorded(__file__, args.results) as figures:
        s = setting(args.ne, args.np, args.hours, args.every, args.points, args.sigma, args.seed, args.dt)
        r = recover(s, args.iterations, args.length * 1e3, args.sigma_b, args.h_scale)
        per_gradient = r.cpu / r.result.nfev
        times = len(s.cost.at_steps)
        print(
            f"galewsky ne{args.ne} np{args.np} {s.scene.stepper}, {s.steps} steps of {s.scene.dt:.1f} s "
            f"({s.steps * s.scene.dt / 3600:.2f} h); {args.points} points × {times} times (every "
            f"{args.every:g} h from t = 0), σ {args.sigma:g} m, seed {args.seed}; h(0) at {r.h0.size} "
            f"unique nodes, wind held; background L {args.length:g} km, σ_b {args.sigma_b:g} m, L_h {args.h_scale:g} m; one thread; "
            f"load {os.getloadavg()}"
        )
        print(f"{'':14} {'J':>12} {'J_o':>12} {'l2 h(0) err / bump':>20}")
        print(f"{'first guess':14} {r.cost0:12.5g} {'':12} {r.error0:20.4f}")
        print(f"{'recovered':14} {r.cost:12.5g} {r.observed:12.5g} {r.error:20.4f}")
        print(f"{'truth':14} {'':12} {r.cost_truth:12.5g} {0.0:20.4f}")
        print(
            f"{r.result.nit} iterations, {r.result.nfev} cost+gradient evaluations, CPU {r.cpu:.2f} s "
            f"({per_gradient:.4f} s a gradient, {per_gradient / s.forward_cpu:.2f}× a run's "
            f"{s.forward_cpu:.4f} s); scipy: {r.result.message}"
        )
        figures |= {
            "cost0": r.cost0,
            "cost": r.cost,
            "observed": r.observed,
            "cost_truth": r.cost_truth,
            "error0": r.error0,
            "error": r.error,
            "iterations": int(r.result.nit),
            "evaluations": int(r.result.nfev),
            "cpu": r.cpu,
            "forward_cpu": s.forward_cpu,
        }


if __name__ == "__main__":
    main()
