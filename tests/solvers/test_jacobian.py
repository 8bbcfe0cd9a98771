"""The finite-difference Jacobian-vector product (``solvers.jacobian``, the implicit stepper's
``jacobian_product``) against the exact directional derivative (ne = 2): F is quadratic in the
state, so a central difference is exact up to round-off for any step; forward difference error
1.4e-8 relative. Its two backends of the pointwise passes agree."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene

from helpers import make_sim
from numpy_ops import NumpyOps

DEVICE = "cpu"


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.parametrize("name", ["tc5_mountain", "tc6_rossby_haurwitz", "tc2_steady_alpha_pi4"])
def test_jacobian_vector_product_matches_exact_directional_derivative(name, rng):
    """ne = 2. ``Implicit.jacobian_product`` (forward difference, ε = sqrt(ε_mach)(1 + ‖x‖)/‖v‖,
    on unique-node vectors) against the exact directional derivative. Every term of F is at most quadratic
    in the state (h v, ζ v, |v|², linear Coriolis and pressure gradient, constant
    topography; the DSS is linear), so the central difference
    (F(x + s v) − F(x − s v)) / 2s is exact up to round-off for any s: that is
    checked first (s = 1 against s = 1e-3, and the second difference scales as s²).
    Direction: random, DSS'd to be continuous, wind ~10 m/s and depth ~100 m.
    Measured: 1.37e-8 (TC5), 1.37e-8 (TC6), 1.36e-8 (TC2) relative."""
    scene = load_scene(name, ne=2, np_=4, days=1.0, stepper="implicit", dt=3600.0)
    sim = make_sim(scene)
    st, m = sim.stepper, sim.model
    x0 = sim.x.numpy().copy()
    ops = NumpyOps(sim.grid)
    v = ops.dss(rng.standard_normal((3, m.N)) * np.array([[10.0], [10.0], [100.0]]))

    xa = wp.zeros((3, m.N), dtype=wp.float64, device=DEVICE)
    fa = wp.zeros_like(xa)

    def F(a):
        xa.assign(a)
        m.rhs(xa, fa)
        return fa.numpy().copy()

    F0 = F(x0)
    exact = (F(x0 + v) - F(x0 - v)) / 2
    small = (F(x0 + 1e-3 * v) - F(x0 - 1e-3 * v)) / 2e-3
    second1 = F(x0 + v) + F(x0 - v) - 2 * F0
    second2 = (F(x0 + 2 * v) + F(x0 - 2 * v) - 2 * F0) / 4
    assert rel(small, exact) < 1e-9
    assert rel(second2, second1) < 1e-10

    # the stepper's state for a θ = 0.5 step at x0 (as its Newton iteration sets it up)
    st.rhs_evals, st.beta, st.x = 0, 0.5, sim.x
    st.xnorm = np.linalg.norm(x0[:, sim.grid.first])
    m.rhs(sim.x, st.Fx)
    # Krylov vectors are on unique nodes: row r of node g at r·nunique + g
    unique = lambda a: a[:, sim.grid.first].ravel()  # noqa: E731
    vu = unique(v)
    vw = wp.array(vu, dtype=wp.float64, device=DEVICE)
    out = wp.zeros_like(vw)
    evals, F = [0], st.jacobian.F
    st.jacobian.F = lambda *a: (evals.__setitem__(0, evals[0] + 1), F(*a))
    st.jacobian_product(vw, out)
    assert evals[0] == 1  # one F evaluation per product
    Jv = out.numpy().copy()  # numpy() is a view of the Warp array on the CPU
    JF = (vu / st.dt - Jv) / st.beta  # the F'(x) v inside it
    err_F = rel(JF, unique(exact))
    err_J = rel(Jv, vu / st.dt - st.beta * unique(exact))
    print(
        f"\n{name}: |F'v - central| / |central| = {err_F:.3e}; whole J v: {err_J:.3e}; "
        f"central s = 1e-3 vs 1: {rel(small, exact):.1e}; x unchanged: {np.array_equal(sim.x.numpy(), x0)}"
    )
    assert err_F < 1e-6
    assert err_J < 1e-6
    np.testing.assert_array_equal(sim.x.numpy(), x0)  # J v leaves the iterate alone
    # linear in v (to the difference's accuracy), and zero for v = 0
    st.jacobian_product(wp.array(-3.0 * vu, dtype=wp.float64, device=DEVICE), out)
    assert rel(out.numpy(), -3.0 * Jv) < 1e-6
    st.jacobian_product(wp.zeros_like(vw), out)
    assert not np.any(out.numpy())


def test_jacobian_passes_host_and_kernels_agree(rng):
    """``jacobian.FiniteDifferenceJacobian``'s two backends of its pointwise passes
    (``HostPasses``, numpy, the CPU's; ``KernelPasses``, Warp kernels, CUDA's) on TC5 at
    ne = 2: the gather, the scatter and shift·w + scale·J w give the same numbers to
    round-off (measured: the gather and scatter the same bits, J·v 2.5e-17 apart: ε's
    norms are summed in another order, KernelPasses' on the device); J·0 = 0."""
    from swe_sphere.solvers.jacobian import FiniteDifferenceJacobian, HostPasses, KernelPasses

    sim = make_sim(load_scene("tc5_mountain", ne=2, np_=4, days=1.0, stepper="implicit", dt=3600.0))
    m, first = sim.model, sim.grid.first
    Fx = wp.zeros_like(sim.x)
    m.rhs(sim.x, Fx)
    x_np = sim.x.numpy()
    w = wp.array(rng.standard_normal(3 * first.size) * 10.0, dtype=wp.float64, device=DEVICE)
    got = {}
    for passes in (HostPasses, KernelPasses):
        jac = FiniteDifferenceJacobian(m, m.rhs, passes)
        u, xu, e, jv = wp.zeros_like(w), wp.zeros_like(w), wp.zeros_like(sim.x), wp.zeros_like(w)
        jac.gather(-2.0, sim.x, u)
        jac.gather(1.0, sim.x, xu)
        jac.scatter(w, e)
        xnorm = jac.point_norm(xu)  # KernelPasses: a device array
        jac.apply(sim.x, Fx, xnorm, w, jv, 0.25, -0.5)
        got[passes] = [a.numpy().copy() for a in (u, e, jv)]
        jac.apply(sim.x, Fx, xnorm, wp.zeros_like(w), jv, 0.25, -0.5)
        assert not np.any(jv.numpy())  # w = 0: J w = 0 (KernelPasses: ε = 0 on the device)
    for name, a, b in zip(("gather", "scatter", "J·v"), got[HostPasses], got[KernelPasses]):
        print(
            f"\n{name}: bitwise {np.array_equal(a, b)}, max |host - kernels| / max |kernels| {np.abs(a - b).max() / np.abs(b).max():.1e}",
            end="",
        )
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-14 * np.abs(b).max())
    np.testing.assert_array_equal(got[HostPasses][0], -2.0 * x_np[:, first].ravel())  # the unique-node layout
    np.testing.assert_array_equal(
        got[HostPasses][1], w.numpy().reshape(3, -1)[:, sim.grid.gid]
    )  # one process: index = gid
