"""A run made on a mesh file is remapped and plotted where the ``.g`` file is not (issue 65,
item 9): the run file carries the elements' mesh (``run_file.write_element_mesh``)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import xarray as xr

import swe_sphere
from swe_sphere.io.remap import remap_dataset
from swe_sphere.studies.plotting import plot_map

from meshes import TEMPEST_NE2


def test_a_mesh_runs_file_is_remapped_and_plotted_without_its_mesh_file(tmp_path):
    made, sent = tmp_path / "made", tmp_path / "sent"
    made.mkdir(), sent.mkdir()
    mesh = shutil.copy(TEMPEST_NE2, made / "ne2.g")
    run = made / "run.nc"
    swe_sphere.run("tc2_steady", mesh=str(mesh), np=3, days=0.25, device="cpu", output_file=run)
    here = remap_dataset(run, 30)
    moved = shutil.move(run, sent / "run.nc")
    (made / "ne2.g").unlink()
    there = remap_dataset(moved, 30)  # the same grid rebuilt from the run file's own mesh
    np.testing.assert_array_equal(there.h.values, here.h.values)
    with xr.open_dataset(moved, decode_times=False) as ds:
        assert ds["element_mesh_corners"].shape == (24, 4) and ds["element_mesh_node_xyz"].shape == (26, 3)
        figure = plot_map(ds, "h", 0.25)["figure"]
    assert figure.axes


def test_a_run_file_without_its_mesh_or_the_file_says_so(tmp_path):
    mesh = shutil.copy(TEMPEST_NE2, tmp_path / "ne2.g")
    run = tmp_path / "run.nc"
    swe_sphere.run("tc2_steady", mesh=str(mesh), np=3, days=0.25, device="cpu", output_file=run)
    with xr.open_dataset(run, decode_times=False) as ds:
        old = ds.drop_vars(["element_mesh_corners", "element_mesh_node_xyz"]).load()
    (tmp_path / "ne2.g").unlink()
    with pytest.raises(swe_sphere.SceneError, match=r"ne2.g not found, and the run file carries no mesh$"):
        remap_dataset(old, 30)
