"""Time steppers behind one interface (``base.Stepper``), by name.

Runge–Kutta methods by their tables, one engine (``runge_kutta``; the tables in
``tables``, their checks in ``butcher``): explicit ``ssprk3``, ``rk4``,
``kgu35`` and the embedded pairs ``bs32``, ``dp54``, ``ssprk43``, ``rdpk3sp35`` (their
``error_estimate`` a step's local error); ``imex`` (ARS IMEX pairs,
the linear gravity waves implicit) and the embedded IMEX pairs ``ark324``, ``ark436``;
``tableau`` (an explicit table or IMEX pair from the scene). Their own classes:
explicit ``leapfrog``, ``leapfrog_trapezoidal``, ``fbrk32`` (``explicit``);
``semi_implicit`` (leapfrog, gravity waves averaged over n ± 1); ``implicit``
(JFNK θ-method / BDF2). ``imex``, ``semi_implicit`` and ``implicit`` share the
linear gravity-wave operator ``model.gravity_wave.GravityWaveOperator`` and its
Helmholtz solve ``model.helmholtz.HelmholtzSolver`` (``helmholtz_steps``); the multirate split
uses the operator.
Exponential: ``epi2``, ``epi3`` (φ-functions of the Jacobian by KIOPS).
Multirate (``multirate``: the gravity waves in explicit substeps of their own, no
global solve): ``split_explicit`` (Wicker–Skamarock RK3, forward–backward
substeps), ``mri`` (MIS and MRI-GARK tables); ``lts`` (``local``: local time stepping,
the same engine with the fine elements' tendency fast and the coarse ones' slow).
"""

from __future__ import annotations

from ..core.arguments import got, number_argument
from ..core.errors import ArgumentError, StepFailure, SweSphereError
from ..model.shallow_water import ShallowWater
from .base import Stepper, StepStats, option_types
from .explicit import FBRK32, Leapfrog, LeapfrogTrapezoidal
from .exponential import Epi2, Epi3
from .imex_rk import Imex, imex_pair_steppers
from .implicit import Implicit
from .local import Lts
from .multirate import Mri, SplitExplicit
from .runge_kutta import Tableau, explicit_steppers
from .semi_implicit import SemiImplicit

STEPPERS: dict[str, type[Stepper]] = {
    cls.name: cls
    for cls in (
        Leapfrog,
        LeapfrogTrapezoidal,
        *explicit_steppers(),
        FBRK32,
        SplitExplicit,
        Mri,
        Lts,
        SemiImplicit,
        Implicit,
        Imex,
        *imex_pair_steppers(),
        Tableau,
        Epi2,
        Epi3,
    )
}


def make_stepper(name: str, model: ShallowWater, dt: float, /, **options) -> Stepper:
    """Build a registered stepper from its options as keywords (the scene's
    ``[<name>]`` table): ``name`` a key of ``STEPPERS``, ``model`` a ``ShallowWater``, ``dt``
    the step (s, finite, > 0). Raises ``ArgumentError`` (a ``SweSphereError`` and
    ``ValueError``) naming an unknown stepper, a model or Δt of the wrong kind, or an unknown
    option or invalid value."""
    if not isinstance(name, str) or name not in STEPPERS:
        named = repr(name) if isinstance(name, str) else got(name)
        raise ArgumentError(f"unknown stepper {named} (known: {', '.join(STEPPERS)})")
    if not isinstance(model, ShallowWater):
        raise ArgumentError(f"model must be a ShallowWater (got {got(model)})")
    dt = number_argument("dt", dt, "s", positive=True)
    cls = STEPPERS[name]
    try:
        made = cls.make_options(**options)
    except SweSphereError:
        raise
    except (TypeError, ValueError) as e:
        raise ArgumentError(f"{name}: {e}") from None
    return cls(model, dt, made)


__all__ = ["STEPPERS", "StepFailure", "Stepper", "StepStats", "make_stepper", "option_types"]
