"""The fast/slow split of the RHS and the multirate steppers (``steppers.multirate``):
split + fast = RHS, what a fast evaluation costs, slow order, the substeps' limit, mass,
a table in the scene, and bad options on the command line. (Bitwise restarts: every
registered stepper in test_restart.py and test_steppers.py; MPI: test_mpi.py.)"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.core.tally import Tally, instrumented
from swe_sphere.model.diagnostics import courant_numbers
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers.multirate import GravitySplit, MriOptions, parse_mri
from swe_sphere.steppers.tables import MULTIRATE
from swe_sphere.studies.stability import run_is_stable
from swe_sphere.studies.sweep import explicit_limits

from helpers import cli_main, one_line

EPS = np.finfo(float).eps


def sim_of(case, **kw):
    options = kw.pop("options", {})
    scene = load_scene(case, np_=4, **kw)
    return Simulation(dataclasses.replace(scene, stepper_options=options), "cpu", progress=False)


def parts(case):
    """(F, fast, slow) at the case's initial state on ne 4, numpy (3, N) each."""
    sim = sim_of(case, ne=4)
    m, x = sim.model, sim.x
    F = wp.zeros_like(x)
    m.rhs(x, F)
    split = GravitySplit(m)
    split.set_depth(x)
    xp = wp.clone(x)
    split.to_perturbation(xp)
    fast, slow = wp.zeros_like(x), wp.zeros_like(x)
    split.fast(xp, fast)
    split.slow(xp, slow)
    return sim, split, xp, F, fast, slow


@pytest.mark.parametrize("case", ["tc5_mountain", "tc6_rossby_haurwitz", "galewsky", "tc4_forced_low"])
def test_fast_plus_slow_is_the_rhs(case):
    """fast + slow = F row by row to 1e-13 of the parts' size (max|fast| + max|slow|): the
    two parts are each O(g∇h) and O(H∇·v), and the RHS of a balanced start is their small
    difference, so its own round-off is relative to them (TC5's F_u is 1e-11 of max|F_u|
    off for that reason alone; measured 1e-16..2e-15 of the parts). The slow part has no
    gravity wave: at rest, a bump in h′ changes the fast part alone."""
    sim, split, xp, F, fast, slow = parts(case)
    F, fast, slow = F.numpy(), fast.numpy(), slow.numpy()
    for r in range(3):
        scale = np.abs(fast[r]).max() + np.abs(slow[r]).max()
        err = np.abs(fast[r] + slow[r] - F[r]).max() / scale
        print(f"\n{case} row {r}: |fast + slow - F| / scale {err:.1e}")
        assert err <= 1e-13
    bump = np.zeros((3, sim.model.N))
    out = wp.zeros_like(xp)
    still = []
    for height in (0.0, 100.0):
        bump[2] = height * np.cos(sim.grid.lat) ** 2
        xp.assign(bump)
        split.slow(xp, out)
        still.append(out.numpy())
    split.fast(xp, out)
    waves = np.abs(out.numpy()).max()
    assert waves > 1e-6 and np.abs(still[1] - still[0]).max() <= 1e-15 * waves


def test_fast_evaluation_cost_in_launches_and_bytes():
    """Counted by ``tally.Tally`` (each distinct array argument's bytes once a launch for a read
    and once for a write, as its kernel's source says; the same counts on any machine and at any
    ne: every array scales with N): on TC5 (every tendency
    term) the RHS is 2 launches (the tendency kernel, the DSS of 3 rows), the slow part the
    same 2 launches and bytes (one pass, compiled without the pressure gradient). A fast
    evaluation L x + ρ (the inner ssprk3/rk4's) is 2 launches (``linear_element``, the
    DSS-update of 3 rows) moving 0.96x the RHS's bytes (the RHS's tendency reads the element mass
    too, which its DSS then does not gather; 0.85x before the tendency stopped taking D, which it did not
    read), with far less arithmetic than the
    flux-form tendency. A forward–backward substep
    (split_explicit's) needs the new wind before its mass flux: 4 launches (element gradient,
    DSS-update of 2 rows, the continuity tendency −∇·(h v) about the stage's depth, DSS-update
    of 1 row into the depth and the next substep's forward-weighted depth) counted at 1.61x
    the RHS's bytes (1.54x with D), the update of the state included (the tally counts every array argument:
    the continuity kernel's unused fcor and topographic forcing too)."""
    sim, split, xp, F, fast, slow = parts("tc5_mountain")
    m = split.model
    fb = sim_of("tc5_mountain", ne=4, stepper="split_explicit").stepper
    fb.split.set_depth_value(split.H)
    z = wp.clone(xp)
    tally = Tally()
    counts = {}
    calls = (
        ("rhs", lambda: m.rhs(xp, F)),
        ("slow", lambda: split.slow(xp, slow)),
        ("fast", lambda: split.fast(xp, fast, slow)),
        ("forward-backward substep", lambda: fb.forward_backward(z, z, 10.0, slow)),
    )
    with instrumented(tally):
        for name, call in calls:
            call()  # recorded outside the count
            with tally.counting():
                call()
            counts[name] = (tally.total_launches, tally.total_bytes, list(tally.launches))
    counts = {name: (n, b / counts["rhs"][1], k) for name, (n, b, k) in counts.items()}
    print("\n" + "\n".join(f"{k}: {n} launches, {b:.3f} of the RHS's bytes {l}" for k, (n, b, l) in counts.items()))
    assert counts["rhs"][:2] == counts["slow"][:2] == (2, 1.0)
    assert counts["fast"][:2] == (2, pytest.approx(0.965, abs=0.01)) and counts["fast"][2][0] == "linear_element"
    assert counts["forward-backward substep"][:2] == (4, pytest.approx(1.612, abs=0.01))
    assert not any(k.startswith("tendency") for k in counts["fast"][2])
    assert [k for k in counts["forward-backward substep"][2] if k.startswith("tendency")] == [
        "tendency__continuity__mass"
    ]


# -- slow order and the substeps' limit on TC6 -----------------------------------------------
CASE = "tc6_rossby_haurwitz_inviscid"  # no ∇⁴: its split step would be first order


@functools.cache
def final_depth(stepper: str, options: tuple, dt: float) -> np.ndarray:
    sim = sim_of(CASE, ne=4, days=1.0, stepper=stepper, dt=dt, options=dict(options))
    assert sim.run(None).blowup is None
    return sim.x.numpy()[2].copy()


def error(stepper, options, dt):
    """max |h − h_ref| / max |h_ref| at day 1 against RK4 at 75 s (time-converged: RK4's own
    error there is below 1e-9; the errors measured are 1e-4..1e-6)."""
    ref = final_depth("rk4", (), 75.0)
    return np.abs(final_depth(stepper, tuple(sorted(options.items())), dt) - ref).max() / np.abs(ref).max()


@pytest.mark.parametrize(
    "stepper, options, expected",
    [
        # Wicker & Skamarock 2002 (MWR 130, 2088): second order in the split sense (third for linear
        # problems); ClimaTimeSteppers.jl's convergence table lists WSRK3 as 2. The forward–backward
        # substeps are first order in their step τ, so n doubles as Δt halves (τ ∝ Δt²). Measured 1.86
        # (1.81 without divergence damping).
        ("split_explicit", {"substeps": 12}, 2),
        # MIS2 (Wensch, Knoth & Galant 2009), second order; measured 2.07
        ("mri", {"method": "mis2", "inner": "rk4"}, 2),
        # MIS3C (Knoth & Wensch 2014): second order for the coupled problem although its slow table is
        # third order (ClimaTimeSteppers.jl lists 2); measured 2.13
        ("mri", {"method": "mis3c", "inner": "rk4"}, 2),
        # MIS4a (Knoth & Wensch 2014), third order; measured 2.97
        ("mri", {"method": "mis4a", "inner": "rk4"}, 3),
        # MRI-GARK-ERK33a (Sandu 2019, §8.1.1), third order; measured 2.99
        ("mri", {"method": "mri_gark_erk33a", "inner": "rk4"}, 3),
    ],
    ids=["split_explicit", "mis2", "mis3c", "mis4a", "mri_gark_erk33a"],
)
def test_slow_order(stepper, options, expected):
    """TC6 (no ∇⁴) ne 4, day 1, Δt = 900 s and 450 s (0.9 and 0.45 of Δt_g): the rate
    log2(e(900)/e(450)) within ±0.3 of the method's order. The inner RK4 with 12 substeps
    a step keeps the fast part's error below the slow one's (Δt⁴/n⁴)."""
    options = {"substeps": 12, **options}
    coarse = error(stepper, options, 900.0)
    if stepper == "split_explicit":
        options = {**options, "substeps": 2 * options["substeps"]}
    fine = error(stepper, options, 450.0)
    rate = math.log2(coarse / fine)
    print(f"\n{stepper} {options}: {coarse:.3e} -> {fine:.3e}, rate {rate:.2f}")
    assert abs(rate - expected) <= 0.3


@pytest.mark.parametrize(
    "stepper, options, ns, order",
    [
        (
            "split_explicit",
            {"divergence_damping": 0.0},
            (12, 24, 48),
            1,
        ),  # forward–backward: symplectic Euler, first order in τ
        ("mri", {"method": "mis3c", "inner": "fbrk32"}, (12, 24, 48), 2),
        ("mri", {"method": "mis3c", "inner": "ssprk3"}, (12, 24, 48), 3),
        ("mri", {"method": "mis3c", "inner": "rk4"}, (12, 24, 48), 4),
    ],
    ids=["split_explicit", "fbrk32", "ssprk3", "rk4"],
)
def test_many_substeps_converge_to_the_fast_part_solved_exactly(stepper, options, ns, order):
    """At a fixed slow step (TC6 ne 4, Δt = 1800 s, 1.8 Δt_g, 1 day) the runs with n, 2n, 4n
    substeps approach a limit, the method with its fast part integrated exactly, at the inner
    method's order: log2 of successive differences within ±0.3 of it (measured 1.21, 2.00,
    3.00, 4.01), and the error against the converged RK4 run does not grow with n (for
    WS-RK3 the limit is RK3 with each stage's fast system exact: 8.7e-4, 8.3e-4, 8.1e-4 for
    12, 24, 48, against the unsplit RK3's time error of the same order). split_explicit
    without its divergence damping, whose forward weighting adds an O(τ) term of its own
    that is not yet asymptotic at these n (rate 0.78)."""
    runs = [final_depth(stepper, tuple(sorted({**options, "substeps": n}.items())), 1800.0) for n in ns]
    d = [np.abs(runs[i] - runs[i + 1]).max() / np.abs(runs[i + 1]).max() for i in range(2)]
    rate = math.log2(d[0] / d[1])
    errors = [error(stepper, {**options, "substeps": n}, 1800.0) for n in ns]
    print(f"\n{stepper} {options}: differences {d[0]:.2e}, {d[1]:.2e}, rate {rate:.2f}; errors {errors}")
    assert abs(rate - order) <= 0.3
    assert errors[2] <= errors[1] * (1 + 1e-3) and errors[1] <= errors[0] * (1 + 1e-3)


@pytest.mark.parametrize(
    "stepper, options",
    [
        ("split_explicit", {}),
        ("mri", {}),
        ("mri", {"method": "mri_gark_erk33a", "inner": "fbrk32"}),
        ("mri", {"method": "mis4a", "inner": "rk4", "substeps": 4}),
    ],
    ids=["split_explicit", "mri", "mri_gark-fbrk32", "mis4a-rk4"],
)
def test_mass_kept_to_round_off(stepper, options):
    """TC5 ne 4 (mountain, ∇⁴), 2 days at 4 Δt_g. Every pass that writes the depth rounds each
    node's h by at most ε|h|, so the mass ∫h (h > 0) by at most ε·mass; the DSS'd divergences
    of both parts integrate to zero but for the rounding of their sums, each smaller than
    that (they are τ·H·D v ≪ h). So the relative mass change after n_steps is at most
    n_steps · passes · ε, passes the depth-writing passes of a step: its fast evaluations,
    its slow ones, the two shifts h ↔ h′ and the ∇⁴ evaluations."""
    base = load_scene("tc5_mountain", ne=4, np_=4, days=2.0, stepper=stepper)
    dt = 86400.0 / math.ceil(86400.0 / (4 * explicit_limits(base, "cpu")["dt_gravity"]))
    sim = Simulation(dataclasses.replace(base, dt=dt, stepper_options=options), "cpu", progress=False)
    st = sim.stepper
    steps_per_day = round(86400.0 / sim.scene.dt)
    result = sim.run(None)
    assert result.blowup is None
    passes = st.fast_evaluations() + 4 + 2 + sim.model.hv.plan(sim.scene.dt)[0]
    bound = result.steps * passes * EPS
    change = max(abs(h["mass_change"]) for h in result.history)
    print(
        f"\n{stepper} {options}: {result.steps} steps ({steps_per_day} a day), mass change {change:.1e}, bound {bound:.1e}"
    )
    assert change <= bound


@pytest.mark.parametrize("stepper, courant", [("split_explicit", 0.6), ("mri", 1.0)])
@pytest.mark.parametrize("multiple", [2, 7.8])
def test_auto_substeps_are_the_fewest_within_the_fast_courant_number(stepper, courant, multiple):
    """substeps "auto" (the default): n is the fewest fast steps a slow step whose gravity-wave
    Courant number about the mean depth H, sqrt(g H) Δt/(n Δx) by the run's own Courant
    diagnostic on a still state of depth H, is ≤ fast_courant (split_explicit 0.6, mri 1.0).
    TC5 ne 4, one step at 2 and 7.8 Δt_g; the step takes that many: its forward–backward
    substeps (⌈n/3⌉ + ⌈n/2⌉ + n) or inner ssprk3 stages (3 Σ_r ⌈d_r n⌉), counted."""
    base = load_scene("tc5_mountain", ne=4, np_=4, days=1.0, stepper=stepper)
    dt = 86400.0 / math.ceil(86400.0 / (multiple * explicit_limits(base, "cpu")["dt_gravity"]))
    sim = Simulation(dataclasses.replace(base, dt=dt), "cpu", progress=False)
    counted = [0]
    owner, name = (sim.stepper, "forward_backward") if stepper == "split_explicit" else (sim.stepper.split, "fast")
    real = getattr(owner, name)

    def counting(*args, **kwargs):
        counted[0] += 1
        return real(*args, **kwargs)

    setattr(owner, name, counting)
    sim.run(None, until_step=1)
    n, H, grid = sim.stepper.substeps(), sim.stepper.split.H, sim.model.grid
    still = (np.zeros(grid.dx.size), np.zeros(grid.dx.size), np.full(grid.dx.size, H))
    fast = courant_numbers(grid, *still, dt / n, sim.model.g)["courant_gravity"]
    coarser = courant_numbers(grid, *still, dt / (n - 1), sim.model.g)["courant_gravity"] if n > 1 else math.inf
    print(f"\n{stepper} at {multiple} Δt_g: n = {n}, fast Courant {fast:.3f} (n - 1: {coarser:.3f})")
    assert fast <= courant < coarser
    stages = (1 / 3, 1 / 2, 1) if stepper == "split_explicit" else sim.stepper.tab.d
    taken = (1 if stepper == "split_explicit" else 3) * sum(max(1, math.ceil(d * n - 1e-9)) for d in stages)
    assert n > 1 and counted[0] == taken == sim.stepper.fast_evaluations()


@pytest.mark.slow  # a 100-day run (10 s); the defaults' short-run stability: test_stable_over_twice_the_scene_at_the_defaults
def test_split_explicit_defaults_hold_tc2_rotated_over_100_days():
    """TC2 rotated by π/4, ne 4, Δt = 1200 s (fast Courant 0.37 a second), 100 days: at the
    defaults ("auto" takes 2 substeps, the least it takes; divergence damping 0.1) the run
    ends; with one substep a stage and no damping (the defaults before) it blows up on day
    34, the weak instability of the split (SplitExplicit's docstring)."""
    scene = load_scene("tc2_steady_alpha_pi4", ne=4, np_=4, days=100.0, dt=1200.0, stepper="split_explicit")
    sim = Simulation(scene, "cpu", progress=False)
    st = sim.stepper
    st.split.set_depth(sim.x)
    assert st.substeps() == 2
    st.fewest_auto_substeps = 1
    assert st.substeps() == 1  # what the fast Courant number alone asks for
    ok, reason, _, _ = run_is_stable(scene, "cpu")
    assert ok, reason
    before = dataclasses.replace(scene, stepper_options={"substeps": 1, "divergence_damping": 0.0})
    ok, reason, _, _ = run_is_stable(before, "cpu")
    assert not ok and "blow-up" in reason


@pytest.mark.parametrize("stepper", ["split_explicit", "mri"])
@pytest.mark.parametrize(
    "case, multiple",
    [
        pytest.param("tc5_mountain", 6, marks=pytest.mark.slow),  # long by construction: TC6, the
        ("tc6_rossby_haurwitz", 4),  # case nearest its limit, stays in the default run
        pytest.param("galewsky", 6, marks=pytest.mark.slow),
    ],
)
def test_stable_over_twice_the_scene_at_the_defaults(stepper, case, multiple):
    """ne 8, twice the scene's length (TC5 30 days, TC6 28, Galewsky 12) at the defaults and a
    slow step of 6 Δt_g (TC6 4 Δt_g: its advective Courant number is 0.32 of the gravity
    waves', 1.26 there). Measured: every one stable; TC6 blew up at 5.9 Δt_g (split_explicit)
    and, with MIS3C instead of MIS4a, at 2.9 Δt_g. TC5 and Galewsky run with ``-m slow``."""
    base = load_scene(case, ne=8, np_=4)
    base = load_scene(case, ne=8, np_=4, days=2 * base.days, stepper=stepper)
    dt = 86400.0 / math.ceil(86400.0 / (multiple * explicit_limits(base, "cpu")["dt_gravity"]))
    ok, reason, _, _ = run_is_stable(dataclasses.replace(base, dt=dt), "cpu")
    assert ok, reason


def test_a_table_in_the_scene_is_the_built_in_one(tmp_path):
    """[mri] with MIS2's coefficients and name steps bitwise as method = "mis2"; the run file
    names the table."""
    table = {k: v for k, v in MULTIRATE["mis2"].items() if k != "description"}
    runs = []
    for options in ({"method": "mis2"}, {"method": "mis4a", **table}):
        sim = sim_of("tc5_mountain", ne=2, days=0.25, stepper="mri", options=options)
        sim.run(None)
        runs.append(sim.x.numpy())
        assert sim.stepper.attrs()["mri"] == "MIS2"
    np.testing.assert_array_equal(runs[0], runs[1])


def test_the_slow_tables_order_is_checked():
    """A table whose slow part (the method with no fast part) fails its claimed order is refused."""
    with pytest.raises(ValueError, match="order = 3 claimed, but the order-3 condition"):
        MriOptions(name="MIS2 claimed third", order=3, **{k: MULTIRATE["mis2"][k] for k in ("alpha", "beta", "gamma")})
    assert parse_mri(MriOptions(method="mri_gark_erk33a")).slow.b == ("1/4", "0", "3/4")  # Heun's third-order table


BAD = [
    (
        "split_explicit",
        "split_explicit.substeps=0",
        'split_explicit.substeps must be an integer >= 1 or "auto" (got 0)',
    ),
    (
        "split_explicit",
        "split_explicit.substeps=-3",
        'split_explicit.substeps must be an integer >= 1 or "auto" (got -3)',
    ),
    (
        "split_explicit",
        "split_explicit.substeps=2.5",
        'split_explicit.substeps must be an integer >= 1 or "auto" (got 2.5)',
    ),
    (
        "split_explicit",
        "split_explicit.divergence_damping=1",
        "split_explicit.divergence_damping must be in [0, 1) (got 1",
    ),
    ("mri", "mri.substeps=0", 'mri.substeps must be an integer >= 1 or "auto" (got 0)'),
    ("mri", "mri.inner=euler", "mri.inner must be one of fbrk32, ssprk3, rk4 (got 'euler')"),
    ("mri", "mri.method=mis5", "mri.method must be one of mis2, mis3c, mis4a, mri_gark_erk33a (got 'mis5')"),
    ("mri", "mri.name=mine", "mri.beta must be a non-empty array of rows"),
    ("mri", "mri.mean_depth=-1", "mri.mean_depth must be >= 0 (got -1"),
    ("mri", "mri.substeps=many", "mri.substeps must be an integer >= 1 or \"auto\" (got 'many')"),
    ("split_explicit", "split_explicit.fast_courant=0", "split_explicit.fast_courant must be > 0 (got 0"),
]


@pytest.mark.parametrize("stepper, setting, words", BAD, ids=[b[1] for b in BAD])
def test_bad_option_is_one_line(tmp_path, capsys, stepper, setting, words):
    out = tmp_path / "o.nc"
    code, _, err = cli_main(
        capsys, "run", "tc5_mountain", "--ne", "2", "--stepper", stepper, "-s", setting, "--output", out
    )
    one_line(code, err, 2, words)
    assert not out.exists()


@pytest.mark.parametrize(
    "table, words",
    [
        ("mri = 3", "[mri] must be a table"),
        (
            '[mri]\nname = "x"\norder = 2\nbeta = [[1, 0], [0.5]]',
            "mri.beta must be square (got 2 rows of 2, 1 entries)",
        ),
        (
            '[mri]\nname = "x"\norder = 1\nbeta = [["half"]]',
            "mri.beta entry (1,1) = 'half' is not a number or a fraction",
        ),
        (
            '[mri]\nname = "x"\norder = 1\nbeta = [[0.5, 0], [1, -0.5]]',
            "mri.order = 1 claimed, but the order-1 condition Σb = 1 fails",
        ),
        (
            '[mri]\nname = "x"\norder = 1\nbeta = [[0.5, 0], [0, -0.5]]',
            "mri.beta row 2 sums to -0.5: each inner solve's span",
        ),
        ('[mri]\nname = "x"\norder = 1\nbeta = [[1, 1], [0, 1]]', "mri.beta entry (1,2) is above the diagonal"),
        ('[mri]\nname = "x"\norder = 2\nbeta = [[1]]', "mri.order = 2 claimed, but the order-2 condition"),
    ],
    ids=["not-a-table", "ragged", "not-a-number", "first-order-fails", "negative-span", "above-diagonal", "order"],
)
def test_malformed_table_is_one_line(tmp_path, capsys, table, words):
    scene = tmp_path / "mine.toml"
    scene.write_text(
        f'terms = ["continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography"]\n{table}\n'
        '[case]\nname = "tc5_mountain"\n[grid]\nne = 2\nnp = 4\n[time]\nstepper = "mri"\ndt = 1800.0\ndays = 0.125\n'
    )
    out = tmp_path / "o.nc"
    code, _, err = cli_main(capsys, "run", scene, "--output", out)
    one_line(code, err, 2, words)
    assert not out.exists()
