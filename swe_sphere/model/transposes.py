"""The transpose of the model's tendency, for the gradients of a run (``swe_sphere.adjoint``).

``TendencyTranspose`` (made by ``ElementOperators.tendency_transpose``) launches x̄ = Tᵀ(Y) W k̄,
T the element-local tendency of ``ShallowWater.rhs`` at the state Y, W the element mass spheremp
and k̄ a continuous adjoint of F(Y) in the mass form (μ = R Q λ, R the inverse assembled mass,
Q the sum over a node's copies: ``adjoint.explicit``'s module doc); R Q x̄ by the unweighted DSS
that the caller writes where it needs it is then the adjoint of Y. The kernels are
``kernels.tendency_adjoint``'s (written by hand: one element kernel a stage on the CPU, two
per-node gathers on CUDA).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import tendencies, tendency_adjoint

f64 = wp.float64


class TendencyTranspose:
    """The tendency's transpose for the terms of ``terms`` that F holds (``kernels.tendencies.
    TENDENCY_TERMS`` order) at gravity ``g`` (m s⁻²), on ``operators``' arrays and layout (an
    ``ElementOperators``), its launches through their ``LaunchRecorder``.

    Arrays (device, element-local, N the nodes): ``xbar`` (3, N), what each transpose writes;
    ``fbar`` (2, N), Σ λ's wind rows over the transposes with topography (the adjoint of the
    forcing −g∇hs, for ∂J/∂hs: ``forcing_transpose``); the element mass ``spheremp`` (N,; m²);
    made on first use: ``kbar`` (3, N), k̄ combined where the kernels cannot read it as it is,
    and ``adj`` (5, N), the per-node kernels' reference-derivative adjoints."""

    def __init__(self, operators, terms: tuple, g: float):
        self.operators, self.g = operators, g
        self.topology, self.launches = operators.topology, operators.launches
        self.terms = tuple(t for t in tendencies.TENDENCY_TERMS if t in terms)
        self.xbar = self._zeros(3)
        self.fbar = self._zeros(2)
        self.spheremp = wp.array(self.topology.grid.spheremp, dtype=f64, device=self.topology.device)

    def _zeros(self, rows: int) -> wp.array2d:
        return wp.zeros((rows, self.topology.N), dtype=f64, device=self.topology.device)

    def transpose(self, Y, kbar, terms=None, runs=None) -> list:
        """Launches of x̄ = Tᵀ(Y) W k̄ into ``xbar``, k̄ = Σ c·k over (c, k) ``kbar`` (element-local
        (3, N) arrays or row views), T the tendency of ``terms`` (None: all this object's): the
        element kernel on the CPU's layout, reading up to three terms; the per-node ``point`` and
        ``gather`` on CUDA's; k̄ combined by a pass of its own first where they cannot read it as
        it is. ``runs``: (start, stop) element ranges, the tendency of those elements alone (x̄
        zero on the others). The recorded launches read the arrays, not their values: replay
        them for new values."""
        ops, rec, launches = self.operators, self.launches, []
        if runs is not None:
            launches.append(rec.lincomb(self.xbar, [(0.0, self.xbar)]))
        ranges = [None] if runs is None else list(runs)
        terms = self.terms if terms is None else tuple(t for t in self.terms if t in terms)
        if len(kbar) > 3 or not ops.per_element and kbar != [(1.0, kbar[0][1])]:
            if not hasattr(self, "kbar"):
                self.kbar = self._zeros(3)
            more = (rec.lincomb(self.kbar, [(1.0, self.kbar), *kbar[i : i + 3]]) for i in range(4, len(kbar), 3))
            launches, kbar = [*launches, rec.lincomb(self.kbar, kbar[:4]), *more], [(1.0, self.kbar)]
        np_ = self.topology.grid.np
        if ops.per_element:
            R, (c, k) = ops.as_rows, zip(*kbar)
            c, k = [*c, *(0.0,) * (3 - len(c))], [*k, *(k[0],) * (3 - len(k))]
            kernel = tendency_adjoint.element(terms, np_, len(kbar))
            args = [*map(R, (Y, ops.D, ops.Dinv, ops.metdet, ops.fcor, self.spheremp)), self.g, ops.dvv_rows]
            args += [wp.vec3d(*c), *map(R, k), R(self.xbar), R(self.fbar)]
            return [*launches, *(rec.elements(kernel, args, elements=r) for r in ranges)]
        if not hasattr(self, "adj"):
            self.adj = self._zeros(5)
        point = [Y, ops.D, ops.Dinv, ops.metdet, ops.fcor, self.spheremp, ops.dvv, kbar[0][1]]
        point += [self.adj, self.xbar, self.fbar]
        gather = [Y, ops.D, ops.Dinv, ops.metdet, ops.dvv, self.g, self.adj, self.xbar]
        kernels = (
            (tendency_adjoint.point(terms, np_), point),
            (tendency_adjoint.gather(terms, np_), gather),
        )
        return [*launches, *(rec.nodes(k, self.topology.N, a, elements=r) for r in ranges for k, a in kernels)]

    def forcing_transpose(self) -> np.ndarray:
        """The forcing −g∇hs's share of ∂J/∂hs (N,) on this rank's nodes, continuous (mass form):
        R Q of the pressure gradient's transpose of ``fbar`` (the forcing is the pressure gradient
        of hs), by the per-node kernels on either layout, unrecorded (once a gradient)."""
        ops, topo, N = self.operators, self.topology, self.topology.N
        kbar = wp.array(np.concatenate([self.fbar.numpy(), np.zeros((1, N))]), dtype=f64, device=topo.device)
        ones, xbar, d = wp.ones(N, dtype=f64, device=topo.device), wp.zeros_like(kbar), wp.zeros_like(kbar)
        adj = self._zeros(5)
        point = [kbar, ops.D, ops.Dinv, ops.metdet, ops.fcor, ones, ops.dvv, kbar, adj, xbar, self.fbar]
        terms = ("pressure_gradient",)
        wp.launch(tendency_adjoint.point(terms, topo.grid.np), N, [*point, 0], device=topo.device)
        gather = [kbar, ops.D, ops.Dinv, ops.metdet, ops.dvv, self.g, adj, xbar]
        wp.launch(tendency_adjoint.gather(terms, topo.grid.np), N, [*gather, 0], device=topo.device)
        for launch in topo.dss(xbar, False, d):
            launch.launch()
        return d.numpy()[2]
