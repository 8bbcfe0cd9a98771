"""The exponential steppers ``epi2``, ``epi3`` and their KIOPS φ-function evaluator.

What is checked, and what was measured on Warp's CPU backend:

* KIOPS against dense φ-functions: scipy's ``expm_multiply`` (φ₀) and the
  exponential of the augmented matrix (φ₁, φ₂ together), on a random matrix
  (n = 300; with and without substeps) and on the model's Jacobian at ne = 2
  (TC5, Δt = 14400 s, about 6 Δt_g), assembled by central differences (exact: F
  is quadratic): within tol; with the steppers' forward-difference J·v, 2e-7–6e-7
  relative.
* Temporal order on TC5 and TC2 (ne = 4, np = 4, no hyperviscosity, 0.25 day)
  against rk4 with 2048 steps, tol 1e-10: 16 -> 32 steps, epi2 TC5
  6.488e-7 -> 1.645e-7 (rate 1.98), TC2 5.344e-10 -> 1.350e-10 (1.99); epi3 TC5
  3.992e-7 -> 5.117e-8 (2.96), TC2 2.228e-10 -> 2.854e-11 (2.96). (TC6: epi2
  1.99, epi3 2.98 at 32 -> 64; TC4, with its time-dependent forcing, in
  test_forcing.py: without ∂F/∂t in the step both ran at order 1.0 there.)
* Mass to round-off at 5 Δt_g with hyperviscosity; bad options exit 2 with one
  line; ``swe-sphere list`` names them. Bitwise restarts and the MPI runs are
  in test_steppers.py / test_restart.py / test_mpi.py (every registered stepper).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sl
import warp as wp
from scipy.sparse.linalg import expm_multiply

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.grid.topology import Topology
from swe_sphere.solvers.kiops import Kiops

import roundoff
from helpers import cached_grid, cli_main, cli_one_line, make_sim, run, tc6_error, write_tc2_scene


def dense_phi(A: np.ndarray, tau: float, u: list[np.ndarray]) -> np.ndarray:
    """Σ_k τ^k φ_k(τA) u_k from the exponential of the augmented matrix [[A, W], [0, J]]
    (Al-Mohy & Higham 2011, Thm 2.1), dense."""
    n, p = A.shape[0], len(u) - 1
    M = np.zeros((n + p, n + p))
    M[:n, :n] = A
    for k in range(1, p + 1):
        M[:n, n + p - k] = u[k]
    for q in range(p - 1):
        M[n + q, n + q + 1] = 1.0
    start = np.concatenate([u[0], np.zeros(p)])
    if p:
        start[-1] = 1.0
    return (sl.expm(tau * M) @ start)[:n]


def kiops_apply(A, u, tau, tol, m_max=64, m_min=10):
    """Kiops on the numpy matrix A: (w, KiopsStats)."""
    n, p = A.shape[0], len(u) - 1
    one_process = Topology(cached_grid(2, 4))  # Kiops takes its device, threads and reductions
    k = Kiops(n, p, m_max, one_process)
    ws = [wp.array(v, dtype=wp.float64) for v in u]
    out = wp.zeros(n, dtype=wp.float64)

    def matvec(v, o):
        o.assign(A @ v.numpy())

    stats = k.apply(matvec, ws[0], ws[1:], out, tau, tol, m_min, m_min)
    return out.numpy().copy(), stats


@pytest.mark.parametrize("p", [0, 1, 2])
@pytest.mark.parametrize("tau, m_max", [(1.0, 64), (3.0, 64), (1.0, 8)], ids=["tau1", "tau3", "substeps"])
def test_kiops_matches_dense_phi_functions(p, tau, m_max, rng):
    """A random nonsymmetric matrix (n = 300, spectrum in a disc of radius 3 about −2):
    KIOPS's w = Σ τ^k φ_k(τA) u_k against the dense augmented exponential (and, for
    φ₀, scipy's ``expm_multiply``), within tol = 1e-9; m_max = 8 forces substeps."""
    n, tol = 300, 1e-9
    A = rng.standard_normal((n, n)) * 3 / math.sqrt(n) - 2 * np.eye(n)
    u = [rng.standard_normal(n) for _ in range(p + 1)]
    w, stats = kiops_apply(A, u, tau, tol, m_max)
    ref = dense_phi(A, tau, u)
    err = np.linalg.norm(w - ref)
    print(f"\np={p} tau={tau} m_max={m_max}: |w - dense| {err:.2e} (estimate {stats.error:.2e}), {stats}")
    assert err <= tol
    if p == 0:
        assert np.linalg.norm(w - expm_multiply(tau * A, u[0])) <= tol
    if m_max == 8:
        assert stats.substeps > 1
    else:
        assert stats.substeps >= 1 and stats.m <= m_max


def test_kiops_on_the_model_jacobian(rng):
    """TC5 at ne = 2, A = ΔtJ, Δt = 14400 s (about 6 Δt_g), J assembled by central
    differences (exact to round-off: F is quadratic in the state): φ₀ against
    ``expm_multiply``, φ₁ + φ₂ against the dense augmented exponential. With the dense
    J·v within tol; with the epi2 stepper's own J·v (forward differences) within
    1e-5 relative (measured 6.4e-7 and 2.3e-7: ~1e-8 of each J·v, through ΔtJ)."""
    scene = load_scene("tc5_mountain", ne=2, np_=4, days=1.0, stepper="epi2", dt=14400.0)
    sim = make_sim(scene)
    st, m, grid = sim.stepper, sim.model, sim.grid
    nu, n = grid.nunique, 3 * grid.nunique
    x0 = sim.x.numpy().copy()
    xa, fa = wp.zeros_like(sim.x), wp.zeros_like(sim.x)

    def F(u):  # F at x0 + the unique-node vector u, on unique nodes
        xa.assign(x0 + u.reshape(3, nu)[:, grid.gid])
        m.rhs(xa, fa)
        return fa.numpy()[:, grid.first].ravel().copy()

    J = np.stack([(F(e) - F(-e)) / 2 for e in np.eye(n)], axis=1)  # central differences, steps of 1 m/s or 1 m: exact
    A = scene.dt * J
    # the stepper's J·v about x0
    st.rhs_evals = 0
    m.set_time(0.0)  # the step's t(n)
    m.rhs(sim.x, st.Fx)
    xu = wp.array(x0[:, grid.first].ravel(), dtype=wp.float64)
    xnorm = st.jacobian.point_norm(xu)

    def matvec(v, out):
        st.jacobian.apply(sim.x, st.Fx, xnorm, v, out, 0.0, scene.dt)

    F0 = F(np.zeros(n))
    u = [F0 * 1e3, F0 * 1e3, rng.standard_normal(n) * np.abs(F0).max() * 1e3]  # ~ m, m/s: a step's size
    tol = 1e-7 * np.linalg.norm(u[1])
    for k, ref in ((0, expm_multiply(A, u[0])), (2, dense_phi(A, 1.0, u) - expm_multiply(A, u[0]))):
        for name, product in (("exact", lambda v, out: out.assign(A @ v.numpy())), ("forward-difference", matvec)):
            kiops = Kiops(n, k, 64, m.topology)
            ws = [wp.array(v, dtype=wp.float64) for v in u[: k + 1]]
            out = wp.zeros(n, dtype=wp.float64)
            stats = kiops.apply(product, ws[0] if k == 0 else None, ws[1:], out, 1.0, tol, 10, 10)  # φ₁, φ₂ without φ₀
            err = np.linalg.norm(out.numpy() - ref)
            print(
                f"\nphi_0..phi_{k}, {name} J·v: error {err / tol:.2f} tol, {err / np.linalg.norm(ref):.1e} relative, {stats}"
            )
            assert stats.krylov > 10  # ΔtJ is not small: a real Krylov space
            if name == "exact":
                assert err <= 1.4 * tol  # KIOPS accepts an estimate up to 1.4 tol
            else:  # the forward differences' 1e-8 of each J·v, through ‖ΔtJ‖ ~ 10
                assert err <= 1e-5 * np.linalg.norm(ref)


# -- temporal order --------------------------------------------------------------------

ORDER_DAYS = 0.25
ORDER_REF_STEPS = 2048  # rk4, dt = 10.5 s


@pytest.mark.parametrize("case, nsteps", [("tc5_mountain", 16), ("tc2_steady", 16)])
@pytest.mark.parametrize("stepper, lo, hi", [("epi2", 1.8, 2.2), ("epi3", 2.8, 3.2)])
def test_temporal_order(stepper, lo, hi, case, nsteps):
    options = (("tol", 1e-10),)
    coarse, rc, _ = tc6_error(ORDER_DAYS, ORDER_REF_STEPS, stepper, nsteps, options, case)
    fine, rf, _ = tc6_error(ORDER_DAYS, ORDER_REF_STEPS, stepper, 2 * nsteps, options, case)
    rate = math.log2(coarse / fine)
    print(
        f"\n{case} {stepper}: {nsteps} -> {2 * nsteps} steps: {coarse:.3e} -> {fine:.3e}, rate {rate:.3f}; {rc.iterations} / {rf.iterations}"
    )
    assert lo <= rate <= hi
    assert fine > 1e-11  # well above the rk4 reference's own error


def test_epi3_beats_epi2_at_the_same_step():
    options = (("tol", 1e-10),)
    e2 = tc6_error(ORDER_DAYS, ORDER_REF_STEPS, "epi2", 32, options, "tc5_mountain")[0]
    e3 = tc6_error(ORDER_DAYS, ORDER_REF_STEPS, "epi3", 32, options, "tc5_mountain")[0]
    assert e3 < e2 / 2


# -- mass, reports, options ---------------------------------------------------------------

EXPONENTIAL_UPDATES = 4  # updates of the depth an epi step makes once its increment's mass is zeroed: ≤ 4 ε of the mass


@pytest.mark.roundoff
@pytest.mark.parametrize("stepper", ["epi2", "epi3"])
def test_mass_to_round_off_at_five_times_the_gravity_wave_limit(stepper):
    """TC5 with hyperviscosity, ne = 4, one day in 8 steps of 10800 s (about 5 Δt_g).
    Without setting the increment's mass to zero the forward differences' round-off
    drifted by −3.3e-13 (ne 8, 10 Δt_g, 9 steps); measured here −1.8e-16. Bound: the
    increment's mass is zeroed, so only adding it rounds, a few ε a step
    (``EXPONENTIAL_UPDATES``), not an ε per Krylov vector."""
    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper=stepper, dt=10800.0)
    result, _, _ = run(scene)
    assert result.blowup is None
    changes = [h["mass_change"] for h in result.history]
    print(f"\n{stepper}: mass change {changes}, {result.iterations}, {result.rhs_evals} RHS")
    roundoff.mass_kept(result.history, cached_grid(4, 4).nnodes, lambda d: EXPONENTIAL_UPDATES * d["steps"])
    it = result.iterations
    assert it["substeps"] >= 8 and it["krylov"] >= 8 * 10
    # F(x(n)) and a J·v per Krylov vector but the first (of the zero vector); epi3's J (x(n−1) − x(n))
    assert result.rhs_evals == it["krylov"] + (7 if stepper == "epi3" else 0)


def test_list_shows_the_exponential_steppers(capsys):
    code, out, _ = cli_main(capsys, "list")
    assert code == 0
    lines = {line.split()[0]: line for line in out.splitlines() if line.startswith("  epi")}
    assert set(lines) == {"epi2", "epi3"}
    assert "Exponential Rosenbrock–Euler" in lines["epi2"] and "EPI3" in lines["epi3"]


@pytest.mark.parametrize(
    "table, needle",
    [
        ("tol = 0.0", "epi3.tol must be in (0, 1)"),
        ("tol = 2.0", "epi3.tol"),
        ("m_min = 2", "epi3.m_min must be >= 3"),
        ("m_min = 20\nm_max = 10", "epi3.m_max must be >= m_min = 20"),
        ("m_max = 1000", "epi3.m_max must be <= 256"),
        ("iop = 0", "epi3.iop must be >= 1"),
        ('m_max = "big"', "epi3.m_max"),
        ("krylov = 30", "epi3.krylov"),
    ],
)
def test_bad_option_exits_2(table, needle, tmp_path, capsys):
    path = write_tc2_scene(tmp_path / "bad.toml", stepper="epi3", tables="[epi3]\n" + table + "\n")
    output = tmp_path / "bad.nc"
    cli_one_line(capsys, ["run", path, "--device", "cpu", "--output", output, "--no-progress"], 2, needle)
    assert not output.exists()


def test_a_state_with_no_tendency_costs_one_rhs():
    """F = 0 exactly (a flat sea at rest is not: the SE gradient of a constant is
    round-off, so the zero state, on TC2's terms without topography): one F, no
    Krylov vector, nothing moves."""
    scene = load_scene("tc2_steady", ne=2, np_=4, days=2 * 3600.0 / DAY, stepper="epi2", dt=3600.0)
    sim = make_sim(scene)
    x = np.zeros((3, sim.model.N))
    sim.x.assign(x)
    stats = sim.stepper.step(sim.x)
    assert stats.rhs_evals == 1 and stats.iterations == {"krylov": 0, "substeps": 0, "rejected": 0}
    np.testing.assert_array_equal(sim.x.numpy(), x)


def test_kiops_that_cannot_converge_fails_the_step(tmp_path, capsys):
    """A Krylov space of 3 at 6 h steps: KIOPS's substeps shrink until it gives up
    (``MAX_SUBSTEPS``): a step failure, exit 3, one line naming KIOPS."""
    path = write_tc2_scene(
        tmp_path / "small.toml", stepper="epi2", dt=21600.0, days=0.25, tables="[epi2]\nm_min = 3\nm_max = 3\n"
    )
    cli_one_line(
        capsys,
        ["run", path, "--device", "cpu", "--output", tmp_path / "small.nc", "--no-progress"],
        3,
        "KIOPS did not reach tol",
    )
