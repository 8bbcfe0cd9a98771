"""The semi-implicit leapfrog stepper (``stepper = "semi_implicit"``) and its
Helmholtz solver.

Measured on Warp's CPU backend (2 busy cores):

* TC2, ne = 4, np = 4, 5 days. Explicit gravity-wave limit dt_limit = the
  Courant-1 step min Δx / max sqrt(g h) = 2856.7 s (ssprk3's own limit, by
  bisection: 0.975 and 0.905 dt_limit for alpha = 0 and pi/4). Semi-implicit,
  default options (H = initial mean depth, Robert–Asselin 0.05), over 5 days:

      dt / dt_limit   1.00   1.39   1.78   1.87   1.91   1.94   1.99   2.19
      alpha = 0 l2    1.76   1.79   1.81   1.87   2.71   4.21   12.7   979   (1e-4)
      alpha = pi/4    3.08   3.07   3.07   3.24   4.89   8.47   27.2   blow-up
      (ssprk3 at its scene step 1200 s: 1.970e-4 and 3.170e-4)

  so the largest step that stays stable is ~1.85 dt_limit (~1.9x ssprk3's
  limit); the test uses 1.78 dt_limit (85 steps of 5082 s): l2(h) ratio to the
  explicit 0.921 / 0.969. The step is limited by the explicitly leapfrogged
  advection (advective Courant number ~0.42 there, leapfrog's limit being ~0.5
  of a Courant-1 step), not by gravity waves. A deeper reference depth
  (mean_depth = 3000 m, the maximum) moves the limit to ~2.2 dt_limit
  (1.99 dt_limit: 1.750e-4, ratio 0.888).
* Mass (TC5 ne = 4, one day): 1.1e-15 at the scene step (675 s), -3.6e-16 at 3600 s.
* Helmholtz CG: "warp" (warp.optim.linear.cg) and "scipy" agree to 1.8e-16 on
  one solve and give identical states over 4 SI steps on TC5 ne = 2.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import pytest
import warp as wp

from conftest import make_sim, run, write_tc2_scene
from swe_sphere.cli import main
from swe_sphere.config import load_scene
from swe_sphere.constants import DAY
from swe_sphere.steppers.helmholtz import Helmholtz

from numpy_ops import NumpyOps

DEVICE = "cpu"
STEADY_DAYS = 5.0
SI_FACTOR = 1.78  # the SI step in units of dt_limit (largest stable: ~1.85)
UNSTABLE_FACTOR = 2.2


def at_multiple(base, stepper, factor, limit, **options):
    """``base`` with ``stepper`` at the longest step <= factor·limit dividing the run;
    one output at the end, so the step need not divide a day."""
    n = math.ceil(base.days * DAY / (factor * limit))
    return dataclasses.replace(base, stepper=stepper, dt=base.days * DAY / n, stepper_options=options,
                               output_every_days=base.days)


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# -- TC2 at the largest stable semi-implicit step ----------------------------------------


@pytest.mark.parametrize("name", ["tc2_steady", "tc2_steady_alpha_pi4"])
def test_semi_implicit_keeps_tc2_steady_at_its_largest_stable_step(name):
    """5 days at ne = 4, np = 4. dt_limit = Δx_min / max sqrt(g h), the Courant-1
    step (ssprk3 blows up there and at the SI step). SI at 1.78 dt_limit keeps
    l2(h) within 2x of ssprk3 at the scene's step; at 2.2 dt_limit it does not
    (blow-up or l2(h) > 10x), so 1.78 is near its largest stable step."""
    base = load_scene(name, ne=4, np=4, days=STEADY_DAYS)
    limit = base.dt / make_sim(base).courant()["courant_gravity"]
    explicit, _, t_exp = run(dataclasses.replace(base, output_every_days=STEADY_DAYS))
    assert explicit.blowup is None
    e = explicit.diagnostics["l2_h"]

    scene = at_multiple(base, "semi_implicit", SI_FACTOR, limit)
    si, sim, t_si = run(scene)
    assert si.blowup is None, si.blowup
    s = si.diagnostics["l2_h"]
    explicit_there, _, _ = run(at_multiple(base, "ssprk3", SI_FACTOR, limit))
    too_long, _, _ = run(at_multiple(base, "semi_implicit", UNSTABLE_FACTOR, limit))
    print(f"\n{name}: dt_limit {limit:.1f} s; ssprk3 dt {base.dt:g} s: l2(h) {e:.4e} ({t_exp:.2f} s); "
          f"SI dt {scene.dt:.1f} s = {scene.dt / limit:.3f} dt_limit, {scene.nsteps} steps: l2(h) {s:.4e}, "
          f"ratio {s / e:.3f}, l2(wind) {si.diagnostics['l2_wind']:.4e} (explicit {explicit.diagnostics['l2_wind']:.4e}), "
          f"mass change {si.diagnostics['mass_change']:.1e}, {si.iterations}, {t_si:.2f} s; "
          f"ssprk3 at that step: {explicit_there.blowup or explicit_there.diagnostics['l2_h']}; "
          f"SI at {UNSTABLE_FACTOR} dt_limit: {too_long.blowup or too_long.diagnostics['l2_h']}")
    assert scene.dt >= 1.75 * limit
    assert 0.5 * e <= s <= 2.0 * e
    assert si.diagnostics["l2_wind"] <= 2.0 * explicit.diagnostics["l2_wind"]
    assert abs(si.diagnostics["mass_change"]) < 1e-13
    assert explicit_there.blowup is not None
    assert too_long.blowup is not None or too_long.diagnostics["l2_h"] > 10 * e


def test_mean_depth_option_reaches_the_stepper():
    """TC2 (alpha = 0) at 1.99 dt_limit: with the default H (the initial mean depth,
    2363 m) the wave starts to go unstable (l2(h) 1.27e-3, 6.5x ssprk3); with
    mean_depth = 3000 m (the deepest point) it stays steady (1.750e-4)."""
    base = load_scene("tc2_steady", ne=4, np=4, days=STEADY_DAYS)
    limit = base.dt / make_sim(base).courant()["courant_gravity"]
    e = run(dataclasses.replace(base, output_every_days=STEADY_DAYS))[0].diagnostics["l2_h"]
    default, sim_d, _ = run(at_multiple(base, "semi_implicit", 2.0, limit))
    deep, sim_h, _ = run(at_multiple(base, "semi_implicit", 2.0, limit, mean_depth=3000.0))
    print(f"\nH = {sim_d.stepper.H:.1f} m: {default.blowup or default.diagnostics['l2_h']}; "
          f"H = {sim_h.stepper.H:.1f} m: {deep.blowup or deep.diagnostics['l2_h']}; ssprk3 {e:.4e}")
    h0 = make_sim(base).fields()[2]  # the initial depth
    w = sim_d.grid.spheremp
    assert sim_h.stepper.H == 3000.0
    assert sim_d.stepper.H == pytest.approx(float(w @ h0 / w.sum()), rel=1e-12)  # the initial mean depth
    assert deep.blowup is None and deep.diagnostics["l2_h"] < 2 * e
    assert default.blowup is not None or default.diagnostics["l2_h"] > 2 * e


# -- mass ---------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [None, 3600.0], ids=["scene_dt", "dt3600"])
def test_semi_implicit_conserves_mass_to_round_off(dt):
    """TC5 (with topography and hyperviscosity), ne = 4, one day."""
    scene = load_scene("tc5_mountain", ne=4, np=4, days=1.0, stepper="semi_implicit", dt=dt)
    result, sim, wall = run(scene)
    assert result.blowup is None
    changes = [h["mass_change"] for h in result.history]
    print(f"\ndt {scene.dt:g} s ({scene.nsteps} steps, gravity-wave Courant {result.courant['courant_gravity']:.2f}): "
          f"mass change {changes}, {result.iterations}, {wall:.2f} s")
    assert max(abs(c) for c in changes) < 1e-13


# -- the Helmholtz solver and its two CG backends --------------------------------------


def _helmholtz_setup(rng):
    scene = load_scene("tc5_mountain", ne=2, np=4, days=1.0, stepper="semi_implicit", dt=1800.0)
    sim = make_sim(scene)
    ops = NumpyOps(sim.grid)
    r = ops.dss(rng.standard_normal((1, sim.model.N)) * 100.0)
    c = 1800.0**2 * sim.model.g * 5000.0
    return sim, ops, r, c


def _solve(sim, backend, r, c, tol=1e-12):
    H = Helmholtz(sim.model, tol, 1000, backend)
    assert H.backend == backend
    out = wp.zeros((3, sim.model.N), dtype=wp.float64, device=DEVICE)
    iterations = H.solve(wp.array(r, dtype=wp.float64, device=DEVICE), 0, c, out, 2)
    return out.numpy()[2].copy(), iterations


@pytest.mark.parametrize("backend", ["scipy", "warp"])
def test_helmholtz_solves_its_equation_and_keeps_mass(backend, rng):
    """(I − c DG) h = r with D, G the DSS'd strong divergence and gradient (checked
    with the independent numpy operators), and ∫h = ∫r to round-off."""
    sim, ops, r, c = _helmholtz_setup(rng)
    h, iterations = _solve(sim, backend, r, c)
    G = ops.dss(ops.gradient(h))
    DG = ops.dss(ops.divergence(G[0], G[1]))
    w = sim.grid.spheremp
    resid = math.sqrt(w @ (h - c * DG - r[0]) ** 2 / (w @ r[0] ** 2))
    mass = (w @ h - w @ r[0]) / (w @ np.abs(r[0]))
    print(f"\n{backend}: {iterations} CG iterations, relative residual {resid:.2e}, mass {mass:.1e}, "
          f"|h - r| / |r| = {rel(h, r[0]):.2f}")
    assert resid < 1e-9
    assert abs(mass) < 1e-12
    assert rel(h, r[0]) > 0.1  # a real correction, not the identity


def test_helmholtz_backends_agree(rng):
    sim, _, r, c = _helmholtz_setup(rng)
    (hs, its), (hw, itw) = _solve(sim, "scipy", r, c), _solve(sim, "warp", r, c)
    print(f"\nscipy {its}, warp {itw} CG iterations; relative difference of the corrections {rel(hw - r[0], hs - r[0]):.1e}")
    assert its == itw
    assert rel(hw - r[0], hs - r[0]) < 1e-10


def test_helmholtz_warp_backend_is_scale_invariant(rng):
    """The same solve with r (~100 m) scaled by 1e-18 must give the scaled solution."""
    sim, _, r, c = _helmholtz_setup(rng)
    scale = 1e-18
    h1, it1 = _solve(sim, "warp", r, c, tol=1e-10)
    hs, its = _solve(sim, "warp", scale * r, c, tol=1e-10)
    print(f"\nwarp CG: {it1} iterations at scale 1, {its} at scale {scale:g}; "
          f"relative difference {rel(hs / scale - r[0], h1 - r[0]):.1e}")
    assert its == it1
    assert rel(hs / scale - r[0], h1 - r[0]) < 1e-12


def test_semi_implicit_linear_solver_warp_matches_scipy():
    """4 SI steps of 1800 s on TC5 at ne = 2, CG tol 1e-12: same CG counts
    (8, 13, 13, 13) and the same state (measured: identical)."""
    finals, counts = {}, {}
    for solver in ("scipy", "warp"):
        scene = load_scene("tc5_mountain", ne=2, np=4, days=1.0, stepper="semi_implicit", dt=1800.0)
        sim = make_sim(dataclasses.replace(scene, stepper_options={"linear_solver": solver, "tol": 1e-12}))
        assert sim.stepper.helmholtz.backend == solver
        t0 = time.perf_counter()
        counts[solver] = [sim.stepper.step(sim.x).iterations["cg"] for _ in range(4)]
        finals[solver] = sim.x.numpy().copy()
        print(f"\n{solver}: CG {counts[solver]}, {time.perf_counter() - t0:.2f} s", end="")
    diffs = [rel(finals["warp"][k], finals["scipy"][k]) for k in range(3)]
    print(f"\nrow-wise relative differences {diffs}")
    assert counts["warp"] == counts["scipy"]
    assert max(diffs) < 1e-8


# -- bad options ---------------------------------------------------------------------------

@pytest.mark.parametrize(
    "option, needle",
    [
        ('linear_solver = "cusparse"', "semi_implicit.linear_solver"),
        ("tol = 1.5", "semi_implicit.tol"),
        ("maxiter = 0", "semi_implicit.maxiter"),
        ("mean_depth = -1.0", "semi_implicit.mean_depth"),
        ("robert_asselin = 0.5", "semi_implicit.robert_asselin"),
        ('tol = "tight"', "semi_implicit.tol"),
        ("theta = 0.5", "semi_implicit.theta"),
    ],
)
def test_bad_semi_implicit_option_exits_2(option, needle, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "scene.toml"
    write_tc2_scene(path, stepper="semi_implicit", tables=f"[semi_implicit]\n{option}\n")
    output = tmp_path / "bad.nc"
    try:
        code = main(["run", str(path), "--device", "cpu", "--output", str(output), "--no-progress"])
    except SystemExit as exc:
        code = exc.code
    _, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    print(f"\n{option!r}: exit {code}: {err.strip()}")
    assert code == 2
    assert len(lines) == 1 and needle in lines[0]
    assert not list(tmp_path.glob("*.nc*"))
