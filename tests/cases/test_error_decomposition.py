"""The wind error split into vorticity (balanced flow) and divergence (gravity waves).

Checked on TC2 (tilted solid-body rotation: the exact divergence is zero and the
vorticity 2u0/a (sin φ cos α − cos φ cos λ sin α)) and on wind perturbations
built from the spherical harmonic Y = sin φ cos φ cos λ (degree 2, ∇²Y = −6Y/a²):
an irrotational one ∇(Aa²Y) has divergence −6AY and no vorticity, a
non-divergent one k×∇(Aa²Y) vorticity −6AY and no divergence.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import xarray as xr

from swe_sphere.cases.scoring import rotational_divergent_errors
from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene

import roundoff
from helpers import make_sim, write_tc2_scene

AMPLITUDE = 1e-6  # s⁻¹: the perturbation's wind is ~ A a ≈ 6 m/s


def tc2(ne: int):
    scene = load_scene("tc2_steady_alpha_pi4", ne=ne, np_=4, days=1.0)
    return make_sim(scene)


def exact_vorticity(sim):
    c, lat, lon = sim.case, sim.grid.lat, sim.grid.lon
    return 2 * c.u0 / c.planet.a * (np.sin(lat) * math.cos(c.alpha) - np.cos(lat) * np.cos(lon) * math.sin(c.alpha))


def harmonic_winds(sim):
    """(irrotational u, v), (non-divergent u, v) and −6AY (s⁻¹) at the nodes."""
    a, lat, lon = sim.case.planet.a, sim.grid.lat, sim.grid.lon
    A = AMPLITUDE
    grad = (-A * a * np.sin(lat) * np.sin(lon), A * a * np.cos(2 * lat) * np.cos(lon))
    rot = (-grad[1], grad[0])  # k × ∇
    return grad, rot, -6 * A * np.sin(lat) * np.cos(lat) * np.cos(lon)


def test_tc2_operators_give_the_exact_vorticity_and_zero_divergence():
    """The model's vorticity and divergence of the exact TC2 wind converge to the
    analytic values at the operators' order (np − 1 = 3) or better."""
    errs = []
    for ne in (4, 8):
        sim = tc2(ne)
        ue, ve, _ = sim.case.exact(sim.grid.lat, sim.grid.lon, 0.0)
        zeta, delta = sim.scorer.rotation_divergence(ue, ve)
        zt = exact_vorticity(sim)
        d = sim.scorer.wind_error_decomposition(ue, ve, ue, ve)
        assert d == {"l2_vorticity": 0.0, "l2_divergence": 0.0}
        errs.append(rotational_divergent_errors(sim.grid, zeta - zt, delta, zt, np.zeros_like(zt)))
    # measured: vorticity 1.23e-3 -> 1.51e-4, divergence 1.07e-3 -> 1.43e-4 (orders 3.0, 2.9)
    for k in ("l2_vorticity", "l2_divergence"):
        assert errs[0][k] < 2e-3
        assert errs[0][k] / errs[1][k] > 2**2.7


@pytest.mark.parametrize("kind", ["irrotational", "non_divergent"])
def test_pure_perturbations_split_cleanly(kind):
    """An irrotational (gravity-wave-like) wind error has l2_divergence =
    ‖6AY‖ / ‖ζT‖ and no vorticity error, a non-divergent one the reverse."""
    sim = tc2(8)
    ue, ve, _ = sim.case.exact(sim.grid.lat, sim.grid.lon, 0.0)
    grad, rot, lap = harmonic_winds(sim)
    du, dv = grad if kind == "irrotational" else rot
    d = sim.scorer.wind_error_decomposition(ue + du, ve + dv, ue, ve)
    I = sim.grid.integrate
    expected = math.sqrt(I(lap**2) / I(exact_vorticity(sim) ** 2))  # ≈ 0.125
    hit, miss = ("l2_divergence", "l2_vorticity") if kind == "irrotational" else ("l2_vorticity", "l2_divergence")
    print(kind, d, expected)
    assert d[hit] == pytest.approx(expected, rel=2e-3)
    assert d[miss] < 1e-3 * d[hit]


@pytest.mark.roundoff
def test_gravity_wave_run_keeps_zero_vorticity_error():
    """An irrotational wind over a fluid at rest, run 6 h without Coriolis and
    momentum advection (gravity waves only): ∂ζ/∂t = −curl(g∇h) vanishes for the
    model's operators too, so the run's error against its start is all divergence
    (measured: l2_vorticity 5e-14, l2_divergence 1.26 at ne4). The vorticity error is
    round-off: each RHS evaluation's gradient, its DSS and the update, three passes of
    ``roundoff.operator_roundings``."""
    base = load_scene("tc2_steady", ne=4, np_=4, days=0.25)
    scene = dataclasses.replace(
        base, terms=("continuity", "pressure_gradient"), stepper="rk4", dt=900.0, output_every_days=0.25
    )
    sim = make_sim(scene)
    grad, _, _ = harmonic_winds(sim)
    x = sim.x.numpy()
    x[0], x[1] = grad
    x[2] = 5000.0  # m, at rest: gravity waves of speed ~220 m/s
    sim.x.assign(x)
    result = sim.run(None)
    u, v, _ = sim.fields()
    d = sim.scorer.wind_error_decomposition(u, v, *grad)
    assert d["l2_divergence"] > 0.5  # the wave has moved on
    roundoff.within(
        d["l2_vorticity"], roundoff.bound(roundoff.operator_roundings(scene.np, 3) * result.rhs_evals), "l2_vorticity"
    )


def test_run_file_and_summary_carry_the_decomposition(tmp_path, capsys):
    """A TC2 run writes divergence as a field and l2_vorticity / l2_divergence as series."""
    scene = write_tc2_scene(tmp_path / "tc2.toml", ne=2, dt=3600.0, days=1.0)
    out = tmp_path / "run.nc"
    assert main(["run", str(scene), "--output", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "l2 vorticity" in text and "l2 divergence" in text
    with xr.open_dataset(out) as ds:
        assert ds.divergence.attrs["units"] == "s-1"
        assert np.all(np.isfinite(ds.divergence.values))
        # a steady solid-body rotation: the divergence is round-off plus truncation at ne2
        assert np.max(np.abs(ds.divergence.values)) < 0.05 * np.max(np.abs(ds.vorticity.values))
        assert ds.l2_vorticity.values[0] == 0.0 and ds.l2_divergence.values[0] == 0.0
        # measured at ne2 np4 ssprk3 dt 3600 s, day 1: l2_vorticity 7.1e-2 (l2_wind 1.3e-2)
        assert 0 < ds.l2_vorticity.values[-1] < 0.15 and 0 < ds.l2_divergence.values[-1] < 0.15
