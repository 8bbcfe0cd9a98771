"""Steps that choose themselves (``Scene.control``): the step control the loop owns when a scene
asks for an accuracy or a Courant number instead of a Δt.

``StepControl.step`` takes one accepted step toward a target time (an output, restart or end
time): Δt the controller's last proposal, held within [dt_min, dt_max] and shortened to land on
the target exactly, told the stepper (``Stepper.set_dt``). Under ``error`` control a step whose
error norm (``control.ErrorNorm`` of the pair's estimate) is above 1 is rejected: the state and
the stepper's state put back, retried at the controller's shorter Δt (with ``per_unit_step`` the
norm per unit step, ‖e‖ · 1 day / Δt, so that the error a run accumulates follows rtol:
Shampine 2005, J. Sci. Comput. 25:3). A CFL target (``control.CflController``) is the whole
control under ``cfl``, a cap under ``error``: by default (``SceneControl.cfl_default``)
``config.control.CFL_FRACTION`` × the pair's measured Courant limit, holding the Courant number
only (no growth bound: where it does not bind, the steps are the error controller's, bit for
bit). Under ``balanced`` control the tolerances follow the grid (``Balance``: issue 64's "a run
that asks for an accuracy"). A run's Δt policy under control is ``core.ControlledDt`` of a ``StepControl`` (``simulation.guard.RunObserver.steer``).

Its tries replay as graphs where a fixed-Δt run's steps do (``core.Unit.try_step``: on CUDA
by default): a graph is keyed by Δt (``GraphCapture.graph_key``), and the controller's Δt are few,
those of its grid (``on_grid``), so each keeps its graph (a step landed on a target, its Δt off
the grid, runs plain); the norm's read is the one host read of a try, and the Courant numbers'
pass, where it is taken, a second. The IMEX pairs' tries run plain (their solver copies its
guess histories on the host's decision, ``HelmholtzSolver.checkpoint``), as the JFNK stepper's.

Lookahead (``StepControl.lookahead``: on CUDA, an explicit pair under "error" control on one
rank): a try's norm is queued with its read, then the next try at the same Δt is launched from
the try's end (kept in ``xs``) before the norm is read, so that the card steps while the host
reads and decides; where the try is accepted and the next Δt is that one (Δt changes in about
2 % of ``rk43``'s steps), the try launched ahead is the next step (its start, in ``xs``, swaps
into ``x0``: no copy), else it is undone (x back from its start, the stepper rolled back), and
only where nothing reads the state between the two steps (``quiet``: no activity due after the
first, neither lands on a target): the same tries, counts and bits as without it (a try
launched ahead and undone is not counted: ``ahead_dropped``).
"""

from __future__ import annotations

import math
from collections import namedtuple

import warp as wp

from ..config.control import ESTIMATED
from ..config.schema import SceneControl
from ..core.constants import DAY
from ..core.errors import BlowUp, SceneError
from ..steppers import StepStats
from ..steppers.capabilities import ErrorEstimates, TrialSteps
from ..steppers.control import ATOL_FLOOR, Balance, CflController, Controller, CourantMax, ErrorNorm, capped

# a target this close past a step's end (relative to Δt) is landed on by that step rather than
# left to a sliver of a step after it
LANDING_SLACK = 1e-6
# a proposal is taken rounded down to one of DT_GRID steps an octave (each ≤ 4.4 % below the next),
# so that the same few Δt recur: the stages' combinations and the ∇⁴ step keep a recorded launch
# list for each of the last LAUNCH_VARIANTS coefficient sets (``LaunchRecorder.variants``), and
# a Δt among them replays its list as recorded; another sets the least recently used list's
# coefficient arguments in place (nothing recorded). Before they were arguments, a new Δt
# recorded the lists again: 1.4–3.1 ms a step at ne8 against a 0.9 ms bs32 step
# (benchmarks/studies/error_control.py adaptive_proportionality (d)); now benchmarks/studies/control_ne30.py control_overhead
DT_GRID = 16
LAUNCH_VARIANTS = 4

# under "error" with a cap, the Courant numbers' pass is skipped after a step whose error
# proposal is below CAP_MARGIN of the cap the last pass found, within the cap's growth bound,
# for at most CAP_EVERY steps in a row: there the cap cannot bind unless the largest signal speed
# over Δx grows by a third within those steps, and the proposal stands as the pass would leave
# it (a pass is 0.31 ms of a 14 ms rk43 step at ne30, one thread)
CAP_MARGIN = 0.75
CAP_EVERY = 16
# where a try is launched ahead, its Courant pass is queued before it when the last step's growth,
# applied again, would bring the proposal within this fraction of CAP_MARGIN of the cap
CAP_LIKELY = 0.9

# the model's recorded launch lists kept under control (``LaunchRecorder.limit``): a bound only,
# as the keys no longer hold Δt (a fixed-Δt run records about 10)
LAUNCH_LISTS = 64


# the times and Δt (s; the day reached, days) a ``StepControl.state`` holds, then its counts and whether
# the last step landed, each restored as its type (``capped`` apart: a file from before it has none)
_TIMES = ("dt", "t", "day", "dt_smallest", "dt_sum", "dt_largest", "dt_last", "error_last")
_RESTORED = {**dict.fromkeys(_TIMES, float), "accepted": int, "rejected": int, "landed": bool}


def on_grid(dt: float) -> float:
    """``dt`` (s, > 0) rounded down to 2^(k / DT_GRID) s, k an integer."""
    return 2.0 ** (math.floor(math.log2(dt) * DT_GRID) / DT_GRID)


# a try (``StepControl._try``; one launched ahead, ``StepControl.lookahead``): its start t (s), Δt (s),
# the stepper's checkpoint before it (None under "cfl") and its ``StepStats``
_Try = namedtuple("_Try", "t dt saved stats")


class StepControl:
    """The step control of ``control`` (a ``SceneControl``) over ``stepper`` (``variable_dt``;
    under "error" with an ``error_estimate``) on ``unit`` (an ``integrator.core.Unit``: its model, stepper,
    state x (3, N) and last good state ``start``, a try's start), from model day ``start_day`` (the
    scene's: 0, or a branch's day). The first proposal is the stepper's Δt. Counts: ``accepted``,
    ``rejected``, the smallest, summed and largest accepted Δt (s); ``history``: (time (s), Δt (s),
    error norm or NaN) per accepted step.
    Where the steps are: ``t`` (s since t = 0, from the scene's start day), ``day`` (days;
    a target's day as given where a step landed on it, ``landed``), the last accepted ``dt_last``
    and its error norm ``error_last`` (NaN under "cfl")."""

    def __init__(self, control: SceneControl, unit, start_day: float = 0.0):
        self.control, self.stepper, self.unit = control, unit.stepper, unit
        stepper, model, topology = unit.stepper, unit.model, unit.model.topology
        pressure = "pressure_gradient" in model.terms  # h a depth: h ≤ 0 is a bad state
        self.error = control.mode in ESTIMATED
        self.norm = self.controller = self.balance = None
        if self.error:
            if not isinstance(stepper, ErrorEstimates) or not isinstance(stepper, TrialSteps):
                raise SceneError(f"stepper {stepper.name}: no error estimate or trial steps to control its steps by")
            # the estimate's order in Δt: p + 1 a step, p per unit step (p the pair's lower order)
            order = min(stepper.order, stepper.embedded_order) + (0 if control.per_unit_step else 1)
            self.controller = Controller(order, control.controller)
            if control.mode == "balanced":  # absolute tolerances alone, set every try (``Balance``)
                self.norm = ErrorNorm(topology, 0.0, ATOL_FLOOR, ATOL_FLOOR, pressure)
                self.balance = Balance(control.balance, unit, self.norm)
            else:
                self.norm = ErrorNorm(topology, control.rtol, control.atol_wind, control.atol_h, pressure)
                # an inner solve's error below the step's (atol 0: rtol in each field's units)
                atol = min(control.atol_wind, control.atol_h) or control.rtol
                stepper.follow_tolerance(atol, control.rtol, control.per_unit_step)
            stepper.estimate_errors()
            stepper.carry_last_stage()  # an FSAL pair's last RHS is the next step's first
        gravity_waves = stepper.courant_limit is not None  # explicit gravity waves: the signal's Courant number
        growth = math.inf if control.cfl_default else CflController.max_change  # the default cap: a bound only
        self.cfl = None if control.cfl is None else CflController(control.cfl, gravity_waves, growth)
        self.courant = None if self.cfl is None else CourantMax(topology, topology.grid.dx, model.g, pressure)
        self.checked = False  # the last try's state found good by the norm or the Courant numbers' pass
        # the Courant numbers' passes taken (under "error", skipped where the cap cannot bind) and of them those
        # queued before the try launched ahead (``_cap_idle``)
        self.courant_passes = self.courant_queued = 0
        self._trend = 1.0  # the last accepted step's proposal over its Δt
        self._cap_seconds, self._since_pass = 0.0, 0  # the last pass's cap (s; 0: take one), steps since it
        self.dt = float(stepper.dt)
        model.launches.limit, model.launches.variants = LAUNCH_LISTS, LAUNCH_VARIANTS
        # the next try launched before this one's norm is read: where the host's read would idle the card
        on_one_card = not topology.backend.host and not topology.distributed
        self.lookahead = on_one_card and self.norm is not None and self.balance is None and stepper.explicit
        self.xs = None  # the start of a try launched ahead (the end of the try before it), made at first use
        self.ahead: _Try | None = None  # the try launched ahead, not yet taken or undone
        self.ahead_taken = self.ahead_dropped = 0
        self.accepted = self.rejected = self.capped = 0  # capped: accepted steps whose next Δt the cap set
        self.dt_smallest, self.dt_sum, self.dt_largest = math.inf, 0.0, 0.0
        self.history: list[tuple[float, float, float]] = []
        self.day, self.landed = float(start_day), True
        self.t, self.dt_last, self.error_last = self.day * DAY, math.nan, math.nan

    def step_to(self, x, day: float, quiet: bool = False) -> StepStats:
        """``step`` from ``t`` toward ``day`` (days from t = 0): ``t``, ``day`` and ``landed``
        moved on; the ``StepStats`` of its tries (rejected ones included)."""
        self.t, stats = self.step(x, self.t, day * DAY, quiet)
        self.landed = self.t == day * DAY
        self.day = day if self.landed else self.t / DAY
        return stats

    def step(self, x, t: float, target: float, quiet: bool = False) -> tuple[float, StepStats]:
        """One accepted step of x (3, N) in place from t (s) toward ``target`` (s, > t), rejected
        steps retried; (the time reached: ``target`` itself where the step landed on it, the
        ``StepStats`` of every try). ``quiet``: nothing reads x between this step and the next,
        which may then be launched ahead (``lookahead``). Raises ``BlowUp`` when the proposal
        falls below dt_min short of the target."""
        c, tries = self.control, StepStats(0, {})
        if self.ahead is None:
            wp.copy(self.unit.start, x)  # the tries' start
        else:  # the start of the try launched ahead is in xs: the two swap (a copy fewer a step)
            self.unit.start, self.xs = self.xs, self.unit.start
        while True:
            left = target - t
            dt = min(self.dt, c.dt_max or math.inf)
            dt = max(on_grid(dt), min(dt, c.dt_min))  # not below dt_min by the rounding alone
            landing = left <= dt * (1 + LANDING_SLACK)
            dt = left if landing else dt
            if self.ahead is not None and (self.ahead.t, self.ahead.dt) != (t, dt):  # launched ahead at another Δt
                self._undo(x, self.unit.start, self.ahead.saved)  # undone
            if dt < c.dt_min and not landing:
                raise BlowUp(
                    f"step {self.accepted + 1} at day {t / DAY:.6g}: the controller's dt {dt:.4g} s fell below "
                    f"time.dt_min = {c.dt_min:g} s ({self.rejected} steps rejected so far)"
                )
            self.ahead_taken += self.ahead is not None  # launched ahead as this try, else tried now
            tried, self.ahead = self.ahead or self._try(x, t, dt), None
            if self.balance is not None:
                self.balance.tolerances(self.unit.start, t, dt)
            queued = False  # the Courant pass over x queued before the next try (``_cap_idle``)
            if self.error:
                self.norm.launch(self.stepper.error_estimate, self.unit.start, x)
                if self.lookahead and quiet and not landing and left - dt > dt * (1 + LANDING_SLACK):
                    if self.courant is not None and not self._cap_idle(dt, dt * self._trend, CAP_LIKELY * CAP_MARGIN):
                        self.courant.launch(x)
                        queued = True
                    if self.xs is None:
                        self.xs = wp.zeros_like(x)
                    wp.copy(self.xs, x)  # the next try's start, launched on x
                    self.ahead = self._try(x, t + dt, dt)
            iterations = {k: tries.iterations.get(k, 0) + n for k, n in tried.stats.iterations.items()}
            tries = StepStats(tries.rhs_evals + tried.stats.rhs_evals, {**tries.iterations, **iterations})
            ok, proposal, err = self._propose(x if self.ahead is None else self.xs, dt, queued)
            if ok:
                break
            self.rejected += 1
            self._undo(x, self.unit.start, tried.saved)  # a try launched ahead undone with the try it followed
            self.dt = proposal
        self.dt = max(proposal, self.dt) if landing else proposal  # a step cut to land: not a shrink
        self.accepted += 1
        if self.balance is not None:
            self.balance.since += 1
        self.dt_smallest, self.dt_largest = min(self.dt_smallest, dt), max(self.dt_largest, dt)
        self.dt_sum += dt
        self.dt_last, self.error_last = dt, err
        reached = target if landing else t + dt
        self.history.append((reached, dt, err))
        return reached, tries

    def _try(self, x, t: float, dt: float) -> _Try:
        """A try of ``dt`` from t (s) on x (``_Try``)."""
        self.stepper.set_dt(dt)
        self.stepper.t0 = t - self.stepper.steps * dt  # the forcing's clock: the time reached, exactly
        saved = self.stepper.checkpoint() if self.error else None
        return _Try(t, dt, saved, self.unit.try_step(x))

    def _undo(self, x, start, saved) -> None:
        """x and the stepper back to the state ``start`` and the stepper's checkpoint ``saved`` (a
        rejected try's start, or where the try launched ahead started), a try launched ahead gone
        (``ahead``, counted in ``ahead_dropped``)."""
        wp.copy(x, start)
        self.stepper.rollback(saved)
        self.ahead_dropped += self.ahead is not None
        self.ahead = None

    x0 = property(lambda self: self.unit.start, doc="A step's start: the guard's last good state (``unit.start``).")

    def settle(self, x) -> None:
        """Undo a try launched ahead (``lookahead``), if one is: x the last accepted step's state
        (before the run stops, or anything reads it)."""
        if self.ahead is not None:
            self._undo(x, self.xs, self.ahead.saved)

    def vouched(self) -> bool:
        """Whether the last accepted step's state was found good by its norm or Courant pass
        (``checked``), so that the integrator's guard need not read it; where not, a try
        launched ahead is undone first (``settle``: the guard reads x)."""
        if not self.checked:
            self.settle(self.unit.x)
            return False
        if self.ahead is None:  # else the next try runs on: the step's time is the host's
            wp.synchronize_device(self.unit.x.device)
        return True

    def _propose(self, x, dt: float, queued: bool = False) -> tuple[bool, float, float]:
        """(accepted, the next Δt, the error norm or NaN) of a step of ``dt`` that ended in x
        (its norm launched: ``ErrorNorm.launch``; with ``queued``, its Courant pass too)."""
        err, ok, proposal, self.checked = math.nan, True, dt, False
        if self.error:
            err = self.norm.read()
            if self.control.per_unit_step:  # the error a day of such steps would add, against the tolerance
                err *= DAY / dt
            ok, proposal = self.controller.propose(dt, err)
            self.checked = math.isfinite(err)  # every node finite and wet (``ErrorNorm``)
            if ok:
                self._trend = proposal / dt
        idle = self.error and ok and self.cfl is not None and self._cap_idle(dt, proposal)  # the pass skipped
        self._since_pass += idle
        if self.cfl is not None and ok and not idle:  # a retry's Δt is the error controller's
            numbers, bad = self.courant.read(dt) if queued else self.courant(x, dt)
            self.courant_passes += 1
            self.courant_queued += queued
            cap = self.cfl.propose(dt, numbers)
            rate = self.cfl.courant(numbers) / dt  # the Courant number a second of Δt
            self._cap_seconds, self._since_pass = (self.cfl.cfl / rate if rate > 0 else math.inf), 0
            if self.error and cap < proposal:
                self.capped += 1
            proposal = capped(proposal, cap) if self.error else cap
            self.checked = self.checked or not bad
        return ok, proposal, err

    def _cap_idle(self, dt: float, proposal: float, margin: float = CAP_MARGIN) -> bool:
        """Whether the Courant pass may be skipped after a step of ``dt`` proposing ``proposal``
        (under "error": ``CAP_MARGIN``): the proposal below ``margin`` of the last pass's cap and
        within its growth bound, the pass taken within ``CAP_EVERY`` steps.
        Also asked before a try's norm is read (``lookahead``), of the last accepted step's
        proposal over its Δt and ``CAP_LIKELY`` of the margin: where the pass is likely to be
        taken (not idle so), it is queued behind the norm and before the try launched ahead, so
        that its read does not wait for that try and leave the card idle while the host launches
        the next (a pass after every 4th step of TC5 ne60 ``rk43`` at rtol 1e-6 on an H100, the
        host waiting 0.39 ms in each under cProfile). A pass queued and not taken is dropped; one
        taken and not queued runs then, as without lookahead: the same numbers either way."""
        within = self._since_pass < CAP_EVERY and proposal <= dt * self.cfl.max_change
        return within and proposal < margin * self._cap_seconds

    def summary(self) -> str:
        """The summary's line: accepted and rejected steps, the smallest, mean and largest Δt."""
        cap = ""
        if self.error and self.cfl is not None:
            cap = f"; the Courant cap {self.cfl.cfl:.3g} set the next dt after {self.capped} of them"
        if (b := self.balance) is not None and b.sigma is not None:
            cap += f"; balanced at {b.fraction:g} of the spatial error's rate (last {b.rate.last:.3g} s⁻¹, relative)"
        return (
            f"{self.accepted} steps accepted, {self.rejected} rejected; dt smallest {self.dt_smallest:.4g} s, "
            f"mean {self.dt_sum / max(self.accepted, 1):.4g} s, largest {self.dt_largest:.4g} s{cap}"
        )

    def state(self) -> dict:
        """The next proposal, the controller's history and the counts (a restart file's numbers)."""
        s = {k: getattr(self, k) for k in (*_TIMES, "accepted", "rejected", "capped", "landed")}
        s |= {"balance": self.balance.state()} if self.balance is not None else {}
        return s | ({"controller": self.controller.state()} if self.error else {})

    def restore(self, state: dict) -> None:
        """Continue from ``state()``: the same steps as the control it came from."""
        for k, kind in _RESTORED.items():
            setattr(self, k, kind(state[k]))
        self.capped = int(state.get("capped", 0))  # a restart file from before the count: 0
        if self.error:
            self.controller.restore(state["controller"])
        if self.balance is not None:
            self.balance.restore(state["balance"])
        self._cap_seconds = 0.0  # the next step takes the Courant pass
