"""Scenes' hyperviscosity coefficients (HOMME's nu, nu_div, nu_s)."""

from __future__ import annotations

import pytest

from swe_sphere.config import HYPERVIS_EXPONENT, SceneError, load_scene

SCENE = """
terms = ["continuity", "momentum_advection", "coriolis", "pressure_gradient", "hyperviscosity"]
[case]
name = "tc6_rossby_haurwitz"
[grid]
ne = 30
np = 4
[time]
stepper = "rk4"
dt = 90.0
days = 1.0
[hyperviscosity]
"""


def scene_file(tmp_path, table):
    path = tmp_path / "s.toml"
    path.write_text(SCENE + table)
    return path


def test_nu_div_and_nu_s_default_to_nu_and_scale_with_the_grid(tmp_path):
    s = load_scene(scene_file(tmp_path, "nu = 1e15\nnu_div = 3e15\n"))
    assert (s.nu, s.nu_div, s.nu_s) == (1e15, 3e15, 1e15)
    s = load_scene(scene_file(tmp_path, "nu = 1e15\nnu_s = 2e14\n"), ne=15)
    scale = 2.0**HYPERVIS_EXPONENT
    assert (s.nu, s.nu_div, s.nu_s) == pytest.approx((1e15 * scale, 1e15 * scale, 2e14 * scale), rel=1e-12)


@pytest.mark.parametrize("table,needle", [("nu = 1e15\nnu_s = -1.0\n", "hyperviscosity.nu_s"), ("nu = 0.0\n", "hyperviscosity.nu")])
def test_bad_coefficients_name_the_key(tmp_path, table, needle):
    with pytest.raises(SceneError, match=needle):
        load_scene(scene_file(tmp_path, table))
