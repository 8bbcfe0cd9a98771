"""Invariants, Courant numbers and ∇⁴ probes (numpy, on element-local fields); error norms are in ``scoring``.

All fields are element-local (N,) and continuous, so an area integral is
``Σ spheremp·f`` (HOMME ``global_integral``).
"""

from __future__ import annotations

import numpy as np

from ..grid.cubed_sphere import CubedSphere
from ..grid.quality import ElementSizes


def invariants(grid: CubedSphere, u, v, h, hs, zeta, fcor, g) -> dict[str, float]:
    """Mass I h (m³), total energy I(½h|v|² + ½g((h+hs)² − hs²)) (m⁵ s⁻²) and
    potential enstrophy I(½(ζ+f)²/h) (m s⁻²), the integral invariants that
    Williamson et al. (1992) ask to be monitored."""
    I = grid.integrate
    energy = 0.5 * h * (u * u + v * v) + 0.5 * g * ((h + hs) ** 2 - hs**2)
    with np.errstate(divide="ignore", invalid="ignore"):  # h = 0 where h is a tracer (TC1)
        enstrophy = I(0.5 * (zeta + fcor) ** 2 / h)
    return {"mass": I(h), "total_energy": I(energy), "potential_enstrophy": enstrophy}


def courant_numbers(grid: CubedSphere, u, v, h, dt, g, gravity_waves=True) -> dict[str, float]:
    """Maximum advective Courant number |v|Δt/Δx and gravity-wave Courant number
    sqrt(g h)Δt/Δx over the nodes, with Δx the distance to the nearest GLL node
    (``grid.dx``). The gravity-wave number is NaN when the scene has no
    pressure gradient (h is then a tracer)."""
    adv = float(np.max(np.hypot(u, v) * dt / grid.dx))
    grav = float(np.max(np.sqrt(g * np.maximum(h, 0.0)) * dt / grid.dx)) if gravity_waves else float("nan")
    return {"courant_advective": adv, "courant_gravity": grav}


def worst_element_courant(grid: CubedSphere, sizes: ElementSizes, u, v, h, dt, g, gravity_waves=True) -> dict:
    """HOMME's ``print_cfl`` Courant numbers of the element that sets the explicit step (the
    largest σ_max of D⁻¹, ``ElementSizes.summary()["worst"]``): max |v| Δt / dx_short and
    max sqrt(g h) Δt / dx_short over its nodes, with dx_short its Dinv-based length scale
    (m); NaN for the gravity-wave number without a pressure gradient. ``grid`` the elements
    ``sizes`` describes; fields (N,) on them."""
    e = sizes.summary()["worst"]
    nodes = slice(e * grid.np * grid.np, (e + 1) * grid.np * grid.np)
    scale = dt / sizes.dx_short[e]
    adv = float(np.max(np.hypot(u[nodes], v[nodes])) * scale)
    grav = float(np.sqrt(g * np.maximum(h[nodes], 0.0)).max() * scale) if gravity_waves else float("nan")
    return {"courant_advective": adv, "courant_gravity": grav}


def max_signal_rate(grid: CubedSphere, u, v, h, g) -> float:
    """max over the nodes of (|v| + sqrt(g h)) / Δx (s⁻¹): the fastest signal (wind
    plus gravity wave) over the nearest-node distance, whose product with Δt is the
    Courant number an explicit stepper's stability limit is stated in."""
    return float(np.max((np.hypot(u, v) + np.sqrt(g * np.maximum(h, 0.0))) / grid.dx))


HARMONIC_KINDS = ("height", "rotational", "divergent")


def harmonic_state(grid: CubedSphere, l: int, kind: str, orientations: int = 3, seed: int = 0):
    """(u, v, h) (N,) each: a spherical harmonic Y of degree l ≥ 1 as the height
    (``kind`` "height"), or the rotational (r̂ × ∇Y) or divergent (∇Y) wind of
    one, unit scale. Y = Σ Re (a·r̂)^l over ``orientations`` random complex null
    vectors a = e₁ + i e₂ (e₁ ⊥ e₂ unit): harmonic homogeneous polynomials, so
    exact eigenfunctions of the Laplacian (−l(l+1)/a²) that mix all orders m
    and sit at no special place on the cube; gradients analytic (no pole
    singularity). Raises ValueError for an unknown kind or l < 1."""
    if kind not in HARMONIC_KINDS:
        raise ValueError(f"unknown harmonic kind {kind!r} (known: {', '.join(HARMONIC_KINDS)})")
    if l < 1:
        raise ValueError(f"harmonic degree must be >= 1 (got {l})")
    rng = np.random.default_rng(seed)
    r = grid.xyz
    Y = np.zeros(grid.nnodes)
    grad = np.zeros((3, grid.nnodes))
    for _ in range(orientations):
        e1, e2 = np.linalg.qr(rng.standard_normal((3, 2)))[0].T
        a = e1 + 1j * e2
        ar = a @ r
        Y += np.real(ar**l)
        grad += np.real(l * ar ** (l - 1) * a[:, None])
    if kind == "height":
        return np.zeros_like(Y), np.zeros_like(Y), Y
    wind = np.cross(r, grad, axis=0) if kind == "rotational" else grad - np.sum(grad * r, axis=0) * r
    return np.sum(wind * grid.east, axis=0), np.sum(wind * grid.north, axis=0), np.zeros_like(Y)


def ideal_hyperviscosity_rate(l: int, kind: str, nu: float, nu_div: float, nu_s: float, radius: float) -> float:
    """Decay rate (s⁻¹) of a degree-l harmonic under HOMME's continuous ∇⁴
    (``vlaplace_sphere_wk``'s +2v/a², ``nu_div`` on the first ∇(∇·v)):
    height ν_s (l(l+1))²/a⁴, rotational ν (l(l+1) − 2)²/a⁴, divergent
    (l(l+1) − 2)(ν_div l(l+1) − 2ν)/a⁴."""
    k = l * (l + 1)
    return {"height": nu_s * k * k, "rotational": nu * (k - 2) ** 2, "divergent": (k - 2) * (nu_div * k - 2 * nu)}[
        kind
    ] / radius**4


def hyperviscosity_rate(model, state) -> float:
    """Rayleigh quotient ⟨x, Bx⟩/⟨x, x⟩ (s⁻¹, area-weighted) of a model's
    hyperviscosity operator B on a state (u, v, h); build the model with hs = 0.
    For a harmonic x it is the rate at which x's amplitude decays. (Bx itself
    is not ∝ x node by node: the assembled weak Laplacian's error at element
    edges, which the second Laplacian raises to grid-scale noise of the size of
    Bx, is orthogonal to smooth x to the scheme's order.)"""
    import warp as wp

    x = model.new_state(*state)
    out = wp.zeros_like(x)
    model.hv.operator(x, out)
    z, b = x.numpy(), out.numpy()
    I = model.grid.integrate
    return I(np.sum(z * b, axis=0)) / I(np.sum(z * z, axis=0))
