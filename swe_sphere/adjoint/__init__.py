"""Gradients of a run (issue 66): the adjoint of an explicit step (``explicit``), binomial
checkpointing of the reverse sweep (``revolve``), observations of h at points and steps
(``observations``) and ``gradient``, the cost of a run's final state or of the run and its
gradient with respect to the initial state."""

from .gradient import Gradient, HeightMisfit, gradient
from .observations import HeightObservations, PointHeights

__all__ = ["Gradient", "HeightMisfit", "HeightObservations", "PointHeights", "gradient"]
