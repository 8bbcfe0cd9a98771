"""[numerics] precision (``config.resolve.resolve_precision``): float64 the default and left out
of the scene's record, float32 read from a file, an override or ``precision=``, a bad value or
key refused in one line naming it, and float32 refused with the steppers that difference the RHS
(``Described.float32_refusal``), on a branch and for gradients."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from swe_sphere.adjoint.gradient import scene_model
from swe_sphere.config.parts import scene_stepper
from swe_sphere.config.scene import load_scene, resolve_scene, scene_dir, scene_from_dict
from swe_sphere.core.errors import ArgumentError, SceneError
from swe_sphere.simulation.checkpoint import Checkpoint, branch
from swe_sphere.steppers import STEPPERS

DIFFERENCING = ("implicit", "epi2", "epi3")  # their J·v a forward difference of the RHS (solvers.jacobian)


def test_float64_is_the_default_and_not_in_the_record():
    scene = load_scene("tc2_steady", ne=2)
    assert scene.precision == "float64"
    assert "precision" not in scene.as_dict()
    assert load_scene("tc2_steady", ne=2, overrides={"numerics.precision": "float64"}) == scene


def test_float32_from_an_override_a_keyword_a_table_and_a_file(tmp_path):
    scene = load_scene("tc2_steady", ne=2, overrides={"numerics.precision": "float32"})
    assert scene.precision == "float32" and scene.as_dict()["precision"] == "float32"
    assert scene_from_dict(scene.as_dict()) == scene  # what run and restart files hold
    assert load_scene("tc2_steady", ne=2, precision="float32") == scene
    assert load_scene("tc2_steady", ne=2, overrides={"numerics": {"precision": "float32"}}) == scene
    # swe_sphere.run's and Simulation's keyword (LOAD_KEYWORDS)
    assert resolve_scene("tc2_steady", {"ne": 2, "precision": "float32"})[0] == scene
    path = tmp_path / "tc2_steady.toml"
    path.write_text((scene_dir() / "tc2_steady.toml").read_text() + '\n[numerics]\nprecision = "float32"\n')
    assert load_scene(path, ne=2).precision == "float32"
    assert load_scene(path, ne=2, precision="float64").precision == "float64"  # the keyword wins


@pytest.mark.parametrize(
    ("kw", "words"),
    [
        ({"overrides": {"numerics.precision": "float16"}}, "numerics.precision must be one of float64, float32"),
        ({"precision": "double"}, "numerics.precision must be one of float64, float32, float32_state (got 'double'"),
        ({"overrides": {"numerics.precision": 32}}, "numerics.precision must be str (got 32)"),
        (
            {"overrides": {"numerics.dtype": "float32"}},
            "unknown key numerics.dtype in scene (known: precision, compensated, mass_fixer)",
        ),
        (
            {"precision": "float32", "overrides": {"numerics.precision": "half"}},
            "numerics.precision = 'half': must be one of float64, float32",
        ),
    ],
)
def test_a_bad_precision_is_refused_naming_the_key(kw, words):
    with pytest.raises(SceneError) as err:
        load_scene("tc2_steady", ne=2, **kw)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_the_steppers_that_difference_the_rhs_refuse_float32():
    refusing = sorted(name for name, cls in STEPPERS.items() if cls.float32_refusal is not None)
    assert refusing == sorted(DIFFERENCING)
    for name in DIFFERENCING:
        with pytest.raises(SceneError, match=rf'numerics.precision = "float32" with stepper {name}: its Jacobian'):
            load_scene("tc2_steady", ne=2, stepper=name, precision="float32")
        assert load_scene("tc2_steady", ne=2, stepper=name).precision == "float64"
    assert load_scene("tc2_steady", ne=2, stepper="imex", precision="float32").precision == "float32"


def test_a_branch_or_a_changed_scene_in_float32_refuses_them_too():
    """A restart file in float32 branched to implicit (``run --continue R --stepper implicit``,
    ``sweep --from R``), and a Scene changed by ``dataclasses.replace``: refused before a model."""
    scene = load_scene("tc2_steady", ne=2, precision="float32")
    ck = Checkpoint(scene, 4, np.zeros((3, 1)), {}, {}, {}, "version")
    assert branch(ck, stepper="rk4").precision == "float32"
    with pytest.raises(SceneError, match='"float32" with stepper epi3'):
        branch(ck, stepper="epi3")
    with pytest.raises(SceneError, match='"float32" with stepper implicit'):
        scene_stepper(dataclasses.replace(scene, stepper="implicit", stepper_options={}), model=None)


def test_gradients_stay_float64():
    scene = load_scene("tc2_steady", ne=2, stepper="rk4", precision="float32")
    with pytest.raises(ArgumentError, match="scene.precision = 'float32': gradients stay float64"):
        scene_model(scene)


def test_the_float32_state_is_carried_by_the_explicit_runge_kutta_steppers_alone():
    """``precision = "float32_state"``: a step's state and stages in float32, which only the
    explicit Runge-Kutta engine carries (``Described.float32_state_refusal``): the others refused
    in one line naming the value and the stepper, and so is step control (its estimate is read in
    float64); ``numerics.compensated`` (false by default: the float32 state kept between steps;
    written in its record either way, a record without it being from when true was the default)
    and ``numerics.mass_fixer`` (true by default, left out of the record) read with it; each
    record reads back as its scene."""
    carrying = sorted(name for name, cls in STEPPERS.items() if cls.float32_state_refusal is None)
    assert {"rk4", "ssprk3", "kgu35", "rk43"} <= set(carrying) and "leapfrog" not in carrying
    for name in carrying:
        assert load_scene("tc2_steady", ne=2, stepper=name, precision="float32_state").precision == "float32_state"
    for name in ("leapfrog", "semi_implicit", "imex", "fbrk32", "implicit"):
        with pytest.raises(SceneError) as err:
            load_scene("tc2_steady", ne=2, stepper=name, precision="float32_state")
        assert f'numerics.precision = "float32_state" with stepper {name}: ' in str(err.value)
        assert "\n" not in str(err.value)
    with pytest.raises(SceneError, match='"float32_state" with step control'):
        load_scene(
            "tc2_steady",
            ne=2,
            stepper="rk43",
            precision="float32_state",
            overrides={"time.control": "error", "time.rtol": 1e-6},
        )
    scene = load_scene("tc2_steady", ne=2, precision="float32_state")
    mixed = load_scene("tc2_steady", ne=2, precision="float32_state", overrides={"numerics.compensated": True})
    assert not scene.compensated and scene.as_dict()["compensated"] is False
    assert mixed.compensated and mixed.as_dict()["compensated"] is True
    assert scene_from_dict(scene.as_dict()) == scene and scene_from_dict(mixed.as_dict()) == mixed
    old = {k: v for k, v in scene.as_dict().items() if k != "compensated"}  # written before the flip
    assert scene_from_dict(old).compensated
    assert "compensated" not in load_scene("tc2_steady", ne=2, precision="float32").as_dict()
    assert scene.mass_fixer and "mass_fixer" not in scene.as_dict()
    free = load_scene("tc2_steady", ne=2, precision="float32_state", overrides={"numerics.mass_fixer": False})
    assert not free.mass_fixer and free.as_dict()["mass_fixer"] is False
