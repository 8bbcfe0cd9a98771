"""A run's step control (``Scene.control``): the integrator's ``StepControl`` (``integrator.control``,
its names here as the run knows them; the run's Δt policy under it is ``guard.RunObserver.steer``'s)."""

from ..integrator.control import ATOL_FLOOR, BALANCE_EVERY, CAP_EVERY, DT_GRID, StepControl

__all__ = ["ATOL_FLOOR", "BALANCE_EVERY", "CAP_EVERY", "DT_GRID", "StepControl"]
