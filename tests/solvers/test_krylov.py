"""Flexible GMRES (``solvers.krylov``) and its vector work, alone and in the implicit stepper's
Newton systems.

* With an inexact inner solve (the preconditioner's Helmholtz CG to 1e-1): the true linear
  residual at η (9.8e-7 for 1e-6), where scipy's GMRES (not flexible; removed with the other
  Krylov variants) missed it (6.8e-3).
* A changing preconditioner and restarts on a random system; the iterations of scipy's GMRES
  with a fixed one.
* The two backends of the vector work (numpy, Warp kernels) against numpy and against each
  other on Crank–Nicolson steps, one host read a restart cycle, and restart cycles replayed as
  graphs giving the bits of host loops.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.core.tally import Tally, instrumented
from swe_sphere.grid.topology import Topology

import roundoff
from helpers import cached_grid, make_sim


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def test_fgmres_reaches_the_true_residual_with_an_inexact_inner_solve():
    """TC5 ne = 4, the first Newton system J δ = −R of a CN step of 21600 s
    (gravity-wave Courant 10.7), solved to η = 1e-6 with the preconditioner's
    Helmholtz equation solved by the compiled CG to a loose 1e-1, so that the
    preconditioner changes from one application to the next. Flexible GMRES
    keeps the directions it preconditioned: the true residual ‖J δ + R‖/‖R‖ is
    at η (GMRES on J P⁻¹ with δ = P⁻¹w at the end, right for a fixed P only,
    missed it by orders of magnitude: 6.8e-3)."""
    base = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper="implicit", dt=21600.0)
    options = {"helmholtz_tol": 1e-1, "gmres_maxiter": 60}
    sim = make_sim(dataclasses.replace(base, stepper_options=options))
    st, x = sim.stepper, sim.x
    st.forcing_term = lambda *args: 1e-6  # the first Newton iteration's η
    solve, found = st.fgmres.solve, {}

    class Solved(Exception):
        """The first Newton system solved: the step stops there."""

    def first_system(matvec, precond, minus_R, delta, *args, **kw):  # δ (unique nodes) from J δ = −R
        found["its"], _ = solve(matvec, precond, minus_R, delta, *args, **kw)
        jv = wp.zeros_like(delta)
        st.jacobian_product(delta, jv)  # about the step's first iterate, x
        found["true"] = rel(jv.numpy(), minus_R.numpy())  # ‖J δ + R‖ / ‖R‖
        raise Solved

    st.fgmres.solve = first_system
    with pytest.raises(Solved):
        st.step(x)
    print(f"\n{found['its']} GMRES iterations, true relative residual {found['true']:.2e}", end="")
    assert found["true"] < 2e-6


@pytest.mark.parametrize("backend", ["HostVectors", "KernelVectors"])
def test_fgmres_solves_with_a_changing_preconditioner_and_restarts(backend, rng):
    """``krylov.FGMRES`` on a random nonsymmetric, diagonally dominant system
    (n = 200), with either backend of its vector work: with a preconditioner that
    changes at every application (a random-scaled Jacobi) and restarts every 5
    iterations, the true residual reaches the tolerance; without restarts the
    iterations match scipy's GMRES (same Krylov space with a fixed preconditioner)."""
    import scipy.sparse.linalg as spla

    from swe_sphere.solvers import krylov

    n = 200
    A = np.diag(np.linspace(1.0, 10.0, n)) + 0.3 * rng.standard_normal((n, n)) / math.sqrt(n)
    b_np = rng.standard_normal(n)
    d = 1.0 / np.diag(A)
    one_process = Topology(cached_grid(2, 4))  # FGMRES takes its device, threads and reductions

    def solve(restart, scaling, rtol, maxiter, rhs=b_np):
        def matvec(v, out):  # CPU Warp arrays: numpy() is a view
            out.numpy()[:] = A @ v.numpy()

        def precond(v, out):
            out.numpy()[:] = d * v.numpy() * scaling()

        b, x = wp.array(rhs, dtype=wp.float64), wp.full(n, 1.0, dtype=wp.float64)
        its, ok = krylov.FGMRES(n, restart, one_process, getattr(krylov, backend)).solve(
            matvec, precond, b, x, rtol, maxiter
        )
        return x.numpy(), its, ok

    x, its, ok = solve(5, lambda: rng.uniform(0.5, 1.5, n), 1e-10, 500)
    resid = np.linalg.norm(b_np - A @ x) / np.linalg.norm(b_np)
    count = [0]
    spla.gmres(
        A,
        b_np,
        rtol=1e-8,
        atol=0.0,
        restart=n,
        maxiter=1,
        M=np.diag(d),
        callback=lambda _: count.__setitem__(0, count[0] + 1),
        callback_type="pr_norm",
    )
    _, its_fixed, _ = solve(n, lambda: 1.0, 1e-8, n)
    print(
        f"\nchanging preconditioner, restart 5: {its} iterations, true residual {resid:.1e}; "
        f"fixed: FGMRES {its_fixed}, scipy GMRES {count[0]} iterations"
    )
    assert ok and resid < 2e-10
    assert abs(its_fixed - count[0]) <= 1
    # b = 0: x = 0 at once; maxiter = 7 across a restart: 7 products, not converged
    x0, its0, ok0 = solve(5, lambda: 1.0, 1e-10, 500, rhs=np.zeros(n))
    assert (its0, ok0) == (0, True) and not np.any(x0)
    assert solve(5, lambda: 1.0, 1e-10, 7)[1:] == (7, False)


@pytest.mark.parametrize("backend", ["HostVectors", "KernelVectors"])
def test_krylov_basis_vector_work_matches_numpy(backend, rng):
    """``krylov.KrylovBasis``'s two backends of its vector work (numpy/BLAS on the
    CPU, ``kernels.krylov`` on CUDA, both runnable on the CPU) against a numpy
    reference on random vectors (n = 1000, not a multiple of the kernels' chunk): the
    projection with its inner products (k_sub, k_dot in 0–3, B a row range of the
    basis) and the combinations (out aliasing x; a = 0), to round-off (1e-13 relative:
    the sums differ only in order and fused multiply–adds)."""
    from swe_sphere.solvers import krylov

    n, rows = 1000, 6
    basis = krylov.KrylovBasis(n, rows, Topology(cached_grid(2, 4)), vectors=getattr(krylov, backend))
    V = rng.standard_normal((rows, n))
    basis.V.assign(V)
    close = lambda got, ref: np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())  # noqa: E731
    for k_sub, k_dot in [(0, 0), (0, 3), (2, 2), (3, 1)]:
        w = rng.standard_normal(n)
        basis.w.assign(w)
        h = rng.standard_normal(k_sub)
        B = basis.V[2:]  # a row range, as KIOPS's incomplete orthogonalisation takes
        d = basis.project_dots(B, basis.w, k_sub, h if k_sub else None, k_dot)
        ref = w - h @ V[2 : 2 + k_sub]
        close(basis.w.numpy(), ref)
        close(d, np.append(V[2 : 2 + k_dot] @ ref, ref @ ref))
    for k, a in [(0, 0.7), (3, -1.3), (5, 0.0)]:
        c = rng.standard_normal(k)
        x = basis.V.numpy()[5].copy()
        basis.lincomb(basis.V, c, a, basis.rows_V[5], basis.rows_V[5])  # out aliasing x
        close(basis.V.numpy()[5], a * x + c @ V[:k])


@pytest.mark.roundoff
def test_krylov_backends_agree_on_cn_steps_and_fgmres_reads_once_a_cycle():
    """TC5 ne = 2 np = 4, three CN steps at 4 Δt_g with ``gmres_restart`` = 3 (so that
    solves restart): the Krylov work in Warp kernels (``KernelVectors``, ``KernelPasses``:
    CUDA's backends) against numpy (the CPU's) gives the same Newton and GMRES
    iterations and states round-off apart (within 3 ops times the run's own floor: its
    end from a start one rounding away, ``roundoff.nudged``; the backends' sums differ by
    ≤ 3 roundings in each RHS evaluation and iteration); and with the kernels, inside the GMRES solves
    (their preconditioner's Helmholtz solves left out), one host read a restart cycle
    (the tally's ``.numpy()`` read-backs: the J·v's ε, the Gram–Schmidt sums and the
    least squares stay on the device; before, 4 reads an Arnoldi step)."""
    from swe_sphere.solvers import jacobian, krylov

    scene = load_scene("tc5_mountain", ne=2, np_=4, stepper="implicit")
    scene = dataclasses.replace(scene, dt=4.0 * scene.dt, stepper_options={"gmres_restart": 3})
    runs = {}
    for backend in ("host", "kernels", "nudged"):
        sim = make_sim(scene)
        if backend == "nudged":  # host, from a start one rounding away: the run's round-off floor
            sim.x.assign(roundoff.nudged(sim.x.numpy(), sim.grid, np.random.default_rng(5)))
        st, tally, own = sim.stepper, Tally(), [0]
        if backend == "kernels":
            st.fgmres.vectors, st.jacobian.passes = krylov.KernelVectors(st.fgmres), jacobian.KernelPasses(st.model)

        def counted(fn, sign):  # the reads inside fn added to own (sign 1) or taken from it (−1)
            def call(*a, **k):
                before = tally.syncs
                out = fn(*a, **k)
                own[0] += sign * (tally.syncs - before)
                return out

            return call

        st.fgmres.solve, st.helmholtz.solve = counted(st.fgmres.solve, 1), counted(st.helmholtz.solve, -1)
        with instrumented(tally), tally.counting():
            its = [st.step(sim.x).iterations for _ in range(3)]
        runs[backend] = sim.x.numpy(), its, own[0], tally.launches["fgmres_end"]
    (host, its_host, _, _), (kern, its_kern, reads, cycles) = runs["host"], runs["kernels"]
    floor, ops = max(roundoff.state_difference(runs["nudged"][0], host)), sum(sum(i.values()) for i in its_host)
    print(
        f"\n{its_kern}; kernels against numpy {rel(kern, host):.1e} (floor {floor:.1e}); {reads} reads in {cycles} GMRES cycles",
        end="",
    )
    assert its_kern == its_host
    roundoff.within(max(roundoff.state_difference(kern, host)), 3 * ops * floor, "|kernels − numpy| (wind, depth)")
    assert reads == cycles > sum(i["newton"] for i in its_kern)  # restarts happened


def test_fgmres_cycles_replayed_as_graphs_give_the_bits_of_host_loops(monkeypatch):
    """CN without a preconditioner (HOMME's default) on TC5 ne = 2 at 2 Δt_g, three steps
    with CUDA's Krylov backends on one CPU thread: each restart cycle's Arnoldi steps
    captured once per (iterate, F(x), Δt, β) as Warp's CPU graph (conditional steps
    on the device flag) and replayed give the bits, iterations and RHS count of the
    steps run as host loops; a replayed cycle runs no Python (its J·v not called)."""
    from swe_sphere.solvers import jacobian, krylov

    monkeypatch.setenv("SWE_SPHERE_THREADS", "1")
    scene = load_scene("tc5_mountain", ne=2, np_=4, stepper="implicit")
    scene = dataclasses.replace(
        scene, dt=2.0 * scene.dt, stepper_options={"preconditioner": "none", "gmres_restart": 4}
    )
    runs = {}
    for graphs in (False, True):
        sim = make_sim(scene)
        st = sim.stepper
        st.fgmres.vectors, st.jacobian.passes = krylov.KernelVectors(st.fgmres), jacobian.KernelPasses(st.model)
        if not graphs:
            st.model.launches.guard.enabled = False  # no cycle captured: the model's solvers run plain
        jv, calls = st.jacobian_product, [0]

        def counted(w, out):
            calls[0] += 1
            jv(w, out)

        st.jacobian_product = counted
        stats = [st.step(sim.x) for _ in range(3)]
        runs[graphs] = sim.x.numpy(), [(s.rhs_evals, s.iterations) for s in stats], calls[0], st.fgmres.graph_count
    (plain, plain_stats, plain_calls, _), (graphed, graphed_stats, graphed_calls, captured) = runs[False], runs[True]
    its = sum(s[1]["gmres"] for s in plain_stats)
    print(f"\n{plain_stats}; {captured} graphs; J·v called {graphed_calls} times graphed, {plain_calls} plain", end="")
    np.testing.assert_array_equal(graphed, plain)
    assert graphed_stats == plain_stats and plain_calls == its
    assert 0 < captured and graphed_calls == 4 * captured < its  # the J·v's Python ran while capturing only
