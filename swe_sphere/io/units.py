"""The units a file's fields may carry, as written in the wild (CF's UDUNITS forms and the
usual variants), and their check: what ``initial_state`` and ``reanalysis`` accept."""

from __future__ import annotations

DEPTH_UNITS = {"m", "meter", "meters", "metre", "metres"}
WIND_UNITS = {
    "m s-1",
    "m/s",
    "m s^-1",
    "m s**-1",
    "m.s-1",
    "ms-1",
    "meter/second",
    "meters/second",
    "metre/second",
    "metres/second",
    "meters second-1",
    "metres second-1",
}
LAT_UNITS = {
    "degrees_north",
    "degree_north",
    "degrees_n",
    "degree_n",
    "degrees north",
    "degree north",
    "degrees",
    "degree",
}
LON_UNITS = {"degrees_east", "degree_east", "degrees_e", "degree_e", "degrees east", "degree east", "degrees", "degree"}
GEOPOTENTIAL_UNITS = {"m2 s-2", "m**2 s**-2", "m^2 s^-2", "m2/s2", "m^2/s^2", "m2.s-2", "m**2/s**2", "m2 s**-2"}
PRESSURE_UNITS = {"hpa": 1.0, "mbar": 1.0, "millibar": 1.0, "millibars": 1.0, "mb": 1.0, "pa": 0.01}  # → hPa


def units_ok(units: str, allowed) -> bool:
    """Whether ``units`` (any case and spacing) is one of ``allowed`` (lower case, single spaces)."""
    return normal(units) in allowed


def normal(units) -> str:
    """``units`` in lower case with single spaces."""
    return " ".join(str(units).strip().lower().split())
