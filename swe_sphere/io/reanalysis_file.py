"""The reanalysis file reader: one level and one time of a CF netCDF file (or an
``xarray.Dataset``) on a global regular or Gaussian lat-lon grid, as the values the analysis
(``io.reanalysis``) takes.

Variables are found by their CF ``standard_name``, else by the usual names (``NAMES``); the
height is the geopotential (m² s⁻²) or the geopotential height (m, times g₀), told apart by
``standard_name`` or ``units`` and checked against the standard atmosphere at the level; the wind
u, v in m s⁻¹. The level (hPa) and the time are chosen as ``io.reanalysis`` describes; the grid's
ring layout (Gaussian, regular with or without poles) and its exact quadrature degree are told
from the latitudes. A file is read with netCDF4 itself (xarray's open costs a run 2-3 s of
imports). Every problem raises ``SceneError`` in one line naming the file and variable.

Sources: Williamson et al. (1992) J. Comput. Phys. 102, 211–224, case 7; the U.S. Standard
Atmosphere (1976) for the plausible heights; WMO's g₀ = 9.80665 m s⁻².
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import SceneError
from .formats import refuse_grib
from .units import DEPTH_UNITS, GEOPOTENTIAL_UNITS, LAT_UNITS, LON_UNITS, PRESSURE_UNITS, WIND_UNITS, normal

G0 = 9.80665  # m s⁻²: WMO's standard gravity, geopotential = g₀ × geopotential height
HEIGHT_UNITS = DEPTH_UNITS | {"gpm", "geopotential meters", "geopotential metres"}
# variable names tried when no standard_name says: geopotential or its height, wind, surface
NAMES = {
    "height": ("z", "Z", "Z3", "zg", "hgt", "gh", "geopotential", "geopotential_height"),
    "u": ("u", "U", "ua", "uwnd"),
    "v": ("v", "V", "va", "vwnd"),
    "surface": ("orog", "hs", "zs", "PHIS", "phis", "z", "hgt", "elevation"),
}
STANDARD = {
    "height": ("geopotential_height", "geopotential"),
    "u": ("eastward_wind",),
    "v": ("northward_wind",),
    "surface": ("surface_altitude", "surface_geopotential", "geopotential", "height_above_mean_sea_level"),
}
WHAT = {
    "height": "geopotential (m2 s-2) or geopotential height (m)",
    "u": "eastward wind u (m s-1)",
    "v": "northward wind v (m s-1)",
    "surface": "surface height (m) or surface geopotential (m2 s-2)",
}
LEVEL_NAMES = ("level", "lev", "plev", "pressure_level", "isobaricInhPa", "pressure", "pres")
# a ring layout's (ducc0's geometry's) highest degree analysed exactly from n rings
EXACT_DEGREE = {"GL": lambda n: n - 1, "CC": lambda n: n - 2, "F1": lambda n: n - 1, "DH": lambda n: (n - 2) // 2}
_ATOL = 2e-6  # rad (1e-4 degrees): latitudes written in float32 still tell the layouts apart


def _rings(n: int) -> dict[str, np.ndarray]:
    """The colatitudes (n,) of each ring layout ducc0 analyses exactly, north to south."""
    import ducc0

    return {
        "GL": ducc0.misc.GL_thetas(n),
        "CC": np.linspace(0.0, math.pi, n),
        "F1": (np.arange(n) + 0.5) * math.pi / n,
        "DH": np.arange(n) * math.pi / n,
    }


@dataclass(frozen=True)
class _Variable:
    """A file's variable as the reader sees it: its name, dimensions, attributes and values
    (float64 where numeric, fill values NaN, dates as datetime64) read on ``values()``."""

    name: str
    dims: tuple
    attrs: dict
    values: object  # () -> np.ndarray


@dataclass(frozen=True)
class _Source:
    """A netCDF file or an ``xarray.Dataset`` as the reader sees it: ``variables`` by name
    (data and coordinates), ``sizes`` of its dimensions, its global ``attrs``."""

    variables: dict
    sizes: dict
    attrs: dict
    close: object = lambda: None  # () -> None: the file closed

    def data(self) -> list[str]:
        """The names of the variables that are not a dimension's coordinate."""
        return [n for n, v in self.variables.items() if v.dims != (n,)]

    def coordinate(self, dim: str) -> np.ndarray:
        """The values along ``dim``: its coordinate, else 0, 1, ..."""
        var = self.variables.get(dim)
        return var.values() if var is not None and var.dims == (dim,) else np.arange(self.sizes[dim])


def _netcdf_values(var) -> np.ndarray:
    """A netCDF4 variable read whole and unpacked, its fill values NaN, a time axis as datetime64."""
    import netCDF4

    values = var[...]
    units = getattr(var, "units", "")
    if isinstance(units, str) and " since " in units and var.ndim == 1:
        try:
            dates = netCDF4.num2date(
                values, units, getattr(var, "calendar", "standard"), only_use_cftime_datetimes=False
            )
            return np.array([np.datetime64(d.isoformat()) for d in np.ravel(dates)], dtype="datetime64[s]")
        except ValueError:  # units netCDF makes no dates of ("months since ..."): the numbers
            pass
    if np.ma.isMaskedArray(values):
        values = np.ma.filled(values.astype(np.float64), np.nan) if values.dtype.kind in "fiu" else values.data
    return np.asarray(values)


def open_source(source, where: str) -> _Source:
    """``source`` (a path, read with netCDF4: xarray's open costs a run 2-3 s of imports, or an
    ``xarray.Dataset``) as a ``_Source``, refusing a file netCDF cannot read and one of our own
    run or restart files."""
    if isinstance(source, (str, Path)):
        import netCDF4

        path = Path(source)
        if path.is_dir():
            raise SceneError(f"{where}: is a directory, not a netCDF file")
        if not path.is_file():
            raise SceneError(f"{where}: file not found")
        refuse_grib(path, where)
        try:
            ds = netCDF4.Dataset(path)
            ds.set_always_mask(True)
            variables = {
                n: _Variable(n, v.dimensions, {k: v.getncattr(k) for k in v.ncattrs()}, lambda v=v: _netcdf_values(v))
                for n, v in ds.variables.items()
            }
            sizes = {n: len(d) for n, d in ds.dimensions.items()}
            out = _Source(variables, sizes, {k: ds.getncattr(k) for k in ds.ncattrs()}, ds.close)
        except Exception:  # netCDF4 raises several types, some over many lines
            raise SceneError(f"{where}: not a readable netCDF file (truncated, or another format)") from None
    else:
        variables = {
            str(n): _Variable(str(n), tuple(map(str, v.dims)), dict(v.attrs), lambda v=v: np.asarray(v.values))
            for n, v in source.variables.items()
        }
        out = _Source(variables, {str(k): v for k, v in source.sizes.items()}, dict(source.attrs))
    if "ncol" in out.sizes or "swe_sphere_checkpoint" in out.attrs:
        out.close()
        raise SceneError(
            f"{where}: a swe_sphere run or restart file, on the model's nodes, not a lat-lon state "
            '(start from it with case name = "file", path = ...)'
        )
    return out


def _find(ds: _Source, role: str, where: str) -> str:
    """The name of ``ds``'s variable of ``role``: one whose ``standard_name`` is one of
    ``STANDARD``'s (CF), else one of ``NAMES``; ``SceneError`` when none."""
    data = ds.data()
    for standard in STANDARD[role]:
        for name in data:
            if ds.variables[name].attrs.get("standard_name") == standard:
                return name
    for name in NAMES[role]:
        if name in data:
            return name
    raise SceneError(
        f"{where}: no {WHAT[role]} (standard_name {' or '.join(STANDARD[role])}, or a variable named "
        f"{', '.join(NAMES[role])})"
    )


def _scale(var: _Variable, role: str, where: str) -> float:
    """The factor to m² s⁻² (the geopotential of height roles) or m s⁻¹ (wind) of ``var`` by its
    standard_name and units; ``SceneError`` for units that are neither."""
    units, standard = var.attrs.get("units"), var.attrs.get("standard_name", "")
    if role in ("u", "v"):
        if units is not None and normal(units) not in WIND_UNITS:
            raise SceneError(f"{where}: {var.name} has units {units!r}; the wind must be in m s-1")
        return 1.0
    if units is None:
        if standard in ("geopotential", "surface_geopotential"):
            return 1.0
        if standard:
            return G0
        raise SceneError(f"{where}: {var.name} has no units: m (a height) or m2 s-2 (a geopotential) is needed")
    if normal(units) in GEOPOTENTIAL_UNITS:
        return 1.0
    if normal(units) in HEIGHT_UNITS:
        return G0
    raise SceneError(f"{where}: {var.name} has units {units!r}; neither m (a height) nor m2 s-2 (a geopotential)")


def _horizontal(ds: _Source, var: _Variable, where: str) -> tuple[str, str]:
    """The latitude and longitude dimensions of ``var`` (by their units, standard names or names)."""
    found = {}
    for dim in var.dims:
        coord = ds.variables.get(dim)
        attrs = coord.attrs if coord is not None else {}
        units, standard = normal(attrs.get("units", "")), attrs.get("standard_name", "")
        if units in LAT_UNITS - {"degrees", "degree"} or standard == "latitude" or dim in ("lat", "latitude"):
            found["lat"] = dim
        elif units in LON_UNITS - {"degrees", "degree"} or standard == "longitude" or dim in ("lon", "longitude"):
            found["lon"] = dim
    if len(found) < 2:
        raise SceneError(f"{where}: {var.name} has no latitude and longitude dimensions (dimensions {var.dims})")
    return found["lat"], found["lon"]


def _select(ds: _Source, var: _Variable, level, time, where: str):
    """(values (lat, lon), its latitude and longitude dimensions, the pressure level taken in hPa
    or None where the file does not say, and each other dimension's value taken as "DIM VALUE")
    of ``var`` at ``level`` (hPa) and ``time`` (module docstring), its other dimensions gone."""
    lat, lon = _horizontal(ds, var, where)
    values, dims = var.values(), list(var.dims)
    rest = [d for d in dims if d not in (lat, lon)]
    vertical = next((d for d in rest if d in LEVEL_NAMES or _pressure_factor(ds, d) is not None), None)
    taken, picked = None if level is None else float(level), []

    def take(dim, index):
        nonlocal values
        values = np.take(values, index, axis=dims.index(dim))
        dims.remove(dim)
        rest.remove(dim)
        shown = _shown_hpa if dim == vertical else _shown
        picked.append(shown(ds, dim, index=index))

    if level is not None:
        index = _at_level(ds, var, vertical, float(level), where)
        if index is not None:
            take(vertical, index)
    if time is not None:
        dim, value = str(time).split("=", 1) if "=" in str(time) else (None, str(time))
        left = [d for d in rest if d != vertical]
        left = [d for d in left if ds.sizes[d] > 1] if len(left) > 1 else left  # the one it can mean
        dim = dim.strip() if dim is not None else (left[0] if len(left) == 1 else None)
        if dim is None or dim not in rest:
            have = ", ".join(rest) or "none"
            raise SceneError(f"{where}: time {time!r}: no such dimension of {var.name} (its others: {have})")
        take(dim, _at_time(ds, dim, value.strip(), where))
    for dim in list(rest):
        if ds.sizes[dim] == 1:
            if dim == vertical and _pressure_factor(ds, dim) is not None:
                taken = float(_hpa(ds, dim)[0])
            take(dim, 0)
        elif dim == vertical:
            raise SceneError(f"{where}: {var.name} is 3-D: give a level (hPa; the file has {_shown_hpa(ds, dim)})")
        else:
            raise SceneError(f"{where}: {var.name} has {ds.sizes[dim]} {dim} values: give a time ({_shown(ds, dim)})")
    return (values if dims == [lat, lon] else values.T), lat, lon, taken, picked


def _pressure_factor(ds: _Source, dim) -> float | None:
    var = ds.variables.get(dim)
    units = None if var is None else var.attrs.get("units")
    return None if units is None else PRESSURE_UNITS.get(normal(units))


def _shown(ds: _Source, dim, values=None, unit: str = "", index=None) -> str:
    """``dim``'s values (the first 8; the one at ``index`` where given) for a message."""
    values = ds.coordinate(dim) if values is None else values
    values = values if index is None else values[index : index + 1]
    text = [str(v)[:19] if np.issubdtype(values.dtype, np.datetime64) else f"{v:g}" for v in values[:8]]
    return f"{dim} " + ", ".join(text) + (", ..." if values.size > 8 else "") + unit


def _hpa(ds: _Source, dim) -> np.ndarray:
    """The pressure levels along ``dim`` in hPa (a coordinate without pressure units taken as hPa)."""
    return np.asarray(ds.coordinate(dim), dtype=np.float64) * (_pressure_factor(ds, dim) or 1.0)


def _shown_hpa(ds: _Source, dim, index=None) -> str:
    return _shown(ds, dim, _hpa(ds, dim), " hPa", index)


def _at_level(ds: _Source, var: _Variable, vertical, level: float, where: str) -> int | None:
    """The index of pressure ``level`` hPa on ``var``'s vertical dimension (None: a scalar level
    coordinate that is ``level``)."""
    if vertical is None:
        scalar = next((n for n in LEVEL_NAMES if n in ds.variables and ds.variables[n].dims == ()), None)
        if scalar is not None:
            value = float(ds.variables[scalar].values()) * (_pressure_factor(ds, scalar) or 1.0)
            if abs(value - level) < 1e-6:
                return None
        raise SceneError(f"{where}: level {level:g} hPa: {var.name} has no vertical dimension (dimensions {var.dims})")
    values = _hpa(ds, vertical)
    hit = np.flatnonzero(np.abs(values - level) <= 1e-6 * max(1.0, level))
    if hit.size == 0:
        shown = ", ".join(f"{v:g}" for v in values)
        pascal = np.any(np.abs(values - level / 100.0) <= 1e-6 * max(1.0, level / 100.0))
        hint = f": the level is in hPa, {level / 100:g} here" if pascal else ""
        raise SceneError(f"{where}: level {level:g} hPa is not in the file (levels {shown} hPa){hint}")
    return int(hit[0])


def _at_time(ds: _Source, dim: str, value: str, where: str) -> int:
    """The index of the one ``dim`` value that ``value`` names (a date to its given precision)."""
    coord = ds.coordinate(dim)
    if np.issubdtype(coord.dtype, np.datetime64):
        try:
            hit = np.flatnonzero(coord.astype(np.datetime64(value).dtype) == np.datetime64(value))
        except ValueError:
            raise SceneError(f"{where}: time {value!r} is not a date (e.g. 2021-01-15T00)") from None
    else:
        try:
            hit = np.flatnonzero(np.isclose(coord.astype(np.float64), float(value), rtol=1e-9, atol=0.0))
        except ValueError:
            raise SceneError(f"{where}: {dim} {value!r} is not a number") from None
    if hit.size != 1:
        many = "matches several" if hit.size else "is not one"
        raise SceneError(f"{where}: {dim} {value} {many} of the file's ({_shown(ds, dim)})")
    return int(hit[0])


def _grid(ds: _Source, values: np.ndarray, lat_dim: str, lon_dim: str, where: str):
    """(values (nlat, nlon) north to south and from the first longitude east, φ₀ (rad), the
    ring layout, its exact degree) of selected 2-D ``values``; ``SceneError`` for a grid that is
    not global, not uniform in longitude or of rings ducc0 cannot integrate exactly."""
    lat = np.asarray(ds.coordinate(lat_dim), dtype=np.float64)
    lon = np.asarray(ds.coordinate(lon_dim), dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if lat.size > 1 and lat[1] < lat[0]:
        lat, values = lat[::-1], values[::-1]
    if lon.size > 1 and lon[1] < lon[0]:
        lon, values = lon[::-1], values[:, ::-1]
    if lon.size > 4 and abs(lon[-1] - lon[0] - 360.0) <= 1e-4:  # the first meridian again (NCL, GrADS, CDO)
        differ = float(np.max(np.abs(values[:, -1] - values[:, 0])))
        if differ > 1e-6 * max(float(np.max(np.abs(values))), 1e-300):
            raise SceneError(
                f"{where}: longitude {lon[-1]:g} repeats {lon[0]:g} degrees, but its values differ (by up to "
                f"{differ:.3g}): not one global field"
            )
        lon, values = lon[:-1], values[:, :-1]
    step = 360.0 / max(lon.size, 1)
    if lon.size < 4 or np.max(np.abs(np.diff(lon) - step)) > 1e-4:
        spacing = np.diff(lon)
        if lon.size >= 2 and np.ptp(spacing) <= 1e-4 and lon.size * spacing[0] < 360.0 - 1e-4:
            raise SceneError(
                f"{where}: longitudes {lon.min():g} to {lon.max():g} degrees every {spacing[0]:g}: a regional "
                f"grid ({lon.size * spacing[0]:g} of 360 degrees), not the globe"
            )
        raise SceneError(
            f"{where}: longitudes {lon.min():g} to {lon.max():g} degrees in {lon.size} columns: not equally "
            "spaced around the globe"
        )
    theta = np.radians(90.0 - lat[::-1])  # colatitudes, north to south
    for name, rings in _rings(lat.size).items():
        if np.allclose(theta, rings, rtol=0.0, atol=_ATOL):
            degree = min(EXACT_DEGREE[name](lat.size), (lon.size - 1) // 2)
            return values[::-1], math.radians(lon[0]), name, degree
    raise SceneError(
        f"{where}: latitudes {lat.min():g} to {lat.max():g} degrees in {lat.size} rows: not a global Gaussian or "
        "equally spaced grid (a regional grid, or rows missing near the poles)"
    )


def read_field(ds: _Source, role: str, level, time, where: str):
    """(values in m² s⁻² or m s⁻¹ north to south, φ₀, ring layout, exact degree) of ``role``."""
    name = _find(ds, role, where)
    var = ds.variables[name]
    scale = _scale(var, role, where)
    *selected, taken, picked = _select(ds, var, level, time, where)
    values, phi0, rings, degree = _grid(ds, *selected, where)
    bad = np.count_nonzero(~np.isfinite(values))
    if bad:
        raise SceneError(f"{where}: {name} has {bad} missing values (NaN or fill values): a state must be whole")
    if role == "height" and taken is not None:
        _plausible(values * scale / G0, var, taken, where)
    what = {"u": "", "v": ""}.get(role, " as a geopotential" if scale == 1.0 else " as a geopotential height")
    return values * scale, phi0, rings, degree, f"{name}{what}" + (f" ({', '.join(picked)})" if picked else "")


RINGS = {  # ducc0's ring layouts as a reader says them
    "GL": "Gaussian",
    "CC": "regular (poles included)",
    "F1": "regular (no poles: offset half a row)",
    "DH": "regular (the north pole alone)",
}


def standard_height(level: float) -> float:
    """The geopotential height (m) of the pressure ``level`` (hPa) in the ICAO standard atmosphere
    (ICAO Doc 7488, 1993; the US Standard Atmosphere 1976 below 20 km): a lapse rate of 6.5 K km⁻¹
    from 288.15 K and 1013.25 hPa to the tropopause at 11 km (226.32 hPa), isothermal (216.65 K) above."""
    if level >= 226.32:
        return 288.15 / 0.0065 * (1.0 - (level / 1013.25) ** (0.0065 * 287.05287 / G0))
    return 11000.0 + 287.05287 * 216.65 / G0 * math.log(226.32 / level)


PLAUSIBLE = 3.0  # heights within a factor of the standard atmosphere's: g ≈ 9.8 mislabels lie outside
PLAUSIBLE_FROM = 900.0  # hPa: below this the standard height (≥ 990 m) tells a factor; nearer the ground not


def _plausible(heights: np.ndarray, var: _Variable, level: float, where: str) -> None:
    """Refuse (``SceneError``) geopotential heights (m, (nlat, nlon)) whose mean at ``level`` (hPa)
    is not within ``PLAUSIBLE`` times the standard atmosphere's: a geopotential labelled m (about
    9.8 times too high: 49-58 km at 500 hPa) or a height labelled m2 s-2 (9.8 times too low)."""
    if not 0.0 < level <= PLAUSIBLE_FROM:
        return
    standard, mean = standard_height(level), float(np.mean(heights))
    if standard / PLAUSIBLE <= mean <= PLAUSIBLE * standard:
        return
    units = var.attrs.get("units", var.attrs.get("standard_name"))
    guess = "a geopotential (m2 s-2) labelled m" if mean > standard else "a geopotential height (m) labelled m2 s-2"
    raise SceneError(
        f"{where}: {var.name} (units {units!r}) gives heights of {heights.min():.0f} to {heights.max():.0f} m at "
        f"{level:g} hPa, where the standard atmosphere's is {standard:.0f} m: {guess}? (its units decide)"
    )
