"""The bundled initial fields of passive tracers (a scene's ``[tracers]`` ``initial``), by name.

Each takes latitude and longitude (rad, any shape) and returns the mixing ratio q
(dimensionless) of that shape. The transport tests' fields are those of Lauritzen, Skamarock,
Prather & Taylor (2012), Geosci. Model Dev. 5, 887–901, §2.3 (eqs. 10–14): two centres
(λ, θ) = (5π/6, 0) and (7π/6, 0), radius r = 1/2 of the unit sphere (a/2).
"""

from __future__ import annotations

import math

import numpy as np

# Lauritzen et al. 2012's centres (λ_i, θ_i) and radius (unit sphere), and their bells' and
# cylinders' background b and amplitude c
CENTRES = ((5 * math.pi / 6, 0.0), (7 * math.pi / 6, 0.0))
RADIUS = 0.5
BACKGROUND, AMPLITUDE = 0.1, 0.9


def _distance(lat, lon, centre) -> np.ndarray:
    """Great-circle angle (rad) from ``centre`` (λ, θ)."""
    lon_c, lat_c = centre
    cosr = np.sin(lat_c) * np.sin(lat) + np.cos(lat_c) * np.cos(lat) * np.cos(lon - lon_c)
    return np.arccos(np.clip(cosr, -1.0, 1.0))


def constant(lat, lon):
    """q = 1: the tracer the continuity itself carries (hq = h), consistency's check."""
    return np.ones_like(np.asarray(lat, dtype=float))


def latitude(lat, lon):
    """q = the initial latitude in degrees: a Lagrangian marker of where the air started (the
    roll-up of Galewsky's jet, where q moves off the latitude circles)."""
    return np.degrees(np.asarray(lat, dtype=float))


def cosine_bells(lat, lon):
    """Lauritzen et al. 2012 eq. 12: b + c·(1 + cos(π r_i / r))/2 within r of centre i, b
    elsewhere (b = 0.1, c = 0.9; maximum 1): C¹ at the bells' edges."""
    q = np.full(np.shape(lat), BACKGROUND)
    for centre in CENTRES:
        ri = _distance(lat, lon, centre)
        inside = ri < RADIUS
        q = np.where(inside, BACKGROUND + AMPLITUDE * 0.5 * (1.0 + np.cos(math.pi * ri / RADIUS)), q)
    return q


def gaussian_hills(lat, lon):
    """Lauritzen et al. 2012 eq. 10–11: 0.95·Σ exp(−5 |x − x_i|²), x on the unit sphere: C∞."""
    lat, lon = np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)
    x = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    q = np.zeros(lat.shape)
    for lon_c, lat_c in CENTRES:
        xc = np.array([math.cos(lat_c) * math.cos(lon_c), math.cos(lat_c) * math.sin(lon_c), math.sin(lat_c)])
        q += 0.95 * np.exp(-5.0 * np.sum((x - xc.reshape(3, *([1] * lat.ndim))) ** 2, axis=0))
    return q


def slotted_cylinders(lat, lon):
    """Lauritzen et al. 2012 eq. 13: 1 within r of a centre, 0.1 elsewhere, less a slot of width
    r/6 (|λ − λ_i| < r/6) open to the north in the first (all but θ − θ_1 < −5r/12, the bridge
    left at its south edge) and to the south in the second (all but θ − θ_2 > 5r/12):
    discontinuous."""
    lat, lon = np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)
    q = np.full(lat.shape, BACKGROUND)
    for i, centre in enumerate(CENTRES):
        lon_c, lat_c = centre
        inside = _distance(lat, lon, centre) <= RADIUS
        slot = np.abs(lon - lon_c) < RADIUS / 6
        slot &= (lat - lat_c >= -5 * RADIUS / 12) if i == 0 else (lat - lat_c <= 5 * RADIUS / 12)
        q = np.where(inside & ~slot, 1.0, q)
    return q


def correlated_bells(lat, lon):
    """Lauritzen et al. 2012 eq. 14: ψ = −0.8 q² + 0.9 of the cosine bells q, the nonlinearly
    correlated partner of ``cosine_bells`` for the mixing diagnostics."""
    q = cosine_bells(lat, lon)
    return -0.8 * q**2 + 0.9


TRACER_FIELDS = {
    f.__name__: f for f in (constant, latitude, cosine_bells, gaussian_hills, slotted_cylinders, correlated_bells)
}


def with_tracers(state: np.ndarray, fields: tuple, lat, lon) -> np.ndarray:
    """``state`` (3, n: u, v, h) with a row of mass hq (m) for each of ``fields`` (functions of
    (lat, lon) giving q: a scene's ``tracer_fields()``) below it, q at (lat, lon) (rad): (3 + K, n)."""
    h = state[2]
    return np.concatenate([state, *(h[None] * field(lat, lon)[None] for field in fields)])
