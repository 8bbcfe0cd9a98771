"""netCDF output of a run (HOMME/EAM native-output style, CF attributes).

Fields on unique nodes ``(time, ncol)`` with ``lat``, ``lon`` (degrees) and
``area`` (m²) on ``ncol``; diagnostics as time series on ``time``. The file is
written under a temporary name beside the target and renamed when closed, so
the target appears complete or not at all; a run that blows up closes it with
every good output time kept.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shlex
import sys
import threading
import time
from pathlib import Path

import netCDF4
import numpy as np

from ..core.errors import OutputError
from ..core.runtime import package_version
from ..grid.cubed_sphere import CubedSphere
from ..mesh.mesh import Mesh, check
from ..mesh.records import MeshFile
from .dual import MESH as DUAL_MESH
from .dual import write_dual_mesh
from .ugrid import MESH as SUBCELL_MESH
from .ugrid import write_mesh

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
NO_CELLS = (
    "not written (output.cells = false): lon and lat have no bounds and there is no mesh_dual, "
    "so conservative remapping (cdo remapcon) and uxarray's cell operations need a run that writes them"
)
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

SERIES_ATTRS = {
    "mass": dict(units="m3", long_name="mass (area integral of h)"),
    "total_energy": dict(units="m5 s-2", long_name="total energy"),
    "potential_enstrophy": dict(units="m s-2", long_name="potential enstrophy"),
    "mass_change": dict(units="1", long_name="relative change of mass since t = 0"),
    "total_energy_change": dict(units="1", long_name="relative change of total energy since t = 0"),
    "potential_enstrophy_change": dict(units="1", long_name="relative change of potential enstrophy since t = 0"),
    "rhs_evals": dict(units="1", long_name="cumulative right-hand-side evaluations"),
    "wall_time": dict(units="s", long_name="cumulative wall time of the time loop"),
    "courant_advective": dict(units="1", long_name="maximum advective Courant number |v| dt / dx over the nodes"),
    "courant_gravity": dict(
        units="1", long_name="maximum gravity-wave Courant number sqrt(g h) dt / dx over the nodes"
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
    # under step control (``simulation.adaptive``), at each output time
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


def check_target(path: Path, overwrite: bool = False) -> None:
    """Raise ``OutputError`` (one line) unless ``path`` may be written: its folder
    exists and is writable, and it does not exist (or ``overwrite`` and it is a
    writable regular file). A symbolic link or a non-regular file (directory,
    FIFO, device) is never written, with or without ``overwrite``."""
    path = Path(path)
    parent = path.absolute().parent
    if path.is_symlink():
        raise OutputError(f"output path is a symbolic link (not written through): {path}")
    if path.exists():
        if path.is_dir():
            raise OutputError(f"output path is a directory: {path}")
        if not path.is_file():
            raise OutputError(f"output path is not a regular file: {path}")
        if not overwrite:
            raise OutputError(f"output file exists: {path} (--overwrite, or overwrite=True in Python, replaces it)")
        if not os.access(path, os.W_OK):
            raise OutputError(f"output file is read-only: {path}")
    if parent.exists() and not parent.is_dir():
        raise OutputError(f"output path's parent is not a directory: {parent}")
    if not parent.is_dir():
        raise OutputError(f"output directory does not exist: {parent}")
    if not os.access(parent, os.W_OK):
        raise OutputError(f"output directory is not writable: {parent}")


def _identity(path: Path):
    """(device, inode) of the file ``path`` names after resolving links; None if there is none."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def check_distinct(outputs, inputs) -> None:
    """Raise ``OutputError`` (one line) if an output would replace an input.

    Each output path and its ``.part`` and ``.lock`` siblings (``ExclusiveFile``
    writes and removes them) are compared with every input by device and inode
    after resolving links, so another spelling, a link or a hard link of the
    input is caught as well as the same name. ``None`` entries are skipped."""
    known = {}
    for inp in inputs:
        if inp is not None and (ident := _identity(Path(inp))) is not None:
            known[ident] = inp
    for out in outputs:
        if out is None:
            continue
        out = Path(out)
        for path in (out, out.with_name(out.name + ".part"), out.with_name(out.name + ".lock")):
            inp = known.get(_identity(path))
            if inp is not None:
                raise OutputError(
                    f"the output {path} is the input {inp}; writing it would replace the input (choose another output)"
                )


def acquire_lock(lock: Path, what) -> int:
    """An exclusive ``flock`` on the file ``lock`` (created, never through a link):
    its descriptor, or ``OutputError`` naming ``what`` when another process holds it.
    The holder removes ``lock`` before closing the descriptor (``release_lock``)."""
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
        except OSError as err:
            raise OutputError(f"cannot create {lock}: {err.strerror}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise OutputError(f"another run is writing {what} (it holds {lock})") from None
        try:  # the previous holder may have removed the file between our open and lock
            if os.stat(lock, follow_symlinks=False).st_ino == os.fstat(fd).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)


def release_lock(lock: Path, fd: int) -> None:
    """Undo ``acquire_lock``: remove the file first, so a waiting process retries on a new one."""
    lock.unlink(missing_ok=True)
    os.close(fd)


@contextlib.contextmanager
def folder_lock(folder: Path, name: str):
    """Create ``folder`` (with its parents) and hold ``folder/name`` locked while the
    block runs, so a second command on the same folder is refused at its start
    (``OutputError``) instead of computing everything and failing at the end."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create output directory {folder}: {err.strerror}") from None
    lock = folder / name
    fd = acquire_lock(lock, folder)
    try:
        yield folder
    finally:
        release_lock(lock, fd)


_HELD: dict[str, int] = {}  # lock file (absolute) → descriptor: held ahead by ``HeldLock``, not yet taken by a writer


class HeldLock:
    """``with HeldLock(path):`` the writer's lock of ``path`` (``path.lock``) taken now, when
    the object is made, so that a command refuses at its start (``OutputError``, one line,
    when another process writes ``path``) rather than after its set-up and header; the next
    ``ExclusiveFile`` of ``path`` in this process takes it over and releases it when done.
    A lock no writer took over is released at the block's end."""

    def __init__(self, path):
        path = Path(path)
        self.lock = path.with_name(path.name + ".lock")
        self.key = os.path.abspath(self.lock)
        self.fd = acquire_lock(self.lock, path)
        _HELD[self.key] = self.fd

    def __enter__(self) -> HeldLock:
        return self

    def __exit__(self, *exc) -> None:
        if _HELD.get(self.key) == self.fd:
            del _HELD[self.key]
            release_lock(self.lock, self.fd)


class ExclusiveFile:
    """Write ``path`` through ``path.part``, so two processes never write the
    same file and a file is never written through a link: the writer holds an
    exclusive ``flock`` on ``path.lock`` (removed when done; taken over from a
    ``HeldLock`` of this process where there is one) and creates the
    part with O_EXCL | O_NOFOLLOW. A second writer gets ``OutputError``; a
    ``.part`` left by a killed run (its lock is free) is replaced with
    ``overwrite``, else refused. ``commit`` moves the finished part onto
    ``path`` (without ``overwrite``, only if ``path`` still does not exist);
    ``discard`` drops it. As a context manager it yields the part's path and
    commits on success.

    (The lock is a file of its own: HDF5 locks the file it writes itself, and a
    POSIX lock on it would be released when the netCDF library closes it.)
    """

    def __init__(self, path, *, overwrite: bool = False):
        self.path, self.overwrite = Path(path), overwrite
        self.tmp = self.path.with_name(self.path.name + ".part")
        self.lock = self.path.with_name(self.path.name + ".lock")
        check_target(self.path, overwrite)
        self.lock_fd = self._acquire()
        try:
            try:
                self._create()
            except FileExistsError:  # we hold the lock: whoever wrote it is gone
                if not overwrite:
                    raise OutputError(
                        f"{self.tmp} was left by a run that was killed (--overwrite, or overwrite=True in Python, replaces it)"
                    ) from None
                self.tmp.unlink()
                self._create()
        except BaseException:
            self._release()
            raise

    def _acquire(self) -> int:
        held = _HELD.pop(os.path.abspath(self.lock), None)  # taken ahead by the command (``HeldLock``)
        return acquire_lock(self.lock, self.path) if held is None else held

    def _create(self) -> None:
        try:
            os.close(os.open(self.tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o644))
        except FileExistsError:
            raise
        except OSError as err:
            raise OutputError(f"cannot create {self.tmp}: {err.strerror}") from None

    def _release(self) -> None:
        if self.lock_fd is not None:
            release_lock(self.lock, self.lock_fd)
            self.lock_fd = None

    def commit(self) -> None:
        try:
            check_target(self.path, self.overwrite)
            if self.overwrite:
                os.replace(self.tmp, self.path)
                return
            try:
                os.link(self.tmp, self.path)  # fails if the target appeared meanwhile
            except FileExistsError:
                raise OutputError(
                    f"{self.path} appeared while it was written; the result is kept in {self.tmp}"
                ) from None
            except OSError:  # a file system without hard links: check, then rename
                check_target(self.path, False)
                os.rename(self.tmp, self.path)
                return
            os.unlink(self.tmp)
        finally:
            self._release()

    def discard(self) -> None:
        self.tmp.unlink(missing_ok=True)
        self._release()

    def __enter__(self) -> Path:
        return self.tmp

    def __exit__(self, kind, value, tb):
        if kind is None:
            self.commit()
        else:
            self.discard()


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
    from the cache or were not written.
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
    ):
        self.path, self.fields, self.cells = Path(path), tuple(fields), cells
        self.cells_seconds = None  # CPU seconds spent building the cells, where they were not in the cache
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
        located = UGRID_FACE if self.cells else UGRID_NODE
        hsv = ds.createVariable("hs", "f8", ("ncol",))
        hsv.setncatts({**FIELDS["hs"], **FIELD_ATTRS, **located})
        hsv[:] = grid.to_unique(hs)
        if self.cells:  # first: uxarray opens the first mesh_topology, the one the fields are on
            self.cells_seconds = write_dual_mesh(ds, grid)
        else:
            ds.cells = NO_CELLS
        write_mesh(ds, grid)
        if grid.mesh is not None:
            write_element_mesh(ds, grid.mesh)
        for name in self.fields:
            fill = dict(fill_value=np.nan) if name in ("vorticity", "divergence") else {}  # NaN where a writer got none
            var = ds.createVariable(name, "f4" if compress else "f8", ("time", "ncol"), zlib=compress, **fill)
            var.setncatts({**FIELDS[name], **FIELD_ATTRS, **located})
        for name in series:
            var = ds.createVariable(name, "f8", ("time",))
            var.setncatts(SERIES_ATTRS[name])
        self.n = 0

    def append(self, day: float, u, v, h, series: dict, vorticity=None, divergence=None) -> None:
        """Add one output time (model days since the start); fields element-local (N,); ``vorticity``
        and ``divergence`` (s⁻¹, DSS'd, element-local) are optional (NaN in the file without them)."""
        with WRITING:
            self._append(day, u, v, h, series, vorticity, divergence)

    def _append(self, day, u, v, h, series, vorticity, divergence) -> None:
        ds, n, g = self.ds, self.n, self.grid
        ds["time"][n] = day
        for name, f in (("u", u), ("v", v), ("h", h), ("vorticity", vorticity), ("divergence", divergence)):
            if f is not None and name in self.fields:
                ds[name][n, :] = g.to_unique(f)
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
    xyz.setncatts(dict(long_name=f"nodes of the elements' mesh {mesh.name} (unit vectors)", units="1"))
    xyz[:] = mesh.coords
    corners = ds.createVariable(ELEMENT_CORNERS, "i4", ("element_mesh_elem", "corner"))
    corners.setncatts(
        dict(
            long_name="each element's corner nodes (0-based rows of element_mesh_node_xyz), counter-clockwise",
            units="1",
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
    the element-local ``fields`` (N,) (name → array, of ``OUTPUT_FIELDS``) and ``hs``
    on the unique nodes ``ncol`` with their ``FIELDS`` attributes, ``lat``/``lon``
    (degrees) coordinates, ``area`` (m²), a scalar ``time`` (days, ``TIME_ATTRS``) and ``attrs``."""
    import xarray as xr

    ds = xr.Dataset(
        {name: ("ncol", grid.to_unique(f), {**FIELDS[name], **FIELD_ATTRS}) for name, f in fields.items()},
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
    for key, fd in list(_HELD.items()):  # a lock taken ahead (``HeldLock``) for a run that never wrote
        del _HELD[key]
        release_lock(Path(key), fd)


def check_results(directory: Path, names, overwrite: bool = False) -> None:
    """``check_target`` for each of a command's result files ``names`` under
    ``directory`` (a folder still to be made holds none), so a study is refused
    before it runs rather than replacing an earlier one's results at its end."""
    directory = Path(directory)
    if directory.is_dir():
        for name in names:
            check_target(directory / name, overwrite)


def atomic_path(path: Path, *, overwrite: bool = True) -> ExclusiveFile:
    """``with atomic_path(p) as tmp:`` write tmp; it is moved onto ``p`` if the block succeeds."""
    return ExclusiveFile(path, overwrite=overwrite)
