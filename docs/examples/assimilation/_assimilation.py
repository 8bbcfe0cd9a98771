"""What the assimilation examples share (imported by them, not shown in the gallery: sphinx-gallery's
``ignore_pattern`` leaves out ``_*.py``; tests/adjoint imports it too).

Two problems. A TC5 truth whose initial height is sought from its final height at every node
(``recover_height``: plot_fourdvar.py). Galewsky's jet whose 120 m bump is sought from h at a
few seeded points every few hours (``setting``, ``recover``: plot_fourdvar_points.py, and the
ensemble methods of plot_enkf_points.py and plot_enkf_filter.py), with a background error
covariance B = G Gᵀ that follows the background's height contours (``background_root``) and
Gaspari & Cohn's taper for the ensembles' covariances (``gaspari_cohn``). The unknowns are h(0)
at the grid's unique nodes, the wind held; one ``swe_sphere.gradient`` call (a forward and a
reverse sweep) gives a cost and its gradient.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import NamedTuple

import numpy as np
import scipy.optimize
import scipy.sparse
import scipy.spatial

import swe_sphere


def observed_run(scene, steps: int, x0=None, every: int | None = None):
    """({k: x(k)} at steps 0, every, 2·every, … ≤ ``steps`` (every None: 0 and ``steps``), each
    (3, N) numpy element-local u, v (m s⁻¹) and h (m); the grid; CPU s) of ``scene`` run from x0
    (None: its case's state) by ``swe_sphere.Simulation``, the run ``gradient`` differentiates."""
    clock = time.process_time()
    sim = swe_sphere.Simulation(scene, start=x0, progress=False)
    every = every or steps
    states = {0: sim.states()[0].copy()}
    for k in range(every, steps + 1, every):
        sim.run(None, until_step=k)
        states[k] = sim.states()[0].copy()
    return states, sim.grid, time.process_time() - clock


def height_cost(scene, steps: int, grid, cost, x0):
    """h0 ↦ (J, dJ/dh0) for L-BFGS: h0 (n_unique,) m the initial height at the grid's unique
    nodes (the wind x0[:2] held), J = ``cost`` of ``scene`` run ``steps`` steps (one
    ``swe_sphere.gradient`` call). The gradient is in the mass inner product (δJ = Σ spheremp ·
    grad · δx over the element copies), so a unique node's derivative sums its copies'
    spheremp · grad[2]."""

    def evaluate(h0):
        x = x0.copy()
        x[2] = h0[grid.gid]
        g = swe_sphere.gradient(scene, steps, cost, x0=x)
        return g.cost, np.bincount(grid.gid, grid.spheremp * g.grad[2], minlength=grid.nunique)

    return evaluate


def bump(grid, amplitude: float, width: float, lat0: float = 30.0, lon0: float = 90.0) -> np.ndarray:
    """A Gaussian of ``amplitude`` (m) and e-folding great-circle distance ``width`` (m) about
    (lat0, lon0) (degrees), at the grid's unique nodes (n_unique,)."""
    lat, lon = grid.lat[grid.first], grid.lon[grid.first]
    p0, l0 = np.radians(lat0), np.radians(lon0)
    cos_d = np.sin(lat) * np.sin(p0) + np.cos(lat) * np.cos(p0) * np.cos(lon - l0)
    return amplitude * np.exp(-((grid.radius * np.arccos(np.clip(cos_d, -1.0, 1.0)) / width) ** 2))


class HeightRecovery(NamedTuple):
    """``recover_height``'s answer: J (m²) and the normalised l2 error of h(0) (Williamson's,
    ‖h0 − h_t(0)‖ / ‖h_t(0)‖) at the first guess and at the end; the truth's h(0) and the first
    guess's at the unique nodes (m); scipy's result (``nit``, ``nfev``, ``x`` the recovered h(0));
    the grid; the minimisation's CPU s; J at each of its evaluations (m²)."""

    cost0: float
    cost: float
    error0: float
    error: float
    truth: np.ndarray
    guess: np.ndarray
    result: scipy.optimize.OptimizeResult
    grid: swe_sphere.CubedSphere
    cpu: float
    costs: list


def mean_square_cost(scene, steps: int, grid, x0, h_obs, costs=None):
    """``height_cost`` of J = ½ ∫ (h(T) − h_obs)² dA / 4πa² (m²: half the mean square misfit, so
    that L-BFGS's tolerances read in m²), h_obs (N,) element-local m; each J appended to the
    list ``costs`` where given."""
    total = grid.area.sum()
    evaluate = height_cost(scene, steps, grid, swe_sphere.HeightMisfit(h_obs), x0)

    def scaled(h0):
        J, dJ = evaluate(h0)
        if costs is not None:
            costs.append(J / total)
        return J / total, dJ / total

    return scaled


def recover_height(scene, steps: int, amplitude: float, width: float, iterations: int) -> HeightRecovery:
    """A 4D-Var-style recovery of ``scene``'s initial height from its final height at every node
    after ``steps`` steps: L-BFGS-B (at most ``iterations``) on ``mean_square_cost`` from the
    truth's h(0) plus ``bump(amplitude, width)`` (m, m), the wind held at the truth's."""
    states, grid, _ = observed_run(scene, steps)
    truth = states[0]
    costs = []
    cost = mean_square_cost(scene, steps, grid, truth, states[steps][2], costs)
    h_true = truth[2][grid.first]

    def error(h0):
        return float(np.sqrt(np.sum(grid.area * (h0 - h_true) ** 2) / np.sum(grid.area * h_true**2)))

    guess = h_true + bump(grid, amplitude, width)
    clock = time.process_time()
    result = scipy.optimize.minimize(
        cost, guess, jac=True, method="L-BFGS-B", options={"maxiter": iterations, "ftol": 1e-15, "gtol": 1e-12}
    )
    cpu = time.process_time() - clock
    return HeightRecovery(costs[0], result.fun, error(guess), error(result.x), h_true, guess, result, grid, cpu, costs)


class Setting(NamedTuple):
    """Galewsky's problem: ``scene`` run ``steps`` steps; ``cost`` the ``HeightObservations``
    (every ``every`` steps from 0); ``grid``; x(0) of the truth and of the first guess, (3, N)
    element-local u, v (m s⁻¹) and h (m)."""

    scene: swe_sphere.Scene
    steps: int
    every: int
    cost: swe_sphere.HeightObservations
    grid: swe_sphere.CubedSphere
    truth: np.ndarray
    guess: np.ndarray


def setting(ne: int, np_: int, hours: float, every_hours: float, points: int, sigma: float, seed: int) -> Setting:
    """Galewsky's jet with its bump (the ``galewsky`` scene at ne, np, its Δt shortened to divide
    ``every_hours``) run ``hours``; h at ``points`` points uniform on the sphere (seeded) every
    ``every_hours`` from t = 0, each with Gaussian noise of σ = ``sigma`` m (seeded), read off the
    truth by ``PointHeights`` (the element's own GLL polynomial); the first guess the balanced jet
    without the bump (Galewsky et al. 2004's perturbation is in h alone)."""
    own = swe_sphere.load_scene("galewsky", ne=ne, np_=np_, days=hours / 24.0).dt
    every = math.ceil(every_hours * 3600.0 / own)
    scene = swe_sphere.load_scene("galewsky", ne=ne, np_=np_, days=hours / 24.0, dt=every_hours * 3600.0 / every)
    steps = round(hours / every_hours) * every
    states, grid, _ = observed_run(scene, steps, None, every)
    truth = states[0]
    guess = np.stack(dataclasses.replace(scene.make_case(), perturbed=False).initial(grid.lat, grid.lon))
    rng = np.random.default_rng(seed)
    H = swe_sphere.PointHeights(grid, np.arcsin(rng.uniform(-1.0, 1.0, points)), rng.uniform(-np.pi, np.pi, points))
    values = {k: H(x[2]) + sigma * rng.standard_normal(points) for k, x in states.items()}
    return Setting(scene, steps, every, swe_sphere.HeightObservations(H, values, sigma), grid, truth, guess)


def unit_xyz(lat, lon) -> np.ndarray:
    """Points (n, 3) on the unit sphere of ``lat``, ``lon`` (n,) in radians."""
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)


def background_root(grid, length: float, sigma_b: float, h_b=None, h_scale: float = 0.0):
    """G (n_unique, n_unique) scipy CSR, symmetric, the root of the background error covariance
    B = G Gᵀ: σ_b c exp(−d²/L²) for chord distances d < 3L between unique nodes (``length`` L m,
    ``sigma_b`` σ_b m), c such that the mean of diag(B) is σ_b². With ``h_scale`` L_h > 0 (m) each
    entry also takes exp(−(h_b,i − h_b,j)²/L_h²) of the background's heights ``h_b``
    (n_unique,) m: correlations that follow its height contours, as a balanced flow's
    streamlines do (Riishøjgaard 1998, Tellus 50A, 42, eq. 5)."""
    xyz = grid.radius * unit_xyz(grid.lat[grid.first], grid.lon[grid.first])
    near = scipy.spatial.cKDTree(xyz).query_ball_point(xyz, 3.0 * length)
    rows = np.repeat(np.arange(len(near)), [len(j) for j in near])
    cols = np.concatenate(near)
    w = np.exp(-np.sum((xyz[rows] - xyz[cols]) ** 2, axis=1) / length**2)
    if h_scale > 0:
        w *= np.exp(-((h_b[rows] - h_b[cols]) ** 2) / h_scale**2)
    c = 1.0 / np.sqrt(np.sum(w**2) / len(near))
    return scipy.sparse.csr_matrix((sigma_b * c * w, (rows, cols)), shape=(len(near),) * 2)


def gaspari_cohn(d: np.ndarray, c: float) -> np.ndarray:
    """Gaspari & Cohn (1999, QJRMS 125, 723) eq. 4.10: the compactly supported correlation of
    distance d (≥ 0) with half-width c (same units; zero for d ≥ 2c)."""
    r = d / c
    out = np.zeros_like(r)
    near, far = r <= 1, (r > 1) & (r < 2)
    x = r[near]
    out[near] = -0.25 * x**5 + 0.5 * x**4 + 0.625 * x**3 - 5 / 3 * x**2 + 1
    x = r[far]
    out[far] = x**5 / 12 - 0.5 * x**4 + 0.625 * x**3 + 5 / 3 * x**2 - 5 * x + 4 - 2 / (3 * x)
    return out


def unknowns_cost(s: Setting, G):
    """(z ↦ (J, dJ/dz), z ↦ h0): J = ½ zᵀz + J_o(h_b + G z), J_o the observations' cost of h0
    (``height_cost``), h_b the first guess's h (the control-variable transform, B = G Gᵀ;
    G None: J = J_o(z), z = h0)."""
    observed, h_b = height_cost(s.scene, s.steps, s.grid, s.cost, s.guess), s.guess[2][s.grid.first]
    if G is None:
        return observed, lambda z: z

    def cost(z):
        J, dh = observed(h_b + G @ z)
        return J + 0.5 * float(z @ z), G.T @ dh + z

    return cost, lambda z: h_b + G @ z


class Recovery(NamedTuple):
    """``recover``'s answer: J at the first guess and at the end, J_o at the end and at the truth
    (dimensionless); the l2 error of h(0) relative to the bump, ‖h0 − h_t(0)‖ / ‖h_b − h_t(0)‖
    (area-weighted over the unique nodes), at the first guess (1) and at the end; scipy's result;
    the recovered h(0) at the unique nodes (m); the minimisation's CPU s."""

    cost0: float
    cost: float
    observed: float
    cost_truth: float
    error0: float
    error: float
    result: scipy.optimize.OptimizeResult
    h0: np.ndarray
    cpu: float


def relative_error(grid, h_true, h_b):
    """h ↦ ‖h − h_true‖ / ‖h_b − h_true‖, area-weighted over the unique nodes (each (n_unique,) m)."""
    norm = np.sqrt(np.sum(grid.area * (h_b - h_true) ** 2))
    return lambda h: float(np.sqrt(np.sum(grid.area * (h - h_true) ** 2)) / norm)


def recover(s: Setting, iterations: int, length: float, sigma_b: float, h_scale: float = 0.0) -> Recovery:
    """4D-Var: L-BFGS-B from the first guess (z = 0), at most ``iterations``, on
    J(z) = ½ zᵀz + Σ_k ½ Σ_m ((H h(t_k))_m − y_km)² / σ²; ``length`` (m), ``sigma_b`` (m; 0: no
    background term) and ``h_scale`` (m; 0: isotropic) the background's (``background_root`` on
    the first guess's heights)."""
    first = s.grid.first
    h_true, h_guess = s.truth[2][first], s.guess[2][first]
    error = relative_error(s.grid, h_true, h_guess)
    G = background_root(s.grid, length, sigma_b, h_guess, h_scale) if sigma_b > 0 else None
    cost, state = unknowns_cost(s, G)
    z0 = h_guess.copy() if G is None else np.zeros(s.grid.nunique)
    observed = height_cost(s.scene, s.steps, s.grid, s.cost, s.guess)
    cost0 = cost(z0)[0]
    clock = time.process_time()
    result = scipy.optimize.minimize(
        cost, z0, jac=True, method="L-BFGS-B", options={"maxiter": iterations, "ftol": 1e-12, "gtol": 1e-12}
    )
    cpu = time.process_time() - clock
    h0 = state(result.x)
    return Recovery(cost0, result.fun, observed(h0)[0], observed(h_true)[0], error(h_guess), error(h0), result, h0, cpu)
