"""An initial state of one's own: from a netCDF file or a Python function.

A file (``[case] name = "file"``, ``path = "state.nc"``; ``FileState``)
holds the fluid depth ``h`` (m, > 0: the model's h, not the free surface
h + hs), the winds ``u`` (eastward), ``v`` (northward) (m s⁻¹) and optionally the
surface height ``hs`` (m; zero without it), either

- on the model's own nodes: a run file (``(time, ncol)`` with ``lat``/``lon`` on
  ``ncol``, as ``output.RunWriter`` writes) or a restart file of the same ne and
  np (``restart_file``; its surface height is its scene's), the values taken as
  they are; or
- on a regular or Gaussian lat-lon grid: 1-D ``lat``/``latitude`` (degrees,
  either order) and ``lon``/``longitude`` (an even number of uniformly spaced
  degrees around the circle), fields ``(lat, lon)``.

A ``time`` dimension is allowed; the state is at ``case.time`` (days, one of
the file's) or the last time. Lat-lon fields are interpolated to the GLL nodes
by bicubic splines (scipy's ``RectBivariateSpline``), periodic in longitude and
continued over the poles (the row at latitude φ, longitude λ + 180° is the point
at 180° − φ, λ); the winds are interpolated as their 3-D Cartesian components, so
the poles hold no singularity. Every copy of a node has the same coordinates
(``grid.CubedSphere``), so the interpolated state is continuous (as after a
DSS) by construction.

A function (``initial=fn`` of ``swe_sphere.run`` and ``simulation.Simulation``):
``fn(lat, lon) -> (h, u, v)``, latitude and longitude in radians (arrays of the
nodes), h in m, u and v in m s⁻¹, arrays of lat's shape (or scalars).

Tracers' initial mixing ratios q (a scene's ``[tracers]`` ``file``, whose variables the
``initial`` entries that are not bundled fields name; ``read_tracer_file``) are read from the
same two layouts, each variable on ``ncol`` (a run file's tracers: a run's q continues another's)
or on the lat-lon grid, at the file's last time; the values as they are, no units asked.

Every problem raises ``SceneError`` (one line naming the file and
variable): a missing variable, units other than m / m s⁻¹ where a ``units``
attribute says so, a wrong shape, a non-finite value, h <= 0, nodes that are not
the run's grid.
"""

from __future__ import annotations

import functools
import inspect
import math
from dataclasses import dataclass

import numpy as np

from ..cases.library import CASES, Case, make_case
from ..core.constants import Planet
from ..core.errors import SceneError
from .formats import file_stamp
from .reanalysis import REANALYSIS_CASES
from .restart_file import case_params
from .restart_file import read as read_restart
from .units import DEPTH_UNITS, LAT_UNITS, LON_UNITS, WIND_UNITS, units_ok

FIELD_UNITS = {"h": DEPTH_UNITS, "hs": DEPTH_UNITS, "u": WIND_UNITS, "v": WIND_UNITS}
WHAT = {
    "h": "the fluid depth, m",
    "hs": "the surface height, m",
    "u": "the eastward wind, m s-1",
    "v": "the northward wind, m s-1",
}
PAD = 16  # spline rows/columns continued across a pole or the date line: the end conditions' effect is ~0.27^PAD


def east_north(lat, lon) -> tuple[np.ndarray, np.ndarray]:
    """Unit east and north vectors (3, ...) at (lat, lon) (radians, broadcast together)."""
    lat, lon = np.broadcast_arrays(lat, lon)
    east = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)])
    north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
    return east, north


def check_state(h, u, v, hs, where: str) -> None:
    """Refuse (``SceneError``) non-finite values or h <= 0; ``where`` names the source."""
    for name, f in (("h", h), ("u", u), ("v", v), ("hs", hs)):
        if f is not None and not np.all(np.isfinite(f)):
            raise SceneError(f"{where}: {name} has {np.count_nonzero(~np.isfinite(f))} non-finite values (NaN or inf)")
    if np.any(h <= 0):
        raise SceneError(
            f"{where}: h <= 0 at {np.count_nonzero(h <= 0)} points (min {np.min(h):.4g} m); "
            "h is the fluid depth (> 0), not the free surface h + hs"
        )


def from_function(fn, lat, lon) -> np.ndarray:
    """The state (3, ...) rows u, v, h of ``fn(lat, lon) -> (h, u, v)`` at the nodes
    (lat, lon in radians). Raises ``SceneError`` for another number or shape of
    values, a ``fn`` that cannot be called with (lat, lon), non-finite values or h <= 0."""
    where = f"initial={getattr(fn, '__name__', type(fn).__name__)}"
    try:  # bound first, so that a TypeError inside fn is fn's own, not ours
        inspect.signature(fn).bind(lat, lon)
    except (TypeError, ValueError) as err:  # not callable, or callable but not with two arguments
        raise SceneError(f"{where} must be a function of (lat, lon) returning (h, u, v) ({err})") from None
    out = fn(lat, lon)
    if not isinstance(out, (tuple, list)) or len(out) != 3:
        raise SceneError(
            f"{where} must return (h, u, v) (got {type(out).__name__}"
            f"{f' of {len(out)}' if isinstance(out, (tuple, list)) else ''})"
        )
    fields = []
    for name, f in zip("huv", out):
        try:
            fields.append(np.broadcast_to(np.asarray(f, dtype=np.float64), np.shape(lat)))
        except (ValueError, TypeError):
            raise SceneError(f"{where}: {name} has shape {np.shape(f)}; the nodes' is {np.shape(lat)}") from None
    h, u, v = fields
    check_state(h, u, v, None, where)
    return np.stack([u, v, h])


def _unit_vectors(lat, lon) -> np.ndarray:
    """(n, 3) unit vectors of the points (lat, lon) (radians, flattened)."""
    lat, lon = np.ravel(lat), np.ravel(lon)
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)


class NodeState:
    """A state given at the unique nodes of a grid (lat, lon in radians, (n,))."""

    def __init__(self, where, lat, lon, fields: dict):
        from scipy.spatial import cKDTree

        self.where, self.fields = where, fields
        self.tree = cKDTree(_unit_vectors(lat, lon))

    def __call__(self, name, lat, lon) -> np.ndarray:
        dist, index = self.tree.query(_unit_vectors(lat, lon))
        if dist.size and dist.max() > 1e-9:  # the degrees written round-trip to ~1e-16
            raise SceneError(
                f"{self.where}: its {self.tree.n} nodes are not those of this run's grid "
                "(a run or restart file of the same ne and np is needed)"
            )
        f = self.fields.get(name)
        return np.zeros(np.shape(lat)) if f is None else f[index].reshape(np.shape(lat))

    def initial(self, lat, lon):
        return tuple(self(name, lat, lon) for name in ("u", "v", "h"))


class LatLonState:
    """A state on a lat-lon grid, interpolated by bicubic splines (module docstring)."""

    def __init__(self, lat, lon, fields: dict):
        from scipy.interpolate import RectBivariateSpline

        self.lon0 = lon[0]
        if "u" in fields:  # a state's winds (a tracer file's fields are scalars)
            u, v = fields.pop("u"), fields.pop("v")
            east, north = east_north(lat[:, None], lon[None, :])
            fields.update(zip(("ux", "uy", "uz"), u * east + v * north))  # Cartesian components: smooth at the poles
        half = lon.size // 2
        # over a pole: latitude -180° - φ (south) or 180° - φ (north) at longitude λ is the point φ at
        # λ + 180°; the pole rows themselves (where a grid has them) are not repeated
        s0 = 1 if lat[0] <= -math.pi / 2 + 1e-12 else 0
        n0 = lat.size - 2 if lat[-1] >= math.pi / 2 - 1e-12 else lat.size - 1
        k = min(PAD, lat.size - 2)
        rows_s, rows_n = np.arange(s0, s0 + k)[::-1], np.arange(n0, n0 - k, -1)
        lat_ext = np.concatenate([-math.pi - lat[rows_s], lat, math.pi - lat[rows_n]])
        lon_ext = np.concatenate([lon[-PAD:] - 2 * math.pi, lon, lon[:PAD] + 2 * math.pi])
        self.splines = {}
        for name, f in fields.items():
            if f is None:
                continue
            shifted = np.roll(f, -half, axis=1)  # column i: longitude λ_i + 180°
            ext = np.concatenate([shifted[rows_s], f, shifted[rows_n]])
            ext = np.concatenate([ext[:, -PAD:], ext, ext[:, :PAD]], axis=1)
            self.splines[name] = RectBivariateSpline(lat_ext, lon_ext, ext, kx=3, ky=3, s=0)

    def __call__(self, name, lat, lon) -> np.ndarray:
        spline = self.splines.get(name)
        if spline is None:
            return np.zeros(np.shape(lat))
        lon = self.lon0 + np.mod(lon - self.lon0, 2 * math.pi)
        return spline(np.ravel(lat), np.ravel(lon), grid=False).reshape(np.shape(lat))

    def initial(self, lat, lon):
        east, north = east_north(lat, lon)
        vec = np.stack([self(name, lat, lon) for name in ("ux", "uy", "uz")])
        return np.sum(vec * east, axis=0), np.sum(vec * north, axis=0), self("h", lat, lon)


def _values(ds, name: str, dims: tuple, where: str, t_index, state: bool = True) -> np.ndarray | None:
    """Variable ``name`` of ``ds`` on ``dims`` (after taking time ``t_index``) as float64,
    a state's (``state``: h, u, v, hs) units checked; None for a missing hs. Raises ``SceneError``."""
    if name not in ds.variables:
        if name == "hs":
            return None
        raise SceneError(f"{where}: no variable {name} ({WHAT[name]}); the file needs h, u, v (and optionally hs)")
    var = ds[name]
    units = var.attrs.get("units")
    if state and units is not None and not units_ok(units, FIELD_UNITS[name]):
        raise SceneError(
            f"{where}: {name} has units {units!r}; {name} is {WHAT[name].split(', ')[0]} in "
            f"{'m' if FIELD_UNITS[name] is DEPTH_UNITS else 'm s-1'}"
        )
    if "time" in var.dims and name != "hs":
        var = var.isel(time=t_index)
    if var.dims != dims:
        raise SceneError(
            f"{where}: {name} has dimensions {var.dims}; expected {dims}"
            + (" (and time)" if t_index is not None else "")
        )
    return np.asarray(var.values, dtype=np.float64)


def _time_index(ds, day, where):
    """The index of model day ``day`` in ``ds.time`` (the last one when None); None without a time dimension."""
    if "time" not in ds.dims:
        if day is not None:
            raise SceneError(f"{where}: case.time = {day:g} but the file has no time dimension")
        return None
    times = np.asarray(ds["time"].values, dtype=np.float64) if "time" in ds.variables else np.arange(ds.sizes["time"])
    if times.size == 0:
        raise SceneError(f"{where}: the time dimension is empty")
    if day is None:
        return times.size - 1
    hit = np.flatnonzero(np.abs(times - day) <= 1e-9 * max(1.0, abs(day)))
    if hit.size == 0:
        shown = ", ".join(f"{t:g}" for t in times[:8]) + (", ..." if times.size > 8 else "")
        raise SceneError(f"{where}: case.time = {day:g} is not one of the file's times ({shown})")
    return int(hit[0])


def _axis(ds, names, allowed, where):
    for name in names:
        if name in ds.variables and ds[name].dims == (name,):
            units = ds[name].attrs.get("units")
            if units is not None and not units_ok(units, allowed):
                raise SceneError(f"{where}: {name} has units {units!r}; degrees are needed")
            return name, np.radians(np.asarray(ds[name].values, dtype=np.float64))
    return None, None


def _lat_lon_axes(ds, where: str, what: str) -> tuple:
    """(lat's name, lat, lon's name, lon) of ``ds``'s 1-D lat-lon grid (radians); ``SceneError``
    ("{where}: {what} the model's nodes ... nor a lat-lon grid") where there is none."""
    lat_name, lat = _axis(ds, ("lat", "latitude"), LAT_UNITS, where)
    lon_name, lon = _axis(ds, ("lon", "longitude"), LON_UNITS, where)
    if lat is None or lon is None:
        raise SceneError(
            f"{where}: {what} the model's nodes (ncol, lat, lon) nor a lat-lon grid (1-D coordinates lat and lon, degrees)"
        )
    return lat_name, lat, lon_name, lon


def read_state(path, day: float | None = None):
    """``load_state`` of the file as it is now, kept while it is unchanged (a scene's
    case is made several times)."""
    if path is None:
        raise SceneError('case.path is missing: the netCDF file of the initial state (case name = "file")')
    return _cached(str(path), file_stamp(path), day)


@functools.lru_cache(maxsize=4)
def _cached(path, stamp, day):
    return load_state(path, day)


def load_state(path, day: float | None = None):
    """The state of the file ``path`` (module docstring) at model day ``day`` (None: the
    last time): a ``NodeState`` or ``LatLonState`` whose ``initial(lat, lon)`` gives
    (u, v, h) and ``(name, lat, lon)`` any field ("hs": zero when absent). Raises ``SceneError``."""
    # here, not at the top: remap brings xarray and scipy.sparse, a third of a second that
    # every command paid on importing the scenes (which import this module)
    from .remap import cached_grid, open_netcdf

    where = f"case.path = {str(path)!r}"
    try:
        ds = open_netcdf(path)
    except (FileNotFoundError, ValueError) as err:
        raise SceneError(f"{where}: {err}") from None
    with ds:
        if "swe_sphere_checkpoint" in ds.attrs:  # a restart file: its element-local state and its scene's hs
            if day is not None:
                raise SceneError(f"{where}: case.time = {day:g}, but a restart file holds one state (drop case.time)")
            stored = read_restart(path)
            scene = stored["scene"]  # as ``Scene.as_dict()`` wrote it
            grid = cached_grid(scene["ne"], scene["np"], scene.get("mesh"))
            lat, lon = grid.lat[grid.first], grid.lon[grid.first]
            u, v, h = grid.to_unique(stored["x"])
            params = case_params(scene["case_params"], stored["path"], stored["analysed"])
            case = make_case(scene["case"], params, Planet.from_table(scene["planet"]), SCENE_CASES)
            return NodeState(where, lat, lon, dict(u=u, v=v, h=h, hs=case.hs(lat, lon)))
        t = _time_index(ds, day, where)
        if "h" in ds.variables and "ncol" in ds["h"].dims:
            fields = {name: _values(ds, name, ("ncol",), where, t) for name in ("h", "u", "v", "hs")}
            check_state(*(fields[k] for k in ("h", "u", "v", "hs")), where)
            lat, lon = (_axis_ncol(ds, name, where) for name in ("lat", "lon"))
            return NodeState(where, lat, lon, fields)
        lat_name, lat, lon_name, lon = _lat_lon_axes(ds, where, "neither")
        fields = {name: _values(ds, name, (lat_name, lon_name), where, t) for name in ("h", "u", "v", "hs")}
    check_state(*(fields[k] for k in ("h", "u", "v", "hs")), where)
    return lat_lon_state(lat, lon, fields, where)


def lat_lon_state(lat, lon, fields: dict, where: str) -> LatLonState:
    """A ``LatLonState`` of ``fields`` ((lat, lon) arrays, None: absent) on the 1-D ``lat`` and
    ``lon`` (radians) of a file (``where``), the rows put south to north. Raises ``SceneError``:
    fewer than 4 latitudes, rows that do not reach the poles (a regional grid), an odd or
    non-uniform number of longitudes around the circle."""
    if np.any(np.diff(lat) < 0):
        lat = lat[::-1]
        fields = {k: None if f is None else f[::-1] for k, f in fields.items()}
    spacing = 2 * math.pi / lon.size
    if lat.size < 4 or np.any(np.diff(lat) <= 0) or lat[0] < -math.pi / 2 - 1e-9 or lat[-1] > math.pi / 2 + 1e-9:
        raise SceneError(f"{where}: lat must hold 4 or more distinct latitudes in [-90, 90] degrees")
    # values that would all fit in radians' range, read as degrees: say so (else the grid looks merely too small)
    radians = (
        " (radians? lat and lon are read in degrees)"
        if np.degrees(max(abs(lat[0]), abs(lat[-1]))) <= math.pi / 2 + 1e-9
        else ""
    )
    # the poles within one row spacing of the first and last rows (a regular grid's half-offset rows, a Gaussian
    # grid's ≈ 0.77 spacing): a regional grid would be extrapolated over the rest of the globe
    if max(lat[0] + math.pi / 2, math.pi / 2 - lat[-1]) > (lat[-1] - lat[0]) / (lat.size - 1) * (1 + 1e-9):
        raise SceneError(
            f"{where}: lat covers {np.degrees(lat[0]):g} to {np.degrees(lat[-1]):g} degrees, not the globe "
            f"(its first and last rows must lie within one row spacing of the poles){radians}"
        )
    if lon.size % 2 or np.max(np.abs(np.diff(lon) - spacing)) > 1e-6 * spacing:
        raise SceneError(
            f"{where}: lon must hold an even number of uniformly spaced longitudes around the circle "
            f"(got {lon.size}{'' if lon.size % 2 else ' not uniformly spaced over 360 degrees'}){radians}"
        )
    return LatLonState(np.clip(lat, -math.pi / 2, math.pi / 2), lon, fields)


def _axis_ncol(ds, name, where) -> np.ndarray:
    if name not in ds.variables or ds[name].dims != ("ncol",):
        raise SceneError(f"{where}: no {name} on ncol (the nodes' coordinates, degrees)")
    return np.radians(np.asarray(ds[name].values, dtype=np.float64))


def read_tracer_file(path, names: tuple):
    """The variables ``names`` of the tracer file ``path`` (module docstring) as a
    ``NodeState`` or ``LatLonState``: ``state(name, lat, lon)`` gives q at the nodes (radians;
    ``NodeState`` refuses nodes that are not the file's). Read once while the file is unchanged
    (a scene's fields are asked for on every rank and every build). Raises ``SceneError``: a
    missing file or variable, other dimensions, non-finite values, a lat-lon grid that is not
    the globe's."""
    return _cached_tracers(str(path), file_stamp(path), tuple(names))


@functools.lru_cache(maxsize=4)
def _cached_tracers(path: str, stamp, names: tuple):
    from .remap import open_netcdf  # here, not at the top: as load_state's

    where = f"tracers.file = {path!r}"
    try:
        ds = open_netcdf(path)
    except SceneError as err:
        raise SceneError(f"{where}: {err}") from None
    with ds:
        missing = [n for n in names if n not in ds.data_vars]
        if missing:
            raise SceneError(
                f"{where}: no variable {missing[0]} (the file's: {', '.join(map(str, ds.data_vars)) or 'none'}); "
                "a tracers.initial that is not a bundled field names a variable of tracers.file"
            )
        t = _time_index(ds, None, where)
        on_nodes = "ncol" in ds[names[0]].dims
        if on_nodes:
            dims = ("ncol",)
            lat, lon = (_axis_ncol(ds, c, where) for c in ("lat", "lon"))
        else:
            lat_name, lat, lon_name, lon = _lat_lon_axes(ds, where, f"{names[0]} is on neither")
            dims = (lat_name, lon_name)
        fields = {n: _values(ds, n, dims, where, t, state=False) for n in names}
    for name, f in fields.items():
        if not np.all(np.isfinite(f)):
            raise SceneError(f"{where}: {name} has {np.count_nonzero(~np.isfinite(f))} non-finite values (NaN or inf)")
    return NodeState(where, lat, lon, fields) if on_nodes else lat_lon_state(lat, lon, fields, where)


@dataclass(frozen=True)
class FileState(Case):
    """An initial state read from a netCDF file (module docstring): h, u, v and
    optionally hs on the model's nodes or a lat-lon grid, at model day ``time``
    of the file (default its last). Unforced, scored against nothing."""

    path: str | None = None
    time: float | None = None

    def __post_init__(self):  # read and checked once (``SceneError``), when the scene is loaded
        object.__setattr__(self, "_state", read_state(self.path, self.time))

    def hs(self, lat, lon):
        return self._state("hs", lat, lon)

    def initial(self, lat, lon):
        return self._state.initial(lat, lon)


# every case a scene may name: the analytic ones, a file's state and a reanalysis's (``reanalysis``)
SCENE_CASES = {**CASES, "file": (FileState, {"path": str, "time": float}), **REANALYSIS_CASES}
