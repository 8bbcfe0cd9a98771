"""Misuses of the Python API (issue 65, item 3): each raises one ``SweSphereError`` subclass
whose one-line message names the argument or value, as docs/reference.md says every error
does; none escapes as a TypeError, pathlib's or numpy's wording, or a bare ValueError."""

from __future__ import annotations

import pytest
import warp as wp

import swe_sphere
from swe_sphere import OutputError, SceneError, Simulation, SweSphereError, remap_dataset

TINY = dict(ne=2, np=3, days=0.01, device="cpu")
SIM = dict(ne=2, np=3, days=0.01)


def _sim():
    return Simulation("tc2_steady", "cpu", **SIM)


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
