"""Restart files: everything a run needs to continue bitwise (HOMME's restart,
Oceananigans' ``Checkpointer``).

A checkpoint is a netCDF4 file holding the element-local state ``x`` (3, N)
(u, v in m/s, h in m), the stepper's ``state()`` (arrays as variables
``stepper_<key>``, scalars as attributes ``stepper_<key>``), the run's counters
(step, RHS evaluations, solver iterations, wall time), the invariants at t = 0
(so relative changes keep their origin), the resolved scene (JSON) and the
package version. Restoring it into a fresh ``Simulation`` of the same scene is
just another initial state: the continued run is bitwise the uninterrupted one.

Every variable is written with netCDF's per-variable Fletcher-32 checksum, and
the attribute ``content_sha256`` holds a SHA-256 of the state, the stepper's
history and the step (``content_hash``), so a damaged file is refused instead of
continued.

A checkpoint also starts other runs: ``branch`` makes the scene of a run from
its state with another stepper or Δt (``Simulation.from_checkpoint``, ``swe-sphere
run --continue R --stepper S --dt DT``, ``swe-sphere sweep --from R``).

``read`` raises ``CheckpointError`` (a ValueError, one line) for a file that is
not a checkpoint, was written by another swe_sphere version, or is damaged: a
failed checksum or hash, a non-finite value, a depth h <= 0, or a wind beyond
``MAX_FROUDE`` times the gravity-wave speed of the deepest node (no shallow-water
flow the model runs comes near it), each naming the variable.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import netCDF4
import numpy as np

from . import __version__
from .config import Scene, SceneError, scene_from_dict, with_days
from .constants import Planet
from .output import WRITING, ExclusiveFile
from .steppers import STEPPERS

FORMAT = 2  # bump when the layout changes (2: checksums and content hash)
MAX_FROUDE = 2.0  # |v| / sqrt(g max h) beyond which a stored wind is not a state the model made


class CheckpointError(ValueError):
    """A checkpoint cannot be used; the message says why."""


@dataclass
class Checkpoint:
    """A read checkpoint: the scene, the step reached and what continues from it."""

    scene: Scene
    step: int
    x: np.ndarray  # (3, N) element-local u, v, h
    stepper_state: dict
    counters: dict  # rhs_evals, wall_time, iterations (dict)
    initial: dict  # diagnostics at t = 0
    version: str
    path: Path | None = None  # the file read (absolute)
    sha256: str | None = None  # SHA-256 (hex) of the file's bytes


def branch(ck: Checkpoint, *, stepper: str | None = None, dt: float | None = None, days: float | None = None) -> Scene:
    """The scene of a new run from checkpoint ``ck``'s state with ``stepper`` and
    ``dt`` (s; None: the checkpoint's), to model day ``days`` (from t = 0; None:
    the checkpoint scene's): a fresh stepper (multistep ones start as at t = 0),
    step 0 at the checkpoint's day (``Scene.start_day``), output every output
    interval from there, and ``Scene.branch`` recording the source (its path and
    SHA-256, step, day, stepper and dt). The stepper's options are the
    checkpoint's for its own stepper, else the defaults. Raises ``SceneError``
    (one line) for an unknown stepper, a dt <= 0, or a run from the branch day to
    ``days`` or an output interval that is not whole steps of dt."""
    s = ck.scene
    stepper = s.stepper if stepper is None else stepper
    if stepper not in STEPPERS:
        raise SceneError(f"unknown stepper {stepper!r} (known: {', '.join(STEPPERS)})")
    if dt is not None and not (math.isfinite(dt) and dt > 0):
        raise SceneError(f"dt must be > 0 (got {dt:g})")
    record = {"restart": None if ck.path is None else str(ck.path), "sha256": ck.sha256, "step": ck.step, "day": s.day(ck.step),
              "stepper": s.stepper, "dt": s.dt}
    scene = replace(s, stepper=stepper, stepper_options=s.stepper_options if stepper == s.stepper else {},
                    dt=s.dt if dt is None else float(dt), branch=record)
    return with_days(scene, s.days if days is None else days, "the restart file's" if dt is None else "the dt given")


def branch_attrs(scene: Scene) -> dict:
    """The global attributes of a branched run's files (``Scene.branch``): ``branched_from``
    (the restart file's path), ``branched_from_sha256``, ``_step``, ``_day``, ``_stepper``,
    ``_dt`` (those known); {} for a scene that did not branch."""
    b = scene.branch or {}
    return {"branched_from" + ("" if k == "restart" else f"_{k}"): v for k, v in b.items() if v is not None}


def content_hash(step: int, x: np.ndarray, stepper_state: dict) -> str:
    """SHA-256 (hex) of the step, the state ``x`` and the stepper's history
    (arrays as float64 bytes, scalars by repr, in key order)."""
    h = hashlib.sha256(str(int(step)).encode())
    h.update(np.ascontiguousarray(x, dtype=np.float64).tobytes())
    for key in sorted(stepper_state):
        value = stepper_state[key]
        h.update(key.encode())
        h.update(np.ascontiguousarray(value, dtype=np.float64).tobytes() if isinstance(value, np.ndarray) else repr(value).encode())
    return h.hexdigest()


def _check_state(path, scene: Scene, x: np.ndarray, stepper_state: dict) -> None:
    """Refuse (``CheckpointError`` naming the variable) non-finite values, h <= 0 and implausible winds."""
    for name, value in (("x", x), *((f"stepper_{k}", v) for k, v in stepper_state.items() if isinstance(v, np.ndarray))):
        bad = np.flatnonzero(~np.isfinite(value))
        if bad.size:
            raise CheckpointError(f"{path}: variable {name} holds {bad.size} non-finite values; not continued")
    h = x[2]
    if h.min() <= 0:
        raise CheckpointError(f"{path}: variable x (row h) holds a depth h = {h.min():.4g} m <= 0; not continued")
    g = Planet.from_table(scene.planet).g  # not the case: a file case would read its file
    bound = MAX_FROUDE * np.sqrt(g * h.max())
    speed = np.hypot(x[0], x[1]).max()
    if speed > bound:
        raise CheckpointError(f"{path}: variable x (rows u, v) holds a wind of {speed:.4g} m/s, beyond {bound:.4g} m/s "
                              f"({MAX_FROUDE:g} x the gravity-wave speed of the deepest node); not continued")


def write(path, scene: Scene, step: int, x: np.ndarray, stepper_state: dict, counters: dict, initial: dict,
          *, overwrite: bool = True) -> Path:
    """Write a checkpoint to ``path`` atomically (via ``output.ExclusiveFile``).

    ``x``: (3, N) element-local state (u, v in m s⁻¹, h in m) at ``step``
    (model time step·dt); ``stepper_state``: ``Stepper.state()`` (arrays (3, N),
    scalars); ``counters``: {"rhs_evals", "wall_time" (s), "iterations": {solver: n}};
    ``initial``: the diagnostics at t = 0. Raises ``output.OutputError`` when
    ``path`` exists and not ``overwrite`` (or is a link / being written)."""
    path = Path(path)
    with WRITING, ExclusiveFile(path, overwrite=overwrite) as tmp:  # WRITING: see mpi.watch_failures
        with netCDF4.Dataset(tmp, "w", format="NETCDF4") as ds:
            ds.title = f"swe_sphere restart file of scene {scene.name}"
            ds.swe_sphere_checkpoint = FORMAT
            ds.swe_sphere_version = __version__
            ds.scene = json.dumps(scene.as_dict())
            ds.step = int(step)
            ds.time_days = scene.day(step)
            ds.counters = json.dumps(counters)
            ds.initial = json.dumps(initial)
            ds.content_sha256 = content_hash(step, x, stepper_state)
            ds.createDimension("row", 3)
            ds.createDimension("node", x.shape[1])
            var = ds.createVariable("x", "f8", ("row", "node"), fletcher32=True)
            var.long_name = "element-local state: rows u (m s-1), v (m s-1), h (m)"
            var[:] = x
            for key, value in stepper_state.items():
                if isinstance(value, np.ndarray):
                    var = ds.createVariable(f"stepper_{key}", "f8", ("row", "node"), fletcher32=True)
                    var[:] = value
                else:
                    ds.setncattr(f"stepper_{key}", value)
    return path


def read_on_root(path, comm) -> Checkpoint:
    """``read`` on rank 0 of ``comm`` (None or one rank: ``read``): the other ranks
    get the checkpoint without its whole-grid arrays (x and the stepper's arrays
    None), which rank 0 hands out (``Topology.distribute``), so no other rank holds
    the whole state. Raises what ``read`` raises, on every rank."""
    if comm is None or comm.size == 1:
        return read(path)
    ck = error = None
    if comm.rank == 0:
        try:
            ck = read(path)
        except Exception as err:  # every rank must raise it, or the others wait for rank 0 forever
            error = err
    error = comm.bcast(error, root=0)
    if error is not None:
        raise error
    light = None
    if comm.rank == 0:
        light = replace(ck, x=None, stepper_state={k: None if isinstance(v, np.ndarray) else v for k, v in ck.stepper_state.items()})
    light = comm.bcast(light, root=0)
    return ck if comm.rank == 0 else light


def read(path) -> Checkpoint:
    """Read a checkpoint. Raises ``CheckpointError`` (one line)."""
    path = Path(path)
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
            raise CheckpointError(f"{path} is in checkpoint format {written}; this swe_sphere reads format {FORMAT} only")
        version = str(attrs.get("swe_sphere_version"))
        if version != __version__:
            raise CheckpointError(f"{path} was written by swe_sphere {version}; this is {__version__} (continue it with that version)")
        arrays = {}
        for name in ds.variables:
            try:
                arrays[name] = np.asarray(ds[name][:], dtype=np.float64)
            except (RuntimeError, OSError) as err:  # a failed Fletcher-32 checksum reads as an HDF error
                raise CheckpointError(f"{path}: variable {name} fails its checksum ({err}); the file is damaged") from None
        try:
            scene = scene_from_dict(json.loads(attrs["scene"]))
            x = arrays["x"]
            state = {k[len("stepper_"):]: v for k, v in arrays.items() if k.startswith("stepper_")}
            state.update({k[len("stepper_"):]: v.item() if isinstance(v, np.generic) else v for k, v in attrs.items() if k.startswith("stepper_")})
            ck = Checkpoint(scene, int(attrs["step"]), x, state, json.loads(attrs["counters"]), json.loads(attrs["initial"]), version,
                            path.resolve(), sha256)
            stored = attrs["content_sha256"]
        except (KeyError, ValueError, TypeError) as err:
            raise CheckpointError(f"{path}: damaged checkpoint ({type(err).__name__}: {err})") from None
    if content_hash(ck.step, ck.x, ck.stepper_state) != stored:
        raise CheckpointError(f"{path}: the state or stepper history does not match its content_sha256; the file is damaged")
    _check_state(path, scene, ck.x, ck.stepper_state)
    return ck
