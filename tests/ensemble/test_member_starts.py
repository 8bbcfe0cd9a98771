"""What members start from, checked on every path (issue 117, item 7): a perturbation's band past
the grid is refused from Python as from the command line."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from swe_sphere.core.errors import ArgumentError
from swe_sphere.ensemble import Ensemble
from swe_sphere.members.initial import Perturbation
from swe_sphere.simulation.simulation import Simulation

from helpers import TINY, cli_main, one_line

TINY_PY = {"ne": 2, "np": 4, "device": "cpu", "progress": False}
BAND = (
    "grid resolves degrees up to about {top} (2 ne (np - 1), its nodes along the equator over 2): give l_max <= {top}"
)


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize(
    "build, words",
    [
        (  # the issue's: accepted, its noise aliased onto the 24 degrees the ne4 grid holds
            lambda: Ensemble("tc2_steady", 2, Perturbation(1.0, degrees=(1, 2000)), ne=4, device="cpu"),
            "initial: perturbation degrees 1,2000: the ne=4 np=4 " + BAND.format(top=24),
        ),
        (
            lambda: Simulation("tc2_steady", members=2, initial=Perturbation(1.0, degrees=(1, 13)), **TINY_PY),
            "initial: perturbation degrees 1,13: the ne=2 np=4 " + BAND.format(top=12),
        ),
        (  # a scene's [ensemble] band, which the command line's -s ensemble.degrees gives too
            lambda: Simulation(
                "tc2_steady", ensemble={"members": 2, "perturbation": 1.0, "degrees": [2, 13]}, **TINY_PY
            ),
            "ensemble.degrees 2,13: the ne=2 np=4 " + BAND.format(top=12),
        ),
    ],
)
def test_a_band_past_the_grid_is_refused_from_python(build, words):
    with pytest.raises(ArgumentError) as err, warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # Ensemble, the old name
        build()
    assert str(err.value) == words


def test_a_band_the_grid_resolves_runs():
    """l_max = 2 ne (np - 1) = 12 on ne2 np4, the largest the command line takes too."""
    sim = Simulation("tc2_steady", members=2, initial=Perturbation(1.0, degrees=(12, 12)), **TINY_PY)
    h = sim.states()[:, 2]
    assert sim.ensemble.initial_states.endswith("degrees 12 to 12, seed 0") and np.ptp(h, axis=0).max() > 0.1


def test_the_command_line_s_band_and_python_s_are_one_check(capsys):
    code, out, err = cli_main(
        capsys, "run", "tc2_steady", *TINY, "--members", "2", "--perturbation", "1", "--perturbation-degrees", "1,13"
    )
    one_line(code, err, 2, "--perturbation-degrees 1,13: the ne=2 np=4 " + BAND.format(top=12))
    code, out, err = cli_main(
        capsys,
        "run",
        "tc2_steady",
        *TINY,
        "--members",
        "2",
        "-s",
        "ensemble.perturbation=1",
        "-s",
        "ensemble.degrees=[1,13]",
    )
    one_line(code, err, 2, "ensemble.degrees 1,13: the ne=2 np=4 " + BAND.format(top=12))
