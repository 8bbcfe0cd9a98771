"""netCDF output of a run (HOMME/EAM native-output style, CF attributes).

Fields on unique nodes ``(time, ncol)`` with ``lat``, ``lon`` (degrees) and
``area`` (m²) on ``ncol``; diagnostics as time series on ``time``. The file is
written under a temporary name beside the target and renamed when closed, so
the target appears complete or not at all; a run that blows up closes it with
every good output time kept.
"""

from __future__ import annotations

import json
import shlex
import sys
import threading
import time
from pathlib import Path

import netCDF4
import numpy as np

from ..core.cache import cache_dir
from ..core.errors import ArgumentError
from ..core.runtime import package_version
from ..grid.cubed_sphere import CubedSphere
from ..mesh.mesh import Mesh, check
from ..mesh.records import MeshFile
from .dual import MESH as DUAL_MESH
from .dual import write_dual_mesh
from .output_files import ExclusiveFile, release_held_locks
from .ugrid import MESH as SUBCELL_MESH
from .ugrid import NOT_A_FIELD, write_mesh

CELLS_NOTE_SECONDS = 1.0  # a cells build below this is less than a run's set-up (Warp's start alone) and goes unsaid
FIELDS = {
    "h": dict(units="m", long_name="fluid depth"),  # CF has no standard name for a shallow-water depth
    "hs": dict(units="m", long_name="surface height", standard_name="surface_altitude"),
    "u": dict(units="m s-1", long_name="eastward wind", standard_name="eastward_wind"),
    "v": dict(units="m s-1", long_name="northward wind", standard_name="northward_wind"),
    "vorticity": dict(
        units="s-1", long_name="relative vorticity", standard_name="atmosphere_upward_relative_vorticity"
    ),
    "divergence": dict(units="s-1", long_name="divergence of the wind", standard_name="divergence_of_wind"),
}
NODE_COORDINATES = {  # lat/lon of the unique nodes: the one latitude and longitude of a run file
    "lat": dict(units="degrees_north", standard_name="latitude", long_name="latitude of the GLL node"),
    "lon": dict(units="degrees_east", standard_name="longitude", long_name="longitude of the GLL node"),
}
AREA_ATTRS = dict(
    units="m2", long_name="area of the node's quadrature cell (assembled spheremp)", standard_name="cell_area"
)
OUTPUT_FIELDS = ("h", "u", "v", "vorticity", "divergence")  # the (time, ncol) fields of a run file, in its order
# On each node field (and hs). ``area`` is a cell measure, not a coordinate: listed in
# ``coordinates`` CDO warns on every command; xarray makes it a coordinate of the fields with
# ``decode_coords="all"``, and then cf_xarray's ``ds.h.cf.weighted("area")`` is the GLL quadrature.
FIELD_ATTRS = {"coordinates": "lat lon", "cell_measures": "area: area"}
# Held while a file is written: a failure reported from another MPI rank
# (``mpi.watch_failures``) closes the run's files between writes, never inside one.
WRITING = threading.RLock()
_OPEN: set = set()  # the RunWriters not yet closed or aborted

# Every node field lives on the faces of the dual mesh (one control volume a node, dual.py):
# tools that average, integrate and remap need cells; the sub-cell mesh (ugrid.py) shares its nodes.
UGRID_FACE = {"mesh": DUAL_MESH, "location": "face"}
# Without the cells (``cells=False``) the fields are on the sub-cell mesh's nodes, and the file says what is missing.
UGRID_NODE = {"mesh": SUBCELL_MESH, "location": "node"}


def no_cells(why: str) -> str:
    """The global attribute ``cells`` of a file written without them, ``why`` in parentheses."""
    return (
        f"not written ({why}): lon and lat have no bounds and there is no mesh_dual, "
        "so conservative remapping (cdo remapcon) and uxarray's cell operations need a run that writes them"
    )


NO_CELLS = no_cells("output.cells = false")
CONVENTIONS = "CF-1.8 UGRID-1.0"
# CF time: model days since the initial state, put at an arbitrary epoch (the model has no
# calendar date); CDO and the CF checker need the reference date and the calendar. xarray
# decodes it to datetimes unless opened with ``decode_times=False`` (as ``swe_sphere.run`` and
# ``remap.open_netcdf`` do), which keeps ``time`` in days: ``.sel(time=3)`` is model day 3.
TIME_ATTRS = dict(
    units="days since 2000-01-01 00:00:00",
    calendar="proleptic_gregorian",
    long_name="model time (day 0: the initial state)",
    standard_name="time",
    axis="T",
)
COURANT_DT = "dt: the scene's; under step control the controller's at that time (the step it goes on with)"


def tracer_names(ds) -> tuple:
    """The passive tracers' names of a run file's Dataset ``ds`` (its scene's [tracers], from the
    global attribute ``scene``): each a (time, ncol) variable of q; () for a run without them."""
    try:
        return tuple(name for name, _ in json.loads(ds.attrs["scene"]).get("tracers", ()))
    except (KeyError, TypeError, ValueError):
        return ()


def tracer_attrs(name: str) -> dict:
    """The CF attributes of passive tracer ``name``'s node field: its mixing ratio q = hq / h."""
    return dict(units="1", long_name=f"mixing ratio of passive tracer {name} (its mass per unit depth, hq / h)")


def series_attrs(name: str) -> dict:
    """The attributes of time series ``name``: ``SERIES_ATTRS``' own, or a tracer's mass
    ``<tracer>_mass`` and its relative change ``<tracer>_mass_change``. KeyError for another."""
    if name in SERIES_ATTRS:
        return SERIES_ATTRS[name]
    if name.endswith("_mass_change"):
        return dict(units="1", long_name=f"relative change of tracer {name[:-12]}'s mass since t = 0")
    if name.endswith("_mass"):
        return dict(units="m3", long_name=f"mass of tracer {name[:-5]} (area integral of h q)")
    raise KeyError(name)


SERIES_ATTRS = {
    "mass": dict(units="m3", long_name="mass (area integral of h)"),
    "total_energy": dict(units="m5 s-2", long_name="total energy"),
    "potential_enstrophy": dict(units="m s-2", long_name="potential enstrophy"),
    "mass_change": dict(units="1", long_name="relative change of mass since t = 0"),
    "total_energy_change": dict(units="1", long_name="relative change of total energy since t = 0"),
    "potential_enstrophy_change": dict(units="1", long_name="relative change of potential enstrophy since t = 0"),
    "rhs_evals": dict(units="1", long_name="cumulative right-hand-side evaluations"),
    "wall_time": dict(units="s", long_name="cumulative wall time of the time loop"),
    "courant_advective": dict(
        units="1", long_name="maximum advective Courant number |v| dt / dx over the nodes", comment=COURANT_DT
    ),
    "courant_gravity": dict(
        units="1", long_name="maximum gravity-wave Courant number sqrt(g h) dt / dx over the nodes", comment=COURANT_DT
    ),
    "helmholtz_iterations": dict(
        units="1", long_name="cumulative Helmholtz-solve iterations (CG iterations or AMG V-cycles)"
    ),
    "precond_iterations": dict(units="1", long_name="cumulative applications of the JFNK preconditioner"),
    "newton_iterations": dict(units="1", long_name="cumulative Newton iterations"),
    "gmres_iterations": dict(units="1", long_name="cumulative GMRES iterations"),
    "krylov_iterations": dict(units="1", long_name="cumulative Krylov vectors of the exponential steppers' KIOPS"),
    "substeps_iterations": dict(units="1", long_name="cumulative accepted KIOPS substeps"),
    "rejected_iterations": dict(units="1", long_name="cumulative rejected KIOPS substeps"),
    "fast_iterations": dict(
        units="1", long_name="cumulative fast (gravity-wave) evaluations of the multirate steppers' substeps"
    ),
    "steps": dict(units="1", long_name="time steps taken"),
    # under step control (``integrator.control``), at each output time
    "dt": dict(units="s", long_name="length of the last accepted time step (the controller's; cut to land here)"),
    "rejected_steps": dict(units="1", long_name="cumulative time steps rejected by the error controller"),
    "error_estimate": dict(
        units="1",
        long_name="weighted RMS norm of the last accepted step's local error estimate over rtol and atol "
        "(<= 1: within tolerance; NaN under CFL control)",
    ),
    "spatial_rate": dict(
        units="s-1",
        long_name="the balanced control's last estimate of the spatial error's relative rate (the tendency's "
        "highest Legendre mode over the state; NaN under other controls)",
    ),
}
for _f in ("h", "wind"):
    for _n, _long in (("l1", "normalized l1"), ("l2", "normalized l2"), ("linf", "normalized l-infinity")):
        SERIES_ATTRS[f"{_n}_{_f}"] = dict(
            units="1", long_name=f"{_long} error of {_f} against the exact solution (Williamson et al. 1992)"
        )
for _f, _what in (("h_surface", "free-surface height h + hs"), ("wind", "wind")):
    for _n, _long in (("l1", "normalized l1"), ("l2", "normalized l2"), ("linf", "normalized l-infinity")):
        SERIES_ATTRS[f"ref_{_n}_{_f}"] = dict(
            units="1",
            long_name=f"{_long} error of the {_what} against the spectral reference (global attribute reference; NaN where it stores no output)",
        )


for _pre, _what in (
    ("", "the exact solution"),
    ("ref_", "the spectral reference (global attribute reference; NaN where it stores no output)"),
):
    for _f, _part in (
        ("vorticity", "relative vorticity (balanced flow)"),
        ("divergence", "divergence (gravity waves)"),
    ):
        SERIES_ATTRS[f"{_pre}l2_{_f}"] = dict(
            units="1",
            long_name=f"l2 of the {_part} of the wind error against {_what}, over that of the true wind's vorticity and divergence",
        )


# an ensemble's run file (``RunWriter(members=N)``): its member coordinate and its spread's time series
MEMBER_ATTRS = dict(standard_name="realization", long_name="ensemble member", units="1")
SERIES_ATTRS["h_spread_rms"] = dict(
    units="m",
    long_name="area-weighted RMS over the sphere of the ensemble spread of h (the members' standard deviation)",
)
STATISTICS = (
    ("mean", "mean", "ensemble mean"),
    ("spread", "standard_deviation", "ensemble spread (standard deviation) of"),
)


def area_rms(grid: CubedSphere, f: np.ndarray) -> float:
    """The area-weighted RMS over the sphere of ``f`` (nunique,) on ``grid``'s unique nodes
    (GLL quadrature: ``grid.area``)."""
    return float(np.sqrt(np.sum(grid.area * f**2) / np.sum(grid.area)))


def member_statistics(fields: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ensemble mean and spread over the first axis of ``fields`` (members, ...): the mean
    and the sample standard deviation (N − 1 in the denominator; 0 for one member), over the
    members with no NaN (a member dropped at a blow-up; NaN where none is left); where every
    member holds the same value, that value and 0."""
    if np.isnan(fields).any():
        fields = fields[~np.isnan(fields.reshape(len(fields), -1)).any(axis=1)]
        if not len(fields):
            return (np.full(fields.shape[1:], np.nan),) * 2
    mean, spread = fields.mean(axis=0), fields.std(axis=0, ddof=1) if len(fields) > 1 else 0.0
    # where every member holds one value, it is their mean and their spread 0 (numpy's sums round
    # N equal values apart: 1000 members alike had an h spread of 3.3e-11 m)
    same = (fields == fields[0]).all(axis=0)
    return np.where(same, fields[0], mean), np.where(same, 0.0, spread)


SERIES_ATTRS["ref_l2_vorticity_eq83"] = dict(
    units="1",
    long_name="normalized l2 error of the relative vorticity (the model's operator) against the spectral "
    "reference's own vorticity at the nodes, Williamson et al. 1992 eq. 83 (global attribute reference; NaN where "
    "it stores no output)",
)


def attribute(value):
    """A global attribute as netCDF stores it: a dict, list or tuple as JSON, an
    integer as a 32-bit NC_INT when it fits (the 64-bit type is netCDF-4 only,
    and tools built on the classic model, such as CDO, read it as text), the rest
    as given."""
    if isinstance(value, (dict, list, tuple)):
        return json.dumps(value)
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and -(2**31) <= value < 2**31:
        return np.int32(value)
    return value


def history_line(what: str) -> str:
    """One line of a file's CF ``history`` attribute: the UTC time, ``what`` made the
    file, and the package version (CF: the newest line first, one line an operation)."""
    return f"{time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())}: {what} (swe_sphere {package_version()})"


def command_line(default: str) -> str:
    """What made a file, for its ``history``: the command line when this process is the
    ``swe-sphere`` console script (as a run file records it), else ``default`` (a Python
    call, whose ``sys.argv`` is not the command's)."""
    if Path(sys.argv[0]).name != "swe-sphere":
        return default
    return shlex.join(["swe-sphere", *sys.argv[1:]])


class RunWriter:
    """Writes one run to ``path`` (netCDF4), via an exclusive ``path.part`` until
    ``close`` (see ``ExclusiveFile``; ``OutputError`` if the path may not be written).

    ``attrs``: global attributes (strings or numbers; see ``attribute``).
    ``series``: names of the diagnostics time series (see ``SERIES_ATTRS``).
    ``time`` is model time in days as CF time (``TIME_ATTRS``; read with
    ``decode_times=False``, ``ds.h.sel(time=3)`` is day 3; ``Scene.day`` makes it exact). ``compress``: the (time, ncol)
    fields as float32 with zlib (about 3× smaller; not for bitwise comparisons).
    ``fields``: the node fields it holds (of ``OUTPUT_FIELDS``; default all).
    ``cells``: write the control volumes (``dual.write_dual_mesh``: the UGRID mesh the
    fields are on, and ``lon_bnds``/``lat_bnds``); without them the fields are on the
    sub-cell mesh's nodes and the global attribute ``cells`` says what is missing.
    ``cells_seconds``: the CPU seconds spent building the cells, None where they came
    from the cache or were not written. ``cells_failure``: where their fit failed
    (``dual.dual_mesh``'s ``ArithmeticError``), its message, and the file is written without
    them, its ``cells`` attribute saying so; else None.
    ``members``: an ensemble's file (``swe_sphere.ensemble``): the dimension and coordinate
    ``member`` (CF ``realization``), each field (time, member, ncol) beside its ensemble mean
    and spread ``<field>_mean``, ``<field>_spread`` (time, ncol; CF ``cell_methods``
    "realization: mean" and "realization: standard_deviation", ``member_statistics``), the time
    series ``member_series`` (time, member) and ``h_spread_rms`` (time) besides ``series``.
    """

    def __init__(
        self,
        path,
        grid: CubedSphere,
        hs: np.ndarray,
        attrs: dict,
        series,
        *,
        overwrite: bool = False,
        compress: bool = False,
        fields=OUTPUT_FIELDS,
        cells: bool = True,
        members: int | None = None,
        member_series=(),
        tracers=(),
    ):
        self.path, self.fields, self.cells = Path(path), tuple(fields), cells
        self.tracers = tuple(tracers)
        self.members, self.member_series = members, tuple(member_series)
        self.cells_seconds = None  # CPU seconds spent building the cells, where they were not in the cache
        self.cells_failure = None  # why the cells' fit failed, where it did (the file is written without them)
        self.file = ExclusiveFile(self.path, overwrite=overwrite)
        self.tmp = self.file.tmp
        self.grid = grid
        try:
            with WRITING:
                self._create(attrs, hs, series, compress)
        except BaseException:
            self.abort()
            raise
        _OPEN.add(self)

    def cells_notes(self, grid_text: str) -> list[str]:
        """The lines to tell a user about this file's cells (``grid_text`` names the grid): that
        their fit failed and the file is written without them; or that building them took
        ``CELLS_NOTE_SECONDS`` of CPU or more (a build can cost more than a short run), once per
        grid; else none."""
        what = f"the run file's cells (GLL control volumes, {grid_text})"
        if self.cells_failure is not None:
            return [
                f"{what} could not be fitted ({self.cells_failure}): the file is written without them, "
                "as with output.cells = false"
            ]
        if self.cells_seconds is not None and self.cells_seconds >= CELLS_NOTE_SECONDS:
            return [
                f"{what} took {self.cells_seconds:.1f} s of CPU to build, once per grid: later runs read them "
                f"from {cache_dir()}; output.cells = false (--no-cells) leaves them out"
            ]
        return []

    def _create(self, attrs, hs, series, compress):
        grid = self.grid
        ds = self.ds = netCDF4.Dataset(self.tmp, "w", format="NETCDF4")
        ds.Conventions = CONVENTIONS
        for k, v in attrs.items():
            setattr(ds, k, attribute(v))
        ds.createDimension("time", None)
        ds.createDimension("ncol", grid.nunique)
        t = ds.createVariable("time", "f8", ("time",))
        t.setncatts(TIME_ATTRS)
        for name, deg in (("lat", np.degrees(grid.lat)), ("lon", np.degrees(grid.lon))):
            ds.createVariable(name, "f8", ("ncol",)).setncatts(NODE_COORDINATES[name])
            ds[name][:] = grid.to_unique(deg)
        ds.createVariable("area", "f8", ("ncol",)).setncatts(AREA_ATTRS)
        ds["area"][:] = grid.area
        if self.cells:  # first: uxarray opens the first mesh_topology, the one the fields are on
            try:
                self.cells_seconds = write_dual_mesh(ds, grid)
            except ArithmeticError as err:  # their fit failed, before it wrote anything: the run goes on without them
                self.cells, self.cells_failure = False, str(err)
        if not self.cells:
            ds.cells = NO_CELLS if self.cells_failure is None else no_cells(f"their fit failed: {self.cells_failure}")
        located = UGRID_FACE if self.cells else UGRID_NODE
        hsv = ds.createVariable("hs", "f8", ("ncol",))
        hsv.setncatts({**FIELDS["hs"], **FIELD_ATTRS, **located})
        hsv[:] = grid.to_unique(hs)
        write_mesh(ds, grid)
        if grid.mesh is not None:
            write_element_mesh(ds, grid.mesh)
        lead = ("time",)
        if self.members is not None:
            ds.createDimension("member", self.members)
            ds.createVariable("member", "i4", ("member",)).setncatts(MEMBER_ATTRS)
            ds["member"][:] = np.arange(self.members)
            lead = ("time", "member")
        dtype = "f4" if compress else "f8"
        for name in self.fields:
            fill = dict(fill_value=np.nan) if name in ("vorticity", "divergence") else {}  # NaN where a writer got none
            var = ds.createVariable(name, dtype, (*lead, "ncol"), zlib=compress, **fill)
            var.setncatts({**FIELDS[name], **FIELD_ATTRS, **located})
            for stat, method, what in STATISTICS if self.members is not None else ():
                var = ds.createVariable(f"{name}_{stat}", dtype, ("time", "ncol"), zlib=compress, **fill)
                long_name = f"{what} {FIELDS[name]['long_name']}"
                var.setncatts({**FIELDS[name], **FIELD_ATTRS, **located, "long_name": long_name})
                var.cell_methods = f"realization: {method}"
        for name in self.tracers:  # q, each tracer's mixing ratio
            var = ds.createVariable(name, dtype, (*lead, "ncol"), zlib=compress)
            var.setncatts({**tracer_attrs(name), **FIELD_ATTRS, **located})
        for name in (*series, *(("h_spread_rms",) if self.members is not None and "h" in self.fields else ())):
            ds.createVariable(name, "f8", ("time",)).setncatts(series_attrs(name))
        for name in self.member_series:
            ds.createVariable(name, "f8", ("time", "member")).setncatts(series_attrs(name))
        self.n = 0

    def append(self, day: float, u, v, h, series: dict, vorticity=None, divergence=None, masses=None) -> None:
        """Add one output time (model days since the start); fields element-local (N,), an
        ensemble's (members, N) with ``series`` holding its ``member_series`` as (members,)
        arrays; ``vorticity`` and ``divergence`` (s⁻¹, DSS'd, element-local) are optional (NaN
        in the file without them); ``masses`` (K, N) the tracers' hq (m), written as q = hq / h."""
        with WRITING:
            self._append(day, u, v, h, series, vorticity, divergence, masses)

    def _append(self, day, u, v, h, series, vorticity, divergence, masses) -> None:
        ds, n, g = self.ds, self.n, self.grid
        ds["time"][n] = day
        for name, hq in zip(self.tracers, () if masses is None else masses, strict=True):
            ds[name][n, :] = g.to_unique(hq / h)
        for name, f in (("u", u), ("v", v), ("h", h), ("vorticity", vorticity), ("divergence", divergence)):
            if f is None or name not in self.fields:
                continue
            if self.members is None:
                ds[name][n, :] = g.to_unique(f)
                continue
            each = np.stack([g.to_unique(a) for a in f])
            ds[name][n, :, :] = each
            mean, spread = member_statistics(each)
            ds[f"{name}_mean"][n, :], ds[f"{name}_spread"][n, :] = mean, spread
            if name == "h":
                ds["h_spread_rms"][n] = area_rms(g, spread)
        for k, val in series.items():
            ds[k][n] = val
        ds.sync()
        self.n += 1

    def set_attrs(self, **attrs) -> None:
        with WRITING:
            for k, v in attrs.items():
                setattr(self.ds, k, attribute(v))

    def close(self) -> None:
        """Finish the file and move it to its final name."""
        with WRITING:
            _OPEN.discard(self)
            self.ds.close()
            self.file.commit()

    def abort(self) -> None:
        """Drop the partial file."""
        with WRITING:
            _OPEN.discard(self)
            try:
                if getattr(self, "ds", None) is not None and self.ds.isopen():
                    self.ds.close()
            finally:
                self.file.discard()


ELEMENT_NODES, ELEMENT_CORNERS = "element_mesh_node_xyz", "element_mesh_corners"


def write_element_mesh(ds, mesh: Mesh) -> None:
    """The elements' mesh (its nodes and corners, a few kB) into the run file ``ds``, so that
    ``remap`` and ``plot`` rebuild the grid where the mesh file is not (``element_mesh``)."""
    ds.createDimension("element_mesh_node", mesh.nnodes)
    ds.createDimension("element_mesh_elem", mesh.nelem)
    ds.createDimension("xyz", 3)
    ds.createDimension("corner", 4)
    xyz = ds.createVariable(ELEMENT_NODES, "f8", ("element_mesh_node", "xyz"))
    xyz.setncatts(dict(long_name=f"nodes of the elements' mesh {mesh.name} (unit vectors)", units="1", **NOT_A_FIELD))
    xyz[:] = mesh.coords
    corners = ds.createVariable(ELEMENT_CORNERS, "i4", ("element_mesh_elem", "corner"))
    corners.setncatts(
        dict(
            long_name="each element's corner nodes (0-based rows of element_mesh_node_xyz), counter-clockwise",
            units="1",
            **NOT_A_FIELD,
        )
    )
    corners[:] = mesh.quads


def element_mesh(ds, record: MeshFile) -> Mesh:
    """The elements' ``Mesh`` a run file carries (``write_element_mesh``; an ``xarray`` or
    netCDF4 dataset), named and mapped as the run's mesh file ``record`` (``mesh.records.MeshFile``).
    Raises ``KeyError`` where the file carries none (written before it did)."""
    return check(
        Mesh(
            np.asarray(ds[ELEMENT_NODES][:], dtype=np.float64),
            np.asarray(ds[ELEMENT_CORNERS][:], dtype=np.int64),
            Path(record.path).name,
            record.map,
        )
    )


def node_dataset(grid: CubedSphere, hs: np.ndarray, day: float, fields: dict, attrs: dict):
    """One output time as an ``xarray.Dataset`` laid out as a run file's (``RunWriter``):
    the element-local ``fields`` (n,), or (members, n) (name → array, of ``OUTPUT_FIELDS``) and ``hs``
    on the unique nodes ``ncol`` (``member``, ``ncol``) with their ``FIELDS`` attributes, ``lat``/``lon``
    (degrees) coordinates, ``area`` (m²), a scalar ``time`` (days, ``TIME_ATTRS``) and ``attrs``."""
    import xarray as xr

    dims = {name: ("member", "ncol")[2 - np.ndim(f) :] for name, f in fields.items()}
    ds = xr.Dataset(
        {name: (dims[name], grid.to_unique(f), {**FIELDS[name], **FIELD_ATTRS}) for name, f in fields.items()},
        coords=dict(
            lat=("ncol", grid.to_unique(np.degrees(grid.lat)), NODE_COORDINATES["lat"]),
            lon=("ncol", grid.to_unique(np.degrees(grid.lon)), NODE_COORDINATES["lon"]),
            time=((), day, TIME_ATTRS),
        ),
        attrs={k: attribute(v) for k, v in attrs.items()},
    )
    ds["hs"] = ("ncol", grid.to_unique(hs), {**FIELDS["hs"], **FIELD_ATTRS})
    ds["area"] = ("ncol", grid.area, AREA_ATTRS)
    return ds


def close_open_runs(failed: str) -> None:
    """Close every open run file with the output times it holds and a global
    attribute ``failed`` (the reason), once no file is being written, and keep
    ``WRITING`` so that nothing is written after, and release the locks taken ahead of a
    writer: the caller ends the process (``mpi.watch_failures`` on rank 0 when another rank
    failed)."""
    WRITING.acquire()
    for writer in list(_OPEN):
        writer.set_attrs(failed=failed)
        writer.close()
    release_held_locks()  # a lock taken ahead (``HeldLock``) for a run that never wrote


def member_states(path, day: float | None, members: int, nunique: int, where: str, tracers=()) -> tuple:
    """(states, q): states (members, 3, nunique) float64, u, v (m s⁻¹) and h (m) of every member
    of the ensemble's run file ``path`` (``RunWriter`` with ``members``) at model day ``day``
    (None: the file's last time) on the unique nodes, as written; q {name: (members, nunique)
    float64} the mixing ratio (1) of each of ``tracers`` (names) the file holds on (time, member,
    ncol) there. ``ArgumentError`` beginning ``where`` for a file that cannot be read, is not an
    ensemble's run file (no h on time, member, ncol), holds another member count or another grid's
    ``nunique`` nodes, or not ``day``."""
    try:
        ds = netCDF4.Dataset(path)
    except (OSError, TypeError) as err:
        raise ArgumentError(f"{where}: not a readable netCDF file ({err})") from None
    with ds:
        if "h" not in ds.variables or ds["h"].dimensions != ("time", "member", "ncol"):
            raise ArgumentError(f"{where}: not an ensemble's run file (no h on time, member, ncol)")
        held, ncol = ds.dimensions["member"].size, ds.dimensions["ncol"].size
        if held != members:
            raise ArgumentError(f"{where}: the file holds {held} members, the ensemble {members}")
        if ncol != nunique:
            raise ArgumentError(f"{where}: the file's grid has {ncol} unique nodes, the scene's {nunique}")
        days = np.asarray(ds["time"][:], dtype=np.float64)
        last = np.arange(days.size)[-1:]  # none in a file without output times
        at = last if day is None else np.flatnonzero(np.isclose(days, day, rtol=0, atol=1e-9))
        if at.size == 0:
            raise ArgumentError(f"{where}: no output at day {day} (it holds {', '.join(f'{d:g}' for d in days)})")
        states = np.stack([np.asarray(ds[name][at[0]], dtype=np.float64) for name in "uvh"], axis=1)
        held = [name for name in tracers if name in ds.variables and ds[name].dimensions == ds["h"].dimensions]
        return states, {name: np.asarray(ds[name][at[0]], dtype=np.float64) for name in held}
