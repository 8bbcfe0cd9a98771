"""``swe_sphere.Ensemble``, the deprecated name of ``Simulation(scene, members=N)``: the one place
the suite meets its ``DeprecationWarning`` lines (constructing it, its old names), so that a new
warning anywhere else shows. It is a ``Simulation`` of members; its old names say what they are
called now, and its old refusals keep their words."""

from __future__ import annotations

import warnings

import pytest

from swe_sphere.core.errors import ArgumentError
from swe_sphere.ensemble import Ensemble, Perturbation
from swe_sphere.simulation.simulation import Simulation

SMALL = {"ne": 2, "np": 4, "dt": 900.0}
CONTROLLED = {"ne": 2, "np": 4, "days": 0.25, "stepper": "bs32", "output.every_days": 0.125, "time.control": "error"}


def test_the_old_class_is_a_simulation_of_members_and_its_old_names_warn(tmp_path):
    with pytest.warns(DeprecationWarning, match=r"^swe_sphere.Ensemble is deprecated"):
        ens = Ensemble("galewsky", 2, Perturbation(1.0, seed=2), device="cpu", **SMALL)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the driver's own names: no warning
        assert isinstance(ens, Simulation) and ens.time == 0.0 and ens.states().shape == (2, 3, 384)
        assert len(ens.members) == 2 and ens.members.layout == "in_turn"
    with pytest.warns(DeprecationWarning, match=r"^Ensemble.step_count is deprecated: step$"):
        assert ens.step_count == 0
    with pytest.warns(DeprecationWarning, match=r"^Ensemble.layout is deprecated: members.layout$"):
        assert ens.layout == "in_turn"
    with pytest.warns(DeprecationWarning, match=r"^Simulation.ensemble is deprecated: Simulation.members$"):
        assert ens.ensemble is ens.members
    with pytest.warns(DeprecationWarning, match=r"^Ensemble.step\(n\) is deprecated"):
        ens.step(2)
    with pytest.warns(DeprecationWarning, match=r"^Ensemble.fields\(member\) is deprecated"):
        assert all((a == b).all() for a, b in zip(ens.fields(1), ens.states()[1]))
    assert ens.time == 2 * 900.0 / 86400  # ``step`` is the old class's method
    path = ens.write_checkpoint(tmp_path / "e.restart.nc")
    with pytest.warns(DeprecationWarning, match=r"^swe_sphere.Ensemble is deprecated"):
        again = Ensemble.from_checkpoint(path, device="cpu")
    assert again.time == ens.time and (again.states() == ens.states()).all()


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_the_old_refusals_keep_their_words(tmp_path):
    with pytest.warns(DeprecationWarning):
        ens = Ensemble("tc2_steady_alpha_pi4", 2, device="cpu", ne=2, dt=900.0, days=0.25)
    ens.advance(0.25)
    with pytest.raises(ArgumentError, match=r"^Ensemble\.run: at step 24 \(day 0\.25\) the run is at its end"):
        ens.run(tmp_path / "b.nc")
    assert not list(tmp_path.iterdir())
    with pytest.warns(DeprecationWarning), pytest.raises(ArgumentError, match=r"^Ensemble.step takes steps of a fixed"):
        Ensemble("galewsky", 2, Perturbation(1.0, seed=1), device="cpu", **CONTROLLED).step(1)
