"""Observations of a run for its gradient (``gradient``): the height at given points
(``PointHeights``, the observation operator H and its transpose) and a cost of the run against
observations of it at several steps (``HeightObservations``).

H evaluates h at a point from the element's own GLL polynomial, Σ_ij ℓ_i(ξ) ℓ_j(η) h_ij, as
``io.remap.Remapper`` does for maps (its point location and weights): a sparse (M, N) matrix
over the element-local nodes, M points, np² entries a row. The cost's ∂J/∂h is Hᵀ applied to
the weighted misfit, an element-local λ (nonzero on the np² nodes of each point's element);
``gradient`` gathers it to the continuous adjoint (R Q λ). The 4D-Var observation term
(e.g. Talagrand & Courtier 1987, Q. J. R. Meteorol. Soc. 113:1311; a diagonal
observation-error covariance σ²).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


class PointHeights:
    """The observation operator H: h at M points (``lat``, ``lon`` radians, broadcastable
    arrays, flattened to (M,)) of ``grid`` (a ``CubedSphere``: the scene's grid, e.g.
    ``scene_model(scene)[0].grid``), from the element's own GLL polynomial
    (``io.remap.Remapper``'s location and Lagrange weights).

    ``matrix``: scipy CSR (M, N) over the element-local nodes, np² weights a row (summing to 1).
    ``__call__(h)``: H h (M,) for h (N,) element-local (m → m); ``transpose(r)``: Hᵀ r (N,)
    for r (M,), the adjoint (⟨H h, r⟩ = ⟨h, Hᵀ r⟩). A point on an element's edge takes one
    adjacent element (a continuous h has one value there)."""

    def __init__(self, grid, lat, lon):
        from scipy.sparse import csr_matrix

        from ..io.remap import Remapper  # here: remap brings xarray, which a gradient alone needs not

        lat, lon = (np.asarray(a, dtype=float).ravel() for a in np.broadcast_arrays(lat, lon))
        remap = Remapper(grid, lat, lon)
        m, per = remap.weights.shape
        rows = np.repeat(np.arange(m), per)
        self.lat, self.lon, self.size = lat, lon, m
        self.matrix = csr_matrix((remap.weights.ravel(), (rows, remap.nodes.ravel())), shape=(m, grid.lat.size))

    def __call__(self, h) -> np.ndarray:
        return self.matrix @ np.asarray(h, dtype=float)

    def transpose(self, r) -> np.ndarray:
        return self.matrix.T @ np.asarray(r, dtype=float)


class HeightObservations:
    """A cost of the run against observations y_k (M,) m of h at ``operator``'s M points at the
    steps k of ``values`` ({k: y_k}, 0 ≤ k ≤ n of the run):

        J = Σ_k J_k,   J_k = ½ Σ_m ((H h(k))_m − y_km)² / σ_m²   (dimensionless),

    σ = ``sigma`` (m; a scalar or (M,)), the observations' error. For ``gradient``:
    ``at_steps`` the sorted k; ``cost(k, x, spheremp)`` → (J_k, λ_k), x (3, N) the state at step
    k (rows u, v, h; m s⁻¹, m s⁻¹, m), λ_k (3, N) = ∂J_k/∂x element-local, zero but its h row
    Hᵀ (H h − y_k) / σ² (m⁻¹). ``misfit(k, x)``: H h(k) − y_k (M,) m. ValueError for an
    observation of another shape than (M,) or σ not positive."""

    def __init__(self, operator: PointHeights, values: Mapping, sigma=1.0):
        self.operator = operator
        self.values = {int(k): np.asarray(y, dtype=float) for k, y in values.items()}
        for k, y in self.values.items():
            if y.shape != (operator.size,):
                raise ValueError(f"the observations at step {k} must have shape ({operator.size},) (got {y.shape})")
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (operator.size,))
        if not np.all(self.sigma > 0):
            raise ValueError("sigma must be positive")
        self.at_steps = tuple(sorted(self.values))

    def misfit(self, k: int, x) -> np.ndarray:
        return self.operator(np.asarray(x)[2]) - self.values[k]

    def __call__(self, k: int, x, spheremp=None):
        r = self.misfit(k, x) / self.sigma
        lam = np.zeros(np.shape(x))
        lam[2] = self.operator.transpose(r / self.sigma)
        return 0.5 * float(r @ r), lam
