"""The restart file's layout: written, read back and checked (``checkpoint`` makes
a run of what it holds).

A restart file is a netCDF4 file (CF-1.8 attributes) holding the element-local
state ``x`` (3, N) as the variables ``u``, ``v`` (m s⁻¹) and ``h`` (m) on
``node`` (every element's copy of its GLL nodes; their ``lat``, ``lon`` and
``area``, the unassembled spheremp, beside them for tools), the stepper's ``state()``
(arrays (3, N) as variables ``stepper_<key>`` on (``row``, ``node``), scalars as
attributes ``stepper_<key>``), the run's counters
(step, RHS evaluations, solver iterations, wall time), the invariants at t = 0
(so relative changes keep their origin), the resolved scene (JSON; its precision also as the
attribute ``precision``, "float64" or "float32": the tendency's, which a continuation keeps), under step control
the control's state (``StepControl.state()``: the next Δt, the controller's history, the
counts and the time reached; JSON, attribute ``step_control``), an ensemble's member count
(attribute ``ensemble_members``: its state is every member's, side by side), the package version
and, for a start from a reanalysis file, its analysed state (``ANALYSED``: what a continuation
rebuilds the case from, so the restart file stands alone when the input file is moved or gone).

Every variable is written with netCDF's per-variable Fletcher-32 checksum, and
the attribute ``content_sha256`` holds a SHA-256 of the state, the stepper's
history and the step (``content_hash``), so a damaged file is refused instead of
continued.

``read`` raises ``CheckpointError`` (a ValueError, one line) for a file that is
not a restart file, was written by another swe_sphere version, or is damaged: a
failed checksum or hash, a non-finite value, a depth h <= 0, or a wind beyond
``MAX_FROUDE`` times the gravity-wave speed of the deepest node (no shallow-water
flow the model runs comes near it), each naming the variable.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import netCDF4
import numpy as np

from ..core.constants import Planet
from ..core.errors import CheckpointError
from ..core.runtime import package_version
from ..grid.cubed_sphere import CubedSphere
from .output_files import ExclusiveFile
from .run_file import AREA_ATTRS, FIELD_ATTRS, FIELDS, NODE_COORDINATES, WRITING, history_line

FORMAT = 3  # bump when the layout changes (2: checksums and content hash; 3: the state as named fields)
STATE = ("u", "v", "h")  # the rows of x, each a variable with output.FIELDS' attributes


def mass_names(scene: dict) -> list[str]:
    """The variables of the tracers' masses hq, x's rows after ``STATE``: ``<name>_mass`` for each
    of the stored scene's (``Scene.as_dict``) [tracers], in order."""
    return [f"{name}_mass" for name, _ in scene.get("tracers", ())]


ANALYSED = ("h_surface", "vorticity", "divergence", "hs")  # ``reanalysis.Analysed``'s coefficients
"""A reanalysis start's state: the complex coefficients (nalm,) of ``reanalysis.Analysed`` (h + hs,
vorticity, divergence and hs; m, s⁻¹, s⁻¹, m; ducc0's order) as variables ``analysed_<name>`` on
(``part``: real, imaginary; ``alm``), hs absent when the start has none; its ``lmax``, sphere radius
``a`` (m) and words of what was read as the attributes ``analysed_lmax``, ``analysed_a``, ``analysed_read``.
A file without them (a case that reads no file, or one written before they were kept) continues
from its scene's case as it always did: the format is 3 either way."""

MAX_FROUDE = 2.0  # |v| / sqrt(g max h) beyond which a stored wind is not a state the model made


def content_hash(step: int, x: np.ndarray, stepper_state: dict, departure: np.ndarray | None = None) -> str:
    """SHA-256 (hex) of the step, the state ``x``, a float32 state's ``departure`` (its float32
    bytes; None: none) and the stepper's history (arrays as float64 bytes, scalars by repr, in
    key order)."""
    h = hashlib.sha256(str(int(step)).encode())
    h.update(np.ascontiguousarray(x, dtype=np.float64).tobytes())
    if departure is not None:
        h.update(np.ascontiguousarray(departure, dtype=np.float32).tobytes())
    for key in sorted(stepper_state):
        value = stepper_state[key]
        h.update(key.encode())
        h.update(
            np.ascontiguousarray(value, dtype=np.float64).tobytes()
            if isinstance(value, np.ndarray)
            else repr(value).encode()
        )
    return h.hexdigest()


def _check_state(path, planet: dict | None, x: np.ndarray, stepper_state: dict) -> None:
    """Refuse (``CheckpointError`` naming the variable) non-finite values, h <= 0 and
    implausible winds; ``planet``: the scene's [planet] table (its gravity)."""
    for name, value in (
        *zip(STATE, x),
        *((f"stepper_{k}", v) for k, v in stepper_state.items() if isinstance(v, np.ndarray)),
    ):
        bad = np.flatnonzero(~np.isfinite(value))
        if bad.size:
            raise CheckpointError(f"{path}: variable {name} holds {bad.size} non-finite values; not continued")
    h = x[2]
    if h.min() <= 0:
        raise CheckpointError(f"{path}: variable h holds a depth h = {h.min():.4g} m <= 0; not continued")
    g = Planet.from_table(planet).g  # not the case: a file case would read its file
    bound = MAX_FROUDE * np.sqrt(g * h.max())
    speed = np.hypot(x[0], x[1]).max()
    if speed > bound:
        raise CheckpointError(
            f"{path}: variables u, v hold a wind of {speed:.4g} m/s, beyond {bound:.4g} m/s "
            f"({MAX_FROUDE:g} x the gravity-wave speed of the deepest node); not continued"
        )


def write(
    path,
    scene,
    step: int,
    x: np.ndarray,
    stepper_state: dict,
    counters: dict,
    initial: dict,
    *,
    grid: CubedSphere,
    overwrite: bool = True,
    restart_every: float | None = None,
    control: dict | None = None,
    members: int | None = None,
    analysed=None,
    departure: np.ndarray | None = None,
) -> Path:
    """Write a restart file to ``path`` atomically (via ``output.ExclusiveFile``).

    ``scene``: the run's ``config.Scene``; ``x``: (3 + K, N) element-local state (u, v
    in m s⁻¹, h in m, the K tracers' masses hq in m as ``<name>_mass``) at ``step`` (model time step·dt); ``stepper_state``:
    ``Stepper.state()`` (arrays (3, N), scalars); ``counters``: {"rhs_evals",
    "wall_time" (s), "iterations": {solver: n}}; ``initial``: the diagnostics at
    t = 0; ``grid``: the run's grid, whose element-local ``lat``/``lon`` (degrees) and
    ``spheremp`` (m², the variable ``area``) go beside the state as its CF coordinates
    and cell measure (for tools; ``read`` does not need them); ``restart_every``: the
    run's restart interval (days; None: none), which a continuation keeps; ``control``: under
    step control ``StepControl.state()`` (its ``day`` the time written); ``members``: an
    ensemble's (``swe_sphere.ensemble``; x and ``grid`` its members' copies side by side); ``analysed``:
    a reanalysis start's ``reanalysis.Analysed`` (``ANALYSED``; None: the case reads no file);
    ``departure``: (N,) a run's kept float32 state's h − H₀ as it held it (``model.held``), the
    variable ``h_departure`` (float32) a continuation takes its bits from (h = f64(y) + H₀ does
    not round back to y where |y| < 2⁻²⁹ H₀); None: none. Raises
    ``output.OutputError`` when ``path`` exists and not ``overwrite`` (or is a link /
    being written)."""
    path = Path(path)
    with WRITING, ExclusiveFile(path, overwrite=overwrite) as tmp:  # WRITING: see mpi.watch_failures
        with netCDF4.Dataset(tmp, "w", format="NETCDF4") as ds:
            ds.Conventions = "CF-1.8"
            ds.title = f"swe_sphere restart file of scene {scene.name}"
            ds.history = history_line(f"swe_sphere restart at step {int(step)}")
            ds.swe_sphere_checkpoint = np.int32(FORMAT)
            ds.swe_sphere_version = package_version()
            ds.scene = json.dumps(scene.as_dict())
            ds.precision = scene.precision  # for tools: the scene (JSON) holds it for a continuation
            ds.step = np.int32(step)  # no 64-bit attributes: `nccopy -k classic` copies the file
            ds.time_days = scene.day(step) if control is None else control["day"]
            ds.counters = json.dumps(counters)
            ds.initial = json.dumps(initial)
            ds.content_sha256 = content_hash(step, x, stepper_state, departure)
            if restart_every is not None:
                ds.restart_every_days = float(restart_every)
            if control is not None:
                ds.step_control = json.dumps(control)  # floats as repr: read back to the bit
            if members is not None:
                ds.ensemble_members = np.int32(members)
            ds.createDimension("row", 3)
            ds.createDimension("node", x.shape[1])
            for name, values, attrs in (
                ("lat", np.degrees(grid.lat), NODE_COORDINATES["lat"]),
                ("lon", np.degrees(grid.lon), NODE_COORDINATES["lon"]),
                (
                    "area",
                    grid.spheremp,
                    dict(AREA_ATTRS, long_name="spheremp: GLL weight x metdet x a^2 (not assembled)"),
                ),
            ):
                ds.createVariable(name, "f8", ("node",), fletcher32=True).setncatts(attrs)
                ds[name][:] = values
            for name, row in zip(STATE, x):
                var = ds.createVariable(name, "f8", ("node",), fletcher32=True)
                var.setncatts(
                    {
                        **FIELDS[name],
                        **FIELD_ATTRS,
                        "long_name": f"{FIELDS[name]['long_name']} at each element's GLL nodes",
                    }
                )
                var[:] = row
            for name, row in zip(mass_names(scene.as_dict()), x[3:], strict=True):
                var = ds.createVariable(name, "f8", ("node",), fletcher32=True)
                var.setncatts(dict(units="m", long_name=f"{name[:-5]} tracer's mass hq at each element's GLL nodes"))
                var[:] = row
            if departure is not None:
                var = ds.createVariable("h_departure", "f4", ("node",), fletcher32=True)
                var.setncatts(dict(units="m", long_name="the float32 state's h - H0 as the run held it"))
                var[:] = departure
            if analysed is not None:
                _write_analysed(ds, analysed)
            for key, value in stepper_state.items():
                if isinstance(value, np.ndarray):
                    var = ds.createVariable(f"stepper_{key}", "f8", ("row", "node"), fletcher32=True)
                    var.long_name = f"the stepper's history {key!r} (Stepper.state(); rows u, v, h)"
                    var[:] = value
                else:  # an integer as int32 (read back as a Python int: the same content hash)
                    ds.setncattr(
                        f"stepper_{key}",
                        np.int32(value) if isinstance(value, int) and not isinstance(value, bool) else value,
                    )
    return path


def _write_analysed(ds, analysed) -> None:
    """``analysed``'s coefficients and attributes into the open restart file ``ds`` (``ANALYSED``)."""
    ds.createDimension("part", 2)
    ds.createDimension("alm", analysed.h_surface.size)
    for name in ANALYSED:
        value = getattr(analysed, name)
        if value is not None:
            var = ds.createVariable(f"analysed_{name}", "f8", ("part", "alm"), fletcher32=True)
            var.long_name = f"the reanalysis start's {name} as spherical-harmonic coefficients (real, imaginary)"
            var[:] = np.stack([value.real, value.imag])
    ds.analysed_lmax = np.int32(analysed.lmax)
    ds.analysed_a = float(analysed.a)
    ds.analysed_read = analysed.read


def case_params(params: dict, path, analysed: bool) -> dict:
    """A stored scene's case parameters ``params`` as a case rebuilt from the restart file ``path``
    takes them: with ``analysed_file`` the file itself where it keeps a reanalysis start's state
    (``analysed``, ``read``'s; ``ANALYSED``), so the input file is not needed; else as stored."""
    return params | {"analysed_file": str(path)} if analysed else params


def read_analysed(path) -> dict:
    """The reanalysis start's state kept in the restart file ``path`` (``ANALYSED``), as
    ``reanalysis.Analysed`` takes it: {"h_surface", "vorticity", "divergence", "hs" (complex (nalm,)
    arrays; hs None when not kept), "lmax", "a", "read"}. Raises ``CheckpointError`` (one line) for a
    file gone, without that state, or failing a checksum."""
    try:
        with netCDF4.Dataset(path, "r") as ds:
            if "analysed_h_surface" not in ds.variables:
                raise CheckpointError(f"{path}: holds no analysed reanalysis state (variables analysed_*)")
            parts = {
                name: np.asarray(ds[f"analysed_{name}"][:], np.float64)
                for name in ANALYSED
                if f"analysed_{name}" in ds.variables
            }
            out = {name: None for name in ANALYSED} | {k: v[0] + 1j * v[1] for k, v in parts.items()}
            return out | {"lmax": int(ds.analysed_lmax), "a": float(ds.analysed_a), "read": str(ds.analysed_read)}
    except (OSError, RuntimeError, AttributeError) as err:  # gone, not netCDF, a failed Fletcher-32 checksum
        raise CheckpointError(f"{path}: its analysed reanalysis state cannot be read ({err})") from None


def glance(path) -> dict:
    """What a command line checks of the restart file ``path`` before reading it: {"members": an
    ensemble's member count, "stepper" and "dt" (s): its scene's}, each None for a single run's (members),
    or for a file that is not a readable restart file (``read`` says why)."""
    try:
        with netCDF4.Dataset(path, "r") as ds:
            attrs = ds.__dict__
        scene = json.loads(attrs["scene"])
        return {"members": int(attrs["ensemble_members"]) if "ensemble_members" in attrs else None} | {
            key: scene.get(key) for key in ("stepper", "dt")
        }
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return dict.fromkeys(("members", "stepper", "dt"))


def read(path) -> dict:
    """Read and check a restart file: {"scene": the scene as stored (``Scene.as_dict()``),
    "step", "x" (3, N), "departure" (N float32, or None: ``write``'s), "stepper_state", "counters", "initial", "version", "path"
    (absolute), "sha256" (of the file's bytes), "restart_every", "control" (None without
    step control), "members" (an ensemble's; None for a single run), "analysed" (whether it holds a
    reanalysis start's state, ``ANALYSED``)}. Raises ``CheckpointError`` (one line)."""
    path = Path(path)
    if path.is_dir():
        raise CheckpointError(f"checkpoint {path} is a directory, not a restart file")
    if not path.is_file():
        raise CheckpointError(f"checkpoint not found: {path}")
    with open(path, "rb") as f:
        sha256 = hashlib.file_digest(f, "sha256").hexdigest()
    try:
        ds = netCDF4.Dataset(path, "r")
    except OSError:
        raise CheckpointError(f"{path}: not a readable netCDF file") from None
    with ds:
        attrs = ds.__dict__
        written = attrs.get("swe_sphere_checkpoint")
        if written is None:
            raise CheckpointError(f"{path}: not a swe_sphere checkpoint")
        if written != FORMAT:
            raise CheckpointError(
                f"{path} is in checkpoint format {written}; this swe_sphere reads format {FORMAT} only"
            )
        version = str(attrs.get("swe_sphere_version"))
        if version != package_version():
            raise CheckpointError(
                f"{path} was written by swe_sphere {version}; this is {package_version()} (continue it with that version)"
            )
        arrays = {}
        for name in ds.variables:
            try:
                arrays[name] = np.asarray(ds[name][:], dtype=np.float64)
            except (RuntimeError, OSError) as err:  # a failed Fletcher-32 checksum reads as an HDF error
                raise CheckpointError(
                    f"{path}: variable {name} fails its checksum ({err}); the file is damaged"
                ) from None
        try:
            state = {k[len("stepper_") :]: v for k, v in arrays.items() if k.startswith("stepper_")}
            state.update(
                {
                    k[len("stepper_") :]: v.item() if isinstance(v, np.generic) else v
                    for k, v in attrs.items()
                    if k.startswith("stepper_")
                }
            )
            scene = json.loads(attrs["scene"])
            x = np.stack([arrays[name] for name in (*STATE, *mass_names(scene))])
            departure = arrays["h_departure"].astype(np.float32) if "h_departure" in arrays else None
            stored = dict(
                scene=scene,
                step=int(attrs["step"]),
                x=x,
                stepper_state=state,
                counters=json.loads(attrs["counters"]),
                initial=json.loads(attrs["initial"]),
                version=version,
                path=path.resolve(),
                sha256=sha256,
                restart_every=float(attrs["restart_every_days"]) if "restart_every_days" in attrs else None,
                control=json.loads(attrs["step_control"]) if "step_control" in attrs else None,
                members=int(attrs["ensemble_members"]) if "ensemble_members" in attrs else None,
                analysed="analysed_h_surface" in arrays,
                departure=departure,
            )
            digest = attrs["content_sha256"]
            planet = stored["scene"].get("planet")
        except (KeyError, ValueError, TypeError, AttributeError) as err:
            raise CheckpointError(f"{path}: damaged checkpoint ({type(err).__name__}: {err})") from None
    if content_hash(stored["step"], stored["x"], state, stored["departure"]) != digest:
        raise CheckpointError(
            f"{path}: the state or stepper history does not match its content_sha256; the file is damaged"
        )
    _check_state(path, planet, stored["x"], state)
    return stored


def members_state(parts: list, layout: str) -> tuple:
    """(x, stepper state) of a run's members as a restart file keeps them (``write``'s ``members``),
    from ``parts``, (x (3, its members·n), ``Stepper.state()``) of every unit of the run (an
    ``integrator.core.Unit``: members stepped together) over the ranks in member order: the units'
    x side by side; with ``layout`` "shared" the one stepper's state (its arrays side by side over
    the ranks' units), "in_turn" the members' arrays (3, n) side by side (a member without one of
    them zeros there) and member k's scalars under ``member<k>_``."""
    if layout == "shared" and len(parts) == 1:
        return parts[0]
    arrays = sorted({k for _, st in parts for k, v in st.items() if isinstance(v, np.ndarray)})
    side = {k: np.concatenate([st.get(k, np.zeros_like(x)) for x, st in parts], axis=-1) for k in arrays}
    prefix = "" if layout == "shared" else "member{}_"  # in turn, the members' scalars named by member
    scalars = {prefix.format(j) + k: v for j, (_, st) in enumerate(parts) for k, v in st.items() if k not in arrays}
    return np.concatenate([x for x, _ in parts], axis=-1), side | scalars


def unit_state(state: dict, nodes, prefix: str | None) -> dict:
    """A unit's stepper state from a restart file's ``state`` (``members_state``'s): its members'
    columns ``nodes`` of the arrays; the scalars as they are (``prefix`` None) or those under
    ``prefix``, without it."""
    own = state if prefix is None else {k[len(prefix) :]: v for k, v in state.items() if k.startswith(prefix)}
    return own | {k: v[..., nodes] for k, v in state.items() if isinstance(v, np.ndarray)}
