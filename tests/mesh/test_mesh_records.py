"""Meshes as records (``mesh.records``): the JSON a scene's mesh travels as in run and restart
files reads back to the same record; a mesh file is read and hashed once along ``run --mesh``;
``-s grid.mesh_file`` typed on the command line takes the file's elements and the working folder."""

from __future__ import annotations

import contextlib

import pytest

from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import SceneError
from swe_sphere.mesh import records
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import write_exodus
from swe_sphere.mesh.records import CubeMesh, MeshFile, StretchedCube, from_json


@pytest.fixture
def cube_file(tmp_path):
    return write_exodus(tmp_path / "cube2.g", cube_mesh(2))


def test_records_read_back_from_their_json(cube_file):
    file = MeshFile.of(cube_file)
    for record, text in (
        (CubeMesh(4, "element_local"), {"map": "element_local"}),
        (CubeMesh(4, "equiangular", "equidistant"), {"map": "equiangular", "cube": "equidistant"}),
        (
            StretchedCube(4, 2.5, 40.0, 270.0),
            {"map": "element_local", "stretch_factor": 2.5, "target_lat": 40.0, "target_lon": 270.0},
        ),
        (file, {"map": "element_local", "file": str(cube_file), "sha256": file.sha256, "nelem": 24}),
    ):
        assert record.as_json() == text and list(record.as_json()) == list(text)  # the same keys, in order
        assert from_json(4, text) == record
    assert CubeMesh(4).as_json() is None and from_json(4, None) is None
    assert (file.label, file.description(4), file.nelem, file.mean_ne) == ("cube2", "mesh cube2.g np=4", 24, 2.0)


def test_run_on_a_mesh_file_reads_and_hashes_it_once(cube_file, tmp_path, monkeypatch):
    """Before: 3 reads and 3 hashes of the file along ``run --mesh F --dt``; now one each."""
    calls = {"read": 0, "hash": 0}
    read, digest = records.read_exodus, records.file_sha256

    def counted(name, f):
        def call(path):
            calls[name] += str(path) == str(cube_file)
            return f(path)

        return call

    monkeypatch.setattr(records, "read_exodus", counted("read", read))
    monkeypatch.setattr(records, "file_sha256", counted("hash", digest))
    argv = ["run", "tc2_steady", "--mesh", str(cube_file), "--dt", "600", "--days", str(1200 / 86400)]
    assert main([*argv, "--no-progress", "--output", str(tmp_path / "o.nc")]) == 0
    assert calls == {"read": 1, "hash": 1}


def test_a_mesh_file_on_the_command_line_takes_its_elements_and_the_working_folder(cube_file, tmp_path):
    """``-s grid.mesh_file=cube2.g`` on a cube scene (tc2_steady: ne = 16): no ``grid.ne = 0``
    needed, and the relative name is the working folder's, as ``--mesh``'s."""
    with contextlib.chdir(tmp_path):
        typed = load_scene("tc2_steady", overrides={"grid.mesh_file": "cube2.g"})
        assert typed.as_dict() == load_scene("tc2_steady", mesh="cube2.g").as_dict()
    assert typed.ne == 0 and typed.mesh == MeshFile.of(cube_file)
    with pytest.raises(
        SceneError, match=r"^grid.ne must be 0 with grid.mesh_file \(HOMME's ne = 0: the file's elements; got 3\)$"
    ):
        load_scene("tc2_steady", overrides={"grid.mesh_file": str(cube_file), "grid.ne": 3})
