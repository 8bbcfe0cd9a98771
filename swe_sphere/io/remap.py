"""Spectral-element fields → arbitrary points and regular lat-lon grids.

A value at a target point is the owning element's own GLL interpolant evaluated
there: the target's Cartesian position is mapped back to an element and reference
coordinates (ξ, η) ∈ [-1, 1]² through the grid's map: on the cube, the equiangular
gnomonic projection of ``cubed_sphere.FACES`` (face by the largest c·P, then
tan α = P·ea / P·c, tan β = P·eb / P·c, element (ia, jb)); on a mesh (a file, a
stretched cube, the element-local map), the inverse of the mesh's own map, element-local or
equiangular in each element's face (``element_local.locate``, Newton's method in the nearest
elements). The field is Σ_ij ℓ_i(ξ) ℓ_j(η) f_ij with
ℓ the Lagrange basis on the GLL points. No smoothing: a polynomial of degree
< np in (ξ, η) is reproduced exactly, and at a target that coincides with a
GLL node the node's value comes back to round-off. Points on element or cube
edges may take any adjacent element (fields are continuous there).

``u`` and ``v`` are remapped component by component, as the model stores them
(east/north at each node; at the two pole nodes the model's basis is that of
longitude 0).
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.sparse import csr_matrix

from ..core.arguments import path_argument
from ..core.errors import SceneError
from ..core.runtime import check_memory
from ..grid.cubed_sphere import CubedSphere
from ..mesh.element_local import locate as locate_on_mesh
from ..mesh.face_map import FACES
from ..mesh.records import MeshFile, MeshRecord, from_json, mesh_of
from .output_files import atomic_path, check_distinct
from .run_file import element_mesh, history_line, member_statistics, tracer_names

#: node fields (time, ncol) or (ncol,) that ``remap_dataset`` carries to the lat-lon grid (an ensemble's
#: (time, member, ncol) too, with their ``_mean`` and ``_spread``)
NODE_FIELDS = ("h", "hs", "u", "v", "vorticity", "divergence")


def lagrange_basis(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """ℓ_k(x) for the Lagrange basis on ``nodes`` (n,): (M, n) for x (M,).

    Product form, exact 1/0 at the nodes themselves (n ≤ 8, so no loss of accuracy): ℓ_k(x) =
    Π_{m≠k} (x − x_m)/(x_k − x_m), the factors multiplied in order of m (all k at once, a factor of
    exactly 1 for m = k: the bits of the product taken k by k)."""
    x = np.asarray(x, dtype=np.float64)
    nodes = np.asarray(nodes, dtype=np.float64)
    n = len(nodes)
    out = np.ones(x.shape + (n,))
    for m in range(n):
        gap = nodes - nodes[m]  # x_k − x_m for every k
        gap[m] = 1.0
        factor = (x - nodes[m])[..., None] / gap
        factor[..., m] = 1.0
        out *= factor
    return out


def locate(ne: int, lat, lon):
    """Element and reference coordinates of points (``lat``, ``lon`` radians, 1-D).

    Returns ``elem`` (M,) int64 (``face*ne*ne + jb*ne + ia`` as in grid.py), ``xi``,
    ``eta`` (M,) float64 in [-1, 1] (up to round-off at element edges)."""
    lat = np.asarray(lat, dtype=np.float64).ravel()
    lon = np.asarray(lon, dtype=np.float64).ravel()
    P = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)
    cdot = P @ FACES[:, 0].T  # (M, 6): c_k · P
    face = np.argmax(cdot, axis=1)
    cp = cdot[np.arange(P.shape[0]), face]
    ta = np.einsum("ij,ij->i", P, FACES[face, 1]) / cp
    tb = np.einsum("ij,ij->i", P, FACES[face, 2]) / cp
    dalpha = math.pi / 2 / ne
    sa = (np.arctan(ta) + math.pi / 4) / dalpha
    sb = (np.arctan(tb) + math.pi / 4) / dalpha
    ia = np.clip(np.floor(sa), 0, ne - 1).astype(np.int64)
    jb = np.clip(np.floor(sb), 0, ne - 1).astype(np.int64)
    xi = 2.0 * (sa - ia) - 1.0
    eta = 2.0 * (sb - jb) - 1.0
    return face * ne * ne + jb * ne + ia, xi, eta


class Remapper:
    """Evaluation of fields of ``grid`` at fixed target points (``lat``, ``lon`` radians,
    broadcastable arrays of any shape). Built once, applied to any number of fields.

    ``remapper(f)``: f (..., nunique) on unique nodes (a run file's ``ncol``) →
    (..., *shape). ``remapper.local(f)``: f (N,) element-local (need not be
    continuous: each target takes its own element's polynomial). ``matrix``: the (M, nunique) CSR
    matrix ``remapper(f)`` applies (M targets); ``weights``, ``nodes``: each target's np² weights and
    the element-local nodes they weigh (M, np²).
    """

    def __init__(self, grid: CubedSphere, lat, lon):
        lat, lon = np.broadcast_arrays(np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64))
        self.shape = lat.shape
        self.grid = grid
        if grid.mesh is None:
            elem, xi, eta = locate(grid.ne, lat, lon)
        else:
            cos_lat = np.cos(lat.ravel())
            xyz = np.stack([cos_lat * np.cos(lon.ravel()), cos_lat * np.sin(lon.ravel()), np.sin(lat.ravel())], axis=1)
            elem, xi, eta = locate_on_mesh(grid.mesh, xyz)
        self._li = lagrange_basis(grid.rule.points, xi)  # (M, n) along ξ (index i)
        self._lj = lagrange_basis(grid.rule.points, eta)  # (M, n) along η (index j)
        self._elem = elem
        self.matrix = _gather_matrix(grid, elem, self._lj, self._li)

    @functools.cached_property
    def weights(self) -> np.ndarray:
        """(M, np²) float64: each target's weights ℓ_j(η) ℓ_i(ξ) at [j np + i] (made when first asked for:
        the matrix holds them)."""
        n = self.grid.np
        return (self._lj[:, :, None] * self._li[:, None, :]).reshape(self._elem.size, n * n)

    @functools.cached_property
    def nodes(self) -> np.ndarray:
        """(M, np²) int64: the element-local node (element × np² + j np + i) of each of ``weights``."""
        n2 = self.grid.np**2
        return self._elem[:, None] * n2 + np.arange(n2)[None, :]

    def __call__(self, f) -> np.ndarray:
        f = np.asarray(f, dtype=np.float64)
        lead = f.shape[:-1]
        cols = f.reshape(-1, f.shape[-1]).T  # (nunique, k)
        out = np.asarray(self.matrix @ cols).T  # (k, M)
        return out.reshape(lead + self.shape)

    def local(self, f) -> np.ndarray:
        f = np.asarray(f, dtype=np.float64)
        return np.einsum("mk,mk->m", self.weights, f[self.nodes]).reshape(self.shape)


def _gather_matrix(grid: CubedSphere, elem: np.ndarray, lj: np.ndarray, li: np.ndarray) -> csr_matrix:
    """The (M, nunique) CSR matrix of the targets' weights ℓ_j(η) ℓ_i(ξ) (``lj``, ``li`` (M, np)) on the
    unique nodes of their elements ``elem`` (M,), in scipy's canonical form (each row's columns
    ascending) built directly: the same arrays, bit for bit, as ``csr_matrix((weights, (rows, gid)))``
    makes by sorting all M np² entries (several times this), for an element's np² nodes are distinct
    unique nodes; each element's order of its columns is found once, not once a target."""
    m, n = li.shape
    weights = (lj[:, :, None] * li[:, None, :]).reshape(m, n * n)  # as ``Remapper.weights``
    gid = grid.gid.reshape(-1, n * n)  # (elements, np²): the unique node of each element-local node
    order = np.argsort(gid, axis=1, kind="stable")
    columns = np.take_along_axis(gid, order, axis=1)
    if np.any(columns[:, 1:] == columns[:, :-1]):  # an element that meets one node twice: scipy sums them
        rows = np.repeat(np.arange(m), n * n)
        return csr_matrix((weights.ravel(), (rows, gid[elem].ravel())), shape=(m, grid.nunique))
    data = np.take_along_axis(weights, order[elem], axis=1)
    indices = columns[elem].ravel()
    index = np.int32 if max(grid.nunique, indices.size) <= np.iinfo(np.int32).max else np.int64  # as scipy picks
    matrix = csr_matrix(
        (data.ravel(), indices.astype(index, copy=False), np.arange(0, indices.size + 1, n * n, dtype=index)),
        shape=(m, grid.nunique),
    )
    matrix.has_canonical_format = True  # sorted, no duplicates: as scipy leaves its own
    return matrix


def grid_name(grid: CubedSphere) -> str:
    """A grid in a message: ``ne=4 np=4``, or its mesh's name and np (``cube2.g np=4``)."""
    return f"{f'ne={grid.ne}' if grid.mesh is None else grid.mesh.name} np={grid.np}"


def cached_grid(ne: int, np_: int, mesh: dict | None = None) -> CubedSphere:
    """The whole ne, np grid on the mesh ``mesh`` (a run's ``Scene.mesh`` as a run file records
    it, ``mesh.records.from_json``; None: the equiangular cube), built once a process."""
    return _grid(ne, np_, from_json(ne, mesh))


@functools.lru_cache(maxsize=4)
def _grid(ne: int, np_: int, record: MeshRecord | None) -> CubedSphere:
    return CubedSphere(ne, np_, mesh=mesh_of(ne, record).build())


def open_netcdf(path) -> xr.Dataset:
    """A netCDF file opened lazily with xarray, times as numbers (``decode_times=False``).
    Raises ``SceneError`` (a ValueError; one line naming the file) for a missing file, a folder
    or a file that netCDF cannot read."""
    path = Path(path)
    if path.is_dir():
        raise SceneError(f"{path}: is a directory, not a netCDF file")
    if not path.is_file():
        raise SceneError(f"file not found: {path}")
    try:
        return xr.open_dataset(path, decode_times=False)
    except Exception:  # netCDF4 / xarray raise several types (their text: a many-line trace or the type)
        raise SceneError(f"{path}: not a readable netCDF file") from None


MEMBER_VIEWS = ("mean", "spread")  # an ensemble's run file read as one run, besides a member k


def member_label(member) -> str:
    """What a plot of ``member`` adds to its files' names: ``member<K>``, ``mean`` or ``spread``."""
    return member if member in MEMBER_VIEWS else f"member{member}"


def member_view(ds: xr.Dataset, path, member, members: int) -> xr.Dataset:
    """An ensemble's run file ``ds`` (``path``, ``members`` members) read as one run (the plots'
    ``studies.plotting.open_run``): ``member`` k, "mean" (each field's ensemble mean, the series'
    mean over the members) or "spread" (each field's spread, hs zero so that h + hs is h's; the
    series' standard deviation; the members in ``attrs["_ensemble"]``, for a map drawn from them).
    ``ValueError`` (one line; ``ds`` closed) for another member."""
    if member not in MEMBER_VIEWS:
        k = int(member) if str(member).isdigit() else -1
        if not 0 <= k < members:
            ds.close()
            raise ValueError(f"{path}: --member must be 0 to {members - 1}, mean or spread (got {member!r})")
        view = ds.isel(member=k, drop=True)
        view.attrs["_member"] = member_label(k)
        return view
    out = ds.copy()
    out.attrs["_member"] = member
    for name, var in ds.data_vars.items():
        if "member" in var.dims:
            stat = f"{name}_{member}"
            out[name] = (
                ds[stat] if stat in ds else var.mean("member") if member == "mean" else var.std("member", ddof=1)
            )
    if member == "spread":
        out["hs"] = out["hs"] * 0.0
        # a map's spread is the members' where it is drawn: a standard deviation does not commute with
        # the interpolation (the plots' ``plot_map``); the members as read, not a file's attribute
        out.attrs["_ensemble"] = ds
    return out.drop_vars("member")


def run_grid(ds: xr.Dataset) -> CubedSphere:
    """The grid of a run file (from its ``scene`` attribute, else ``ne``/``np``; on the
    mesh the scene records, ``mesh.records``), checked against the file's ``lat``/``lon``.
    Where the mesh file is gone, the elements' mesh the run file carries
    (``run_file.element_mesh``). Raises ``SceneError`` (a ValueError; one line) if the file is
    not a swe_sphere run, its nodes do not match, or its mesh file is changed (or gone from a
    run file that carries no mesh)."""
    if "ncol" not in ds.dims or any(name not in ds.variables for name in ("lat", "lon", "area")):
        where = ds.encoding.get("source")  # the file it was opened from, named as plot names it
        raise SceneError(f"{f'{where}: ' if where else ''}not a swe_sphere run file (no ncol/lat/lon/area)")
    try:
        scene = json.loads(ds.attrs["scene"])
        ne, np_, mesh = int(scene["ne"]), int(scene["np"]), scene.get("mesh")
    except (KeyError, ValueError, TypeError):
        try:
            ne, np_, mesh = int(ds.attrs["ne"]), int(ds.attrs["np"]), None
        except (KeyError, ValueError, TypeError):
            raise SceneError("run file has no scene (ne, np) attribute") from None
    record = mesh_of(ne, from_json(ne, mesh))
    if isinstance(record, MeshFile) and not Path(record.path).is_file():
        try:  # the file moved or sent on: the elements' mesh the run file carries
            grid = CubedSphere(ne, np_, mesh=element_mesh(ds, record))
        except KeyError:
            raise SceneError(f"mesh file {record.path} not found, and the run file carries no mesh") from None
    else:
        grid = cached_grid(ne, np_, mesh)
    if ds.sizes["ncol"] != grid.nunique:
        raise SceneError(f"run file has {ds.sizes['ncol']} columns, {record.description(np_)} has {grid.nunique}")
    lat = np.radians(np.asarray(ds["lat"].values, dtype=np.float64))
    lon = np.radians(np.asarray(ds["lon"].values, dtype=np.float64))
    a = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    if np.max(np.abs(a - grid.xyz[:, grid.first])) > 1e-9:
        raise SceneError(f"run file's lat/lon do not match the grid it names ({record.description(np_)})")
    return grid


def latlon_shape(resolution: float) -> tuple[int, int]:
    """(rows, columns) of ``latlon_grid(resolution)``, 180/r + 1 and 360/r, without building it
    (a memory check comes first). Raises ``SceneError`` (a ValueError) unless 0 < r ≤ 90 and
    180/r is an integer (to 1e-9)."""
    if isinstance(resolution, bool) or not isinstance(resolution, (int, float, np.floating, np.integer)):
        raise SceneError(f"resolution must be a number of degrees (got {resolution!r})")
    r = float(resolution)
    if not (math.isfinite(r) and 0 < r <= 90):
        raise SceneError(f"resolution must be in (0, 90] degrees (got {resolution})")
    nlat = 180.0 / r
    if abs(nlat - round(nlat)) > 1e-9 * nlat:
        raise SceneError(f"resolution must divide 180 degrees (got {resolution})")
    nlat = int(round(nlat))
    return nlat + 1, 2 * nlat


def latlon_grid(resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """Regular node grid (degrees): lat −90, −90+r, …, 90 (both poles) and lon 0, r, …, 360−r.

    Raises ``SceneError`` (a ValueError) unless 0 < r ≤ 90 and 180/r is an integer (to 1e-9)."""
    nlat = latlon_shape(resolution)[1] // 2
    lat = np.linspace(-90.0, 90.0, nlat + 1)
    lon = np.arange(2 * nlat) * (360.0 / (2 * nlat))
    return lat, lon


def latlon_areas(lat: np.ndarray, nlon: int) -> np.ndarray:
    """Areas (nlat, nlon) on the unit sphere of the cells about the points of a regular
    node grid (``latlon_grid``): each point's cell reaches half way to its neighbours,
    the pole rows' cells are caps of half the spacing; they sum to 4π."""
    half = 0.5 * (lat[1] - lat[0])
    top, bottom = np.radians(np.minimum(lat + half, 90.0)), np.radians(np.maximum(lat - half, -90.0))
    band = (np.sin(top) - np.sin(bottom)) * (2 * math.pi / nlon)
    return np.repeat(band[:, None], nlon, axis=1)


def remap_bytes(points: int, np_: int, ntime: int) -> int:
    """Estimated peak bytes of ``remap_dataset`` onto ``points`` lat-lon points: the
    locator's temporaries (~40 floats), the interpolation weights and sparse matrix
    (~6 np² words) and the remapped fields h, hs, u, v, vorticity, divergence, h_surface
    (ntime each, twice: computed and written)."""
    return 8 * points * (40 + 6 * np_ * np_ + 14 * ntime)


def check_remap_memory(ds: xr.Dataset, resolution: float) -> tuple[int, int]:
    """Refuse (``ResourceError``, one line) a remap of the run ``ds`` to ``resolution`` degrees
    that would not fit in memory (``remap_bytes``), before anything is built: from the grid's
    shape (``latlon_shape``) and the file's np (its scene's, else 8, the most). Returns the
    shape. Raises ``SceneError`` for a resolution ``latlon_shape`` refuses."""
    nlat, nlon = latlon_shape(resolution)
    try:
        np_ = int(json.loads(ds.attrs["scene"])["np"])
    except (KeyError, ValueError, TypeError):
        np_ = int(ds.attrs["np"]) if str(ds.attrs.get("np", "")).isdigit() else 8
    fields = ds.sizes.get("time", 1) * (ds.sizes["member"] + 2 if "member" in ds.sizes else 1)  # and mean, spread
    check_memory(
        remap_bytes(nlat * nlon, np_, fields),
        f"remapping to {resolution:g} degrees ({nlat} x {nlon} points)",
    )
    return nlat, nlon


def remap_dataset(ds, resolution: float = 1.0) -> xr.Dataset:
    """A run on a regular lat-lon grid, for maps and lat-lon tools (xarray, CDO).

    Each value is the owning element's GLL polynomial evaluated at the point
    (``Remapper``, as HOMME's ``interpolate_mod``): no smoothing, the model's own
    interpolant.

    Parameters
    ----------
    ds : xarray.Dataset or path
        A run (``swe_sphere.run``'s result, or a run file opened with
        ``xr.open_dataset``), or the path of a run file (read into memory and closed).
    resolution : float
        Grid spacing in degrees; it must divide 180. The grid is
        ``latlon_grid(resolution)``: lat −90..90 with both poles (``180/resolution + 1``
        rows), lon 0..360 − resolution (``360/resolution`` columns), degrees_north /
        degrees_east.

    Returns
    -------
    xarray.Dataset
        The node fields h, hs (m), u, v (m s⁻¹), vorticity, divergence (s⁻¹) on
        (time, lat, lon) ((lat, lon) for hs) with their units and names,
        ``h_surface`` = h + hs (m), the run's diagnostics time series on ``time``
        (model days, exact multiples of the output interval, so ``.sel(time=3)``
        works), ``area`` (lat, lon) (m²: the cells about the points, ``latlon_areas``
        on the run's sphere; the fields' ``cell_measures``) and the run's global
        attributes with a ``remap`` note.

    Raises
    ------
    SceneError
        ``ds`` neither a Dataset nor a path, a missing file, a folder, a file or dataset that is not a swe_sphere run, a
        resolution that is not in (0, 90] or does not divide 180 degrees (a ValueError;
        one line naming it).
    ResourceError
        The grid would not fit in memory.

    Examples
    --------
    >>> swe_sphere.remap_dataset("run.nc").h_surface.sel(time=3).plot()  # doctest: +SKIP
    """
    if not isinstance(ds, xr.Dataset):
        path = path_argument("ds", ds, "an xarray.Dataset or a run file's path", SceneError)
        with open_netcdf(path) as opened:
            return remap_dataset(opened.load(), resolution)  # loaded: the result outlives the file
    check_remap_memory(ds, resolution)
    grid = run_grid(ds)
    lat, lon = latlon_grid(resolution)
    rm = Remapper(grid, np.radians(lat)[:, None], np.radians(lon)[None, :])
    out = _latlon_frame(ds, lat, lon)
    _add_fields(out, ds, rm)
    out.attrs = dict(ds.attrs)
    out.attrs["Conventions"] = "CF-1.8"
    out.attrs["remap"] = (
        f"GLL interpolation (each element's own polynomial) from {grid_name(grid)} "
        f"to a regular {resolution:g} degree lat-lon grid by swe_sphere.io.remap"
    )
    line = history_line(f"swe_sphere.io.remap to {resolution:g} degrees")  # CF: the newest line first
    out.attrs["history"] = f"{line}\n{ds.attrs['history']}" if ds.attrs.get("history") else line
    return out


_MEASURE = {"cell_measures": "area: area"}  # cf_xarray: ds.h.cf.weighted("area") with decode_coords="all"


def _latlon_frame(ds: xr.Dataset, lat: np.ndarray, lon: np.ndarray) -> xr.Dataset:
    """The lat-lon grid's coordinates (degrees), the run's time and the cells' ``area`` (m²)."""
    out = xr.Dataset(
        coords=dict(
            lat=("lat", lat, dict(units="degrees_north", standard_name="latitude", long_name="latitude", axis="Y")),
            lon=("lon", lon, dict(units="degrees_east", standard_name="longitude", long_name="longitude", axis="X")),
        )
    )
    if "time" in ds.variables:
        out = out.assign_coords(time=ds["time"].variable.copy())
    out["area"] = (  # the planet's a² from the run's own spheremp, whatever its radius
        ("lat", "lon"),
        latlon_areas(lat, lon.size) * float(ds["area"].sum()) / (4 * math.pi),
        dict(
            units="m2", long_name="area of the cell about the grid point (caps at the poles)", standard_name="cell_area"
        ),
    )
    return out


def _add_fields(out: xr.Dataset, ds: xr.Dataset, rm: Remapper) -> None:
    """The run's node fields interpolated by ``rm`` onto ``out``'s grid, h + hs as ``h_surface``,
    and its diagnostics time series copied. An ensemble's mean and spread are those of its members
    interpolated (``run_file.member_statistics``), not the nodes' statistics interpolated: a standard
    deviation does not commute with the interpolation (its polynomial dips below zero)."""
    keep = ("units", "long_name", "standard_name", "cell_methods")
    if "member" in ds.variables:  # an ensemble's: its members, and each field's mean and spread
        out.coords["member"] = ds["member"]
    fields = (*NODE_FIELDS, *tracer_names(ds))  # a run's passive tracers' q too
    for name in (*fields, *(f"{n}_{view}" for n in NODE_FIELDS for view in MEMBER_VIEWS)):
        if name not in ds.variables:
            continue
        var = ds[name]
        dims = tuple(d if d != "ncol" else None for d in var.dims)
        if dims[-1] is not None:
            continue
        base, _, view = name.rpartition("_")
        if view in MEMBER_VIEWS and base in out.data_vars and "member" in out[base].dims:
            members = out[base]
            stats = member_statistics(np.moveaxis(members.values, members.dims.index("member"), 0))
            values = stats[MEMBER_VIEWS.index(view)]
        else:
            values = rm(np.asarray(var.values, dtype=np.float64))
        attrs = {k: v for k, v in var.attrs.items() if k in keep}
        out[name] = (var.dims[:-1] + ("lat", "lon"), values, {**attrs, **_MEASURE})
    if "h" in out and "hs" in out:
        out["h_surface"] = out["h"] + out["hs"]
        out["h_surface"].attrs = dict(
            units="m", long_name="free-surface height h + hs", standard_name="height_above_mean_sea_level", **_MEASURE
        )
    for name, var in ds.data_vars.items():
        if var.dims in (("time",), ("time", "member")):
            out[name] = var.copy()


def remap_file(path, resolution: float, output, *, overwrite: bool = False) -> Path:
    """Write ``remap_dataset`` of the run ``path`` to ``output`` (netCDF4), via an
    exclusive ``output.part`` renamed when complete (``output.OutputError`` if
    ``output`` exists and not ``overwrite``). Returns the output path."""
    output = Path(output)
    check_distinct([output], [path])
    out = remap_dataset(path, resolution)
    encoding = {k: {"_FillValue": None} for k in out.coords}  # CF: coordinates hold no missing values
    encoding.update({k: {"_FillValue": np.nan} for k in out.data_vars if out[k].dtype.kind == "f"})
    with atomic_path(output, overwrite=overwrite) as tmp:
        out.to_netcdf(
            tmp, format="NETCDF4", encoding=encoding, unlimited_dims=("time",) if "time" in out.dims else None
        )
    return output
