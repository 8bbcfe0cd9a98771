"""Element levels for local time stepping: each element steps Δt/2^k, k its level.

An element's explicit step limit scales as 1 / λ_e with its rate
λ_e = σ_e (√(g h_max,e) + |v|_max,e) (1/s): σ_e its largest singular value of D⁻¹ over its
GLL nodes (HOMME's "normDinv", ``quality.element_sizes``), h_max,e and |v|_max,e the largest
depth and wind speed on it (its gravity-wave and advective limits together, as HOMME's
``print_cfl`` takes them). Levels count from the coarsest (0) to the finest (K): the element
with the largest rate (the one that sets a global explicit step) is on level K, and an element
whose rate is at most λ_max / 2^j is on level K − j or finer (j = ⌊log₂(λ_max / λ_e)⌋, at most
``max_levels`` − 1), so a step of Δt/2^k on level k is within each element's limit whenever the
finest level's Δt/2^K is within the worst element's. Then neighbours (elements sharing a node)
are brought to at most one level apart by moving the coarser one finer (Rietmann, Grote,
Peter & Schenk 2017, J. Comput. Phys. 334:308, §3: the same rule; finer is always stable).

The saving's bound (``ElementLevels.bound``): per coarse step Δt a global step at the finest
level's Δt/2^K evaluates every element 2^K times, a local one element e 2^(k_e) times;
their ratio E·2^K / Σ_e 2^(k_e) is what local stepping can save before its overhead.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .quality import element_sizes

if TYPE_CHECKING:  # scipy.sparse is imported where used: every run's start imports this module (0.2-0.5 s)
    import scipy.sparse as sp

ROUNDOFF = 1e-9  # log₂ ratios this close below a whole number count as it (a rate λ_max/2^j exactly)


@dataclass(frozen=True)
class ElementLevels:
    """``level`` (E,) int: each element's level (0 the coarsest, steps Δt/2^level);
    ``count``: the levels used (max level + 1)."""

    level: np.ndarray
    count: int

    def elements_per_level(self) -> list[int]:
        """Elements on each level, coarsest first."""
        return np.bincount(self.level, minlength=self.count).tolist()

    def bound(self) -> float:
        """E·2^K / Σ_e 2^(k_e): the element evaluations a coarse step of a global step at
        the finest level's over those of the local one (1 with one level)."""
        return float(self.level.size * 2 ** (self.count - 1) / np.sum(2.0**self.level))

    def describe(self) -> str:
        """'levels 2: 420, 336 elements (coarsest first), bound 1.47x'."""
        counts = ", ".join(map(str, self.elements_per_level()))
        return f"levels {self.count}: {counts} elements (coarsest first), saving's bound {self.bound():.2f}x"


def element_neighbours(grid) -> sp.csr_matrix:
    """(E, E) boolean: elements of ``grid`` (the whole grid) that share a node, each with
    itself; from the unique-node index ``gid`` of every element-local node."""
    import scipy.sparse as sp

    per = grid.np * grid.np
    rows = np.repeat(np.arange(grid.nelem), per)
    incidence = sp.csr_matrix(
        (np.ones(grid.nnodes, dtype=np.int32), (rows, grid.gid)), shape=(grid.nelem, grid.nunique)
    )
    return (incidence @ incidence.T).astype(bool).tocsr()


def element_rates(grid, x: np.ndarray, g: float) -> np.ndarray:
    """λ_e = σ_e (√(g h_max,e) + |v|_max,e) (E,), 1/s, of the state x (3, N) (u, v in m/s,
    h the depth in m, element-local) on ``grid``; ``g`` in m/s²."""
    per = (grid.nelem, grid.np * grid.np)
    u, v, h = (np.asarray(r).reshape(per) for r in x)
    speed = np.sqrt(u * u + v * v).max(axis=1)
    depth = np.maximum(h, 0).max(axis=1)
    return element_sizes(grid).norm_dinv * (np.sqrt(g * depth) + speed)


def element_levels(grid, rate: np.ndarray, max_levels: int, margin: float = 1.0) -> ElementLevels:
    """The levels of ``grid``'s elements (the whole grid) from their rates λ_e (E,) > 0
    (``element_rates``): at most ``max_levels`` of them, neighbours at most one apart
    (the module docstring); with ``margin`` m ≥ 1 an element is K − j or finer when
    m λ_e ≤ λ_max / 2^j (the finest element's own level unchanged: for a method whose
    coupled levels hold less than each element's own limit). Raises ValueError for
    max_levels < 1, margin < 1 or a rate that is not finite and positive."""
    if isinstance(max_levels, bool) or int(max_levels) != max_levels or max_levels < 1:
        raise ValueError(f"max_levels must be an integer >= 1 (got {max_levels})")
    rate = np.asarray(rate, dtype=np.float64)
    if rate.shape != (grid.nelem,) or not np.all(np.isfinite(rate) & (rate > 0)):
        raise ValueError("element rates must be finite and > 0, one per element")
    if not margin >= 1.0:
        raise ValueError(f"margin must be >= 1 (got {margin})")
    # j: levels below the finest, from each element's own limit
    j = np.floor(np.maximum(np.log2(rate.max() / (margin * rate)), 0.0) + ROUNDOFF).astype(np.int64)
    j = np.minimum(j, int(max_levels) - 1)
    adjacency = element_neighbours(grid)
    while True:  # a neighbour's j + 1 bounds j: move the coarser element finer until none is two apart
        nearest = _neighbour_min(adjacency, j)
        moved = np.minimum(j, nearest + 1)
        if np.array_equal(moved, j):
            break
        j = moved
    level = j.max() - j
    return ElementLevels(level.astype(np.int64), int(level.max()) + 1)


def _neighbour_min(adjacency: sp.csr_matrix, values: np.ndarray) -> np.ndarray:
    """For each row of ``adjacency``, the least of ``values`` over its columns."""
    per_entry = values[adjacency.indices]
    return np.minimum.reduceat(per_entry, adjacency.indptr[:-1])
