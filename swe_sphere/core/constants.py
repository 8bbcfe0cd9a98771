"""Planetary constants of Williamson et al. (1992), section 2, and a planet of one's own."""

import math
from dataclasses import dataclass

# the scene's [planet] keys → the Planet attributes they set
PLANET_KEYS = {"radius": "a", "omega": "omega", "gravity": "g"}
# A planet value's bounds: the grid's area takes a², the ∇⁴'s ν a⁴ and the balance g·h, which a
# float holds only for values within about 1e±77; every planet of interest is far inside.
PLANET_RANGE = (1e-30, 1e30)


@dataclass(frozen=True)
class Planet:
    """Radius ``a`` (m), rotation rate ``omega`` (s⁻¹), gravity ``g`` (m s⁻²);
    the defaults are Williamson et al.'s (1992) Earth."""

    a: float = 6.37122e6
    omega: float = 7.292e-5
    g: float = 9.80616

    @classmethod
    def from_table(cls, table: dict | None) -> "Planet":
        """The planet of a scene's ``[planet]`` table ({"radius": m, "omega": s⁻¹,
        "gravity": m s⁻²}, each optional, the rest Williamson's). Raises ValueError
        naming the key (``planet.radius`` ...) of an unknown key or of a value that
        is not a positive finite number within ``PLANET_RANGE``."""
        values = {}
        for key, value in (table or {}).items():
            if key not in PLANET_KEYS:
                raise ValueError(f"unknown key planet.{key} (known: {', '.join(PLANET_KEYS)})")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise ValueError(f"planet.{key} must be a positive finite number (got {value!r})")
            if not PLANET_RANGE[0] <= value <= PLANET_RANGE[1]:
                raise ValueError(
                    f"planet.{key} must be between {PLANET_RANGE[0]:g} and {PLANET_RANGE[1]:g} (got {value!r})"
                )
            values[PLANET_KEYS[key]] = float(value)
        return cls(**values)

    def as_table(self) -> dict:
        """{"radius", "omega", "gravity"}: the scene's ``[planet]`` table of this planet."""
        return {key: getattr(self, attr) for key, attr in PLANET_KEYS.items()}


EARTH = Planet()
DAY = 86400.0  # s
