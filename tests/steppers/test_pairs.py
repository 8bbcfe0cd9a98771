"""Embedded pairs: every built-in pair's orders and its embedding's pass ``butcher.parse``'s
order conditions, a perturbed or over-claimed b̂ fails them, and the engine's error estimate
(one more combination of the stage tendencies, ``runge_kutta``) is the difference between the
pair's step and the step of the same stages with b̂ as the weights."""

from __future__ import annotations

import dataclasses
from fractions import Fraction

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.steppers import STEPPERS
from swe_sphere.steppers.butcher import TableauOptions, parse
from swe_sphere.steppers.tables import EXPLICIT, IMEX_PAIRS

from helpers import make_sim

PAIRS = {key: t for key, t in {**EXPLICIT, **IMEX_PAIRS}.items() if t.get("embedded_order")}
CLAIMS = {
    "bs32": (3, 2),
    "rk43": (4, 3),
    "kgu352": (3, 2),
    "dp54": (5, 4),
    "ssprk43": (3, 2),
    "rdpk3sp35": (3, 2),
    "ark324": (3, 2),
    "ark436": (4, 3),
}


def test_the_pairs_are_the_claimed_ones_and_registered():
    assert set(PAIRS) == set(CLAIMS)
    for key, (p, q) in CLAIMS.items():
        table = parse(TableauOptions(**PAIRS[key]))
        assert (table.order, table.embedded_order) == (p, q)
        assert (STEPPERS[key].order, STEPPERS[key].embedded_order) == (p, q)


def _bumped(t: dict, delta: Fraction) -> dict:
    """``t`` with δ moved from b̂'s first weight to its second: Σb̂ kept, a higher condition broken."""
    keys = ("b_hat_E", "b_hat_I") if "b_hat_E" in t else ("b_hat",)
    out = dict(t)
    for key in keys:
        bh = [Fraction(v) for v in t[key]]
        bh[0] += delta
        bh[1] -= delta
        out[key] = tuple(str(v) for v in bh)
    return out


@pytest.mark.parametrize("key", list(CLAIMS))
def test_a_perturbed_or_over_claimed_embedding_fails_its_order_conditions(key):
    t = PAIRS[key]
    with pytest.raises(ValueError, match=r"^embedded_order = \d claimed, but the order-\d condition .*b_hat"):
        parse(TableauOptions(**_bumped(t, Fraction(1, 10**6))))
    with pytest.raises(ValueError, match=f"embedded_order = {t['embedded_order'] + 1} claimed|1..order"):
        parse(TableauOptions(**{**t, "embedded_order": t["embedded_order"] + 1}))


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(embedded_order=0), "b_hat is missing"),
        (dict(b_hat=()), "b_hat is missing"),
        (dict(b_hat=("1/2", "1/2")), "b_hat has 2 entries, not 4"),
        (dict(embedded_order=3), "embedded_order must be the order b_hat claims, 1..order − 1 = 2"),
    ],
)
def test_a_wrong_embedding_is_refused_in_one_line(change, words):
    t = {**EXPLICIT["bs32"], **change}
    if not t["b_hat"]:
        t["embedded_order"] = 2
    if not t["embedded_order"]:  # b_hat without its order
        t["b_hat"] = EXPLICIT["bs32"]["b_hat"]
        words = "embedded_order must be"
    with pytest.raises(ValueError, match=words) as info:
        parse(TableauOptions(**t))
    assert "\n" not in str(info.value)


def test_an_imex_pair_needs_both_embedded_rows():
    t = {**IMEX_PAIRS["ark324"], "b_hat_I": ()}
    with pytest.raises(ValueError, match="b_hat_I is missing"):
        parse(TableauOptions(**t))


@pytest.mark.roundoff
@pytest.mark.parametrize("key", list(CLAIMS))
def test_the_estimate_is_the_step_minus_the_embedded_step(key):
    """One step of TC2 (ne 2, no ∇⁴): the pair's estimate against x(n+1) of the pair minus
    x̂(n+1) of the ``tableau`` of the same stages with b̂ as its weights (the same stages, bit
    for bit), to the round-off of that difference: 16 ε |x|."""
    scene = load_scene("tc2_steady", ne=2, days=1.0, stepper=key)
    assert "hyperviscosity" not in scene.terms
    pair = make_sim(scene)
    t = PAIRS[key]
    parts = {k: v for k, v in t.items() if k not in ("b_hat", "b_hat_E", "b_hat_I", "embedded_order", "description")}
    if "b_hat" in t:
        parts["b"] = t["b_hat"]
    else:
        parts["b_E"], parts["b_I"] = t["b_hat_E"], t["b_hat_I"]
    parts |= dict(order=t["embedded_order"], name=f"{key} embedded")
    hat = make_sim(dataclasses.replace(scene, stepper="tableau", stepper_options=parts))
    x0 = pair.x.numpy().copy()
    pair.stepper.step(pair.x)
    hat.stepper.step(hat.x)
    e, x1, xh = pair.stepper.error_estimate.numpy(), pair.x.numpy(), hat.x.numpy()
    bound = 16 * np.finfo(float).eps * np.abs(x1).max(axis=1, keepdims=True)  # x1 − x̂ cancels |x|'s digits
    assert np.all(np.abs(e - (x1 - xh)) <= bound), np.abs(e - (x1 - xh)).max(axis=1)
    assert np.all(np.abs(e).max(axis=1) > 1e3 * bound.ravel()), np.abs(e).max(axis=1)
    assert np.all(np.abs(e).max(axis=1) < 0.1 * np.abs(x1 - x0).max(axis=1))


FSAL = ("bs32", "rk43", "kgu352", "dp54", "rdpk3sp35")


@pytest.mark.roundoff
@pytest.mark.parametrize("key", FSAL)
def test_a_carried_last_stage_keeps_the_steps_bits_and_saves_a_rhs(key):
    """TC5 ne 2 (with its ∇⁴): an FSAL pair whose last stage is carried over as the next step's
    first (``carry_last_stage``, error control's) steps x bit for bit as the pair that
    evaluates it in the step, through a change of Δt and a ``restore``, with s − 1 RHS
    evaluations a step where the step before wrote its first stage ahead (s at the first step,
    at a new Δt and after the restore: F(x(n)) evaluated again); its estimate is the other's
    with the last stage's F taken after the ∇⁴: e + Δt d_s (F(x(n+1)) − F(Y_s)), to 16 ε |x|."""
    scene = load_scene("tc5_mountain", ne=2, days=1.0, stepper=key)
    assert "hyperviscosity" in scene.terms
    carried, inline = make_sim(scene), make_sim(scene)
    assert carried.stepper.fsal() and carried.stepper.carry_last_stage()
    s = len(PAIRS[key]["b"])
    d_s = float(Fraction(PAIRS[key]["b"][-1]) - Fraction(PAIRS[key]["b_hat"][-1]))
    before_hv = []
    apply = inline.model.hyperviscosity
    inline.model.hyperviscosity = lambda x, dt: (before_hv.append(x.numpy().copy()), apply(x, dt))
    F, Y = (wp.zeros((3, inline.model.N), dtype=wp.float64, device=inline.model.device) for _ in range(2))
    dt = carried.stepper.dt
    for n, change in enumerate((None, None, 0.7 * dt, "restore", None)):
        if change == "restore":
            for sim in (carried, inline):
                sim.stepper.restore(sim.stepper.state())
        elif change is not None:
            for sim in (carried, inline):
                sim.stepper.set_dt(change)
        evals = carried.stepper.step(carried.x).rhs_evals
        assert evals == (s if n in (0, 2, 3) else s - 1)  # the first stage not written ahead: a new Δt, a restore
        assert inline.stepper.step(inline.x).rhs_evals == s
        x1 = carried.x.numpy()
        assert np.array_equal(x1, inline.x.numpy()), n
        inline.model.rhs(carried.x, F)
        after = F.numpy().copy()  # numpy() is a view of a CPU array
        Y.assign(before_hv[-1])
        inline.model.rhs(Y, F)
        expected = inline.stepper.error_estimate.numpy() + carried.stepper.dt * d_s * (after - F.numpy())
        bound = 16 * np.finfo(float).eps * np.abs(x1).max(axis=1, keepdims=True)
        got = carried.stepper.error_estimate.numpy()
        assert np.all(np.abs(got - expected) <= bound), (n, np.abs(got - expected).max(axis=1))
        assert np.all(np.abs(got - inline.stepper.error_estimate.numpy()).max(axis=1) > bound.ravel())


@pytest.mark.parametrize("pair, method", [("rk43", "rk4"), ("kgu352", "kgu35")])
def test_a_pair_built_on_a_method_steps_as_it_at_a_fixed_dt(pair, method):
    """rk43's x(n+1) is RK4's, kgu352's KGU35's: three TC5 steps (ne 2) the same bits."""
    sims = [make_sim(load_scene("tc5_mountain", ne=2, days=1.0, stepper=key)) for key in (pair, method)]
    for _ in range(3):
        for sim in sims:
            sim.stepper.step(sim.x)
    assert np.array_equal(sims[0].x.numpy(), sims[1].x.numpy())
