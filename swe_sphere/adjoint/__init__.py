"""Gradients of a run (issue 66): the adjoint of an explicit step (``explicit``), binomial
checkpointing of the reverse sweep (``revolve``) and ``gradient``, the cost of a run's final
state and its gradient with respect to the initial state."""

from .gradient import Gradient, HeightMisfit, gradient

__all__ = ["Gradient", "HeightMisfit", "gradient"]
