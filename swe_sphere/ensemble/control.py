"""An ensemble's Δt chosen step to step (``Scene.control``, issue 100): the run's step control
(``simulation.adaptive.StepControl``) over the members in the same launches, so that every
member takes the same Δt (member-uniform), its error norm the RMS over every member's nodes
(``ErrorNorm`` on the ``MemberGrid``'s copies) and its Courant cap the largest over them; a step
is rejected where the members' error together is above the tolerance. The steps land on the
output and restart days as a run's do; ``StepControl.state`` goes in the restart file."""

from __future__ import annotations

from ..core.constants import DAY
from ..core.errors import ArgumentError
from ..integrator import Integrator, Observer, Rewind, Stop, Unit
from ..simulation.adaptive import StepControl

# ``Ensemble.add_callback``'s refusal of a callback every so many days under step control
STEERED = "every_days: under step control the steps are the controller's (give every_steps)"


class _Members:
    """What ``StepControl`` reads of a run, of the one ``Unit`` that steps every held member."""

    def __init__(self, unit: Unit, scene):
        self.unit, self.scene, self.model, self.x = unit, scene, unit.model, unit.x
        self.topology, self.g = unit.model.topology, unit.model.g
        self.device = self.topology.device

    @property
    def last_good(self):
        return self.unit.start

    @last_good.setter
    def last_good(self, value) -> None:  # the control's tries swap their start in (``StepControl.step``)
        self.unit.start = value

    def try_step(self, x):
        """A try of every member on x (3, members·n): a graph where the unit's steps may be one."""
        return self.unit.graphed.step(self.unit.stepper, self.unit.model, x, False)


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
    return StepControl(scene.control, units[0].stepper, _Members(units[0], scene))


class _Kept(Rewind):
    """A controlled step's start kept by the control itself (``StepControl.step``): nothing here."""

    def keep(self, active: list, whole: bool) -> dict:
        return {}


def controlled_steps(core: Integrator, control: StepControl, day: float, most: int, observer: Observer) -> Stop:
    """Accepted steps of ``core``'s one unit (every member) toward model ``day`` (days from t =
    0), ``most`` at the most, each landed on ``day`` where it reaches it and each a block of the
    integrator checked at once (``observer.vouched``: the norm's finite value, else
    ``BadNodes.first``). Returns why it stopped (``integrator.Stop``; a bad state kept for the
    blow-up's report). ``BlowUp`` where Δt falls below ``time.dt_min``."""
    with core.stepping_by(lambda unit, j, watch: control.step_to(unit.x, day), _Kept()):
        for _ in range(most):
            if control.t >= day * DAY:
                break
            stop = core.advance(core.step + 1, observer)
            if stop.bad is not None:
                return stop
    return Stop()
