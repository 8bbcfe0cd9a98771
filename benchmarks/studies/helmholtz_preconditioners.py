"""Preconditioners for the Helmholtz operator M + cK on the production solves.

``--record PATH``: the production solves, TC5 ne30 np4 IMEX (ARS(3,4,3), ``guess_history`` 8)
at 2160 s after ``--spin-up`` days, the next ``--count`` solves' c, b, start x0 (the projected
guess) and the model CG's iterations (npz; the solves run outside graphs to be seen).
``--solves PATH``: preconditioners on them, CG from x0 to ‖r‖ ≤ ``--tol``‖b‖ (``pcg``'s test),
all as scipy sparse products on the assembled M + cK (``helmholtz_matrix``; the same footing):

* mass: M⁻¹ (what ``pcg`` uses);
* blocks: each element's 16×16 block of the assembled matrix inverted, applied additively with
  weights 1/√(copies of the node) on both sides (HOMME ``solver_mod`` ``block_jacobi``, symmetrised);
* p-MG: a two-grid cycle, 3 Chebyshev steps on [λmax/8, λmax] (Saad 2003, Alg. 12.1) before and
  after a Galerkin correction on np = 2 (bilinear on the element corners), the coarse system by
  one pyamg smoothed-aggregation V-cycle.

Median iterations and products a solve, CPU time a solve (medians of ``--rounds`` interleaved
rounds over every ``--stride``-th solve), the set-up (once a run) per solve of a day's solves,
and a lower bound as kernels: iterations × (the model's CG iteration + blocks' batched 16×16
products, or p-MG's 6 model products and its coarse V-cycle). The random-right-hand-side study
before it (Chebyshev, low-order-refined and AMG preconditioners, the weak Laplacian, the
spectra) is in git history (``git log -- benchmarks/studies/helmholtz_preconditioners.py``).
CPU clock (``time.process_time``); run with one thread:

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/studies/helmholtz_preconditioners.py --record solves.npz
    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/studies/helmholtz_preconditioners.py --solves solves.npz
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import pyamg
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import warp as wp
from threadpoolctl import threadpool_limits

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import DAY, recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import (  # noqa: E402
    Simulation,  # noqa: E402
    load_scene,  # noqa: E402
)
from swe_sphere.grid.gll import gll  # noqa: E402
from swe_sphere.model.gravity_wave import GravityWaveOperator  # noqa: E402
from swe_sphere.model.helmholtz import HelmholtzOptions, HelmholtzSolver  # noqa: E402
from swe_sphere.solvers.helmholtz_matrix import helmholtz_matrix  # noqa: E402

SGS = ("gauss_seidel", {"sweep": "symmetric"})
SMOOTHING = 3  # Chebyshev steps before and after the p-MG coarse correction


def corner_prolongation(grid) -> sp.csr_matrix:
    """(nunique × corners): bilinear interpolation from the element corners (np = 2) to the GLL nodes."""
    n = grid.np
    x = gll(n).points
    gid = grid.gid.reshape(grid.nelem, n, n)
    corner = np.stack([gid[:, 0, 0], gid[:, 0, -1], gid[:, -1, 0], gid[:, -1, -1]], axis=1)
    _, coarse = np.unique(corner, return_inverse=True)
    coarse = coarse.reshape(corner.shape)
    e, p = np.divmod(grid.first, n * n)
    j, i = np.divmod(p, n)
    s, t = x[i], x[j]
    weights = np.stack([(1 - s) * (1 - t), (1 + s) * (1 - t), (1 - s) * (1 + t), (1 + s) * (1 + t)], axis=1) / 4
    P = sp.csr_matrix(
        (weights.ravel(), (np.repeat(np.arange(grid.nunique), 4), coarse[e].ravel())),
        shape=(grid.nunique, coarse.max() + 1),
    )
    P.eliminate_zeros()
    return P


def cg_iterations(A, b, precond, tol, maxiter=5000, x0=None) -> int:
    """Iterations of CG with ``precond`` from x0 (None: 0) until ‖r‖ ≤ tol ‖b‖ (−1: not within maxiter)."""
    count = [0]
    _, info = spla.cg(
        A,
        b,
        x0=x0,
        rtol=tol,
        atol=0.0,
        maxiter=maxiter,
        M=spla.LinearOperator(A.shape, matvec=precond),
        callback=lambda _: count.__setitem__(0, count[0] + 1),
    )
    return count[0] if info == 0 else -1


def chebyshev(A, minv, lo, hi, steps):
    """y ↦ ``steps`` Chebyshev steps for A y = r on [lo, hi] ∋ spec(M⁻¹A), from y (None: 0, no product)
    (Saad 2003, Alg. 12.1)."""
    theta, delta = (hi + lo) / 2, (hi - lo) / 2
    sigma = theta / delta

    def apply(r, y):
        rho = 1 / sigma
        res, y = (r, 0.0) if y is None else (r - A @ y, y)
        d = minv * res / theta
        for k in range(steps):
            y = y + d
            if k < steps - 1:
                res = res - A @ d
                rho_new = 1 / (2 * sigma - rho)
                d = rho_new * rho * d + (2 * rho_new / delta) * (minv * res)
                rho = rho_new
        return y

    return apply


def block_jacobi(grid, A):
    """r ↦ Σ_e W R_eᵀ A_e⁻¹ R_e W r, A_e the element's block of A, W = diag(1/√copies); and its dense part alone."""
    n2 = grid.np**2
    ids = grid.gid.reshape(grid.nelem, n2)
    w = 1 / np.sqrt(np.bincount(grid.gid, minlength=grid.nunique).astype(float))
    A = A.tocsr()
    inv = np.linalg.inv(np.stack([A[e][:, e].toarray() for e in ids]))
    dense = lambda r: np.einsum("eij,ej->ei", inv, (w * r)[ids])  # noqa: E731
    return (lambda r: w * np.bincount(ids.ravel(), weights=dense(r).ravel(), minlength=grid.nunique)), dense


def two_level(grid, A, minv, hi):
    """r ↦ the p-MG two-grid cycle (``SMOOTHING`` Chebyshev steps on [hi/8, hi], the Galerkin correction on
    the element corners by one SA V-cycle, the same steps again), and r ↦ its coarse part alone."""
    Pc = corner_prolongation(grid)
    coarse = pyamg.smoothed_aggregation_solver(
        (Pc.T @ A @ Pc).tocsr(), symmetry="symmetric", presmoother=SGS, postsmoother=SGS
    ).aspreconditioner(cycle="V")
    smooth = chebyshev(A, minv, hi / 8, hi, SMOOTHING)

    def cycle(r):
        y = smooth(r, None)
        return smooth(r, y + Pc @ coarse.matvec(Pc.T @ (r - A @ y)))

    return cycle, lambda r: coarse.matvec(Pc.T @ r)


def lambda_max(K, minv) -> float:
    """λmax(M⁻¹K) = λmax(M^-½ K M^-½) by Lanczos."""
    scale = sp.diags(np.sqrt(minv))
    return float(spla.eigsh(scale @ K @ scale, k=1, which="LA", tol=1e-3, return_eigenvectors=False)[0])


def cpu_seconds(f, repeat) -> float:
    f()
    t0 = time.process_time()
    for _ in range(repeat):
        f()
    return (time.process_time() - t0) / repeat


def record(path, spin_up, count):
    sim = Simulation(
        load_scene("tc5_mountain", ne=30, np_=4, days=1.0, stepper="imex", dt=2160.0), "cpu", progress=False
    )
    sim.graphs, gw = "off", sim.stepper.helmholtz
    gw.graphable = False
    sim.advance(spin_up)
    seen, solve, first = {"c": [], "b": [], "x0": [], "its": []}, gw.cg.solve, sim.step

    def watched(c, *args, **kw):  # y holds the start: the projected guess
        its = gw.stats.numpy()[0]
        (
            seen["c"].append(c),
            seen["b"].append(gw.b.numpy().copy()),
            seen["x0"].append(gw.y.numpy().copy()),
        )  # CPU numpy() is a view
        solve(c, *args, **kw)
        seen["its"].append(gw.stats.numpy()[0] - its)

    gw.cg.solve = watched
    while len(seen["b"]) < count:
        sim.advance(sim.scene.dt / DAY)
    np.savez(
        path,
        **{k: np.array(v) for k, v in seen.items()},
        per_day=len(seen["b"]) / (sim.step - first) * DAY / sim.scene.dt,
    )
    print(
        f"{len(seen['b'])} solves of {sim.step - first} steps from day {spin_up:g} into {path}; model CG iterations: median {np.median(seen['its']):g}"
    )


def production(path, tol, rounds, stride):
    d = dict(np.load(path))
    sim, c = build(30)[0], float(d["c"][0])
    assert np.all(d["c"] == c), "one c a run"  # the IMEX ARS(3,4,3) stages share a_ii
    grid, minv = sim.grid, 1 / sim.grid.area
    A = (sp.diags(grid.area) + c * helmholtz_matrix(sim.model)).tocsr()
    gw = HelmholtzSolver(
        GravityWaveOperator(sim.model, 1.0), HelmholtzOptions(tol, 5000, guess_history=0)
    )  # the model's CG from zero on the first b: its time an iteration
    gw.b.assign(d["b"][0])
    gw.solve_height(c)
    its0 = gw.iterations()
    t_it = cpu_seconds(lambda: gw.solve_height(c), 3) / its0
    t_op = cpu_seconds(lambda: gw.apply(gw.cg.u, gw.cg.w, c), 20)

    def pmg():
        cycle, coarse = two_level(grid, A, minv, 1.05 * lambda_max(A, minv))
        return cycle, lambda: 2 * SMOOTHING * t_op + cpu_seconds(lambda: coarse(d["b"][0]), 10)

    def blocks():
        apply, dense = block_jacobi(grid, A)
        return apply, lambda: cpu_seconds(lambda: dense(d["b"][0]), 10)

    setups = {
        "mass (production)": lambda: (lambda r: minv * r, lambda: 0.0),
        "blocks (HOMME blkjac)": blocks,
        f"p-MG np2 (cheb {SMOOTHING}+{SMOOTHING}, SA coarse)": pmg,
    }
    products = dict(zip(setups, (1, 1, 1 + 2 * SMOOTHING)))
    precond, setup, extra = {}, {}, {}
    for name, make in setups.items():
        t0 = time.process_time()
        precond[name], extra[name] = make()
        setup[name] = time.process_time() - t0
        extra[name] = extra[name]()  # the preconditioner's time as kernels (a lower bound; the module's docstring)
    its = {n: [cg_iterations(A, b, p, tol, x0=x0) for b, x0 in zip(d["b"], d["x0"])] for n, p in precond.items()}
    seconds = {n: [] for n in precond}
    for _ in range(rounds):
        for n, p in precond.items():
            t0 = time.process_time()
            for b, x0 in zip(d["b"][::stride], d["x0"][::stride]):
                cg_iterations(A, b, p, tol, x0=x0)
            seconds[n].append((time.process_time() - t0) / len(d["b"][::stride]))
    print(
        f"{len(d['b'])} recorded solves, c = {c:.4g} m² (a²gH), {float(d['per_day']):.0f} solves a day; model CG iterations: median {np.median(d['its']):g}, "
        f"{np.mean(d['its']):.1f} mean; tol {tol:g}; {rounds} rounds over every {stride}th solve; "
        f"the model's CG {t_it * 1e3:.2f} ms an iteration, its product {t_op * 1e3:.2f} ms"
    )
    print(
        "| preconditioner | its a solve (median, mean) | products a solve | scipy CPU ms a solve | set-up s (ms a solve over a day) | scipy total ms | kernels ms (bound) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for n in precond:
        t, s, k = (
            1e3 * np.median(seconds[n]),
            1e3 * setup[n] / float(d["per_day"]),
            1e3 * np.mean(its[n]) * (t_it + extra[n]),
        )
        print(
            f"| {n} | {np.median(its[n]):g}, {np.mean(its[n]):.1f} | {products[n] * np.mean(its[n]):.1f} | {t:.1f} | {setup[n]:.2f} ({s:.1f}) | {t + s:.1f} | {k + s:.1f} |"
        )


def build(ne):
    sim = Simulation(
        load_scene("tc5_mountain", ne=ne, np_=4, days=1.0, stepper="semi_implicit", dt=60.0), "cpu", progress=False
    )
    sim.stepper.helmholtz.operator.set_depth(sim.x)
    return sim, 60.0 / sim.courant()["courant_gravity"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--record", help="write the production solves to this npz")
    mode.add_argument("--solves", help="run the preconditioners on the solves of this npz")
    ap.add_argument("--spin-up", type=float, default=0.5, help="days before --record's solves")
    ap.add_argument("--count", type=int, default=100, help="--record's solves")
    ap.add_argument("--tol", type=float, default=1e-6)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--stride", type=int, default=4)
    args = ap.parse_args()
    threadpool_limits(1)
    # the recording's log apart from the solves' figures: the README's two steps keep both files
    with recorded(__file__, "helmholtz_preconditioners_record" if args.record else None):
        print(
            f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, CPU clock, SWE_SPHERE_THREADS={os.environ.get('SWE_SPHERE_THREADS', '(all)')}, "
            f"load {os.getloadavg()[0]:.2f}"
        )
        if args.record:
            record(args.record, args.spin_up, args.count)
        else:
            production(args.solves, args.tol, args.rounds, args.stride)
        print(f"# load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
