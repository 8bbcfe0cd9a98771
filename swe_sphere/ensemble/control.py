"""An ensemble's Δt chosen step to step (``Scene.control``, issue 100): the run's step control
(``simulation.adaptive.StepControl``) over the members in the same launches, every member at the
same Δt, its error norm the RMS over every member's nodes and its Courant cap the largest over
them; the steps land on the output and restart days as a run's do."""

from __future__ import annotations

from ..core.errors import ArgumentError
from ..simulation.adaptive import StepControl

# ``Ensemble.add_callback``'s refusal of a callback every so many days under step control
STEERED = "every_days: under step control the steps are the controller's (give every_steps)"


def member_control(scene, units: list, layout: str, comm) -> StepControl | None:
    """The step control of ``scene``'s members (None at a fixed Δt): ``ArgumentError`` (one
    line) where they do not step in the same launches (``layout`` "in_turn": a model each) or
    lie on several MPI ranks (``comm``), which would take Δt apart."""
    if scene.control is None:
        return None
    if layout != "shared" or comm is not None:
        where = "over MPI ranks" if comm is not None else "each on a model of its own"
        raise ArgumentError(
            f"scene: its dt is controlled (time.control = {scene.control.mode!r}), which an ensemble takes with its "
            f"members in the same launches, one rank (an explicit pair, the members' g and ν alike, blow_up 'stop'), "
            f"not {where}"
        )
    return StepControl(scene.control, units[0], scene.start_day)
