"""Gradients of a run: ``gradient``, the cost of a run's final state or of the run and its
gradient with respect to the initial state (and parameters), each step taken again on a tape
and reversed (``tape``, ``reverse``), the sweep checkpointed (``revolve``, ``disk``); its costs
(``costs``), such as observations of h at points and steps (``io.observations``, here too)."""

from ..io.observations import HeightObservations, PointHeights
from .costs import HeightMisfit
from .gradient import Gradient, gradient

__all__ = ["Gradient", "HeightMisfit", "HeightObservations", "PointHeights", "gradient"]
