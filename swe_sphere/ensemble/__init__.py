"""Ensembles: N members of one scene advanced together (``ensemble.Ensemble``): an explicit
stepper's in the same launches, on N disjoint copies of the grid's elements
(``members.MemberGrid``); any other's, or members whose g or ν differ, each on a model of its
own (``units``).

May import: every layer below (``simulation`` down to ``kernels``)."""

from .ensemble import Ensemble
from .initial import MemberFile, Perturbation, Variants
from .members import MemberGrid

__all__ = ["Ensemble", "MemberFile", "MemberGrid", "Perturbation", "Variants"]
