"""Gradients of a run: ``gradient``, the cost of a run's final state or of the run and its
gradient with respect to the initial state (and parameters), each step taken again on a tape
and reversed (``tape``, ``reverse``), the sweep checkpointed (``revolve``, ``disk``); costs and
observations of h at points and steps (``observations``)."""

from .gradient import Gradient, gradient
from .observations import HeightMisfit, HeightObservations, PointHeights

__all__ = ["Gradient", "HeightMisfit", "HeightObservations", "PointHeights", "gradient"]
