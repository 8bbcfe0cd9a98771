"""The stepper interface.

A stepper is built with the model, the step ``dt`` (s) and its options (a
frozen ``Options`` dataclass per stepper: defaults and checks in one place; the
scene's ``[<name>]`` table is read into it). It allocates its buffers and records
its launches once, then ``step(x)`` advances the state ``x`` (3, N) in place by dt
and returns a ``StepStats``.

Everything a stepper carries from one step to the next besides x (the step
count, leapfrog's x(n−1), BDF2's x(n−1), a mean depth fixed at the first step)
is explicit: ``state()`` returns it as numpy arrays and scalars and
``restore(state)`` sets it, so a stepper restored into a fresh process continues
bitwise as if it had never stopped (restart files, ``swe_sphere.simulation.checkpoint``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ..model.shallow_water import ShallowWater
from .capabilities import Described, NoOptions, option_types

__all__ = ["NoOptions", "StepStats", "Stepper", "option_types"]

f64 = wp.float64


@dataclass
class StepStats:
    """What one step cost: RHS evaluations and solver iterations (by solver name)."""

    rhs_evals: int
    iterations: dict = field(default_factory=dict)


class Stepper(Described):
    """Base class. Subclasses set ``name`` (the registry key and scene table),
    ``Options`` (a frozen dataclass; its ``__post_init__`` raises ValueError
    "<option> must ..."), ``explicit`` (True: stable only below a Courant
    limit), ``solvers`` (names of the iteration counts in StepStats) and
    implement ``advance(x)``; those with history extend ``state``/``restore``;
    explicit ones set ``courant_limit``, those with explicit advection only
    ``advective_courant_limit``. The base holds stepping (``prepare``, ``step``, ``advance``,
    ``counts``, the ∇⁴ and the stage's clock), Δt (``set_dt``), phase (``set_phase``) and
    history (``state``, ``restore``, ``carried_arrays``); the rest are capabilities
    (``steppers.capabilities``) a stepper takes where it has them and their users check:
    ``GraphCapture`` (a step replayed as a graph, ``capturable``), ``ErrorEstimates`` and
    ``TrialSteps`` (under error control), and ``Described`` (its name, options and lines, every
    stepper's).

    What a stepper may ask of the model is ``model.protocol.SteppingModel``: the tendency
    (``rhs``, ``rhs_update``, ``rhs_part``, ``set_time``), the ∇⁴ (``hyperviscosity``, ``hv``),
    states (``new_state``, ``lincomb``, ``pointwise``, ``bad_nodes``), the operators beside the
    tendency (``operators``: the gravity-wave operator's G and D, as
    ``model.gravity_wave.GravityWaveOperator`` and the Helmholtz solves use them) and where it
    runs (``topology``, ``launches``, ``terms``, ``g``); ``tests/test_layers.py`` holds steppers,
    solvers and the adjoint to it. What the adjoint may ask of a stepper is ``steppers.protocol``
    (``DifferentiableStepper`` and each family's description of its step), held there too.
    """

    explicit = False
    # True: its step calls only the verbs the adjoint's tape reads (``steppers.protocol``), so
    # ``adjoint.gradient`` differentiates it: the explicit steppers, those that solve with L and
    # the multirate and local ones; not the JFNK ``implicit`` nor the exponential ones
    differentiable = False
    # explicit steppers: the largest stable (|v| + sqrt(g h)) Δt / Δx at t = 0, Δx the
    # nearest-node distance: the smallest of bisections on TC2 (5 days) at ne 4 np 4,
    # ne 8 np 4 and ne 3 np 6 (leapfrog 0.618 / 0.580 / 0.646, leapfrog_trapezoidal
    # 0.926 / 0.883 / 1.005, ssprk3 1.195 / 1.108 / 1.242, rk4 1.853 / 1.726 / 1.919)
    courant_limit: float | None = None
    courant_limit_source = "measured on TC2"  # where ``courant_limit`` comes from, for the warning
    # steppers whose advection alone is explicit (IMEX): the largest |v| Δt / Δx at t = 0
    # the study ran stably (a warning threshold, not a bisection)
    advective_courant_limit: float | None = None
    solvers: tuple[str, ...] = ()
    # True: once recorded, a step launches the same kernels with the same arguments every
    # step and reads nothing back (the explicit steppers; the semi-implicit and IMEX ones
    # with ``deferred``), so ``Simulation`` may replay it as a captured graph (``graph_key``).
    # JFNK's Newton test reads its residual on the host every iteration: never capturable.
    capturable = False
    # True (``Simulation.run`` sets it): a step leaves its solvers' device counters
    # unread (``StepStats.iterations`` empty for them), read by ``counts`` once a block
    deferred = False
    # True: ``set_dt`` may change Δt between steps (a one-step method whose launches take Δt's
    # coefficients as arguments, or that reads Δt each step). False where Δt is part of the history (leapfrog's
    # x(n−1), BDF2's, a multirate split's substeps): those run at a fixed Δt only.
    variable_dt = False
    # None: a step's ∇⁴ is one ``_hyperviscosity`` over its own span (a one-step method), so it may
    # be applied every k steps over kΔt (the scene's ``hyperviscosity.every``); else why it runs
    # after every step, the end of "<stepper> ..." (the leapfrog family: on a three-level scheme's
    # x(n+1) over 2Δt)
    dense_hyperviscosity: str | None = None
    # an embedded pair's local error estimate of the last step, (3, N) in x's units
    # (``runge_kutta``); None for a stepper without one
    error_estimate = None
    embedded_order = 0  # the embedded solution's order (0: no embedded pair)

    def __init__(self, model: ShallowWater, dt: float, options=None):
        if not dt > 0:
            raise ValueError(f"dt must be > 0 (got {dt})")
        if options is None:
            options = self.Options()
        if not isinstance(options, self.Options):
            raise TypeError(f"{self.name} options must be {self.Options.__name__} (got {type(options).__name__})")
        self.model, self.dt, self.options = model, float(dt), options
        self.N = model.topology.N
        self.steps = 0  # steps taken since the initial state
        self.t0 = 0.0  # s, the model time of that state (a branched run's start; ``Simulation`` sets it)

    def prepare(self, x: wp.array2d) -> None:
        """Called with the initial state x (3, N) before the first step and before any
        ``restore`` (``Simulation``): what a stepper fixes from the flow at the start
        (local time stepping's element levels). Nothing here."""

    def set_phase(self, k: int) -> None:
        """Put the stepper at step k of its run (the gradient's sweep, taking step k again from a
        state it held): its step count, on which its clock and its start read. Its Δt and t0 are
        set apart (``set_dt``)."""
        self.steps = k

    def carried_arrays(self) -> list:
        """The (3, N) device arrays the next step reads besides x that a step writes (the
        gradient's sweep holds them in its states beside x, in this order): none here."""
        return []

    # -- what carries over between steps -------------------------------------------
    def state(self) -> dict:
        """Everything besides x that the next step depends on: numpy arrays
        (copies) and Python scalars, keyed by name."""
        return {"steps": self.steps}

    def restore(self, state: dict) -> None:
        """Continue from ``state()`` of a stepper of the same kind, options, dt and grid.
        Raises ValueError naming a missing or misshapen entry."""
        self.steps = int(entry(self, state, "steps"))

    # -- stepping ----------------------------------------------------------------------
    def step(self, x: wp.array2d) -> StepStats:
        """Advance x (3, N) in place by dt; count the step."""
        stats = self.advance(x)
        self.steps += 1
        return stats

    def advance(self, x: wp.array2d) -> StepStats:
        """The step's work on x (3, N) in place, the step not counted: the hook each stepper
        implements. Step with ``step``, which counts it: the step's index decides the ∇⁴ under
        ``hyperviscosity.every`` k > 1 (``_dissipates``) and the stages' model time (``_at``), so
        ``advance`` alone never reaches the k-th step (TC5 ne6, every 2: no ∇⁴ in a day, h 10 m
        off the run's), unless the index is set before each call (``set_phase``, as the gradient's
        sweep does)."""
        raise NotImplementedError

    def set_dt(self, dt: float) -> None:
        """Take the next steps with Δt = ``dt`` (s): the state of the stepper as if it had been
        built with ``dt`` and restored from this one's ``state()`` (``_dt_changed`` drops what
        depends on the old Δt). The model time reached, t0 + steps·Δt, stays (t0 rebased).
        ValueError: dt not > 0, or a stepper that cannot change Δt (``variable_dt``)."""
        if not self.variable_dt:
            raise ValueError(f"{self.name} cannot change its dt between steps (its history is the old dt's)")
        if not dt > 0:
            raise ValueError(f"dt must be > 0 (got {dt})")
        dt = float(dt)
        if dt != self.dt:
            self.t0 += self.steps * (self.dt - dt)
            self.dt = dt
            self._dt_changed()

    def _dt_changed(self) -> None:
        """Forget what was built for the old Δt (recorded launches with Δt folded in)."""

    def counts(self) -> dict:
        """Solver iterations (by name, as ``StepStats.iterations``) counted on the device
        by the steps since the last call, then zeroed: one host read. Raises
        ``StepFailure`` when a solve among them failed (the step unknown: re-run them one
        by one to name it). {} for steppers that count on the host (in ``StepStats``)."""
        return {}

    def _dissipates(self) -> bool:
        """Whether the step under way (index ``steps``) ends with the ∇⁴ (``_hyperviscosity``)."""
        return (self.steps + 1) % self.model.hv.every == 0

    def _hyperviscosity(self, x: wp.array2d) -> None:
        """The step's ∇⁴ on x (3, N) in place over Δt, split from the dynamics
        (``model.hyperviscosity``; HOMME ``advance_hypervis``); with the scene's
        ``hyperviscosity.every`` k > 1, over kΔt at the end of every k-th step (steps k, 2k, ...:
        by the step's index, so a restart or the gradient's step taken again agrees) and not at
        the others: a lever on the ∇⁴'s cost where its limit is far above Δt (one substep, or
        one RKL1 super-step, covers kΔt; docs/explanation/efficiency.md, "A step's cost")."""
        hv = self.model.hv
        if hv is None or hv.every == 1:
            self.model.hyperviscosity(x, self.dt)
        elif self._dissipates():
            self.model.hyperviscosity(x, hv.every * self.dt)

    def _at(self, c: float) -> None:
        """Set the model time to t(n) + c·Δt, t(n) = t0 + steps·Δt, for the next RHS
        evaluation (a stage's abscissa c; ``ShallowWater.set_time``: a time-dependent
        forcing reads it, nothing else does)."""
        self.model.set_time(self.t0 + (self.steps + c) * self.dt)


# -- what a stepper's implementation builds on: its work arrays, its history's entries --------------
def work_array(stepper: Stepper, dtype=f64) -> wp.array:
    """A (rows, N) array of zeros of ``dtype`` (float64, or a float32 state's: ``ExplicitRK``) on
    ``stepper``'s device, a row for each of the model's state's (3 and its tracers'): a stage's,
    or a history's."""
    return wp.zeros((stepper.model.rows, stepper.N), dtype=dtype, device=stepper.model.topology.device)


def device_counts(stepper: Stepper) -> dict:
    """A step's device-counted iterations for its ``StepStats``: read now (``counts``, the step's
    one host read), or {} when ``deferred``."""
    return {} if stepper.deferred else stepper.counts()


def entry(stepper: Stepper, state: dict, key: str):
    """``state[key]`` of ``stepper``'s ``state()``; ValueError naming a missing entry."""
    if key not in state:
        raise ValueError(f"{stepper.name} stepper state lacks {key!r}")
    return state[key]


def gathered_copy(stepper: Stepper, a: wp.array) -> np.ndarray | None:
    """A whole-grid copy of a (rows, N) array of ``stepper``'s, gathered from every rank on rank 0
    (call on every rank; None on the others)."""
    whole = stepper.model.topology.gather(a.numpy())
    return None if whole is None else whole.copy()


def load_entry(stepper: Stepper, a: wp.array, state: dict, key: str) -> None:
    """Set a (rows, N) array of ``stepper``'s from a whole-grid entry of ``state`` (read on rank 0
    when several ranks: None on the others; call on every rank)."""
    where = f"{stepper.name} stepper state {key!r}"
    a.assign(stepper.model.topology.distribute(entry(stepper, state, key), a.shape[0], where))
