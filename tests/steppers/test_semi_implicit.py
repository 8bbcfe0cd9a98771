"""The semi-implicit leapfrog stepper (``stepper = "semi_implicit"``) and its
Helmholtz solves in a step (the solver's own tests: tests/solvers/test_helmholtz.py).

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
* The Helmholtz solves of a semi-implicit and an IMEX step: one host read a step, captured
  as graphs at the same calls in either layout, the same bits as host loops.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import re

import numpy as np
import pytest

from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.core.backend import Backend
from swe_sphere.core.constants import DAY
from swe_sphere.model.gravity_wave import reference_depth
from swe_sphere.model.helmholtz import HelmholtzOptions
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS

import roundoff
from helpers import make_sim, requires_cuda, run, write_tc2_scene

DEVICE = "cpu"
STEADY_DAYS = 5.0
SI_FACTOR = 1.78  # the SI step in units of dt_limit (largest stable: ~1.85)
UNSTABLE_FACTOR = 2.2


def at_multiple(base, stepper, factor, limit, **options):
    """``base`` with ``stepper`` at the longest step <= factor·limit dividing the run;
    one output at the end, so the step need not divide a day."""
    n = math.ceil(base.days * DAY / (factor * limit))
    return dataclasses.replace(
        base, stepper=stepper, dt=base.days * DAY / n, stepper_options=options, output_every_days=base.days
    )


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# -- TC2 at the largest stable semi-implicit step ----------------------------------------


@pytest.mark.parametrize("name", ["tc2_steady", "tc2_steady_alpha_pi4"])
def test_semi_implicit_keeps_tc2_steady_at_its_largest_stable_step(name):
    """5 days at ne = 4, np = 4. dt_limit = Δx_min / max sqrt(g h), the Courant-1
    step (ssprk3 blows up there and at the SI step). SI at 1.78 dt_limit keeps
    l2(h) within 2x of ssprk3 at the scene's step; at 2.2 dt_limit it does not
    (blow-up or l2(h) > 10x), so 1.78 is near its largest stable step."""
    base = load_scene(name, ne=4, np_=4, days=STEADY_DAYS)
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
    print(
        f"\n{name}: dt_limit {limit:.1f} s; ssprk3 dt {base.dt:g} s: l2(h) {e:.4e} ({t_exp:.2f} s); "
        f"SI dt {scene.dt:.1f} s = {scene.dt / limit:.3f} dt_limit, {scene.nsteps} steps: l2(h) {s:.4e}, "
        f"ratio {s / e:.3f}, l2(wind) {si.diagnostics['l2_wind']:.4e} (explicit {explicit.diagnostics['l2_wind']:.4e}), "
        f"mass change {si.diagnostics['mass_change']:.1e}, {si.iterations}, {t_si:.2f} s; "
        f"ssprk3 at that step: {explicit_there.blowup or explicit_there.diagnostics['l2_h']}; "
        f"SI at {UNSTABLE_FACTOR} dt_limit: {too_long.blowup or too_long.diagnostics['l2_h']}"
    )
    assert scene.dt >= 1.75 * limit
    assert 0.5 * e <= s <= 2.0 * e
    assert si.diagnostics["l2_wind"] <= 2.0 * explicit.diagnostics["l2_wind"]
    roundoff.within(
        abs(si.diagnostics["mass_change"]),
        roundoff.mass_change_bound(2 * roundoff.operations(si), sim.grid.nnodes),
        "|mass change|",
    )
    assert explicit_there.blowup is not None
    assert too_long.blowup is not None or too_long.diagnostics["l2_h"] > 10 * e


def test_mean_depth_option_reaches_the_stepper():
    """TC2 (alpha = 0) at 1.99 dt_limit: with the default H (the initial mean depth
    rounded to 6 digits, 2363.02 m) the wave starts to go unstable (l2(h) 1.27e-3, 6.5x ssprk3); with
    mean_depth = 3000 m (the deepest point) it stays steady (1.750e-4)."""
    base = load_scene("tc2_steady", ne=4, np_=4, days=STEADY_DAYS)
    limit = base.dt / make_sim(base).courant()["courant_gravity"]
    e = run(dataclasses.replace(base, output_every_days=STEADY_DAYS))[0].diagnostics["l2_h"]
    default, sim_d, _ = run(at_multiple(base, "semi_implicit", 2.0, limit))
    deep, sim_h, _ = run(at_multiple(base, "semi_implicit", 2.0, limit, mean_depth=3000.0))
    print(
        f"\nH = {sim_d.stepper.H:.1f} m: {default.blowup or default.diagnostics['l2_h']}; "
        f"H = {sim_h.stepper.H:.1f} m: {deep.blowup or deep.diagnostics['l2_h']}; ssprk3 {e:.4e}"
    )
    h0 = make_sim(base).fields()[2]  # the initial depth
    w = sim_d.grid.spheremp
    assert sim_h.stepper.H == 3000.0
    mean = float(w @ h0 / w.sum())  # the initial mean depth, rounded to 6 digits (the same on any ranks)
    assert sim_d.stepper.H == reference_depth(mean) and abs(sim_d.stepper.H - mean) <= 0.005
    assert deep.blowup is None and deep.diagnostics["l2_h"] < 2 * e
    assert default.blowup is not None or default.diagnostics["l2_h"] > 2 * e


# -- mass ---------------------------------------------------------------------------------


@pytest.mark.roundoff
@pytest.mark.parametrize("dt", [None, 3600.0], ids=["scene_dt", "dt3600"])
def test_semi_implicit_conserves_mass_to_round_off(dt):
    """TC5 (with topography and hyperviscosity), ne = 4, one day: mass to round-off,
    two updates of the depth (the leapfrog step and its time filter) per RHS evaluation
    and Helmholtz iteration (``roundoff.mass_kept``)."""
    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper="semi_implicit", dt=dt)
    result, sim, wall = run(scene)
    assert result.blowup is None
    changes = [h["mass_change"] for h in result.history]
    print(
        f"\ndt {scene.dt:g} s ({scene.nsteps} steps, gravity-wave Courant {result.courant['courant_gravity']:.2f}): "
        f"mass change {changes}, {result.iterations}, {wall:.2f} s"
    )
    roundoff.mass_kept(result.history, sim.grid.nnodes, lambda d: 2 * roundoff.operations(d))


# -- the steps' Helmholtz solves: host reads and graphs -----------------------------------


def _steps(monkeypatch, stepper, device="cpu", threads=1, precision="float64", tally=None):
    """Three steps of ``stepper`` (TC5, ne = 4, 8x the scene step, one rank): (final state,
    Helmholtz iterations a step, host reads in the third step (``tally``), the solves'
    graphs after the second and the third step)."""
    monkeypatch.setenv("SWE_SPHERE_THREADS", str(threads))
    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper=stepper)
    scene = dataclasses.replace(scene, dt=8 * scene.dt, stepper_options={"precision": precision})
    sim = Simulation(scene, device, progress=False)
    gw = sim.stepper.helmholtz
    its = [sim.stepper.step(sim.x).iterations["helmholtz"] for _ in range(2)]  # records and captures, fixes H (a read)
    graphs = gw.graph_count
    with tally.counting() if tally else contextlib.nullcontext():
        its.append(sim.stepper.step(sim.x).iterations["helmholtz"])
    return sim.x.numpy(), its, tally.syncs if tally else None, (graphs, gw.graph_count)


# the solve graphs after ``_steps``' second and third step with one rank where the solver may capture
# (one CPU thread; CUDA with conditional nodes): a solve is captured at its second call, so
# leapfrog's start at dt/2, called once, never; the semi-implicit step's solve at the third step,
# the ARS steps' three at the second (issue 83: the CUDA test still asked for a graph after the
# second step, as before a876498, and read the semi-implicit step's (0, 1) as "no graph")
CAPTURED = {"semi_implicit": (0, 1), "imex": (3, 3)}


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("stepper", ["semi_implicit", "imex"])
def test_a_solver_step_reads_the_host_once(monkeypatch, tally, stepper, threads):
    """A semi-implicit and an IMEX ARS(3,4,3) step on the CPU read the device once: the
    step's Helmholtz iteration count and failure flag (``HelmholtzSolver.iterations``); its 1
    or 3 solves none, as replayed CPU graphs (one thread) or host loops (two). (Before:
    3 + 1 a CG iteration a solve, 36 and 57 a step here.)"""
    _, its, reads, graphs = _steps(monkeypatch, stepper, threads=threads, tally=tally)
    assert reads == 1 and min(its) > 5
    assert graphs == (CAPTURED[stepper] if threads == 1 else (0, 0))


@pytest.mark.parametrize("stepper", ["semi_implicit", "imex"])
def test_the_per_node_layouts_solves_are_captured_as_the_cpus(monkeypatch, stepper):
    """The CUDA layout's solve (the per-node kernels: ``HelmholtzSolver._solve``'s other branch)
    run on one CPU thread is captured at the same calls as the per-element layout's, with its
    iterations: the capture decision a card makes, checked without one."""
    _, its, _, graphs = _steps(monkeypatch, stepper)
    monkeypatch.setattr(Backend, "per_element", property(lambda self: False))
    monkeypatch.setattr(Backend, "nodes_per_thread", lambda self, np_: 1)
    _, per_node, _, per_node_graphs = _steps(monkeypatch, stepper)
    assert per_node_graphs == graphs == CAPTURED[stepper]
    assert per_node == its and min(its) > 5


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("stepper", ["semi_implicit", "imex", "implicit"])
def test_graphed_solves_have_the_bits_of_host_loops(monkeypatch, stepper, precision):
    """The solves as Warp CPU graphs (one thread: ``wp.capture_while`` loops, nested for
    the refinement) and as host loops (two threads, the same kernels): the same
    iterations and the same bits after three steps (JFNK: its preconditioner's solves)."""
    x1, its1, _, graphs1 = _steps(monkeypatch, stepper, threads=1, precision=precision)
    x2, its2, _, graphs2 = _steps(monkeypatch, stepper, threads=2, precision=precision)
    assert graphs1[1] > 0 and graphs2[1] == 0
    assert its1 == its2 and min(its1) > 5
    assert np.array_equal(x1, x2)


@pytest.mark.parametrize("old, new", [("double", "float64"), ("mixed", "float32")])
def test_the_old_precision_words_are_the_new_ones_after_a_warning(monkeypatch, old, new):
    """Issue 124: the Helmholtz solve's precision in [numerics] precision's words, "float64" and
    "float32" (the model's one dtype path, ``precision_dtype``); the old "double" and "mixed" still
    taken (a deprecation, one line) as the new word: the same options and the same bits."""
    with pytest.warns(
        DeprecationWarning, match=rf'^precision "{old}" is deprecated: "{new}", as \[numerics\] precision$'
    ):
        assert HelmholtzOptions(precision=old) == HelmholtzOptions(precision=new)
    with pytest.warns(DeprecationWarning):
        x_old, its_old, _, _ = _steps(monkeypatch, "semi_implicit", precision=old)
    x_new, its_new, _, _ = _steps(monkeypatch, "semi_implicit", precision=new)
    assert its_old == its_new and min(its_new) > 5 and np.array_equal(x_old, x_new)


@requires_cuda
@pytest.mark.parametrize("stepper", ["semi_implicit", "imex"])
def test_a_solver_step_on_cuda_replays_graphs_and_reads_once(monkeypatch, tally, stepper):
    """On CUDA (one rank) the step's solves are CUDA graphs captured at their second call
    (the CG's loop a conditional node) and replayed: the step reads the device once."""
    _, its, reads, graphs = _steps(monkeypatch, stepper, "cuda", tally=tally)
    assert reads == 1 and min(its) > 5 and graphs == CAPTURED[stepper]


# -- bad options ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "option, needle",
    [
        ('helmholtz_solver = "cusparse"', "semi_implicit.helmholtz_solver"),
        ('helmholtz_solver = "pcg"', "semi_implicit.helmholtz_solver was removed"),
        ("tol = 1.5", "semi_implicit.tol"),
        ("maxiter = 0", "semi_implicit.maxiter"),
        ("mean_depth = -1.0", "semi_implicit.mean_depth"),
        ("robert_asselin = 0.5", "semi_implicit.robert_asselin"),
        ('tol = "tight"', "semi_implicit.tol"),
        ('precision = "single"', "semi_implicit.precision"),
        ("guess_history = -1", "semi_implicit.guess_history"),
        ("guess_history = 33", "semi_implicit.guess_history"),
        ("guess_history = 2.5", "semi_implicit.guess_history"),
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


@pytest.mark.parametrize("stepper", ["semi_implicit", "imex", "tableau"])
def test_the_helmholtz_options_are_one_declaration(stepper):
    """The [semi_implicit], [imex] and [tableau] tables take the Helmholtz solve's options
    from ``HelmholtzOptions`` (semi_implicit with its own tighter tol): the same keys and
    defaults, the same one-line errors."""
    cls = STEPPERS[stepper]
    assert issubclass(cls.Options, HelmholtzOptions)
    o = cls.make_options()
    assert (o.maxiter, o.mean_depth, o.precision, o.guess_history) == (500, 0.0, "float64", 8)
    assert o.tol == (1e-7 if stepper == "semi_implicit" else 1e-6)
    for key, value, message in (
        ("tol", 1.0, "tol must be in (0, 1)"),
        ("maxiter", 0, "maxiter must be >= 1"),
        ("mean_depth", -5.0, "mean_depth must be >= 0"),
        ("precision", "single", "precision must be one of float64, float32"),
        ("guess_history", 33, "guess_history must be in 0..32"),
    ):
        with pytest.raises(ValueError, match=re.escape(f"{message} (got {value!r})")):
            cls.make_options(**{key: value})
