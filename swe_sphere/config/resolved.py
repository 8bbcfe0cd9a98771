"""The resolved scene: ``Scene`` (what ``config.scene.load_scene`` returns, frozen; its parts
``grid``, ``time``, ``hyperviscosity``, ``output`` and the run's clock), its dict form
(``Scene.as_dict``, ``scene_from_dict``: what run and restart files hold) and ``with_days``
(the same scene run to another day)."""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

from ..cases.library import make_case
from ..cases.reference import reference_path
from ..cases.tracers import TRACER_FIELDS
from ..core.clock import Clock
from ..core.constants import EARTH, Planet
from ..core.errors import SceneError
from ..io.initial_state import SCENE_CASES, read_tracer_file
from ..mesh.records import MeshRecord, from_json, with_ne
from ..steppers.initialization import DigitalFilter
from .schema import SceneControl, SceneGrid, SceneHyperviscosity, SceneOutput, SceneTime


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
        The terms integrated (``model.arguments.TERMS``); an absent term costs nothing.
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
    element_filter : tuple or None
        (mu, p_bv, s_bv) of the Boyd–Vandeven element filter applied with the ∇⁴ ([filter];
        HOMME's ``filter_mu``, ``p_bv``, ``s_bv``); None: no filter.
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
    precision : str
        [numerics] precision: "float64" (the default) or "float32", the RHS tendency's type
        (``ShallowWater.from_scene`` reads it); the state and its accumulation stay float64; or
        "float32_state", a step's state and stages float32 too (``model.precision``).
    compensated : bool
        [numerics] compensated: under "float32_state", whether the run keeps the float32 state
        from step to step (False, the default: ``model.held``) or holds a float64 state between
        steps, each step's float32 increment added to it in float64 (True); unread otherwise.
    mass_fixer : bool
        [numerics] mass_fixer: under "float32_state", whether a step's end puts back the mass
        its start held (True, the default: ``model.mass_fixer``); unread otherwise.
    tracers : tuple of (str, str)
        [tracers]: each passive tracer's name and its initial field, bundled
        (``cases.tracers.TRACER_FIELDS``) or a variable of ``tracer_file``, carried as hq in the
        state's rows 3..; (): none (``tracer_fields``: the fields as functions).
    tracer_file : str or None
        [tracers] file: the netCDF file (absolute path) of the initial fields that are not
        bundled (``io.initial_state.read_tracer_file``); None: none.
    tracer_limiter : str
        [tracers] limiter: "none" or "optimization", the tracers' shape-preserving limiter
        (``model.limiter``: Guba et al. 2014, HOMME's limiter 8).
    tracer_hyperviscosity : bool
        [tracers] hyperviscosity: the tracers take the depth's ∇⁴ (ν_s ∇⁴ of q(h + hs); True, the
        default) or none (then q = 1 is no longer kept at 1 where the depth is damped).
    tracer_stage_hyperviscosity : bool
        [tracers] stage_hyperviscosity: the depth's and the tracers' ν_s ∇⁴ inside every stage's
        right-hand side, limited with the stage (True: HOMME's ``advance_nonstag_rk``;
        ``ShallowWater``'s ``stage_hyperviscosity``), or split after each step (False, the default).
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
    element_filter: tuple | None = None  # [filter]: (mu, p_bv, s_bv); None: none
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
    precision: str = "float64"  # [numerics] precision: the RHS tendency's type (and "float32_state": the state's)
    compensated: bool = False  # [numerics] compensated: the float32 state's increments added to a float64 one
    mass_fixer: bool = True  # [numerics] mass_fixer: the float32 state's mass put back each step
    tracers: tuple = ()  # [tracers]: ((name, initial field), ...); (): none
    tracer_file: str | None = None  # [tracers] file: the netCDF file of the fields not bundled (absolute)
    tracer_limiter: str = "none"  # [tracers] limiter: "none" or "optimization" (Guba et al. 2014)
    tracer_hyperviscosity: bool = True  # [tracers] hyperviscosity: the depth's ∇⁴ on the tracers
    tracer_stage_hyperviscosity: bool = False  # [tracers] stage_hyperviscosity: ν_s ∇⁴ in every stage

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
        case = make_case(self.case, self.case_params, Planet.from_table(self.planet), SCENE_CASES)
        if hasattr(case, "grid_degree"):  # a reanalysis: its default truncation is what this grid resolves
            case = dataclasses.replace(case, grid_degree=self.grid_degree)
        return case

    def tracer_fields(self) -> tuple:
        """Each of ``tracers``' initial fields as a function of (lat, lon) (rad, any shape) giving
        q of that shape: the bundled one, or ``tracer_file``'s variable (read once: ``SceneError``
        for nodes that are not the file's)."""
        from_file = tuple(dict.fromkeys(f for _, f in self.tracers if f not in TRACER_FIELDS))
        state = read_tracer_file(self.tracer_file, from_file) if from_file else None
        return tuple(TRACER_FIELDS[f] if f in TRACER_FIELDS else functools.partial(state, f) for _, f in self.tracers)

    @property
    def grid_degree(self) -> float:
        """The highest spherical-harmonic degree the grid resolves, about: 2 ne (np - 1), half its
        4 ne (np - 1) nodes along the equator (a mesh's ne: that of the cube of as many elements,
        the record's ``mean_ne``)."""
        return 2 * self.grid.record.mean_ne * (self.np - 1)

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
        for key in ("hypervis_scaling", "control", "ensemble", "element_filter"):
            if d[key] is None:
                del d[key]
        if d["hypervis_every"] == 1:  # the default: a scene's dict as before the key
            del d["hypervis_every"]
        if d["precision"] != "float32_state":  # unread; written under it, either way (``scene_from_dict``)
            del d["compensated"]
        if d["precision"] == "float64":  # the default, likewise
            del d["precision"]
        if d["mass_fixer"]:  # the default, likewise
            del d["mass_fixer"]
        if not d["tracers"]:  # none: a scene's dict as before the key
            del d["tracers"]
        if d["tracer_file"] is None:  # the default, likewise
            del d["tracer_file"]
        if d["tracer_limiter"] == "none":  # the default, likewise
            del d["tracer_limiter"]
        if d["tracer_hyperviscosity"]:  # the default, likewise
            del d["tracer_hyperviscosity"]
        if not d["tracer_stage_hyperviscosity"]:  # the default, likewise
            del d["tracer_stage_hyperviscosity"]
        return d


def scene_from_dict(d: dict) -> Scene:
    """A Scene from ``Scene.as_dict()`` (e.g. read back from JSON).

    A key this version added with a default (e.g. ``initialization``) may be
    missing: its default is the behaviour of the version that wrote ``d``, so a
    restart file from before the key existed still continues bitwise. ValueError
    for an unknown key or a missing key without a default. A "float32_state" record without
    ``compensated`` was written when the compensated state was that precision's default: True.
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
    if d.get("precision") == "float32_state":
        d = {"compensated": True, **d}
    return Scene(
        **{
            **d,
            "terms": tuple(d["terms"]),
            "notes": tuple(d.get("notes", ())),
            "output_fields": tuple(d.get("output_fields", ())),
            "output_streams": streams,
            "control": None if d.get("control") is None else SceneControl(**d["control"]),
            "element_filter": None if d.get("element_filter") is None else tuple(d["element_filter"]),
            "tracers": tuple(tuple(t) for t in d.get("tracers", ())),
            "mesh": from_json(d["ne"], d.get("mesh")),
        }
    )


def run_end(days, start: float = 0.0) -> float:
    """``days`` (model day, from t = 0) as the end of a run from ``start``: a finite number
    > ``start``. Raises ``SceneError`` (naming the day a branch starts at)."""
    if not (isinstance(days, (int, float)) and math.isfinite(days) and days > start):
        raise SceneError(
            f"days must be > {start:g} (got {days})"
            + (f": the run branches at day {start:g} and days is the model day it ends at" if start else "")
        )
    return float(days)


def with_days(scene: Scene, days: float, dt_source: str = "the restart file's") -> Scene:
    """The scene run to ``days`` (model day, from t = 0) instead; dt must divide the
    run from ``start_day`` and its output interval (``dt_source`` says where dt comes
    from, for the message). Raises ``SceneError``."""
    scene = dataclasses.replace(scene, days=run_end(days, scene.start_day))
    Clock(scene.dt, scene.start_day, scene.days, dt_source, scene.control is not None).check(
        {"the output interval (output.every_days)": scene.output_every_days}
    )
    return scene
