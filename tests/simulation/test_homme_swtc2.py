"""TC2 in HOMME's own regression setup (``test/reg_test/namelists/swtc2.nl``) on E3SM's
``mountain_10_x2.g``: swe_sphere's day-1 errors of h are HOMME's ``sweqx``'s (skipped where the
mesh is not beside the checkout; ``benchmarks/peers/peer_homme_rrm.py`` runs both codes)."""

from __future__ import annotations

import json
import math

import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.simulation.simulation import Simulation

import roundoff
from meshes import MOUNTAIN

HOMME_RADIUS = 6.376e6  # m: HOMME's rearth
HOMME_NU, SCALING = 1e-9, 3.2  # swtc2.nl: nu = nu_s (nu_div = nu), hypervis_scaling
HOMME_ERRORS = {  # np: HOMME's day-1 normalized (l1, l2, l∞) of h on mountain_10_x2.g
    4: (4.327139e-6, 5.888612e-6, 4.041528e-5),  # sweqx NP 4 (E3SM 75e17cce, the HOMME kit's build)
    8: (1.05e-7, 1.26e-7, 3.30e-7),  # E3SM's swtc2 regression baseline (NP 8), three digits
}


@pytest.mark.slow
@pytest.mark.roundoff
@pytest.mark.parametrize("np_", sorted(HOMME_ERRORS))
def test_tc2_in_homme_s_swtc2_setup_gives_homme_s_errors(np_, tmp_path):
    """Leapfrog-trapezoidal at 90 s for 1 day, tensor ∇⁴ with s = 3.2 and HOMME's nu = 1e-9
    (1/s) as ν = nu·a⁴·(π / (4 √(F/6)))^s (m⁴/s; F = 780 elements), subcycled twice, on
    HOMME's Earth (a = 6.376e6 m): l1, l2 and l∞ of h within 1 % of HOMME's (measured within
    0.05 % (l1, l2) and 0.5 % (l∞) at np 4, within the baseline's three digits at np 8),
    mass to round-off, and the run's note gives HOMME's nu back. The mesh, np and radius are
    the scene file's own, for which its ν and Δt are taken as given (any other grid rescales them)."""
    if not MOUNTAIN.is_file():
        pytest.skip(f"{MOUNTAIN} is not beside the checkout")
    nu = HOMME_NU * HOMME_RADIUS**4 * (math.pi / (4 * math.sqrt(780 / 6))) ** SCALING
    terms = '["continuity", "momentum_advection", "coriolis", "pressure_gradient", "hyperviscosity"]'
    path = tmp_path / "swtc2.toml"
    path.write_text(
        f'terms = {terms}\n[case]\nname = "tc2_steady"\n'
        f"[grid]\nne = 0\nmesh_file = {json.dumps(str(MOUNTAIN))}\nnp = {np_}\n"
        f"[planet]\nradius = {HOMME_RADIUS!r}\n"
        '[time]\nstepper = "leapfrog_trapezoidal"\ndt = 90.0\ndays = 1.0\n'
        f"[hyperviscosity]\nnu = {nu!r}\nscaling = {SCALING!r}\nsubcycle = 2\n"
    )
    scene = load_scene(path)
    assert (scene.dt, scene.nu, scene.nu_div, scene.nu_s) == (90.0, nu, nu, nu)
    assert any(f"hypervis_scaling = {SCALING:g}, nu = {HOMME_NU:g})" in note for note in scene.notes), scene.notes
    sim = Simulation(scene, "cpu", progress=False)
    result = sim.run(None)
    ours = [result.diagnostics[key] for key in ("l1_h", "l2_h", "linf_h")]
    assert ours == pytest.approx(HOMME_ERRORS[np_], rel=0.01), (ours, HOMME_ERRORS[np_])
    roundoff.mass_kept(result.history, sim.grid.nnodes)
