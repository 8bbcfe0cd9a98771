"""Planetary constants of Williamson et al. (1992), section 2."""

from dataclasses import dataclass


@dataclass(frozen=True)
class Planet:
    """Radius ``a`` (m), rotation rate ``omega`` (s⁻¹), gravity ``g`` (m s⁻²)."""

    a: float = 6.37122e6
    omega: float = 7.292e-5
    g: float = 9.80616


EARTH = Planet()
DAY = 86400.0  # s
