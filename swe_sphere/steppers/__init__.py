"""Time steppers behind one interface (``base.Stepper``), by name.

Explicit: ``leapfrog``, ``leapfrog_trapezoidal``, ``ssprk3``, ``rk4``, ``kgu35``, ``fbrk32``;
``semi_implicit`` (leapfrog, gravity waves averaged over n ± 1); ``implicit``
(JFNK θ-method / BDF2); ``imex`` (ARS IMEX Runge–Kutta). The last three share
the linear gravity-wave operator ``helmholtz.GravityWave``. ``tableau``: an
explicit or IMEX table from the scene, through the RK and IMEX machinery (``butcher``).
Exponential: ``epi2``, ``epi3`` (φ-functions of the Jacobian by KIOPS).
"""

from __future__ import annotations

from ..model import ShallowWater
from .base import StepFailure, Stepper, StepStats, option_types
from .butcher import Tableau
from .exponential import Epi2, Epi3
from .explicit import FBRK32, Leapfrog, LeapfrogTrapezoidal, rk_steppers
from .imex import Imex
from .implicit import Implicit
from .semi_implicit import SemiImplicit

STEPPERS: dict[str, type[Stepper]] = {
    cls.name: cls for cls in (Leapfrog, LeapfrogTrapezoidal, *rk_steppers(), FBRK32, SemiImplicit, Implicit, Imex, Tableau, Epi2, Epi3)
}


def make_stepper(name: str, model: ShallowWater, dt: float, /, **options) -> Stepper:
    """Build a registered stepper from its options as keywords (the scene's
    ``[<name>]`` table); ValueError names an unknown stepper, option or value."""
    if name not in STEPPERS:
        raise ValueError(f"unknown stepper {name!r} (known: {', '.join(STEPPERS)})")
    cls = STEPPERS[name]
    return cls(model, dt, cls.make_options(**options))


__all__ = ["STEPPERS", "StepFailure", "Stepper", "StepStats", "make_stepper", "option_types"]
