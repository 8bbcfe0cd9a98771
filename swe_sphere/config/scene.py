"""Scenes: a TOML file per test case, validated once into a frozen ``Scene``.

A scene names its case, the terms it simulates, the grid, stepper and step,
the run length, the output interval and the hyperviscosity. Layout::

    description = "..."
    terms = ["continuity", "momentum_advection", ...]
    [case]            name = "tc5_mountain" (+ case parameters, e.g. alpha), or
                      name = "file", path = "state.nc", time = 3.0 (a state of one's
                      own from a file, at a time it holds: ``initial_state``),
                      initialization = "none" | "dfi" (a digital-filter balanced start),
                      reference = "T341" or "PATH" (the reference to score against
                      instead of the case's bundled T213 one: a bundled truncation
                      or a file; ``reference.locate``)
    [dfi]             span_hours = 48.0, cutoff_hours = 24.0 (``initialization.DigitalFilter``)
    [grid]            ne = 30, np = 4, and the mesh: the uniform cube of ne (the default),
                      map = "equiangular" | "element_local" (the cube's map: HOMME's
                      cubed_sphere_map 0 or 2), stretch_factor = 2.5, target_lat = 40.0,
                      target_lon = 270.0 (degrees: the Schmidt-stretched cube of ne, FV3's
                      do_schmidt; element-local), cube = "equiangular" | "equidistant" (the
                      cube's element corners equally spaced in angle, the default, or on the
                      cube's faces as pySEs's grid; element-local unless map says), or mesh_file = "x.g" (an Exodus II mesh,
                      relative to the scene file or absolute; ne = 0 as HOMME's; element-local,
                      or with map = "equiangular" each element in its cube face);
                      ``grid.spec`` records the choice in ``Scene.mesh``
    [time]            stepper = "leapfrog_trapezoidal", dt = 90.0, days = 15.0
    [output]          every_days = 1.0, log_every_steps = 0 (a line of invariant
                      changes and Courant numbers every so many steps; 0: none),
                      fields = ["h", "u", "v"] (the run file's node fields; default
                      all of ``OUTPUT_FIELDS``), cells = true (the GLL control volumes
                      that tools remap and integrate on; false: a file without them)
    [[output.streams]] name = "6h", every_days = 0.25, fields = ["h"]: one more run
                      file RUN.6h.nc per table, at its own interval (whole steps)
    [hyperviscosity]  efold_hours = 3.0, nu = ..., nu_div = ..., nu_s = ..., subcycle = 1
                      (efold_hours: e-folding time at the grid scale, which sets
                      nu, nu_div, nu_s on every grid (``efold_nu``); nu, nu_div,
                      nu_s (m^4/s at the scene's grid, scaled as dx^3.2): the
                      rotational wind, divergent wind, h + hs (HOMME's names),
                      given explicitly; without efold_hours nu_div, nu_s default to nu),
                      scaling = 3.2 (s in 0..4: HOMME's tensor hyperviscosity, hypervis_scaling:
                      the effective nu along each element direction is nu (dx / dx_ref)^s, dx_ref
                      the mean spacing's, so s = 4 is the efold_hours rule element by element;
                      nu, nu_div, nu_s then scale as dx^s between grids; absent: constant nu)
    [leapfrog]        robert_asselin = 0.05   (a table per stepper, named after
                      it, holds that stepper's options; an option typed tuple
                      is a TOML array, e.g. [tableau] A = [[0, 0], ["1/2", 0]])
    [planet]          radius = 6.37122e6 (m), omega = 7.292e-5 (s^-1),
                      gravity = 9.80616 (m s^-2) (Williamson's, the defaults;
                      ``constants.Planet``). A scene's dt and ν are for its
                      file's radius: with another radius set by an override
                      (``-s planet.radius=...``) and no dt given (``--dt``,
                      ``-s time.dt``), dt scales with the radius (the node
                      spacing) as for a grid, and ν as a⁴ (the same damping time
                      at the grid scale). A run on another planet than
                      Williamson's Earth is not scored against the bundled
                      spectral references (the Earth's).

Every problem raises ``SceneError`` (a ValueError) with a one-line message
naming the offending key or value.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import tomllib
import types
from dataclasses import dataclass, field
from fractions import Fraction
from importlib.resources import files
from pathlib import Path
from typing import NamedTuple

from ..cases.library import Case, make_case
from ..cases.reference import cases_of, locate, reference_path, stored_days
from ..core.constants import DAY, EARTH, Planet
from ..core.errors import SceneError
from ..grid import spec as grid_spec
from ..grid.gll import NP_MAX, NP_MIN, gll
from ..grid.quality import smallest_dx
from ..io.initial_state import SCENE_CASES
from ..io.run_file import OUTPUT_FIELDS
from ..model.shallow_water import TERMS
from ..steppers import STEPPERS, option_types
from ..steppers.initialization import METHODS, DigitalFilter

HYPERVIS_EXPONENT = 3.2  # ν ∝ Δx^3.2 (HOMME's resolution scaling; Dennis et al. 2012)


def efold_nu(hours: float, ne: float, np_: int, radius: float) -> float:
    """ν (m⁴ s⁻¹) that e-folds a degree-L harmonic in ``hours``, L = 2 ne (np − 1)
    the Nyquist degree of the 4 ne (np − 1) nodes around a great circle:
    ν = a⁴ / (τ (L(L+1))²). The T213 references use the same rule (3 h at
    l = 213: ν₄ = 7.34e13 m⁴ s⁻¹). On a mesh the rule is stated at the mean
    spacing: ne is that of the uniform cube with as many elements (``grid.spec.mean_ne``:
    √(F/6) for a file of F elements; a stretched cube's own ne), so ν is the same for
    the same element count, and elements smaller than the mean are damped faster, as
    (mean spacing / their spacing)⁴; with the tensor ∇⁴ (``hyperviscosity.scaling = s``) as
    that ratio to the power 4 − s, so s = 4 states the rule element by element."""
    L = 2 * ne * (np_ - 1)
    return radius**4 / (hours * 3600.0 * (L * (L + 1)) ** 2)


@dataclass(frozen=True)
class SceneGrid:
    """A scene's grid ([grid]; ``Scene.grid``): ``ne`` elements along a cube edge (0 for a mesh
    file, HOMME's), ``np`` GLL points per element direction, ``mesh`` the ``grid.spec`` record
    (None: the equiangular cube)."""

    ne: int
    np: int
    mesh: dict | None = None


@dataclass(frozen=True)
class SceneTime:
    """A scene's stepping ([time] and the stepper's table; ``Scene.time``): the ``stepper``
    (``steppers.STEPPERS``) and its ``options``, the step ``dt`` (s) and the last model day
    ``days``."""

    stepper: str
    options: dict
    dt: float
    days: float


@dataclass(frozen=True)
class SceneHyperviscosity:
    """A scene's ∇⁴ hyperviscosity ([hyperviscosity]; ``Scene.hyperviscosity``): ``nu``,
    ``nu_div``, ``nu_s`` (m⁴ s⁻¹, on this grid; the rotational wind, divergent wind and h + hs,
    HOMME's names), ``subcycle`` substeps a step and ``scaling`` (None: constant ν; s: the
    tensor ∇⁴, ν ∝ Δx^s along each element direction, HOMME's ``hypervis_scaling``)."""

    nu: float
    nu_div: float
    nu_s: float
    subcycle: int
    scaling: float | None = None


@dataclass(frozen=True)
class SceneOutput:
    """A scene's output ([output]; ``Scene.output``): the interval ``every_days``, a log line
    every ``log_every_steps`` (0: none), the run file's node ``fields`` (() : all of
    ``OUTPUT_FIELDS``) and the more run files ``streams`` ({"name", "every_days", "fields"})."""

    every_days: float
    log_every_steps: int
    fields: tuple
    streams: tuple


@dataclass(frozen=True)
class Scene:
    """A validated, resolved scene: all values final, overrides applied (``load_scene``).

    The fields are flat; the properties ``grid``, ``time``, ``hyperviscosity`` and ``output``
    group them by their scene table as small frozen dataclasses (``SceneGrid``, ``SceneTime``,
    ``SceneHyperviscosity``, ``SceneOutput``), read-only.

    Attributes
    ----------
    name, description : str
        The scene's name (its file's stem) and one line saying what it runs.
    case : str
        The case (``cases.library``: Williamson et al. 1992 TC1, TC2, TC5, TC6; Galewsky
        et al. 2004; ...).
    case_params : dict
        The case's parameters ([case] table).
    terms : tuple of str
        The terms integrated (``model.shallow_water.TERMS``); an absent term costs nothing.
    ne, np : int
        Elements along a cube edge; GLL points per element direction.
    stepper : str
        The time stepper (``steppers.STEPPERS``).
    stepper_options : dict
        Its options (the scene's table of the stepper's name).
    dt : float
        Time step (s).
    days : float
        The last model day (from t = 0); the run is ``start_day`` to ``days``.
    output_every_days : float
        Output interval (days), a whole number of steps.
    nu, nu_div, nu_s : float
        ∇⁴ hyperviscosity coefficients (m⁴ s⁻¹) on the rotational wind, the divergent
        wind and h, already scaled to this grid.
    hypervis_subcycle : int
        Hyperviscosity substeps a step.
    hypervis_scaling : float or None
        None (constant ν) or s: the tensor ∇⁴ with ν ∝ Δx^s per element direction
        ([hyperviscosity] scaling; HOMME's ``hypervis_scaling``).
    notes : tuple of str
        What resolving the scene changed (e.g. dt scaled to the grid), for the run's header.
    branch : dict or None
        A run branched from a restart file (``checkpoint.branch``): its path and SHA-256,
        step, day, stepper and dt; its steps count from that day.
    initialization : dict or None
        None (the case's initial state) or {"method": "dfi", "span_hours": ...,
        "cutoff_hours": ...} (``initialization.DigitalFilter``).
    reference : str or None
        None (the case's bundled reference, if any) or the absolute path of the
        reference file the run is scored against (``case.reference``).
    log_every_steps : int
        A log line every so many steps (``Simulation.run``'s ``log``); 0: none.
    planet : dict
        [planet]: radius (m), omega (s⁻¹), gravity (m s⁻²).
    output_fields : tuple of str
        The node fields the run file holds; (): all (``OUTPUT_FIELDS``).
    output_streams : tuple of dict
        More run files, each {"name": suffix, "every_days": interval, "fields": (...)}.
    mesh : dict or None
        The mesh ([grid] ``map``, ``stretch_factor``/``target_lat``/``target_lon``,
        ``mesh_file``) as a ``grid.spec`` record; None: the equiangular cube of ne.
    output_cells : bool
        [output] cells: the run files hold the control volumes (``io.dual``).
    """

    name: str
    description: str
    case: str
    case_params: dict
    terms: tuple
    ne: int
    np: int
    stepper: str
    stepper_options: dict
    dt: float
    days: float
    output_every_days: float
    nu: float
    hypervis_subcycle: int
    nu_div: float = 0.0
    nu_s: float = 0.0
    notes: tuple = field(default=())
    # a run branched from a restart file (``checkpoint.branch``): {"restart": its path, "sha256": the
    # file's, "step", "day", "stepper", "dt": where and from what}; its steps count from that day
    branch: dict | None = None
    initialization: dict | None = None
    reference: str | None = None
    log_every_steps: int = 0  # a log line every so many steps (``Simulation.run``'s ``log``); 0: none
    planet: dict = field(default_factory=EARTH.as_table)  # [planet]: radius (m), omega (s⁻¹), gravity (m s⁻²)
    output_fields: tuple = ()  # [output] fields: the node fields the run file holds; (): all (``OUTPUT_FIELDS``)
    # [[output.streams]]: more run files, each {"name": suffix, "every_days": interval, "fields": (...)}
    output_streams: tuple = ()
    # the mesh ([grid] map, stretch_factor, mesh_file): a ``grid.spec`` record; None: the equiangular cube of ne
    mesh: dict | None = None
    output_cells: bool = True  # [output] cells: the run files hold the control volumes (``dual``)
    hypervis_scaling: float | None = None  # [hyperviscosity] scaling: the tensor ∇⁴'s s; None: constant ν

    # the nested view: the flat fields grouped by their table, read-only (the flat fields stay
    # what the rest of the package reads)
    @property
    def grid(self) -> SceneGrid:
        """ne, np and the mesh ([grid])."""
        return SceneGrid(self.ne, self.np, self.mesh)

    @property
    def time(self) -> SceneTime:
        """The stepper, its options, dt and days ([time] and the stepper's table)."""
        return SceneTime(self.stepper, self.stepper_options, self.dt, self.days)

    @property
    def hyperviscosity(self) -> SceneHyperviscosity:
        """nu, nu_div, nu_s and the subcycles ([hyperviscosity])."""
        return SceneHyperviscosity(self.nu, self.nu_div, self.nu_s, self.hypervis_subcycle, self.hypervis_scaling)

    @property
    def output(self) -> SceneOutput:
        """The output interval, log interval, fields and streams ([output])."""
        return SceneOutput(self.output_every_days, self.log_every_steps, self.output_fields, self.output_streams)

    @property
    def start_day(self) -> float:
        """The model day of step 0: 0, or for a branched run the day it branched at."""
        return 0.0 if self.branch is None else self.branch["day"]

    @property
    def run_days(self) -> float:
        """The run's length in days: from ``start_day`` to ``days``."""
        return self.days - self.start_day

    @property
    def nsteps(self) -> int:
        return round(self.run_days * DAY / self.dt)

    def day(self, step: int) -> float:
        """The model time of ``step`` in days: start_day + step × (run length / nsteps),
        in exact rational arithmetic from the days as written (their shortest
        decimals), rounded once. So the output times are the multiples of the output
        interval as typed (3.0, where step × dt / 86400 gives 3.0000000000000004 for
        dt = 86400/408 s) and ``ds.h.sel(time=3)`` finds them; a run continued to
        another length of whole steps (``with_days``) gives the same times, and a
        branch at day 10 with another dt gives 10 + the multiples."""
        start = Fraction(repr(self.start_day))
        return float(start + (Fraction(repr(self.days)) - start) * int(step) / self.nsteps)

    def make_case(self):
        return make_case(self.case, self.case_params, Planet.from_table(self.planet), SCENE_CASES)

    def make_mesh(self):
        """The grid's ``Mesh`` for ``CubedSphere(ne, np, mesh=...)``, None for the equiangular
        cube (``grid.spec.build_mesh``: ``SceneError`` for a mesh file gone or changed)."""
        return grid_spec.build_mesh(self.ne, self.mesh)

    @property
    def nelem(self) -> int:
        """Elements of the grid: 6·ne² on a cube, a mesh file's own count."""
        return grid_spec.nelem(self.ne, self.mesh)

    @property
    def grid_text(self) -> str:
        """The grid in words: ``ne=4 np=4``, ``mesh x.g np=4``... (``grid.spec.describe``)."""
        return grid_spec.describe(self.ne, self.np, self.mesh)

    @property
    def grid_label(self) -> str:
        """The grid's part of a default file name: ``ne4``, ``ne4map2``, ``ne4c2.5``, a mesh
        file's stem (``grid.spec.label``)."""
        return grid_spec.label(self.ne, self.mesh)

    @property
    def digital_filter(self) -> DigitalFilter | None:
        """The start's digital filter, or None for the case's own initial state."""
        if self.initialization is None:
            return None
        return DigitalFilter(**{k: v for k, v in self.initialization.items() if k != "method"})

    @property
    def reference_file(self) -> Path | None:
        """The reference file the run is scored against: the chosen one, else the
        case's bundled one (``reference.reference_path``) on Williamson's Earth; None
        for a case scored against its exact solution or without a reference, and
        on another planet (the bundled references are the Earth's)."""
        if self.reference is not None:
            return Path(self.reference)
        return reference_path(self.make_case()) if Planet.from_table(self.planet) == EARTH else None

    def as_dict(self) -> dict:
        """The scene as plain values (JSON-able); the output choices and the mesh only when
        made, so a scene without them reads as before they existed (run files, restart files)."""
        d = dataclasses.asdict(self)
        for key in ("output_fields", "output_streams", "mesh"):
            if not d[key]:
                del d[key]
        if d["output_cells"]:  # the default
            del d["output_cells"]
        if d["hypervis_scaling"] is None:
            del d["hypervis_scaling"]
        return d


def scene_from_dict(d: dict) -> Scene:
    """A Scene from ``Scene.as_dict()`` (e.g. read back from JSON).

    A key this version added with a default (e.g. ``initialization``) may be
    missing: its default is the behaviour of the version that wrote ``d``, so a
    restart file from before the key existed still continues bitwise. ValueError
    for an unknown key or a missing key without a default.
    """
    fields = dataclasses.fields(Scene)
    unknown = set(d) - {f.name for f in fields}
    missing = {
        f.name
        for f in fields
        if f.name not in d and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    }
    if unknown or missing:
        raise ValueError(f"scene keys differ from this version's: {', '.join(sorted(unknown | missing))}")
    streams = tuple({**st, "fields": tuple(st["fields"])} for st in d.get("output_streams", ()))
    return Scene(
        **{
            **d,
            "terms": tuple(d["terms"]),
            "notes": tuple(d.get("notes", ())),
            "output_fields": tuple(d.get("output_fields", ())),
            "output_streams": streams,
        }
    )


_SCHEMA = {
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
    "time": {"stepper": str, "dt": float, "days": float},
    "output": {"every_days": float, "log_every_steps": int, "fields": list, "streams": list, "cells": bool},
    "hyperviscosity": {
        "efold_hours": float,
        "nu": float,
        "nu_div": float,
        "nu_s": float,
        "subcycle": int,
        "scaling": float,
    },
    "dfi": {"span_hours": float, "cutoff_hours": float},
    "planet": {"radius": float, "omega": float, "gravity": float},
    # one table per stepper, named after it, with the stepper's own options
    **{name: option_types(cls.Options) for name, cls in STEPPERS.items() if option_types(cls.Options)},
}


def scene_dir() -> Path:
    """Folder of the bundled scenes (testcases/)."""
    return Path(str(files("swe_sphere.testcases")))


SCENE_FOLDERS = ("", "tableaus")  # testcases/ and its folders of bundled scenes (tableaus/: Butcher tables)


def list_scenes() -> list[Path]:
    return [p for folder in SCENE_FOLDERS for p in sorted((scene_dir() / folder).glob("*.toml"))]


def resolve_path(spec: str) -> Path:
    """A scene path, or the name of a bundled scene (with or without .toml, and
    with or without its folder: "ark2_gkc" or "tableaus/ark2_gkc").
    Raises ``SceneError``, suggesting the closest bundled names for a typo."""
    p = Path(spec)
    if p.exists():
        return p
    name = p.name if p.suffix == ".toml" else p.name + ".toml"
    for folder in SCENE_FOLDERS:
        bundled = scene_dir() / folder / name
        if bundled.exists() and p.parent in (Path("."), Path(folder)):
            return bundled
    close = difflib.get_close_matches(p.stem, [q.stem for q in list_scenes()], n=3)
    hint = f" (did you mean {' or '.join(close)}?)" if close and p.parent in map(Path, SCENE_FOLDERS) else ""
    raise SceneError(f"scene file not found: {spec}{hint}")


def _whole_step_days(dt: float) -> Fraction | None:
    """The shortest decimal number of days that is a whole number of steps of
    ``dt`` (s), when a day is a rational number of them with a denominator up to
    1000 (dt = 86400/408 s: 0.125 days, 51 steps); None otherwise."""
    per_day = Fraction(DAY / dt).limit_denominator(1000)
    if abs(per_day - DAY / dt) > 1e-9 * DAY / dt:
        return None
    twos_fives = math.gcd(per_day.numerator, 10**30)  # the 2s and 5s of the numerator: a decimal unit absorbs them
    return Fraction(per_day.denominator, twos_fives)


def _whole_steps(dt: float, days: float) -> bool:
    n = round(days * DAY / dt)
    return n >= 1 and abs(n * dt - days * DAY) <= 1e-6 * dt


def _not_whole_steps(what: str, days: float, dt: float, dt_source: str) -> SceneError:
    """The one-line refusal of an interval (output or run length, days) that is not a
    whole number of steps, with where dt comes from and the nearest intervals that are."""
    unit = _whole_step_days(dt)
    if unit is not None:
        below = math.floor(Fraction(repr(days)) / unit) * unit
        near = " or ".join(f"{float(x):.10g}" for x in (below, below + unit) if x > 0)
        fits = f"whole-step intervals are the multiples of {float(unit):.10g} days (nearest: {near})"
    else:
        n = days * DAY / dt
        near = " or ".join(f"{k * dt / DAY:.6g}" for k in sorted({max(1, math.floor(n)), math.ceil(n)}))
        fits = f"the nearest whole-step intervals are {near} days"
    return SceneError(
        f"{what} of {days:g} days is not a whole number of steps of dt = {dt:g} s ({dt_source}): "
        f"a run writes and ends at whole steps; {fits}, or set a dt that divides it"
    )


def _check_schedule(dt: float, days: float, every: float, dt_source: str = "the scene's time.dt") -> None:
    """dt must divide the run length and (if shorter than the run) the output interval;
    ``dt_source`` says where dt comes from, for the message."""
    nsteps = round(days * DAY / dt)
    if nsteps > MAX_STEPS:
        raise SceneError(f"dt = {dt:g} s gives {nsteps:.3g} steps to day {days:g} (more than {MAX_STEPS:.0e})")
    if not _whole_steps(dt, days):
        raise _not_whole_steps("the run length", days, dt, dt_source)
    if days > every and not _whole_steps(dt, every):
        raise _not_whole_steps("the output interval (output.every_days)", every, dt, dt_source)


def common_interval(*days: float) -> float:
    """The longest interval (days) that divides each of ``days``: their greatest
    common divisor as the decimals they are written as (0.5 and 0.75: 0.25)."""
    parts = [Fraction(repr(float(d))) for d in days]
    denominator = math.lcm(*(p.denominator for p in parts))
    return float(Fraction(math.gcd(*(int(p * denominator) for p in parts)), denominator))


def _common_interval(every: float, days: float) -> float:
    """The longest interval (days) that divides the run length and, when the run is
    longer, the output interval."""
    return days if days <= every else common_interval(every, days)


def with_days(scene: Scene, days: float, dt_source: str = "the restart file's") -> Scene:
    """The scene run to ``days`` (model day, from t = 0) instead; dt must divide the
    run from ``start_day`` and its output interval (``dt_source`` says where dt comes
    from, for the message). Raises ``SceneError``."""
    start = scene.start_day
    if not (isinstance(days, (int, float)) and math.isfinite(days) and days > start):
        raise SceneError(
            f"days must be > {start:g} (got {days})"
            + (f": the run branches at day {start:g} and days is the model day it ends at" if start else "")
        )
    scene = dataclasses.replace(scene, days=float(days))
    _check_schedule(scene.dt, scene.run_days, scene.output_every_days, dt_source)
    return scene


def _reference(spec, case_name: str, case_obj) -> str:
    """The absolute path of the reference file ``case.reference`` names (a path, a
    bundled file name or a truncation, "T341": see ``reference.locate``), its
    variables and layout checked without reading its fields. Raises ``SceneError`` naming the key and the value."""
    where = f"case.reference = {spec!r}"
    if not isinstance(spec, str):
        raise SceneError(f'case.reference must be a file path or a truncation such as "T341" (got {_got(spec)})')
    if case_obj.exact_solution:
        raise SceneError(f"{where}: case {case_name} is scored against its exact solution, not a reference file")
    try:
        path = locate(spec, case_obj)
        stored_days(path)
        solves, expected = cases_of(path, case_obj)
    except (OSError, ValueError) as err:
        raise SceneError(f"{where}: {err}") from None
    if solves is not None and expected is not None and solves != expected:
        raise SceneError(f"{where}: the file is a {solves} reference (its title), not one of {expected}")
    return str(path)


def _first_gll_gap(np_: int) -> float:
    x = gll(np_).points
    return float(x[1] - x[0])


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_integer(value) -> bool:
    return _is_number(value) and math.isfinite(value) and int(value) == value


def _got(value) -> str:
    """A refused value for a message: its repr, and its type where that is not a number's."""
    return repr(value) if _is_number(value) else f"{value!r}, a {type(value).__name__}"


def _check_type(key, value, kind):
    if isinstance(kind, types.UnionType):  # e.g. a count or "auto": the options' own check names the choices
        return value
    if (
        kind is tuple
    ):  # a list-valued option (a Butcher table): a TOML array, its entries the stepper's options to check
        if not isinstance(value, (list, tuple)):
            raise SceneError(f"{key} must be an array (got {_got(value)})")
        return value
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if kind is int and isinstance(value, float) and value.is_integer():
        value = int(value)
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise SceneError(f"{key} must be {kind.__name__} (got {value!r})")
    if kind is float and not math.isfinite(value):
        raise SceneError(f"{key} must be finite (got {value!r})")
    return value


def _validate(raw: dict) -> dict:
    out = {}
    for key, value in raw.items():
        if key not in _SCHEMA:
            raise SceneError(f"unknown key {key!r} in scene (known: {', '.join(_SCHEMA)})")
        spec = _SCHEMA[key]
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
                sub[k] = _check_type(f"{key}.{k}", v, spec[k])
            out[key] = sub
        else:
            out[key] = _check_type(key, value, spec)
    return out


MAX_STEPS = 10**9  # a run longer than this is a typo in dt, not a plan


# the starts of load_scene's notes on how it scaled (and cut) dt: stale once a dt is given (a branch's)
DT_NOTES = ("dt scaled", "warning: dt cut")

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


def _grid_record(grid: dict, scene_path: Path) -> dict | None:
    """The ``grid.spec`` record of a scene's [grid] table (``_SCHEMA``'s types
    checked): ``mesh_file`` relative to the scene file's folder, read and checked here. Raises
    ``SceneError`` naming the key."""
    chosen = grid.get("map")
    if chosen is not None and chosen not in grid_spec.MAPS:
        raise SceneError(f"grid.map must be one of {', '.join(grid_spec.MAPS)} (got {chosen!r})")
    stretch = [k for k in ("stretch_factor", "target_lat", "target_lon") if k in grid]
    cube = grid.get("cube", "equiangular")
    if cube not in grid_spec.CUBES:
        raise SceneError(f"grid.cube must be one of {', '.join(grid_spec.CUBES)} (got {cube!r})")
    if cube != "equiangular" and ("mesh_file" in grid or stretch):
        raise SceneError(
            f"grid.cube = {cube!r} is a cube of ne; drop grid.{'mesh_file' if 'mesh_file' in grid else stretch[0]}"
        )
    if cube == "equidistant":
        return {"map": chosen or "element_local", "cube": cube}
    if "mesh_file" in grid:
        if stretch:
            raise SceneError(f"grid.{stretch[0]} stretches the cube; a mesh file is its own mesh (drop one)")
        given = Path(grid["mesh_file"]).expanduser()
        return grid_spec.file_record(
            given if given.is_absolute() else scene_path.parent / given, chosen or "element_local"
        )
    if stretch:
        if "stretch_factor" not in grid:
            raise SceneError(f"grid.{stretch[0]} needs grid.stretch_factor (the Schmidt-stretched cube)")
        if chosen == "equiangular":
            raise SceneError('grid.map = "equiangular" cannot stretch the cube; the stretched cube is "element_local"')
        c, lat, lon = grid["stretch_factor"], grid.get("target_lat", 90.0), grid.get("target_lon", 0.0)
        if not c >= 1:
            raise SceneError(f"grid.stretch_factor must be >= 1 (got {c!r})")
        if not -90 <= lat <= 90:
            raise SceneError(f"grid.target_lat must be in [-90, 90] degrees (got {lat!r})")
        return {"map": "element_local", "stretch_factor": c, "target_lat": lat, "target_lon": lon}
    return {"map": "element_local"} if chosen == "element_local" else None


class Spacing(NamedTuple):
    """``resolve_spacing``'s answer: the run's node spacing over the scene file's, ``mean`` (on
    the grid alone; it scales ν) and ``smallest`` (the explicit limit, times ``scale``; it scales
    dt); ``scale`` the planet's radius over the scene file's (1 where that does not apply), and
    ``radii`` (m) the planet's and the scene file's (None with a dt set by ``-s time.dt``)."""

    mean: float
    smallest: float
    scale: float
    radii: tuple


class ResolvedCase(NamedTuple):
    """``resolve_case``'s answer: the case's name, its parameters (the [case] table less name,
    initialization and reference), the start's method ("none" or "dfi"), the reference file's
    absolute path or None, the ``Case`` built on the planet, and the notes for the run's header."""

    name: str
    params: dict
    method: str
    reference: str | None
    case: Case
    notes: tuple


def read_scene(path: Path, overrides: dict) -> tuple[dict, float | None, str | None, dict]:
    """(the tables of the scene file ``path`` with ``overrides`` applied (``_apply_overrides``),
    their keys and types checked (``_SCHEMA``); the file's own radius (m): that of its [planet]
    before the overrides, for which its dt and ν are, None with an override of time.dt; the
    file's own case name, None without one; the file's own [grid] before the overrides, for
    which its dt and ν are, its types checked, {} without one). Raises ``SceneError``: a file
    that cannot be read or is not TOML, an unknown key, a value of the wrong type, a bad override."""
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"malformed TOML in {path}: {err}") from None
    except OSError as err:
        raise SceneError(f"cannot read scene {path}: {err.strerror}") from None
    table = raw.get("planet", {})
    file_radius = table.get("radius", EARTH.a) if isinstance(table, dict) and "time.dt" not in overrides else None
    file_case = raw.get("case", {}).get("name") if isinstance(raw.get("case"), dict) else None
    file_grid = _validate({"grid": raw.get("grid", {})})["grid"]
    _apply_overrides(raw, overrides)
    return _validate(raw), file_radius, file_case, file_grid


def resolve_planet(table: dict | None) -> Planet:
    """The [planet] table's ``Planet`` (radius, omega, gravity; Williamson's Earth's by default).
    Raises ``SceneError`` naming the key (``Planet.from_table``)."""
    try:
        return Planet.from_table(table)
    except ValueError as err:
        raise SceneError(str(err)) from None


def resolve_case(table: dict, planet: Planet, scene_path: Path) -> ResolvedCase:
    """The [case] table resolved on ``planet``: a ``case.path`` (the "file" case) relative to the
    current folder, else to ``scene_path``'s folder; a ``case.reference`` located and checked
    (``_reference``); a note where the case's bundled reference is not used (another planet).
    Raises ``SceneError`` naming the key: no ``name``, an unknown initialization, case or
    parameter (``cases.make_case``), a reference on another planet than Williamson's Earth."""
    params = dict(table)
    if "name" not in params:
        raise SceneError("case.name is missing")
    name = params.pop("name")
    method = params.pop("initialization", "none")
    if method not in METHODS:
        raise SceneError(f"case.initialization must be one of {', '.join(METHODS)} (got {method!r})")
    reference = params.pop("reference", None)
    if name == "file" and isinstance(params.get("path"), str):
        given = Path(params["path"]).expanduser()
        beside = scene_path.parent / given
        params["path"] = str((beside if not given.exists() and beside.exists() else given).absolute())
    try:
        case = make_case(name, params, planet, SCENE_CASES)
    except ValueError as err:
        raise SceneError(str(err)) from None
    notes = ()
    if reference is not None:
        if planet != EARTH:
            raise SceneError(
                f"case.reference = {reference!r}: the spectral references are of Williamson's Earth, "
                f"not of this scene's planet ({_planet_text(planet)}); drop case.reference or [planet]"
            )
        reference = _reference(reference, name, case)
    elif planet != EARTH and case.reference_file is not None:
        notes = (
            f"not scored against the {case.reference_file} reference: it is of Williamson's Earth, "
            f"not of this planet ({_planet_text(planet)})",
        )
    return ResolvedCase(name, params, method, reference, case, notes)


def resolve_terms(terms: list | None, case: Case, case_name: str) -> tuple:
    """The ``terms`` list as a tuple (``model.shallow_water.TERMS``). Raises ``SceneError``: none,
    an unknown or repeated term, one the case needs missing (``Case.required_terms``), forcing
    for a case without one."""
    if not terms:
        raise SceneError("terms is missing or empty")
    for i, t in enumerate(terms):
        if t not in TERMS:
            raise SceneError(f"unknown term {t!r} (known: {', '.join(TERMS)})")
        if t in terms[:i]:
            raise SceneError(f"term {t!r} is listed twice in terms")
    missing = [t for t in TERMS if t in case.required_terms and t not in terms]
    if missing:
        raise SceneError(f"case {case_name} needs the term(s) {', '.join(missing)} (terms = {terms})")
    if "forcing" in terms and case.forcing() is None:
        raise SceneError(f"case {case_name} has no forcing: drop the term 'forcing'")
    return tuple(terms)


def resolve_initialization(method: str, dfi: dict, case: Case, case_name: str) -> dict | None:
    """``Scene.initialization`` of ``case.initialization`` and the [dfi] table: None for "none",
    {"method": "dfi", "span_hours": ..., "cutoff_hours": ...} (``initialization.DigitalFilter``).
    Raises ``SceneError``: a digital filter on a case with an exact solution, or a bad [dfi]."""
    if method != "dfi":
        return None
    if case.exact_solution:
        raise SceneError(
            f'case.initialization = "dfi" would spoil case {case_name}\'s exact solution (its errors are '
            "measured against it); use it on cases without one (tc5_mountain, tc6_rossby_haurwitz, galewsky)"
        )
    try:
        filt = DigitalFilter(**dfi)
    except ValueError as err:
        raise SceneError(str(err)) from None
    return {"method": "dfi", **dataclasses.asdict(filt)}


def _table_grid(grid: dict, scene_path: Path) -> SceneGrid:
    """The grid a [grid] table names (``_grid_record`` for the mesh's keys; ne defaults to 16, 0
    with a mesh file, np to 4). Raises ``SceneError``: ne not 0 with a mesh file."""
    record = _grid_record(grid, scene_path)
    on_file = record is not None and "file" in record
    ne, np = grid.get("ne", 0 if on_file else 16), grid.get("np", 4)
    if on_file and ne != 0:
        raise SceneError(f"grid.ne must be 0 with grid.mesh_file (HOMME's ne = 0: the file's elements; got {ne})")
    return SceneGrid(ne, np, record)


def resolve_grid(
    table: dict | None, scene_path: Path, ne=None, np_=None, mesh=None, file_table: dict | None = None
) -> tuple[SceneGrid, SceneGrid, tuple]:
    """(the scene file's grid, the run's grid, notes) of the [grid] table (None: absent; the
    overrides applied) and ``load_scene``'s ``ne``, ``np_`` and ``mesh`` (an Exodus II file
    replacing the scene's grid, through the table's ``map`` where it names one). The scene file's grid is that of ``file_table``, the file's own
    [grid] before the overrides ({} if it has none; None: ``table``): its dt and ν are for it, so
    every way of choosing the run's mesh (``-s grid.*``, ``ne``, ``np_``, ``mesh``) scales them
    alike (``resolve_spacing``). The defaults are ne = 16 (0 with a mesh file) and np = 4.
    Raises ``SceneError`` naming the key: ne not 0 with a mesh file, ne < 1 on a cube, np
    outside ``NP_MIN``..``NP_MAX`` or below 3 on the element-local map (``_grid_record`` for
    the mesh's own keys)."""
    named = _table_grid(table or {}, scene_path)  # the grid of the tables as overridden
    scene_grid = named if file_table is None else _table_grid(file_table, scene_path)
    on_file = named.mesh is not None and "file" in named.mesh
    record1 = named.mesh
    if mesh is not None:
        if ne is not None:
            raise SceneError(f"ne = {ne} and mesh {mesh}: a mesh file's elements are its own (HOMME's ne = 0)")
        record1, ne = grid_spec.file_record(mesh, (table or {}).get("map", "element_local")), 0
    elif on_file and ne not in (None, 0):
        raise SceneError(f"ne = {ne} with grid.mesh_file: a mesh file's elements are its own (HOMME's ne = 0)")
    ne1 = named.ne if ne is None else ne
    np1 = named.np if np_ is None else np_
    notes = ()
    if table is None and (ne is None or np_ is None) and mesh is None:
        notes = (f"the scene has no [grid]: ne = {ne1}, np = {np1} (the defaults)",)
    if not _is_integer(ne1) or (ne1 < 1 and not (record1 is not None and "file" in record1)):
        raise SceneError(f"ne must be an integer >= 1 (got {_got(ne1)})")
    if not _is_integer(np1) or not NP_MIN <= np1 <= NP_MAX:
        raise SceneError(f"np must be an integer in {NP_MIN}..{NP_MAX} (got {_got(np1)})")
    if record1 is not None and record1["map"] == "element_local" and np1 < 3:
        raise SceneError(
            f"np must be >= 3 on {grid_spec.describe(ne1, np1, record1)}: the element-local map's area correction moves interior nodes"
        )
    return scene_grid, SceneGrid(ne1, np1, record1), notes


def resolve_spacing(scene_grid: SceneGrid, run_grid: SceneGrid, radius: float, file_radius) -> Spacing:
    """How the run's node spacing differs from the scene file's, on ``run_grid`` and a planet of
    ``radius`` (m) against ``scene_grid`` and ``file_radius`` (m; None or not a positive number:
    the scene file's dt and ν are not for a radius, scale 1). The mean spacing goes as
    1 / (``grid.spec.mean_ne`` · (np − 1)); the smallest as the first GLL interval / ne on two
    equiangular cubes, else as ``quality.smallest_dx`` of both meshes. Raises ``SceneError`` for
    a stretch that folds an element."""
    ne0, np0, record0 = scene_grid.ne, scene_grid.np, scene_grid.mesh
    ne1, np1, record1 = run_grid.ne, run_grid.np, run_grid.mesh
    scale = radius / file_radius if _is_number(file_radius) and file_radius > 0 else 1.0
    ratio = (grid_spec.mean_ne(ne0, record0) * (np0 - 1)) / (grid_spec.mean_ne(ne1, record1) * (np1 - 1))
    if record0 is None and record1 is None:
        smallest = (_first_gll_gap(np1) / ne1) / (_first_gll_gap(np0) / ne0)
    elif scene_grid == run_grid:
        smallest = 1.0
    else:
        try:
            old = smallest_dx(ne0, np0, grid_spec.build_mesh(ne0, record0))
            new = smallest_dx(ne1, np1, grid_spec.build_mesh(ne1, record1))
        except ValueError as err:  # a stretch that folds an element
            raise SceneError(f"{grid_spec.describe(ne1, np1, record1)}: {err}") from None
        smallest = new / old
    return Spacing(ratio, smallest * scale, scale, (radius, file_radius))


def resolve_output_interval(output: dict) -> tuple[float, int]:
    """(output.every_days, output.log_every_steps) of the [output] table, defaults 1 day and no
    log lines. Raises ``SceneError`` naming the key: an interval ≤ 0, a negative log interval."""
    every = output.get("every_days", 1.0)
    if not every > 0:
        raise SceneError(f"output.every_days must be > 0 (got {every})")
    log_every = output.get("log_every_steps", 0)
    if log_every < 0:
        raise SceneError(f"output.log_every_steps must be >= 0 (got {log_every}; 0: no log lines)")
    return every, log_every


def resolve_stepper_days(table: dict, stepper=None, days=None) -> tuple[str, float]:
    """(stepper, days) of the [time] table and ``load_scene``'s ``stepper`` and ``days`` (defaults
    ssprk3 and 1 day). Raises ``SceneError``: an unknown stepper, days not a number > 0."""
    name = stepper or table.get("stepper", "ssprk3")
    if name not in STEPPERS:
        raise SceneError(f"unknown stepper {name!r} (known: {', '.join(STEPPERS)})")
    days = table.get("days", 1.0) if days is None else days
    if not (_is_number(days) and math.isfinite(days) and days > 0):
        raise SceneError(f"days must be > 0 (got {_got(days)})")
    return name, days


def resolve_dt(
    scene_dt, dt, days: float, every: float, scene: str, grid: SceneGrid, spacing: Spacing
) -> tuple[float, str, tuple]:
    """(dt (s), where it comes from for messages, notes): ``dt`` as given, else the time.dt of
    scene ``scene`` (``scene_dt``) times ``spacing.smallest`` (the run's smallest node spacing
    on ``grid`` over the scene file's), shortened to divide the output interval ``every`` and
    the run of ``days`` (``_common_interval``). The schedule is checked (``_check_schedule``).
    Raises ``SceneError``: no time.dt, dt ≤ 0, a run or output interval of no whole steps."""
    if dt is not None:
        source, notes = "the dt given", ()
    elif scene_dt is None:
        raise SceneError("time.dt is missing")
    elif not scene_dt > 0:
        raise SceneError(f"time.dt must be > 0 (got {scene_dt})")
    elif spacing.smallest == 1.0:
        dt, source, notes = scene_dt, f"time.dt of scene {scene}", ()
    else:
        common = _common_interval(every, days)
        interval = common * DAY
        scaled = scene_dt * spacing.smallest
        dt = interval / max(1, math.ceil(interval / scaled - 1e-9))
        radius, file_radius = spacing.radii
        moved = spacing.scale != 1.0  # the planet's radius; file_radius is a number then
        where = grid_spec.describe(grid.ne, grid.np, grid.mesh) + (f" radius={radius:g} m" if moved else "")
        source = f"time.dt of scene {scene} scaled to {where}"
        # what the smallest node spacing changed with: the grid, the planet's radius or both
        changes = ["the smallest node spacing"] if spacing.smallest != spacing.scale else []
        if moved:
            changes.append(f"the planet's radius ({radius:g} m against the scene's {file_radius:g} m)")
        why = " and ".join(changes)
        if scaled / dt > 2:  # one line for both: "scaled to" the cut dt read as if the grid had asked for it
            if days <= every:
                what = f"the run length of {days:g} days"
            elif common == every:
                what = f"the output interval of {every:g} days"
            else:
                what = f"both the output interval of {every:g} and the run length of {days:g} days"
            notes = (
                f"warning: dt cut {scaled / dt:.3g}x (from {scaled:g} s, scaled with {why}) "
                f"to {dt:g} s to divide {what}",
            )
        else:
            notes = (f"dt scaled with {why} to {dt:g} s",)
    if not (_is_number(dt) and math.isfinite(dt) and dt > 0):
        raise SceneError(f"dt must be > 0 (got {_got(dt)})")
    _check_schedule(dt, days, every, source)
    return dt, source, notes


def resolve_stepper_options(stepper: str, table: dict, overrides: dict) -> tuple[dict, tuple]:
    """(the options of ``stepper``: its table, checked by its ``make_options``; notes). An
    override of another stepper's table is a slip: a note warns that it is not used. Raises
    ``SceneError`` naming ``stepper.key``."""
    options = dict(table)
    try:
        STEPPERS[stepper].make_options(**options)
    except ValueError as err:
        raise SceneError(f"{stepper}.{err}") from None
    # a scene file may hold tables for other steppers (--stepper picks one); an -s for one is a slip
    other = sorted(k for k in overrides if k.partition(".")[0] in STEPPERS and k.partition(".")[0] != stepper)
    if not other:
        return options, ()
    return options, (f"warning: -s {', '.join(other)}: not an option of {stepper}, the stepper that runs; not used",)


def resolve_hyperviscosity(
    table: dict, terms: tuple, grid: SceneGrid, spacing: Spacing
) -> tuple[SceneHyperviscosity, tuple]:
    """(nu, nu_div, nu_s (m⁴ s⁻¹) and subcycle; notes) of the [hyperviscosity] table on the
    run's ``grid`` and planet. Coefficients given are for the scene file's grid and planet: they
    scale as ``spacing.mean`` to ``HYPERVIS_EXPONENT`` and, keeping their damping time at the
    grid scale, as ``spacing.scale``⁴ (the radii's ratio); ``efold_hours``
    sets the others on the run's grid (``efold_nu``); without it nu_div and nu_s default to nu.
    All are 0 without the hyperviscosity term. Raises ``SceneError`` naming the key: a negative
    coefficient, efold_hours or subcycle not > 0, the term without a coefficient > 0."""
    for key in ("efold_hours", "nu", "nu_div", "nu_s"):
        if table.get(key, 0.0) < 0 or (key == "efold_hours" and key in table and table[key] == 0):
            raise SceneError(
                f"hyperviscosity.{key} must be {'> 0' if key == 'efold_hours' else '>= 0'} (got {table[key]})"
            )
    scaling = table.get("scaling")
    if scaling is not None and not 0 <= scaling <= 4:
        raise SceneError(
            f"hyperviscosity.scaling must be in 0..4 (got {scaling}): the s of nu ~ dx^s per element "
            "(HOMME's hypervis_scaling, E3SM's 3.2)"
        )
    # under the tensor, given coefficients scale as dx^s
    exponent = HYPERVIS_EXPONENT if scaling is None else scaling
    ratio, planet_factor = spacing.mean, spacing.scale**4
    given = [k for k in ("nu", "nu_div", "nu_s") if k in table]
    nus = {key: table[key] * ratio**exponent * planet_factor for key in given}
    notes = []
    if "efold_hours" in table:
        mean_ne = grid_spec.mean_ne(grid.ne, grid.mesh)
        rule = efold_nu(table["efold_hours"], mean_ne, grid.np, spacing.radii[0])
        nus = {key: nus.get(key, rule) for key in ("nu", "nu_div", "nu_s")}
        if ratio != 1.0:
            degree = round(2 * mean_ne * (grid.np - 1))
            notes.append(f"nu = {rule:.3g} m^4/s: {table['efold_hours']:g} h e-folding at degree {degree}")
    else:
        nus = {key: nus.get(key, nus.get("nu", 0.0)) for key in ("nu", "nu_div", "nu_s")}
    if "hyperviscosity" in terms and max(nus.values()) == 0:
        raise SceneError("the hyperviscosity term needs hyperviscosity.nu, nu_div, nu_s or efold_hours > 0")
    if "hyperviscosity" not in terms:
        if given or scaling is not None:
            notes.append("hyperviscosity coefficients given, but the scene's terms have no hyperviscosity: not used")
        nus = dict.fromkeys(nus, 0.0)
    elif (ratio != 1.0 or planet_factor != 1.0) and given and max(nus.values()) > 0:
        notes.append(
            f"nu scaled as dx^{exponent:g} and radius^4: nu, nu_div, nu_s = "
            f"{nus['nu']:.3g}, {nus['nu_div']:.3g}, {nus['nu_s']:.3g} m^4/s"
        )
    if scaling is not None and "hyperviscosity" in terms:
        a = spacing.radii[0]
        d_ref = math.pi * a / (4 * grid_spec.mean_ne(grid.ne, grid.mesh))  # ``grid.quality.reference_spacing``
        notes.append(
            f"tensor hyperviscosity: nu (dx / {2 * d_ref / (grid.np - 1) / 1e3:.4g} km)^{scaling:g} along each element "
            f"direction (HOMME's hypervis_scaling = {scaling:g}, nu = {nus['nu'] / (a**4 * (d_ref / a) ** scaling):.3g})"
        )
    subcycle = table.get("subcycle", 1)
    if subcycle < 1:
        raise SceneError(f"hyperviscosity.subcycle must be >= 1 (got {subcycle})")
    scaling = None if scaling is None or "hyperviscosity" not in terms else float(scaling)
    hv = SceneHyperviscosity(float(nus["nu"]), float(nus["nu_div"]), float(nus["nu_s"]), int(subcycle), scaling)
    return hv, tuple(notes)


def scene_title(case_name: str, file_case: str | None, stem: str, description: str) -> tuple[str, str]:
    """(``Scene.name``, ``Scene.description``) of the scene file ``stem`` running ``case_name``:
    its own, or for a case switched from the file's (``-s case.name=...``) names that say so, for
    the header, the run file's title and its default name."""
    if case_name == file_case:
        return stem, description
    return f"{case_name}_in_{stem}", f"case {case_name} with scene {stem}'s grid, terms and stepping"


def load_scene(
    path, *, ne=None, np_=None, dt=None, days=None, stepper=None, mesh=None, overrides: dict | None = None
) -> Scene:
    """Read, validate and resolve a scene file, applying command-line overrides.

    Each table is resolved by a function of its own, in this order (the first refusal
    wins): ``read_scene`` (the file, the overrides, keys and types), ``resolve_planet``,
    ``resolve_case``, ``resolve_terms``, ``resolve_initialization`` ([dfi]),
    ``resolve_grid``, ``resolve_spacing``, ``resolve_output_interval``,
    ``resolve_stepper_days``, ``resolve_dt``, ``resolve_output_files``,
    ``resolve_stepper_options`` and ``resolve_hyperviscosity``.

    Parameters
    ----------
    path : str or path
        A scene file (TOML) or the name of a bundled scene under ``testcases/``.
    ne, np_ : int, optional
        Elements along a cube edge and GLL points per element direction. When the grid
        is overridden and ``dt`` is not, dt scales with the smallest node spacing
        (first GLL interval / ne) and is shortened to divide the output interval (or
        the run, if shorter; a note warns when that cuts dt by more than 2×); ν scales
        as the mean spacing 1/(ne·(np−1)) to the power 3.2 (HOMME's rule).
    dt : float, optional
        Time step (s).
    days : float, optional
        Run length (days).
    stepper : str, optional
        Time stepper (``steppers.STEPPERS``).
    mesh : str or path, optional
        An Exodus II file (relative to the current folder) to run on instead of the
        scene's grid (``--mesh``; ne = 0); where the mesh differs from the scene file's own
        (as do ``-s grid.*`` overrides alike), dt scales with the smallest ``dx_short`` of
        the two (``quality.smallest_dx``) and ν with the mean spacing (``grid.spec.mean_ne``).
    overrides : dict, optional
        ``{"section.key": value}`` set in the file's values before they are validated
        (``-s hyperviscosity.nu=5e14``), so they are checked like the file.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        An unreadable file or malformed TOML; an unknown or invalid value (the message
        names the field); duplicate terms, or terms that omit what the case needs
        (``Case.required_terms``).
    """
    path = resolve_path(str(path))
    overrides = overrides or {}
    s, file_radius, file_case, file_grid = read_scene(path, overrides)
    planet = resolve_planet(s.get("planet"))
    case = resolve_case(s.get("case", {}), planet, path)
    terms = resolve_terms(s.get("terms"), case.case, case.name)
    initialization = resolve_initialization(case.method, s.get("dfi", {}), case.case, case.name)
    scene_grid, grid, grid_notes = resolve_grid(s.get("grid"), path, ne, np_, mesh, file_grid)
    spacing = resolve_spacing(scene_grid, grid, planet.a, file_radius)
    output, time = s.get("output", {}), s.get("time", {})
    every, log_every = resolve_output_interval(output)
    stepper, days = resolve_stepper_days(time, stepper, days)
    dt, dt_source, dt_notes = resolve_dt(time.get("dt"), dt, days, every, path.stem, grid, spacing)
    output_fields, streams = resolve_output_files(output, dt, days, dt_source)
    options, stepper_notes = resolve_stepper_options(stepper, s.get(stepper, {}), overrides)
    hv, hv_notes = resolve_hyperviscosity(s.get("hyperviscosity", {}), terms, grid, spacing)
    name, description = scene_title(case.name, file_case, path.stem, s.get("description", ""))
    return Scene(
        name=name,
        description=description,
        case=case.name,
        case_params=case.params,
        terms=terms,
        ne=int(grid.ne),
        np=int(grid.np),
        stepper=stepper,
        stepper_options=options,
        dt=float(dt),
        days=float(days),
        output_every_days=float(every),
        nu=hv.nu,
        hypervis_subcycle=hv.subcycle,
        nu_div=hv.nu_div,
        nu_s=hv.nu_s,
        notes=case.notes + grid_notes + dt_notes + stepper_notes + hv_notes,
        initialization=initialization,
        reference=case.reference,
        log_every_steps=int(log_every),
        planet=planet.as_table(),
        output_fields=output_fields,
        output_streams=streams,
        mesh=grid.mesh,
        output_cells=output.get("cells", True),
        hypervis_scaling=hv.scaling,
    )


_STREAM_KEYS = ("name", "every_days", "fields")


def _fields(value, key: str) -> tuple:
    """A list of run-file fields, checked (``SceneError``); () for all of them."""
    if value is None:
        return ()
    if not isinstance(value, list) or not value or not all(isinstance(f, str) for f in value):
        raise SceneError(
            f"{key} must be a non-empty list of field names from {', '.join(OUTPUT_FIELDS)} (got {value!r})"
        )
    for f in value:
        if f not in OUTPUT_FIELDS:
            raise SceneError(
                f"{key}: unknown field {f!r} (known: {', '.join(OUTPUT_FIELDS)}; hs, lat, lon, area are always written)"
            )
    return tuple(f for f in OUTPUT_FIELDS if f in value)  # the file's order


def resolve_output_files(output: dict, dt: float, days: float, dt_source: str) -> tuple[tuple, tuple]:
    """([output] fields, [[output.streams]]) checked: field names, stream names (a
    file-name suffix, distinct, not "restart") and intervals of whole steps."""
    fields = _fields(output.get("fields"), "output.fields")
    streams, names = [], set()
    for i, st in enumerate(output.get("streams", [])):
        where = f"output.streams[{i}]"
        if not isinstance(st, dict):
            raise SceneError(f"{where} must be a table ([[output.streams]] with name, every_days, fields)")
        unknown = set(st) - set(_STREAM_KEYS)
        if unknown:
            raise SceneError(f"unknown key {where}.{sorted(unknown)[0]} (known: {', '.join(_STREAM_KEYS)})")
        name = st.get("name")
        if not (isinstance(name, str) and re.fullmatch(r"[A-Za-z0-9_-]+", name)) or name == "restart" or name in names:
            raise SceneError(
                f"{where}.name must be a distinct file-name suffix of letters, digits, _ or - other than "
                f"restart (got {name!r}): the stream's file is RUN.{name}.nc"
            )
        names.add(name)
        every = _check_type(f"{where}.every_days", st.get("every_days"), float) if "every_days" in st else None
        if every is None or not every > 0:
            raise SceneError(f"{where}.every_days must be > 0 (got {every})")
        if days > every and not _whole_steps(dt, every):
            raise _not_whole_steps(f"the output interval {where}.every_days", every, dt, dt_source)
        streams.append(
            {
                "name": name,
                "every_days": every,
                "fields": _fields(st.get("fields", list(OUTPUT_FIELDS)), f"{where}.fields"),
            }
        )
    return fields, tuple(streams)


# ``load_scene``'s own keywords among the overrides, by their command-line names (``np`` is its ``np_``)
LOAD_KEYWORDS = {"ne": "ne", "np": "np_", "dt": "dt", "days": "days", "stepper": "stepper", "mesh": "mesh"}


def resolve_scene(scene, overrides: dict) -> tuple[Scene, tuple]:
    """(Scene, its input files) of ``swe_sphere.run``'s and ``Simulation``'s
    ``scene`` and ``overrides``: a ``Scene`` as it is (no overrides: change it with
    ``dataclasses.replace``), else a scene file or bundled name loaded with the
    overrides as on the command line (``ne``, ``np``, ``dt``, ``days``, ``stepper``, ``mesh``
    and tables such as ``hyperviscosity={"nu": 5e14}`` or values ``terms=[...]``).
    The inputs are the scene file (outputs must not replace it). Raises ``SceneError``."""
    if isinstance(scene, Scene):
        if overrides:
            raise SceneError("overrides apply to a scene file; change a Scene with dataclasses.replace")
        return scene, ()
    overrides = dict(overrides)
    kw = {name: overrides.pop(k) for k, name in LOAD_KEYWORDS.items() if k in overrides}
    flat = {}
    for key, value in overrides.items():
        if isinstance(value, dict):
            flat.update({f"{key}.{k}": v for k, v in value.items()})
        else:
            flat[key] = value
    path = resolve_path(str(scene))
    return load_scene(path, **kw, overrides=flat), (path,)


def _planet_text(planet: Planet) -> str:
    """A planet for a message: "radius 637122 m, omega 0.0007292 1/s, gravity 9.80616 m/s^2"."""
    return f"radius {planet.a:g} m, omega {planet.omega:g} 1/s, gravity {planet.g:g} m/s^2"
