"""Steppers from a Butcher tableau in the scene (``stepper = "tableau"``, ``steppers.butcher``).

The named explicit steppers (``ssprk3``, ``rk4``, ``kgu35``: tables of the one
engine, ``steppers.runge_kutta``) step bitwise as a numpy implementation of their
published forms that stores F and combines after, and as their tables written in
the scene; ARS(3,4,3) from its closed forms as a pair steps to ``imex``'s bitwise;
the bundled example pairs converge at their orders;
wrong tables are refused at load in one line (exit 2 from the CLI); the run
file says which table ran.
"""

from __future__ import annotations

import dataclasses
import json
import math
from fractions import Fraction

import numpy as np
import pytest
import warp as wp
import xarray as xr
from test_imex import tableau as ars

from swe_sphere.config.scene import SceneError, load_scene, scene_from_dict
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import ArgumentError
from swe_sphere.ensemble import Perturbation
from swe_sphere.steppers import STEPPERS
from swe_sphere.steppers.butcher import TableauOptions, built_in_table, conditions
from swe_sphere.steppers.runge_kutta import ImexRK, TableauARK, TableauRK
from swe_sphere.steppers.stage_plan import constant_keeping, stage_form
from swe_sphere.steppers.tables import EXPLICIT

import helpers
import roundoff
from helpers import TINY, cached_grid, cli_main, cli_one_line, make_sim, write_tc2_scene

# the built-in explicit schemes' Butcher tables: ssprk3 from its Shu–Osher form, kgu35 from
# the stages of its docstring (u5 = (5 u1 − u0)/4 + 3Δt/4 f(u4) = u0 + Δt/4 f(u0) + 3Δt/4 f(u4))
BUILT_IN = {
    "ssprk3": dict(A=[[0, 0, 0], [1, 0, 0], ["1/4", "1/4", 0]], b=["1/6", "1/6", "2/3"], c=[0, 1, "1/2"], order=3),
    "rk4": dict(
        A=[[0, 0, 0, 0], ["1/2", 0, 0, 0], [0, "1/2", 0, 0], [0, 0, 1, 0]],
        b=["1/6", "1/3", "1/3", "1/6"],
        c=[0, "1/2", "1/2", 1],
        order=4,
    ),
    "kgu35": dict(
        A=[[0] * 5, ["1/5", 0, 0, 0, 0], [0, "1/5", 0, 0, 0], [0, 0, "1/3", 0, 0], [0, 0, 0, "2/3", 0]],
        b=["1/4", 0, 0, 0, "3/4"],
        c=[0, "1/5", "1/5", "1/3", "2/3"],
        order=3,
    ),
}


# the Shu–Osher forms the hand-written steppers recorded before they became tables: per
# stage (c, the RHS's argument, updates (out, ((a, src), ...))), src "k" F times aΔt; a
# combination's weights summing to 1 exactly in float64 (``stage_plan.constant_keeping``: 1/3 as
# 1 − fl(2/3), whose sum with fl(2/3) is 1, where fl(1/3) + fl(2/3) = 1 − 2⁻⁵⁴)
Q = Fraction  # a fraction of Δt
SHU_OSHER = {
    "ssprk3": (
        (0.0, "x", (("s1", ((1.0, "x"), (Q(1), "k"))),)),
        (1.0, "s1", (("s2", ((0.75, "x"), (0.25, "s1"), (Q(1, 4), "k"))),)),
        (0.5, "s2", (("x", ((1.0 - 2.0 / 3.0, "x"), (2.0 / 3.0, "s2"), (Q(2, 3), "k"))),)),
    ),
    "rk4": (
        (0.0, "x", (("s", ((1.0, "x"), (Q(1, 2), "k"))), ("acc", ((1.0, "x"), (Q(1, 6), "k"))))),
        (0.5, "s", (("acc", ((1.0, "acc"), (Q(1, 3), "k"))), ("s", ((1.0, "x"), (Q(1, 2), "k"))))),
        (0.5, "s", (("acc", ((1.0, "acc"), (Q(1, 3), "k"))), ("s", ((1.0, "x"), (Q(1), "k"))))),
        (1.0, "s", (("x", ((1.0, "acc"), (Q(1, 6), "k"))),)),
    ),
    "kgu35": (
        (0.0, "x", (("s1", ((1.0, "x"), (Q(1, 5), "k"))),)),
        (0.2, "s1", (("s", ((1.0, "x"), (Q(1, 5), "k"))),)),
        (0.2, "s", (("s", ((1.0, "x"), (Q(1, 3), "k"))),)),
        (1.0 / 3.0, "s", (("s", ((1.0, "x"), (Q(2, 3), "k"))),)),
        (2.0 / 3.0, "s", (("x", ((1.25, "s1"), (-0.25, "x"), (Q(3, 4), "k"))),)),
    ),
}


def ars343_pair() -> dict:
    """ARS(3,4,3) as a pair, its entries the floats of the paper's closed forms (``test_imex.tableau``)."""
    A_E, A_I, b, _ = ars("ars343")
    return dict(
        name="ARS(3,4,3)",
        order=3,
        A_E=A_E.tolist(),
        b_E=b.tolist(),
        A_I=A_I.tolist(),
        b_I=b.tolist(),
        c=A_E.sum(1).tolist(),
    )


def short(stepper, options, steps=4, dt=1800.0, scene="tc2_steady"):
    """``scene`` on ne = 2 np = 4 with ``stepper`` and its options for ``steps`` steps of ``dt``."""
    base = load_scene(scene, ne=2, np_=4, dt=dt, days=steps * dt / DAY, stepper=stepper)
    return dataclasses.replace(base, stepper_options=options, output_every_days=steps * dt / DAY)


def final_state(scene, steps):
    sim = make_sim(scene)
    stats = [sim.stepper.step(sim.x) for _ in range(steps)]
    return sim, sim.x.numpy().copy(), stats


def example(name) -> tuple:
    """A bundled example scene's table as hashable (key, value) pairs (``helpers.tc6_final``)."""
    o = TableauOptions(**load_scene(name).stepper_options)
    return tuple(
        (f.name, getattr(o, f.name)) for f in dataclasses.fields(o) if f.name not in ("tol", "maxiter", "mean_depth")
    )


# -- the table's checks -----------------------------------------------------------


def test_explicit_order_conditions_are_the_eight_of_order_four_and_imex_the_coupled_ones():
    """Order 4: the 8 rooted trees (Butcher's table); a pair to order 3: 2 + 2 + 2·3
    conditions (b_E and b_I on c², A_E c and A_I c: the coupling ones included)."""
    found = [(p, t) for p, _, _, t in conditions(4, False)]
    assert found == [
        (1, 1),
        (2, Fraction(1, 2)),
        (3, Fraction(1, 3)),
        (3, Fraction(1, 6)),
        (4, Fraction(1, 4)),
        (4, Fraction(1, 8)),
        (4, Fraction(1, 12)),
        (4, Fraction(1, 24)),
    ]
    assert sum(1 for _ in conditions(3, True)) == 10
    assert sum(1 for _ in conditions(5, False)) == 17  # 9 rooted trees of 5 vertices


@pytest.mark.parametrize("name", list(BUILT_IN))
def test_built_in_tables_record_as_few_combinations_as_the_built_ins(name):
    """The table's stage form writes no more combinations a stage (each pair shares
    one DSS) than the hand-written Shu–Osher form; ssprk3's are the built-in's."""
    t = BUILT_IN[name]
    F = lambda v: Fraction(str(v))  # noqa: E731
    _, stages = stage_form([[F(a) for a in row] for row in t["A"]], [F(x) for x in t["b"]], [F(x) for x in t["c"]])
    built_in = SHU_OSHER[name]
    assert [math.ceil(len(u) / 2) for _, _, u in stages] == [math.ceil(len(u) / 2) for _, _, u in built_in]
    assert sum(len(u) for _, _, u in stages) <= sum(len(u) for _, _, u in built_in)
    if name == "ssprk3":  # the same coefficients and abscissae (its s1, s2 are one buffer here)
        assert [(c, [terms for _, terms in u]) for c, _, u in stages] == [
            (c, [tuple((a, "s1" if src == "s2" else src) for a, src in terms) for _, terms in u])
            for c, _, u in built_in
        ]


@pytest.mark.parametrize("whole_partials", [False, True])
def test_stage_form_of_random_tables_forms_every_stage(whole_partials):
    """Random explicit tables (2..7 stages, dense and sparse rows): replaying the
    recorded updates on coefficient vectors over (x(n), Δt K_1, ..., Δt K_s), each
    stage's input is its Y_i and the state ends as x(n+1) (to round-off); at most two
    arrays and F once per update (chains where a row needs more). With ``whole_partials``
    (the float32 state's form) every link of a chain whose partial sums could hold its x(n) part
    (nonzero, as every Y_i's and x(n+1)'s) holds it exactly, from its float weights: a partial
    sum is never a fraction of the state."""
    rng = np.random.default_rng(33)
    held_whole = 0  # chains whose partial sums hold their whole x(n) part
    for trial in range(60):
        s = int(rng.integers(2, 8))
        A = [
            [
                Fraction(int(rng.integers(-4, 5)), int(rng.integers(1, 6)))
                if j < i and rng.random() < 0.6
                else Fraction(0)
                for j in range(s)
            ]
            for i in range(s)
        ]
        b = [Fraction(int(rng.integers(-4, 5)), int(rng.integers(1, 6))) for _ in range(s)]
        buffers, stages = stage_form(A, b, [sum(row) for row in A], whole_partials=whole_partials)
        held = {"x": np.eye(s + 1)[0]}
        size = {"x": 1.0}  # Σ |a|·size of what a buffer was summed from: the scale of its roundings
        part = {"x": Fraction(1)}  # each buffer's multiple of x(n), exactly, from the float weights
        chains = []  # each combination's x(n) parts, link by link
        for j, (_, arg, updates) in enumerate(stages):
            atol = roundoff.bound(4, size[arg])  # a weight's rounding, the others' moved onto one (once each), sums
            np.testing.assert_allclose(held[arg], [1, *map(float, A[j])], rtol=0, atol=atol, err_msg=f"{trial} {j}")
            assert part[arg] == 1  # x(n)'s part exactly: the float weights keep a constant
            for out, terms in updates:
                assert (
                    len(terms) <= 3
                    and sum(src == "k" for _, src in terms) <= 1
                    and sum(src != "k" for _, src in terms) <= 2
                )
                held[out] = sum(float(a) * (np.eye(s + 1)[j + 1] if src == "k" else held[src]) for a, src in terms)
                size[out] = sum(abs(float(a)) * (1.0 if src == "k" else size[src]) for a, src in terms)
                part[out] = sum(Fraction(a) * part[src] for a, src in terms if src != "k")
                if chains and chains[-1][0] == out and terms[0][1] == out and terms[1][1] != "k":  # a link
                    chains[-1][1].append(part[out])
                else:
                    chains.append((out, [part[out]]))
        atol = roundoff.bound(4, size["x"])
        np.testing.assert_allclose(held["x"], [1, *map(float, b)], rtol=0, atol=atol, err_msg=str(trial))
        assert part["x"] == 1
        assert set(held) <= {"x", *buffers}
        if whole_partials:  # a chain's parts all its whole one, but where that or a partial one is 0
            chained = [parts for _, parts in chains if len(parts) > 1]  # (0 exactly: its float weights' ulps)
            assert all(len(set(parts)) == 1 or min(map(abs, parts)) < 2**-40 for parts in chained), str(trial)
            held_whole += sum(len(set(parts)) == 1 for parts in chained)
    assert held_whole > 0 or not whole_partials


@pytest.mark.parametrize("name", [k for k in EXPLICIT])
def test_built_in_stage_forms_keep_a_constant_state_exactly(name):
    """Every built-in explicit table's recorded combinations, their float weights replayed in
    exact arithmetic: each stage's input and x(n+1) hold x(n) with weight exactly 1 (the
    estimate exactly 0), so a constant state with F = 0 stays the same number, not
    (1 − 2⁻⁵⁴) of it a step (fl(1/3) + fl(2/3) rounded alone: TC5's mass drifted so)."""
    t = built_in_table(name)
    d = t.estimate
    _, stages = stage_form(t.A_E, t.b_E, t.c, None if d is None else d[0])
    part = {"x": Fraction(1)}  # each buffer's multiple of x(n), exactly, from the float weights
    for _, arg, updates in stages:
        assert part[arg] == 1
        for out, terms in updates:
            part[out] = sum(Fraction(a) * part[src] for a, src in terms if src != "k")
    assert part["x"] == 1 and part.get("e", 0) == 0


def test_constant_keeping_moves_the_smallest_weight_that_can_take_the_remainder():
    """fl(1/3) + fl(2/3) misses 1 by 2⁻⁵⁴: 1/3 takes 1 − fl(2/3), a float 1 ulp above fl(1/3);
    weights whose floats already sum exactly (kgu35's −1/4, 5/4) stay as rounded; scales (the
    sources' multiples of x(n)) weigh the sum."""
    assert Fraction(1, 3) + Fraction(2, 3) == 1 and Fraction(1 / 3) + Fraction(2 / 3) != 1
    assert constant_keeping([Fraction(1, 3), Fraction(2, 3)], [1, 1]) == [1.0 - 2.0 / 3.0, 2.0 / 3.0]
    assert constant_keeping([Fraction(-1, 4), Fraction(5, 4)], [1, 1]) == [-0.25, 1.25]
    weights = constant_keeping([Fraction(1, 3), Fraction(1, 3)], [Fraction(1), Fraction(2)])
    assert sum(Fraction(w) * s for w, s in zip(weights, (1, 2))) == 1


# -- the named steppers' bits ------------------------------------------------------

# RK4 as the engine writes it (``stage_form``): two registers, s1 = x + Δt/2 K1,
# s2 = x + Δt/2 K2, then s1 = (s1 + 2 s2)/3 + Δt/3 K3 = x + Δt (K1 + 2K2 + 2K3)/6 and
# s2 = x + Δt K3, x(n+1) = s1 + Δt/6 K4: one combination fewer than the accumulator form
RK4_TWO_REGISTERS = (
    (0.0, "x", (("s1", ((1.0, "x"), (Q(1, 2), "k"))),)),
    (0.5, "s1", (("s2", ((1.0, "x"), (Q(1, 2), "k"))),)),
    (
        0.5,
        "s2",
        (("s1", ((1.0 - 2.0 / 3.0, "s1"), (2.0 / 3.0, "s2"), (Q(1, 3), "k"))), ("s2", ((1.0, "x"), (Q(1), "k")))),
    ),
    (1.0, "s2", (("x", ((1.0, "s1"), (Q(1, 6), "k"))),)),
)


def numpy_steps(scene, form, steps) -> np.ndarray:
    """``steps`` steps of the explicit method written as ``form`` (stages as
    ``SHU_OSHER``'s) in numpy: F = ``model.rhs`` stored, then each combination summed
    left to right in float64, qΔt as Δt/d for q = 1/d; the model's hyperviscosity after."""
    sim = make_sim(scene)
    m, dt = sim.model, scene.dt
    arg, out = wp.zeros_like(sim.x), wp.zeros_like(sim.x)
    held = {"x": sim.x.numpy().copy()}
    for _ in range(steps):
        for _, src, updates in form:
            arg.assign(held[src])
            m.rhs(arg, out)
            k = out.numpy().copy()
            for name, terms in updates:
                total = None
                for a, what in terms:
                    term = (
                        (dt / a.denominator if a.numerator == 1 else float(a) * dt) * k
                        if what == "k"
                        else a * held[what]
                    )
                    total = term if total is None else total + term
                held[name] = total
        arg.assign(held["x"])
        m.hyperviscosity(arg, dt)
        held["x"] = arg.numpy().copy()
    return held["x"]


@pytest.mark.roundoff
@pytest.mark.parametrize("name", list(BUILT_IN))
def test_named_explicit_steppers_have_the_bits_of_their_published_forms(name):
    """TC5 (topography, ∇⁴) on ne = 2, 6 steps of 30 min: ``ssprk3`` and ``kgu35``
    bitwise as their Shu–Osher forms (``SHU_OSHER``: Shu & Osher 1988 eq. 2.18;
    HOMME's tstep_type 5) and ``rk4`` as its two-register form, each computed in
    numpy from stored F. RK4's accumulator form (its hand-written stepper before it
    was a table) sums in another order: the two differ by round-off, measured
    4.0e-15 relative to the largest wind and depth, bounded by 8ε a stage a step
    (each stage's input and its share of x(n+1), sums of up to five terms, rounded
    up to 4 times each)."""
    scene = short(name, {}, scene="tc5_mountain")
    _, x, stats = final_state(scene, 6)
    np.testing.assert_array_equal(x, numpy_steps(scene, RK4_TWO_REGISTERS if name == "rk4" else SHU_OSHER[name], 6))
    assert [s.rhs_evals for s in stats] == [len(BUILT_IN[name]["b"])] * 6
    if name == "rk4":
        ref = numpy_steps(scene, SHU_OSHER["rk4"], 6)
        diff = roundoff.state_difference(x, ref)
        print(f"\nrk4: max |two registers - accumulator| in the wind and the depth over their largest values {diff}")
        roundoff.within(max(diff), roundoff.bound(8 * 4 * 6), "|two registers − accumulator| (wind, depth)")


@pytest.mark.parametrize("name", list(BUILT_IN))
def test_named_explicit_steppers_are_their_tables(name):
    """The registry's ssprk3, rk4, kgu35 step bitwise as their Butcher tables written in the
    scene (``stepper = "tableau"``, the tables transcribed above), at the same RHS count."""
    options = {"name": name, **BUILT_IN[name]}
    _, ref, _ = final_state(short(name, {}, scene="tc5_mountain"), 6)
    sim, x, stats = final_state(short("tableau", options, scene="tc5_mountain"), 6)
    assert isinstance(sim.stepper, TableauRK) and sim.stepper.explicit
    np.testing.assert_array_equal(x, ref)
    assert [s.rhs_evals for s in stats] == [len(BUILT_IN[name]["b"])] * 6
    assert EXPLICIT[name]["order"] == BUILT_IN[name]["order"]


def test_ars343_written_as_a_pair_steps_to_imex_bitwise():
    """ARS(3,4,3) as (A_E, b_E, A_I, b_I, c) from the paper's closed forms: the same states
    and Helmholtz iterations as ``imex`` (TC5 ne = 2, 4 steps of 1 h, tol 1e-10)."""
    _, ref, ref_stats = final_state(
        short("imex", {"scheme": "ars343", "tol": 1e-10}, dt=3600.0, scene="tc5_mountain"), 4
    )
    sim, x, stats = final_state(short("tableau", {**ars343_pair(), "tol": 1e-10}, dt=3600.0, scene="tc5_mountain"), 4)
    assert isinstance(sim.stepper, TableauARK) and not sim.stepper.explicit
    np.testing.assert_array_equal(x, ref)
    assert [(s.rhs_evals, s.iterations) for s in stats] == [(r.rhs_evals, r.iterations) for r in ref_stats]


# -- order of accuracy of the bundled examples ----------------------------------


# HOMME's M1 pair (Guba et al. 2020, Geosci. Model Dev. 13, 6467, §4.1; ClimaTimeSteppers'
# HOMMEM1): b_E ≠ b_I (each part's last row), five implicit stages with differing a_ii
HOMMEM1 = (
    ("name", "HOMME M1"),
    ("order", 2),
    ("c", (0, "1/5", "1/5", "1/3", "1/2", 1)),
    (
        "A_E",
        (
            (0,) * 6,
            ("1/5", 0, 0, 0, 0, 0),
            (0, "1/5", 0, 0, 0, 0),
            (0, 0, "1/3", 0, 0, 0),
            (0, 0, 0, "1/2", 0, 0),
            (0, 0, 0, 0, 1, 0),
        ),
    ),
    ("b_E", (0, 0, 0, 0, 1, 0)),
    (
        "A_I",
        (
            (0,) * 6,
            (0, "1/5", 0, 0, 0, 0),
            (0, 0, "1/5", 0, 0, 0),
            (0, 0, 0, "1/3", 0, 0),
            (0, 0, 0, 0, "1/2", 0),
            ("5/18", "5/18", 0, 0, 0, "8/18"),
        ),
    ),
    ("b_I", ("5/18", "5/18", 0, 0, 0, "8/18")),
)


# a second-order pair (b_E·c = b_I·c = 1/2) whose last stage is explicit in both parts but
# weighed differently (b_E ≠ b_I): its L Y comes from a product, not from a solve
EXPLICIT_LAST = (
    ("name", "explicit last stage"),
    ("order", 2),
    ("c", (0, "1/2", "1/2")),
    ("A_E", ((0, 0, 0), ("1/2", 0, 0), ("1/4", "1/4", 0))),
    ("b_E", (0, 0, 1)),
    ("A_I", ((0, 0, 0), ("1/4", "1/4", 0), ("1/4", "1/4", 0))),
    ("b_I", (0, "1/2", "1/2")),
)
PAIRS = {"hommem1": HOMMEM1, "explicit_last": EXPLICIT_LAST}


@pytest.mark.parametrize("pair", list(PAIRS))
def test_a_pair_replayed_as_graphs_has_the_bits_of_plain_steps(monkeypatch, pair):
    """A pair's steps (HOMME M1: five solves a step; a last stage explicit in both parts:
    its L Y a product) replayed as graphs with the CG's loops inside, checked every 5
    steps (its counters read once a block), against plain steps checked every step
    (TC5 ne = 2, 12 steps of 1 h): the same state and Helmholtz iterations."""
    monkeypatch.setenv("SWE_SPHERE_THREADS", "1")  # a CPU graph replays on one thread
    scene = short("tableau", dict(PAIRS[pair]), steps=12, dt=3600.0, scene="tc5_mountain")
    runs = []
    for graphs, every in ((False, 1), (True, 5)):
        sim = make_sim(scene)
        sim.graphs, sim.check_every = graphs, every
        result = sim.run(None)
        runs.append((sim.x.numpy(), result.iterations, sim.graphs_kept))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    assert runs[0][1] == runs[1][1] and runs[0][1]["helmholtz"] > 12
    assert runs[1][2] >= 1  # steps were captured


@pytest.mark.roundoff
@pytest.mark.parametrize("scene, order", [("ark2_gkc", 2), ("ark324l2sa", 3), ("hommem1", 2), ("explicit_last", 2)])
def test_example_tables_converge_at_their_order(scene, order):
    """TC6 inviscid at ne = 4 for 0.25 day against rk4 with 2048 steps, 64 -> 128 steps
    (the imex tests' case): rate ≈ 2 for ARK2 (GKC 2013), ≈ 3 for ARK3(2)4L[2]SA (the
    bundled examples), ≈ 2 for HOMME's M1 (b_E ≠ b_I) and for a pair with an explicit
    last stage; mass kept to round-off, an update of the depth per RHS evaluation and
    Helmholtz iteration (``roundoff.operations``)."""
    # the Helmholtz CG's tolerance above its round-off floor: at 1e-13 the explicit-last pair's
    # error at 128 and 256 steps moved with round-off-sized changes (2.2e-5 and 3.6e-5 where rate 2
    # gives 4.2e-6 and 1.0e-6); 64 and 128 steps are clean from 1e-12 (256: 7.1e-6 at 1e-12, 1.2e-6
    # at 1e-11)
    options = (*(PAIRS[scene] if scene in PAIRS else example(scene)), ("tol", 1e-12))
    coarse, _, _ = helpers.tc6_error(0.25, 2048, "tableau", 64, options)
    fine, rf, _ = helpers.tc6_error(0.25, 2048, "tableau", 128, options)
    rate = math.log2(coarse / fine)
    print(
        f"\n{scene}: error {coarse:.4e} -> {fine:.4e}, rate {rate:.3f}, mass change {rf.diagnostics['mass_change']:.1e}"
    )
    assert order - 0.3 <= rate <= order + 0.3
    assert fine > 1e-8  # far above the reference's own error
    roundoff.within(
        abs(rf.diagnostics["mass_change"]),
        roundoff.mass_change_bound(roundoff.operations(rf), cached_grid(4, 4).nnodes),
        "|mass change|",
    )


@pytest.mark.parametrize("pair", ["ars232", "ars343", *PAIRS, "ark2_gkc", "ark324l2sa"])
def test_fused_combinations_have_the_bits_of_plain_passes(monkeypatch, pair):
    """IMEX combinations with their F-holding passes in the RHS's DSS (``ImexRK.fused``: the
    ``imex`` schemes; pairs with b_E ≠ b_I, L terms after the F ones, an explicit last stage
    writing the Y its RHS reads, five solves) bitwise those of storing every F and combining
    after (``fused`` False: a plain ``rhs``): TC5 ne = 2, 4 steps of 1 h."""
    if pair.startswith("ars"):
        scene = short("imex", {"scheme": pair}, dt=3600.0, scene="tc5_mountain")
    else:
        scene = short("tableau", dict(PAIRS[pair] if pair in PAIRS else example(pair)), dt=3600.0, scene="tc5_mountain")
    runs = [final_state(scene, 4)[1]]
    monkeypatch.setattr(ImexRK, "fused", False)
    runs.append(final_state(scene, 4)[1])
    np.testing.assert_array_equal(*runs)


# -- refusals --------------------------------------------------------------------------

GOOD = '[tableau]\nname = "t"\norder = 2\nA = [[0, 0], ["1/2", 0]]\nb = [0, 1]\nc = [0, "1/2"]\n'
PAIR = (
    '[tableau]\nname = "p"\norder = 2\nc = [0, "1/2"]\nA_E = [[0, 0], ["1/2", 0]]\nb_E = [0, 1]\n'
    'A_I = [[0, 0], [0, "1/2"]]\nb_I = [0, 1]\n'
)


@pytest.mark.parametrize(
    "table, words",
    [
        (GOOD.replace('c = [0, "1/2"]', 'c = [0, "1/3"]'), ("tableau.A row 2 sums to 1/2, not c entry 2 = 1/3",)),
        (
            GOOD.replace("order = 2", "order = 3"),
            ("tableau.order = 3 claimed", "order-3 condition b·c² = 1/3 fails", "1/4"),
        ),
        (PAIR.replace("order = 2", "order = 3"), ("order-3 condition b_E·c² = 1/3 fails",)),
        (
            PAIR.replace('A_I = [[0, 0], [0, "1/2"]]', 'A_I = [[0, "1/4"], ["1/4", "1/4"]]'),
            ("tableau.A_I entry (1,2) = 1/4 is above the diagonal", "diagonally implicit"),
        ),
        (GOOD.replace('A = [[0, 0], ["1/2", 0]]', 'A = [[0, 0], ["1/2"]]'), ("tableau.A row 2 has 1 entries, not 2",)),
        (GOOD.replace("b = [0, 1]", "b = [0, 1, 0]"), ("tableau.b has 3 entries, not 2",)),
        (
            GOOD.replace('"1/2", 0]]', '"1/two", 0]]'),
            ("tableau.A entry (2,1) = '1/two' is not a number or a fraction",),
        ),
        (
            GOOD.replace('A = [[0, 0], ["1/2", 0]]', 'A = [["1/2", 0], [0, "1/2"]]'),
            ("tableau.A entry (1,1) = 1/2 is on the diagonal",),
        ),
        (GOOD.replace("b = [0, 1]", "b = 1"), ("tableau.b must be an array",)),
        (GOOD + "A_I = [[0, 0], [0, 1]]\n", ("not both",)),
        (PAIR.replace("b_I = [0, 1]\n", ""), ("tableau.b_I is missing",)),
        (GOOD.replace('name = "t"\n', ""), ("tableau.name is missing",)),
    ],
)
def test_wrong_tables_are_refused_in_one_line(capsys, tmp_path, table, words):
    scene = write_tc2_scene(tmp_path / "t.toml", stepper="tableau", tables=table)
    cli_one_line(capsys, ["run", scene, *TINY, "--days", "0.125", "--output", tmp_path / "t.nc"], 2, *words)
    assert not (tmp_path / "t.nc").exists()


# -- restart, run file, list --------------------------------------------------------


@pytest.mark.parametrize(
    "options", [BUILT_IN["kgu35"] | {"name": "kgu35"}, dict(example("ark324l2sa"))], ids=["explicit", "imex"]
)
def test_state_restore_continues_bitwise(options):
    """3 steps, state() and x into a fresh simulation, 3 more: bitwise the 6 straight
    (the IMEX pair carries the mean depth and the warm Helmholtz guess)."""
    scene = short("tableau", options, steps=6)
    _, whole, _ = final_state(scene, 6)
    first, x, _ = final_state(scene, 3)
    second = make_sim(scene)
    second.x.assign(x)
    second.stepper.restore(first.stepper.state())
    for _ in range(3):
        second.stepper.step(second.x)
    np.testing.assert_array_equal(second.x.numpy(), whole)


def test_run_file_and_list_say_which_table_ran(capsys, tmp_path):
    out = tmp_path / "ark2.nc"
    code, stdout, _ = cli_main(
        capsys, "run", "tableaus/ark2_gkc", *TINY, "--dt", "3600", "--days", "0.125", "--output", out
    )
    assert code == 0
    assert "stepper     tableau ARK2 (Giraldo, Kelly & Constantinescu 2013), dt = 3600 s" in stdout
    with xr.open_dataset(out) as ds:
        assert ds.attrs["stepper"] == "tableau" and ds.attrs["tableau"] == "ARK2 (Giraldo, Kelly & Constantinescu 2013)"
        assert ds.attrs["tableau_order"] == 2
        table = json.loads(ds.attrs["tableau_table"])
        assert table["A_I"][1] == [0.29289321881345254, 0.29289321881345254, 0] and set(table) == {
            "A_E",
            "b_E",
            "A_I",
            "b_I",
            "c",
        }
        assert scene_from_dict(json.loads(ds.attrs["scene"])).stepper_options["name"] == ds.attrs["tableau"]
    code, stdout, _ = cli_main(capsys, "list")
    assert code == 0
    assert any(line.split()[:1] == ["tableau"] for line in stdout.splitlines())
    assert "ark324l2sa" in stdout and "tableau ARK3(2)4L[2]SA (Kennedy & Carpenter 2003) dt=1800s" in stdout


def test_without_a_table_it_is_rk4():
    """No [tableau] table: the classical RK4 table (the documented default), the
    engine's own ``rk4`` bitwise; registry-wide tests run it."""
    o = STEPPERS["tableau"].make_options()
    assert o.name == "rk4" and o.order == 4 and o == TableauOptions()
    _, ref, _ = final_state(short("rk4", {}), 3)
    _, x, _ = final_state(short("tableau", {}), 3)
    np.testing.assert_array_equal(x, ref)


# -- a table's stability limit ------------------------------------------------------
HEUN2 = dict(name="heun2", A=[[0, 0], [1, 0]], b=["1/2", "1/2"], c=[0, 1], order=2)
HEUN3 = dict(
    name="heun3", A=[[0, 0, 0], ["1/3", 0, 0], [0, "2/3", 0]], b=["1/4", 0, "3/4"], c=[0, "1/3", "2/3"], order=3
)


@pytest.mark.parametrize(
    "table, limit",
    [
        (BUILT_IN["ssprk3"], math.sqrt(3)),  # every three-stage third-order table's
        (HEUN3, math.sqrt(3)),
        (BUILT_IN["rk4"], math.sqrt(8)),
        (BUILT_IN["kgu35"], math.sqrt(15)),  # its docstring's
        (HEUN2, 0.0),  # |R(iy)|² = 1 + y⁴/4
        (dict(A=[[0]], b=[1]), 0.0),  # forward Euler: 1 + y²
    ],
    ids=["ssprk3", "heun3", "rk4", "kgu35", "heun2", "euler"],
)
def test_the_imaginary_axis_limit_of_a_table(table, limit):
    from swe_sphere.steppers.butcher import imaginary_axis_limit

    A = [[Fraction(a) for a in row] for row in table["A"]]
    assert imaginary_axis_limit(A, [Fraction(b) for b in table["b"]]) == pytest.approx(limit, abs=1e-8)


def test_a_tables_courant_limit_follows_its_stability_polynomial_as_the_measured_ones_do():
    """The rule (rk4's measured limit over its axis limit, times the table's) lands within
    5 % of ssprk3's and kgu35's measured limits, the tables it was not taken from."""
    from swe_sphere.steppers.runge_kutta import COURANT_PER_AXIS_LIMIT
    from swe_sphere.steppers.tables import COURANT_LIMITS

    assert COURANT_PER_AXIS_LIMIT == pytest.approx(1.73 / math.sqrt(8), rel=1e-9)
    for name, axis in (("ssprk3", math.sqrt(3)), ("kgu35", math.sqrt(15))):
        assert COURANT_PER_AXIS_LIMIT * axis == pytest.approx(COURANT_LIMITS[name], rel=0.05), name


def test_a_table_warns_above_its_courant_limit_and_heuns_second_order_one_always():
    """Tables had no Courant warning: Heun's second-order method blew up in TC2 and TC5 at
    the scenes' own Δt without one."""
    heun2 = make_sim(short("tableau", HEUN2))
    assert heun2.stepper.courant_limit == 0.0
    warning = heun2.stability_warning()
    assert warning.startswith("warning: tableau heun2 is stable on no stretch of the imaginary axis"), warning
    fast = make_sim(short("tableau", HEUN3, dt=7200.0))  # Courant number 1.54 at ne2
    assert fast.stepper.courant_limit == pytest.approx(1.73 / math.sqrt(8) * math.sqrt(3), rel=1e-9)
    assert "above tableau heun3's stability limit of about 1.06" in fast.stability_warning()
    assert make_sim(short("tableau", HEUN3, dt=3600.0)).stability_warning() is None


# -- what a table carries -----------------------------------------------------------------

TRACERS = {"names": ["one", "dye"], "initial": ["constant", "gaussian_hills"]}


@pytest.mark.parametrize("precision, tracers", [("float64", TRACERS), ("float32_state", None)])
def test_an_explicit_table_carries_what_its_engine_carries(precision, tracers):
    """``tableau``'s refusals are those of the engine its table picks (``Described.picked``, as
    ``Tableau.__new__`` picks it), not the registered class's: ssprk3's table in the scene carries
    tracers and the float32 state as ``ssprk3`` does, to its bits (Galewsky ne2, 3 steps)."""
    tables = {} if tracers is None else {"tracers": tracers}
    options = {"name": "ssprk3", **BUILT_IN["ssprk3"]}
    runs = []
    for stepper, table in (("tableau", {"tableau": options}), ("ssprk3", {})):
        scene = load_scene("galewsky", ne=2, np_=4, stepper=stepper, precision=precision, **tables, **table)
        assert scene.precision == precision and len(scene.tracers) == (0 if tracers is None else 2)
        runs.append(final_state(scene, 3))
    (sim, x, _), (_, ref, _) = runs
    assert isinstance(sim.stepper, TableauRK) and x.shape[0] == (3 if tracers is None else 5)
    np.testing.assert_array_equal(x, ref)


@pytest.mark.parametrize("precision, tracers", [("float64", TRACERS), ("float32_state", None)])
def test_an_imex_pair_refuses_tracers_and_the_float32_state_in_one_line(precision, tracers):
    """An IMEX pair's engine (``TableauARK``, as ``imex``) carries neither: refused in one line
    naming the stepper."""
    tables = {} if tracers is None else {"tracers": tracers}
    with pytest.raises(SceneError) as err:
        load_scene("galewsky", ne=2, np_=4, stepper="tableau", precision=precision, tableau=ars343_pair(), **tables)
    line = str(err.value)
    assert "\n" not in line
    assert ("[tracers] with stepper tableau" if tracers else '"float32_state" with stepper tableau') in line


def test_an_explicit_tables_members_may_share_launches():
    """The members' layout asks the engine too (``units.layout``): an explicit table's members step in
    the same launches as ``ssprk3``'s may; an IMEX pair's need a model each, refused in one line."""
    options = {"name": "ssprk3", **BUILT_IN["ssprk3"]}
    scene = load_scene("galewsky", ne=2, np_=4, stepper="tableau", tableau=options)
    members = helpers.members_run(scene, 2, Perturbation(1.0, seed=1), device="cpu", layout="shared")
    assert members.members.layout == "shared"
    pair = load_scene("galewsky", ne=2, np_=4, stepper="tableau", tableau=ars343_pair())
    with pytest.raises(ArgumentError, match=r"need a model each \(stepper tableau\)"):
        helpers.members_run(pair, 2, Perturbation(1.0, seed=1), device="cpu", layout="shared")
