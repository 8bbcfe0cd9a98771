"""[time] control and its keys (``config.control.resolve_control``): a fixed dt the default and
left out of the scene's record, the defaults of each mode, the record's round trip through
``as_dict``, and each bad setting refused in one line naming its key."""

from __future__ import annotations

import pytest

from swe_sphere.config.scene import load_scene, scene_from_dict
from swe_sphere.config.schema import SceneControl
from swe_sphere.core.errors import SceneError


def _load(stepper="bs32", **keys):
    return load_scene("tc2_steady", ne=4, stepper=stepper, overrides={f"time.{k}": v for k, v in keys.items()})


def test_a_fixed_dt_is_the_default_and_not_in_the_record():
    scene = _load()
    assert scene.control is None and scene.time.control is None
    assert "control" not in scene.as_dict()
    assert _load(control="fixed") == scene


def test_error_and_cfl_control_and_their_defaults():
    scene = _load(control="error", rtol=1e-5, atol=[0.01, 0.1], cfl=1.0, dt_max=3600.0)
    assert scene.control == SceneControl("error", 1e-5, 0.01, 0.1, "pid_bs32", 1.0, scene.dt * 1e-3, 3600.0)
    assert scene.time.control is scene.control
    assert scene_from_dict(scene.as_dict()) == scene
    defaults = _load("ark324", control="error").control
    assert (defaults.rtol, defaults.atol_wind, defaults.atol_h, defaults.controller) == (1e-4, 1e-4, 1e-4, "pi")
    assert defaults.cfl == pytest.approx(0.9 * 0.85) and defaults.cfl_default  # its advective limit's
    assert defaults.dt_max is None and not defaults.per_unit_step
    per_unit = _load(control="error", per_unit_step=True)
    assert per_unit.control.per_unit_step and scene_from_dict(per_unit.as_dict()) == per_unit
    cfl = _load("ssprk3", control="cfl").control  # 0.9 × ssprk3's measured limit 1.11
    assert cfl.mode == "cfl" and cfl.cfl == pytest.approx(0.999) and cfl.rtol is None
    assert _load("imex", control="cfl").control.cfl == pytest.approx(0.9)  # its advective limit 1.0


def test_error_control_caps_the_courant_number_by_default():
    """Under "error" the default cap is 0.9 × the pair's measured Courant limit (dp54 1.28), marked
    as the default (a bound only) and kept through the record; time.cfl replaces it, false removes
    it; the IMEX pairs' is on their advective limit (``tables.IMEX_ADVECTIVE_LIMITS``)."""
    capped = _load("dp54", control="error")
    assert capped.control.cfl == pytest.approx(0.9 * 1.28) and capped.control.cfl_default
    assert scene_from_dict(capped.as_dict()) == capped
    given = _load("dp54", control="error", cfl=0.55).control
    assert (given.cfl, given.cfl_default) == (0.55, False)
    off = _load("dp54", control="error", cfl=False).control
    assert (off.cfl, off.cfl_default) == (None, False)
    assert _load("ark436", control="error").control.cfl == pytest.approx(0.9 * 0.8)
    assert _load("ark324", control="error").control.cfl == pytest.approx(0.9 * 0.85)


def test_balanced_control_and_its_defaults():
    """Under "balanced" the fraction ``balance`` (default 0.1, the sweep's criterion), the pair's
    controller and the default cap, no rtol or atol (the mode sets its tolerances)."""
    scene = _load(control="balanced")
    c = scene.control
    assert (c.mode, c.balance, c.controller, c.rtol, c.atol_wind) == ("balanced", 0.1, "pid_bs32", None, None)
    assert c.cfl_default and c.cfl == pytest.approx(
        0.9 * 1.11
    )  # bs32: 0.9 × its measured limit 1.11 (ssprk3's polynomial)
    assert _load(control="balanced", balance=0.02).control.balance == 0.02
    assert scene_from_dict(scene.as_dict()) == scene


@pytest.mark.parametrize(
    "stepper, keys, words",
    [
        ("bs32", dict(control="adaptive"), "time.control must be one of fixed, cfl, error, balanced (got 'adaptive')"),
        ("bs32", dict(control="balanced", balance=0.0), "time.balance must be a number > 0 (got 0.0)"),
        ("bs32", dict(control="balanced", balance="a lot"), "time.balance must be float (got 'a lot')"),
        ("bs32", dict(control="balanced", rtol=1e-4), "time.rtol is not read under control = 'balanced'"),
        ("bs32", dict(control="error", balance=0.1), "time.balance is not read under control = 'error'"),
        ("bs32", dict(control="balanced", per_unit_step=True), "time.per_unit_step is not read under control = 'bal"),
        ("bs32", dict(control="error", per_unit_step=1), "time.per_unit_step must be bool (got 1)"),
        ("ssprk3", dict(control="balanced"), "time.control = 'balanced' needs an embedded pair; ssprk3 has no"),
        ("bs32", dict(control="error", rtol=0.0), "time.rtol must be > 0 (got 0.0)"),
        ("bs32", dict(control="error", rtol=-1e-3), "time.rtol must be > 0"),
        ("bs32", dict(control="error", controller="pd"), "time.controller must be one of i, pi, pid, h211"),
        ("ssprk3", dict(control="error"), "time.control = 'error' needs an embedded pair; ssprk3 has no error"),
        (
            "leapfrog",
            dict(control="cfl", cfl=0.5),
            "time.control = 'cfl' needs a stepper that can change its dt between steps; leapfrog",
        ),
        ("bs32", dict(control="cfl", dt_min=600.0, dt_max=300.0), "time.dt_min = 600 s is above time.dt_max = 300 s"),
        ("bs32", dict(control="cfl", dt_min=0.0), "time.dt_min and time.dt_max must be > 0"),
        ("bs32", dict(control="error", dt_min=5e4), "time.dt_min = 50000 s is above the first step's dt = "),
        ("bs32", dict(control="cfl", cfl=-1.0), "time.cfl must be > 0 (got -1.0)"),
        ("bs32", dict(control="cfl", cfl=False), "time.cfl must be > 0 (got False, a bool)"),
        ("bs32", dict(control="error", cfl=True), "time.cfl must be > 0 or false (no cap) (got True, a bool)"),
        ("bs32", dict(control="error", atol=[1.0]), "time.atol must be a number >= 0 or"),
        ("bs32", dict(control="error", atol=-1.0), "time.atol must be a number >= 0 or"),
        ("bs32", dict(rtol=1e-3), "time.rtol is not read under control = 'fixed'"),
        ("bs32", dict(control="cfl", controller="pi"), "time.controller is not read under control = 'cfl'"),
        ("tableau", dict(control="cfl"), "time.cfl is missing: tableau has no measured Courant limit"),
    ],
)
def test_a_bad_setting_is_refused_in_one_line(stepper, keys, words):
    with pytest.raises(SceneError) as info:
        _load(stepper, **keys)
    assert str(info.value).startswith(words), str(info.value)
    assert "\n" not in str(info.value)
