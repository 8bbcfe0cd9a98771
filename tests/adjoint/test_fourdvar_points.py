"""The 4D-Var example from point observations (benchmarks/fourdvar_points.py, issue 66):
Galewsky's bump recovered from h at points every 3 hours, on a grid small enough for the suite."""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "fourdvar_points.py"


@functools.cache
def script():
    """benchmarks/fourdvar_points.py as a module (benchmarks/ is no package)."""
    spec = importlib.util.spec_from_file_location("fourdvar_points", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@functools.cache
def small():
    """Galewsky ne4 np4 over 6 h, 40 points every 3 h (t = 0, 3, 6 h), σ 0.1 m."""
    return script().setting(4, 4, 6.0, 3.0, 40, 0.1, 0)


def test_the_setting_observes_every_three_hours_from_the_start():
    s = small()
    assert s.scene.stepper == "kgu35" and s.steps * s.scene.dt == 6 * 3600.0
    assert s.cost.at_steps == (0, s.steps // 2, s.steps)
    bump = s.truth[2] - s.guess[2]
    assert 50.0 < bump.max() <= 120.0 and np.array_equal(s.truth[:2], s.guess[:2])  # h alone differs


def test_the_unknowns_gradient_against_central_differences():
    s = small()
    G = script().background_root(s.grid, 1.0e6, 10.0)
    cost, _ = script().unknowns_cost(s, G)
    rng = np.random.default_rng(2)
    z, d = rng.standard_normal((2, s.grid.nunique))
    _, grad = cost(z)
    e = 1e-3  # z is O(1): truncation ~ e², round-off ~ ε J / e
    fd = (cost(z + e * d)[0] - cost(z - e * d)[0]) / (2 * e)
    assert abs(fd - grad @ d) <= 1e-7 * abs(grad @ d)  # measured 4.3e-10


def test_lbfgs_recovers_part_of_the_bump():
    r = script().recover(small(), 10, 1.0e6, 10.0)
    # measured 0.856 in 10 iterations (ne4, 6 h, 40 points at 3 times: far fewer data than the example's)
    assert r.error0 == 1.0 and r.error < 0.95
    assert r.cost < 0.05 * r.cost0  # measured 0.003


def test_a_flow_following_background_keeps_its_variance_and_follows_the_heights():
    """``h_scale``: G symmetric, the mean of diag(G Gᵀ) still σ_b², and every entry the isotropic
    one's times exp(−Δh_b²/L_h²) before the normalisation (pairs across the jet's height
    contours weighed down, pairs along them kept)."""
    s = small()
    grid, h_b = s.grid, s.guess[2][s.grid.first]
    iso = script().background_root(grid, 1.0e6, 3.0)
    flow = script().background_root(grid, 1.0e6, 3.0, h_b, 100.0)
    assert abs(flow - flow.T).max() == 0.0 and iso.nnz == flow.nnz
    n = grid.nunique
    assert np.isclose((flow.multiply(flow)).sum() / n, 9.0, rtol=1e-12)
    rows, cols = iso.nonzero()
    factor = np.asarray(flow[rows, cols]).ravel() / np.asarray(iso[rows, cols]).ravel()
    expected = np.exp(-((h_b[rows] - h_b[cols]) ** 2) / 100.0**2)
    assert np.allclose(factor / factor.max(), expected / expected.max(), rtol=1e-12)
    assert expected.min() < 1e-3  # some pairs do straddle the jet
