"""Misuses of the Python API (issue 65, item 3): each raises one ``SweSphereError`` subclass
whose one-line message names the argument or value, as docs/how-to/step-by-step.md says every error
does; none escapes as a TypeError, pathlib's or numpy's wording, or a bare ValueError."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import warp as wp

import swe_sphere
from swe_sphere import (
    ArgumentError,
    CheckpointError,
    HeightMisfit,
    HeightObservations,
    OutputError,
    PointHeights,
    SceneError,
    Simulation,
    SweSphereError,
    gradient,
    load_scene,
    remap_dataset,
)
from swe_sphere.adjoint.gradient import scene_model

TINY = dict(ne=2, np=3, days=0.01, device="cpu")
SIM = dict(ne=2, np=3, days=0.01)


def _sim():
    return Simulation("tc2_steady", "cpu", **SIM)


@functools.cache
def _tc5(stepper="rk4"):
    """TC5 at ne 2 np 3 (216 element-local nodes) for the gradient's misuses."""
    return load_scene("tc5_mountain", ne=2, np_=3, stepper=stepper)


def _grid():
    return scene_model(_tc5())[0].grid


def _model():
    return scene_model(_tc5())[0]


def _gradient(*args, **kwargs):
    return gradient(_tc5(), *args, **kwargs)


FLAT = HeightMisfit(0.0)


MISUSES = {
    "stepper not a name": (
        lambda f: swe_sphere.run("tc2_steady", **TINY | {"stepper": ["rk4"]}),
        SceneError,
        "stepper",
    ),
    "output_file a folder": (
        lambda f: swe_sphere.run("tc2_steady", output_file=".", **TINY),
        OutputError,
        "output_file",
    ),
    "initial of one argument": (
        lambda f: swe_sphere.run("tc2_steady", initial=lambda lat: (lat, lat, lat), **TINY),
        SceneError,
        "initial",
    ),
    "initial returning two": (
        lambda f: swe_sphere.run("tc2_steady", initial=lambda lat, lon: (lat, lon), **TINY),
        SceneError,
        "initial",
    ),
    "device tpu": (lambda f: swe_sphere.run("tc2_steady", **TINY | {"device": "tpu"}), SceneError, "device"),
    "steps every < 0": (lambda f: next(_sim().steps(every=-1)), SceneError, "every"),
    "advance days < 0": (lambda f: _sim().advance(days=-1), SceneError, "days"),
    "state remap 0": (lambda f: _sim().state(remap=0), SceneError, "degrees"),
    "remap_dataset resolution < 0": (lambda f: remap_dataset(f, -1), SceneError, "resolution"),
    "remap_dataset missing file": (lambda f: remap_dataset("nosuch.nc"), SceneError, "nosuch.nc"),
    "remap_dataset a folder": (lambda f: remap_dataset(f.parent), SceneError, "is a directory"),
    # Python's wording from deeper in, or nothing at all (issue 86, item 2)
    "output_file a number": (lambda f: swe_sphere.run("tc2_steady", output_file=5, **TINY), OutputError, "output_file"),
    "restart_every 0": (lambda f: swe_sphere.run("tc2_steady", restart_every=0, **TINY), SceneError, "restart_every"),
    "overwrite a str": (lambda f: swe_sphere.run("tc2_steady", overwrite="no", **TINY), SceneError, "overwrite"),
    "graphs maybe": (lambda f: swe_sphere.run("tc2_steady", graphs="maybe", **TINY), SceneError, "graphs must be"),
    "remap_dataset a number": (lambda f: remap_dataset(123), SceneError, "ds must be an xarray.Dataset"),
    "load_scene overrides a str": (
        lambda f: load_scene("tc5_mountain", overrides="grid.ne=3"),
        SceneError,
        "overrides must be a mapping",
    ),
    "load_scene overrides' key a number": (
        lambda f: load_scene("tc5_mountain", overrides={5: 3}),
        SceneError,
        "the keys of overrides must be str",
    ),
    "Simulation of None": (lambda f: Simulation(None, "cpu"), SceneError, "scene must be a Scene"),
    "Simulation.run output a number": (lambda f: _sim().run(5), OutputError, "output must be"),
    "add_callback of a number": (lambda f: _sim().add_callback(5, every_days=1), SceneError, "fn must be a callable"),
    "from_checkpoint a number": (lambda f: Simulation.from_checkpoint(5, "cpu"), CheckpointError, "checkpoint must"),
    "kinetic_energy_spectrum a number": (
        lambda f: swe_sphere.kinetic_energy_spectrum(5),
        SceneError,
        "run must be an xarray.Dataset",
    ),
    "zonal_mean of no such field": (lambda f: swe_sphere.zonal_mean(f, "bogus"), SceneError, "'bogus'"),
    "CubedSphere ne a str": (lambda f: swe_sphere.CubedSphere("x", 4), ArgumentError, "ne must be an integer"),
    "CubedSphere radius < 0": (lambda f: swe_sphere.CubedSphere(2, 4, -1.0), ArgumentError, "radius must be"),
    # the gradient and its observations (issue 86, items 2, 3)
    "gradient of a scene's name": (lambda f: gradient("tc5_mountain", 4, FLAT), ArgumentError, "scene must be a Scene"),
    "gradient cost None": (lambda f: _gradient(4, None), ArgumentError, "cost must be a callable"),
    "gradient comm a str": (lambda f: _gradient(1, FLAT, comm="x"), ArgumentError, "comm must be an mpi4py"),
    "gradient steps 2.5": (lambda f: _gradient(2.5, FLAT), ArgumentError, "steps must be an integer >= 1 (got 2.5)"),
    "gradient steps 0": (lambda f: _gradient(0, FLAT), ArgumentError, "steps must be an integer >= 1 (got 0)"),
    "gradient snapshots 1.5": (lambda f: _gradient(2, FLAT, snapshots=1.5), ArgumentError, "snapshots"),
    "gradient parameters a str": (lambda f: _gradient(1, FLAT, parameters="yes"), ArgumentError, "parameters"),
    "gradient disk a number": (lambda f: _gradient(1, FLAT, disk=5), ArgumentError, "disk must be"),
    "gradient history a number": (lambda f: _gradient(1, FLAT, history=5), ArgumentError, "history must be rows"),
    "gradient x0 with a NaN": (
        lambda f: _gradient(1, FLAT, x0=np.full((3, 216), np.nan)),
        ArgumentError,
        "x0 holds a NaN or an infinity",
    ),
    "gradient device tpu": (lambda f: _gradient(1, FLAT, device="tpu"), SceneError, "device"),
    "gradient cost returning a number": (lambda f: _gradient(1, lambda x, s: 1.0), ArgumentError, "cost must return"),
    "gradient of implicit": (
        lambda f: gradient(_tc5("implicit"), 1, FLAT),
        ArgumentError,
        "scene.stepper = 'implicit' has no gradient",
    ),
    "semi_implicit parameters' gradient": (
        lambda f: gradient(_tc5("semi_implicit"), 1, FLAT, parameters=True),
        ArgumentError,
        "parameters must be False with semi_implicit",
    ),
    "HeightMisfit of 7 nodes": (
        lambda f: _gradient(1, HeightMisfit(np.zeros(7))),
        ArgumentError,
        "h_obs must be a number or have shape (216,)",
    ),
    "HeightMisfit NaN": (lambda f: HeightMisfit(np.nan), ArgumentError, "h_obs must be finite"),
    "PointHeights lengths differ": (
        lambda f: PointHeights(_grid(), [0.1, 0.2], [0.3]),
        ArgumentError,
        "lat and lon must have one shape",
    ),
    "PointHeights in degrees": (
        lambda f: PointHeights(_grid(), [100.0], [0.3]),
        ArgumentError,
        "lat must be in [-1.5708, 1.5708] (radians",
    ),
    "PointHeights lon in degrees": (lambda f: PointHeights(_grid(), [0.1], [300.0]), ArgumentError, "lon must be in"),
    "PointHeights grid a number": (lambda f: PointHeights(5, [0.1], [0.3]), ArgumentError, "grid must be"),
    "HeightObservations values a list": (
        lambda f: HeightObservations(PointHeights(_grid(), [0.1], [0.3]), [1.0]),
        ArgumentError,
        "values must be a mapping",
    ),
    "HeightObservations step -1": (
        lambda f: HeightObservations(PointHeights(_grid(), [0.1], [0.3]), {-1: [1.0]}),
        ArgumentError,
        "the keys of values must be an integer >= 0",
    ),
    "HeightObservations sigma NaN": (
        lambda f: HeightObservations(PointHeights(_grid(), [0.1], [0.3]), {0: [1.0]}, sigma=np.nan),
        ArgumentError,
        "sigma must be a finite number > 0",
    ),
    "Simulation start of two rows": (
        lambda f: Simulation("tc2_steady", "cpu", start=np.zeros((2, 216)), **SIM),
        ArgumentError,
        "start must have shape (3, any)",
    ),
    "Simulation start of another length": (
        lambda f: Simulation("tc2_steady", "cpu", start=np.zeros((3, 7)), **SIM),
        ArgumentError,
        "start state has shape (3, 7)",
    ),
    "Simulation start NaN": (
        lambda f: Simulation("tc2_steady", "cpu", start=np.full((3, 216), np.nan), **SIM),
        ArgumentError,
        "start must be finite",
    ),
    "Simulation comm a string": (
        lambda f: Simulation("tc2_steady", "cpu", comm="x", **SIM),
        ArgumentError,
        "comm must be an mpi4py communicator",
    ),
    "Simulation initial a number": (
        lambda f: Simulation("tc2_steady", "cpu", initial=5, **SIM),
        ArgumentError,
        "initial must be a function",
    ),
    "Simulation initial_diagnostics a number": (
        lambda f: Simulation("tc2_steady", "cpu", initial_diagnostics=5, **SIM),
        ArgumentError,
        "initial_diagnostics must be a mapping",
    ),
    # the model and the stepper registry, public at the top level too (issue 86)
    "make_stepper name a list": (lambda f: swe_sphere.make_stepper(["rk4"], _model(), 60.0), ArgumentError, "a list"),
    "make_stepper unknown name": (lambda f: swe_sphere.make_stepper("rk5", _model(), 60.0), ArgumentError, "'rk5'"),
    "make_stepper model a scene": (
        lambda f: swe_sphere.make_stepper("rk4", _tc5(), 60.0),
        ArgumentError,
        "model must be a ShallowWater",
    ),
    "make_stepper dt a string": (lambda f: swe_sphere.make_stepper("rk4", _model(), "60"), ArgumentError, "dt must be"),
    "make_stepper dt negative": (lambda f: swe_sphere.make_stepper("rk4", _model(), -60.0), ArgumentError, "> 0"),
    "make_stepper unknown option": (
        lambda f: swe_sphere.make_stepper("imex", _model(), 60.0, tol2=1e-6),
        ArgumentError,
        "unknown option 'tol2'",
    ),
    "ShallowWater grid a number": (
        lambda f: swe_sphere.ShallowWater(5, ["continuity"], np.zeros(3), np.zeros(3)),
        ArgumentError,
        "grid must be a CubedSphere",
    ),
    "ShallowWater fcor of another length": (
        lambda f: swe_sphere.ShallowWater(_grid(), ["continuity"], np.zeros(7), np.zeros(_grid().nnodes)),
        ArgumentError,
        "fcor must have shape",
    ),
    "ShallowWater hs NaN": (
        lambda f: swe_sphere.ShallowWater(
            _grid(), ["continuity"], np.zeros(_grid().nnodes), np.full(_grid().nnodes, np.nan)
        ),
        ArgumentError,
        "hs must be finite",
    ),
    "ShallowWater nu negative": (
        lambda f: swe_sphere.ShallowWater(_grid(), ["continuity"], *np.zeros((2, _grid().nnodes)), nu=-1.0),
        ArgumentError,
        "nu must be a finite number >= 0",
    ),
    "ShallowWater device a number": (
        lambda f: swe_sphere.ShallowWater(_grid(), ["continuity"], *np.zeros((2, _grid().nnodes)), device=0),
        ArgumentError,
        "device must be",
    ),
}
if wp.get_cuda_device_count() == 0:
    MISUSES["device cuda without a GPU"] = (
        lambda f: swe_sphere.run("tc2_steady", **TINY | {"device": "cuda"}),
        SceneError,
        "device cuda",
    )


@pytest.mark.parametrize("name", list(MISUSES))
def test_api_misuse_raises_one_swe_sphere_error_naming_it(name, tc5_run_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    call, kind, word = MISUSES[name]
    with pytest.raises(SweSphereError) as info:
        call(tc5_run_file)
    assert type(info.value) is kind
    message = str(info.value)
    assert word in message and "\n" not in message
    assert list(tmp_path.iterdir()) == []  # nothing written
