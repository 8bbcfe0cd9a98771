"""Error norms, invariants and Courant numbers (numpy, on element-local fields).

All fields are element-local (N,) and continuous, so an area integral is
``Σ spheremp·f`` (HOMME ``global_integral``).
"""

from __future__ import annotations

import numpy as np

from .grid import CubedSphere


def williamson_norms(grid: CubedSphere, f, f_true) -> dict[str, float]:
    """Normalized l1, l2, l∞ errors of a scalar (Williamson et al. 1992, eqs. 82–84):
    l1 = I|f−fT| / I|fT|, l2 = sqrt(I(f−fT)²)/sqrt(I fT²), l∞ = max|f−fT| / max|fT|."""
    e = f - f_true
    I = grid.integrate
    return {
        "l1": I(np.abs(e)) / I(np.abs(f_true)),
        "l2": float(np.sqrt(I(e * e) / I(f_true * f_true))),
        "linf": float(np.max(np.abs(e)) / np.max(np.abs(f_true))),
    }


def williamson_vector_norms(grid: CubedSphere, u, v, u_true, v_true) -> dict[str, float]:
    """Normalized l1, l2, l∞ errors of the wind (Williamson et al. 1992, eqs. 85–87),
    with |·| the length of the vector difference."""
    I = grid.integrate
    de = np.hypot(u - u_true, v - v_true)
    dt = np.hypot(u_true, v_true)
    return {
        "l1": I(de) / I(dt),
        "l2": float(np.sqrt(I(de * de) / I(dt * dt))),
        "linf": float(np.max(de) / np.max(dt)),
    }


def rotational_divergent_errors(grid: CubedSphere, zeta_err, delta_err, zeta_true, delta_true) -> dict[str, float]:
    """Normalized l2 errors of relative vorticity (the balanced flow) and of
    divergence (gravity waves): sqrt(I ζe²) / n and sqrt(I δe²) / n with
    n = sqrt(I(ζT² + δT²)), the true wind's velocity-gradient scale. One
    normaliser for both (the true divergence may vanish, as on TC2), so that
    their squares add up to the error of the wind's gradient in the same units.
    ``zeta_err``, ``delta_err`` (s⁻¹, (N,)): vorticity and divergence of the
    wind error; ``zeta_true``, ``delta_true``: those of the true wind."""
    I = grid.integrate
    n = np.sqrt(I(zeta_true**2 + delta_true**2))
    return {"l2_vorticity": float(np.sqrt(I(zeta_err**2)) / n), "l2_divergence": float(np.sqrt(I(delta_err**2)) / n)}


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
