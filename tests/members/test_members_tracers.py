"""Tracers in a run of members (issue 125 item 4): each member carries its own rows of mass hq
(the scene's [tracers]), in both layouts, with the bits of its single run, in the run file with a
member axis and through a restart file; over MPI ranks by member in ``tests/test_mpi.py``."""

from __future__ import annotations

import netCDF4
import numpy as np
import pytest

from swe_sphere.config.scene import load_scene, with_days
from swe_sphere.ensemble import Perturbation
from swe_sphere.simulation.simulation import Simulation

from helpers import members_from_checkpoint, members_run

TRACERS = {"names": ["one", "marker"], "initial": ["constant", "latitude"]}


def scene(days: float = 0.5):
    """Galewsky ne2 np4 at 900 s with q = 1 and a latitude marker, output every quarter day."""
    return load_scene("galewsky", ne=2, np_=4, dt=900.0, days=days, output={"every_days": 0.25}, tracers=TRACERS)


def read(path, *names) -> list:
    with netCDF4.Dataset(path) as ds:
        return [np.asarray(ds[name][:]) for name in names]


@pytest.mark.parametrize("layout", ["shared", "in_turn"])
def test_each_member_carries_its_tracers_with_its_single_run_s_bits(tmp_path, layout):
    """3 perturbed members: each starts with the masses h_k·q of its own depth, and after half a
    day its state (u, v, h and both masses), its file's q (time, member, ncol) and its tracers'
    masses (time, member) are those of the single run from its start, to the bit."""
    ens = members_run(scene(), 3, Perturbation(2.0, seed=5), device="cpu", layout=layout)
    starts = ens.states()
    assert starts.shape == (3, 5, ens.grid.nnodes) and not np.array_equal(starts[0, 4], starts[1, 4])
    assert np.array_equal(starts[:, 3], starts[:, 2])  # q = 1: hq is h itself
    ens.run(tmp_path / "ens.nc")
    one, marker, mass = read(tmp_path / "ens.nc", "one", "marker", "marker_mass")
    assert marker.shape == (3, 3, ens.grid.nunique) and mass.shape == (3, 3)
    for k in range(3):
        sim = Simulation(scene(), "cpu", progress=False, start=starts[k])
        sim.run(tmp_path / f"{k}.nc")
        assert np.array_equal(ens.states()[k], sim.x.numpy()), k
        one1, marker1, mass1 = read(tmp_path / f"{k}.nc", "one", "marker", "marker_mass")
        assert np.array_equal(one[:, k], one1) and np.array_equal(marker[:, k], marker1), k
        assert np.array_equal(mass[:, k], mass1), k
    assert np.abs(one - 1).max() < 1e-13 and np.abs(marker[-1] - marker[0]).max() > 1e-3  # q = 1 kept; it moved


@pytest.mark.parametrize("layout", ["shared", "in_turn"])
def test_members_with_tracers_continue_from_their_restart_file_bitwise(tmp_path, layout):
    """Half a day at once, and a quarter then its restart file continued: every member's state,
    tracers' masses included, to the bit; the restart file keeps each mass (node)."""
    whole = members_run(scene(), 3, Perturbation(2.0, seed=5), device="cpu", layout=layout)
    whole.run(tmp_path / "whole.nc")
    first = members_run(with_days(scene(), 0.25), 3, Perturbation(2.0, seed=5), device="cpu", layout=layout)
    first.run(tmp_path / "first.nc", restart_every=0.25)
    with netCDF4.Dataset(tmp_path / "first.restart.nc") as ds:
        assert ds["marker_mass"].dimensions == ds["h"].dimensions
    rest = members_from_checkpoint(tmp_path / "first.restart.nc", days=0.5)
    rest.run(tmp_path / "rest.nc")
    assert rest.states().shape == (3, 5, whole.grid.nnodes)
    assert np.array_equal(rest.states(), whole.states())


def test_members_from_an_ensemble_s_run_file_take_its_tracers(tmp_path):
    """``MemberFile``: each tracer the file holds starts from member k's q there (hq = h·q, both
    as written: the file's last output), one it does not from the scene's [tracers] field."""
    from swe_sphere.ensemble import MemberFile

    first = members_run(scene(0.25), 2, Perturbation(2.0, seed=5), device="cpu")
    first.run(tmp_path / "e.nc")
    h, marker = read(tmp_path / "e.nc", "h", "marker")
    wider = {"names": ["marker", "dye"], "initial": ["latitude", "constant"]}  # dye: not in the file
    again = load_scene("galewsky", ne=2, np_=4, dt=900.0, days=0.25, tracers=wider)
    starts = members_run(again, 2, MemberFile(tmp_path / "e.nc"), device="cpu").states()
    gid, lat = first.grid.gid, np.degrees(first.grid.lat)
    for k in range(2):
        assert np.array_equal(starts[k, 2], h[-1, k][gid])
        assert np.array_equal(starts[k, 3], h[-1, k][gid] * marker[-1, k][gid])  # the file's moved marker
        assert np.array_equal(starts[k, 4], starts[k, 2])  # the dye from the scene: q = 1
    assert np.abs(marker[-1, 0][gid] - lat).max() > 1e-3  # the file's q is not the scene's initial latitude
