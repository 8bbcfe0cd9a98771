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
relative (``tests/solvers/test_jacobian.py``).
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..core.parallel import record
from ..kernels import implicit as ik
from ..kernels import krylov as kk
from .krylov import NumpyViews

f64 = wp.float64
_SQRT_EPS = math.sqrt(np.finfo(float).eps)
# why a stepper on these products cannot step a float32 tendency (``Described.float32_refusal``):
# F's round-off, ~6e-8 of it in float32, is above the difference's step ε, ~1.5e-8 of x
FLOAT32_REFUSAL = (
    "its Jacobian-vector products difference the RHS over a step of 1.5e-8 (relative), which float32 "
    "round-off in F (6e-8) swamps"
)


class KernelPasses:
    """The J·v's pointwise passes in Warp kernels (``kernels.implicit``, ``kernels.blas``;
    the backend on CUDA), recorded once per set of arrays by ``model.pointwise``:
    ``gather(a, v, out)``: unique-node out = a·v at each node's first copy;
    ``scatter(u, out)``: element-local out from the unique-node u;
    ``point_norm(u)``: ‖u‖ of the point x (unique-node u) as ``epsilon`` takes it;
    ``epsilon(w, xnorm, scale)``: ε and scale/ε for w (True: w may be nonzero, go on);
    ``perturb(x, w, xp)``: element-local xp = x + ε·w (w unique-node);
    ``difference(w, Fx, Fp, shift, out)``: unique-node out = shift·w + (scale/ε)(Fp − Fx)
    (Fp may be overwritten); ``norm(v)``: ‖v‖ over all processes.

    Here ε stays on the device: ‖x‖² and ‖w‖² by ``kernels.krylov``'s chunked inner
    product, its partial sums added there (``Topology.device_sums``; over ranks through
    the host, ``Topology.allreduce``), ε by the one-thread ``fd_epsilon``, read by the
    passes; a J·v reads nothing back on one rank (for w = 0, ε = 0 and the product is 0)."""

    def __init__(self, model):
        self.model, self.topology = model, model.topology
        dev, n = model.topology.device, 3 * model.topology.nunique
        self._chunk = chunk = model.topology.backend.reduction_chunk(n)
        self._partial = wp.zeros((1, (n + chunk - 1) // chunk), dtype=f64, device=dev)
        self.xx, self.ww, self.eps = (wp.zeros(k, dtype=f64, device=dev) for k in (1, 1, 2))  # ‖x‖², ‖w‖², (ε, scale/ε)
        self._squares = {}  # (v.ptr, out.ptr) -> the recorded launches of v·v into out (with v)
        self._epsilon = wp.launch(
            ik.fd_epsilon, 1, [self.ww, self.xx, f64(_SQRT_EPS), f64(1.0), self.eps], device=dev, record_cmd=True
        )

    def _square(self, v, out) -> None:
        """out[0] = v·v over all processes (one row of ``kernels.krylov.project_dots``, k_sub = k_dot = 0)."""
        topo, key = self.topology, (v.ptr, out.ptr)
        entry = self._squares.get(key)
        if entry is None:
            dots = record(
                kk.project_dots,
                self._partial.shape[1],
                [v.reshape((1, v.shape[0])), 0, out, v, 0, self._partial, self._chunk],
                device=topo.backend,
                threads=topo.threads,
                nodes_per_index=self._chunk,
            )
            entry = self._squares[key] = ([dots, *topo.device_sums(self._partial, 1, out)], v)
        for launch in entry[0]:
            launch.launch()
        topo.allreduce(out)

    def gather(self, a: float, v, out) -> None:
        self.model.pointwise(ik.gather, f64(a), v, self.topology.first, self.topology.nunique, out, unique=True)

    def scatter(self, u, out) -> None:
        self.model.operators.scatter(u, out, 0, rows=3)

    def point_norm(self, u):
        self._square(u, self.xx)
        return self.xx

    def epsilon(self, w, xnorm, scale: float) -> bool:  # xnorm: point_norm's array, read on the device
        self._square(w, self.ww)
        self._epsilon.set_param_by_name("scale", f64(scale))
        self._epsilon.launch()
        return True

    def perturb(self, x, w, xp) -> None:
        self.scatter(w, xp)
        self.model.pointwise(ik.add_scaled, x, self.eps, xp)

    def difference(self, w, Fx, Fp, shift: float, out) -> None:
        topo = self.topology
        self.model.pointwise(
            ik.jacobian_vector, w, Fx, Fp, topo.first, topo.nunique, f64(shift), self.eps, out, unique=True
        )

    def norm(self, v) -> float:
        return self.topology.norm(v)


class HostPasses:
    """``KernelPasses``'s passes in numpy on zero-copy views of the Warp arrays (the
    backend on a CPU device: Warp's CPU kernels took 5–13 ns an entry for them, at ne16
    more than the RHS of the J·v altogether; numpy's take and arithmetic 0.3–1.3 ns). The
    same arithmetic entry by entry, so the same bits (``tests/solvers/test_jacobian.py``) but for
    ε, which is a host value here (‖w‖ by BLAS on a view: no copy), and the same whatever
    the model's threads: numpy runs them on one."""

    def __init__(self, model):
        self.topology = topo = model.topology
        nu, N, nh = topo.nunique, model.topology.N, topo.owned.size
        rows = np.arange(3)[:, None]
        # the flat (3, N) index of each unique-node vector entry: row r of node g at r·nunique + g
        self.first3 = (rows * N + topo.first.numpy()[None, :]).ravel().astype(np.intp)
        # each element-local entry's in [u, halo]: u's row r of owned node g at r·nunique + g, a node
        # owned elsewhere (gid ≥ nunique) in the halo ``Topology.exchange`` fills (node-major, ``dss.pack``)
        gid = topo.gid.numpy()[None, :].astype(np.intp)
        self.gid3 = np.where(gid < nu, rows * nu + gid, 3 * nu + (gid - nu) * 3 + rows).ravel()
        self.halo = topo.owned.recv_buffer.numpy()[: 3 * nh]
        self.ext = np.zeros(3 * (nu + nh))  # a·[u, halo]
        self.tmp = np.zeros(3 * nu)
        self._np = NumpyViews()
        self._exchanges: dict[int, tuple] = {}

    def _scaled_scatter(self, u, a: float, out) -> None:
        """Element-local out = a·u (a·u on unique nodes first: fewer entries than out)."""
        topo, src, n = self.topology, self._np(u), 3 * self.topology.nunique
        # the exchange with the neighbours (none on one process; a rank that receives nothing may still
        # send), recorded once per vector, which is held so that its address stays its own
        entry = self._exchanges.get(u.ptr)
        if entry is None:
            entry = self._exchanges[u.ptr] = (topo.exchange(u.reshape((3, topo.nunique)), unique=True), u)
        for launch in entry[0]:
            launch.launch()
        np.multiply(src, a, out=self.ext[:n])
        np.multiply(self.halo, a, out=self.ext[n:])
        np.take(
            self.ext, self.gid3, out=self._np(out).ravel(), mode="clip"
        )  # clip: no bounds pass (the indices are valid)

    def gather(self, a: float, v, out) -> None:
        o = self._np(out)
        np.take(self._np(v).ravel(), self.first3, out=o, mode="clip")
        np.multiply(o, a, out=o)

    def scatter(self, u, out) -> None:
        self._scaled_scatter(u, 1.0, out)

    def point_norm(self, u) -> float:
        return self.norm(u)

    def epsilon(self, w, xnorm: float, scale: float) -> bool:
        wnorm = self.norm(w)
        if wnorm == 0.0:
            return False
        self.eps = _SQRT_EPS * (1.0 + xnorm) / wnorm
        self.c = scale / self.eps
        return True

    def perturb(self, x, w, xp) -> None:
        self._scaled_scatter(w, self.eps, xp)
        p = self._np(xp)
        np.add(self._np(x), p, out=p)

    def difference(self, w, Fx, Fp, shift: float, out) -> None:
        o, d, c = self._np(out), self._np(Fp), self.c
        if shift:
            np.multiply(self._np(w), shift, out=self.tmp)  # first: out may alias w
        np.subtract(
            d, self._np(Fx), out=d
        )  # on every copy (one subtraction pass over (3, N) costs less than a second gather)
        np.take(d.ravel(), self.first3, out=o, mode="clip")
        np.multiply(o, c, out=o)
        if shift:
            np.add(o, self.tmp, out=o)

    def norm(self, v) -> float:
        return self.topology.norm(self._np(v))  # on the cached view: no new view per call


class FiniteDifferenceJacobian:
    """J w of ``model``'s RHS about a point x, with ``F(x, out)`` the caller's RHS
    evaluation (it counts them). ``apply(x, Fx, xnorm, w, out, shift, scale)``:
    out = shift·w + scale·J w for unique-node vectors w, out (3·nunique,), with
    F(x) in Fx (3, N) and xnorm = ‖x‖ on unique nodes as ``point_norm`` gives it; one
    F evaluation (none for w = 0, out = 0, where ε is a host value). x and Fx are left alone.

    ``passes``: the backend of the pointwise passes (gather, scatter, x + εw, the difference),
    by the backend (``Backend.choose``): ``HostPasses`` (numpy) on a CPU device,
    ``KernelPasses`` elsewhere; either may be given."""

    def __init__(self, model, F, passes=None):
        self.model, self.F = model, F
        self.topology = model.topology
        self.nu = self.topology.nunique
        self.xp = wp.zeros((3, model.topology.N), dtype=f64, device=model.topology.device)  # x + εw
        self.Fp = wp.zeros((3, model.topology.N), dtype=f64, device=model.topology.device)  # F(x + εw)
        self.passes = (passes or self.topology.backend.choose(HostPasses, KernelPasses))(model)

    def norm(self, a) -> float:
        """Euclidean norm of an array (3, N) or (3·nunique,) over all processes."""
        return self.passes.norm(a)

    def gather(self, a: float, v, out) -> None:
        """Unique-node out = a·v from a continuous (3, N) v."""
        self.passes.gather(a, v, out)

    def scatter(self, u, out) -> None:
        """Element-local out (3, N) from the unique-node vector u."""
        self.passes.scatter(u, out)

    def point_norm(self, u):
        """‖x‖ for ``apply`` from the point's unique-node vector u (3·nunique,): a float
        (``HostPasses``) or a device array (``KernelPasses``: no host read)."""
        return self.passes.point_norm(u)

    def apply(self, x, Fx, xnorm, w, out, shift: float = 0.0, scale: float = 1.0) -> None:
        if not self.passes.epsilon(w, xnorm, scale):  # w = 0 (known on the host)
            out.zero_()
            return
        self.passes.perturb(x, w, self.xp)  # x + ε w
        self.F(self.xp, self.Fp)
        self.passes.difference(w, Fx, self.Fp, shift, out)  # shift·w + scale (F(x + εw) − F(x)) / ε
