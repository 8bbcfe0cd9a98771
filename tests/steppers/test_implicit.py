"""The fully implicit Jacobian-free Newton–Krylov stepper (``stepper = "implicit"``).

What is checked, and what was measured on Warp's CPU backend (2 busy cores):

* Steady state at huge steps (TC2, ne = 4, np = 4, 5 days). The explicit
  gravity-wave limit is taken as the Courant-1 step
  dt_limit = min Δx / max sqrt(g h) = dt / courant_gravity(dt) (``Simulation.courant``,
  Δx the smallest GLL node spacing): 2856.7 s. It is not an underestimate: the
  largest stable ssprk3 step found by bisection over 5 days is 0.975 dt_limit
  (alpha = 0) and 0.905 dt_limit (alpha = pi/4), and ssprk3 at dt_limit blows up.
  Crank–Nicolson at 3 steps of 144000 s = 50.4 dt_limit: l2(h) 1.786e-4 against
  ssprk3's 1.970e-4 at its scene step 1200 s (ratio 0.907; alpha = pi/4: 3.617e-4
  against 3.170e-4, ratio 1.141). With the default gravity-wave preconditioner
  (Jacobi-CG to 1e-2) and flexible GMRES: 9 and 9 Newton, 455 and 449 GMRES
  iterations (no preconditioner, GMRES: 9 and 11 Newton, 1678 and 1988 GMRES).
* Temporal order on TC6 (ne = 4, np = 4, no hyperviscosity, 0.25 day) against
  rk4 with 2048 steps on the same grid (its own error, from 1024 steps: 3.5e-12),
  Newton atol 1e-12 (the rates are the same with 1e-10 and 1e-14):
  Crank–Nicolson 64 -> 128 steps: 3.084e-5 -> 7.755e-6, rate 1.992;
  BDF2 128 -> 256: 3.157e-5 -> 8.007e-6, rate 1.979;
  backward Euler 512 -> 1024: 1.067e-4 -> 5.592e-5, rate 0.932.
  (The rates are reached late: the initial state's gravity waves, ω up to
  ~1e-3 s⁻¹, are damped by backward Euler as exp(−T ω² Δt / 2), which is
  linear in Δt only once T ω² Δt ≪ 1. Over 0.5 day, CN 8 -> 16 steps gives 0.60,
  BE 256 -> 512 gives 0.68.)
* Newton near the solution (one step of 3600 s, ne = 4): with the default
  Eisenstat–Walker forcing the observed order is 1.80, 2.17 (TC5), 2.13, 2.09
  (TC6); with the inner solve made tight (forcing term 1e-13)
  r_{k+1} / r_k² = 3.9, 1.2 (TC5), 1.1, 0.8 (TC6) down to round-off (4e-17).
* Mass: conserved to round-off whatever the Newton tolerance (TC5 ne = 4, one
  day in 4 steps: 1.5e-14 at atol 1e-6, 5.4e-16 at atol 1e-10): every Krylov vector has
  zero mass, since J v has the h-mass of v/Δt and F's h-row integrates to zero.
* The gravity-wave preconditioner (TC5 ne = 4, 4 steps of 21600 s, gravity-wave
  Courant 10.7, atol 1e-10, flexible GMRES): GMRES 617 -> 95 iterations (6.5x),
  664 -> 128 RHS evaluations, with 1792 Jacobi-CG iterations on the assembled
  Helmholtz matrix (0.37 s -> 0.33 s).
* Bad ``[implicit]`` options give exit status 2; a Newton failure exit status 3.

Its solvers' own tests (the Jacobian-vector product, flexible GMRES and its backends) are in
tests/solvers/.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
import warp as wp
import xarray as xr

from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import BlowUp

import helpers
import roundoff
from helpers import cached_grid, make_sim, run, write_tc2_scene

DEVICE = "cpu"
EPS = np.finfo(float).eps


def single_output(scene, **changes):
    """The scene with ``changes`` and one output at the end, so that dt only has to
    divide the run length (a step may be longer than the daily output interval)."""
    changes.setdefault("output_every_days", changes.get("days", scene.days))
    return dataclasses.replace(scene, **changes)


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# -- steady state at 50 times the explicit gravity-wave limit ---------------------

STEADY_DAYS = 5.0


def courant1_step(scene) -> float:
    """The explicit gravity-wave limit: the step at which the gravity-wave Courant
    number sqrt(g h) Δt / Δx_min (max over the nodes, t = 0) is 1."""
    return scene.dt / make_sim(scene).courant()["courant_gravity"]


@pytest.mark.parametrize("name", ["tc2_steady", "tc2_steady_alpha_pi4"])
def test_crank_nicolson_keeps_tc2_steady_at_50x_the_explicit_limit(name):
    """TC2 for 5 days at ne = 4, np = 4. Explicit: the scene's ssprk3 at its own
    step (gravity-wave Courant number 0.42). Implicit: Crank–Nicolson (the default
    θ = 0.5) at the longest step dividing 5 days that is >= 50 dt_limit, with
    dt_limit = Δx_min / max sqrt(g h) (the Courant-1 step; ssprk3's measured
    limit is 0.90–0.98 of it, and ssprk3 at dt_limit is checked to fail here).
    The implicit l2(h) must lie within a factor 2 of the explicit one."""
    base = load_scene(name, ne=4, np_=4, days=STEADY_DAYS)
    limit = courant1_step(base)
    explicit, _, t_exp = run(single_output(base))
    assert explicit.blowup is None

    # dt_limit is not an underestimate of the explicit limit: ssprk3 fails at it
    n_lim = math.ceil(STEADY_DAYS * DAY / limit)
    at_limit, _, _ = run(single_output(base, dt=STEADY_DAYS * DAY / n_lim))
    assert at_limit.blowup is not None or at_limit.diagnostics["l2_h"] > 10 * explicit.diagnostics["l2_h"]

    nsteps = math.floor(STEADY_DAYS * DAY / (50 * limit))
    scene = single_output(base, stepper="implicit", dt=STEADY_DAYS * DAY / nsteps, stepper_options={})
    assert scene.dt >= 50 * limit and scene.nsteps == nsteps
    implicit, sim, t_imp = run(scene)
    assert implicit.blowup is None
    e, i = explicit.diagnostics["l2_h"], implicit.diagnostics["l2_h"]
    print(
        f"\n{name}: dt_limit {limit:.1f} s; ssprk3 dt {base.dt:g} s l2(h) {e:.4e} ({t_exp:.2f} s); "
        f"ssprk3 at dt_limit: {at_limit.blowup or at_limit.diagnostics['l2_h']}; implicit CN dt {scene.dt:g} s "
        f"= {scene.dt / limit:.1f} dt_limit, {nsteps} steps: l2(h) {i:.4e}, ratio {i / e:.3f}, "
        f"l2(wind) {implicit.diagnostics['l2_wind']:.4e} (explicit {explicit.diagnostics['l2_wind']:.4e}), "
        f"mass change {implicit.diagnostics['mass_change']:.1e}, {implicit.iterations}, "
        f"{implicit.rhs_evals} RHS, {t_imp:.2f} s"
    )
    assert 0.5 * e <= i <= 2.0 * e
    assert implicit.diagnostics["l2_wind"] <= 2.0 * explicit.diagnostics["l2_wind"]
    roundoff.within(
        abs(implicit.diagnostics["mass_change"]),
        roundoff.mass_change_bound(roundoff.operations(implicit), sim.grid.nnodes),
        "|mass change|",
    )
    assert implicit.iterations["newton"] >= nsteps


# -- temporal order on TC6 ----------------------------------------------------------

ORDER_DAYS = 0.25
ORDER_REF_STEPS = 2048  # rk4, dt = 10.5 s
ORDER_ATOL = 1e-12


def tc6_error(nsteps, options):
    """Normalized l2 distance of the whole state (u, v, h) to the rk4 reference."""
    return helpers.tc6_error(ORDER_DAYS, ORDER_REF_STEPS, "implicit", nsteps, options)


@pytest.mark.parametrize(
    "options, nsteps, lo, hi",
    [
        ((("method", "theta"), ("theta", 0.5)), 64, 1.7, 2.3),
        ((("method", "bdf2"),), 128, 1.7, 2.3),
        ((("method", "theta"), ("theta", 1.0)), 512, 0.7, 1.3),
    ],
    ids=["crank_nicolson", "bdf2", "backward_euler"],
)
def test_temporal_order_tc6(options, nsteps, lo, hi):
    options = (*options, ("atol", ORDER_ATOL))
    coarse, rc, wc = tc6_error(nsteps, options)
    fine, rf, wf = tc6_error(2 * nsteps, options)
    rate = math.log2(coarse / fine)
    dt = ORDER_DAYS * DAY / nsteps
    print(
        f"\n{dict(options)}: dt {dt:g} -> {dt / 2:g} s: error {coarse:.4e} -> {fine:.4e}, rate {rate:.3f}; "
        f"{rc.iterations} / {rf.iterations}; {wc:.2f} s / {wf:.2f} s"
    )
    assert lo <= rate <= hi
    # the reference (rk4 at dt = 10.5 s: 3.5e-12 from its half-step run) is far below
    assert fine > 1e-8


def test_second_order_schemes_beat_backward_euler_at_the_same_step():
    atol = (("atol", ORDER_ATOL),)
    cn = tc6_error(64, (("method", "theta"), *atol))[0]
    bdf2 = tc6_error(64, (("method", "bdf2"), *atol))[0]
    be = tc6_error(64, (("method", "theta"), ("theta", 1.0), *atol))[0]
    print(f"\n64 steps: CN {cn:.3e}, BDF2 {bdf2:.3e}, BE {be:.3e}")
    assert cn < bdf2 < be


# -- Newton converges quadratically near the solution ---------------------------------


def _one_step_history(name, exact_inner):
    scene = load_scene(name, ne=4, np_=4, days=1.0, stepper="implicit", dt=3600.0)
    # without the preconditioner: Newton's order does not depend on it, and it
    # reaches round-off in one iteration fewer, leaving one observed order
    scene = dataclasses.replace(scene, stepper_options={"atol": 1e-13, "gmres_tol": 1e-13, "preconditioner": "none"})
    sim = make_sim(scene)
    st = sim.stepper
    if exact_inner:
        # inexact Newton → Newton: the forcing term at its floor on every iteration
        st.forcing_term = lambda *args: st.o["gmres_tol"]
    x = sim.x.numpy()
    noise = EPS * math.sqrt(np.mean(x**2)) / scene.dt  # round-off level of R = (x - b)/dt - βF
    stats = st.step(sim.x)
    return list(st.residual_history), stats, noise


@pytest.mark.parametrize("name", ["tc5_mountain", "tc6_rossby_haurwitz"])
def test_newton_converges_quadratically(name):
    """One Crank–Nicolson step of 3600 s from x(n) (ne = 4), atol = gmres_tol = 1e-13.

    With the stepper's Eisenstat–Walker forcing (choice 2, α = 2; η = 0.1 on the
    first iteration, so that one is linear by design) the observed order
    p_k = log(r_{k+1}/r_k) / log(r_k/r_{k−1}) of the iterations above 10 atol must
    be >= 1.5: measured 1.80, 2.17 (TC5); 2.13, 2.09 (TC6).
    With the inner solve tight (η = 1e-13 throughout) r_{k+1} <= 10 r_k² down to
    round-off: measured r_{k+1}/r_k² = 3.9, 1.2 (TC5), 1.1, 0.8 (TC6)."""
    hist, stats, _ = _one_step_history(name, exact_inner=False)
    print(f"\n{name} Eisenstat-Walker: {stats.iterations}; residual RMS " + " ".join(f"{r:.3e}" for r in hist))
    assert hist[-1] <= 1e-13
    above = [r for r in hist if r > 10 * 1e-13]
    orders = [math.log(above[k + 1] / above[k]) / math.log(above[k] / above[k - 1]) for k in range(1, len(above) - 1)]
    print("  observed orders " + " ".join(f"{p:.2f}" for p in orders))
    assert len(orders) >= 2
    assert all(p >= 1.5 for p in orders)

    hist, stats, noise = _one_step_history(name, exact_inner=True)
    ratios = [hist[k + 1] / hist[k] ** 2 for k in range(len(hist) - 1) if hist[k + 1] > 1e3 * noise]
    print(
        f"{name} exact inner solve: {stats.iterations}; residual RMS "
        + " ".join(f"{r:.3e}" for r in hist)
        + f"; round-off ~{noise:.1e}; r_(k+1)/r_k^2 "
        + " ".join(f"{c:.2f}" for c in ratios)
    )
    assert hist[-1] <= 1e-13
    assert len(ratios) >= 2
    assert all(c <= 10.0 for c in ratios)
    assert stats.iterations["newton"] <= 4


# -- mass -------------------------------------------------------------------------------


@pytest.mark.roundoff
@pytest.mark.parametrize("atol", [1e-6, 1e-10])
def test_implicit_conserves_mass(atol):
    """TC5 (hyperviscosity on), ne = 4, one day in 4 steps of 21600 s. The Newton
    tolerance bounds the mass error by ~nsteps Δt sqrt(3) atol / mean(h) (1e-3 at
    atol 1e-6), but every Newton update has zero mass, so the change is round-off:
    measured 1.5e-14 (atol 1e-6) and 5.4e-16 (atol 1e-10); with HOMME's vector
    Laplacian in the ∇⁴ (+2v/a², a slightly different wind) the atol 1e-6 run
    drifts by −1.1e-14, −2.9e-14, −9.4e-14, −1.6e-13 over its four steps, all from
    the Newton updates (the ∇⁴ keeps mass to 3.6e-16 a call). Bound: an update of
    the depth per RHS evaluation and per Newton, GMRES and Helmholtz iteration
    (``roundoff.operations``), far below the tolerance's 1e-3."""
    scene = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper="implicit", dt=21600.0)
    scene = dataclasses.replace(scene, stepper_options={"atol": atol})
    result, _, wall = run(scene)
    assert result.blowup is None
    changes = [h["mass_change"] for h in result.history]
    print(f"\natol {atol:g}: mass change {changes}, {result.iterations}, {wall:.2f} s")
    roundoff.mass_kept(result.history, cached_grid(4, 4).nnodes)


# -- the Helmholtz (gravity-wave Schur complement) preconditioner --------------------


def test_helmholtz_preconditioner_cuts_gmres_iterations():
    """TC5 ne = 4, 4 steps of 21600 s (gravity-wave Courant number 10.7), CN,
    flexible GMRES, without and with the gravity-wave preconditioner (Helmholtz
    by Jacobi-CG to 1e-2). Both solve the same equations; the preconditioner
    must at least halve the GMRES iterations, and every application is counted."""
    base = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper="implicit", dt=21600.0)
    out = {}
    for pc in ("none", "helmholtz"):
        result, sim, wall = run(dataclasses.replace(base, stepper_options={"preconditioner": pc, "atol": 1e-10}))
        assert result.blowup is None
        out[pc] = (result, sim.x.numpy().copy(), wall)
        print(
            f"\n{pc}: {result.iterations}, {result.rhs_evals} RHS, mass change "
            f"{result.diagnostics['mass_change']:.1e}, {wall:.2f} s",
            end="",
        )
    none, helm = out["none"][0], out["helmholtz"][0]
    diff = rel(out["helmholtz"][1], out["none"][1])
    print(
        f"\nGMRES {none.iterations['gmres']} -> {helm.iterations['gmres']} "
        f"({none.iterations['gmres'] / helm.iterations['gmres']:.1f}x); final states differ by {diff:.1e}"
    )
    assert none.iterations["precond"] == 0 and helm.iterations["precond"] >= helm.iterations["gmres"]
    assert helm.iterations["helmholtz"] >= helm.iterations["precond"]  # a CG solve each
    assert helm.iterations["gmres"] * 2 <= none.iterations["gmres"]
    assert diff < 1e-8  # both solve the same equations to the Newton tolerance
    roundoff.within(
        abs(helm.diagnostics["mass_change"]),
        roundoff.mass_change_bound(roundoff.operations(helm), cached_grid(4, 4).nnodes),
        "|mass change|",
    )


# -- failures and bad input through the command line ---------------------------------


def scene_file(tmp_path, table: str, name="scene.toml") -> str:
    return str(write_tc2_scene(tmp_path / name, tables=table))


def run_cli(capsys, *args):
    try:
        code = main(["run", *map(str, args)])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_newton_failure_exits_3_and_keeps_the_initial_state(tmp_path, capsys, monkeypatch):
    """[implicit] maxiter = 1 with atol = 1e-14: the first step cannot converge
    (one iteration leaves a residual RMS of 5.3e-6). Exit 3, the message names
    Newton, and the file holds t = 0, the initial state, and a ``blowup`` attribute."""
    monkeypatch.chdir(tmp_path)
    path = scene_file(tmp_path, "[implicit]\nmaxiter = 1\natol = 1e-14\n")
    output = tmp_path / "fail.nc"
    code, out, err = run_cli(
        capsys,
        path,
        "--ne",
        "2",
        "--days",
        "1",
        "--stepper",
        "implicit",
        "--dt",
        "21600",
        "--device",
        "cpu",
        "--output",
        output,
        "--no-progress",
    )
    print(f"\nexit {code}; stderr: {err.strip()}")
    assert code == 3
    assert "Newton" in err and "step 1" in err
    assert str(output) in err
    assert output.exists()
    scene = load_scene(path, ne=2, days=1.0, stepper="implicit", dt=21600.0)
    initial = make_sim(scene)
    with xr.open_dataset(output) as ds:
        assert ds.sizes["time"] == 1
        assert "Newton did not converge in 1 iterations" in ds.attrs["blowup"]
        assert ds.attrs["stepper"] == "implicit"
        u, v, h = (initial.grid.to_unique(f) for f in initial.fields())
        np.testing.assert_array_equal(ds["h"].values[0], h)
        np.testing.assert_array_equal(ds["u"].values[0], u)
        np.testing.assert_array_equal(ds["v"].values[0], v)
        assert float(ds["steps"].values[0]) == 0
    assert not list(tmp_path.glob("*.part"))


def test_newton_failure_mid_run_keeps_the_last_good_state(tmp_path):
    """The Newton iteration is made to fail on step 3 of 24 (tolerance tightened
    and maxiter cut to 1 after two good steps): BlowUp, the result and the file
    end at step 2 (not an output step), with the state of a clean 2-step run."""
    scene = load_scene(scene_file(tmp_path, ""), ne=2, days=1.0, stepper="implicit", dt=3600.0)
    sim = make_sim(scene)
    real_step, o = sim.stepper.step, sim.stepper.o
    good = {"maxiter": o["maxiter"], "atol": o["atol"]}

    def step(x):  # by the stepper's own count: the guard re-runs a failed block one step at a time
        o.update({"maxiter": 1, "atol": 1e-15} if sim.stepper.steps == 2 else good)
        return real_step(x)

    sim.stepper.step = step
    output = tmp_path / "mid.nc"
    with pytest.raises(BlowUp, match="step 3 failed.*Newton") as info:
        sim.run(output)
    result = info.value.result
    assert result.steps == 2 and result.history[-1]["steps"] == 2

    clean = make_sim(scene)
    for _ in range(2):
        clean.stepper.step(clean.x)
    np.testing.assert_array_equal(sim.last_good.numpy(), clean.x.numpy())
    with xr.open_dataset(output) as ds:
        assert list(ds["steps"].values) == [0, 2]
        assert "Newton" in ds.attrs["blowup"]
        np.testing.assert_array_equal(ds["h"].values[-1], clean.grid.to_unique(clean.x.numpy()[2]))


@pytest.mark.parametrize(
    "table, needle",
    [
        ('method = "rk4"', "implicit.method"),
        ("theta = 0.3", "implicit.theta"),
        ('krylov = "petsc"', "implicit.krylov"),
        ('preconditioner = "ilu"', "implicit.preconditioner"),
        ('helmholtz_solver = "direct"', "implicit.helmholtz_solver"),
        ("helmholtz_tol = 0.0", "implicit.helmholtz_tol"),
        ('initial_guess = "zero"', "implicit.initial_guess"),
        ("maxiter = 0", "implicit.maxiter"),
        ("gmres_tol = 1.5", "implicit.gmres_tol"),
        ("atol = 0.0\nrtol = 0.0", "atol and rtol"),
        ('maxiter = "ten"', "implicit.maxiter"),
        ("tolerance = 1e-8", "implicit.tolerance"),
    ],
)
def test_bad_implicit_option_exits_2(table, needle, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = scene_file(tmp_path, "[implicit]\n" + table + "\n")
    output = tmp_path / "bad.nc"
    code, out, err = run_cli(
        capsys, path, "--stepper", "implicit", "--device", "cpu", "--output", output, "--no-progress"
    )
    lines = [line for line in err.splitlines() if line.strip()]
    print(f"\n{table!r}: exit {code}: {err.strip()}")
    assert code == 2
    assert len(lines) == 1 and needle in lines[0]
    assert not output.exists() and not list(tmp_path.glob("*.nc*"))


def _tc5_estimating():
    """TC5 ne 4 without ∇⁴ with Crank–Nicolson estimating its errors (Newton atol 1e-12): (the
    simulation, its stepper, F (3, N) numpy → numpy, the exact flow (RK4 at 25 s; a, T s), the
    spheremp-weighted RMS)."""
    terms = [t for t in load_scene("tc5_mountain").terms if t != "hyperviscosity"]
    scene = load_scene("tc5_mountain", ne=4, stepper="implicit", overrides={"terms": terms, "implicit.atol": 1e-12})
    sim = make_sim(scene)
    stepper, model, w = sim.stepper, sim.model, sim.grid.spheremp
    stepper.estimate_errors()

    # F's arrays made once: the model records its launches for the arrays it is given, and new
    # arrays each call made an evaluation 1.2 ms instead of 0.14 ms (the flow below takes thousands)
    x, out = wp.zeros((3, model.N), dtype=wp.float64), wp.zeros((3, model.N), dtype=wp.float64)

    def F(a):
        x.assign(a)
        model.rhs(x, out)
        return out.numpy().copy()  # not a view of ``out``, which the next call overwrites

    def flow(a, T, h=25.0):  # RK4, the exact flow of this grid to round-off here
        n = round(T / h)
        h = T / n
        for _ in range(n):
            k1 = F(a)
            k2 = F(a + 0.5 * h * k1)
            k3 = F(a + 0.5 * h * k2)
            a = a + h / 6 * (k1 + 2 * k2 + 2 * k3 + F(a + h * k3))
        return a

    def rms(a):
        return np.sqrt(np.sum(w * a**2) / np.sum(w) / 3)

    return sim, stepper, F, flow, rms


@functools.cache
def _tc5_exact_at_5h() -> np.ndarray:
    """The exact flow (``_tc5_estimating``'s) from TC5's start to 5 h: 720 RK4 steps, 0.4 s of
    CPU, made once for the two tests below that start there (read-only: they read it alone)."""
    sim, _, _, flow, _ = _tc5_estimating()
    x5 = flow(sim.x.numpy(), 5 * 3600.0)
    x5.flags.writeable = False
    return x5


def _estimates_follow_the_local_error(stepper, flow, rms, start):
    """One step at Δt = 1200, 600, 300 s from ``start(Δt)`` (the stepper set up after
    ``set_dt``; x(n) (3, N) numpy): the estimate within 5 % of the true local error (against
    ``flow``, the exact flow) and falling 7 to 8.5 times a halving (third order)."""
    estimates = []
    for dt in (1200.0, 600.0, 300.0):
        stepper.set_dt(dt)
        now = start(dt)
        x = wp.array(now, dtype=wp.float64)
        stepper.step(x)
        e, true = stepper.error_estimate.numpy(), x.numpy() - flow(now, dt)
        assert 0.95 < rms(e) / rms(true) < 1.05, (dt, rms(e), rms(true))
        estimates.append(rms(e))
    assert all(7.0 < a / b < 8.5 for a, b in zip(estimates, estimates[1:])), estimates


def test_crank_nicolson_s_error_estimate_is_its_local_error_to_third_order():
    """Under error control Crank–Nicolson estimates each step's local error by TR against its
    AB2 predictor (Kay et al. 2010): on TC5 ne 4 without ∇⁴ (Newton atol 1e-12), one step
    from the exact flow at 6 h, the flow at 6 h − Δt giving F(x(n−1)), against the exact
    flow at 6 h + Δt (RK4 at 25 s): measured 0.974, 0.989, 0.996 of the true error at
    Δt = 1200, 600, 300 s, falling 7.7 and 7.9 times a halving (third order)."""
    sim, stepper, F, flow, rms = _tc5_estimating()
    assert stepper.carry_last_stage() is False and stepper.error_estimate is not None

    x6 = _tc5_exact_at_5h()  # 5 h: the rungs below start at 6 h − Δt from here

    def at_6h(dt):
        before = flow(x6, 3600.0 - dt)
        stepper.Fprev.assign(F(before))
        stepper.dt_old = dt
        return flow(before, dt)

    _estimates_follow_the_local_error(stepper, flow, rms, at_6h)


def test_crank_nicolson_s_first_step_estimate_is_its_local_error_to_third_order_too():
    """The first step has no F(x(n−1)): Heun's rule predicts, and e = (x − x_p) / 3 (TR's error
    constant −1/12 against Heun's 1/6 on a linear problem) is of TR's order as the later steps'
    (forward Euler's x − x_p, of second order, shrank the first step linearly in Δt, and under
    ``per_unit_step`` below dt_min). TC5 ne 4 without ∇⁴, one first step from the exact flow at
    5 h against the exact flow (RK4 at 25 s): measured 1.001, 0.993, 0.995 of the true error at
    Δt = 1200, 600, 300 s, falling 7.8 and 8.0 times a halving."""
    sim, stepper, F, flow, rms = _tc5_estimating()

    x5 = _tc5_exact_at_5h()

    def first_step_at_5h(dt):
        stepper.dt_old = math.nan  # a first step
        return x5

    _estimates_follow_the_local_error(stepper, flow, rms, first_step_at_5h)


def test_crank_nicolson_under_error_control_continues_bitwise_from_its_restart_file(tmp_path):
    """``-s time.control=error`` with the implicit stepper (θ = 0.5): a run stopped at day 0.5
    by its restart file and continued holds at day 1 the bits of one that did not stop (the
    AB2 predictor's F(x(n−1)) and Δt are in the stepper's state); BDF2 and θ ≠ 0.5 are refused
    in one line (no variable-step history; no estimate)."""

    def run(path, days, *extra):
        args = ["run", "tc5_mountain", "--ne", "2", "--stepper", "implicit", "--days", str(days)]
        args += ["-s", "time.control=error", "-s", "time.rtol=1e-3", "-s", "output.every_days=0.25"]
        args += ["--no-cells", "--no-progress", "--device", "cpu", "--output", str(path), *map(str, extra)]
        return main(args)

    assert run(tmp_path / "whole.nc", 1) == 0
    assert run(tmp_path / "first.nc", 0.5, "--restart-every", 0.5) == 0
    args = ["run", "--continue", str(tmp_path / "first.restart.nc"), "--days", "1", "--output", str(tmp_path / "b.nc")]
    assert main([*args, "--no-cells", "--no-progress", "--device", "cpu"]) == 0
    with xr.open_dataset(tmp_path / "whole.nc") as whole, xr.open_dataset(tmp_path / "b.nc") as second:
        np.testing.assert_array_equal(whole["h"][-1].values, second["h"][-1].values)
        assert int(whole["steps"][-1]) == int(second["steps"][-1]) and int(whole["rejected_steps"][-1]) >= 1
    for option in ("implicit.method=bdf2", "implicit.theta=0.6"):
        assert run(tmp_path / "x.nc", 1, "-s", option) == 2


def test_under_error_control_newton_converges_below_the_step_s_tolerance():
    """Newton's own error must stay below the step's: under error control (atol 1e-7 m s⁻¹ and
    m) it stops at a residual RMS ≤ 0.1 atol / Δt (here below its default 1e-8 s⁻¹: a state
    error of Δt × 1e-8 m a step, 4e-3 m over TC2 ne16's 1800 steps of 240 s)."""
    from swe_sphere.integrator.control import StepControl

    overrides = {"time.control": "error", "time.rtol": 1e-7}
    sim = make_sim(load_scene("tc2_steady", ne=4, days=0.5, stepper="implicit", overrides=overrides))
    control = StepControl(sim.scene.control, sim.core.units[0], sim.scene.start_day)
    control.step(sim.x, 0.0, 0.5 * DAY)
    bound = 0.1 * 1e-7 / sim.stepper.dt
    assert bound < 1e-8 and sim.stepper.residual_history[-1] <= bound
