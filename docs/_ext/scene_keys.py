"""The scene keys page, generated from the scene schema (``swe_sphere.config.schema.SCHEMA``)
when the site is built: every table and key with its type, its default and what it means.

The schema holds the types and the steppers' option dataclasses their defaults; the defaults of
the other keys and every key's meaning are held here, in ``KEYS``, one entry a key. A key of the
schema without an entry (or an entry no key has) stops the build, and the default test run
(tests/config/test_scene_keys_page.py), so that a new key cannot go undocumented.
"""

from __future__ import annotations

import dataclasses
import types

# What each table is for (a stepper's table is described by its stepper).
TABLES = {
    "": "Top-level keys.",
    "case": "The flow: the test case and its parameters, or a state read from a file.",
    "grid": "The mesh: the equiangular cube of ``ne`` (the default), its stretched or equidistant "
    "forms, or an Exodus II mesh file; ``np`` GLL points per element direction.",
    "time": "The stepper, the step, the run's length and the step's control.",
    "output": "The run file: its interval, its fields, more streams of their own.",
    "hyperviscosity": "The ∇⁴ hyperviscosity (HOMME's ``nu``, ``nu_div``, ``nu_s``); without the "
    "table, no ∇⁴ coefficient is set.",
    "filter": "HOMME's element filter (Boyd–Vandeven); without the table, none.",
    "dfi": 'The digital-filter start (``case.initialization = "dfi"``; Lynch & Huang 1992).',
    "ensemble": "The scene's ensemble: its members and how they start.",
    "planet": "The planet (Williamson et al. 1992's Earth by default).",
    "numerics": "Floating-point choices.",
    "tracers": "Passive tracers q, carried as hq by the depth's own continuity (explicit Runge-Kutta steppers).",
}

# "table.key" (or "key" at the top level) -> (default, meaning). Units are SI unless said.
KEYS = {
    "description": ("the scene's name", "a line saying what the scene is, shown in the run's header"),
    "terms": (
        "(required)",
        "the terms integrated, of continuity, momentum_advection, coriolis, pressure_gradient, "
        "topography, hyperviscosity, forcing; an absent term costs nothing",
    ),
    "case": (
        "(required: name)",
        '``name`` (a case of ``swe-sphere list``, or "file" with ``path`` and ``time``: a state of '
        "one's own), the case's parameters (e.g. ``alpha``, radians), ``initialization`` "
        '("none" or "dfi") and ``reference`` ("T341" or a file: the reference scored against)',
    ),
    "grid.ne": ("16 (0 with a mesh file)", "elements along a cube edge (6 ne² elements)"),
    "grid.np": ("4", "GLL points per element direction, 2..8"),
    "grid.map": (
        '"equiangular" ("element_local" on a mesh file)',
        'the map of the elements to the sphere: HOMME\'s ``cubed_sphere_map`` 0 ("equiangular") or 2 ("element_local")',
    ),
    "grid.stretch_factor": ("none (uniform)", "c ≥ 1: the Schmidt-stretched cube of ne (FV3's do_schmidt)"),
    "grid.target_lat": ("90.0", "degrees: the latitude the stretched cube is refined towards"),
    "grid.target_lon": ("0.0", "degrees: the longitude the stretched cube is refined towards"),
    "grid.cube": (
        '"equiangular"',
        'the cube\'s element corners at equal angles, or "equidistant" (at equal tangents)',
    ),
    "grid.mesh_file": (
        "none",
        "an Exodus II mesh (.g), relative to the scene file or absolute; ``ne`` 0 or left out",
    ),
    "time.stepper": ('"ssprk3"', "the time stepper, a name of ``swe_sphere.STEPPERS``"),
    "time.dt": (
        "(required)",
        "the step (s) on the scene file's own grid and planet; scaled with the smallest node "
        "spacing on another grid; the first step under ``control``",
    ),
    "time.dt_np": ("{}", "{np = factor}: the scaled step that much longer at that np"),
    "time.days": ("1.0", "the run's length in days"),
    "time.control": (
        '"fixed"',
        'the step\'s control: "fixed", "cfl" (a Courant number), "error" (an embedded pair\'s '
        'error estimate) or "balanced" (a fraction of the spatial error)',
    ),
    "time.rtol": ("1e-4", 'under "error": the relative tolerance of a step\'s error estimate'),
    "time.atol": (
        "rtol",
        'under "error": the absolute tolerance, one number or [wind (m s⁻¹), h (m)]',
    ),
    "time.per_unit_step": (
        "false",
        'under "error": the error norm taken per unit step (‖e‖ · 1 day / Δt), Shampine 2005',
    ),
    "time.controller": (
        'the stepper\'s PID controller where it has one, else "pi"',
        'under "error" and "balanced": the step-size controller',
    ),
    "time.cfl": (
        "0.9 × the stepper's measured Courant limit",
        'the target Courant number under "cfl", a cap under "error" and "balanced" (false: none)',
    ),
    "time.dt_min": ("1e-3 × dt", "s: a controlled step below it stops the run as a blow-up"),
    "time.dt_max": ("none", "s: the longest controlled step"),
    "time.balance": ("0.1", 'under "balanced": the fraction of the spatial error a step\'s error is held to'),
    "output.every_days": ("1.0", "the run file's interval in days"),
    "output.log_every_steps": ("0 (none)", "a log line of invariant changes and Courant numbers every so many steps"),
    "output.fields": (
        "all: h, u, v, vorticity, divergence",
        "the run file's node fields",
    ),
    "output.streams": (
        "[]",
        "more run files, one a table: ``name``, ``every_days``, ``fields`` (RUN.name.nc)",
    ),
    "output.cells": ("true", "the GLL control volumes in the run file (false: a file without them)"),
    "hyperviscosity.efold_hours": (
        "none",
        "the grid's Nyquist degree e-folds in this many hours: sets ``nu``, ``nu_div``, ``nu_s`` on any grid",
    ),
    "hyperviscosity.nu": ("0.0", "m⁴ s⁻¹ on the scene file's grid (scaled as Δx^3.2): the rotational wind's"),
    "hyperviscosity.nu_div": ("nu", "m⁴ s⁻¹: the divergent wind's"),
    "hyperviscosity.nu_s": ("nu", "m⁴ s⁻¹: the height's (h + hs)"),
    "hyperviscosity.subcycle": ("1", "∇⁴ substeps a step"),
    "hyperviscosity.scaling": (
        "none (constant ν)",
        "s in 0..4: the tensor ∇⁴, ν ∝ Δx^s along each element direction (HOMME's hypervis_scaling)",
    ),
    "hyperviscosity.every": (
        "1",
        'k (or "auto"): the ∇⁴ over kΔt after every k-th step (a fixed Δt, a one-step stepper)',
    ),
    "filter.mu": ("none", "the weight of one application of the filter"),
    "filter.efold_hours": ("none", "instead of ``mu``: the elements' highest mode e-folds in this many hours"),
    "filter.p_bv": ("12", "the Boyd–Vandeven transfer function's order"),
    "filter.s_bv": ("2/3", "the fraction of the modes left untouched (below s_bv·np − 1)"),
    "dfi.span_hours": ("48.0", "the filter's whole window (−span/2 … span/2), at least twice the cutoff"),
    "dfi.cutoff_hours": ("24.0", "the half-power period"),
    "ensemble.members": ("(required)", "N, the members"),
    "ensemble.perturbation": ("0.0", "m: the amplitude of the seeded noise in h"),
    "ensemble.seed": ("0", "the noise's seed"),
    "ensemble.degrees": ("none (white noise)", "[l_min, l_max]: the noise's spherical-harmonic degrees"),
    "planet.radius": ("6.37122e6", "m; a scene's dt and ν are for its file's radius"),
    "planet.omega": ("7.292e-5", "s⁻¹: the rotation rate"),
    "planet.gravity": ("9.80616", "m s⁻²"),
    "numerics.precision": (
        '"float64"',
        'the tendency\'s floating-point type, "float64" or "float32" (the state float64), or "float32_state" '
        "(a step's state and stages float32 too: the explicit Runge-Kutta steppers, a fixed dt)",
    ),
    "numerics.compensated": (
        "false",
        'under "float32_state": the run keeps the float32 state from step to step (false), or holds the '
        "float64 state between steps, each step's float32 increment added to it in float64 (true)",
    ),
    "numerics.mass_fixer": (
        "true",
        'under "float32_state": each step\'s end puts back the mass its start held, spread over the sphere '
        "by weight spheremp (a uniform depth), from float64 sums",
    ),
    "tracers.names": ("none", "the tracers' names: distinct identifiers, each a variable of the run file (q, units 1)"),
    "tracers.limiter": (
        '"none"',
        "the tracers' shape-preserving limiter: \"optimization\" (Guba et al. 2014, HOMME's limiter 8)",
    ),
    "tracers.hyperviscosity": (
        "true",
        "the depth's ∇⁴ on the tracers, ν_s ∇⁴ of q(h + hs) (keeps q = 1 at 1); false: none on them",
    ),
    "tracers.stage_hyperviscosity": (
        "false",
        "true: that ν_s ∇⁴ (and the depth's) inside every stage's right-hand side, from the stage's state and "
        "limited with its transport (HOMME's advance_nonstag_rk; the stepper's stability interval must hold "
        "ν_s Δt λ); false: split after each step (substeps or RKL1). Needs the hyperviscosity term",
    ),
    "tracers.initial": (
        "none",
        "each tracer's initial field, by name: constant, latitude, cosine_bells, gaussian_hills, slotted_cylinders, "
        "correlated_bells (Lauritzen et al. 2012), or a variable of tracers.file",
    ),
    "tracers.file": (
        "none",
        "a netCDF file of initial mixing ratios, on the model's nodes (a run file) or a lat-lon grid (interpolated), "
        "its last time; relative to the working folder, else to the scene file's",
    ),
}


def _type_name(kind) -> str:
    if isinstance(kind, types.UnionType):
        return " or ".join(_type_name(k) for k in kind.__args__)
    return {
        str: "string",
        int: "integer",
        float: "number",
        bool: "boolean",
        list: "array",
        tuple: "array",
        dict: "table",
    }.get(kind, getattr(kind, "__name__", str(kind)))


def _default(field: dataclasses.Field) -> str:
    if field.default is not dataclasses.MISSING:
        value = field.default
    elif field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    else:
        return "(required)"
    return toml_value(value)


def toml_value(value) -> str:
    """A default as a scene file writes it (``"theta"``, ``true``, ``[1, 20]``); None: none."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return repr(value)


def rows() -> dict[str, list[tuple[str, str, str, str]]]:
    """Table name ("" for the top level) -> [(key, type, default, meaning)] of every key of the
    schema, in its order. Raises ``KeyError`` naming the keys without an entry in ``KEYS``, or
    the entries of ``KEYS`` no key of the schema has."""
    from swe_sphere.config.schema import SCHEMA
    from swe_sphere.steppers import STEPPERS

    tables: dict[str, list] = {"": []}
    seen = []
    for name, spec in SCHEMA.items():
        if name in STEPPERS:  # a stepper's options: types and defaults from its dataclass
            fields = {f.name: f for f in dataclasses.fields(STEPPERS[name].Options)}
            tables[name] = [
                (key, _type_name(kind), _default(fields[key]), f"an option of the ``{name}`` stepper")
                for key, kind in spec.items()
            ]
        elif isinstance(spec, dict):
            seen += [f"{name}.{key}" for key in spec]
            tables[name] = [(key, _type_name(kind), *KEYS.get(f"{name}.{key}", ("", ""))) for key, kind in spec.items()]
        else:
            seen.append(name)
            tables[""].append((name, _type_name(spec), *KEYS.get(name, ("", ""))))
    missing, stale = [k for k in seen if k not in KEYS], [k for k in KEYS if k not in seen]
    if missing or stale:
        raise KeyError(
            f"scene keys without a meaning: {missing}; meanings of no key: {stale} (docs/_ext/scene_keys.py)"
        )
    return tables


def sections() -> list[tuple[str, str, str]]:
    """(label, title, reStructuredText table) a table of the schema, in its order."""
    out = []
    for table, entries in rows().items():
        intro = TABLES.get(table, f"The options of the ``{table}`` stepper (:ref:`stepper-{table}`).")
        lines = [intro, "", ".. list-table::", "   :header-rows: 1", "   :widths: 18 12 22 48", ""]
        lines += ["   * - key", "     - type", "     - default", "     - meaning"]
        for key, kind, default, meaning in entries:
            lines += [f"   * - ``{key}``", f"     - {kind}", f"     - {default}", f"     - {meaning}"]
        out.append((f"scene-{table or 'top'}", f"[{table}]" if table else "Top level", "\n".join(lines)))
    return out


def setup(app):
    from generated import add  # Sphinx's: only when the site is built

    return add(app, "scene-keys", sections, "scene_keys.py")
