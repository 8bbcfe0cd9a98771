"""What the adjoint (``adjoint/``) and the gradient's driver (``adjoint.gradient``) may ask of a
stepper: ``DifferentiableStepper``, the members every stepper with a gradient offers, and, where
a family's step needs more to be reversed, one method of its own that returns a frozen
description of that step (``tests/test_layers.py`` holds ``adjoint/`` to these members, as
``model.protocol`` holds steppers to the model's).

A new stepper's author reads this first. The driver replays the run: it sets Δt and the clock
of step k (``dt``, ``set_dt``, ``t0``), puts the stepper at step k's phase (``set_phase``), copies
x and what the step carries besides x (``carried_arrays``) in and out of the sweep's states, and
takes the step (``step``), after ``prepare`` from x(0). It picks the step's adjoint by ``name``
for the multirate families (``adjoint.gradient.ADJOINTS``); any other ``explicit`` stepper (every
explicit Butcher table, FB-RK(3,2), leapfrog, leapfrog-trapezoidal) and any that solves with the
gravity-wave operator L (offering ``linear``, the ``model.gravity_wave.GravityWaveOperator``, its
H fixed by the first step: semi_implicit, the IMEX pairs and tables) needs nothing more: its
adjoint takes a twin of it (its class, ``dt`` and ``options``) on a tape of the model's verbs,
L's update and its Helmholtz solve, and reverses the tape (``adjoint.tape``), so a step written
with those verbs (``model.protocol``) differentiates as it is. The multirate families' adjoints
take the step's stages again from x(n) and transpose them; what they need to know of the step is
the family's description, which the stepper returns from one method, so the step's coefficients
(MRAB3's weights) live in the stepper alone:

- ``split_explicit()``: ``SplitExplicitSteps``, its stages, substeps and substep;
- ``multirate()`` (mri; lts with a multirate table on several levels): ``MultirateSteps``;
- ``local()`` (lts): ``LocalSteps``, which of its three steps it takes (one level's table, MRAB3's
  ``MrabSteps``, or the multirate levels').

A description read before the first step may hold what that step fixes unfixed (a multirate
step's n_fast and H): an adjoint asks for it again once the sweep has stepped forward.
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

    def set_dt(self, dt: float) -> None: ...
    def set_phase(self, k: int) -> None: ...
    def prepare(self, x) -> None: ...
    def step(self, x): ...
    def carried_arrays(self) -> list: ...


class SolvingStepper(DifferentiableStepper, Protocol):
    """A step that solves with the gravity-wave operator L (semi_implicit, the IMEX pairs)."""

    linear: object  # ``model.gravity_wave.GravityWaveOperator``


@dataclass(frozen=True)
class SplitExplicitSteps:
    """The split-explicit step (``multirate.SplitExplicit``): its stages' ``c`` (Fractions of Δt)
    and substeps ``n_fast`` (None before the first step), the mean depth ``H`` (m; 0 before the
    first step) and ``depth`` (1, N) H at every node, ``slow_terms`` (the slow part's), the
    divergence damping β, and the stepper's own ``substep`` (``SplitExplicit.forward_backward``)
    with the arrays it writes: ``wind`` (3, N: the substeps' wind, the stage's full depth) and
    ``weighted`` (3, N: row 2 the next substep's h̃)."""

    c: tuple
    n_fast: tuple | None
    H: float
    depth: object
    slow_terms: tuple
    divergence_damping: float
    substep: Callable
    wind: object
    weighted: object


@dataclass(frozen=True)
class MultirateSteps:
    """A multirate table's step (``multirate.Mri``; ``local.Lts`` on several levels): its
    ``table`` (``multirate_options.MriTable``: alpha, beta, beta1, gamma, c, d), the ``inner``
    explicit table (None for the fbrk32 inner method), each solve's fast steps ``n_fast`` (None
    before the first step), and the split: ``slow(x, out)`` and ``fast(x, out, rho)``. The
    gravity waves' split (mri) has the mean depth ``H`` (m; 0 before the first step), ``depth``
    (1, N) and ``slow_terms``; the levels' split (lts) ``level`` (the element levels, (nelem,)
    of the whole grid) and ``parts`` (the coarse and the finer levels' ``ElementPart``), the
    others None."""

    table: object
    inner: Table | None
    n_fast: tuple | None
    slow: Callable
    fast: Callable
    H: float | None = None
    depth: object = None
    slow_terms: tuple | None = None
    level: np.ndarray | None = None
    parts: tuple | None = None


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
    """Which step local time stepping (``local.Lts``, after ``prepare``) takes: ``single`` the
    inner method's table on one level, ``mrab`` MRAB3's, or neither: the multirate levels'
    (``multirate()``)."""

    single: Table | None
    mrab: MrabSteps | None


class SplitExplicitStepper(DifferentiableStepper, Protocol):
    def split_explicit(self) -> SplitExplicitSteps: ...


class MultirateStepper(DifferentiableStepper, Protocol):
    def multirate(self) -> MultirateSteps: ...


class LocalStepper(MultirateStepper, Protocol):
    def local(self) -> LocalSteps: ...


PROTOCOLS = (
    DifferentiableStepper,
    SolvingStepper,
    SplitExplicitStepper,
    MultirateStepper,
    LocalStepper,
)


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
