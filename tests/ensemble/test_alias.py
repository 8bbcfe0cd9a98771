"""``swe_sphere.Ensemble``, the deprecated name of ``Simulation(scene, members=N)``: the one place
the suite meets its ``DeprecationWarning`` line (constructing it), so that a new warning anywhere
else shows. It is a ``Simulation`` of members with the driver's names alone (its old ones gone,
issue 124), and its refusals keep their words."""

from __future__ import annotations

import warnings

import pytest

from swe_sphere.core.errors import ArgumentError
from swe_sphere.ensemble import Ensemble, Perturbation
from swe_sphere.simulation.simulation import Simulation

SMALL = {"ne": 2, "np": 4, "dt": 900.0}


def test_the_old_class_is_a_simulation_of_members_that_warns_once(tmp_path):
    with pytest.warns(DeprecationWarning, match=r"^swe_sphere.Ensemble is deprecated"):
        ens = Ensemble("galewsky", 2, Perturbation(1.0, seed=2), device="cpu", **SMALL)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the driver's own names: no warning
        assert isinstance(ens, Simulation) and ens.time == 0.0 and ens.states().shape == (2, 3, 384)
        assert len(ens.members) == 2 and ens.members.layout == "in_turn"
        assert ens.step == 0  # Simulation.step, the steps taken (the old step(n) hid it)
        ens.advance(2 * 900.0 / 86400)
        assert ens.step == 2 and ens.time == 2 * 900.0 / 86400
    with pytest.warns(DeprecationWarning, match=r"^Simulation.ensemble is deprecated: Simulation.members$"):
        assert ens.ensemble is ens.members
    for old in ("step_count", "day", "wall_time", "layout"):  # the old names are gone, not forwarded
        assert not hasattr(ens, old)
    path = ens.write_checkpoint(tmp_path / "e.restart.nc")
    with pytest.warns(DeprecationWarning, match=r"^swe_sphere.Ensemble is deprecated"):
        again = Ensemble.from_checkpoint(path, device="cpu")
    assert isinstance(again, Ensemble) and again.step == 2 and again.time == ens.time
    assert (again.states() == ens.states()).all()


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_the_old_refusals_keep_their_words(tmp_path):
    with pytest.warns(DeprecationWarning):
        ens = Ensemble("tc2_steady_alpha_pi4", 2, device="cpu", ne=2, dt=900.0, days=0.25)
    ens.advance(0.25)
    with pytest.raises(ArgumentError, match=r"^Ensemble\.run: at step 24 \(day 0\.25\) the run is at its end"):
        ens.run(tmp_path / "b.nc")
    assert not list(tmp_path.iterdir())
    with pytest.warns(DeprecationWarning), pytest.raises(ArgumentError, match=r"^members must be given"):
        Ensemble("galewsky", device="cpu", **SMALL)  # no members, nor a scene's [ensemble]
