"""The element filter ([filter]; ``model.filter.ElementFilter``, ``grid.gll.boyd_vandeven``):
HOMME's Boyd–Vandeven transfer function, the mass and a fluid at rest kept, the highest modes
damped, the scene's table checked, and a gradient of a run with it refused."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from numpy.polynomial import legendre

from swe_sphere.adjoint import gradient
from swe_sphere.config.resolved import scene_from_dict
from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import ArgumentError, SceneError
from swe_sphere.grid.gll import boyd_vandeven, gll

import roundoff
from helpers import make_sim


def modal_factors(np_: int, mu: float, **kw) -> np.ndarray:
    """What F does to each Legendre mode: V⁻¹ F V, which must be diagonal."""
    V = legendre.legvander(gll(np_).points, np_ - 1)
    D = np.linalg.solve(V, boyd_vandeven(np_, mu, **kw) @ V)
    assert np.abs(D - np.diag(np.diag(D))).max() < 1e-12
    return np.diag(D)


def test_the_transfer_function_is_homme_bv_transfer():
    """HOMME's ``bv_transfer`` at p = 12, s = 2/3: the mode of degree k − 1 kept whole where
    k/np < s, σ = 1/2 where (k/np − s)/(1 − s) = 1/2 (the erfc's centre), 0 at the highest
    degree, the same σ at the same k/np on every np; F = (1 − μ)I + μ V σ V⁻¹."""
    f8 = modal_factors(8, 1.0)
    np.testing.assert_allclose(f8[:5], 1.0, atol=1e-13)
    assert f8[7] == pytest.approx(0.0, abs=1e-13)
    assert 0.99 < f8[5] < 1.0 and 0.05 < f8[6] < 0.2  # k/np = 3/4 and 7/8: arguments 1/4 and 5/8
    np.testing.assert_allclose(modal_factors(4, 1.0), [1.0, 1.0, f8[5], 0.0], atol=1e-13)  # k/np = 3/4 again
    assert modal_factors(6, 1.0)[4] == pytest.approx(0.5, abs=1e-13)  # k/np = 5/6: argument 1/2
    mu = 0.05
    np.testing.assert_allclose(modal_factors(8, mu), 1.0 - mu + mu * f8, atol=1e-13)
    np.testing.assert_allclose(boyd_vandeven(8, mu).sum(axis=1), 1.0, atol=1e-14)  # constants kept


def _tc5(mu=1.0, ne=2, np_=8):
    return make_sim(load_scene("tc5_mountain", ne=ne, np_=np_, days=1.0, overrides={"filter.mu": mu}))


@pytest.mark.roundoff
def test_a_fluid_at_rest_and_the_mass_are_kept(rng):
    """Over TC5's mountain (hs not smooth across the elements) a flat free surface at rest stays
    so to round-off; a rough continuous state keeps its mass to round-off over 20 applications
    while its rough part is damped at every one."""
    sim = _tc5()
    m, grid = sim.model, sim.grid
    hs = m.operators.hs.numpy()
    rest = np.stack([np.zeros(m.N), np.zeros(m.N), 5000.0 - hs])
    x = wp.array(rest, dtype=wp.float64, device="cpu")
    m.filter.apply(x)
    change = np.abs(x.numpy() - rest).max() / 5000.0
    roundoff.within(change, roundoff.bound(roundoff.operator_roundings(8, 3)), "a flat surface at rest, filtered")

    x0 = sim.x.numpy()
    noisy = x0 + np.array([[5.0], [5.0], [50.0]]) * rng.standard_normal(x0.shape)
    noisy = noisy[:, grid.first][:, grid.gid]  # continuous
    x.assign(noisy)
    spheremp = m.spheremp.numpy()[: m.N]
    mass0 = float(np.sum(spheremp * noisy[2]))
    norms = [np.linalg.norm(noisy - x0)]
    for _ in range(20):
        m.filter.apply(x)
        norms.append(np.linalg.norm(x.numpy() - x0))
    assert all(b < a for a, b in zip(norms, norms[1:]))
    # μ = 1: the noise's modes of degree 5–7 in either direction, about a third of its energy, gone (0.83)
    assert norms[-1] < 0.87 * norms[0]
    change = abs(float(np.sum(spheremp * x.numpy()[2])) / mass0 - 1.0)
    roundoff.within(change, roundoff.mass_change_bound(20 * 2, m.N), "the mass over 20 filter applications")


def test_a_smooth_state_barely_changes():
    """TC5's initial state (a smooth wind; h + hs smooth): one application at μ = 1 moves it by
    what its top modes hold, which falls as a high power of the element's size (measured 3.2e-6 and
    8.8e-8 of the state's size at ne 2 and 4, np 8: 36×, toward the 2⁶ of a degree-5 mode)."""
    changes = []
    for ne in (2, 4):
        sim = _tc5(ne=ne)
        x0 = sim.x.numpy()
        x = wp.array(x0, dtype=wp.float64, device="cpu")
        sim.model.filter.apply(x)
        free = lambda a: a + np.array([[0.0], [0.0], [1.0]]) * sim.model.operators.hs.numpy()  # noqa: E731
        changes.append(np.abs(free(x.numpy()) - free(x0)).max() / np.abs(free(x0)).max())
    assert changes[0] < 1e-5 and changes[1] < changes[0] / 25


def test_a_run_with_the_filter_keeps_its_mass():
    sim = make_sim(load_scene("galewsky", ne=2, np_=4, days=0.5, overrides={"filter.mu": 0.1}))
    result = sim.run()
    roundoff.mass_kept(result.history, sim.model.N, lambda d: roundoff.operations(d) + 2 * d["steps"])


@pytest.mark.parametrize(
    "table,needle",
    [
        ({"filter.mu": 0.0}, "filter.mu"),
        ({"filter.mu": 1.5}, "filter.mu"),
        ({"filter.p_bv": 12.0}, "filter.mu"),
        ({"filter.mu": 0.1, "filter.p_bv": -1.0}, "filter.p_bv"),
        ({"filter.mu": 0.1, "filter.s_bv": 1.0}, "filter.s_bv"),
        ({"filter.mu": 0.1, "filter.efold_hours": 4.0}, "one of filter.mu and filter.efold_hours"),
        ({"filter.efold_hours": -1.0}, "filter.efold_hours"),
        (
            {"filter.efold_hours": 4.0, "time.control": "cfl"},
            "filter.efold_hours needs a fixed dt",
        ),
    ],
)
def test_a_bad_filter_names_its_key(table, needle):
    with pytest.raises(SceneError, match=needle):
        load_scene("galewsky", ne=2, overrides=table)


def test_efold_hours_sets_mu_from_the_step():
    """mu = 1 − exp(−kΔt/τ): the highest mode e-folds in τ at any Δt and k."""
    for dt in (300.0, 600.0):
        scene = load_scene("tc5_mountain", ne=2, dt=dt, overrides={"filter.efold_hours": 4.0})
        span = scene.hypervis_every * dt
        assert scene.element_filter[0] == pytest.approx(1.0 - np.exp(-span / 14400.0), rel=1e-14)
        assert any("e-folds in 4 h" in note for note in scene.notes)


def test_the_scene_record_keeps_the_filter():
    scene = load_scene("galewsky", ne=2, overrides={"filter.mu": 0.05, "filter.s_bv": 0.75})
    assert scene.element_filter == (0.05, 12.0, 0.75)
    assert scene_from_dict(scene.as_dict()) == scene
    assert "element_filter" not in load_scene("galewsky", ne=2).as_dict()  # a record as before the key


def test_a_gradient_with_the_filter_is_refused():
    scene = load_scene("tc5_mountain", ne=2, np_=4, dt=1800.0, stepper="rk4", overrides={"filter.mu": 0.1})
    with pytest.raises(ArgumentError, match=r"\[filter\]"):
        gradient(scene, 2, lambda x: float(np.sum(x[2] ** 2)))
