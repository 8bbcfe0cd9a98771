"""What the adjoint (``adjoint/``) and the gradient's driver (``adjoint.gradient``) may ask of a
stepper: ``DifferentiableStepper``, the members every stepper with a gradient offers, and, where
a family's step needs more to be reversed, one method of its own that returns a frozen
description of that step (``tests/test_layers.py`` holds ``adjoint/`` to these members, as
``model.protocol`` holds steppers to the model's).

A new stepper's author reads this first. The driver replays the run: it sets Δt and the clock
of step k (``dt``, ``set_dt``, ``t0``), puts the stepper at step k's phase (``set_phase``), copies
x and what the step carries besides x (``carried_arrays``) in and out of the sweep's states, and
takes the step (``step``), after ``prepare`` from x(0); an adjoint that takes steps again on a
twin of the stepper gives it the stepper's ``state`` (``restore``). It picks the step's adjoint
by ``name`` (``adjoint.gradient.ADJOINTS``) or by being ``explicit`` or solving with the gravity-wave operator L (offering
``linear``, the ``model.gravity_wave.GravityWaveOperator``): every explicit Butcher table, FB-RK(3,2),
leapfrog, leapfrog-trapezoidal, semi_implicit, the IMEX pairs and tables, split_explicit, mri and
lts need nothing more: their adjoint takes a twin of the stepper (its class, ``dt`` and
``options``, then its ``state``) on a tape of the model's verbs, L's update, the Helmholtz solve
and the operators' gradient and divergence updates, and reverses the tape (``adjoint.tape``), so a
step written with those verbs (``model.protocol``) differentiates as it is. MRAB3 (lts with
``method = "mrab3"``) keeps an adjoint of its own (``adjoint.multirate_ab``), which reads the
description of its step that ``local()`` returns (``LocalSteps``: ``MrabSteps``), so its
coefficients live in the stepper alone.

Shapes: states (3, N) float64 device arrays, N the element-local nodes; times in s.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .butcher import Table


class DifferentiableStepper(Protocol):
    """The members of a stepper (``base.Stepper``) that the adjoint and the gradient's driver use."""

    name: str  # the registry key (``steppers.STEPPERS``)
    dt: float  # Δt (s)
    t0: float  # the model time (s) of the state its step count runs from
    explicit: bool  # True: a table of the engine whose adjoint is its table's (with ``table``)
    options: object  # the stepper's frozen ``Options``

    def state(self) -> dict: ...  # what its first step and ``prepare`` fixed, as a restart keeps it
    def restore(self, state: dict) -> None: ...
    def set_dt(self, dt: float) -> None: ...
    def set_phase(self, k: int) -> None: ...
    def prepare(self, x) -> None: ...
    def step(self, x): ...
    def carried_arrays(self) -> list: ...


class SolvingStepper(DifferentiableStepper, Protocol):
    """A step that solves with the gravity-wave operator L (semi_implicit, the IMEX pairs)."""

    linear: object  # ``model.gravity_wave.GravityWaveOperator``


@dataclass(frozen=True)
class MrabSteps:
    """MRAB3's step (``multirate_ab.MultirateAB3``): ``levels`` (K + 1), ``substeps`` (2^K),
    ``parts`` (one ``ElementPart`` a level; [None]: one level), ``evaluate(k, y, out)`` (level
    k's tendency), ``history`` (the tendencies a level keeps), ``start_steps`` (the coarse steps
    of the start), ``weights`` ((2^K, K + 1, history) in Δt: ``ab3_weights``), ``inner`` (the
    start's explicit table) and ``level`` (the element levels, (nelem,) of the whole grid)."""

    levels: int
    substeps: int
    parts: list
    evaluate: Callable
    history: int
    start_steps: int
    weights: np.ndarray
    inner: Table
    level: np.ndarray


@dataclass(frozen=True)
class LocalSteps:
    """Which step local time stepping (``local.Lts``, after ``prepare``) takes: ``mrab`` MRAB3's,
    or None: a multirate table's or one level's, which the tape reverses (``adjoint.tape``)."""

    mrab: MrabSteps | None


class LocalStepper(DifferentiableStepper, Protocol):
    def local(self) -> LocalSteps: ...


PROTOCOLS = (DifferentiableStepper, SolvingStepper, LocalStepper)


def members(*protocols) -> set[str]:
    """The member names of ``protocols`` (none given: ``PROTOCOLS``, every stepper's and each
    family's), their bases' included."""
    out: set[str] = set()
    for protocol in protocols or PROTOCOLS:
        for klass in protocol.__mro__:
            if klass in (object, Protocol) or klass.__name__ == "Generic":
                continue
            out |= set(vars(klass).get("__annotations__", {}))
            out |= {name for name, v in vars(klass).items() if not name.startswith("_") and callable(v)}
    return out
