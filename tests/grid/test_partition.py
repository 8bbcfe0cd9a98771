"""Space-filling-curve partition of the cube's elements (``swe_sphere.grid.partition``)."""

from __future__ import annotations

import numpy as np
import pytest

from swe_sphere.grid import partition as P

from helpers import cached_grid


@pytest.mark.parametrize("ne", [1, 2, 3, 4, 5, 7, 8])
def test_curve_visits_every_element_once_through_edge_neighbours(ne):
    g = cached_grid(ne, 2)
    order = P.sfc_order(ne)
    assert np.array_equal(np.sort(order), np.arange(g.nelem))
    nbrs = P.element_neighbours(ne)
    assert nbrs.shape == (g.nelem, 4)  # every element of the cube has four edge neighbours
    corners = g.gid.reshape(g.nelem, 4)  # np = 2: the nodes are the corners
    for e in range(g.nelem):  # the elements sharing two corners, and only those
        shared = [len(set(corners[e]) & set(corners[f])) for f in range(g.nelem)]
        assert sorted(f for f in range(g.nelem) if f != e and shared[f] == 2) == nbrs[e].tolist()
    steps = [order[k + 1] in nbrs[order[k]] for k in range(g.nelem - 1)]
    assert all(steps), f"curve jumps at {steps.index(False)}"


@pytest.mark.parametrize("ne,parts", [(2, 2), (3, 5), (4, 3), (4, 7), (5, 150)])
def test_partition_covers_once_balanced_and_contiguous(ne, parts):
    g = cached_grid(ne, 2)
    chunks = P.partition(ne, parts)
    sizes = [len(c) for c in chunks]
    assert len(chunks) == parts and sum(sizes) == g.nelem
    assert max(sizes) - min(sizes) <= 1
    assert np.array_equal(np.sort(np.concatenate(chunks)), np.arange(g.nelem))
    # the chunks are consecutive pieces of the curve, in rank order
    assert np.array_equal(np.concatenate(chunks), P.sfc_order(ne))


def test_edge_cut_of_whole_faces_and_halves():
    """Six parts are the six faces (the curve finishes a face before the next):
    the cut is the cube's 12 edges of ne element edges each."""
    ne = 4
    faces = P.partition(ne, 6)
    assert sorted(int(c.min()) // (ne * ne) for c in faces) == list(range(6))
    assert all(len(set((c // (ne * ne)).tolist())) == 1 for c in faces)
    assert P.edge_cut(ne, faces) == 12 * ne
    assert P.edge_cut(ne, P.partition(ne, 1)) == 0


def test_bad_part_counts_raise():
    for parts in (0, 7):
        with pytest.raises(ValueError, match="cannot split 6 elements"):
            P.partition(1, parts)


@pytest.mark.parametrize("parts", [2, 3, 7])
def test_level_chunks_give_each_part_its_share_of_every_level(parts):
    """Along the ne4 curve, levels 0/1/2 on 60/30/6 elements: every element in one part,
    each part within one element of an equal share of every level (the 6 finest over 7 parts:
    one each, the last part none), each level's share one run of the level's curve order;
    with one level, ``partition``'s chunks."""
    order = P.sfc_order(4)
    level = np.zeros(96, dtype=np.int64)
    level[order[60:90]], level[order[90:]] = 1, 2
    chunks = P.level_chunks(order, level, parts)
    assert np.array_equal(np.sort(np.concatenate(chunks)), np.arange(96))
    for k, n in enumerate((60, 30, 6)):
        counts = [np.sum(level[c] == k) for c in chunks]
        assert sum(counts) == n and max(counts) - min(counts) <= 1 and max(counts) == -(-n // parts)
        mine = order[level[order] == k]
        for c in chunks:
            run = c[level[c] == k]
            assert run.size == 0 or np.array_equal(run, mine[np.flatnonzero(mine == run[0])[0] :][: run.size])
    flat = P.level_chunks(order, np.zeros(96, dtype=np.int64), parts)
    assert all(np.array_equal(a, b) for a, b in zip(flat, P.partition(4, parts)))
