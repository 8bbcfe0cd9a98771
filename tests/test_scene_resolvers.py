"""``load_scene`` and its per-table resolvers: every bundled scene resolves as frozen in
``resolved_scenes.json`` (``scene_cases``), and each resolver alone, fed a table, gives its
values or the one-line ``SceneError`` naming the key."""

from __future__ import annotations

import json

from meshes import TEMPEST_NE2
from scene_cases import FROZEN, resolve_all

from swe_sphere.config.scene import load_scene


def test_every_bundled_scene_and_refusal_resolves_as_frozen(tmp_path):
    """Each case's ``as_dict()`` (or SceneError line) equals the frozen one, to the bit (floats
    read back from their shortest repr); the mesh file's cases where the shared meshes are."""
    frozen = json.loads(FROZEN.read_text())
    got = resolve_all(tmp_path, with_mesh=TEMPEST_NE2.is_file())
    assert len(got) >= 580 and sum("error" in v for v in got.values()) >= 120  # the whole record ran
    assert set(got) <= set(frozen)
    differ = [key for key in got if got[key] != frozen[key]]
    assert not differ, f"{len(differ)} differ, first {differ[0]}: {got[differ[0]]} != {frozen[differ[0]]}"


def test_a_dt_set_by_an_override_scales_with_another_grid():
    """-s time.dt is the scene's dt for the grid (scaled from ne = 16 to ne = 4) but the dt
    for the planet given (not scaled with the radius); the note names the grid alone."""
    scene = load_scene("tc2_steady", ne=4, overrides={"planet.radius": 6.37122e5, "time.dt": 100.0})
    assert scene.dt == 400.0
    assert scene.notes == ("dt scaled with the smallest node spacing to 400 s",)
