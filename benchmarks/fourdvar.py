"""A 4D-Var-style recovery of an initial height field from the final one, by L-BFGS on
``swe_sphere.gradient``: issue 66's example.

    python benchmarks/fourdvar.py [--scene tc5_mountain] [--ne 4] [--hours 6] [--iterations 100]
                                  [--amplitude 80] [--width 1600]

A truth run of the scene (np 4, its own Δt at that ne) from the case's initial state x_t(0) for
``--hours``; the observations are the truth's final height h_t(T) at every node. The first guess
is h_t(0) plus a Gaussian bump (``--amplitude`` m, e-folding ``--width`` km, centred at 30° N
90° E), the wind held at the truth's. The unknowns are h(0) at the unique nodes (a continuous
field), and L-BFGS-B (scipy) minimises

    J(h0) = ½ ∫ (h(T; h0) − h_t(T))² dA / (4πa²)    (m²: half the mean square misfit)

with its gradient from one ``gradient`` call (a forward and a reverse sweep, every state held).
Printed: J and the normalised l2 error of h(0) (Williamson's, ‖h0 − h_t(0)‖ / ‖h_t(0)‖) at
the first guess and at the end, the iterations, the cost evaluations (each one gradient), the
CPU time of the whole minimisation, and one gradient's CPU time against a forward run's (its
model built, as each ``gradient`` call builds one). One thread (``SWE_SPHERE_THREADS=1`` unless
set).
"""

from __future__ import annotations

import argparse
import os
import time
from typing import NamedTuple

import numpy as np
import scipy.optimize
import warp as wp

import swe_sphere
from swe_sphere.adjoint.gradient import scene_model


class Recovery(NamedTuple):
    """What ``recover`` returns: J (m²) and the normalised l2 error of h(0) at the first guess
    (the bump's own) and at the end, scipy's result (``nit``, ``nfev``, ``x`` the
    recovered h(0) at the unique nodes, m), the minimisation's CPU s and a forward run's (its
    model built, as each ``gradient`` call builds one)."""

    cost0: float
    cost: float
    error0: float
    error: float
    result: scipy.optimize.OptimizeResult
    cpu: float
    forward_cpu: float


def bump(grid, amplitude: float, width: float, lat0: float = 30.0, lon0: float = 90.0) -> np.ndarray:
    """A Gaussian of ``amplitude`` (m) and e-folding great-circle distance ``width`` (m) about
    (lat0, lon0) (degrees), at the grid's unique nodes (n,)."""
    lat, lon = grid.lat[grid.first], grid.lon[grid.first]
    p0, l0 = np.radians(lat0), np.radians(lon0)
    cos_d = np.sin(lat) * np.sin(p0) + np.cos(lat) * np.cos(p0) * np.cos(lon - l0)
    d = grid.radius * np.arccos(np.clip(cos_d, -1.0, 1.0))
    return amplitude * np.exp(-((d / width) ** 2))


def truth_run(scene, steps: int):
    """(x(n), x(0), grid, CPU s) of ``scene`` run ``steps`` steps from its case's state, the CPU
    time that of a whole run as ``gradient`` makes one: its model built, then the steps."""
    clock = time.process_time()
    model, stepper, x0 = scene_model(scene)
    x = wp.array(x0, dtype=wp.float64, device=model.device)
    stepper.prepare(x)
    for _ in range(steps):
        stepper.advance(x)
    return x.numpy(), x0, model.grid, time.process_time() - clock


def height_cost(scene, steps: int, grid, x0, h_obs):
    """The function h0 ↦ (J, dJ/dh0) that L-BFGS is handed: h0 (n,) m at the grid's unique nodes
    (the wind x0[:2] held), J = ½ ∫ (h(T) − h_obs)² dA / 4πa² (m²) after ``steps`` steps of
    ``scene``, dJ/dh0 (n,) m (the Euclidean gradient in the unknowns)."""
    misfit = swe_sphere.HeightMisfit(h_obs)
    total = grid.area.sum()  # 4πa²: J as a mean square, so that L-BFGS's tolerances read in m²

    def cost(h0):
        # h0 at the unique nodes → the element-local state (every copy of a node the same value);
        # the gradient is in the mass inner product (δJ = Σ spheremp·grad·δx over the copies), so
        # the derivative with respect to a unique node's value sums its copies' spheremp·grad.
        x = x0.copy()
        x[2] = h0[grid.gid]
        g = swe_sphere.gradient(scene, steps, misfit, x0=x)
        return g.cost / total, np.bincount(grid.gid, grid.spheremp * g.grad[2], minlength=grid.nunique) / total

    return cost


def recover(scene, steps: int, amplitude: float, width: float, iterations: int) -> Recovery:
    """The truth run, its observations and the minimisation (module docstring) of ``scene`` over
    ``steps`` steps, from a first guess ``bump(amplitude, width)`` off the truth."""
    runs = [truth_run(scene, steps) for _ in range(3)]  # the first warms Warp's caches
    final, truth, grid = runs[-1][:3]
    forward_cpu = min(r[3] for r in runs[1:])
    cost = height_cost(scene, steps, grid, truth, final[2])
    h_true = truth[2][grid.first]

    def error(h0):
        return float(np.sqrt(np.sum(grid.area * (h0 - h_true) ** 2) / np.sum(grid.area * h_true**2)))

    guess = h_true + bump(grid, amplitude, width)
    cost0 = cost(guess)[0]
    clock = time.process_time()
    result = scipy.optimize.minimize(
        cost, guess, jac=True, method="L-BFGS-B", options={"maxiter": iterations, "ftol": 1e-15, "gtol": 1e-12}
    )
    cpu = time.process_time() - clock
    return Recovery(cost0, result.fun, error(guess), error(result.x), result, cpu, forward_cpu)


def main() -> None:
    from results import positive, recorded  # benchmarks/ is first on the path of a script run from it

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="tc5_mountain")
    parser.add_argument("--ne", type=int, default=4)
    parser.add_argument("--hours", type=positive(float), default=6.0, help="the window: truth run and observation time")
    parser.add_argument("--iterations", type=positive(int), default=100, help="L-BFGS iterations at most")
    parser.add_argument("--amplitude", type=float, default=80.0, help="the first guess's bump (m)")
    parser.add_argument("--width", type=float, default=1600.0, help="the bump's e-folding distance (km)")
    args = parser.parse_args()
    os.environ.setdefault("SWE_SPHERE_THREADS", "1")  # read when the model is built
    scene = swe_sphere.load_scene(args.scene, ne=args.ne, np_=4)
    steps = max(1, round(args.hours * 3600.0 / scene.dt))
    with recorded(__file__) as figures:
        r = recover(scene, steps, args.amplitude, args.width * 1e3, args.iterations)
        per_gradient = r.cpu / r.result.nfev
        print(
            f"{args.scene} ne{args.ne} np4 {scene.stepper}, {steps} steps of {scene.dt:.1f} s "
            f"({steps * scene.dt / 3600:.2f} h); h(0) at {r.result.x.size} unique nodes; one thread; "
            f"load {os.getloadavg()}"
        )
        print(f"{'':14} {'J (m²)':>12} {'l2 h(0) err':>12}")
        print(f"{'first guess':14} {r.cost0:12.4e} {r.error0:12.4e}")
        print(f"{'recovered':14} {r.cost:12.4e} {r.error:12.4e}")
        print(
            f"J fell {r.cost0 / r.cost:.3g}×, the h(0) error {r.error0 / r.error:.3g}×; "
            f"{r.result.nit} iterations, {r.result.nfev} cost+gradient evaluations, CPU {r.cpu:.2f} s "
            f"({per_gradient:.4f} s a gradient, {per_gradient / r.forward_cpu:.1f}× a run's "
            f"{r.forward_cpu:.4f} s); scipy: {r.result.message}"
        )
        figures |= {
            "cost0": r.cost0,
            "cost": r.cost,
            "error0": r.error0,
            "error": r.error,
            "iterations": int(r.result.nit),
            "evaluations": int(r.result.nfev),
            "cpu": r.cpu,
            "forward_cpu": r.forward_cpu,
        }


if __name__ == "__main__":
    main()
