"""ν fitted to a spectral reference by L-BFGS-B on ``swe_sphere.gradient`` (issue 66's second
example): the ∇⁴ coefficients of a scene that make its h + hs closest to T341's on a stored day.

    python benchmarks/nu_fit.py [--scene tc5_mountain] [--ne 16] [--days 1] [--truncation T341]
                                [--iterations 30]

The run: the scene (np 4, its own stepper and Δt at that ne, an explicit table) from its case's
initial state for ``--days`` (a day the reference stores). The unknowns: p = (log s, log s_s),
ν = ν_div = s ν₀ on the wind and ν_s = s_s ν₀ₛ on the surface, ν₀ and ν₀ₛ the scene's own
(its ``efold_hours`` rule). L-BFGS-B (scipy), each p in [log 0.05, log 20], minimises

    J(p) = ½ ∫ (h(T; p) + hs − (h + hs)_ref(T))² dA / (4πa²)    (m²: half the mean square misfit)

with dJ/dp = (s ν₀ ∂J/∂ν, s_s ν₀ₛ ∂J/∂ν_s) from one ``gradient(..., parameters=True)`` call
(a forward and a reverse sweep, every state held). The reference is the spectral model's
h + hs evaluated at the model's nodes (TC5: its truncated mountain, so h + hs and not h is
compared). Printed: ν, ν_s, J and Williamson's normalised l2 error of h + hs (eq. 83) at the
scene's ν and at the fit, a ladder of J over s = s_s (the fit's landscape, one forward run
each), the iterations, the gradients and the CPU s. One thread (``SWE_SPHERE_THREADS=1`` unless
set). The ∇⁴'s forward-Euler substeps are fixed by ν Δt: where the fit crosses a substep count
J has a kink (reported as the substeps at each ν).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import time

import numpy as np
import scipy.optimize

import swe_sphere
from swe_sphere.adjoint.gradient import scene_model
from swe_sphere.cases.reference import Reference, reference_path
from swe_sphere.core.constants import DAY

BOUNDS = (math.log(0.05), math.log(20.0))


def setting(name: str, ne: int, days: float, truncation: str):
    """(scene, steps, cost, grid, h + hs of the reference at the nodes (N,), the model's hs (N,))."""
    scene = swe_sphere.load_scene(name, ne=ne, np_=4, days=days)
    steps = round(days * DAY / scene.dt)
    if not math.isclose(steps * scene.dt, days * DAY, rel_tol=1e-9):
        raise ValueError(f"{days:g} days is not a whole number of steps of {scene.dt:g} s")
    model, _, _ = scene_model(scene)
    grid, hs = model.grid, model.operators.hs.numpy()
    path = reference_path(scene.make_case(), truncation)
    if path is None:
        raise ValueError(f"no {truncation} reference for {name}")
    surface = Reference(path).at(days, grid.lat, grid.lon)["h_surface"]
    return scene, steps, swe_sphere.HeightMisfit(surface - hs), grid, surface, hs


def with_nu(scene, s: float, s_s: float):
    """The scene with ν = ν_div scaled by s and ν_s by s_s."""
    return dataclasses.replace(scene, nu=s * scene.nu, nu_div=s * scene.nu_div, nu_s=s_s * scene.nu_s)


def main() -> None:
    from results import recorded  # benchmarks/ is first on the path of a script run from it

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="tc5_mountain")
    parser.add_argument("--ne", type=int, default=16)
    parser.add_argument("--days", type=float, default=1.0, help="the run, to a day the reference stores")
    parser.add_argument("--truncation", default="T341")
    parser.add_argument("--iterations", type=int, default=30, help="L-BFGS iterations at most")
    parser.add_argument("--ladder", type=float, nargs="*", default=[0.25, 0.5, 1, 2, 4], help="s = s_s of the ladder")
    args = parser.parse_args()
    os.environ.setdefault("SWE_SPHERE_THREADS", "1")  # read when the model is built
    scene, steps, misfit, grid, surface, hs = setting(args.scene, args.ne, args.days, args.truncation)
    total = grid.spheremp.sum()  # 4πa² over the element-local nodes
    norm = math.sqrt(float(np.sum(grid.spheremp * surface**2)))

    def run(p):
        s, s_s = np.exp(p)
        sc = with_nu(scene, s, s_s)
        g = swe_sphere.gradient(sc, steps, misfit, parameters=True)
        l2 = math.sqrt(2.0 * g.cost) / norm  # ½ Σ spheremp r² = J: Williamson's l2 of h + hs
        dJ = np.array([s * scene.nu * g.d_nu, s_s * scene.nu_s * g.d_nu_s]) / total
        return g.cost / total, dJ, l2

    with recorded(__file__) as figures:
        start = run(np.zeros(2))
        ladder = []
        for s in args.ladder:
            sc = with_nu(scene, s, s)
            model, _, _ = scene_model(sc)
            substeps = model.hv.plan(sc.dt)[0] if model.hv is not None else 0
            J, _, l2 = run(np.log([s, s]))
            ladder.append({"s": s, "J": J, "l2": l2, "substeps": substeps})
        clock = time.process_time()
        result = scipy.optimize.minimize(
            lambda p: run(p)[:2],
            np.zeros(2),
            jac=True,
            method="L-BFGS-B",
            bounds=[BOUNDS, BOUNDS],
            options={"maxiter": args.iterations, "ftol": 1e-12, "gtol": 1e-10},
        )
        cpu = time.process_time() - clock
        s, s_s = np.exp(result.x)
        fit = run(result.x)
        print(
            f"{args.scene} ne{args.ne} np4 {scene.stepper}, {steps} steps of {scene.dt:.1f} s ({args.days:g} days) "
            f"against {args.truncation}; ν₀ = ν_div = {scene.nu:.4g}, ν₀ₛ = {scene.nu_s:.4g} m⁴ s⁻¹; one thread; "
            f"load {os.getloadavg()}"
        )
        print("ladder (s = s_s):")
        for row in ladder:
            print(f"  s {row['s']:6g}  J {row['J']:.6e} m²  l2 {row['l2']:.6e}  ∇⁴ substeps {row['substeps']}")
        print(f"{'':12} {'ν (m⁴/s)':>12} {'ν_s (m⁴/s)':>12} {'J (m²)':>14} {'l2 h+hs':>12}")
        print(f"{'scene':12} {scene.nu:12.4e} {scene.nu_s:12.4e} {start[0]:14.6e} {start[2]:12.6e}")
        print(f"{'fitted':12} {s * scene.nu:12.4e} {s_s * scene.nu_s:12.4e} {fit[0]:14.6e} {fit[2]:12.6e}")
        print(
            f"s = {s:.4g}, s_s = {s_s:.4g}; {result.nit} iterations, {result.nfev} gradients, CPU {cpu:.2f} s; "
            f"scipy: {result.message}"
        )
        figures |= {
            "nu0": scene.nu,
            "nu_s0": scene.nu_s,
            "s": float(s),
            "s_s": float(s_s),
            "J0": start[0],
            "J": fit[0],
            "l2_0": start[2],
            "l2": fit[2],
            "ladder": ladder,
            "iterations": int(result.nit),
            "evaluations": int(result.nfev),
            "cpu": cpu,
        }


if __name__ == "__main__":
    main()
