"""Scenes resolved for the frozen comparison in ``test_scene_resolvers``: every bundled scene
with and without typical overrides, and the refusals of bad tables, each as ``Scene.as_dict()``
or ``{"error": the SceneError's line}``, with the machine's paths replaced by placeholders so the
record holds on any checkout. ``resolved_scenes.json`` holds them as ``load_scene`` resolved
them before it became per-table resolvers; the test loads them again and compares."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

from swe_sphere.config.scene import list_scenes, load_scene, scene_dir
from swe_sphere.core.errors import SceneError

from meshes import TEMPEST_NE2

FROZEN = Path(__file__).with_name("resolved_scenes.json")

TC2_TERMS = ["continuity", "momentum_advection", "coriolis", "pressure_gradient"]
TC5 = {"case.name": "tc5_mountain", "terms": [*TC2_TERMS, "topography"]}  # tc2_steady's scene switched to TC5
STREAM = {"name": "6h", "every_days": 0.25, "fields": ["h"]}

# load_scene's keywords for each bundled scene: the grid, the step, the run length, the stepper,
# the planet, the hyperviscosity, the start, the reference, the case, the mesh and the output
VARIANTS = {
    "as_is": {},
    "ne4": {"ne": 4},
    "ne6_np3_2days": {"ne": 6, "np_": 3, "days": 2.0},
    "ne4_dt600": {"ne": 4, "dt": 600.0, "days": 1.0},
    "ne2_rk4": {"ne": 2, "stepper": "rk4", "days": 0.5},
    "ne5_output_0.1": {"ne": 5, "overrides": {"output.every_days": 0.1}},
    "output_0.3": {"overrides": {"output.every_days": 0.3}},
    "ne4_short": {"ne": 4, "days": 0.01},
    "small_planet": {"ne": 4, "overrides": {"planet.radius": 6.37122e5}},
    "small_planet_dt": {"ne": 4, "overrides": {"planet.radius": 6.37122e5, "time.dt": 100.0}},
    "planet_omega": {"overrides": {"planet.omega": 1e-4, "planet.gravity": 9.0}},
    "nu": {"ne": 8, "overrides": {"hyperviscosity.nu": 1e15}},
    "efold": {"ne": 8, "overrides": {"hyperviscosity.efold_hours": 6.0, "hyperviscosity.nu_div": 2e15}},
    "nu_no_term": {"overrides": {"hyperviscosity.nu": 1e15, "terms": TC2_TERMS}},
    "subcycle": {"overrides": {"hyperviscosity.subcycle": 3}},
    "dfi": {"ne": 4, "overrides": {"case.initialization": "dfi"}},
    "dfi_span": {"overrides": {"case.initialization": "dfi", "dfi.span_hours": 12.0, "dfi.cutoff_hours": 6.0}},
    "T341": {"overrides": {"case.reference": "T341"}},
    "switch_case": {"ne": 4, "overrides": {"case.name": "tc2_steady"}},
    "map2": {"ne": 3, "overrides": {"grid.map": "element_local"}},
    "map0": {"overrides": {"grid.map": "equiangular"}},
    "stretched": {"ne": 3, "overrides": {"grid.stretch_factor": 2.0, "grid.target_lat": 40.0}},
    "outputs": {
        "ne": 4,
        "overrides": {"output.fields": ["v", "h"], "output.streams": [STREAM], "output.log_every_steps": 10},
    },
    "leapfrog": {"ne": 4, "stepper": "leapfrog", "overrides": {"leapfrog.robert_asselin": 0.1}},
    "other_stepper_option": {"overrides": {"leapfrog.robert_asselin": 0.1, "time.stepper": "rk4"}},
    "description": {"overrides": {"description": "another"}},
}
MESH_VARIANTS = {"mesh": {"mesh": TEMPEST_NE2}, "mesh_np3_days": {"mesh": TEMPEST_NE2, "np_": 3, "days": 2.0}}

# refusals and their notes, each on tc2_steady (or on the scene file ``TOML`` below): load_scene's keywords
REFUSALS = {
    "case_init": {"overrides": {"case.initialization": "spin"}},
    "case_unknown": {"overrides": {"case.name": "tc9"}},
    "case_param": {"overrides": {"case.beta": 1.0}},
    "reference_planet": {"overrides": {"case.reference": "T341", "planet.radius": 1e6}},
    "reference_type": {"overrides": {"case.reference": 341}},
    "reference_exact": {"overrides": {"case.reference": "T341"}},
    "reference_missing": {"overrides": {**TC5, "case.reference": "nowhere.nc"}},
    "file_case": {"overrides": {"case.name": "file", "case.path": "nowhere.nc", "case.time": 0.0}},
    "terms_empty": {"overrides": {"terms": []}},
    "terms_unknown": {"overrides": {"terms": [*TC2_TERMS, "friction"]}},
    "terms_twice": {"overrides": {"terms": [*TC2_TERMS, "coriolis"]}},
    "terms_missing": {"overrides": {"terms": TC2_TERMS[1:]}},
    "terms_forcing": {"overrides": {"terms": [*TC2_TERMS, "forcing"]}},
    "terms_type": {"overrides": {"terms": "continuity"}},
    "dfi_exact": {"overrides": {"case.initialization": "dfi"}},
    "dfi_span": {"overrides": {**TC5, "case.initialization": "dfi", "dfi.span_hours": -1.0}},
    "ne_zero": {"ne": 0},
    "ne_text": {"ne": "8"},
    "ne_float": {"ne": 2.5},
    "np_big": {"np_": 9},
    "np_bool": {"np_": True},
    "np2_map2": {"np_": 2, "overrides": {"grid.map": "element_local"}},
    "grid_ne_override": {"overrides": {"grid.ne": 3, "grid.np": 5}},
    "map_bad": {"overrides": {"grid.map": "gnomonic"}},
    "stretch_alone": {"overrides": {"grid.target_lat": 10.0}},
    "stretch_map0": {"overrides": {"grid.stretch_factor": 2.0, "grid.map": "equiangular"}},
    "stretch_small": {"overrides": {"grid.stretch_factor": 0.5}},
    "stretch_lat": {"overrides": {"grid.stretch_factor": 2.0, "grid.target_lat": 100.0}},
    "stepper_unknown": {"stepper": "euler"},
    "stepper_table": {"overrides": {"time.stepper": "leapfrog", "leapfrog.robert_asselin": -1.0}},
    "stepper_key": {"overrides": {"rk4.order": 4}},
    "every_zero": {"overrides": {"output.every_days": 0.0}},
    "log_negative": {"overrides": {"output.log_every_steps": -1}},
    "days_negative": {"days": -1.0},
    "days_text": {"days": "5"},
    "days_inf": {"days": float("inf")},
    "dt_negative": {"overrides": {"time.dt": -1.0}},
    "dt_zero": {"dt": 0.0},
    "dt_text": {"dt": "60"},
    "dt_odd": {"dt": 7.0, "days": 1.0},
    "dt_tiny": {"dt": 1e-6, "days": 100.0},
    "every_odd": {"dt": 1000.0, "overrides": {"output.every_days": 0.3}},
    "fields_bad": {"overrides": {"output.fields": ["h", "q"]}},
    "fields_empty": {"overrides": {"output.fields": []}},
    "stream_type": {"overrides": {"output.streams": ["6h"]}},
    "stream_key": {"overrides": {"output.streams": [{**STREAM, "every": 1}]}},
    "stream_name": {"overrides": {"output.streams": [{**STREAM, "name": "restart"}]}},
    "stream_twice": {"overrides": {"output.streams": [STREAM, STREAM]}},
    "stream_every": {"overrides": {"output.streams": [{**STREAM, "every_days": 0.0}]}},
    "stream_steps": {
        "dt": 1000.0,
        "overrides": {"output.every_days": 1.25, "output.streams": [{**STREAM, "every_days": 0.3}]},
    },
    "stream_fields": {"overrides": {"output.streams": [{**STREAM, "fields": ["q"]}]}},
    "nu_negative": {"overrides": {"hyperviscosity.nu": -1.0}},
    "efold_zero": {"overrides": {"hyperviscosity.efold_hours": 0.0}},
    "hv_needs_nu": {"overrides": {"terms": [*TC2_TERMS, "hyperviscosity"]}},
    "subcycle_zero": {"overrides": {"hyperviscosity.subcycle": 0}},
    "key_unknown": {"overrides": {"colour": "red"}},
    "key_in_table": {"overrides": {"time.length": 3.0}},
    "not_table": {"overrides": {"grid": 3}},
    "override_bad": {"overrides": {"grid.": 3}},
    "override_section": {"overrides": {"description.x": 3}},
    "float_type": {"overrides": {"time.dt": "fast"}},
    "float_nan": {"overrides": {"time.dt": float("nan")}},
    "planet_bad": {"overrides": {"planet.radius": -1.0}},
    "mesh_and_ne": {"ne": 4, "mesh": TEMPEST_NE2},
    "mesh_file_ne": {"overrides": {"grid.mesh_file": str(TEMPEST_NE2)}},
    "mesh_file_ne0": {"overrides": {"grid.mesh_file": str(TEMPEST_NE2), "grid.ne": 0}},
    "mesh_file_override_ne": {"ne": 3, "overrides": {"grid.mesh_file": str(TEMPEST_NE2), "grid.ne": 0}},
    "mesh_file_stretch": {"overrides": {"grid.mesh_file": str(TEMPEST_NE2), "grid.stretch_factor": 2.0}},
    "mesh_file_missing": {"overrides": {"grid.mesh_file": "nowhere.g", "grid.ne": 0}},
}
MESH_REFUSALS = {"mesh_and_ne", "mesh_file_ne0", "mesh_file_override_ne", "mesh_file_ne"}  # need TEMPEST_NE2 to load

# scene files of their own (stem: text), loaded from a temporary folder with load_scene's keywords
TOML = {
    "no_case": ('terms = ["continuity"]\n[time]\ndt = 60.0\n', {}),
    "no_dt": ('terms = ["continuity"]\n[case]\nname = "tc1_cosine_bell"\n', {}),
    "no_grid": ('terms = ["continuity"]\n[case]\nname = "tc1_cosine_bell"\n[time]\ndt = 900.0\n', {}),
    "no_grid_ne": ('terms = ["continuity"]\n[case]\nname = "tc1_cosine_bell"\n[time]\ndt = 900.0\n', {"ne": 4}),
    "malformed": ("terms = [\n", {}),
    "file_case_beside": ('terms = ["continuity"]\n[case]\nname = "file"\npath = "state.nc"\ntime = 0.0\n', {}),
}


def _plain(value, places: dict):
    """``value`` as JSON would read it back, with the paths of ``places`` replaced by their names."""
    text = json.dumps(value)
    for path, name in places.items():
        text = text.replace(json.dumps(str(path))[1:-1], name)
    return json.loads(text)


def resolved(path, kwargs: dict, places: dict):
    """``load_scene(path, **kwargs)`` as plain values: ``as_dict()`` or {"error": its line}."""
    try:
        value = load_scene(path, **kwargs).as_dict()
    except SceneError as err:
        value = {"error": str(err)}
    return _plain(value, places)


def resolve_all(tmp: Path, with_mesh: bool) -> dict:
    """Every case of this module resolved (the mesh file's only ``with_mesh``), keyed by
    "scene/variant", "refusal/name" and "toml/stem", in ``tmp`` (an empty folder, the current
    one meanwhile, as relative paths resolve there) where the scene files are written."""
    places = {tmp: "<tmp>", TEMPEST_NE2.parent: "<meshes>", scene_dir().parent: "<scenes>"}
    out = {}
    variants = {**VARIANTS, **(MESH_VARIANTS if with_mesh else {})}
    with contextlib.chdir(tmp):
        for path in list_scenes():
            for label, kwargs in variants.items():
                out[f"{path.parent.name}/{path.stem}/{label}"] = resolved(path, kwargs, places)
        for label, kwargs in REFUSALS.items():
            if with_mesh or label not in MESH_REFUSALS:
                out[f"refusal/{label}"] = resolved("tc2_steady", kwargs, places)
        for stem, (text, kwargs) in TOML.items():
            (tmp / f"{stem}.toml").write_text(text)
            out[f"toml/{stem}"] = resolved(tmp / f"{stem}.toml", kwargs, places)
    return out
