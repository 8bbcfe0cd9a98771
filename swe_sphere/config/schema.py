"""Scene files' keys and types: the schema, the small frozen records of a scene's tables, the
checks of a value's type, the command-line overrides, and the file read into checked tables.

Every problem raises ``SceneError`` (a ValueError) with a one-line message naming the key.
"""

from __future__ import annotations

import math
import tomllib
import types
from dataclasses import dataclass
from pathlib import Path

from ..core.arguments import got
from ..core.constants import EARTH
from ..core.errors import SceneError
from ..mesh.records import MeshRecord, mesh_of
from ..steppers import STEPPERS, option_types


@dataclass(frozen=True)
class SceneGrid:
    """A scene's grid ([grid]; ``Scene.grid``): ``ne`` elements along a cube edge (0 for a mesh
    file, HOMME's), ``np`` GLL points per element direction, ``mesh`` the mesh record
    (``mesh.records``; None: the equiangular cube)."""

    ne: int
    np: int
    mesh: MeshRecord | None = None

    @property
    def record(self) -> MeshRecord:
        """The mesh record, the equiangular cube's too (``mesh.records.mesh_of``)."""
        return mesh_of(self.ne, self.mesh)


@dataclass(frozen=True)
class SceneControl:
    """A scene's step control ([time] ``control`` and its keys; ``Scene.control``, None for a
    fixed Δt): ``mode`` "cfl", "error" or "balanced"; under "error" the tolerances ``rtol`` (> 0) and
    ``atol_wind`` (m s⁻¹, on u and v), ``atol_h`` (m) of ``steppers.control.ErrorNorm`` and the
    ``controller`` (a name of ``steppers.control.CONTROLLERS``); ``cfl`` the target Courant
    number (``steppers.control.CflController``; under "error" a cap, None: none); ``dt_min``
    (s, > 0: a step below it stops the run as a blow-up) and ``dt_max`` (s; None: none). The
    scene's ``dt`` is the first step. ``cfl_default``: ``cfl`` is error control's default cap
    (``config.control.CFL_FRACTION`` × the stepper's measured Courant limit), which holds the
    Courant number only: no bound on a step's growth, so that where it does not bind the steps
    are the error controller's alone. Under "balanced" (error control whose tolerances follow
    the spatial error's estimated rate, ``steppers.control.Balance``) ``balance`` (> 0) the
    fraction of it a step's error estimate is held to, per unit of time; rtol and atol None.
    ``per_unit_step`` (under "error"): the error norm taken per unit step, ‖e‖ · (1 day / Δt),
    rather than per step (Shampine 2005, J. Sci. Comput. 25:3, "error per unit step": tolerance
    proportionality for any order, a split first-order term's included)."""

    mode: str
    rtol: float | None = None
    atol_wind: float | None = None
    atol_h: float | None = None
    controller: str | None = None
    cfl: float | None = None
    dt_min: float = 0.0
    dt_max: float | None = None
    cfl_default: bool = False
    balance: float | None = None
    per_unit_step: bool = False


@dataclass(frozen=True)
class SceneTime:
    """A scene's stepping ([time] and the stepper's table; ``Scene.time``): the ``stepper``
    (``steppers.STEPPERS``) and its ``options``, the step ``dt`` (s; under ``control`` the
    first), the last model day ``days`` and the step ``control`` (None: a fixed Δt)."""

    stepper: str
    options: dict
    dt: float
    days: float
    control: SceneControl | None = None


@dataclass(frozen=True)
class SceneHyperviscosity:
    """A scene's ∇⁴ hyperviscosity ([hyperviscosity]; ``Scene.hyperviscosity``): ``nu``,
    ``nu_div``, ``nu_s`` (m⁴ s⁻¹, on this grid; the rotational wind, divergent wind and h + hs,
    HOMME's names), ``subcycle`` substeps a step, ``scaling`` (None: constant ν; s: the
    tensor ∇⁴, ν ∝ Δx^s along each element direction, HOMME's ``hypervis_scaling``) and
    ``every`` (k: the ∇⁴ over kΔt after every k-th step; 1: every step)."""

    nu: float
    nu_div: float
    nu_s: float
    subcycle: int
    scaling: float | None = None
    every: int = 1


@dataclass(frozen=True)
class SceneOutput:
    """A scene's output ([output]; ``Scene.output``): the interval ``every_days``, a log line
    every ``log_every_steps`` (0: none), the run file's node ``fields`` (() : all of
    ``OUTPUT_FIELDS``) and the more run files ``streams`` ({"name", "every_days", "fields"})."""

    every_days: float
    log_every_steps: int
    fields: tuple
    streams: tuple


SCHEMA = {
    "description": str,
    "terms": list,
    "case": dict,
    "grid": {
        "ne": int,
        "np": int,
        "map": str,
        "stretch_factor": float,
        "target_lat": float,
        "target_lon": float,
        "cube": str,
        "mesh_file": str,
    },
    "time": {
        "stepper": str,
        "dt": float,
        "dt_np": dict,  # {np = factor}: a scaled dt that much longer at that np (``resolve.resolve_dt_np``)
        "days": float,
        "control": str,
        "rtol": float,
        "atol": float | list,  # one for every field in its units, or [wind (m/s), h (m)]: ``resolve_control``
        "per_unit_step": bool,
        "controller": str,
        "cfl": float | bool,  # a Courant number, or under "error" and "balanced" false: no cap (``control._cfl``)
        "dt_min": float,
        "dt_max": float,
        "balance": float,
    },
    "output": {"every_days": float, "log_every_steps": int, "fields": list, "streams": list, "cells": bool},
    "hyperviscosity": {
        "efold_hours": float,
        "nu": float,
        "nu_div": float,
        "nu_s": float,
        "subcycle": int,
        "scaling": float,
        "every": int | str,  # or "auto" (``hyperviscosity.resolve_every``)
    },
    "filter": {"mu": float, "efold_hours": float, "p_bv": float, "s_bv": float},
    "dfi": {"span_hours": float, "cutoff_hours": float},
    "ensemble": {"members": int, "perturbation": float, "seed": int, "degrees": tuple},
    "planet": {"radius": float, "omega": float, "gravity": float},
    # the tendency's (and "float32_state": the state's) float type; the float32 state's increments
    # compensated, its mass fixed (``resolve.resolve_precision``)
    "numerics": {"precision": str, "compensated": bool, "mass_fixer": bool},
    # passive tracers: names, their initial fields (bundled, or a file's variables), the limiter, the ∇⁴ and where
    # it acts (``resolve_tracers``, ``resolve_limiter``, ``resolve_tracer_hyperviscosity``, ``resolve_stage_hyperviscosity``)
    "tracers": {
        "names": list,
        "initial": list,
        "limiter": str,
        "hyperviscosity": bool,
        "stage_hyperviscosity": bool,
        "file": str,
    },
    # one table per stepper, named after it, with the stepper's own options
    **{name: option_types(cls.Options) for name, cls in STEPPERS.items() if option_types(cls.Options)},
}


def is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_integer(value) -> bool:
    return is_number(value) and math.isfinite(value) and int(value) == value


def refuse_nonfinite(key: str, value) -> None:
    """Refuse (``SceneError`` naming ``key``, or ``key.k``, ``key[i]`` inside) a NaN or an
    infinity anywhere in ``value``: no float a scene takes may be one."""
    if isinstance(value, float) and not math.isfinite(value):
        raise SceneError(f"{key} must be finite (got {value!r})")
    if isinstance(value, dict):
        for k, v in value.items():
            refuse_nonfinite(f"{key}.{k}", v)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            refuse_nonfinite(f"{key}[{i}]", v)


def check_type(key, value, kind):
    refuse_nonfinite(key, value)
    if isinstance(kind, types.UnionType):  # e.g. a count or "auto": the options' own check names the choices
        return value
    if (
        kind is tuple
    ):  # a list-valued option (a Butcher table): a TOML array, its entries the stepper's options to check
        if not isinstance(value, (list, tuple)):
            raise SceneError(f"{key} must be an array (got {got(value)})")
        return value
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if kind is int and isinstance(value, float) and value.is_integer():
        value = int(value)
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise SceneError(f"{key} must be {kind.__name__} (got {value!r})")
    return value


def validate(raw: dict) -> dict:
    out = {}
    for key, value in raw.items():
        if key not in SCHEMA:
            raise SceneError(f"unknown key {key!r} in scene (known: {', '.join(SCHEMA)})")
        spec = SCHEMA[key]
        if isinstance(spec, dict):
            if not isinstance(value, dict):
                raise SceneError(f"[{key}] must be a table")
            sub = {}
            for k, v in value.items():
                if k not in spec:
                    removed = STEPPERS[key].removed(k) if key in STEPPERS else None
                    if removed:
                        raise SceneError(f"{key}.{removed}")
                    raise SceneError(f"unknown key {key}.{k} in scene (known: {', '.join(spec)})")
                sub[k] = check_type(f"{key}.{k}", v, spec[k])
            out[key] = sub
        else:
            out[key] = check_type(key, value, spec)
    return out


# keys of [case] that say how a run starts, not which flow: they outlive a case switch
SCENE_CASE_KEYS = ("initialization",)


def _apply_overrides(raw: dict, overrides: dict) -> None:
    """Set ``"section.key": value`` (or ``"key": value``) in the raw TOML dict.
    A ``case.name`` other than the file's switches the case: the file's [case]
    parameters (and reference, a truth of the old flow) are the old case's and are
    dropped, all but ``SCENE_CASE_KEYS``; the ``case.*`` overrides then apply (one
    the new case does not know is refused by ``cases.make_case``)."""
    case = raw.get("case")
    if isinstance(case, dict) and "case.name" in overrides and overrides["case.name"] != case.get("name"):
        raw["case"] = {k: v for k, v in case.items() if k in SCENE_CASE_KEYS}
    for key, value in overrides.items():
        section, _, name = key.rpartition(".")
        if not name:
            raise SceneError(f"override {key!r} must be SECTION.KEY or KEY")
        if section:
            table = raw.setdefault(section, {})
            if not isinstance(table, dict):
                raise SceneError(f"override {key}: {section} is not a table")
            table[name] = value
        else:
            raw[name] = value


def read_scene(path: Path, overrides: dict) -> tuple[dict, float | None, str | None, dict, dict]:
    """(the tables of the scene file ``path`` with ``overrides`` applied (``_apply_overrides``),
    their keys and types checked (``SCHEMA``); the file's own radius (m): that of its [planet]
    before the overrides, for which its dt and ν are, None with an override of time.dt; the
    file's own case name, None without one; the file's own [grid] before the overrides, for
    which its dt and ν are, its types checked, {} without one; the file's own tables before the
    overrides, checked, {} where they do not check without the overrides: what a run of the file
    as it is would take, for ``Scene.own_dt``/``own_planet``/``own_days``). Raises ``SceneError``: a file
    that cannot be read or is not TOML, an unknown key, a value of the wrong type, a bad override."""
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"malformed TOML in {path}: {err}") from None
    except UnicodeDecodeError as err:  # TOML is UTF-8 text
        raise SceneError(f"scene {path} is not a text (UTF-8) file: byte {err.start} cannot be read") from None
    except OSError as err:  # IsADirectoryError's strerror: "Is a directory"
        raise SceneError(f"cannot read scene {path}: {err.strerror.lower()}") from None
    table = raw.get("planet", {})
    file_radius = table.get("radius", EARTH.a) if isinstance(table, dict) and "time.dt" not in overrides else None
    file_case = raw.get("case", {}).get("name") if isinstance(raw.get("case"), dict) else None
    file_grid = validate({"grid": raw.get("grid", {})})["grid"]
    try:
        own = validate(raw)
    except SceneError:  # a file that checks only with the overrides: nothing of its own
        own = {}
    _apply_overrides(raw, overrides)
    return validate(raw), file_radius, file_case, file_grid, own
