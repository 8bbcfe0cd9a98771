"""The run file page's tables, generated when the site is built from a real run's file: a
one-day run of ``tc2_steady`` on the ne2 np4 cube (a few seconds on a CPU), its dimensions,
variables (with their own ``units``, ``long_name`` and ``standard_name``) and global attributes.

The file carries its variables' meanings; the dimensions' and the global attributes' are held
here, in ``DIMENSIONS`` and ``ATTRIBUTES``: one the run writes without an entry stops the build
and fails tests/io/test_run_file_page.py.
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

SCENE = "tc2_steady"  # a case with an exact solution: the run file's error norms are in it
GRID = {"ne": 2, "np": 4}

DIMENSIONS = {
    "time": "the output times (days since the start; day 0 the initial state)",
    "ncol": "the unique GLL nodes (HOMME/EAM's native-output name): 6 ne² (np − 1)² + 2 on the cube",
    "ndual_node": "the corners of the nodes' control volumes (``mesh_dual``)",
    "nv": "the most corners a control volume has (4 on the cube; up to 7 on a mesh)",
    "nface": "the sub-cell quadrilaterals between the GLL nodes (``mesh_topology``)",
    "nmax_face": "the corners of a sub-cell (4)",
}

ATTRIBUTES = {
    "Conventions": "CF-1.8 UGRID-1.0",
    "title": "the run's scene",
    "history": "when and by what command the file was written",
    "source": "the model and its version",
    "swe_sphere_version": "the version that wrote the file",
    "scene": "the resolved scene, as JSON: every value the run used (a continuation reads it)",
    "case": "the test case",
    "ne": "elements along a cube edge (0 on a mesh file)",
    "np": "GLL points per element direction",
    "stepper": "the time stepper",
    "dt": "the step (s; under step control the first)",
    "precision": "the tendency's floating-point type",
    "device": "the Warp device the run stepped on",
    "mpi_ranks": "the MPI ranks the run stepped on",
    "initialization": "how the run started: none, or dfi (a digital-filter start)",
    "reference": "what the error norms are against: the exact solution or a reference file",
    "planet_radius": "a (m)",
    "planet_omega": "Ω (s⁻¹)",
    "planet_gravity": "g (m s⁻²)",
    "courant_advective": "the largest advective Courant number |v| Δt/Δx over the output times",
    "courant_gravity": "the largest gravity-wave Courant number √(gh) Δt/Δx over the output times",
}


def write_run_file(folder: Path) -> Path:
    """The run file of a one-day ``SCENE`` run on ``GRID`` (the CPU), written in ``folder``."""
    import swe_sphere

    path = folder / f"{SCENE}.nc"
    swe_sphere.Simulation(SCENE, device="cpu", days=1.0, progress=False, **GRID).run(path)
    return path


def tables(path: Path) -> dict[str, list[tuple[str, ...]]]:
    """{"dimensions": [(name, size, meaning)], "variables": [(name, dimensions, units,
    long_name, standard_name)], "attributes": [(name, meaning)]} of the run file ``path``.
    Raises ``KeyError`` naming the dimensions and global attributes without a meaning here."""
    import netCDF4

    with netCDF4.Dataset(path) as ds:
        missing = [d for d in ds.dimensions if d not in DIMENSIONS] + [a for a in ds.ncattrs() if a not in ATTRIBUTES]
        if missing:
            raise KeyError(f"run file entries without a meaning: {missing} (docs/_ext/run_file_page.py)")
        dims = [(name, str(len(d)), DIMENSIONS[name]) for name, d in ds.dimensions.items()]
        # CF bounds carry no attributes of their own: they are named by their coordinate's ``bounds``
        bounds = {v.bounds: name for name, v in ds.variables.items() if "bounds" in v.ncattrs()}
        variables = [
            (
                name,
                ", ".join(v.dimensions) or "(scalar)",
                _plain(getattr(v, "units", "")),
                _plain(v.long_name) if "long_name" in v.ncattrs() else f"the cell corners of ``{bounds[name]}``",
                _plain(getattr(v, "standard_name", "")),
            )
            for name, v in ds.variables.items()
        ]
        attributes = [(name, _plain(ATTRIBUTES[name])) for name in ds.ncattrs()]
    return {"dimensions": dims, "variables": variables, "attributes": attributes}


def _plain(text: str) -> str:
    """The file's own text (a long_name) as reStructuredText reads it literally (``|v|`` no
    substitution, ``*`` no emphasis)."""
    return re.sub(r"([\\`*|_])", r"\\\1", text)


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]], widths: str) -> str:
    lines = [".. list-table::", "   :header-rows: 1", f"   :widths: {widths}", ""]
    for row in [header, *rows]:
        lines += [f"   * - {row[0] if row is header else f'``{row[0]}``'}", *(f"     - {c}" for c in row[1:])]
    return "\n".join(lines)


def sections() -> list[tuple[str, str, str]]:
    """(label, title, reStructuredText table) for the dimensions, variables and attributes."""
    with tempfile.TemporaryDirectory() as folder:
        t = tables(write_run_file(Path(folder)))
    return [
        ("run-file-dimensions", "Dimensions", _table(("name", "size here", "meaning"), t["dimensions"], "20 12 68")),
        (
            "run-file-variables",
            "Variables",
            _table(("name", "dimensions", "units", "long_name", "standard_name"), t["variables"], "18 16 10 36 20"),
        ),
        ("run-file-attributes", "Global attributes", _table(("name", "meaning"), t["attributes"], "25 75")),
    ]


def setup(app):
    from generated import add  # Sphinx's: only when the site is built

    return add(app, "run-file", sections, "run_file_page.py")
