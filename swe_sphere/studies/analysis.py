"""Diagnostics of a run's output on a regular lat-lon grid: zonal means and the
kinetic-energy spectrum by spherical-harmonic degree.

Both evaluate each element's own GLL polynomial (``remap.Remapper``) on the
grid ``remap.latlon_grid`` (both poles, spacing dividing 180°), by default at
half the mean GLL node spacing 90°/(ne (np − 1)). The spectrum analyses the
run's vorticity ζ and divergence δ (scalars, smooth through the poles, unlike
the east/north wind components) with ducc0's spherical-harmonic transform on
that grid as a Clenshaw–Curtis grid, which is exact for a map of degree up to
its row count − 2.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import xarray as xr

from ..core.arguments import path_argument
from ..core.constants import EARTH
from ..core.errors import SceneError
from ..core.runtime import check_memory
from ..io.remap import Remapper, latlon_grid, latlon_shape, open_netcdf, remap_bytes, run_grid
from ..io.run_file import FIELDS, tracer_names

# name → (long name, units on the colour bar, scale applied before drawing, colour map, symmetric about 0)
MAP_FIELDS = {
    "h": ("fluid depth h", "m", 1.0, "viridis", False),
    "h_surface": ("free-surface height h + hs", "m", 1.0, "viridis", False),
    "u": ("eastward wind u", "m s$^{-1}$", 1.0, "RdBu_r", True),
    "v": ("northward wind v", "m s$^{-1}$", 1.0, "RdBu_r", True),
    "speed": ("wind speed |v|", "m s$^{-1}$", 1.0, "magma_r", False),
    "vorticity": ("relative vorticity ζ", "10$^{-5}$ s$^{-1}$", 1e5, "RdBu_r", True),
    "divergence": ("divergence δ", "10$^{-6}$ s$^{-1}$", 1e6, "RdBu_r", True),
}


def map_field(field: str, ds=None) -> tuple:
    """``MAP_FIELDS``' entry of ``field``, or a passive tracer's q of the run ``ds`` (its scene's
    [tracers]; with ``ds`` None any other name is taken as one). ``SceneError`` naming the known
    fields for another name."""
    if field in MAP_FIELDS:
        return MAP_FIELDS[field]
    tracers = tracer_names(ds) if ds is not None else (field,)
    if field not in tracers:
        raise SceneError(f"unknown field {field!r} (known: {', '.join((*MAP_FIELDS, *tracers))})")
    return (f"passive tracer {field} (mixing ratio q)", "1", 1.0, "viridis", False)


DERIVED = ("vorticity", "divergence")  # stored by the model, NaN in files written before they were
DAY_TOL = 1e-6  # days: an output time asked for matches a stored one this close

SPECTRUM_PARTS = {
    "E_rot": "kinetic energy per unit mass of the rotational wind in degree l",
    "E_div": "kinetic energy per unit mass of the divergent wind in degree l",
    "E": "kinetic energy per unit mass in degree l (rotational + divergent)",
}


def run_name(ds) -> str:
    """The file name of a run (``plotting.open_run``), for messages."""
    return Path(ds.attrs.get("_path", "run")).name


def days_of(ds) -> np.ndarray:
    return np.asarray(ds["time"].values, dtype=np.float64) if "time" in ds.variables else np.zeros(0)


def time_index(ds, day: float) -> int:
    """Index of the output time at ``day`` (within 1e-6 day); ``ValueError`` if not stored."""
    days = days_of(ds)
    hits = np.flatnonzero(np.abs(days - day) <= DAY_TOL)
    if hits.size == 0:
        stored = ", ".join(f"{d:g}" for d in days)
        raise SceneError(f"day {day:g} not in {run_name(ds)} (stored: {stored})")
    return int(hits[0])


def field_at_nodes(ds, field: str, day: float) -> np.ndarray:
    """``field`` (one of ``MAP_FIELDS`` or the run's tracers, ``map_field``) of a run at ``day`` on
    its unique nodes (ncol,), in the file's units (s⁻¹ for vorticity and divergence). ``ValueError``
    if it cannot be had."""
    map_field(field, ds)
    it = time_index(ds, day)

    def get(name):
        if name not in ds.variables:
            raise SceneError(f"{run_name(ds)} has no {name!r}")
        var = ds[name]
        return np.asarray(var.isel(time=it).values if "time" in var.dims else var.values, dtype=np.float64)

    if field == "h_surface":
        return get("h") + get("hs")
    if field == "speed":
        return np.hypot(get("u"), get("v"))
    values = get(field)
    if field in DERIVED and not np.all(np.isfinite(values)):
        raise SceneError(f"{run_name(ds)} has no {field} at day {day:g}")
    return values


def _loaded(run) -> xr.Dataset:
    """A run as a Dataset: ``run`` itself, or the file at that path read into memory and closed."""
    if isinstance(run, xr.Dataset):
        return run
    path_argument("run", run, "an xarray.Dataset or a run file's path", SceneError)
    with open_netcdf(run) as opened:
        ds = opened.load()
    ds.attrs.setdefault("_path", str(run))  # for messages (``run_name``)
    return ds


def planet_radius(ds: xr.Dataset) -> float:
    """The planet radius a (m) of a run: its scene's ``planet.radius`` when the
    file records one, else Williamson et al.'s 6.37122e6 m."""
    try:
        return float(json.loads(ds.attrs["scene"])["planet"]["radius"])
    except (KeyError, TypeError, ValueError):
        return EARTH.a


def node_degree(grid) -> int:
    """ne (np − 1), the nodes along a cube face's edge: on a mesh (ne 0) with ne the cube's of as
    many elements, √(elements / 6), rounded, so that its mean node spacing stands for the mesh's
    (and 45° over it divides 180°, as a lat-lon grid's spacing must)."""
    if grid.ne:
        return grid.ne * (grid.np - 1)
    return max(1, round(math.sqrt(grid.nelem_total / 6) * (grid.np - 1)))


def default_resolution(grid) -> float:
    """Half the mean GLL node spacing, 45°/(ne (np − 1)) (``node_degree``): the lat-lon spacing
    (degrees) ``zonal_mean`` and ``kinetic_energy_spectrum`` evaluate a run on by default."""
    return 45.0 / node_degree(grid)


def _on_latlon(ds, fields, days, resolution):
    """(lat, lon degrees, days, values (len(fields), len(days), nlat, nlon)) of the
    node fields ``fields`` (``MAP_FIELDS`` names) at ``days`` (default: every
    output time) on ``latlon_grid(resolution)``."""
    grid = run_grid(ds)
    days = days_of(ds) if days is None else np.atleast_1d(np.asarray(days, dtype=np.float64))
    if days.size == 0:
        raise SceneError("the run holds no output time")
    nodes = np.array([[field_at_nodes(ds, f, d) for d in days] for f in fields])  # ValueError for a day not stored
    resolution = default_resolution(grid) if resolution is None else resolution
    nlat, nlon = latlon_shape(resolution)  # the memory check before the grid is built
    check_memory(remap_bytes(nlat * nlon, grid.np, nodes.shape[0] * nodes.shape[1]), f"a {nlat} x {nlon} lat-lon grid")
    lat, lon = latlon_grid(resolution)
    values = Remapper(grid, np.radians(lat)[:, None], np.radians(lon)[None, :])(nodes)
    return lat, lon, np.array([days_of(ds)[time_index(ds, d)] for d in days]), values


def zonal_mean(run, field: str = "h", days=None, resolution: float | None = None) -> xr.DataArray:
    """The zonal (longitude) mean of a field of a run, by latitude.

    ``run``: a run as an ``xarray.Dataset`` (``swe_sphere.run``'s result, a run
    file opened with xarray) or a run file's path. ``field``: one of
    ``MAP_FIELDS`` (h, h_surface, u, v, speed, vorticity, divergence).
    ``days``: model days, each an output time (default: all). ``resolution``
    (degrees, dividing 180; default ``default_resolution``): the field is each
    element's GLL polynomial evaluated on ``remap.latlon_grid(resolution)``
    and averaged over its longitudes (equally spaced: the trapezoidal rule,
    spectrally accurate for a smooth periodic field).

    Returns an ``xarray.DataArray`` (time, lat), time in model days, lat in
    degrees_north (−90..90, both poles; u's and v's means there are their limit, 0:
    a wind component's mean over a shrinking circle), in the field's units (m, m s⁻¹, s⁻¹),
    named ``<field>_zonal_mean``. Raises ``SceneError`` (a ValueError) for a missing
    file, ``ValueError`` (one line) for an unknown field, a day not stored, a
    field the file lacks or a resolution that does not divide 180°,
    ``runtime.ResourceError`` when the grid would not fit in memory."""
    ds = _loaded(run)
    lat, _, days, values = _on_latlon(ds, [field], days, resolution)
    long_name = MAP_FIELDS[field][0]
    units = FIELDS[{"h_surface": "h", "speed": "u"}.get(field, field)][
        "units"
    ]  # the file's (MAP_FIELDS': the colour bar's)
    mean = values[0].mean(axis=-1)
    if field in ("u", "v"):  # at a pole east and north turn with longitude: a wind component's mean over a
        mean[:, np.abs(lat) == 90.0] = 0.0  # shrinking circle of latitude tends to 0, its limit there
    return xr.DataArray(
        mean,
        dims=("time", "lat"),
        name=f"{field}_zonal_mean",
        coords=dict(
            time=("time", days, dict(units="days", long_name="model time")),
            lat=("lat", lat, dict(units="degrees_north", standard_name="latitude")),
        ),
        attrs=dict(units=units, long_name=f"zonal mean of the {long_name}"),
    )


def degree_power(alm: np.ndarray, lmax: int) -> np.ndarray:
    """Σ_m |a_lm|² over m = −l..l (l = 0..lmax) of a real field's coefficients
    ``alm`` (healpy order, m ≥ 0 only, as ducc0 stores them, up to degree and
    order ``lmax``): |a_l0|² + 2 Σ_{m>0} |a_lm|², since a_{l,−m} = (−1)^m conj(a_lm)."""
    power = np.zeros(lmax + 1)
    start = 0
    for m in range(lmax + 1):
        block = np.abs(alm[start : start + lmax + 1 - m]) ** 2  # l = m..lmax
        power[m:] += block if m == 0 else 2.0 * block
        start += lmax + 1 - m
    return power


def kinetic_energy_spectrum(run, days=None, lmax: int | None = None) -> xr.Dataset:
    """The kinetic-energy spectrum of a run by spherical-harmonic degree l, as
    rotational and divergent parts (Koshyk & Hamilton 2001; Augier & Lindborg 2013).

    The energy is per unit mass and a global mean: Σ_l E(l) is the area mean
    of ½|v|² (m² s⁻²), h not weighted in. With ζ_lm, δ_lm the coefficients of
    the vorticity and divergence in harmonics orthonormal on the unit sphere,
    ``E_rot(l) = a² / (8π l(l+1)) Σ_{m=−l..l} |ζ_lm|²`` and E_div(l) likewise from
    δ_lm (the streamfunction ψ_lm = −a² ζ_lm / (l(l+1)); a the planet radius,
    ``planet_radius``). The harmonics are ducc0's: ζ and δ of the file (the
    model's DSS'd curl and divergence) on ``remap.latlon_grid`` at
    ``default_resolution`` (half the mean GLL spacing) analysed on that
    Clenshaw–Curtis grid to its full degree (2 lmax by default; exact for
    content up to it, so only the elements' edge kinks beyond alias), then cut
    at ``lmax``.

    ``run``: a run as an ``xarray.Dataset`` or a run file's path. ``days``:
    model days, each an output time (default: all). ``lmax``: the highest degree
    (default 2 ne (np − 1), ``node_degree``'s, the degree of the grid's node spacing: above
    it the spectrum is the elements' edges, not the flow).

    Returns an ``xarray.Dataset`` with ``E_rot``, ``E_div`` and ``E`` (their
    sum) on (time, l), l = 1..lmax, m² s⁻², time in model days; attributes
    ``radius`` (m) and ``definition``. Raises ``SceneError`` (a ValueError) for a
    missing file, ``ValueError`` (one line) for a day not stored, a file without
    vorticity or divergence (written before they were), an lmax < 1,
    ``runtime.ResourceError`` when the grid would not fit in memory."""
    import ducc0

    ds = _loaded(run)
    grid = run_grid(ds)
    lmax = 2 * node_degree(grid) if lmax is None else lmax
    if not (isinstance(lmax, (int, np.integer)) and lmax >= 1):
        raise SceneError(f"lmax must be an integer >= 1 (got {lmax!r})")
    # the grid resolves 2x the node spacing's degree, or lmax + 1 if that is higher
    rows = max(round(180.0 / default_resolution(grid)), lmax + 1)
    lat, lon, days, maps = _on_latlon(ds, ["vorticity", "divergence"], days, 180.0 / rows)
    full = rows - 1  # the CC grid's degree (ntheta − 2) and order ((nphi − 1) // 2)
    power = np.empty(maps.shape[:2] + (lmax + 1,))
    for i, j in np.ndindex(*maps.shape[:2]):
        ring = np.ascontiguousarray(maps[i, j, ::-1])  # CC rings start at the north pole
        alm = ducc0.sht.experimental.analysis_2d(map=ring[None], spin=0, lmax=full, geometry="CC", nthreads=1)[0]
        power[i, j] = degree_power(alm, full)[: lmax + 1]
    a = planet_radius(ds)
    l = np.arange(1, lmax + 1)
    e_rot, e_div = a * a / (8 * math.pi * l * (l + 1)) * power[:, :, 1:]
    attrs = {k: dict(units="m2 s-2", long_name=v) for k, v in SPECTRUM_PARTS.items()}
    return xr.Dataset(
        {
            "E_rot": (("time", "l"), e_rot, attrs["E_rot"]),
            "E_div": (("time", "l"), e_div, attrs["E_div"]),
            "E": (("time", "l"), e_rot + e_div, attrs["E"]),
        },
        coords=dict(
            time=("time", days, dict(units="days", long_name="model time")),
            l=("l", l, dict(long_name="spherical-harmonic degree")),
        ),
        attrs=dict(
            radius=a,
            definition="E(l) = a^2 / (8 pi l (l+1)) sum_m |zeta_lm|^2 (and delta_lm), orthonormal "
            "harmonics; sum_l E(l) = global mean of |v|^2 / 2 (Koshyk & Hamilton 2001)",
            source=f"ducc0 analysis of the vorticity and divergence on a {180 / rows:g} degree Clenshaw-Curtis grid",
        ),
    )
