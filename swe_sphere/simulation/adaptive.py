"""Steps that choose themselves (``Scene.control``): the step control the loop owns when a scene
asks for an accuracy or a Courant number instead of a Δt.

``StepControl.step`` takes one accepted step from time t toward a target time: Δt the
controller's last proposal, held within [dt_min, dt_max] and shortened to land on the target
exactly (an output, restart or end time); the stepper told the Δt (``Stepper.set_dt``). Under
``error`` control a step whose error norm (``control.ErrorNorm`` of the pair's estimate) is
above 1 is rejected: the state and the stepper's state (``Stepper.state``) put back, retried
at the controller's shorter Δt. A CFL target (``control.CflController``) is the whole control
under ``cfl``, a cap under ``error``. A proposal below dt_min stops as a blow-up (``BlowUp``:
step, time, Δt). ``state``/``restore`` keep the proposal, the controller's history and the
counts, so that a restart continues bitwise.
"""

from __future__ import annotations

import math

import warp as wp

from ..config.schema import SceneControl
from ..core.constants import DAY
from ..core.errors import BlowUp
from ..model.diagnostics import courant_numbers
from ..steppers.control import CflController, Controller, ErrorNorm, capped

# a target this close past a step's end (relative to Δt) is landed on by that step rather than
# left to a sliver of a step after it
LANDING_SLACK = 1e-6


class StepControl:
    """The step control of ``control`` (a ``SceneControl``) over ``stepper`` (``variable_dt``;
    under "error" with an ``error_estimate``) on ``sim``'s state and grid: ``sim.x`` (3, N),
    ``sim.fields``, ``sim.grid``, ``sim.g``, ``sim.topology``. The first proposal is the
    stepper's Δt. Counts: ``accepted``, ``rejected``, the smallest, summed and largest
    accepted Δt (s); ``history``: (time (s), Δt (s), error norm or NaN) per accepted step."""

    def __init__(self, control: SceneControl, stepper, sim):
        self.control, self.stepper, self.sim = control, stepper, sim
        self.error = control.mode == "error"
        self.norm = self.controller = None
        if self.error:
            order = min(stepper.order, stepper.embedded_order) + 1
            self.controller = Controller(order, control.controller)
            self.norm = ErrorNorm(sim.topology, control.rtol, control.atol_wind, control.atol_h)
        gravity_waves = stepper.courant_limit is not None  # explicit gravity waves: the signal's Courant number
        self.cfl = None if control.cfl is None else CflController(control.cfl, gravity_waves)
        self.dt = float(stepper.dt)
        self.x0 = wp.empty_like(sim.x)
        self.accepted = self.rejected = 0
        self.dt_smallest, self.dt_sum, self.dt_largest = math.inf, 0.0, 0.0
        self.history: list[tuple[float, float, float]] = []

    def _courant(self, x, dt: float) -> dict:
        u, v, h = self.sim.fields(x)
        gravity_waves = "pressure_gradient" in self.sim.scene.terms
        numbers = courant_numbers(self.sim.grid, u, v, h, dt, self.sim.g, gravity_waves) if self.sim.root else None
        return self.sim.topology.bcast(numbers)

    def step(self, x, t: float, target: float) -> float:
        """One accepted step of x (3, N) in place from t (s) toward ``target`` (s, > t), rejected
        steps retried; the time reached (``target`` itself where the step landed on it).
        Raises ``BlowUp`` when the proposal falls below dt_min short of the target."""
        c = self.control
        while True:
            left = target - t
            dt = min(self.dt, c.dt_max or math.inf)
            landing = left <= dt * (1 + LANDING_SLACK)
            dt = left if landing else dt
            if dt < c.dt_min and not landing:
                raise BlowUp(
                    f"step {self.accepted + 1} at day {t / DAY:.6g}: the controller's dt {dt:.4g} s fell below "
                    f"time.dt_min = {c.dt_min:g} s ({self.rejected} steps rejected so far)"
                )
            self.stepper.set_dt(dt)
            self.stepper.t0 = t - self.stepper.steps * dt  # the forcing's clock: the time reached, exactly
            saved = self.stepper.state() if self.error else None
            wp.copy(self.x0, x)
            self.stepper.step(x)
            ok, proposal, err = self._propose(x, dt)
            if ok:
                break
            self.rejected += 1
            wp.copy(x, self.x0)
            self.stepper.restore(saved)
            self.dt = proposal
        self.dt = max(proposal, self.dt) if landing else proposal  # a step cut to land: not a shrink
        self.accepted += 1
        self.dt_smallest, self.dt_largest = min(self.dt_smallest, dt), max(self.dt_largest, dt)
        self.dt_sum += dt
        reached = target if landing else t + dt
        self.history.append((reached, dt, err))
        return reached

    def _propose(self, x, dt: float) -> tuple[bool, float, float]:
        """(accepted, the next Δt, the error norm or NaN) of a step of ``dt`` that ended in x."""
        err, ok, proposal = math.nan, True, dt
        if self.error:
            err = self.norm(self.stepper.error_estimate, self.x0, x)
            ok, proposal = self.controller.propose(dt, err)
        if self.cfl is not None and ok:  # a rejected step's retry is the error controller's
            cap = self.cfl.propose(dt, self._courant(x, dt))
            proposal = capped(proposal, cap) if self.error else cap
        return ok, proposal, err

    def summary(self) -> str:
        """The summary's line: accepted and rejected steps, the smallest, mean and largest Δt."""
        mean = self.dt_sum / max(self.accepted, 1)
        return (
            f"{self.accepted} steps accepted, {self.rejected} rejected; dt smallest {self.dt_smallest:.4g} s, "
            f"mean {mean:.4g} s, largest {self.dt_largest:.4g} s"
        )

    def state(self) -> dict:
        """The next proposal, the controller's history and the counts (a restart file's numbers)."""
        s = {"dt": self.dt, "accepted": self.accepted, "rejected": self.rejected}
        s |= {"dt_smallest": self.dt_smallest, "dt_sum": self.dt_sum, "dt_largest": self.dt_largest}
        return s | ({"controller": self.controller.state()} if self.error else {})

    def restore(self, state: dict) -> None:
        """Continue from ``state()``: the same steps as the control it came from."""
        self.dt = float(state["dt"])
        self.accepted, self.rejected = int(state["accepted"]), int(state["rejected"])
        self.dt_smallest, self.dt_sum, self.dt_largest = (
            float(state[k]) for k in ("dt_smallest", "dt_sum", "dt_largest")
        )
        if self.error:
            self.controller.restore(state["controller"])
