"""The Helmholtz operator as a matrix, for the tests and benchmarks: K = −M D G on unique nodes
(M the assembled mass, D = DSS∘div and G = DSS∘grad the model's strong operators) assembled
once per grid as a scipy sparse matrix by probing the model's element kernels; it is the
matrix-free operator of ``helmholtz_cg``, to round-off. K is symmetric positive semi-definite
(the SE divergence and gradient are adjoint under the GLL quadrature; Taylor & Fournier 2010)
and K·1 = 0, so M + cK is SPD for c > 0."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from ..model.shallow_water import ShallowWater

if TYPE_CHECKING:
    import scipy.sparse as sp

f64 = wp.float64


def element_gradient(model: ShallowWater) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """(Ĝ, P): the element gradient Ĝ (2N × N, 1/m: (u, v) components of each element's own
    gradient, before the DSS) and the scatter P (N × nunique, ones: unique → element-local copies).

    Ĝ comes from np² probes of ``model.operators.gradient``, which leaves the element-local result in
    ``model.operators.vec_work``: a unit value at one local node of every element gives a column of every
    element's matrix exactly. The whole grid on one process.
    """
    import scipy.sparse as sp  # here, as in helmholtz_matrix: a run needs no sparse matrix

    grid, N = model.topology.grid, model.topology.N
    npp = grid.np**2
    base = np.arange(grid.nelem) * npp
    x = wp.zeros((3, N), dtype=f64, device=model.topology.device)
    G2 = wp.zeros((2, N), dtype=f64, device=model.topology.device)
    nodes = np.arange(N)  # element-major: the rows of element e are e·np² … (e+1)·np² − 1
    rows, cols, vals = [], [], []
    unit = np.zeros((3, N))
    for k in range(npp):
        unit[2] = 0.0
        unit[2, base + k] = 1.0
        x.assign(unit)
        model.operators.gradient(x, 2, G2)
        g = model.operators.vec_work.numpy()
        for c in range(2):
            rows.append(c * N + nodes), cols.append(np.repeat(base + k, npp)), vals.append(g[c].copy())
    G_hat = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * N, N))
    G_hat.eliminate_zeros()
    return G_hat, sp.csr_matrix((np.ones(N), (nodes, grid.gid)), shape=(N, grid.nunique))


def helmholtz_matrix(model: ShallowWater) -> sp.csr_matrix:
    """K = −M D G (nunique × nunique, dimensionless: M in m², D G in m⁻²) on unique nodes, symmetrised (its asymmetry is round-off, ~1e-15 relative).

    Built from the model's own element kernels: Ĝ and P from ``element_gradient``, and the
    element divergence D̂ from 2np² probes of ``model.operators.divergence`` (its element-local result is
    left in ``model.operators.scalar``); with W = diag(spheremp) and the DSS S = P M⁻¹ Pᵀ W,
    K = −Pᵀ W D̂ S Ĝ P. The whole grid on one process (the host solvers').
    """
    # here, not at the top: scipy.sparse costs every command's start 0.1 s of CPU, and only
    # the tests and benchmarks assemble K
    import scipy.sparse as sp

    grid, N = model.topology.grid, model.topology.N
    npp = grid.np**2
    base = np.arange(grid.nelem) * npp
    G_hat, P = element_gradient(model)
    x = wp.zeros((3, N), dtype=f64, device=model.topology.device)
    D1 = wp.zeros((1, N), dtype=f64, device=model.topology.device)
    nodes = np.arange(N)
    drow, dcol, dval = [], [], []
    unit = np.zeros((3, N))
    for k in range(npp):
        col = np.repeat(base + k, npp)  # the probed column of each row's element
        for c in range(2):
            unit[:] = 0.0
            unit[c, base + k] = 1.0
            x.assign(unit)
            model.operators.divergence(x, D1)
            drow.append(nodes), dcol.append(c * N + col), dval.append(model.operators.scalar.numpy()[0].copy())
    D_hat = sp.csr_matrix((np.concatenate(dval), (np.concatenate(drow), np.concatenate(dcol))), shape=(N, 2 * N))
    D_hat.eliminate_zeros()
    PtW = (P.T @ sp.diags(grid.spheremp)).tocsr()
    inv_area = sp.diags(np.tile(1.0 / grid.area, 2))
    G = inv_area @ sp.block_diag((PtW, PtW)) @ G_hat @ P  # (2 nunique, nunique): DSS'd gradient on unique nodes
    K = -(PtW @ D_hat @ sp.block_diag((P, P)) @ G)
    K = ((K + K.T) * 0.5).tocsr()
    K.eliminate_zeros()
    return K
