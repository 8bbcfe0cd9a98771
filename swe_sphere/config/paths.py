"""Where scenes and the files they name are: the bundled scenes, a scene named by path or
name, and a [grid] table's mesh record (its mesh file relative to the scene file, or to the
working folder where the command line names it)."""

from __future__ import annotations

import difflib
from importlib.resources import files
from pathlib import Path

from ..core.errors import SceneError
from ..mesh.records import CUBES, MAPS, CubeMesh, MeshFile, MeshRecord, StretchedCube


def scene_dir() -> Path:
    """Folder of the bundled scenes (testcases/)."""
    return Path(str(files("swe_sphere.testcases")))


SCENE_FOLDERS = ("", "tableaus")  # testcases/ and its folders of bundled scenes (tableaus/: Butcher tables)


def list_scenes() -> list[Path]:
    return [p for folder in SCENE_FOLDERS for p in sorted((scene_dir() / folder).glob("*.toml"))]


def resolve_path(spec: str) -> Path:
    """A scene path, or the name of a bundled scene (with or without .toml, and
    with or without its folder: "ark2_gkc" or "tableaus/ark2_gkc").
    Raises ``SceneError``, suggesting the closest bundled names for a typo, or for an empty name."""
    if not spec.strip():  # Path("") is the current folder
        raise SceneError(f"the scene name is empty (got {spec!r}): give a scene file or a bundled scene's name")
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


def grid_record(grid: dict, scene_path: Path, file_folder: Path | None = None) -> MeshRecord | None:
    """The mesh record (``mesh.records``; None: the equiangular cube) of a scene's [grid] table
    (``SCHEMA``'s types checked) for a cube of its ``ne`` (default 16): a relative ``mesh_file``
    relative to ``file_folder`` (the working folder for one typed on the command line), else to
    the scene file's folder; read and checked here. Raises ``SceneError`` naming the key."""
    chosen = grid.get("map")
    if chosen is not None and chosen not in MAPS:
        raise SceneError(f"grid.map must be one of {', '.join(MAPS)} (got {chosen!r})")
    stretch = [k for k in ("stretch_factor", "target_lat", "target_lon") if k in grid]
    cube = grid.get("cube", "equiangular")
    if cube not in CUBES:
        raise SceneError(f"grid.cube must be one of {', '.join(CUBES)} (got {cube!r})")
    if cube != "equiangular" and ("mesh_file" in grid or stretch):
        raise SceneError(
            f"grid.cube = {cube!r} is a cube of ne; drop grid.{'mesh_file' if 'mesh_file' in grid else stretch[0]}"
        )
    ne = grid.get("ne", 16)
    if cube == "equidistant":
        return CubeMesh(ne, chosen or "element_local", cube)
    if "mesh_file" in grid:
        if stretch:
            raise SceneError(f"grid.{stretch[0]} stretches the cube; a mesh file is its own mesh (drop one)")
        given = Path(grid["mesh_file"]).expanduser()
        folder = scene_path.parent if file_folder is None else file_folder
        return MeshFile.of(given if given.is_absolute() else folder / given, chosen or "element_local")
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
        return StretchedCube(ne, c, lat, lon)
    return CubeMesh(ne, "element_local") if chosen == "element_local" else None
