"""What a stepper may offer beside stepping, Δt, phase and history (``base.Stepper``), each a
capability of its own that its users check, as the adjoint checks ``protocol.DifferentiableStepper``:

- ``Described``: the stepper named and its options made and checked (``make_options``, ``label``,
  ``removed``), what error and step control need of its options (``changes_dt``,
  ``has_estimate``), whether it steps a float32 tendency (``float32_refusal``), its partition (``partition_levels``), its lines and run-file attributes
  (``describe``, ``attrs``): every stepper's (``base.Stepper`` is one), asked by ``config``,
  ``cli`` and the run file.
- ``GraphCapture``: a step replayed as a captured graph (``graph_key``, ``graph_family``,
  ``replayed``) and what a step run twice puts back (``device_arrays``, ``carried``, ``resume``):
  the ``capturable`` steppers; ``core.graphs.GraphedSteps`` checks ``capturable`` first.
- ``ErrorEstimates``: an embedded pair's error estimate asked for, the solves inside the step
  held below it, an FSAL stage carried (``estimate_errors``, ``follow_tolerance``,
  ``carry_last_stage``): the steppers with an ``error_estimate``; ``StepControl`` checks it under
  error control.
- ``TrialSteps``: a step undone (``checkpoint``, ``rollback``: a try that error control
  rejects): the steppers that change Δt (``variable_dt``); ``StepControl`` checks it.
"""

from __future__ import annotations

import dataclasses
import typing
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class NoOptions:
    """A stepper without options."""


def option_types(options_cls) -> dict[str, type]:
    """Option name → type (float, int, str; tuple: a TOML array) of an options dataclass (the scene schema's table)."""
    hints = typing.get_type_hints(options_cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(options_cls)}


class Described:
    """A stepper's description (module doc): its ``name``, ``Options`` (a frozen dataclass),
    ``removed_options`` and ``float32_refusal`` here; its ``variable_dt`` and ``embedded_order``
    the stepper's."""

    name = ""
    Options: type = NoOptions
    removed_options: dict[str, str] = {}  # option → why it is gone, for the error message
    # why the stepper cannot step a float32 tendency (a scene's numerics.precision, refused in one
    # line by ``config.resolve.refuse_precision``); None: it can
    float32_refusal: str | None = None
    # why the stepper cannot carry a float32 state (numerics.precision = "float32_state"; refused
    # likewise); None: it can (``runge_kutta.ExplicitRK``)
    float32_state_refusal: str | None = "its stages and updates are written in float64 only"
    # why the stepper cannot carry passive tracers (a scene's [tracers], refused in one line by
    # ``config.tracers.resolve_tracers``); None: it can (its stages combine whole states, every row)
    tracers_refusal: str | None = "its step is written for u, v and h alone"

    @classmethod
    def removed(cls, key: str) -> str | None:
        """'<key> was removed: <why>' for an option the stepper no longer has, else None."""
        why = cls.removed_options.get(key)
        return None if why is None else f"{key} was removed: {why}"

    @classmethod
    def picked(cls, options) -> type:
        """The class that steps a run with ``options`` (the stepper's table, a dict or its
        ``Options``), whose refusals (``float32_refusal``, ``float32_state_refusal``,
        ``tracers_refusal``) are the run's: the stepper itself, unless its options pick its
        engine (``tableau``: the explicit or the IMEX one by its table, ValueError for a table
        it refuses)."""
        return cls

    @classmethod
    def make_options(cls, **options):
        """The stepper's options from keyword values (defaults for the rest).
        Raises ValueError naming an unknown option or an invalid value."""
        known = option_types(cls.Options)
        for key in options:
            if key in cls.removed_options:
                raise ValueError(cls.removed(key))
            if key not in known:
                raise ValueError(f"unknown option {key!r} for stepper {cls.name} (known: {', '.join(known) or 'none'})")
        return cls.Options(**options)

    @classmethod
    def partition_levels(cls, whole_grid, options: dict) -> np.ndarray | None:
        """(nelem,) int, a level for each element of the whole grid, for a stepper whose work
        goes by levels: a run over several ranks gives each rank its share of every level
        (``grid.topology.rank_parts``). None (here): a partition by element count.
        ``whole_grid()`` builds the whole ``CubedSphere`` (called only where needed);
        ``options`` the scene's ``[<name>]`` table. ValueError names a bad option."""
        return None

    @classmethod
    def changes_dt(cls, options: dict) -> bool:
        """Whether the stepper with these scene options can change its Δt between steps (what
        step control needs): ``variable_dt``, unless its options tie its history to a Δt."""
        return cls.variable_dt

    @classmethod
    def has_estimate(cls, options: dict) -> bool:
        """Whether the stepper with these scene options gives an ``error_estimate`` (an
        embedded pair): what error control needs. ValueError names a bad option."""
        return cls.embedded_order > 0

    @classmethod
    def label(cls, options: dict) -> str:
        """The stepper as ``swe-sphere list`` and a run name it with these scene options."""
        return cls.name

    def attrs(self) -> dict:
        """Global attributes of the run file beyond the scene's (strings, numbers)."""
        return {}

    def describe(self) -> list[str]:
        """Lines a run prints at its start about the stepper beyond its ``label`` (after
        ``prepare``): none here."""
        return []


class GraphCapture:
    """A step that may run as a captured graph (module doc): ``capturable``; the ``model``,
    ``dt``, ``steps`` and ``_dissipates`` of a ``base.Stepper``."""

    capturable = True

    def graph_key(self):
        """What the next step's launches depend on besides the stepper, dt and x: steps with
        equal keys launch the same kernels with the same arguments, so a graph captured of
        one (``wp.ScopedCapture``) replays the others bit for bit. None: the next step
        cannot be captured, because the stepper is not ``capturable`` or the model has a
        time-dependent forcing (its time, ``_at``, is a launch argument a graph would freeze;
        kept on the host, as a device scalar would need a launch per stage to set). With the ∇⁴
        every k > 1 steps, whether this step applies it (``_hyperviscosity``): two graphs."""
        if not self.capturable or "forcing" in self.model.terms:
            return None
        hv = self.model.hv
        return (
            ("step", self.dt) if hv is None or hv.every == 1 else ("step", self.dt, self._dissipates())
        )  # Δt: ``set_dt``

    def graph_family(self):
        """``graph_key`` without Δt where the steps at any Δt take the same kinds of work,
        Δt entering as launch arguments (the stages' coefficients) and counts (the ∇⁴'s
        substeps), nothing read on the host, so that a graph checked against plain launches at
        one Δt vouches for the capture at the others (``graphs.GraphedSteps``); None: each
        key's graph checked."""
        return None

    def replayed(self, stats):
        """Count a step that ran as the graph of an earlier step with the same ``graph_key``
        (whose ``stats`` it returns)."""
        self.steps += 1
        return stats

    def device_arrays(self) -> list:
        """The device arrays a step adds to besides x and ``state()``: its solvers' counters
        (``counts``), what it carries to the next step (``carried``), which a step run twice
        (``graphs.GraphedSteps``' check) restores."""
        return []

    def carried(self):
        """What a step leaves on the host for the next besides ``state()``, true only of the
        ``device_arrays`` as the step left them (an FSAL pair's first stage written ahead,
        ``ExplicitRK.carry_last_stage``): a step run twice (``graphs.GraphedSteps``' check)
        puts it back with them (``resume``), where ``restore`` alone forgets it. None here."""
        return None

    def resume(self, carried) -> None:
        """Take back ``carried()`` after ``restore``, the device arrays put back as they were."""


class ErrorEstimates:
    """An embedded pair's error estimate under error control (module doc)."""

    def follow_tolerance(self, atol: float, rtol: float = 0.0, per_unit_step: bool = False) -> None:
        """Under error control with absolute tolerances ≥ ``atol`` and the relative ``rtol``: an
        iterative solve inside the step tightened to stay below the step's error
        (``implicit.Implicit``, ``imex_rk.ImexRK``); ``per_unit_step``: the tolerances are
        a day's (``time.per_unit_step``: a step's error held to Δt / 1 day of them). Nothing
        here."""

    def estimate_errors(self) -> None:
        """Under error control (the estimate read every step): make ``error_estimate`` from now
        on where the stepper makes it only when asked (``implicit.Implicit``); nothing here."""

    def carry_last_stage(self) -> bool:
        """Under error control (the estimate read every step): carry an FSAL pair's last stage
        over as the next step's first (``runge_kutta.ExplicitRK.carry_last_stage``); whether
        the stepper does. False here."""
        return False


class TrialSteps:
    """A step that may be undone (module doc): ``state``/``restore`` of a ``base.Stepper``."""

    def checkpoint(self):
        """What ``rollback`` needs to undo the next step (a try that error control rejects,
        ``integrator.control.StepControl``): ``state()`` here; a stepper whose state is dear
        to gather keeps device copies instead (``helmholtz_steps.HelmholtzSteps``)."""
        return self.state()

    def rollback(self, saved) -> None:
        """Back to where ``checkpoint()`` returned ``saved``: ``restore`` here."""
        self.restore(saved)
