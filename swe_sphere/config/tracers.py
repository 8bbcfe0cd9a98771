"""The [tracers] table's resolvers for ``load_scene``: the tracers' names and initial fields, their
file, their ∇⁴, where it acts and their limiter, a function each (the first refusal wins).

Every problem raises ``SceneError`` (a ValueError) with a one-line message naming the key.
"""

from __future__ import annotations

from pathlib import Path

from ..cases.tracers import TRACER_FIELDS
from ..core.arguments import got
from ..core.errors import SceneError
from ..io.initial_state import read_tracer_file
from ..io.run_file import OUTPUT_FIELDS
from ..model.limiter import LIMITERS
from ..model.precision import tracers_refusal
from .resolve import ResolvedCase, file_of, stepper_class


def resolve_tracers(
    table: dict, case: ResolvedCase, terms: tuple, stepper: str, controlled: bool, precision: str, options: dict
) -> tuple:
    """``Scene.tracers`` of the [tracers] table: ((name, initial), ...), ``names`` the tracers'
    run-file names and ``initial`` their initial fields, one each: a bundled field's name
    (``cases.tracers.TRACER_FIELDS``) or, with a ``file``, a variable of that file
    (``resolve_tracer_file``); () without the table. Raises ``SceneError`` (one line naming the
    key): names that are not distinct identifiers or that are a run file's own field or
    coordinate, an unknown field (without a file), lists of other lengths, a case whose h is not a depth (TC1's is itself a tracer, zero
    off its bell: q = hq / h has no value there), a scene without the continuity term (the tracers ride it),
    or a stepper (with its ``options``: ``stepper_class``) or step control that does not carry them
    (``Stepper.tracers_refusal``), or a precision that does not (``model.precision.tracers_refusal``)."""
    if not table:
        return ()
    names, initial = table.get("names"), table.get("initial")
    if not names or not all(isinstance(n, str) and n.isidentifier() for n in names):
        raise SceneError(f"tracers.names must be a non-empty list of identifiers (got {names!r})")
    taken = set(OUTPUT_FIELDS) | {"hs", "lat", "lon", "area", "time"}
    if len(set(names)) != len(names) or set(names) & taken:
        raise SceneError(f"tracers.names must be distinct and none of {', '.join(sorted(taken))} (got {names!r})")
    if not isinstance(initial, list) or len(initial) != len(names):
        raise SceneError(f"tracers.initial must list a field for each of the {len(names)} names (got {initial!r})")
    for f in initial:
        if not isinstance(f, str) or not f or (f not in TRACER_FIELDS and "file" not in table):
            raise SceneError(
                f"tracers.initial: unknown field {f!r} (known: {', '.join(TRACER_FIELDS)}; "
                "or a variable of a netCDF file given as tracers.file)"
            )
    if not case.case.h_is_depth:
        raise SceneError(f"[tracers] needs a fluid depth: case {case.name}'s h is itself a tracer (q = hq / h)")
    if "continuity" not in terms:
        raise SceneError("[tracers] needs the continuity term: the tracers ride the depth's mass flux")
    why = stepper_class(stepper, options).tracers_refusal
    if why is None and controlled:
        why = "its step control weighs u, v and h alone"
    if why is not None:
        raise SceneError(f"[tracers] with stepper {stepper}: {why}; tracers run with the explicit Runge-Kutta steppers")
    why = tracers_refusal(precision)
    if why is not None:
        raise SceneError(f"[tracers] with [numerics] {why}")
    return tuple(zip(names, initial, strict=True))


def resolve_tracer_file(table: dict, scene_path: Path) -> str | None:
    """``Scene.tracer_file`` of the [tracers] table (``resolve_tracers``' first): its ``file``'s
    absolute path (``file_of``), the file read and its variables that ``initial`` names checked
    (``io.initial_state.read_tracer_file``); None without one. Raises ``SceneError`` (one line
    naming the file): a file no ``initial`` reads from (each a bundled field), a missing file or
    variable, a variable on neither the model's nodes nor a lat-lon grid of the globe,
    non-finite values."""
    if "file" not in table:
        return None
    from_file = tuple(dict.fromkeys(f for f in table["initial"] if f not in TRACER_FIELDS))
    if not from_file:
        raise SceneError(
            f"tracers.file = {table['file']!r}: no tracers.initial names a variable of it (each is a bundled field); "
            "drop tracers.file"
        )
    path = file_of(table["file"], scene_path)
    read_tracer_file(path, from_file)
    return path


def resolve_tracer_hyperviscosity(table: dict, terms: tuple) -> bool:
    """``Scene.tracer_hyperviscosity`` of the [tracers] table: its ``hyperviscosity`` (default true:
    the tracers take the depth's ∇⁴, ν_s ∇⁴ of q(h + hs)). Raises ``SceneError`` for true given
    where the scene has no hyperviscosity term."""
    value = table.get("hyperviscosity", True)
    if "hyperviscosity" in table and value and "hyperviscosity" not in terms:
        raise SceneError("tracers.hyperviscosity = true needs the hyperviscosity term")
    return bool(value)


def resolve_stage_hyperviscosity(table: dict, terms: tuple) -> bool:
    """``Scene.tracer_stage_hyperviscosity`` of the [tracers] table: its ``stage_hyperviscosity``
    (default false: the ν_s ∇⁴ split after each step; true: inside every stage, HOMME's
    ``advance_nonstag_rk``). Raises ``SceneError`` for true where the scene has no hyperviscosity
    term or ``hyperviscosity`` is false (no ∇⁴ on the tracers to move)."""
    value = bool(table.get("stage_hyperviscosity", False))
    if value and ("hyperviscosity" not in terms or not table.get("hyperviscosity", True)):
        raise SceneError(
            "tracers.stage_hyperviscosity = true needs the hyperviscosity term and tracers.hyperviscosity = true"
        )
    return value


def resolve_limiter(table: dict) -> str:
    """``Scene.tracer_limiter`` of the [tracers] table: its ``limiter``, one of
    ``model.limiter.LIMITERS`` ("none" by default). Raises ``SceneError`` naming the key."""
    value = table.get("limiter", "none")
    if value not in LIMITERS:
        raise SceneError(f"tracers.limiter must be one of {', '.join(LIMITERS)} (got {got(value)})")
    return value
