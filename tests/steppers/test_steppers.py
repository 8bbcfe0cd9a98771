"""Time steppers: stability and cost on TC2, observed temporal order on TC6.

Temporal order is measured on the Rossby–Haurwitz wave (TC6) at ne = 4, np = 4
without hyperviscosity, after half a day, against an rk4 run with 4096 steps on
the same grid (so only the time error is seen). Measured on Warp's CPU backend
(error ratios when halving dt, h and wind):

    rk4                   256 -> 512 steps    rate 4.00 / 4.00
    ssprk3                256 -> 512 steps    rate 3.00 / 3.00
    kgu35                 256 -> 512 steps    rate 3.00 / 3.00
    fbrk32                256 -> 512 steps    rate 2.00 / 2.01
    leapfrog_trapezoidal  512 -> 1024 steps   rate 1.99 / 2.00
    leapfrog, eps = 0     256 -> 512 steps    rate 2.00 / 2.01
    leapfrog, eps = 0.05  1024 -> 2048 steps  rate 1.02 / 1.01  (the Robert–Asselin
                          filter makes leapfrog first order: 1.54 at 128 -> 256,
                          1.30 at 256 -> 512, 1.10 at 512 -> 1024)

The default Robert–Asselin coefficient is 0.05; a scene sets it in its
``[leapfrog]`` table (``robert_asselin``), which reaches the stepper through
``Scene.stepper_options``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.kernels.tendencies import TENDENCY_TERMS
from swe_sphere.steppers import STEPPERS

import roundoff
from helpers import cached_grid, make_sim, tc6_final, write_tc2_scene

# RHS evaluations: (first step, every later step), as the steppers document them.
# A registered stepper missing here (e.g. an iterative implicit one, whose count
# varies) gets the generic checks only: StepStats summed == RunResult.rhs_evals.
DOCUMENTED_RHS = {
    "leapfrog": (2, 1),  # explicit-midpoint start, then one per leapfrog step
    "leapfrog_trapezoidal": (2, 2),
    "ssprk3": (3, 3),
    "rk4": (4, 4),
    "kgu35": (5, 5),
    "fbrk32": (3, 3),  # three continuity and three momentum halves
    "semi_implicit": (1, 1),  # one RHS (and one Helmholtz solve) per step, the start included
    "imex": (4, 4),  # ARS(3,4,3): four stages, three Helmholtz solves
    "tableau": (4, 4),  # its default table, RK4's
}


def count_rhs_calls(sim):
    """Wrap ``sim.model.rhs`` and ``rhs_update`` to count the RHS evaluations the
    stepper really makes: a call on a subset of the terms (fbrk32's continuity and
    momentum halves) counts as the share of the tendency terms it evaluates."""
    calls = []
    tendency = [t for t in sim.model.terms if t in TENDENCY_TERMS]

    def counted(real):
        def rhs(x, out, terms=None):
            calls.append(1 if terms is None else len(set(terms) & set(tendency)) / len(tendency))
            return real(x, out, terms)

        return rhs

    sim.model.rhs, sim.model.rhs_update = counted(sim.model.rhs), counted(sim.model.rhs_update)
    return calls


# -- every registered stepper on TC2 -------------------------------------------


@pytest.mark.roundoff
@pytest.mark.parametrize("name", list(STEPPERS))
def test_stepper_runs_tc2_stably(name):
    """TC2, ne = 4, np = 4, one day at the scene's dt scaled to the grid (1200 s,
    gravity-wave Courant number 0.42). Measured l2(h): leapfrog 1.654e-4,
    leapfrog_trapezoidal 1.662e-4, ssprk3 1.696e-4, rk4 1.711e-4 (spatial error)."""
    scene = load_scene("tc2_steady", ne=4, days=1.0, stepper=name)
    sim = make_sim(scene)
    calls = count_rhs_calls(sim)
    result = sim.run()
    d = result.diagnostics
    print(
        f"\n{name}: dt {scene.dt:g} s, {result.steps} steps, {result.rhs_evals} RHS, l2(h) {d['l2_h']:.4e}, "
        f"linf(h) {d['linf_h']:.4e}, l2(wind) {d['l2_wind']:.4e}, mass change {d['mass_change']:.1e}"
    )
    assert result.blowup is None
    assert result.steps == scene.nsteps == 72
    assert len(result.history) == 2
    assert d["l2_h"] < 5e-4
    assert d["linf_h"] < 2e-3
    assert d["l2_wind"] < 5e-3
    roundoff.mass_kept(
        result.history, sim.grid.nnodes, lambda d: 2 * roundoff.operations(d)
    )  # and leapfrog's time filter
    assert abs(d["total_energy_change"]) < 1e-6
    if name in DOCUMENTED_RHS:
        first, later = DOCUMENTED_RHS[name]
        expected = first + later * (scene.nsteps - 1)
        assert result.rhs_evals == expected
        assert math.isclose(sum(calls), expected)  # what the stepper reports is what it does


@pytest.mark.parametrize("name", list(STEPPERS))
def test_step_stats_report_rhs_evals(name):
    """StepStats per step, and RunResult.rhs_evals is their sum."""
    scene = load_scene("tc2_steady", ne=4, days=8 * 1200.0 / DAY, stepper=name, dt=1200.0)
    sim = make_sim(scene)
    calls = count_rhs_calls(sim)
    counts = []
    for _ in range(4):
        before = len(calls)
        stats = sim.stepper.step(sim.x)
        counts.append(stats.rhs_evals)
        if name in DOCUMENTED_RHS:
            assert math.isclose(sum(calls[before:]), stats.rhs_evals)
    if name in DOCUMENTED_RHS:
        first, later = DOCUMENTED_RHS[name]
        assert counts == [first, later, later, later]
    else:
        assert all(isinstance(c, int) and c >= 0 for c in counts)
    # a fresh run reports the sum of its steps' counts
    sim2 = make_sim(scene)
    stepper, total = sim2.stepper, []
    real_step = stepper.step

    def step(x):
        stats = real_step(x)
        total.append(stats.rhs_evals)
        return stats

    stepper.step = step
    result = sim2.run()
    assert result.rhs_evals == sum(total)
    assert len(total) == scene.nsteps == 8


# -- leapfrog's Robert–Asselin coefficient --------------------------------------


def _leapfrog_scene(tmp_path, eps):
    table = "" if eps is None else f"\n[leapfrog]\nrobert_asselin = {eps!r}\n"
    return load_scene(
        write_tc2_scene(tmp_path / f"lf_{eps}.toml", stepper="leapfrog", ne=4, dt=1200.0, days=0.5, tables=table)
    )


def test_leapfrog_robert_asselin_from_scene(tmp_path):
    default = _leapfrog_scene(tmp_path, None)
    zero = _leapfrog_scene(tmp_path, 0.0)
    tenth = _leapfrog_scene(tmp_path, 0.1)
    assert default.stepper_options == {}
    assert zero.stepper_options == {"robert_asselin": 0.0}
    assert tenth.stepper_options == {"robert_asselin": 0.1}

    def final(scene):
        sim = make_sim(scene)
        sim.run()
        return sim.x.numpy()

    x_default, x_zero, x_tenth = final(default), final(zero), final(tenth)
    # the default is eps = 0.05: the same as setting it explicitly
    x_005 = final(dataclasses.replace(default, stepper_options={"robert_asselin": 0.05}))
    np.testing.assert_array_equal(x_default, x_005)
    # and the option does reach the stepper
    assert not np.array_equal(x_default, x_zero)
    assert not np.array_equal(x_default, x_tenth)
    x_zero_direct = final(dataclasses.replace(default, stepper_options={"robert_asselin": 0.0}))
    np.testing.assert_array_equal(x_zero, x_zero_direct)


def test_leapfrog_robert_asselin_in_other_stepper_table_is_ignored(tmp_path):
    """The [leapfrog] table holds leapfrog's options only: another stepper's scene keeps none."""
    scene = _leapfrog_scene(tmp_path, 0.1)
    path = tmp_path / "lf_0.1.toml"
    other = load_scene(path, stepper="ssprk3")
    assert scene.stepper_options == {"robert_asselin": 0.1}
    assert other.stepper_options == {}


# -- temporal order on TC6 -----------------------------------------------------

# a quarter day, the steps of 168.75 s and less as over half a day before: the same rates (rk4 4.003 /
# 3.997, leapfrog with the filter 1.001 / 1.035), in half the steps, against the reference the implicit,
# IMEX and tableau order tests take too (``helpers.tc6_final``: once a process)
ORDER_DAYS = 0.25
ORDER_REF_STEPS = 2048  # rk4 reference, dt = 10.5 s


def tc6_errors(stepper, nsteps, eps=None):
    """Relative l2 errors (h, wind) against the rk4 reference on the same grid."""
    ref = tc6_final(ORDER_DAYS, "rk4", ORDER_REF_STEPS)[0]
    x = tc6_final(ORDER_DAYS, stepper, nsteps, () if eps is None else (("robert_asselin", eps),))[0]
    w = cached_grid(4, 4).spheremp
    eh = math.sqrt(w @ (x[2] - ref[2]) ** 2 / (w @ ref[2] ** 2))
    ew = math.sqrt(w @ ((x[0] - ref[0]) ** 2 + (x[1] - ref[1]) ** 2) / (w @ (ref[0] ** 2 + ref[1] ** 2)))
    return eh, ew


@pytest.mark.parametrize(
    "stepper, eps, nsteps, lo, hi",
    [
        ("rk4", None, 128, 3.7, 4.3),
        ("ssprk3", None, 128, 2.8, 3.2),
        ("kgu35", None, 128, 2.8, 3.2),
        ("fbrk32", None, 128, 1.8, 2.2),
        ("leapfrog_trapezoidal", None, 256, 1.8, 2.2),
        ("leapfrog", 0.0, 128, 1.8, 2.2),
        ("leapfrog", 0.05, 512, 0.8, 1.25),
    ],
    ids=["rk4", "ssprk3", "kgu35", "fbrk32", "leapfrog_trapezoidal", "leapfrog_eps0", "leapfrog_eps0.05"],
)
def test_temporal_order_tc6(stepper, eps, nsteps, lo, hi):
    coarse = tc6_errors(stepper, nsteps, eps)
    fine = tc6_errors(stepper, 2 * nsteps, eps)
    rate = [math.log2(c / f) for c, f in zip(coarse, fine)]
    dt = ORDER_DAYS * DAY / nsteps
    print(
        f"\n{stepper} eps={eps} dt {dt:g} -> {dt / 2:g} s: err(h) {coarse[0]:.3e} -> {fine[0]:.3e}, "
        f"err(wind) {coarse[1]:.3e} -> {fine[1]:.3e}, ratio {coarse[0] / fine[0]:.2f} / {coarse[1] / fine[1]:.2f}, "
        f"rate {rate[0]:.3f} / {rate[1]:.3f}"
    )
    for r in rate:
        assert lo <= r <= hi, (stepper, eps, coarse, fine, rate)
    # the reference's own error (rk4 at dt/16 or less) must not pollute the finer run
    assert fine[0] > 1e-10


def test_robert_asselin_filter_costs_accuracy():
    """At the same dt the filtered leapfrog is less accurate than the unfiltered one
    and the gap widens as dt shrinks (O(dt) against O(dt^2))."""
    e0 = [tc6_errors("leapfrog", n, 0.0)[0] for n in (128, 512)]
    e5 = [tc6_errors("leapfrog", n, 0.05)[0] for n in (128, 512)]
    assert e5[0] > e0[0] and e5[1] > e0[1]
    assert e5[1] / e0[1] > 2 * e5[0] / e0[0]


# -- explicit state: state() / restore() continue bitwise --------------------------

# every registered stepper, and the variants whose history differs (BDF2's x(n−1),
# JFNK without the preconditioner's mean depth or without the extrapolated guess's x(n−1))
RESTART_VARIANTS = [(name, {}) for name in STEPPERS] + [
    ("implicit", {"method": "bdf2"}),
    ("implicit", {"preconditioner": "none"}),
    ("implicit", {"initial_guess": "previous"}),
]


@pytest.mark.parametrize(
    "name, options", RESTART_VARIANTS, ids=[n + "".join(f"-{v}" for v in o.values()) for n, o in RESTART_VARIANTS]
)
def test_state_restore_continues_bitwise(name, options):
    """k steps, then x and state() into a fresh simulation, restore, k more steps:
    bitwise equal to 2k uninterrupted steps. Without restore (x alone), a stepper
    with a previous level does not continue the same run (the state is needed).
    (TC2 keeps its mass, so a mean depth H re-taken from x(k) happens to equal the
    restored one; the restore of H is what makes it exact in general.)"""
    scene = load_scene("tc2_steady", ne=2, dt=1800.0, days=6 * 1800.0 / DAY, stepper=name)
    scene = dataclasses.replace(scene, stepper_options=options)
    k = 3
    whole = make_sim(scene)
    for _ in range(2 * k):
        whole.stepper.step(whole.x)
    first = make_sim(scene)
    for _ in range(k):
        first.stepper.step(first.x)
    state, x = first.stepper.state(), first.x.numpy().copy()
    assert state["steps"] == k
    assert all(isinstance(v, (int, float, np.ndarray)) for v in state.values())
    second = make_sim(scene)
    second.x.assign(x)
    second.stepper.restore(state)
    for _ in range(k):
        second.stepper.step(second.x)
    np.testing.assert_array_equal(second.x.numpy(), whole.x.numpy())
    assert second.stepper.steps == 2 * k
    if "previous" in state:  # a three-level history: x alone is not enough
        fresh = make_sim(scene)
        fresh.x.assign(x)
        for _ in range(k):
            fresh.stepper.step(fresh.x)
        assert not np.array_equal(fresh.x.numpy(), whole.x.numpy())


def test_restore_rejects_a_misshapen_state():
    scene = load_scene("tc2_steady", ne=2, dt=1800.0, days=1800.0 / DAY, stepper="leapfrog")
    sim = make_sim(scene)
    with pytest.raises(ValueError, match="previous"):
        sim.stepper.restore({"steps": 2, "previous": np.zeros((3, 5))})
    with pytest.raises(ValueError, match="lacks 'previous'"):
        sim.stepper.restore({"steps": 2})


def test_options_dataclass_defaults_checks_and_schema():
    """Each stepper's options: one frozen dataclass whose fields are the scene
    table's keys; unknown keys and bad values raise ValueError naming them."""
    from swe_sphere.config.schema import SCHEMA as _SCHEMA
    from swe_sphere.steppers import option_types

    for name, cls in STEPPERS.items():
        types = option_types(cls.Options)
        assert _SCHEMA.get(name, {}) == types
        opts = cls.make_options()
        assert opts == cls.Options()
        with pytest.raises(dataclasses.FrozenInstanceError):
            opts.x = 1
        with pytest.raises(ValueError, match=f"unknown option 'bogus' for stepper {name}"):
            cls.make_options(bogus=1)
    assert STEPPERS["leapfrog"].Options().robert_asselin == 0.05
    assert STEPPERS["implicit"].Options().atol == 1e-8
    with pytest.raises(ValueError, match=r"robert_asselin must be in \[0, 0.5\)"):
        STEPPERS["semi_implicit"].make_options(robert_asselin=0.5)
    with pytest.raises(ValueError, match="method must be"):
        STEPPERS["implicit"].make_options(method="bdf3")
    assert {n for n, c in STEPPERS.items() if c.explicit} == {
        "leapfrog",
        "leapfrog_trapezoidal",
        "ssprk3",
        "rk4",
        "kgu35",
        "bs32",
        "rk43",
        "kgu352",
        "dp54",
        "ssprk43",
        "rdpk3sp35",
        "fbrk32",
    }
