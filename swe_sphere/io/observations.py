"""Observations of a run's height at points: the observation operator H (``PointHeights``) and
observations of h at several steps with their errors (``HeightObservations``), what a data
assimilation reads of a run, by a gradient (4D-Var: ``adjoint.gradient``, of which a
``HeightObservations`` is a cost) or by an ensemble (an EnKF: the gallery's
``docs/examples/assimilation/plot_enkf_filter.py``).

H evaluates h at a point from the element's own GLL polynomial, Σ_ij ℓ_i(ξ) ℓ_j(η) h_ij, as
``remap.Remapper`` does for maps (its point location and weights): a sparse (M, N) matrix over
the element-local nodes, M points, np² entries a row. The cost's ∂J/∂h is Hᵀ applied to the
weighted misfit, an element-local λ (nonzero on the np² nodes of each point's element). The
4D-Var observation term (e.g. Talagrand & Courtier 1987, Q. J. R. Meteorol. Soc. 113:1311; a
diagonal observation-error covariance σ²).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..core.arguments import array_argument, instance_argument, mapping_argument, number_argument
from ..core.errors import ArgumentError
from ..grid.cubed_sphere import CubedSphere

_RADIANS = "radians: degrees times π/180"


class PointHeights:
    """The observation operator H: h at M ≥ 1 points (``lat`` in [−π/2, π/2], ``lon`` in
    [−2π, 2π], radians, arrays of one shape, flattened to (M,)) of ``grid`` (a ``CubedSphere``:
    the scene's grid, e.g. ``scene_model(scene)[0].grid``), from the element's own GLL
    polynomial (``io.remap.Remapper``'s location and Lagrange weights). ``ArgumentError`` naming
    the argument for another grid, lat and lon of different shapes, no points, a NaN, or a value
    out of those ranges (degrees given for radians).

    ``matrix``: scipy CSR (M, N) over the element-local nodes, np² weights a row (summing to 1).
    ``__call__(h)``: H h (M,) for h (N,) element-local (m → m); ``transpose(r)``: Hᵀ r (N,)
    for r (M,), the adjoint (⟨H h, r⟩ = ⟨h, Hᵀ r⟩). A point on an element's edge takes one
    adjacent element (a continuous h has one value there)."""

    def __init__(self, grid, lat, lon):
        from scipy.sparse import csr_matrix

        from .remap import Remapper  # here: remap brings xarray, which a gradient alone needs not

        instance_argument("grid", grid, CubedSphere, "a CubedSphere (the scene's grid: scene_model(scene)[0].grid)")
        lat, lon = array_argument("lat", lat, unit="radians"), array_argument("lon", lon, unit="radians")
        if lat.shape != lon.shape or lat.size == 0:
            raise ArgumentError(
                f"lat and lon must have one shape, of one point or more (got {lat.shape} and {lon.shape})"
            )
        for name, a, bound in (("lat", lat, np.pi / 2), ("lon", lon, 2 * np.pi)):
            if np.any(np.abs(a) > bound * (1 + 1e-12)):
                worst = float(a.ravel()[np.argmax(np.abs(a))])
                raise ArgumentError(f"{name} must be in [-{bound:.6g}, {bound:.6g}] ({_RADIANS}; got {worst:g})")
        lat, lon = np.clip(lat.ravel(), -np.pi / 2, np.pi / 2), lon.ravel()
        remap = Remapper(grid, lat, lon)
        m, per = remap.weights.shape
        rows = np.repeat(np.arange(m), per)
        self.lat, self.lon, self.size = lat, lon, m
        self.matrix = csr_matrix((remap.weights.ravel(), (rows, remap.nodes.ravel())), shape=(m, grid.lat.size))

    def __call__(self, h) -> np.ndarray:
        return self.matrix @ array_argument("h", h, (self.matrix.shape[1],), "m")

    def transpose(self, r) -> np.ndarray:
        return self.matrix.T @ array_argument("r", r, (self.size,))

    def check_nodes(self, n: int) -> None:
        """Refuse (``ArgumentError``) an operator of another grid than one of ``n`` element-local nodes."""
        if self.matrix.shape[1] != n:
            raise ArgumentError(
                f"the observation operator is of a grid of {self.matrix.shape[1]} nodes, not this run's {n}"
            )


class HeightObservations:
    """A cost of the run against observations y_k (M,) m of h at ``operator``'s M points at the
    steps k of ``values`` ({k: y_k}, 0 ≤ k ≤ n of the run):

        J = Σ_k J_k,   J_k = ½ Σ_m ((H h(k))_m − y_km)² / σ_m²   (dimensionless),

    σ = ``sigma`` (m; a scalar or (M,)), the observations' error. For ``gradient``:
    ``at_steps`` the sorted k; ``cost(k, x, spheremp)`` → (J_k, λ_k), x (3, N) the state at step
    k (rows u, v, h; m s⁻¹, m s⁻¹, m), λ_k (3, N) = ∂J_k/∂x element-local, zero but its h row
    Hᵀ (H h − y_k) / σ² (m⁻¹). ``misfit(k, x)``: H h(k) − y_k (M,) m. ``ArgumentError`` naming
    the argument for an operator that is not a ``PointHeights``, values that are not a mapping
    of steps k ≥ 0 (integers) to finite observations of shape (M,), none, or σ not finite and
    positive (a number or (M,))."""

    def __init__(self, operator: PointHeights, values: Mapping, sigma=1.0):
        self.operator = instance_argument("operator", operator, PointHeights, "a PointHeights (the points' H)")
        m = operator.size
        values = mapping_argument("values", values, keys="int")
        if not values:
            raise ArgumentError("values must hold one observed step or more ({k: y_k}, got none)")
        self.values = {k: array_argument(f"values[{k}]", y, (m,), "m") for k, y in values.items()}
        if np.ndim(sigma) == 0:
            sigma = number_argument("sigma", sigma, "m", positive=True)
        sigma = array_argument("sigma", np.broadcast_to(sigma, np.shape(sigma) or (m,)), (m,), "m")
        if not np.all(sigma > 0):
            raise ArgumentError(f"sigma must be > 0 (m; got {float(sigma.min()):g})")
        self.sigma = sigma
        self.at_steps = tuple(sorted(self.values))

    def check_nodes(self, n: int) -> None:
        self.operator.check_nodes(n)

    def misfit(self, k: int, x) -> np.ndarray:
        return self.operator(np.asarray(x)[2]) - self.values[k]

    def __call__(self, k: int, x, spheremp=None):
        r = self.misfit(k, x) / self.sigma
        lam = np.zeros(np.shape(x))
        lam[2] = self.operator.transpose(r / self.sigma)
        return 0.5 * float(r @ r), lam
