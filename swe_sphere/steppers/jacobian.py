"""The Jacobian-vector product of the model's RHS by a forward difference, on
unique-node vectors: the JFNK stepper's (``implicit``) and the exponential
steppers' (``exponential``).

Krylov vectors live on unique nodes (3·nunique, row r of unique node g at
r·nunique + g: the state is continuous, so one copy per node carries it all;
0.56× the element-local length at np = 4); ``gather`` and ``scatter`` move
between them and element-local (3, N) states (``kernels.implicit``).

    J w ≈ (F(x + εw) − F(x)) / ε,   ε = sqrt(ε_mach) (1 + ‖x‖) / ‖w‖

(one of the choices of Knoll & Keyes 2004, J. Comput. Phys. 193, 357; ‖·‖ the
Euclidean norm of the unique-node vectors over all processes). Every term of F is
at most quadratic in the state, so the difference's error is ε‖F''‖: ~1e-8
relative (``tests/test_implicit.py``).
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..kernels import blas
from ..kernels import implicit as ik
from .krylov import NumpyViews

f64 = wp.float64
_SQRT_EPS = math.sqrt(np.finfo(float).eps)


class KernelPasses:
    """The J·v's pointwise passes in Warp kernels (``kernels.implicit``, ``kernels.blas``;
    the backend on CUDA), recorded once per set of arrays by ``model.pointwise``."""

    def __init__(self, model):
        self.model, self.topology = model, model.topology

    def gather(self, a: float, v, out) -> None:
        self.model.pointwise(ik.gather, f64(a), v, self.topology.first, self.topology.nunique, out, unique=True)

    def perturb(self, x, eps: float, xp) -> None:
        self.model.pointwise(blas.axpby, f64(1.0), x, f64(eps), xp, xp)

    def scatter(self, u, out) -> None:
        self.model.scatter(u, out, 0, rows=3)

    def difference(self, w, Fx, Fp, shift: float, c: float, out) -> None:
        topo = self.topology
        self.model.pointwise(ik.jacobian_vector, w, Fx, Fp, topo.first, topo.nunique, f64(shift), f64(-c), out, unique=True)


class HostPasses:
    """The J·v's pointwise passes in numpy on zero-copy views of the Warp arrays (the
    backend on a CPU device: Warp's CPU kernels took 5–13 ns an entry for them, more than
    the RHS of the J·v altogether at ne16; numpy's take and arithmetic 0.3–1.3 ns). The
    same arithmetic as ``KernelPasses``, entry by entry, so the same bits whatever the
    model's threads; numpy runs them on one."""

    def __init__(self, model):
        self.topology = topo = model.topology
        nu, N, nh = topo.nunique, model.N, topo.owned.size
        rows = np.arange(3)[:, None]
        # the flat (3, N) index of each unique-node vector entry: row r of node g at r·nunique + g
        self.first3 = (rows * N + topo.first.numpy()[None, :]).ravel().astype(np.intp)
        # each element-local entry's in [u, halo]: u's row r of owned node g at r·nunique + g, a node
        # owned elsewhere (gid ≥ nunique) in the halo ``Topology.exchange`` fills (node-major, ``dss.pack``)
        gid = topo.gid.numpy()[None, :].astype(np.intp)
        self.gid3 = np.where(gid < nu, rows * nu + gid, 3 * nu + (gid - nu) * 3 + rows).ravel()
        self.halo = topo.owned.recv_buffer.numpy()[: 3 * nh] if nh else None
        self.ext = np.zeros(3 * (nu + nh)) if nh else None
        self.tmp = np.zeros(3 * nu)
        self._np = NumpyViews()
        self._exchanges: dict[int, tuple] = {}

    def scatter(self, u, out) -> None:
        topo, src = self.topology, self._np(u)
        # the exchange with the neighbours (none on one process; a rank that receives nothing may still
        # send), recorded once per vector, which is held so that its address stays its own
        entry = self._exchanges.get(u.ptr)
        if entry is None:
            entry = self._exchanges[u.ptr] = (topo.exchange(u.reshape((3, topo.nunique)), unique=True), u)
        for launch in entry[0]:
            launch.launch()
        if self.halo is not None:
            self.ext[: src.size] = src
            self.ext[src.size :] = self.halo
            src = self.ext
        np.take(src, self.gid3, out=self._np(out).ravel(), mode="clip")

    def gather(self, a: float, v, out) -> None:
        o = self._np(out)
        np.take(self._np(v).ravel(), self.first3, out=o, mode="clip")  # clip: no bounds pass (the indices are valid)
        np.multiply(o, a, out=o)

    def perturb(self, x, eps: float, xp) -> None:
        p = self._np(xp)
        np.multiply(p, eps, out=p)
        np.add(self._np(x), p, out=p)

    def difference(self, w, Fx, Fp, shift: float, c: float, out) -> None:
        o, d = self._np(out), self._np(Fp)
        if shift:
            np.multiply(self._np(w), shift, out=self.tmp)  # first: out may alias w
        np.subtract(d, self._np(Fx), out=d)  # on every copy (one subtraction pass over (3, N) costs less than a second gather)
        np.take(d.ravel(), self.first3, out=o, mode="clip")
        np.multiply(o, c, out=o)
        if shift:
            np.add(o, self.tmp, out=o)


class FiniteDifferenceJacobian:
    """J w of ``model``'s RHS about a point x, with ``F(x, out)`` the caller's RHS
    evaluation (it counts them). ``apply(x, Fx, xnorm, w, out, shift, scale)``:
    out = shift·w + scale·J w for unique-node vectors w, out (3·nunique,), with
    F(x) in Fx (3, N) and xnorm = ‖x‖ on unique nodes; one F evaluation (none
    for w = 0, out = 0). x and Fx are left alone.

    ``passes``: the backend of the pointwise passes (gather, scatter, x + εw, the difference),
    chosen once here: ``HostPasses`` (numpy) on a CPU device, ``KernelPasses``
    elsewhere; either may be given."""

    def __init__(self, model, F, passes=None):
        self.model, self.F = model, F
        self.topology = model.topology
        self.nu = self.topology.nunique
        self.xp = wp.zeros((3, model.N), dtype=f64, device=model.device)  # x + εw
        self.Fp = wp.zeros((3, model.N), dtype=f64, device=model.device)  # F(x + εw)
        if passes is None:
            passes = HostPasses if wp.get_device(model.device).is_cpu else KernelPasses
        self.passes = passes(model)

    def norm(self, a) -> float:
        """Euclidean norm of an array (3, N) or (3·nunique,) over all processes."""
        return self.topology.norm(a)

    def gather(self, a: float, v, out) -> None:
        """Unique-node out = a·v from a continuous (3, N) v."""
        self.passes.gather(a, v, out)

    def scatter(self, u, out) -> None:
        """Element-local out (3, N) from the unique-node vector u."""
        self.passes.scatter(u, out)

    def apply(self, x, Fx, xnorm: float, w, out, shift: float = 0.0, scale: float = 1.0) -> None:
        wnorm = self.norm(w)
        if wnorm == 0.0:
            out.zero_()
            return
        eps = _SQRT_EPS * (1.0 + xnorm) / wnorm
        self.scatter(w, self.xp)
        self.passes.perturb(x, eps, self.xp)  # x + ε w
        self.F(self.xp, self.Fp)
        self.passes.difference(w, Fx, self.Fp, shift, scale / eps, out)  # shift·w + scale (F(x + εw) − F(x)) / ε
