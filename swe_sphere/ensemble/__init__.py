"""Ensembles: N members of one scene in one model, advanced in the same launches
(``ensemble.Ensemble``), on N disjoint copies of the grid's elements (``members.MemberGrid``).

May import: every layer below (``simulation`` down to ``kernels``)."""

from .ensemble import Ensemble
from .initial import MemberFile, Perturbation, Variants
from .members import MemberGrid

__all__ = ["Ensemble", "MemberFile", "MemberGrid", "Perturbation", "Variants"]
