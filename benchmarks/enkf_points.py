"""An ensemble smoother beside 4D-Var (issue 85's example): the problem of
``fourdvar_points.py`` (Galewsky's height bump recovered from h at ``--points`` points every
``--every`` hours over ``--hours``, σ = ``--sigma`` m, the wind held at the balanced jet's), solved by
an ensemble of forecasts instead of a gradient.

The method: ES-MDA, the ensemble smoother with multiple data assimilation (Emerick & Reynolds
2013, Computers & Geosciences 55, 3, eqs. 5–8). ``--members`` N initial heights drawn from the
4D-Var example's background, h0_k = h_b + G z_k with z_k ~ N(0, I) (B = G Gᵀ: ``--length``,
``--sigma-b``, ``--h-scale`` as there), are run together over the window
(``swe_sphere.Simulation`` with ``members``: N members in the same launches), their heights read at the points
(the example's ``PointHeights``); then every h0_k is updated at once with all the observations,

    h0_k ← h0_k + C_xy (C_yy + α R)⁻¹ (y + √α σ ε_k − H(h_k)),   R = σ² I,  ε_k ~ N(0, I),

C_xy, C_yy the ensemble's covariances of h0 with the predicted observations and of those among
themselves, each tapered by Gaspari & Cohn's (1999, QJRMS 125, 723, eq. 4.10) fifth-order
function of the chord distance (``--localization`` c km: zero beyond 2c), and repeated
``--iterations`` times with α = the iterations' number (Σ 1/α = 1). Printed after each update:
the l2 error of the ensemble mean h(0) relative to the bump (the 4D-Var example's measure) and
the ensemble's spread; then the CPU seconds. ``--ensemble-seed`` draws the members.

    python benchmarks/enkf_points.py --dt 570 --length 1000 --h-scale 100 [--members 32] [--iterations 4]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from fourdvar_points import background_root, setting  # noqa: E402  (benchmarks/, the script's directory)
from results import positive, recorded

from swe_sphere import Simulation


def gaspari_cohn(d: np.ndarray, c: float) -> np.ndarray:
    """Gaspari & Cohn (1999) eq. 4.10: the compactly supported correlation of distance d (≥ 0)
    with half-width c (zero for d ≥ 2c)."""
    r = d / c
    out = np.zeros_like(r)
    near, far = r <= 1, (r > 1) & (r < 2)
    x = r[near]
    out[near] = -0.25 * x**5 + 0.5 * x**4 + 0.625 * x**3 - 5 / 3 * x**2 + 1
    x = r[far]
    out[far] = x**5 / 12 - 0.5 * x**4 + 0.625 * x**3 + 5 / 3 * x**2 - 5 * x + 4 - 2 / (3 * x)
    return out


def unit_xyz(lat, lon) -> np.ndarray:
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)


def forecast(s, h0: np.ndarray, guess: np.ndarray, device: str = "cpu") -> np.ndarray:
    """The predicted observations (M·K, N) of the members' initial heights h0 (n_unique, N), the
    wind the guess's: the ensemble run over the window, H h at each observation step."""
    grid, H, steps = s.grid, s.cost.operator, sorted(s.cost.values)
    states = np.repeat(guess[None], h0.shape[1], axis=0)
    states[:, 2] = h0.T[:, grid.gid]
    ens = Simulation(s.scene, members=h0.shape[1], initial=states, device=device, progress=False)
    predicted = []
    for k in steps:
        ens.run(None, until_step=k)
        predicted.append(np.stack([H(h) for h in ens.states()[:, 2]], axis=1))
    return np.concatenate(predicted)


def main(args: argparse.Namespace, figures: dict) -> None:
    os.environ.setdefault("SWE_SPHERE_THREADS", "1")
    s = setting(args.ne, args.np, args.hours, args.every, args.points, args.sigma, args.seed, args.dt)
    grid, first = s.grid, s.grid.first
    h_true, h_b = s.truth[2][first], s.guess[2][first]

    def error(h0):  # the 4D-Var example's measure: l2 of h(0) − truth over the bump's
        return float(np.sqrt(np.sum(grid.area * (h0 - h_true) ** 2) / np.sum(grid.area * (h_b - h_true) ** 2)))

    G = background_root(grid, args.length * 1e3, args.sigma_b, h_b, args.h_scale)
    rng = np.random.default_rng(args.ensemble_seed)
    N, H = args.members, s.cost.operator
    X = h_b[:, None] + G @ rng.standard_normal((grid.nunique, N))  # (n_unique, N)
    y = np.concatenate([s.cost.values[k] for k in sorted(s.cost.values)])
    K = len(s.cost.values)
    nodes = unit_xyz(grid.lat[first], grid.lon[first])
    points = unit_xyz(H.lat, H.lon)
    c = args.localization * 1e3 / grid.radius  # on the unit sphere
    rho_xy = np.tile(gaspari_cohn(np.linalg.norm(nodes[:, None] - points[None], axis=2), c), (1, K))
    rho_yy = np.tile(gaspari_cohn(np.linalg.norm(points[:, None] - points[None], axis=2), c), (K, K))
    print(
        f"galewsky ne{args.ne} np{args.np} {s.scene.stepper}, {s.steps} steps of {s.scene.dt:.4g} s; {args.points} points × "
        f"{K} times, σ {args.sigma:g} m; ES-MDA, {N} members from the background (L {args.length:g} km, σ_b "
        f"{args.sigma_b:g} m, L_h {args.h_scale:g} m), {args.iterations} updates, localization c {args.localization:g} km"
    )
    print(f"{'':14s} {'l2 h(0) err / bump':>20s} {'spread of h(0) (m)':>20s}")
    spread = lambda X: float(np.sqrt(np.sum(grid.area[:, None] * X.var(axis=1, ddof=1)[:, None]) / grid.area.sum()))  # noqa: E731
    rows = [("background", error(X.mean(axis=1)), spread(X))]
    print(f"{rows[0][0]:14s} {rows[0][1]:20.4f} {rows[0][2]:20.4f}")
    clock = time.process_time()
    alpha = float(args.iterations)
    for i in range(args.iterations):
        Y = forecast(s, X, s.guess, args.device)
        A, D = X - X.mean(axis=1, keepdims=True), Y - Y.mean(axis=1, keepdims=True)
        Cyy = (D @ D.T) / (N - 1) * rho_yy + alpha * args.sigma**2 * np.eye(y.size)
        Cxy = (A @ D.T) / (N - 1) * rho_xy
        innovations = y[:, None] + np.sqrt(alpha) * args.sigma * rng.standard_normal((y.size, N)) - Y
        X = X + Cxy @ np.linalg.solve(Cyy, innovations)
        rows.append((f"update {i + 1}", error(X.mean(axis=1)), spread(X)))
        print(f"{rows[-1][0]:14s} {rows[-1][1]:20.4f} {rows[-1][2]:20.4f}", flush=True)
    cpu = time.process_time() - clock
    print(
        f"{args.iterations} ensemble runs of {N} members ({args.device}) and updates: CPU {cpu:.1f} s; "
        f"load {os.getloadavg()[0]:.2f}"
    )
    figures.update(errors={name: e for name, e, _ in rows}, spreads={name: sp for name, _, sp in rows}, cpu_s=cpu)


def ensemble_arguments(description: str, length: float, h_scale: float, localization: float):
    """The options the ensemble scripts share (the 4D-Var example's problem, its background, the
    members, the localization), with these defaults; each script adds its own."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--ne", type=int, default=16)
    parser.add_argument("--np", type=int, default=4)
    parser.add_argument("--hours", type=positive(float), default=24.0)
    parser.add_argument("--every", type=positive(float), default=3.0, help="hours between observations")
    parser.add_argument("--points", type=positive(int), default=200)
    parser.add_argument("--sigma", type=positive(float), default=0.1, help="observation error (m)")
    parser.add_argument("--seed", type=int, default=0, help="the points' and the noise's seed (the 4D-Var example's)")
    parser.add_argument("--dt", type=float, default=None, help="s, before it is shortened to divide --every")
    parser.add_argument("--length", type=positive(float), default=length, help="background correlation length L (km)")
    parser.add_argument("--sigma-b", type=positive(float), default=3.0, help="background error σ_b (m)")
    parser.add_argument("--h-scale", type=float, default=h_scale, help="background height scale L_h (m; 0: isotropic)")
    parser.add_argument("--members", type=positive(int, above=1), default=32)
    parser.add_argument(
        "--localization", type=positive(float), default=localization, help="Gaspari-Cohn half-width c (km)"
    )
    parser.add_argument("--ensemble-seed", type=int, default=100)
    parser.add_argument("--device", default="cpu", help="the ensemble's forecasts' (the truth runs on the CPU)")
    parser.add_argument("--results", help="results/enkf_points/<STEM>.json (default: the script's stem)")
    return parser


if __name__ == "__main__":
    parser = ensemble_arguments(__doc__.split("\n\n")[0], length=400.0, h_scale=0.0, localization=2000.0)
    parser.add_argument("--iterations", type=int, default=4, help="ES-MDA updates")
    arguments = parser.parse_args()
    with recorded(__file__, stem=arguments.results) as figures:
        main(arguments, figures)
