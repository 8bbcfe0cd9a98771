"""Some of a model's elements: the ranges its kernels run over and the DSS of their copies alone
(local time stepping's levels, a rank's blocks of tendency lanes)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import warp as wp


class ElementPart(NamedTuple):
    """Some of a model's elements (``ElementPart.of``): ``runs`` the (start, stop)
    element ranges its kernels run over (its elements, and any others between them that a
    launch less is worth computing), ``nelem`` its elements, ``nodes`` (int32 device array)
    the element-local nodes whose unique node one of them touches (every copy), ``copies``
    the DSS's table of its own copies alone (``Topology.part_copies``), ``tend`` (rows, N) the
    element-local tendency its kernels write (in the model's precision), ``exact`` the ranges of
    its elements alone (a gradient's transposes run over these: a gap's elements are computed,
    not assembled)."""

    runs: list
    nelem: int
    nodes: wp.array
    copies: object
    tend: wp.array2d
    exact: list

    @classmethod
    def of(cls, model, elements, gap: int = 0, whole=None) -> ElementPart:
        """The part of ``elements`` (indices of elements ``model``'s topology holds, ascending,
        distinct): its tendency kernels run over ranges of consecutive elements that hold them,
        two ranges merged where at most ``gap`` other elements lie between (computed, and left
        out of the assembly: a launch's fixed cost against theirs); its DSS gathers its
        own elements' copies alone (``Topology.part_copies``), with ``whole`` (nelem_total,)
        bool, the part over the whole grid, those other ranks hold too (needed on several
        ranks); its tendency in the model's precision. ValueError for indices that are not
        ascending, distinct elements held; ``gap`` < 0; several ranks without ``whole``."""
        topology = model.topology
        e = np.asarray(elements, dtype=np.int64)
        nelem = topology.grid.nelem
        if e.ndim != 1 or (e.size and (e[0] < 0 or e[-1] >= nelem or np.any(np.diff(e) <= 0))):
            raise ValueError(f"part elements must be ascending distinct indices in 0..{nelem - 1}")
        if isinstance(gap, bool) or int(gap) != gap or gap < 0:
            raise ValueError(f"gap must be an integer >= 0 (got {gap})")
        nodes, copies = topology.part_copies(e, whole)
        tend = wp.zeros((model.rows, topology.N), dtype=model.tendency_arrays.dtype, device=topology.device)
        return cls(element_runs(e, gap), int(e.size), nodes, copies, tend, element_runs(e, 0))


def element_runs(elements, gap: int) -> list[tuple[int, int]]:
    """(start, stop) ranges of consecutive element indices holding ``elements`` (ascending,
    distinct), two merged where at most ``gap`` others lie between."""
    runs = []
    for k in np.asarray(elements).tolist():
        if runs and k - runs[-1][1] <= gap:
            runs[-1][1] = k + 1
        else:
            runs.append([k, k + 1])
    return [tuple(r) for r in runs]
