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
    [tracers]         names = ["dye"], initial = ["cosine_bells"]: passive tracers q carried as hq
                      by the depth's continuity (``cases.tracers.TRACER_FIELDS``: their
                      initial fields; explicit Runge-Kutta steppers at a fixed dt),
                      file = "q.nc" (a netCDF file whose variables the other initial
                      entries name: ``io.initial_state.read_tracer_file``),
                      limiter = "none" | "optimization" (Guba et al. 2014's, HOMME's limiter 8),
                      hyperviscosity = true | false (the depth's ∇⁴ on the tracers, ν_s ∇⁴ of
                      q(h + hs): true keeps q = 1 at 1; false leaves them undamped),
                      stage_hyperviscosity = false | true (that ν_s ∇⁴, the depth's too,
                      inside every stage's right-hand side and its limiter: HOMME's
                      advance_nonstag_rk; false: split after each step)
    [numerics]        precision = "float64" | "float32" (the RHS tendency computed in
                      float32, the state and its accumulation float64; ``Scene.precision``):
                      refused with a stepper that differences the RHS
                      (``Described.float32_refusal``) | "float32_state" (a step's state and
                      stages float32 too: the explicit Runge-Kutta steppers, a fixed dt),
                      compensated = false | true (the float32 state kept from step to step,
                      or its increments added to a float64 one: ``Scene.compensated``),
                      mass_fixer = true | false (the float32 state's mass put back each step:
                      ``Scene.mass_fixer``)

Every problem raises ``SceneError`` (a ValueError) with a one-line message
naming the offending key or value.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import NamedTuple

from ..core.arguments import instance_argument, mapping_argument
from ..core.clock import Clock
from ..core.constants import EARTH, Planet
from ..core.errors import SceneError
from ..io.reanalysis import is_given
from .control import cfl_notes, is_controlled, resolve_control
from .hyperviscosity import (
    HYPERVIS_EXPONENT,
    efold_nu,
    every_span,
    resolve_every,
    resolve_filter,
    resolve_hyperviscosity,
)
from .paths import list_scenes, resolve_path, scene_dir
from .resolve import (
    ResolvedCase,
    Spacing,
    check_superseded,
    refuse_precision,
    resolve_case,
    resolve_dt_np,
    resolve_ensemble,
    resolve_grid,
    resolve_initialization,
    resolve_output_files,
    resolve_output_interval,
    resolve_planet,
    resolve_precision,
    resolve_spacing,
    resolve_stepper_days,
    resolve_stepper_options,
    resolve_terms,
    scene_title,
)
from .resolved import Scene, run_end, scene_from_dict, with_days
from .schema import SCHEMA, SceneGrid, SceneHyperviscosity, SceneOutput, SceneTime, is_number, read_scene
from .state_scene import TEMPLATE, is_state_file, start_overrides
from .step_rule import DT_NOTES, Times, scene_dt
from .tracers import (
    resolve_limiter,
    resolve_stage_hyperviscosity,
    resolve_tracer_file,
    resolve_tracer_hyperviscosity,
    resolve_tracers,
)

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
    precision: str | None = None,
    members: int | None = None,
    **tables,
) -> Scene:
    """Read, validate and resolve a scene file, applying command-line overrides.

    Resolved in stages, each handed what the ones before decided (the first refusal wins):
    ``read_scene`` (the file, the overrides, keys and types); the tables (``resolve``'s
    resolvers: planet, case, terms, [dfi], grid, spacing, output interval, stepper, days,
    precision); the ∇⁴'s coefficients and span (``hyperviscosity``); Δt by the step rule
    (``step_rule.scene_dt``); the ∇⁴'s every k and [filter] at that Δt; the output files,
    the stepper's options and the step control.

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
    precision : {"float64", "float32", "float32_state"}, optional
        The RHS tendency's floating-point type (``--precision``; the scene's
        ``numerics.precision``, default "float64"); the state stays float64. "float32" is
        refused with a stepper that differences the RHS (``implicit``, ``epi2``, ``epi3``);
        "float32_state" (a step's state and stages float32 too) with any but the explicit
        Runge-Kutta steppers and with step control.
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
    members : int, optional
        The scene's [ensemble] ``members`` (``--members``; ``ensemble={"members": N}`` alike, not
        both): a scene of N members (``Simulation`` of it steps them, as with its ``members``).
    **tables
        Any scene value by its table, as ``swe_sphere.run`` takes it (``ensemble={"members": 2}``,
        ``hyperviscosity={"nu": 5e14}``, ``terms=[...]``): merged into ``overrides``.

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
    _not_a_dataset("path", path)
    instance_argument(
        "path", path, (str, os.PathLike), "a scene file's path or a bundled scene's name (str)", SceneError
    )
    overrides = {} if overrides is None else mapping_argument("overrides", overrides, error=SceneError)
    overrides = flat_overrides(overrides) | flat_overrides(tables)
    if members is not None:
        if overrides.get("ensemble.members", members) != members:
            raise SceneError(
                f"members = {members} and ensemble.members = {overrides['ensemble.members']}: give one of them"
            )
        overrides["ensemble.members"] = members
    if np is not None:
        if np_ is not None:
            raise SceneError(f"np = {np} and np_ = {np_}: give one of them (np_ is np's other name)")
        np_ = np
    if is_state_file(path):  # a reanalysis file: case 7's settings, started from it
        keywords = dict(ne=ne, np_=np_, dt=dt, days=days, stepper=stepper, mesh=mesh, precision=precision)
        scene = load_scene(
            TEMPLATE, **keywords, overrides=overrides | start_overrides(path), restart_every=restart_every
        )
        name, source = ("dataset", "an xarray.Dataset") if is_given(path) else (Path(path).stem, Path(path).name)
        description = f"Williamson et al. (1992) case 7 from {source} (settings of {TEMPLATE})"
        return dataclasses.replace(scene, name=name, description=description)
    given = {"ne": ne, "np_": np_, "dt": dt, "days": days, "stepper": stepper, "precision": precision}
    return _resolve(resolve_path(str(path)), given, mesh, overrides, restart_every)


def _not_a_dataset(name: str, value) -> None:
    """``SceneError`` for an xarray Dataset given where a scene goes: a state, which
    ``swe_sphere.run`` takes and a scene takes from a file."""
    if type(value).__module__.partition(".")[0] == "xarray":
        raise SceneError(
            f"{name}: an xarray {type(value).__name__} is a state, not a scene: swe_sphere.run(dataset) runs it; "
            "here give its file (dataset.to_netcdf(PATH), then PATH)"
        )


def _resolve(path: Path, given: dict, mesh, overrides: dict, restart_every=None) -> Scene:
    """``load_scene``'s work on the scene file ``path`` with its keywords ``given`` (ne, np_, dt,
    days, stepper, precision; None: the file's), in stages, each handed what the ones before it
    decided and asking none of them back: the tables (``_tables``); the ∇⁴'s coefficients and
    span (``resolve_hyperviscosity``, ``every_span``); Δt by the step rule (``scene_dt``, also
    for the scene file's own Δt); the ∇⁴'s schedule at that Δt (``_dissipation``); the output
    files, the stepper's options and the step control."""
    s, file_radius, file_case, file_grid, own = read_scene(path, overrides)
    check_superseded(overrides, given)
    t = _tables(s, path, given, mesh, file_grid, file_radius, restart_every)
    hv_table = s.get("hyperviscosity", {})
    hv, hv_notes = resolve_hyperviscosity(hv_table, t.terms, t.grid, t.spacing)
    span = every_span(hv_table, hv, t.grid, t.planet.a, t.stepper, t.controlled)
    time, stem = s.get("time", {}), path.stem
    rule = (stem, t.grid, t.spacing, t.times, t.np_factor, t.controlled, span)
    dt, dt_source, dt_notes = scene_dt(time.get("dt"), given["dt"], *rule)
    own_dt = dt
    if dt_source == "the dt given" or "time.dt" in overrides:  # the dt it would choose itself, all else as given
        own_dt = _own_dt(own, t, rule)
    output_fields, streams = resolve_output_files(t.output, dt, t.days, dt_source, t.controlled)
    options, stepper_notes = resolve_stepper_options(t.stepper, s.get(t.stepper, {}), overrides)
    control = resolve_control(time, t.stepper, options, dt)
    hv, element_filter, hv_notes = _dissipation(s, hv, hv_notes, span, dt, t)
    name, description = _title(t.case, file_case, stem, s.get("description", ""), overrides)
    notes = t.case.notes + t.grid_notes + dt_notes + stepper_notes + cfl_notes(control, t.stepper) + hv_notes
    scene = Scene(
        name=name,
        description=description,
        case=t.case.name,
        case_params=t.case.params,
        terms=t.terms,
        ne=int(t.grid.ne),
        np=int(t.grid.np),
        stepper=t.stepper,
        stepper_options=options,
        dt=float(dt),
        days=float(t.days),
        output_every_days=float(t.times.every),
        nu=hv.nu,
        hypervis_subcycle=hv.subcycle,
        nu_div=hv.nu_div,
        nu_s=hv.nu_s,
        notes=notes,
        initialization=t.initialization,
        reference=t.case.reference,
        log_every_steps=int(t.log_every),
        planet=t.planet.as_table(),
        output_fields=output_fields,
        output_streams=streams,
        mesh=t.grid.mesh,
        output_cells=t.output.get("cells", True),
        hypervis_scaling=hv.scaling,
        hypervis_every=hv.every,
        element_filter=element_filter,
        control=control,
        ensemble=resolve_ensemble(s.get("ensemble")),
        dt_source=dt_source,
        own_dt=own_dt,
        **dict(zip(("own_planet", "own_days"), _own_planet_days(own))),
        precision=t.precision,
        # read under "float32_state" alone (False otherwise: the record leaves it out)
        compensated=t.precision == "float32_state" and bool(s.get("numerics", {}).get("compensated", False)),
        mass_fixer=bool(s.get("numerics", {}).get("mass_fixer", True)),
        tracers=resolve_tracers(s.get("tracers", {}), t.case, t.terms, t.stepper, t.controlled, t.precision, options),
        tracer_file=resolve_tracer_file(s.get("tracers", {}), path),
        tracer_limiter=resolve_limiter(s.get("tracers", {})),
        tracer_hyperviscosity=resolve_tracer_hyperviscosity(s.get("tracers", {}), t.terms),
        tracer_stage_hyperviscosity=resolve_stage_hyperviscosity(s.get("tracers", {}), t.terms),
    )
    if t.case.case.notes():  # what the case read, said as the run's grid has it read (a reanalysis: its truncation)
        scene = dataclasses.replace(scene, notes=(*scene.make_case().notes(), *scene.notes))
    return scene


class Tables(NamedTuple):
    """``_tables``' answer: the scene's tables resolved before its Δt (``resolve``'s resolvers)."""

    planet: Planet
    case: ResolvedCase
    terms: tuple
    initialization: dict | None
    scene_grid: SceneGrid
    grid: SceneGrid
    grid_notes: tuple
    spacing: Spacing
    output: dict
    log_every: int
    stepper: str
    days: float
    precision: str
    controlled: bool
    times: Times
    np_factor: float


def _tables(s: dict, path: Path, given: dict, mesh, file_grid, file_radius, restart_every) -> Tables:
    """The first stage of ``_resolve``: the planet, case, terms, start, grid and its spacing,
    output interval, stepper, run length, precision and ``time.dt_np`` factor of the scene's
    checked tables ``s``, and the times its Δt lands on (``Times``: a restart interval only
    under a fixed Δt)."""
    planet = resolve_planet(s.get("planet"))
    case = resolve_case(s.get("case", {}), planet, path)
    terms = resolve_terms(s.get("terms"), case.case, case.name)
    initialization = resolve_initialization(case.method, s.get("dfi", {}), case.case, case.name)
    scene_grid, grid, grid_notes = resolve_grid(s.get("grid"), path, given["ne"], given["np_"], mesh, file_grid)
    spacing = resolve_spacing(scene_grid, grid, planet.a, file_radius)
    output, time = s.get("output", {}), s.get("time", {})
    every, log_every = resolve_output_interval(output)
    stepper, days = resolve_stepper_days(time, given["stepper"], given["days"])
    controlled = is_controlled(time)
    precision = resolve_precision(s.get("numerics", {}), stepper, given["precision"], controlled, s.get(stepper, {}))
    restart = restart_every if is_number(restart_every) and restart_every > 0 and not controlled else None
    times = Times(days, every, _stream_intervals(output), restart)
    np_factor = resolve_dt_np(time, scene_grid.np, grid.np)
    return Tables(
        planet,
        case,
        terms,
        initialization,
        scene_grid,
        grid,
        grid_notes,
        spacing,
        output,
        log_every,
        stepper,
        days,
        precision,
        controlled,
        times,
        np_factor,
    )


def _stream_intervals(output: dict) -> tuple:
    """The ``[[output.streams]]`` intervals (days) of the ``[output]`` table ``output`` that are
    numbers > 0, for a scaled dt to divide (their values are checked with the streams,
    ``resolve_output_files``)."""
    return tuple(
        st["every_days"]
        for st in output.get("streams", [])
        if isinstance(st, dict) and is_number(st.get("every_days")) and st["every_days"] > 0
    )


def _own_dt(own: dict, t: Tables, rule: tuple):
    """The dt (s) the scene file would choose itself from its own checked tables ``own``
    (``read_scene``: its time.dt at its own planet's radius, scaled to the run's grid), by the
    step rule ``scene_dt`` with ``rule``, the run's other inputs (its times and its ∇⁴'s span
    among them: ``Scene.own_dt``); None where none fits them."""
    stem, grid, _, times, _, controlled, span = rule
    try:
        own_spacing = resolve_spacing(t.scene_grid, grid, t.planet.a, own.get("planet", {}).get("radius", EARTH.a))
        own_time = own.get("time", {})
        np_factor = resolve_dt_np(own_time, t.scene_grid.np, grid.np)
        return scene_dt(own_time.get("dt"), None, stem, grid, own_spacing, times, np_factor, controlled, span)[0]
    except SceneError:  # none that fits the output interval
        return None


def _dissipation(s: dict, hv, hv_notes, span, dt: float, t: Tables):
    """(the resolved ``[hyperviscosity]`` ``hv`` (``resolve_hyperviscosity``'s, its ``hv_notes``)
    with its ``every``, the ``[filter]``'s element filter, their notes) of the scene's tables
    ``s`` at ``dt`` (s), the ∇⁴'s ``span`` (``every_span``) and the output interval and run of
    ``t`` (``resolve_every``, ``resolve_filter``): the last stage of ``_resolve``."""
    clock = Clock(dt)
    steps = (clock.steps_in(t.times.every), clock.steps_in(t.days))  # an output interval's and the run's
    k, every_notes = resolve_every(s.get("hyperviscosity", {}), span, dt, steps, t.stepper, t.controlled)
    element_filter, filter_notes = resolve_filter(s.get("filter", {}), dt, k, t.controlled)
    if k > 1 and max(hv.nu, hv.nu_div, hv.nu_s) == 0 and element_filter is None:
        every_notes += (f"hyperviscosity.every = {k} is unread: the scene has no ∇⁴ (ν = 0) and no [filter]",)
    return dataclasses.replace(hv, every=k), element_filter, hv_notes + every_notes + filter_notes


def _title(case, file_case: str | None, stem: str, description: str, overrides: dict) -> tuple[str, str]:
    """(``Scene.name``, ``Scene.description``) of the scene file ``stem`` running the resolved
    ``case`` (``scene_title``), the description naming the case parameters set by ``overrides``
    where the file's own case runs (its description is of its own values: the header says what
    runs)."""
    name, description = scene_title(case.name, file_case, stem, description)
    given = [f"{k} = {v!r}" for k, v in overrides.items() if k.startswith("case.") and k[5:] in case.params]
    if given and name == stem:
        description = f"{description}; run with {', '.join(given)}"
    return name, description


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
LOAD_KEYWORDS = {
    "ne": "ne",
    "np": "np_",
    "dt": "dt",
    "days": "days",
    "stepper": "stepper",
    "mesh": "mesh",
    "precision": "precision",
    "members": "members",
}


def resolve_scene(scene, overrides: dict) -> tuple[Scene, tuple]:
    """(Scene, its input files) of ``swe_sphere.run``'s and ``Simulation``'s
    ``scene`` and ``overrides``: a ``Scene`` as it is (no overrides: change it with
    ``dataclasses.replace``), else a scene file or bundled name loaded with the
    overrides as on the command line (``ne``, ``np``, ``dt``, ``days``, ``stepper``, ``mesh``,
    ``precision`` and tables such as ``hyperviscosity={"nu": 5e14}`` or values ``terms=[...]``).
    The inputs are the scene file (outputs must not replace it). Raises ``SceneError``."""
    if isinstance(scene, Scene):
        if overrides:
            raise SceneError("overrides apply to a scene file; change a Scene with dataclasses.replace")
        return scene, ()
    _not_a_dataset("scene", scene)
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


def branched(s: Scene, record: dict, stepper: str | None = None, dt: float | None = None, days=None) -> Scene:
    """The scene of a new run from a state of scene ``s`` at its day ``record["day"]`` (a
    restart file's: ``simulation.checkpoint.branch``) with ``stepper`` and ``dt`` (s, taken by
    the scene's step rule, ``step_rule.scene_dt``; None: ``s``'s), to model day ``days`` (from
    t = 0; None: ``s``'s): a fresh stepper (multistep ones start as at t = 0), step 0 at that
    day (``Scene.start_day``), output every output interval from there, and ``Scene.branch``
    the ``record`` of its source with ``s``'s stepper and dt. The stepper's options are ``s``'s
    for its own stepper, else the defaults; its precision ``s``'s. Raises ``SceneError`` (one
    line) for an unknown stepper, one that cannot step the precision (``refuse_precision``), a
    dt <= 0, or a run from the branch day to ``days`` or an output interval that is not whole
    steps of dt."""
    stepper = resolve_stepper_days({"stepper": s.stepper}, stepper)[0]  # s's, or another known one
    opts = s.stepper_options if stepper == s.stepper else {}
    refuse_precision(s.precision, stepper, opts)
    record = {**record, "stepper": s.stepper, "dt": s.dt}
    # the notes on how the scene's dt was chosen are stale once dt is given
    notes = s.notes if dt is None else tuple(n for n in s.notes if not n.startswith(DT_NOTES))
    scene = dataclasses.replace(s, stepper=stepper, stepper_options=opts, branch=record, notes=notes)
    days = s.days if days is None else days
    if dt is None:  # the restart file's Δt, its scene's rule's
        return with_days(scene, days)
    # a Δt given: the scene's rule takes it as given (> 0, whole steps of the run from the branch day and
    # of its output interval; the grid's spacing unasked: a given Δt is not scaled)
    times = Times(run_end(days, scene.start_day), s.output_every_days, start=scene.start_day)
    dt = scene_dt(None, dt, s.name, s.grid, None, times, controlled=s.control is not None)[0]
    return dataclasses.replace(scene, dt=float(dt), days=times.days)
