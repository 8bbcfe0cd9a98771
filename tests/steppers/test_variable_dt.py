"""Δt changed between steps (``Stepper.set_dt``, what a controller needs): a one-step stepper
after ``set_dt`` steps as one built with the new Δt and restored from its state, bit for bit;
changed and changed back before a step, it steps as if never changed; a stepper whose history
is its Δt's refuses."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.steppers import STEPPERS

from helpers import make_sim

# the engines and classes that take a new Δt: explicit tables (a pair and not), FB-RK(3,2),
# IMEX pairs (ARS's and a Kennedy–Carpenter pair; "ark324h" with its Helmholtz guess histories,
# one per a_ii Δt, the others' guess the last solution)
VARIABLE = ("bs32", "ssprk3", "fbrk32", "ark324", "ark324h", "imex")


def _scene(key, dt):
    history = key.endswith("h")
    scene = load_scene("tc2_steady", ne=2, days=1.0, stepper=key.removesuffix("h"), dt=dt)
    if key in ("ark324", "imex"):
        scene = dataclasses.replace(scene, stepper_options={**scene.stepper_options, "guess_history": 0})
    assert not history or scene.stepper_options.get("guess_history", 8) > 0
    return scene


def _take(sim, other) -> None:
    """``sim`` continues from ``other``'s state and stepper state."""
    sim.x.assign(other.x)
    sim.stepper.restore(other.stepper.state())


@pytest.mark.parametrize("key", VARIABLE)
def test_a_changed_dt_steps_as_a_stepper_built_with_it(key):
    """One list a key (``LaunchRecorder.variants``): a new Δt sets the recorded launches'
    coefficients in place; an explicit table's step then records nothing new."""
    dt, dt2 = 1200.0, 720.0
    changed = make_sim(_scene(key, dt))
    changed.model.launches.variants = 1
    at_dt, at_dt2 = make_sim(_scene(key, dt)), make_sim(_scene(key, dt2))
    plan = ((dt, at_dt), (dt2, at_dt2), (dt, at_dt))
    previous = None
    lists = []
    for step_dt, fixed in plan:
        changed.stepper.set_dt(step_dt)
        if previous is not None:
            _take(fixed, previous)
        for _ in range(2):
            changed.stepper.step(changed.x)
            fixed.stepper.step(fixed.x)
        previous = fixed
        lists.append(changed.model.launches.lists())
    assert changed.stepper.dt == dt and changed.stepper.steps == 6
    if key in ("bs32", "ssprk3"):
        assert lists[0] == lists[1] == lists[2]
    assert np.array_equal(changed.x.numpy(), at_dt.x.numpy())


@pytest.mark.parametrize("key", ("bs32", "fbrk32"))
def test_dt_changed_and_back_before_a_step_changes_no_bit(key):
    fixed, changed = make_sim(_scene(key, 1200.0)), make_sim(_scene(key, 1200.0))
    for n in range(3):
        if n == 1:  # the launches recorded at 1200 s are re-recorded at 1200 s again
            changed.stepper.set_dt(540.0)
            changed.stepper.set_dt(1200.0)
        fixed.stepper.step(fixed.x)
        changed.stepper.step(changed.x)
    assert np.array_equal(changed.x.numpy(), fixed.x.numpy())


def test_the_model_time_reached_stays_and_the_imex_histories_follow_dt():
    sim = make_sim(load_scene("tc2_steady", ne=2, days=1.0, stepper="ark324", dt=1200.0))
    s = sim.stepper
    s.t0 = 86400.0
    for _ in range(3):
        s.step(sim.x)
    s.set_dt(480.0)
    assert s.t0 + s.steps * s.dt == pytest.approx(86400.0 + 3 * 1200.0, rel=4 * np.finfo(float).eps)
    s.step(sim.x)
    a = [float(a) for a in np.diag(s.A_I) if a != 0.0]
    assert len(set(a)) == 1  # one a a step (ESDIRK), so one history a Δt
    assert list(s.helmholtz.histories) == [a[0] * 1200.0, a[0] * 480.0]  # the least recently used first
    for dt in (500.0, 520.0, 1200.0, 540.0):  # KEPT_COEFFICIENTS: at most four, the least recently used dropped
        s.set_dt(dt)
        s.step(sim.x)
    assert list(s.helmholtz.histories) == [a[0] * dt for dt in (500.0, 520.0, 1200.0, 540.0)]


@pytest.mark.parametrize("key", [k for k, cls in STEPPERS.items() if not cls.variable_dt])
def test_a_stepper_whose_history_is_its_dt_refuses_another(key):
    cls = STEPPERS[key]
    assert not cls.variable_dt
    stepper = cls.__new__(cls)
    stepper.name = key
    with pytest.raises(ValueError, match=f"^{key} cannot change its dt between steps"):
        stepper.set_dt(100.0)


def _imex(dt=1200.0):
    return make_sim(load_scene("tc5_mountain", ne=4, days=1.0, stepper="ark324", dt=dt))


def _steps(sim, dts) -> list:
    """Steps at ``dts`` (s); the Helmholtz CG iterations of each."""
    its = []
    for dt in dts:
        sim.stepper.set_dt(dt)
        its.append(sim.stepper.step(sim.x).iterations["helmholtz"])
    return its


def test_a_rejected_imex_try_leaves_no_trace():
    """A try that error control rejects (``TrialSteps.checkpoint``/``rollback``, device copies):
    a new Δt's history made in it dropped, the least recently used one it pushed out (four
    a's kept) brought back, a basis it grew put back, the last solution too: the steps after
    are bit for bit those of a run that never tried."""
    past = (1200.0, 1100.0, 1000.0, 900.0)  # four a's, 1200 s's the least recently used
    plain, tried = _imex(), _imex()
    _steps(plain, past)
    _steps(tried, past)
    gamma = {float(a) for a in np.diag(plain.stepper.A_I) if a != 0.0}.pop()  # ESDIRK: one a a step
    for dt in (700.0, 900.0):  # a new a (1200's pushed out), then one whose basis grows
        saved, x = tried.stepper.checkpoint(), tried.x.numpy().copy()  # not a view: x changes
        _steps(tried, [dt])
        held = list(tried.stepper.helmholtz.histories)
        assert held[-1] == gamma * dt and (dt == 900.0) == (gamma * 1200.0 in held)
        tried.x.assign(x)
        tried.stepper.rollback(saved)
    assert list(tried.stepper.helmholtz.histories) == list(plain.stepper.helmholtz.histories)
    assert _steps(tried, [1200.0, 900.0, 1200.0]) == _steps(plain, [1200.0, 900.0, 1200.0])
    assert np.array_equal(tried.x.numpy(), plain.x.numpy())


def test_a_new_dt_starts_its_solves_from_the_last_solution():
    """A Δt never taken: its guess history is empty, so its first solve starts from the last
    solution (one product), not from zero; the same step from zero takes more CG iterations."""
    warm, cold = _imex(7200.0), _imex(7200.0)  # a score of CG iterations a step
    _steps(warm, [7200.0] * 3)
    _steps(cold, [7200.0] * 3)
    cold.stepper.helmholtz.y.zero_()  # as if the new a's first solve started from zero
    new, zero = _steps(warm, [6480.0])[0], _steps(cold, [6480.0])[0]
    steady = _steps(warm, [6480.0])[0]
    assert new <= steady + 3 < zero  # 22, 21 and 28


@pytest.mark.parametrize("estimate", [True, False])
def test_a_rejected_implicit_try_leaves_no_trace(estimate):
    """The JFNK stepper's rollback (Crank–Nicolson's; device copies of x(n−1), which the
    extrapolated guess reads, and of the AB2 predictor's F): after tries at other Δt put
    back, the steps are bit for bit those of a run that never tried."""
    runs = []
    for tries in ((), (2400.0, 600.0)):
        scene = load_scene("tc5_mountain", ne=4, days=1.0, stepper="implicit", dt=1200.0)
        sim = make_sim(scene)
        if estimate:
            sim.stepper.estimate_errors()
        for _ in range(3):
            sim.stepper.step(sim.x)
        for dt in tries:
            saved, x = sim.stepper.checkpoint(), sim.x.numpy().copy()
            sim.stepper.set_dt(dt)
            sim.stepper.step(sim.x)
            sim.x.assign(x)
            sim.stepper.rollback(saved)
            sim.stepper.set_dt(1200.0)
        for _ in range(2):
            sim.stepper.step(sim.x)
        e = sim.stepper.error_estimate
        runs.append([sim.x.numpy().copy(), *([] if e is None else [e.numpy().copy()])])
    assert len(runs[0]) == (2 if estimate else 1)
    assert all(np.array_equal(a, b) for a, b in zip(*runs, strict=True))
