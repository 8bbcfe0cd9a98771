"""The assembly seam (``swe_sphere.grid.topology``): DSS, unique-node vectors and reductions
summed in the fixed global order of the grid's ``dss_table``."""

from __future__ import annotations

import re

import numpy as np
import pytest
import warp as wp

from swe_sphere.grid.reductions import SerialComm
from swe_sphere.grid.topology import Topology

import roundoff
from helpers import cached_grid


def table_order_sum(g, x, weight):
    """Σ over each node's copies, in dss_table order, of weight[c]·x[c], one add at a time (numpy)."""
    s = np.zeros(x.shape[:-1] + (g.nnodes,))
    for k in range(g.dss_table.shape[1]):
        c = g.dss_table[:, k]
        have = c >= 0
        s[..., have] = s[..., have] + weight[c[have]] * x[..., c[have]]
    return s


def launch_all(launches):
    for launch in launches:
        launch.launch()


@pytest.mark.parametrize("weighted", [True, False])
def test_dss_is_the_table_order_sum_bit_for_bit(weighted, rng):
    """The DSS is exactly rspheremp · Σ_copies in table order (the order every process keeps)."""
    g = cached_grid(3, 4)
    topo = Topology(g, "cpu", threads=2)
    x = rng.standard_normal((3, g.nnodes))
    out = wp.zeros((3, g.nnodes), dtype=wp.float64)
    launch_all(topo.dss(wp.array(x, dtype=wp.float64), weighted, out))
    weight = g.spheremp if weighted else np.ones(g.nnodes)
    assert np.array_equal(out.numpy(), g.rspheremp * table_order_sum(g, x, weight))


def test_assemble_scatter_and_reductions_bit_for_bit(rng):
    g = cached_grid(2, 4)
    topo = Topology(g, "cpu")
    x = rng.standard_normal((2, g.nnodes))
    y = wp.zeros(topo.nunique, dtype=wp.float64)
    xw = wp.array(x, dtype=wp.float64)
    launch_all(topo.assemble(xw, 1, y))
    assert np.array_equal(y.numpy(), table_order_sum(g, x[1], g.spheremp)[g.first])
    back = wp.zeros((2, g.nnodes), dtype=wp.float64)
    launch_all(topo.scatter(y, back, 0))
    assert np.array_equal(back.numpy()[0], y.numpy()[g.gid])
    assert topo.integrate(x[0]) == float(np.sum(g.spheremp * x[0]))
    assert topo.norm(xw) == float(np.linalg.norm(x))
    assert topo.dot(xw, xw) == float(x.ravel() @ x.ravel())
    assert topo.total_area == pytest.approx(4 * np.pi * g.radius**2, rel=1e-14)
    assert topo.mean(np.full(g.nnodes, 7.5)) == pytest.approx(7.5, rel=1e-14)
    assert topo.nnodes_total == g.nnodes and topo.nunique == g.nunique


class RankOf(SerialComm):
    """Rank ``rank`` of ``size`` as far as building tables goes (reductions stay local)."""

    def __init__(self, rank, size):
        self.rank, self.size = rank, size


@pytest.mark.parametrize("ranks", [2, 3, 5])
def test_partitioned_dss_with_exchanged_copies_is_the_serial_dss_bit_for_bit(ranks, rng):
    """Each rank packs (``kernels.dss.pack``) what its neighbours need; with those
    buffers placed in its ghost buffer (the exchange, done here by hand), each
    rank's DSS equals the one-process DSS on its nodes, bit for bit."""
    g = cached_grid(3, 4)
    x = rng.standard_normal((3, g.nnodes))
    whole = wp.zeros((3, g.nnodes), dtype=wp.float64)
    launch_all(Topology(g, "cpu").dss(wp.array(x, dtype=wp.float64), True, whole))
    topos = [Topology(g, "cpu", 1, RankOf(r, ranks)) for r in range(ranks)]
    assert np.array_equal(np.sort(np.concatenate([t.elements for t in topos])), np.arange(g.nelem))
    for t in topos:  # each rank built its own elements only: every per-node array is its size
        assert t.elements.size < g.nelem
        for name in ("xyz", "D", "metdet", "spheremp", "rspheremp", "dx", "gid", "nodes"):
            assert getattr(t.grid, name).shape[-1] == t.N, name
        assert t.grid.dss_table.shape == (t.N, 4) and t.grid.halo.size < t.N
    outs, sent = [], []
    for t in topos:  # pack on every rank
        out = wp.zeros((3, t.N), dtype=wp.float64)
        launches = t.dss(wp.array(x[:, t.nodes], dtype=wp.float64), True, out)
        assert [launch.kernel.key for launch in launches][:2] == ["pack", "exchange"]  # then the DSS
        launches[0].launch()
        sent.append(t.copies.send_buffer.numpy().copy())
        outs.append((out, launches[-1]))
        for a, b in t.copies.send_ranges:  # each neighbour gets its copies in the global order
            copies = t.nodes[t.copies.send_index.numpy()[a:b]]
            assert np.all(np.diff(copies) > 0)
            assert np.array_equal(sent[-1][a * 3 : b * 3], x[:, copies].T.ravel())
    for r, t in enumerate(topos):  # "exchange", then the DSS
        ghost = t.ghost.numpy()
        for s, (a, b) in zip(t.neighbours, t.copies.recv_ranges):
            c, d = topos[s].copies.send_ranges[list(topos[s].neighbours).index(r)]
            assert d - c == b - a
            ghost[a * 3 : b * 3] = sent[s][c * 3 : d * 3]
        out, launch = outs[r]
        launch.launch()
        assert np.array_equal(out.numpy(), whole.numpy()[:, t.nodes])
        assert t.halo_copies == t.recv.size > 0


def exchange_by_hand(topos, launch_lists, halos, rows):
    """Run each rank's launches with the exchange done by hand: packs first on every
    rank, then each rank's receive buffer filled from its neighbours' send buffers in
    ``halos`` (one ``_Halo`` per rank), then the launches after the exchange."""
    rest = []
    for launches in launch_lists:
        keys = [launch.kernel.key for launch in launches]
        cut = keys.index("exchange") + 1 if "exchange" in keys else 0
        for launch in launches[: cut - 1 if cut else 0]:
            launch.launch()
        rest.append(launches[cut:])
    for r, halo in enumerate(halos):
        recv = halo.recv_buffer.numpy()
        for s, (a, b) in zip(halo.neighbours, halo.recv_ranges):
            c, d = halos[s].send_ranges[list(halos[s].neighbours).index(r)]
            assert d - c == b - a
            recv[a * rows : b * rows] = halos[s].send_buffer.numpy()[c * rows : d * rows]
    for launches in rest:
        launch_all(launches)


@pytest.mark.roundoff
@pytest.mark.parametrize("ranks", [2, 3, 5])
def test_partitioned_unique_vectors_are_the_serial_ones(ranks, rng):
    """Unique nodes split among ranks (each owned once, by its first copy's rank):
    ``assemble`` over local and exchanged copies gives the serial values bit for bit,
    ``scatter`` with the owners' values exchanged gives every local copy its value,
    and the owned pieces' dot products add up to the serial one."""
    g = cached_grid(3, 4)
    x = rng.standard_normal((3, g.nnodes))
    serial = Topology(g, "cpu")
    whole = wp.zeros(g.nunique, dtype=wp.float64)
    launch_all(serial.assemble(wp.array(x, dtype=wp.float64), 2, whole))
    topos = [Topology(g, "cpu", 1, RankOf(r, ranks)) for r in range(ranks)]
    owned = [t.nodes[t.first.numpy()] for t in topos]  # whole-grid copy of each owned node
    assert np.array_equal(np.sort(g.gid[np.concatenate(owned)]), np.arange(g.nunique))
    ys = [wp.zeros(t.nunique, dtype=wp.float64) for t in topos]
    lists = [t.assemble(wp.array(x[:, t.nodes], dtype=wp.float64), 2, y) for t, y in zip(topos, ys)]
    exchange_by_hand(topos, lists, [t.copies for t in topos], 3)
    for y, nodes in zip(ys, owned):
        assert np.array_equal(y.numpy(), whole.numpy()[g.gid[nodes]])
    u = rng.standard_normal((2, g.nunique))  # a 2-row unique-node vector
    outs = [wp.zeros((3, t.N), dtype=wp.float64) for t in topos]
    parts = [wp.array(u[:, g.gid[nodes]].ravel(), dtype=wp.float64) for nodes in owned]
    lists = [t.scatter(p, out, 1, rows=2) for t, p, out in zip(topos, parts, outs)]
    exchange_by_hand(topos, lists, [t.owned for t in topos], 2)
    for t, out in zip(topos, outs):
        assert np.array_equal(out.numpy()[1:], u[:, g.gid[t.nodes]])
    # the same u.size positive terms summed in two groupings (BLAS per part, numpy's pairwise):
    # each sum within (u.size − 1) ε of it, whatever the order
    by_parts = sum(float(p.numpy() @ p.numpy()) for p in parts)
    roundoff.within(abs(by_parts / float(np.sum(u * u)) - 1), roundoff.bound(2 * u.size), "|Σ parts' u·u / u·u − 1|")


@pytest.mark.parametrize("ranks", [1, 2, 3, 7])
def test_each_rank_draws_its_part_of_one_random_vector(ranks):
    """``standard_normal`` draws the whole stream in pieces and keeps the rank's
    nodes: the parts are the whole-grid vector's, bit for bit (the hyperviscosity
    estimate's start vector is the same on any number of ranks)."""
    g = cached_grid(5, 4)
    whole = np.random.default_rng(0).standard_normal((3, g.nnodes))
    for r in range(ranks):
        t = Topology(g, "cpu", 1, RankOf(r, ranks))
        assert np.array_equal(t.standard_normal(np.random.default_rng(0), 3), whole[:, t.nodes])


class Rank0Sends(RankOf):
    """Rank ``rank`` of ``size`` whose collectives from rank 0 (``bcast``, ``Scatterv``)
    deliver what rank 0 sent: ``sent[name]`` lists rank 0's calls, shared by the
    ranks, so rank 0 must call first."""

    def __init__(self, rank, size, sent: dict):
        super().__init__(rank, size)
        self.sent, self.made = sent, {}

    def _from_root(self, name, value):
        if self.rank == 0:
            self.sent.setdefault(name, []).append(value)
        k = self.made[name] = self.made.get(name, -1) + 1  # this rank's k-th call of name
        return self.sent[name][k]

    def bcast(self, value, root=0):
        return self._from_root("bcast", value)

    def Scatterv(self, send, recv, root=0):
        flat, counts = self._from_root("Scatterv", send)
        start = sum(counts[: self.rank])
        recv[...] = flat[start : start + counts[self.rank]].reshape(recv.shape)


@pytest.mark.parametrize("ranks", [1, 2, 3, 5])
def test_distribute_hands_each_rank_its_part_and_refuses_a_misshapen_field(ranks, rng):
    """``distribute``: each rank gets its nodes' columns of rank 0's whole-grid field,
    bit for bit, after one broadcast of its shape and whether it is finite; a field of another
    shape or not finite on rank 0 is one ValueError naming it, on every rank (those given None
    too)."""
    g = cached_grid(3, 4)
    whole = rng.standard_normal((3, g.nnodes))
    sent = {}
    topos = [Topology(g, "cpu", 1, Rank0Sends(r, ranks, sent)) for r in range(ranks)]
    for r, t in enumerate(topos):
        assert np.array_equal(t.distribute(whole if r == 0 else None, 3, "start state"), whole[:, t.nodes])
    assert sent["bcast"] == [((3, g.nnodes), True)]  # one broadcast: the shape and finiteness
    message = f"start state has shape (2, {g.nnodes}), the grid needs (3, {g.nnodes})"
    for r, t in enumerate(topos):
        with pytest.raises(ValueError, match=rf"^{re.escape(message)}$"):
            t.distribute(whole[:2] if r == 0 else None, 3, "start state")
    whole[1, 5] = np.inf
    for r, t in enumerate(topos):
        with pytest.raises(ValueError, match=r"^start state holds a NaN or an infinity$"):
            t.distribute(whole if r == 0 else None, 3, "start state")
