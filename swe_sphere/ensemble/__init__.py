"""Ensembles: ``Ensemble``, the deprecated name of a ``Simulation`` of members
(``Simulation(scene, members=N, initial=...)``, issue 116: one driver), and the members' starts
and grid re-exported from ``members`` where they were.

May import: every layer below (``simulation`` down to ``kernels``)."""

from ..members.grid import MemberGrid
from ..members.initial import MemberFile, Perturbation, Variants
from .ensemble import Ensemble

__all__ = ["Ensemble", "MemberFile", "MemberGrid", "Perturbation", "Variants"]
