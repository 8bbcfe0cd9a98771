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
# IMEX pairs (ARS's and a Kennedy–Carpenter pair, whose Helmholtz guess is the last solution:
# the guess histories are per a_ii Δt, dropped by a change of Δt)
VARIABLE = ("bs32", "ssprk3", "fbrk32", "ark324", "imex")


def _scene(key, dt):
    scene = load_scene("tc2_steady", ne=2, days=1.0, stepper=key, dt=dt)
    if key in ("ark324", "imex"):
        scene = dataclasses.replace(scene, stepper_options={**scene.stepper_options, "guess_history": 0})
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
    diagonal = {float(a) * 480.0 for a in np.diag(s.A_I) if a != 0.0}
    assert set(s.helmholtz.histories) == diagonal  # the 1200 s histories gone


@pytest.mark.parametrize("key", [k for k, cls in STEPPERS.items() if not cls.variable_dt])
def test_a_stepper_whose_history_is_its_dt_refuses_another(key):
    cls = STEPPERS[key]
    assert not cls.variable_dt
    stepper = cls.__new__(cls)
    stepper.name = key
    with pytest.raises(ValueError, match=f"^{key} cannot change its dt between steps"):
        stepper.set_dt(100.0)
