"""An ensemble Kalman filter beside 4D-Var (issue 85's example): the observations of
``fourdvar_points.py`` (h at ``--points`` points every ``--every`` hours over ``--hours`` of
Galewsky's jet with its bump, σ = ``--sigma`` m) assimilated one time after the other by
``--members`` N forecasts run together (``swe_sphere.Simulation`` with ``members``), the state estimated at each
observation time, where the smoother of ``enkf_points.py`` sought h(0) from all of them at once.

The members start from the 4D-Var example's background (h_b + G z_k, z_k ~ N(0, I), B = G Gᵀ:
``--length``, ``--sigma-b``, ``--h-scale`` as there; the wind the balanced jet's). At each
observation time t_j the ensemble is stopped and every member's whole state (u, v and h at the
unique nodes) updated by the stochastic EnKF with perturbed observations (Burgers, van Leeuwen
& Evensen 1998, MWR 126, 1719; Houtekamer & Mitchell 2001, MWR 129, 123):

    x_k ← x_k + (ρ_xy ∘ C_xy) (ρ_yy ∘ C_yy + R)⁻¹ (y_j + σ ε_k − H(h_k)),   R = σ² I,

C_xy and C_yy the ensemble's covariances of the state with the predicted observations and of
those among themselves, tapered by Gaspari & Cohn's (1999, QJRMS 125, 723, eq. 4.10) function
of the chord distance (``--localization`` c km, zero beyond 2c: at one time the observations
are local, which the smoother's were not), the prior anomalies first inflated by
``--inflation`` (multiplicative; Anderson & Anderson 1999, MWR 127, 2741); then the ensemble
goes on from the analyses (``Simulation.set_states``). Printed at each time: the l2 error of the
ensemble mean's h against the truth at that time, relative to the first guess run forward
(the balanced jet without a bump: 1 at every time), and the spread of h. With
``--fourdvar`` K, 4D-Var's analysis (``fourdvar_points.recover``, K L-BFGS iterations, the same
background) run forward is scored the same way at each time, the last time being where a
filter's estimate and a 4D-Var forecast meet.

    python benchmarks/enkf_filter.py --dt 570 --length 1000 --h-scale 100 [--members 32] [--fourdvar 150]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from enkf_points import ensemble_arguments, gaspari_cohn, unit_xyz
from fourdvar_points import background_root, observed_run, recover, setting
from results import recorded

from swe_sphere import Simulation


def main(args: argparse.Namespace, figures: dict) -> None:
    os.environ.setdefault("SWE_SPHERE_THREADS", "1")
    s = setting(args.ne, args.np, args.hours, args.every, args.points, args.sigma, args.seed, args.dt)
    grid, first, H, times = s.grid, s.grid.first, s.cost.operator, sorted(s.cost.values)
    every = times[1] - times[0]
    truth, _ = observed_run(s.scene, s.steps, s.truth, every)
    guess, _ = observed_run(s.scene, s.steps, s.guess, every)

    def error(h, j):  # h (n_unique,) at step j against the truth's, relative to the first guess's
        t, g = truth[j][2][first], guess[j][2][first]
        return float(np.sqrt(np.sum(grid.area * (h - t) ** 2) / np.sum(grid.area * (g - t) ** 2)))

    def spread(X):  # the area-weighted RMS of h's standard deviation (m)
        return float(np.sqrt(np.sum(grid.area * X.var(axis=1, ddof=1)) / grid.area.sum()))

    G = background_root(grid, args.length * 1e3, args.sigma_b, s.guess[2][first], args.h_scale)
    rng = np.random.default_rng(args.ensemble_seed)
    N, nu = args.members, grid.nunique
    starts = np.repeat(s.guess[None], N, axis=0)
    starts[:, 2] = (s.guess[2][first][:, None] + G @ rng.standard_normal((nu, N))).T[:, grid.gid]
    c = args.localization * 1e3 / grid.radius  # on the unit sphere
    nodes, points = unit_xyz(grid.lat[first], grid.lon[first]), unit_xyz(H.lat, H.lon)
    rho_xy = np.tile(gaspari_cohn(np.linalg.norm(nodes[:, None] - points[None], axis=2), c), (3, 1))
    rho_yy = gaspari_cohn(np.linalg.norm(points[:, None] - points[None], axis=2), c)
    print(
        f"galewsky ne{args.ne} np{args.np} {s.scene.stepper}, {s.steps} steps of {s.scene.dt:.4g} s; {args.points} "
        f"points every {args.every:g} h ({len(times)} times), σ {args.sigma:g} m; stochastic EnKF, {N} members from the "
        f"background (L {args.length:g} km, σ_b {args.sigma_b:g} m, L_h {args.h_scale:g} m), localization c "
        f"{args.localization:g} km, inflation {args.inflation:g}"
    )
    clock = time.process_time()
    ens = Simulation(s.scene, members=N, initial=starts, device=args.device, progress=False)
    rows = []
    for j in times:
        ens.run(None, until_step=j)
        states = ens.states()  # (N, 3, n) element-local
        X = states[:, :, first].reshape(N, 3 * nu).T  # (3 nu, N): u, v, h at the unique nodes
        mean = X.mean(axis=1, keepdims=True)
        X = mean + args.inflation * (X - mean)
        Y = np.stack([H(x[2]) for x in _element_local(X, grid, N)], axis=1)  # (M, N)
        A, D = X - X.mean(axis=1, keepdims=True), Y - Y.mean(axis=1, keepdims=True)
        Cyy = (D @ D.T) / (N - 1) * rho_yy + args.sigma**2 * np.eye(len(Y))
        Cxy = (A @ D.T) / (N - 1) * rho_xy
        y = s.cost.values[j]
        prior = error(X[2 * nu :].mean(axis=1), j)
        X = X + Cxy @ np.linalg.solve(Cyy, y[:, None] + args.sigma * rng.standard_normal(Y.shape) - Y)
        ens.set_states(_element_local(X, grid, N))
        rows.append((j, prior, error(X[2 * nu :].mean(axis=1), j), spread(X[2 * nu :])))
        print(
            f"{j * s.scene.dt / 3600:6.2f} h  forecast {prior:7.4f}  analysis {rows[-1][2]:7.4f}  spread {rows[-1][3]:7.3f} m",
            flush=True,
        )
    cpu = time.process_time() - clock
    print(f"the filter: {N} members over {s.steps} steps, {len(times)} analyses, CPU {cpu:.1f} s")
    figures.update(
        filter={f"{j * s.scene.dt / 3600:g} h": {"forecast": f, "analysis": a, "spread_m": sp} for j, f, a, sp in rows},
        filter_cpu_s=cpu,
    )
    if args.fourdvar:
        r = recover(s, args.fourdvar, args.length * 1e3, args.sigma_b, args.h_scale)
        x0 = s.guess.copy()
        x0[2] = r.h0[grid.gid]
        run, _ = observed_run(s.scene, s.steps, x0, every)
        fourdvar = {f"{j * s.scene.dt / 3600:g} h": error(run[j][2][first], j) for j in times}
        print(f"4D-Var ({r.result.nit} iterations, CPU {r.cpu:.0f} s), its analysis run forward:")
        print("  " + ", ".join(f"{t} {e:.4f}" for t, e in fourdvar.items()))
        figures.update(fourdvar=fourdvar, fourdvar_iterations=int(r.result.nit), fourdvar_cpu_s=r.cpu)
    figures["load"] = os.getloadavg()[0]


def _element_local(X: np.ndarray, grid, N: int) -> np.ndarray:
    """(N, 3, n) element-local states of the unique-node columns X (3 nu, N)."""
    return X.T.reshape(N, 3, grid.nunique)[:, :, grid.gid]


if __name__ == "__main__":
    parser = ensemble_arguments(__doc__.split("\n\n")[0], length=1000.0, h_scale=100.0, localization=1000.0)
    parser.add_argument("--inflation", type=float, default=1.1, help="multiplicative, of the prior anomalies")
    parser.add_argument("--fourdvar", type=int, default=0, help="also 4D-Var with this many L-BFGS iterations")
    arguments = parser.parse_args()
    with recorded(__file__, stem=arguments.results) as figures:
        main(arguments, figures)
