"""The 4D-Var example from point observations (docs/examples/assimilation/plot_fourdvar_points.py,
its functions in docs/examples/assimilation/_assimilation.py): Galewsky's bump recovered from h at
points every 3 hours, on a grid small enough for the suite."""

from __future__ import annotations

import functools

import numpy as np
from gallery_helpers import assimilation


@functools.cache
def small():
    """Galewsky ne4 np4 over 6 h, 40 points every 3 h (t = 0, 3, 6 h), σ 0.1 m."""
    return assimilation().setting(4, 4, 6.0, 3.0, 40, 0.1, 0)


def test_the_setting_observes_every_three_hours_from_the_start():
    s = small()
    assert s.scene.stepper == "kgu35" and s.steps * s.scene.dt == 6 * 3600.0
    assert s.cost.at_steps == (0, s.steps // 2, s.steps) and s.every == s.steps // 2
    bump = s.truth[2] - s.guess[2]
    assert 50.0 < bump.max() <= 120.0 and np.array_equal(s.truth[:2], s.guess[:2])  # h alone differs


def test_the_unknowns_gradient_against_central_differences():
    s = small()
    G = assimilation().background_root(s.grid, 1.0e6, 10.0)
    cost, _ = assimilation().unknowns_cost(s, G)
    rng = np.random.default_rng(2)
    z, d = rng.standard_normal((2, s.grid.nunique))
    _, grad = cost(z)
    e = 1e-3  # z is O(1): truncation ~ e², round-off ~ ε J / e
    fd = (cost(z + e * d)[0] - cost(z - e * d)[0]) / (2 * e)
    assert abs(fd - grad @ d) <= 1e-7 * abs(grad @ d)  # measured 4.3e-10


def test_lbfgs_recovers_part_of_the_bump():
    r = assimilation().recover(small(), 10, 1.0e6, 10.0)
    # measured 0.855 in 10 iterations (ne4, 6 h, 40 points at 3 times: far fewer data than the example's)
    assert r.error0 == 1.0 and r.error < 0.95
    assert r.cost < 0.05 * r.cost0  # measured 0.003


def test_a_flow_following_background_keeps_its_variance_and_follows_the_heights():
    """``h_scale``: G symmetric, the mean of diag(G Gᵀ) still σ_b², and every entry the isotropic
    one's times exp(−Δh_b²/L_h²) before the normalisation (pairs across the jet's height
    contours weighed down, pairs along them kept)."""
    s = small()
    grid, h_b = s.grid, s.guess[2][s.grid.first]
    iso = assimilation().background_root(grid, 1.0e6, 3.0)
    flow = assimilation().background_root(grid, 1.0e6, 3.0, h_b, 100.0)
    assert abs(flow - flow.T).max() == 0.0 and iso.nnz == flow.nnz
    n = grid.nunique
    assert np.isclose((flow.multiply(flow)).sum() / n, 9.0, rtol=1e-12)
    rows, cols = iso.nonzero()
    factor = np.asarray(flow[rows, cols]).ravel() / np.asarray(iso[rows, cols]).ravel()
    expected = np.exp(-((h_b[rows] - h_b[cols]) ** 2) / 100.0**2)
    assert np.allclose(factor / factor.max(), expected / expected.max(), rtol=1e-12)
    assert expected.min() < 1e-3  # some pairs do straddle the jet


def test_gaspari_cohn_is_one_at_zero_continuous_and_zero_from_twice_the_half_width():
    """Eq. 4.10: 1 at d = 0, its two pieces meeting at d = c (both 5/24), zero from d = 2c on."""
    gc = assimilation().gaspari_cohn
    c = 1.0e6
    d = np.array([0.0, c * (1 - 1e-9), c * (1 + 1e-9), 2 * c * (1 - 1e-9), 2 * c, 3 * c])
    v = gc(d, c)
    assert v[0] == 1.0 and v[4] == 0.0 and v[5] == 0.0
    assert (
        abs(v[1] - v[2]) < 1e-8 and abs(v[1] - 5.0 / 24.0) < 1e-8 and abs(v[3]) < 1e-8
    )  # (2 − r)³ near 2c: round-off alone
