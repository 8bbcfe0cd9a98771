"""Hyperviscosity over long steps: RKL1 super-time-stepping (``hypervis.Hyperviscosity.apply``).

Measured (TC5, hyperviscosity alone over T = 45 forward-Euler limits, ne = 4):
RKL1 with s = 6 stages and k = 16 … 128 steps against k = 1024: error ratios
2.06, 2.05, 2.08, 2.15 (first order). At ne = 16 one call over 30 dt_g
(gravity-wave limit) takes 9 ∇⁴ evaluations instead of 45 forward-Euler
substeps. RKL2 (second order: ratios 4.12, 4.10 with s = 6) was tried first:
it damps stiff modes only by ≈ 1/2 a step and IMEX ARS(2,3,2) at 12 dt_g on
TC5 ne = 8 blew up with it on day 4 (stable with forward Euler and with RKL1:
l2(h+hs) 9.51e-4 and 9.55e-4).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene

import roundoff
from helpers import make_sim


def _tc5(ne=4):
    sim = make_sim(load_scene("tc5_mountain", ne=ne, np_=4, days=1.0))
    m = sim.model
    dt_fe = 1.5 / (m.hv.nu_max * m.hv.biharmonic_radius())  # the forward-Euler limit used for substeps
    return sim, m, dt_fe


def test_rkl1_is_first_order():
    sim, m, dt_fe = _tc5()
    x0 = sim.x.numpy().copy()
    x = wp.array(x0, dtype=wp.float64, device="cpu")
    T = 45 * dt_fe

    def run(k, s=6):
        x.assign(x0)
        for _ in range(k):
            m.hv.rkl1(x, T / k, s)
        return x.numpy().copy()

    ref = run(1024)
    errors = [np.linalg.norm(run(k) - ref) / np.linalg.norm(ref - x0) for k in (16, 32, 64)]
    ratios = [errors[i] / errors[i + 1] for i in range(2)]
    print(f"\nRKL1 s = 6, k = 16/32/64 steps: errors {errors}, ratios {ratios}")
    assert all(1.8 <= r <= 2.3 for r in ratios)


@pytest.mark.roundoff
def test_long_steps_use_rkl1_stably_and_conservatively(rng):
    """At Δt = 45 forward-Euler limits: 9 RKL1 stages instead of 46 substeps;
    close to the finely subcycled result; repeated calls on a rough field
    decay a random perturbation monotonically and keep the mass to round-off. At the scene's
    own step the forward-Euler path (and so every explicit result) is unchanged."""
    sim, m, dt_fe = _tc5()
    T = 45 * dt_fe
    assert m.hv.substeps(T) in (45, 46) and m.hv.stages(T) == 9  # ceil(45 · (1 ± round-off))
    n, s = m.hv.substeps(sim.scene.dt), m.hv.stages(sim.scene.dt)
    assert n <= s  # forward Euler at the scene's step (RKL1 would take as many evaluations or more)

    x0 = sim.x.numpy().copy()
    x = wp.array(x0, dtype=wp.float64, device="cpu")
    m.hyperviscosity(x, T)
    rkl = x.numpy().copy()
    x.assign(x0)
    coef = -T / 720  # hv.build applies coef·B x, B including ν
    for _ in range(720):
        m.launches.replay(("hv", x.ptr, coef), (x,), lambda: m.hv.build(x, coef))
    fine = x.numpy()
    distance = np.linalg.norm(rkl - fine) / np.linalg.norm(fine - x0)
    print(f"\nRKL1 (9 stages) against 720 forward-Euler substeps: {distance:.2e} of the change")
    assert distance < 0.05

    noisy = x0 + np.array([[5.0], [5.0], [50.0]]) * rng.standard_normal(x0.shape)
    noisy = noisy[:, sim.grid.first][:, sim.grid.gid]  # continuous
    clean = wp.array(x0, dtype=wp.float64, device="cpu")
    x.assign(noisy)
    norms = [np.linalg.norm(noisy - x0)]  # the noise, which evolves under the linear ∇⁴ alone
    for _ in range(10):
        m.hyperviscosity(x, T)
        m.hyperviscosity(clean, T)
        norms.append(np.linalg.norm(x.numpy() - clean.numpy()))
    I = sim.grid.integrate
    mass = (I(x.numpy()[2]) - I(noisy[2])) / I(noisy[2])
    print(f"noise norm {' '.join(f'{n:.3e}' for n in norms)}, mass change {mass:.1e}")
    assert all(b < a for a, b in zip(norms, norms[1:]))
    assert norms[-1] < 0.5 * norms[0]  # measured 0.28 (the low modes of the noise decay slowly, as they should)
    # each RKL1 stage y_j = μ_j y_{j−1} + ν_j y_{j−2} + μ̃_j τ L y_{j−1} (|μ_j| + |ν_j| < 3) rounds a node by ≤ 3 ε |h|
    roundoff.within(abs(mass), roundoff.mass_change_bound(10 * m.hv.stages(T) * 3, sim.grid.nnodes), "|mass change|")


def _integral(grid, row) -> float:
    """∫ row dA (``CubedSphere.integrate``) with the products spheremp·row summed exactly
    (``math.fsum``): only their own roundings, unbiased and independent, stay in a mass change
    (numpy's pairwise sum of the N products may round a whole integral by up to log₂N ε)."""
    return math.fsum(grid.spheremp * row)


@pytest.mark.roundoff
@pytest.mark.parametrize("limiter", ["none", "optimization"])
def test_rkl1_stages_keep_the_mass_without_a_bias(limiter):
    """Galewsky's jet with a latitude marker and q = 1 (ne4 np4), 50 RKL1 steps of 4 stages on
    its state: each stage rounds every node's h and hq by ≤ ε/2 of its size, unbiased, so the
    change of ∫h and ∫hq over K = 200 stage updates, relative to ∫|h|, ∫|hq|, is a random walk
    far inside √K·ε (its standard deviation about ε√K / √(12 N), N nodes).
    Formed as μ·t + ν·Y_{j−2} (fl(5/3) + fl(−2/3) ≠ 1, h·μ and h·ν rounding alike at nearly every
    node) h's mass rose by a steady ≈ 2.5e-16 an application: 1.22e-14 here (55 ε, 3.9x the
    bound); as t + ν·(Y_{j−2} − t) h, the marker, q = 1 measured 0, 1.2e-16, 0.
    With the limiter, its bounds taken from each application's start as a step takes them (q = 1
    on its bounds in every element), the same bound holds: measured h 0, the marker −0.7 ε, q = 1
    −0.9 ε (−1.8 ε after 200 applications). It failed before: q = 1 lost a steady 0.07 ε a stage
    (−15.4 ε here, −54 ε after 200), the mass-weighted DSS of the limited stage's whole values
    (rspheremp = fl(1/M) rounds each node's assembled value alike at every DSS: −0.035 ε a DSS
    here), now of their change from the stage's assembled part alone (``TracerLimiter.stage``).
    Against zero bounds (every element infeasible, its mean kept) the test measured 9.3e-16,
    8.0e-16 before."""
    scene = load_scene("galewsky_marker", ne=4, np_=4, days=1.0, tracers={"limiter": limiter})
    sim = make_sim(scene)
    m, grid = sim.model, sim.grid
    x = wp.array(sim.x.numpy(), dtype=wp.float64, device="cpu")
    x0 = x.numpy().copy()
    dt_fe = 1.5 / (m.hv.nu_max * m.hv.biharmonic_radius())
    applications, stages = 50, 4
    for _ in range(applications):
        if (
            m.limiter is not None
        ):  # each application's bounds from its start, as a step takes them (``RungeKutta.advance``)
            m.limiter.bound(x)
        m.hv.rkl1(x, 10 * dt_fe, stages, tracers=True)  # ν dt λ = 15 of the 20 four stages allow
    updates = applications * stages
    limit = roundoff.bound(math.sqrt(updates))
    names = ["h", *(name for name, _ in scene.tracers)]
    for name, a, b in zip(names, x0[2:], x.numpy()[2:]):
        change = abs(_integral(grid, b) - _integral(grid, a)) / _integral(grid, np.abs(a))
        roundoff.within(change, limit, f"{name}'s mass change")
