"""A grid's element sizes and shapes as HOMME reports them (``cube_mod::metric_atomic``,
``global_norms_mod::test_global_integral`` and ``print_cfl``): the Dinv-based length scales and
element distortion, from the singular values of D⁻¹ at every GLL node.

With σ_max, σ_min the largest and smallest singular values of D⁻¹ (1/m; D maps the reference
element [−1, 1]² to the sphere of radius a) over an element's nodes: its short length scale is
dx_short = 2 / ((np − 1) σ_max) and its long one dx_long = 2 / ((np − 1) σ_min) (m; HOMME's
``dx_short``/``dx_long`` in km on the unit sphere), its distortion dx_long / dx_short = σ_max /
σ_min (1 on a square, ≈ 1.7 at the equiangular cube's corners; HOMME warns above 4), and its
"normDinv" σ_max, which sets the explicit step: the gravity-wave and advective limits scale as
1 / max σ_max over the mesh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core import cache
from .cubed_sphere import CubedSphere

SMALLEST_DX_BUILD = 1  # the ``smallest_dx`` cache entries' version: raised by any change that moves their bits


def dinv_singular_values(Dinv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(σ_max, σ_min) (N,) each: the singular values of the 2×2 matrices Dinv (4, N) (row-major),
    in closed form (the square roots of the eigenvalues of Dinv Dinvᵀ)."""
    a, b, c, d = Dinv
    trace = a * a + b * b + c * c + d * d
    det = np.abs(a * d - b * c)
    spread = np.sqrt(np.maximum(trace * trace - 4 * det * det, 0))
    large = np.sqrt((trace + spread) / 2)
    return large, det / large  # σ_max σ_min = |det Dinv|: no cancellation for σ_min


@dataclass(frozen=True)
class ElementSizes:
    """Per element held (E,): ``dx_short``, ``dx_long`` (m), ``distortion`` (dx_long / dx_short),
    ``norm_dinv`` (1/m, σ_max over the element's nodes) and ``area`` (m², Σ spheremp)."""

    dx_short: np.ndarray
    dx_long: np.ndarray
    distortion: np.ndarray
    norm_dinv: np.ndarray
    area: np.ndarray

    def summary(self) -> dict:
        """The figures HOMME prints at start (over the elements held: a rank's part, or all):
        dx_short min/mean/max and the largest dx_long (m), the largest distortion, the area
        ratio max/min, the largest σ_max (1/m) and the element that has it (``worst``: the one
        that sets the explicit step; an index into the elements held)."""
        return {
            "dx_short_min": float(self.dx_short.min()),
            "dx_short_mean": float(self.dx_short.mean()),
            "dx_short_max": float(self.dx_short.max()),
            "dx_long_max": float(self.dx_long.max()),
            "distortion_max": float(self.distortion.max()),
            "area_ratio": float(self.area.max() / self.area.min()),
            "norm_dinv_max": float(self.norm_dinv.max()),
            "worst": int(np.argmax(self.norm_dinv)),
        }


def element_sizes(grid, Dinv: np.ndarray | None = None) -> ElementSizes:
    """The ``ElementSizes`` of the elements ``grid`` (a ``CubedSphere``) holds; ``Dinv`` (4, N):
    the grid's, for a grid that holds none (rank 0's gathered whole grid,
    ``topology.GatheredGrid``: ``Topology.gather`` of the parts' Dinv)."""
    large, small = dinv_singular_values(grid.Dinv if Dinv is None else Dinv)
    per_element = (grid.nelem, grid.np * grid.np)
    sigma_max = large.reshape(per_element).max(axis=1)
    sigma_min = small.reshape(per_element).min(axis=1)
    half = (grid.np - 1) / 2
    return ElementSizes(
        dx_short=1 / (half * sigma_max),
        dx_long=1 / (half * sigma_min),
        distortion=sigma_max / sigma_min,
        norm_dinv=sigma_max,
        area=grid.spheremp.reshape(per_element).sum(axis=1),
    )


REGIONS = ("refined", "transition", "coarse")  # ``element_regions``' labels, finest first
# a spread of element sizes below this is one resolution: the equiangular cube's own corners
# and centres differ by 1.17x (Dinv-based mean length, ne10); a 2x refinement spreads 2.35x
UNIFORM_RATIO = 1.5


def element_regions(sizes: ElementSizes) -> np.ndarray | None:
    """Each element's region (E,) int, an index into ``REGIONS``, by its Dinv-based mean length
    d = √(dx_short·dx_long) (the local resolution, m) within the mesh's range d_min..d_max, split
    in three equal ratios: refined where d < d_min·R^(1/3), coarse where d > d_max·R^(−1/3), the
    transition between (R = d_max / d_min). On a mesh refined by levels of 2× (HOMME's RRM) the
    refined and coarse elements are the levels' and the transition the elements between; on a
    stretched cube the thirds of its resolution. None where R < ``UNIFORM_RATIO``: a mesh of one
    resolution has no regions. ``sizes``: the whole mesh's (``element_sizes``)."""
    d = np.sqrt(sizes.dx_short * sizes.dx_long)
    ratio = float(d.max() / d.min())
    if ratio < UNIFORM_RATIO:
        return None
    third = ratio ** (1 / 3)
    return np.where(d < d.min() * third, 0, np.where(d > d.max() / third, 2, 1))


def smallest_dx(ne: int, np_: int, mesh=None) -> float:
    """The smallest ``dx_short`` (HOMME's Dinv-based length scale) of the grid ``CubedSphere(ne,
    np_, mesh=mesh)`` on the unit sphere: what the explicit step scales with between grids. On
    the equiangular cube only its first element is built: a face corner's, the smallest
    element (the eight cube corners' are alike by symmetry); on a mesh it is read from the cache
    (``core.cache``, entry ``smallest_dx``, keyed by the mesh's content as the dual mesh is) or
    built once and stored there."""
    if mesh is None:
        return float(element_sizes(CubedSphere(ne, np_, 1.0, elements=np.array([0]))).dx_short.min())

    def build():
        return {"dx": np.float64(element_sizes(CubedSphere(ne, np_, 1.0, mesh=mesh)).dx_short.min())}

    key = {"mesh": mesh.sha256(), "map": mesh.map, "ne": ne, "np": np_, "build": SMALLEST_DX_BUILD}
    return float(cache.cached("smallest_dx", key, build)[0]["dx"])


def reference_spacing(grid) -> float:
    """d_ref (m): half the width of the face-centre element of the uniform cube with as many
    elements as ``grid`` (ne_mean = √(F/6) for F elements; the cube's own ne), πa / (4 ne_mean):
    the singular value of D where the equiangular map is conformal, and HOMME's (np − 1) dx / 2
    with dx = 2πa / (4 ne (np − 1)) in its conversion of ν to the tensor's ``nu`` (``cube_mod``)."""
    return math.pi * grid.radius / (4 * math.sqrt(grid.nelem_total / 6))


def hypervis_tensor(grid, scaling: float) -> np.ndarray:
    """HOMME's tensor hyperviscosity V at every node ``grid`` holds (``cube_mod::metric_atomic``'s
    ``tensorVisc``; Guba, Taylor, Ullrich, Overfelt & Levy 2014, GMD 7:2803, §3), (3, N): V₁₁,
    V₁₂, V₂₂ in the (east, north) basis, dimensionless, before its DSS.

    With the metric inverse M = Dinv Dinvᵀ = E diag(μ) Eᵀ (1/m²), V = (D E) diag(λ*² μ) (D E)ᵀ
    with λ* = μ^(−s/4) (s = ``scaling``, HOMME's ``hypervis_scaling``), i.e. D M^(1 − s/2) Dᵀ,
    divided by its value d_ref^s at the ``reference_spacing`` d_ref, where D = d_ref·(a rotation):
    along a principal direction of an element whose D has singular value d, the effective ν is
    ν·(d / d_ref)^s (HOMME's eigenvalues are on the unit sphere, scaled by a²; the a^(4−s) of its
    ``nu`` in 1/s is kept in ν here, m⁴ s⁻¹ at d_ref). s = 0 gives V = I, s = 4 gives
    (D Dᵀ)² / d_ref⁴. Raises ``ValueError`` for s < 0 or not finite."""
    if not (math.isfinite(scaling) and scaling >= 0):
        raise ValueError(f"scaling must be a finite number >= 0 (got {scaling})")
    D = grid.D.T.reshape(-1, 2, 2)
    Dinv = grid.Dinv.T.reshape(-1, 2, 2)
    mu, E = np.linalg.eigh(Dinv @ Dinv.transpose(0, 2, 1))
    power = (E * (mu ** (1 - scaling / 2))[:, None, :]) @ E.transpose(0, 2, 1)  # M^(1 − s/2)
    V = D @ power @ D.transpose(0, 2, 1) / reference_spacing(grid) ** scaling
    return np.stack([V[:, 0, 0], (V[:, 0, 1] + V[:, 1, 0]) / 2, V[:, 1, 1]])


def element_bilinear(f: np.ndarray, rule) -> np.ndarray:
    """Fields f (rows, N), element-local at the GLL nodes of ``rule``, replaced in each element by
    the bilinear interpolant of its four corner values (HOMME ``global_norms_mod::dss_hvtensor``,
    after the DSS that makes the corners continuous: the result is then continuous across every
    edge, linear along it between the same two corners)."""
    n = rule.np
    g = f.reshape(f.shape[0], -1, n, n)  # (rows, element, j, i)
    x, y = rule.points[None, None, None, :], rule.points[None, None, :, None]
    sw, se, nw, ne = (g[:, :, j, i][:, :, None, None] for j, i in ((0, 0), (0, -1), (-1, 0), (-1, -1)))
    out = ((1 - x) * (1 - y) * sw + (1 - x) * (1 + y) * nw + (1 + x) * (1 - y) * se + (1 + x) * (1 + y) * ne) / 4
    return out.reshape(f.shape)
