"""What the adjoint (``adjoint/``) and the gradient's driver (``adjoint.gradient``) may ask of a
stepper: ``DifferentiableStepper``, the members every stepper with a gradient offers, and
``linear`` of a stepper that solves with the gravity-wave operator L (``SolvingStepper``)
(``tests/test_layers.py`` holds ``adjoint/`` to these members, as ``model.protocol`` holds
steppers to the model's).

A new stepper's author reads this first. The driver replays the run: it sets Δt and the clock
of step k (``dt``, ``set_dt``, ``t0``), puts the stepper at step k's phase (``set_phase``), copies
x and what the step carries besides x (``carried_arrays``, in the order it holds them now) in and
out of the sweep's states, and takes the step (``step``), after ``prepare`` from x(0). The step's
adjoint takes a twin of the stepper (its class, ``dt`` and ``options``, then its ``state``:
``restore``) on a tape of the verbs the step calls — the model's (``model.protocol``), L's update
(``GravityWaveOperator``), its Helmholtz solve and the operators' gradient and divergence updates —
and reverses the tape (``adjoint.tape``, ``adjoint.reverse``). So every stepper written with those
verbs differentiates as it is, with no adjoint code: it says so (``differentiable``; the
explicit ones, those that offer ``linear``, the ``model.gravity_wave.GravityWaveOperator`` with
its H fixed by the first step, split_explicit, mri and lts). The JFNK ``implicit`` and the
exponential steppers step through kernels and Krylov solves of their own, which the tape cannot
read: they have no gradient.

Shapes: states (3, N) float64 device arrays, N the element-local nodes; times in s.
"""

from __future__ import annotations

from typing import Protocol


class DifferentiableStepper(Protocol):
    """The members of a stepper (``base.Stepper``) that the adjoint and the gradient's driver use."""

    name: str  # the registry key (``steppers.STEPPERS``)
    dt: float  # Δt (s)
    t0: float  # the model time (s) of the state its step count runs from
    differentiable: bool  # True: its step is the verbs the tape reads (``base.Stepper``)
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


PROTOCOLS = (DifferentiableStepper, SolvingStepper)


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
