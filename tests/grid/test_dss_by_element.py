"""The DSS by element on GLL rows (``kernels.dss.dss_update_elements``: the
CPU's form) gives the node gather's bits (``dss_rows``, ``dss_update``) on cubes and meshes."""

from __future__ import annotations

from unittest import mock

import numpy as np
import pytest
import warp as wp

from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.topology import Topology
from swe_sphere.simulation.simulation import Simulation

from helpers import cached_grid
from meshes import icosahedral_mesh, refined_equiangular

f64 = wp.float64


def launch_all(launches):
    for launch in launches:
        launch.launch()


def assemblies(topo: Topology, x: np.ndarray, a: np.ndarray, b: np.ndarray) -> list[np.ndarray]:
    """The weighted and unweighted DSS of x, and two ``dss_update`` combinations of it
    (out0 = a + 0.3 k over a itself, then out1 = 0.5 out0 + 0.7 b + 0.2 k), each way."""
    got = []
    xw = wp.array(x, dtype=f64)
    for weighted in (True, False):
        out = wp.zeros(x.shape, dtype=f64)
        launch_all(topo.dss(xw, weighted, out))
        s0, s1 = wp.array(a, dtype=f64), wp.array(b, dtype=f64)
        updates = [(s0, [(1.0, s0), (0.3, None)]), (s1, [(0.5, s0), (0.7, s1), (0.2, None)])]
        launch_all(topo.dss_update(xw, updates, weighted=weighted))
        got += [out.numpy(), s0.numpy(), s1.numpy()]
    return got


GRIDS = {
    "cube ne3 np3": lambda: cached_grid(3, 3),
    "cube ne2 np4": lambda: cached_grid(2, 4),
    "cube ne2 np5": lambda: cached_grid(2, 5),
    "cube ne3 np6": lambda: cached_grid(3, 6),
    "cube ne2 np8": lambda: cached_grid(2, 8),
    "refined ne4 np4 (valence 3-5)": lambda: CubedSphere(0, 4, mesh=refined_equiangular()),
    "icosahedral np5 (valence 3-6)": lambda: CubedSphere(0, 5, mesh=icosahedral_mesh(1)),
}


@pytest.mark.parametrize("name", list(GRIDS))
def test_element_rows_give_the_node_gathers_bits(name, rng):
    """Every DSS and DSS update by element equals the node gather's, bit for bit (an edge
    node's two copies summed (0 + own) + other commute into the table's order; a corner's
    through the table), on rotated cube faces and on meshes whose neighbours' edges run in
    any direction."""
    g = GRIDS[name]()
    x, a, b = (rng.standard_normal((3, g.nnodes)) for _ in range(3))
    by_element = Topology(g, "cpu", threads=2)
    assert by_element.edges is not None
    with mock.patch.object(Topology, "element_rows", False):
        by_node = Topology(g, "cpu", threads=2)
    for got, want in zip(assemblies(by_element, x, a, b), assemblies(by_node, x, a, b)):
        assert np.array_equal(got.view(np.int64), want.view(np.int64))


@pytest.mark.parametrize("element_rows", [True, False])
def test_assembled_rows_are_the_weighted_dss_of_their_values(element_rows, rng):
    """A limited stage's pass (``dss_update``'s ``assembled``: the limiter writes spheremp·v over
    its tracer rows, v its values less the stage's first source s, ``kernels.limiter.limit_stage``'s
    ``weigh`` and ``relative``): its last rows are s + the weighted DSS of v and its first the
    unweighted update's, bit for bit, each way (cube ne2 np4)."""
    g = cached_grid(2, 4)
    with mock.patch.object(Topology, "element_rows", element_rows):
        topo = Topology(g, "cpu", threads=2)
    assert (topo.edges is not None) == element_rows
    x, v, a = (rng.standard_normal((5, g.nnodes)) for _ in range(3))
    spheremp = topo.spheremp.numpy()[: g.nnodes]
    mixed = np.concatenate([x[:3], spheremp * v[3:]])
    got, want, assembled = (wp.array(a, dtype=f64) for _ in range(3))
    launch_all(topo.dss_update(wp.array(mixed, dtype=f64), [(got, [(1.0, got), (0.3, None)])], False, assembled=2))
    launch_all(topo.dss_update(wp.array(x[:3], dtype=f64), [(want[:3], [(1.0, want[:3]), (0.3, None)])], False))
    launch_all(topo.dss(wp.array(v[3:], dtype=f64), True, want[3:]))
    expected = want.numpy()
    expected[3:] += a[3:]  # s (got's own rows before the pass) + the DSS, one rounding
    assert np.array_equal(got.numpy().view(np.int64), expected.view(np.int64))
    assert not np.array_equal(got.numpy()[3:], a[3:])  # written
    with pytest.raises(ValueError, match="one update"):
        topo.dss_update(wp.array(mixed, dtype=f64), [(got, [(0.3, None)]), (got, [(0.3, None)])], False, assembled=2)


def test_each_edge_nodes_other_copy(rng):
    """``Edges.other`` holds the one other copy of each node inside an edge; ``aligned`` the
    neighbour's row whose inner lanes are those copies, where it runs lane for lane."""
    g = cached_grid(3, 4)
    e = Topology(g, "cpu").edges
    other, aligned = e.other.numpy(), e.aligned.numpy()
    npp, gid = g.np**2, g.gid
    south = np.arange(g.nelem)[:, None] * npp + np.arange(1, g.np - 1)[None, :]
    assert np.array_equal(gid[other[:, : g.np - 2]], gid[south])  # the same unique node
    assert np.all(other[:, : g.np - 2] // npp != south // npp)  # in another element
    ok = aligned[:, 0] >= 0
    rows = aligned[ok, 0][:, None] * g.np + np.arange(1, g.np - 1)[None, :]
    assert np.array_equal(rows, other[ok, : g.np - 2])
    assert 0.5 < ok.mean() < 1  # the faces' insides line up; the cube's edges turn


def test_two_point_elements_keep_the_node_gather():
    """np 2 has no node inside an edge: the node gather stays."""
    assert Topology(cached_grid(2, 2), "cpu").edges is None


@pytest.mark.parametrize(
    "scene,np_",
    [("galewsky", 6), ("tc6_rossby_haurwitz", 4), ("tc5_mountain_homme", 4)],
    ids=["rkl1-stages", "euler-substep", "leapfrog"],
)
def test_runs_with_the_hyperviscosity_are_the_node_gathers_bits(scene, np_):
    """A run's steps (the stages' DSS updates, the ∇⁴'s two DSSs in its element passes: RKL1
    stages at ne2 np6 Galewsky, a forward-Euler substep at TC6, the leapfrog's ∇⁴) give the
    node gather's bits."""

    def steps():
        sim = Simulation(scene, "cpu", progress=False, graphs=False, hyperviscosity={"every": 1}, ne=2, np=np_)
        for _ in range(6):
            sim.stepper.step(sim.x)
        return sim.x.numpy(), sim.model.topology.edges

    by_element, edges = steps()
    with mock.patch.object(Topology, "element_rows", False):
        by_node, none = steps()
    assert edges is not None and none is None
    assert np.all(np.isfinite(by_element)) and np.array_equal(by_element.view(np.int64), by_node.view(np.int64))
