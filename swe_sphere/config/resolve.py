"""The resolvers of ``load_scene``: each of a scene's tables, checked types in, final values
and notes for the run's header out, a function each (the first refusal wins).

Every problem raises ``SceneError`` (a ValueError) with a one-line message naming the key.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import NamedTuple

from ..cases.library import Case, make_case
from ..cases.reference import cases_of, locate, stored_days
from ..core.arguments import band_argument, got
from ..core.clock import Clock
from ..core.constants import EARTH, Planet
from ..core.errors import SceneError
from ..grid.gll import NP_MAX, NP_MIN, gll
from ..grid.quality import smallest_dx
from ..io.initial_state import SCENE_CASES
from ..io.reanalysis import is_given
from ..io.run_file import OUTPUT_FIELDS
from ..mesh.records import MeshFile, with_ne
from ..model.arguments import TERMS
from ..steppers import STEPPERS
from ..steppers.initialization import METHODS, DigitalFilter
from .paths import grid_record
from .schema import SceneGrid, check_type, is_integer, is_number


def _reference(spec, case_name: str, case_obj) -> str:
    """The absolute path of the reference file ``case.reference`` names (a path, a
    bundled file name or a truncation, "T341": see ``reference.locate``), its
    variables and layout checked without reading its fields. Raises ``SceneError`` naming the key and the value."""
    where = f"case.reference = {spec!r}"
    if not isinstance(spec, str):
        raise SceneError(f'case.reference must be a file path or a truncation such as "T341" (got {got(spec)})')
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


def resolve_planet(table: dict | None) -> Planet:
    """The [planet] table's ``Planet`` (radius, omega, gravity; Williamson's Earth's by default).
    Raises ``SceneError`` naming the key (``Planet.from_table``)."""
    try:
        return Planet.from_table(table)
    except ValueError as err:
        raise SceneError(str(err)) from None


# a case's angles (radians) and their largest magnitude: the tilt of the flow's axis, the bump's place
ANGLES = {"alpha": (2 * math.pi, "2π"), "lat2": (math.pi / 2, "π/2"), "lon2": (2 * math.pi, "2π")}


FILE_KEYS = {
    "file": ("path",),
    "reanalysis": ("initial_file", "surface_file", "analysed_file"),
}  # a case's keys naming files


def file_of(value: str, scene_path: Path) -> str:
    """The absolute path of a file a scene's key names: relative to the current folder where it is
    there, else to the scene file's folder (a bundled scene's data beside it)."""
    given = Path(value).expanduser()
    beside = scene_path.parent / given
    return str((beside if not given.exists() and beside.exists() else given).absolute())


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
    for key in FILE_KEYS.get(name, ()):  # a file the case reads (not a Dataset given to swe_sphere.run)
        if isinstance(params.get(key), str) and not is_given(params[key]):
            params[key] = file_of(params[key], scene_path)
    try:
        case = make_case(name, params, planet, SCENE_CASES)
    except ValueError as err:
        raise SceneError(str(err)) from None
    for key, value in params.items():  # angles in radians (a number of degrees, or 1e308, is no tilt one means)
        most = ANGLES.get(key)
        if most is not None and not abs(value) <= most[0]:
            raise SceneError(f"case.{key} must be an angle in radians within ±{most[1]} (got {value!r})")
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
    """The ``terms`` list as a tuple (``model.arguments.TERMS``). Raises ``SceneError``: none,
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


def resolve_ensemble(table: dict | None) -> dict | None:
    """``Scene.ensemble`` of the [ensemble] table: None without one, else {"members": N ≥ 1,
    "perturbation": metres ≥ 0 (default 0), "seed": ≥ 0 (default 0), "degrees": (l_min, l_max)
    of the noise's spherical harmonics, or None for white noise (``ensemble.Perturbation``)}
    (``swe-sphere run`` runs the scene's ensemble, ``swe_sphere.Ensemble`` takes its members and
    perturbation by default). Raises ``SceneError`` naming the key."""
    if not table:
        return None
    members, amplitude, seed = table.get("members"), table.get("perturbation", 0.0), table.get("seed", 0)
    if not (math.isfinite(amplitude) and amplitude >= 0):
        raise SceneError(f"ensemble.perturbation must be a number of metres >= 0 (got {amplitude!r})")
    if seed < 0:
        raise SceneError(f"ensemble.seed must be an integer >= 0 (got {seed!r})")
    degrees = band_argument("ensemble.degrees", table.get("degrees"), error=SceneError)
    # the values given first: -s ensemble.degrees=[20,1] with --members is refused for its degrees
    if members is None:
        raise SceneError("ensemble.members is missing: an [ensemble] table names its members (an integer >= 1)")
    if members < 1:
        raise SceneError(f"ensemble.members must be an integer >= 1 (got {members!r})")
    out = {"members": int(members), "perturbation": float(amplitude), "seed": int(seed)}
    return out | ({} if degrees is None else {"degrees": degrees})


def _table_grid(grid: dict, scene_path: Path, file_folder: Path | None = None) -> SceneGrid:
    """The grid a [grid] table names (``grid_record`` for the mesh's keys, a relative mesh file
    in ``file_folder`` if given; ne defaults to 16, 0 with a mesh file, np to 4). Raises
    ``SceneError``: ne not 0 with a mesh file."""
    record = grid_record(grid, scene_path, file_folder)
    on_file = isinstance(record, MeshFile)
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
    outside ``NP_MIN``..``NP_MAX`` or below 3 on the element-local map (``grid_record`` for
    the mesh's own keys)."""
    typed, folder = _typed_mesh_file(table or {}, file_table)
    named = _table_grid(typed, scene_path, folder)  # the grid of the tables as overridden
    scene_grid = named if file_table is None else _table_grid(file_table, scene_path)
    on_file = isinstance(named.mesh, MeshFile)
    record1 = named.mesh
    if mesh is not None:
        if ne is not None:
            raise SceneError(f"ne = {ne} and mesh {mesh}: a mesh file's elements are its own (HOMME's ne = 0)")
        own = file_table if file_table is not None else (table or {})
        typed = sorted(k for k, v in (table or {}).items() if k not in ("np", "map") and own.get(k, None) != v)
        if typed:  # a -s grid.* the mesh file would drop unread (its elements and their layout are the file's)
            raise SceneError(
                f"grid.{typed[0]} = {table[typed[0]]!r} and mesh {mesh}: the mesh file's grid replaces the "
                "scene's (only grid.np and grid.map apply to it)"
            )
        record1, ne = MeshFile.of(mesh, (table or {}).get("map", "element_local")), 0
    elif on_file and ne not in (None, 0):
        raise SceneError(f"ne = {ne} with grid.mesh_file: a mesh file's elements are its own (HOMME's ne = 0)")
    ne1 = named.ne if ne is None else ne
    np1 = named.np if np_ is None else np_
    notes = ()
    if table is None and (ne is None or np_ is None) and mesh is None:
        notes = (f"the scene has no [grid]: ne = {ne1}, np = {np1} (the defaults)",)
    if not is_integer(ne1) or (ne1 < 1 and not isinstance(record1, MeshFile)):
        raise SceneError(f"ne must be an integer >= 1 (got {got(ne1)})")
    if not is_integer(np1) or not NP_MIN <= np1 <= NP_MAX:
        raise SceneError(f"np must be an integer in {NP_MIN}..{NP_MAX} (got {got(np1)})")
    run_grid = SceneGrid(ne1, np1, with_ne(record1, ne1))
    if run_grid.record.map == "element_local" and np1 < 3:
        raise SceneError(
            f"np must be >= 3 on {run_grid.record.description(np1)}: the element-local map's area correction moves interior nodes"
        )
    return scene_grid, run_grid, notes


def _typed_mesh_file(table: dict, file_table: dict | None) -> tuple[dict, Path | None]:
    """(the [grid] table, the folder of a relative mesh file) where ``-s grid.mesh_file`` was
    typed on the command line (``table``'s differs from the file's own ``file_table``): the file's
    elements (the scene file's ne dropped, as ``--mesh``) and the working folder, else ``table``
    and None (the scene file's folder)."""
    own = file_table or {}
    if file_table is None or "mesh_file" not in table or table["mesh_file"] == own.get("mesh_file"):
        return table, None
    if "ne" in own and table.get("ne") == own["ne"]:  # the scene file's cube, not one typed with the file
        table = {k: v for k, v in table.items() if k != "ne"}
    return table, Path.cwd()


def resolve_spacing(scene_grid: SceneGrid, run_grid: SceneGrid, radius: float, file_radius) -> Spacing:
    """How the run's node spacing differs from the scene file's, on ``run_grid`` and a planet of
    ``radius`` (m) against ``scene_grid`` and ``file_radius`` (m; None or not a positive number:
    the scene file's dt and ν are not for a radius, scale 1). The mean spacing goes as
    1 / (the record's ``mean_ne`` · (np − 1)); the smallest as the first GLL interval / ne on two
    equiangular cubes, else as ``quality.smallest_dx`` of both meshes. Raises ``SceneError`` for
    a stretch that folds an element."""
    ne0, np0, record0 = scene_grid.ne, scene_grid.np, scene_grid.record
    ne1, np1, record1 = run_grid.ne, run_grid.np, run_grid.record
    scale = radius / file_radius if is_number(file_radius) and file_radius > 0 else 1.0
    ratio = (record0.mean_ne * (np0 - 1)) / (record1.mean_ne * (np1 - 1))
    if scene_grid.mesh is None and run_grid.mesh is None:
        smallest = (_first_gll_gap(np1) / ne1) / (_first_gll_gap(np0) / ne0)
    elif scene_grid == run_grid:
        smallest = 1.0
    else:
        try:
            old = smallest_dx(ne0, np0, record0.build())
            new = smallest_dx(ne1, np1, record1.build())
        except ValueError as err:  # a stretch that folds an element
            raise SceneError(f"{record1.description(np1)}: {err}") from None
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
    name = table.get("stepper", "ssprk3") if stepper is None else stepper  # "" is a name, and unknown
    if not isinstance(name, str) or name not in STEPPERS:
        raise SceneError(f"unknown stepper {name!r} (known: {', '.join(STEPPERS)})")
    days = table.get("days", 1.0) if days is None else days
    if not (is_number(days) and math.isfinite(days) and days > 0):
        raise SceneError(f"days must be > 0 (got {got(days)})")
    return name, days


# the precisions ([numerics] precision, ``--precision``): of the RHS tendency, the state float64;
# "float32_state": the tendency and a step's state and stages (``model.precision``)
PRECISIONS = ("float64", "float32", "float32_state")


def resolve_precision(
    table: dict, stepper: str, precision=None, controlled: bool = False, options: dict | None = None
) -> str:
    """``Scene.precision`` of the [numerics] table and ``load_scene``'s ``precision`` (default
    "float64") for ``stepper`` with its ``options`` (its scene table). Raises ``SceneError`` naming
    the key: a value not of ``PRECISIONS``; "float32" with a stepper that refuses it
    (``Described.float32_refusal``); "float32_state" with one that refuses it
    (``Described.float32_state_refusal``) or with step control (``controlled``: its estimate is
    read in float64)."""
    value = table.get("precision", "float64") if precision is None else precision
    if value not in PRECISIONS:
        raise SceneError(f"numerics.precision must be one of {', '.join(PRECISIONS)} (got {got(value)})")
    refuse_precision(value, stepper, options)
    if value == "float32_state" and controlled:
        raise SceneError(
            'numerics.precision = "float32_state" with step control: its error estimate is read in float64; '
            "use a fixed dt or float32"
        )
    return value


def stepper_class(stepper: str, options: dict | None = None) -> type:
    """The class that steps ``stepper`` with ``options`` (its scene table; None: the defaults),
    whose refusals are the run's (``Described.picked``: ``tableau``'s engine by its table).
    Raises ``SceneError`` naming ``stepper.key`` for options the stepper refuses."""
    try:
        return STEPPERS[stepper].picked({} if options is None else options)
    except ValueError as err:
        raise SceneError(f"{stepper}.{err}") from None


def refuse_precision(precision: str, stepper: str, options: dict | None = None) -> None:
    """Refuse (``SceneError``, one line) a ``precision`` that ``stepper`` with ``options`` cannot
    step in (``stepper_class``'s refusals): float32 with a stepper whose ``float32_refusal`` says
    why (its Jacobian-vector products difference the RHS); a scene resolved
    (``resolve_precision``) and one branched (``checkpoint.branch``)."""
    described = stepper_class(stepper, options)
    why = described.float32_refusal if precision != "float64" else None
    if why is not None:
        raise SceneError(f'numerics.precision = "{precision}" with stepper {stepper}: {why}; it runs in float64 only')
    why = described.float32_state_refusal if precision == "float32_state" else None
    if why is not None:
        raise SceneError(
            f'numerics.precision = "float32_state" with stepper {stepper}: {why}; use "float32" or an explicit Runge-Kutta stepper'
        )


# the keywords of ``load_scene`` (``--ne``, ``--days``, ...) and the values they replace
SUPERSEDED = {
    "grid.ne": "ne",
    "grid.np": "np_",
    "time.days": "days",
    "time.stepper": "stepper",
    "time.dt": "dt",
    "numerics.precision": "precision",
}


def check_superseded(overrides: dict, given: dict) -> None:
    """Check the overrides (``-s``) that a keyword of ``given`` (``load_scene``'s: ``--ne``,
    ``--np``, ``--days``, ``--stepper``, ``--dt``, ``--precision``) replaces, as the file's own values are checked:
    a wrong one is refused, not dropped unread. Raises ``SceneError`` naming the key and value."""
    for key, keyword in SUPERSEDED.items():
        if key not in overrides or given.get(keyword) is None:
            continue
        value = overrides[key]
        try:
            if keyword == "ne" and not (is_integer(value) and value >= 0):  # 0: a mesh file's (resolve_grid)
                raise SceneError(f"must be an integer >= 1, or 0 with a mesh file (got {got(value)})")
            if keyword == "np_" and not (is_integer(value) and NP_MIN <= value <= NP_MAX):
                raise SceneError(f"must be an integer in {NP_MIN}..{NP_MAX} (got {got(value)})")
            if keyword == "dt" and not (is_number(value) and math.isfinite(value) and value > 0):
                raise SceneError(f"must be > 0 (got {got(value)})")
            if keyword in ("days", "stepper"):
                resolve_stepper_days({keyword: value})
            if keyword == "precision" and value not in PRECISIONS:
                raise SceneError(f"must be one of {', '.join(PRECISIONS)} (got {got(value)})")
        except SceneError as err:
            raise SceneError(
                f"{key} = {value!r}: {str(err).removeprefix('days ')} (though {keyword.rstrip('_')} = "
                f"{given[keyword]!r} replaces it, -s values are checked as the file's)"
            ) from None


def resolve_dt_np(table: dict, file_np: int, run_np: int) -> float:
    """The factor of the [time] table's ``dt_np`` (``{np = factor}``, TOML keys: a scaled dt is
    ``factor`` times longer on grids of that np; 1 for an np it does not name) for a run at
    ``run_np`` over the scene file's own ``file_np``: the file's dt is for its own np. Raises
    ``SceneError`` naming ``time.dt_np``: a key that is not an np of ``NP_MIN``–``NP_MAX``, a
    factor not a number > 0, a ratio of the two past a float's range."""
    factors = table.get("dt_np", {})
    for key, factor in factors.items():
        if not (key.isdigit() and NP_MIN <= int(key) <= NP_MAX):
            raise SceneError(f"time.dt_np keys must be np values {NP_MIN}-{NP_MAX} (got {key!r})")
        if not (is_number(factor) and factor > 0):
            raise SceneError(f"time.dt_np.{key} must be a number > 0 (got {got(factor)})")
    factor = factors.get(str(run_np), 1.0) / factors.get(str(file_np), 1.0)
    if not 0 < factor < math.inf:
        raise SceneError(
            f"time.dt_np: the factor at np {run_np} over np {file_np}'s is {factor:g}, out of a float's range"
        )
    return factor


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


def scene_title(case_name: str, file_case: str | None, stem: str, description: str) -> tuple[str, str]:
    """(``Scene.name``, ``Scene.description``) of the scene file ``stem`` running ``case_name``:
    its own, or for a case switched from the file's (``-s case.name=...``) names that say so, for
    the header, the run file's title and its default name."""
    if case_name == file_case:
        return stem, description
    return f"{case_name}_in_{stem}", f"case {case_name} with scene {stem}'s grid, terms and stepping"


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


def resolve_output_files(
    output: dict, dt: float, days: float, dt_source: str, controlled: bool = False
) -> tuple[tuple, tuple]:
    """([output] fields, [[output.streams]]) checked: field names, stream names (a
    file-name suffix, distinct, not "restart") and intervals of whole steps (any interval
    with ``controlled`` steps, which land on the times)."""
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
        every = check_type(f"{where}.every_days", st.get("every_days"), float) if "every_days" in st else None
        if every is None or not every > 0:
            raise SceneError(f"{where}.every_days must be > 0 (got {every})")
        Clock(dt, 0.0, days, dt_source, controlled).check({f"the output interval {where}.every_days": every})
        streams.append(
            {
                "name": name,
                "every_days": every,
                "fields": _fields(st.get("fields", list(OUTPUT_FIELDS)), f"{where}.fields"),
            }
        )
    return fields, tuple(streams)


def _planet_text(planet: Planet) -> str:
    """A planet for a message: "radius 637122 m, omega 0.0007292 1/s, gravity 9.80616 m/s^2"."""
    return f"radius {planet.a:g} m, omega {planet.omega:g} 1/s, gravity {planet.g:g} m/s^2"
