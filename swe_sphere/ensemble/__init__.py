"""Ensembles: ``Ensemble``, the deprecated name of a ``Simulation`` of members
(``Simulation(scene, members=N, initial=...)``, issue 116: one driver): constructing one says so
in one ``DeprecationWarning`` line and makes that ``Simulation``, whose names it has, every one
meaning what it means there (issue 124: its own old names, ``step(n)`` among them, which hid
``Simulation.step``, are gone); and the members' starts and grid re-exported from ``members``
where they were.

May import: every layer below (``simulation`` down to ``kernels``)."""

from __future__ import annotations

import warnings

from ..members.grid import MemberGrid
from ..members.initial import MemberFile, Perturbation, Variants
from ..simulation.simulation import Simulation

__all__ = ["Ensemble", "MemberFile", "MemberGrid", "Perturbation", "Variants"]

# the one line constructing an Ensemble warns
DEPRECATED = "swe_sphere.Ensemble is deprecated: Simulation(scene, members=N, initial=...) is the one driver"


class Ensemble(Simulation):
    """Deprecated: ``Simulation(scene, members=N, initial=…)``, which it is, warning once in one
    line where constructed; ``from_checkpoint`` continues an ensemble's restart file.

    Parameters
    ----------
    scene, members, initial
        As ``Simulation``'s (``members`` and ``initial`` here by position; ``members`` None: the
        scene's [ensemble] ``members``, refused where it has none).
    device, progress
        As ``Simulation``'s (no progress bar by default).
    **kw
        ``Simulation``'s other arguments (``comm``, ``graphs``, ``layout``, ``blow_up``,
        ``per_element``, ``threads``) and the scene's overrides.

    Raises
    ------
    ArgumentError, SceneError
        As ``Simulation``'s.
    """

    _of_members = True

    def __init__(self, scene, members: int | None = None, initial=None, *, device=None, progress=False, **kw):
        warnings.warn(DEPRECATED, DeprecationWarning, stacklevel=2)
        super().__init__(scene, device, members=members, initial=initial, progress=progress, **kw)

    @classmethod
    def from_checkpoint(cls, path, device=None, **kw):
        """An ensemble's restart file continued (``Simulation.from_checkpoint(..., members=True)``;
        no progress bar by default)."""
        return Simulation.from_checkpoint.__func__(cls, path, device, members=True, **{"progress": False, **kw})
