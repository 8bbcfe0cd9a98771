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
    [ensemble]        members = 8, perturbation = 1.0 (m of noise in h), seed = 0, degrees = [1, 20]
                      (the noise's spherical-harmonic band; none: white noise): the
                      scene's ensemble (``swe-sphere run``, ``swe_sphere.Ensemble``'s defaults)
    [grid]            ne = 30, np = 4, and the mesh: the uniform cube of ne (the default),
                      map = "equiangular" | "element_local" (the cube's map: HOMME's
                      cubed_sphere_map 0 or 2), stretch_factor = 2.5, target_lat = 40.0,
                      target_lon = 270.0 (degrees: the Schmidt-stretched cube of ne, FV3's
                      do_schmidt; element-local), cube = "equiangular" | "equidistant" (the
                      cube's element corners equally spaced in angle, the default, or on the
                      cube's faces as pySEs's grid; element-local unless map says), or
                      mesh_file = "x.g" (an Exodus II mesh,
                      relative to the scene file or absolute, or to the working folder when
                      given by -s grid.mesh_file; ne = 0 as HOMME's; element-local,
                      or with map = "equiangular" each element in its cube face);
                      ``mesh.records`` records the choice in ``Scene.mesh``
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
                      nu, nu_div, nu_s then scale as dx^s between grids; absent: constant nu),
                      every = 1 (k: the ∇⁴ over k dt after every k-th step, fixed dt and a
                      one-step stepper only: cheaper where its limit is well above dt)
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
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from ..cases.library import make_case
from ..cases.reference import reference_path
from ..core.arguments import instance_argument, mapping_argument
from ..core.clock import Clock
from ..core.constants import DAY, EARTH, Planet
from ..core.errors import SceneError
from ..io.initial_state import SCENE_CASES
from ..mesh.records import MeshRecord, from_json, with_ne
from ..steppers.initialization import DigitalFilter
from .control import cfl_notes, is_controlled, resolve_control
from .paths import list_scenes, resolve_path, scene_dir
from .resolve import (
    DT_NOTES,
    HYPERVIS_EXPONENT,
    check_superseded,
    efold_nu,
    resolve_case,
    resolve_dt,
    resolve_ensemble,
    resolve_every,
    resolve_grid,
    resolve_hyperviscosity,
    resolve_initialization,
    resolve_output_files,
    resolve_output_interval,
    resolve_planet,
    resolve_spacing,
    resolve_stepper_days,
    resolve_stepper_options,
    resolve_terms,
    scene_title,
)
from .schema import SCHEMA, SceneControl, SceneGrid, SceneHyperviscosity, SceneOutput, SceneTime, is_number, read_scene

# the names the package, its tests and benchmarks import from here, defined in the config's other modules
__all__ = [
    "DT_NOTES",
    "HYPERVIS_EXPONENT",
    "SCHEMA",
    "LOAD_KEYWORDS",
    "Scene",
    "SceneError",
    "SceneGrid",
    "SceneHyperviscosity",
    "SceneOutput",
    "SceneTime",
    "efold_nu",
    "list_scenes",
    "load_scene",
    "resolve_path",
    "resolve_scene",
    "scene_dir",
    "scene_from_dict",
    "with_days",
]


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
    hypervis_every : int
        k: the ∇⁴ over kΔt after every k-th step ([hyperviscosity] every; 1: every step).
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
    mesh : CubeMesh, StretchedCube, MeshFile or None
        The mesh ([grid] ``map``, ``stretch_factor``/``target_lat``/``target_lon``, ``cube``,
        ``mesh_file``) as a ``mesh.records`` record; None: the equiangular cube of ne.
    output_cells : bool
        [output] cells: the run files hold the control volumes (``io.dual``).
    control : SceneControl or None
        [time] control: the step chosen step to step by an error or CFL controller, dt the
        first (``schema.SceneControl``); None: a fixed dt.
    ensemble : dict or None
        [ensemble] (``resolve.resolve_ensemble``): {"members", "perturbation", "seed"[, "degrees"]}; None: a single run.
    dt_source : str
        Where ``dt`` comes from, for messages ("the scene's", "the dt given", ...): not part
        of the scene's identity (left out of comparisons and of ``as_dict``).
    own_dt, own_planet, own_days : float, dict, float or None
        What the scene file as it is would take on this grid and length: the dt it would
        choose itself (None: none that fits), its planet and its days (None: the file does not
        load alone); for default file names (``cli.run``), not part of the record.
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
    # the mesh ([grid] map, stretch_factor, mesh_file): a ``mesh.records`` record; None: the equiangular cube of ne
    mesh: MeshRecord | None = None
    output_cells: bool = True  # [output] cells: the run files hold the control volumes (``dual``)
    hypervis_scaling: float | None = None  # [hyperviscosity] scaling: the tensor ∇⁴'s s; None: constant ν
    hypervis_every: int = 1  # [hyperviscosity] every: the ∇⁴ over kΔt after every k-th step
    control: SceneControl | None = None  # [time] control: None, a fixed dt
    ensemble: dict | None = None  # [ensemble]: members, perturbation (m), seed; None: one run
    # where dt comes from, for the refusals (``Clock.source``); not part of the scene's record (``as_dict``)
    dt_source: str = field(default="the scene's", compare=False)
    # what a run of the scene file as it is would take, for default file names (``cli.run``); not
    # part of the record either: the dt it would choose itself on this grid and length (None: none
    # that fits), and the file's own planet and days (None: the file does not load alone)
    own_dt: float | None = field(default=None, compare=False)
    own_planet: dict | None = field(default=None, compare=False)
    own_days: float | None = field(default=None, compare=False)

    def __post_init__(self):
        # a cube's record follows ne (``dataclasses.replace(scene, ne=...)``), as its JSON does
        object.__setattr__(self, "mesh", with_ne(self.mesh, self.ne))

    # the nested view: the flat fields grouped by their table, read-only (the flat fields stay
    # what the rest of the package reads)
    @property
    def grid(self) -> SceneGrid:
        """ne, np and the mesh ([grid])."""
        return SceneGrid(self.ne, self.np, self.mesh)

    @property
    def time(self) -> SceneTime:
        """The stepper, its options, dt and days ([time] and the stepper's table)."""
        return SceneTime(self.stepper, self.stepper_options, self.dt, self.days, self.control)

    @property
    def hyperviscosity(self) -> SceneHyperviscosity:
        """nu, nu_div, nu_s and the subcycles ([hyperviscosity])."""
        return SceneHyperviscosity(
            self.nu, self.nu_div, self.nu_s, self.hypervis_subcycle, self.hypervis_scaling, self.hypervis_every
        )

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
    def clock(self) -> Clock:
        """The run's clock (``core.clock``): dt, ``start_day``, ``days`` and where dt comes from."""
        return Clock(self.dt, self.start_day, self.days, self.dt_source, self.control is not None)

    @property
    def nsteps(self) -> int:
        """The steps from ``start_day`` to ``days`` (``Clock.nsteps``)."""
        return self.clock.nsteps

    def day(self, step: int) -> float:
        """The model time of ``step`` in days (``Clock.day``: exact from the days as written,
        so ``ds.h.sel(time=3)`` finds the outputs)."""
        return self.clock.day(step)

    def make_case(self):
        return make_case(self.case, self.case_params, Planet.from_table(self.planet), SCENE_CASES)

    def make_mesh(self):
        """The grid's ``Mesh`` for ``CubedSphere(ne, np, mesh=...)``, None for the equiangular
        cube (the record's ``build``: ``SceneError`` for a mesh file gone or changed)."""
        return self.grid.record.build()

    @property
    def nelem(self) -> int:
        """Elements of the grid: 6·ne² on a cube, a mesh file's own count."""
        return self.grid.record.nelem

    @property
    def grid_text(self) -> str:
        """The grid in words: ``ne=4 np=4``, ``mesh x.g np=4``... (the record's ``description``)."""
        return self.grid.record.description(self.np)

    @property
    def grid_label(self) -> str:
        """The grid's part of a default file name: ``ne4``, ``ne4map2``, ``ne4c2.5``, a mesh
        file's stem (the record's ``label``)."""
        return self.grid.record.label

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
        for key in ("dt_source", "own_dt", "own_planet", "own_days"):
            del d[key]
        d["mesh"] = None if self.mesh is None else self.mesh.as_json()
        for key in ("output_fields", "output_streams", "mesh"):
            if not d[key]:
                del d[key]
        if d["output_cells"]:  # the default
            del d["output_cells"]
        for key in ("hypervis_scaling", "control", "ensemble"):
            if d[key] is None:
                del d[key]
        if d["hypervis_every"] == 1:  # the default: a scene's dict as before the key
            del d["hypervis_every"]
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
            "control": None if d.get("control") is None else SceneControl(**d["control"]),
            "mesh": from_json(d["ne"], d.get("mesh")),
        }
    )


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
    Clock(scene.dt, start, scene.days, dt_source, scene.control is not None).check(
        {"the output interval (output.every_days)": scene.output_every_days}
    )
    return scene


def load_scene(
    path,
    *,
    ne=None,
    np_=None,
    dt=None,
    days=None,
    stepper=None,
    mesh=None,
    overrides: dict | None = None,
    restart_every: float | None = None,
    np=None,
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
    ne, np_, np : int, optional
        Elements along a cube edge and GLL points per element direction (``np_``, or ``np`` as
        ``swe_sphere.run``, ``Simulation`` and ``Ensemble`` take it; not both). When the grid
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
        the two (``quality.smallest_dx``) and ν with the mean spacing (the record's ``mean_ne``).
    overrides : dict, optional
        ``{"section.key": value}`` set in the file's values before they are validated
        (``-s hyperviscosity.nu=5e14``), so they are checked like the file; a table's values
        as a dict (``{"time": {"control": "error"}}``) are merged into the file's table, as
        ``swe_sphere.run(time={...})`` merges them, not put in its place.
    restart_every : float, optional
        The run's restart interval (days, ``--restart-every``): a dt the scene scales itself is
        shortened to divide it too (a note says so); checked by the run, not here.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        A ``path`` that is not a str or path, ``overrides`` that is not a mapping with str
        keys; an unreadable file or malformed TOML; an unknown or invalid value (the message
        names the field); duplicate terms, or terms that omit what the case needs
        (``Case.required_terms``).
    """
    instance_argument(
        "path", path, (str, os.PathLike), "a scene file's path or a bundled scene's name (str)", SceneError
    )
    overrides = {} if overrides is None else flat_overrides(mapping_argument("overrides", overrides, error=SceneError))
    if np is not None:
        if np_ is not None:
            raise SceneError(f"np = {np} and np_ = {np_}: give one of them (np_ is np's other name)")
        np_ = np
    return _resolve(resolve_path(str(path)), ne, np_, dt, days, stepper, mesh, overrides, restart_every)


def _resolve(path: Path, ne, np_, dt, days, stepper, mesh, overrides: dict, restart_every=None) -> Scene:
    """``load_scene``'s work on the scene file ``path``: its tables resolved in order."""
    s, file_radius, file_case, file_grid, own = read_scene(path, overrides)
    check_superseded(overrides, {"ne": ne, "np_": np_, "dt": dt, "days": days, "stepper": stepper})
    planet = resolve_planet(s.get("planet"))
    case = resolve_case(s.get("case", {}), planet, path)
    terms = resolve_terms(s.get("terms"), case.case, case.name)
    initialization = resolve_initialization(case.method, s.get("dfi", {}), case.case, case.name)
    scene_grid, grid, grid_notes = resolve_grid(s.get("grid"), path, ne, np_, mesh, file_grid)
    spacing = resolve_spacing(scene_grid, grid, planet.a, file_radius)
    output, time = s.get("output", {}), s.get("time", {})
    every, log_every = resolve_output_interval(output)
    stepper, days = resolve_stepper_days(time, stepper, days)
    controlled = is_controlled(time)
    streams = tuple(  # the streams' intervals, for a scaled dt to divide (their values checked with them)
        st["every_days"]
        for st in output.get("streams", [])
        if isinstance(st, dict) and is_number(st.get("every_days")) and st["every_days"] > 0
    )
    restart = restart_every if is_number(restart_every) and restart_every > 0 and not controlled else None
    dt, dt_source, dt_notes = resolve_dt(
        time.get("dt"), dt, days, every, path.stem, grid, spacing, controlled, streams, restart
    )
    own_dt = dt
    if dt_source == "the dt given" or "time.dt" in overrides:  # the dt it would choose itself, all else as given
        try:
            own_spacing = resolve_spacing(scene_grid, grid, planet.a, own.get("planet", {}).get("radius", EARTH.a))
            own_dt = resolve_dt(
                own.get("time", {}).get("dt"), None, days, every, path.stem, grid, own_spacing, controlled, streams
            )[0]
        except SceneError:  # none that fits the output interval
            own_dt = None
    own_planet, own_days = _own_planet_days(own)
    output_fields, streams = resolve_output_files(output, dt, days, dt_source, controlled)
    options, stepper_notes = resolve_stepper_options(stepper, s.get(stepper, {}), overrides)
    control = resolve_control(time, stepper, options, dt)
    hv, hv_notes = resolve_hyperviscosity(s.get("hyperviscosity", {}), terms, grid, spacing)
    steps = (round(every * DAY / dt), round(days * DAY / dt))  # an output interval's and the run's
    k, every_notes = resolve_every(s.get("hyperviscosity", {}), hv, grid, spacing, dt, steps, stepper, controlled)
    hv = dataclasses.replace(hv, every=k)
    name, description = scene_title(case.name, file_case, path.stem, s.get("description", ""))
    given = [f"{k} = {v!r}" for k, v in overrides.items() if k.startswith("case.") and k[5:] in case.params]
    if given and name == path.stem:  # the file's description is of its own values: the header says what runs
        description = f"{description}; run with {', '.join(given)}"
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
        notes=case.notes + grid_notes + dt_notes + stepper_notes + cfl_notes(control, stepper) + hv_notes + every_notes,
        initialization=initialization,
        reference=case.reference,
        log_every_steps=int(log_every),
        planet=planet.as_table(),
        output_fields=output_fields,
        output_streams=streams,
        mesh=grid.mesh,
        output_cells=output.get("cells", True),
        hypervis_scaling=hv.scaling,
        hypervis_every=hv.every,
        control=control,
        ensemble=resolve_ensemble(s.get("ensemble")),
        dt_source=dt_source,
        own_dt=own_dt,
        own_planet=own_planet,
        own_days=own_days,
    )


def _own_planet_days(own: dict) -> tuple[dict | None, float | None]:
    """(planet, days) of the scene file's own checked tables ``own`` (``read_scene``); (None,
    None) where it has none of its own ({}: it checks only with the overrides)."""
    if not own:
        return None, None
    try:
        return resolve_planet(own.get("planet")).as_table(), float(
            resolve_stepper_days(own.get("time", {}), None, None)[1]
        )
    except SceneError:
        return None, None


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
    instance_argument(
        "scene", scene, (str, os.PathLike), "a Scene, a scene file's path or a bundled scene's name", SceneError
    )
    overrides = dict(overrides)
    kw = {name: overrides.pop(k) for k, name in LOAD_KEYWORDS.items() if k in overrides}
    path = resolve_path(str(scene))
    return load_scene(path, **kw, overrides=overrides), (path,)


def flat_overrides(overrides: dict) -> dict:
    """``overrides`` with each table given as a dict (``{"time": {"control": "error"}}``) spread
    into its ``"section.key"`` values (``{"time.control": "error"}``): set into the file's table
    one by one, its other keys kept."""
    flat = {}
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(key, str) and "." not in key:
            flat.update({f"{key}.{k}": v for k, v in value.items()})
        else:
            flat[key] = value
    return flat
