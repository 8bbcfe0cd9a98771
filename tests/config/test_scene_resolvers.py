"""``load_scene`` and its per-table resolvers: every bundled scene resolves as frozen in
``resolved_scenes.json`` (``scene_cases``), and each resolver alone, fed a table, gives its
values or the one-line ``SceneError`` naming the key."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest

from swe_sphere.cases.library import make_case
from swe_sphere.config.hyperviscosity import HYPERVIS_EXPONENT, efold_nu, resolve_hyperviscosity
from swe_sphere.config.resolve import (
    Spacing,
    resolve_case,
    resolve_dt_np,
    resolve_grid,
    resolve_initialization,
    resolve_output_files,
    resolve_output_interval,
    resolve_planet,
    resolve_spacing,
    resolve_stepper_days,
    resolve_stepper_options,
    resolve_terms,
    scene_title,
)
from swe_sphere.config.scene import load_scene
from swe_sphere.config.schema import SceneGrid, SceneHyperviscosity, SceneOutput, SceneTime, read_scene
from swe_sphere.config.step_rule import Times, scene_dt
from swe_sphere.core.constants import DAY, EARTH, Planet
from swe_sphere.core.errors import SceneError
from swe_sphere.grid.quality import smallest_dx
from swe_sphere.grid.refine import make_mesh
from swe_sphere.io.run_file import OUTPUT_FIELDS
from swe_sphere.mesh.mesh import write_exodus
from swe_sphere.mesh.records import CubeMesh, StretchedCube

from meshes import TEMPEST_NE2
from roundoff import bound
from scene_cases import FROZEN, resolve_all


def test_every_bundled_scene_and_refusal_resolves_as_frozen(tmp_path):
    """Each case's ``as_dict()`` (or SceneError line) equals the frozen one, to the bit (floats
    read back from their shortest repr); the mesh file's cases where the shared meshes are."""
    frozen = json.loads(FROZEN.read_text())
    with_mesh = TEMPEST_NE2.is_file()
    got = resolve_all(tmp_path, with_mesh=with_mesh)
    ran = len(got) >= (600 if with_mesh else 560)  # the whole record (the mesh file's 41 cases apart)
    assert ran and sum("error" in v for v in got.values()) >= 120, len(got)
    assert set(got) <= set(frozen)
    differ = [key for key in got if got[key] != frozen[key]]
    assert not differ, f"{len(differ)} differ, first {differ[0]}: {got[differ[0]]} != {frozen[differ[0]]}"


def test_a_scaled_dt_divides_the_streams_intervals_too():
    """tc2_steady at ne2 with a 0.3-day stream: the scaled dt (2400 s, 10.8 steps in 0.3 days)
    was refused for the stream alone, though it is cut to divide the main output interval; it is
    cut for the stream too. A dt given is still refused for it."""
    streams = {"output.every_days": 0.5, "output.streams": [{"name": "a", "every_days": 0.3, "fields": ["h"]}]}
    scene = load_scene("tc2_steady", ne=2, days=1.0, overrides=streams)
    for days in (0.3, 0.5, 1.0):
        steps = days * DAY / scene.dt
        assert abs(steps - round(steps)) < 1e-9, (days, scene.dt)
    assert scene.dt == 2160.0
    with pytest.raises(SceneError, match=r"output.streams\[0\].every_days of 0.3 days is not a whole number"):
        load_scene("tc2_steady", ne=2, days=1.0, dt=2400.0, overrides=streams)


def test_a_dt_set_by_an_override_scales_with_another_grid():
    """-s time.dt is the scene's dt for the grid (scaled from ne = 16 to ne = 4) but the dt
    for the planet given (not scaled with the radius); the note names the grid alone."""
    scene = load_scene("tc2_steady", ne=4, overrides={"planet.radius": 6.37122e5, "time.dt": 100.0})
    assert scene.dt == 400.0
    assert scene.notes == ("dt scaled with the smallest node spacing to 400 s",)


def test_every_way_of_choosing_the_mesh_scales_dt_alike(tmp_path):
    """The scene file's dt is for its own grid (tc5_mountain: ne30): -s grid.ne, -s grid.stretch_factor
    and -s grid.mesh_file scale it with the smallest node spacing as ne= and mesh= do (the ∇⁴ every
    step, so that the spacing's dt is not shortened for a sparser ∇⁴: ``sparse_dt``, where ne8's 109
    steps a day become 110)."""
    dense = {"hyperviscosity.every": 1}
    by_key = load_scene("tc5_mountain", overrides={"grid.ne": 8, **dense})
    assert by_key.dt == load_scene("tc5_mountain", ne=8, overrides=dense).dt == 86400 / 109
    assert load_scene("tc5_mountain", overrides={"grid.ne": 8}).dt == load_scene("tc5_mountain", ne=8).dt == 86400 / 110
    stretch = {"grid.stretch_factor": 2.5, "grid.target_lat": 30.0, "grid.target_lon": 270.0}
    stretched = load_scene("tc5_mountain", ne=8, overrides={**stretch, **dense})
    # ne8 c = 2.5: its worst dx_short is 2.23x below ne8's cube: 243 steps a day where the cube takes 109
    ratio = smallest_dx(8, 4, make_mesh(8, stretch_factor=2.5, target_lat=30.0, target_lon=270.0)) / smallest_dx(30, 4)
    assert stretched.dt == 86400 / math.ceil(86400 / (211.76470588235293 * ratio)) == 86400 / 243
    path = write_exodus(tmp_path / "ne3.g", make_mesh(3))
    by_key = load_scene("tc5_mountain", overrides={"grid.mesh_file": str(path), "grid.ne": 0, **dense})
    assert by_key.dt == load_scene("tc5_mountain", mesh=path, overrides=dense).dt == 86400 / 49


A = EARTH.a
SAME = Spacing(mean=1.0, smallest=1.0, scale=1.0, radii=(A, A))  # the run's grid and planet are the scene file's
STRETCHED = StretchedCube(4, 2.0, 40.0, 0.0)
HV_TERMS = ("continuity", "momentum_advection", "coriolis", "pressure_gradient", "hyperviscosity")


def test_read_scene_applies_overrides_and_keeps_the_files_own_radius_and_case(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[case]\nname = "tc2_steady"\n[planet]\nradius = 1e6\n[time]\ndt = 60\n')
    tables, radius, case, grid, own = read_scene(
        path, {"planet.radius": 2e6, "case.name": "tc5_mountain", "grid.ne": 8}
    )
    assert tables == {
        "case": {"name": "tc5_mountain"},
        "planet": {"radius": 2e6},
        "time": {"dt": 60.0},
        "grid": {"ne": 8},
    }
    assert (radius, case, grid) == (1e6, "tc2_steady", {})  # the file's, before the overrides
    assert own == {"case": {"name": "tc2_steady"}, "planet": {"radius": 1e6}, "time": {"dt": 60.0}}
    assert read_scene(path, {"time.dt": 30.0})[1] is None  # a dt of the override's own: no radius to scale from
    with pytest.raises(
        SceneError,
        match=r"^unknown key time.length in scene \(known: stepper, dt, dt_np, days, control, rtol, atol, per_unit_step, controller, cfl, dt_min, dt_max, balance\)$",
    ):
        read_scene(path, {"time.length": 3.0})
    path.write_text("terms = [\n")
    with pytest.raises(SceneError, match=r"^malformed TOML in .*s\.toml: "):
        read_scene(path, {})


def test_resolve_planet_fills_williamsons_earth_and_names_a_bad_key():
    assert resolve_planet(None) == EARTH
    assert resolve_planet({"radius": 1e6}) == Planet(a=1e6, omega=7.292e-5, g=9.80616)
    with pytest.raises(SceneError, match=r"^planet.radius must be a positive finite number \(got -1.0\)$"):
        resolve_planet({"radius": -1.0})


def test_resolve_case_splits_the_table_and_notes_an_unused_reference():
    case = resolve_case({"name": "tc2_steady", "alpha": 0.5}, EARTH, Path("s.toml"))
    assert (case.name, case.params, case.method, case.reference, case.notes) == (
        "tc2_steady",
        {"alpha": 0.5},
        "none",
        None,
        (),
    )
    assert case.case.exact_solution
    small = resolve_case({"name": "tc5_mountain", "initialization": "dfi"}, Planet(a=A / 10), Path("s.toml"))
    assert small.method == "dfi" and small.params == {}
    assert small.notes == (
        "not scored against the tc5_mountain_T213.nc reference: it is of Williamson's Earth, not of this planet "
        "(radius 637122 m, omega 7.292e-05 1/s, gravity 9.80616 m/s^2)",
    )
    with pytest.raises(SceneError, match=r"^case.name is missing$"):
        resolve_case({"alpha": 0.5}, EARTH, Path("s.toml"))
    with pytest.raises(SceneError, match=r"^case.initialization must be one of none, dfi \(got 'spin'\)$"):
        resolve_case({"name": "tc5_mountain", "initialization": "spin"}, EARTH, Path("s.toml"))
    with pytest.raises(SceneError, match=r"^case.reference = 'T341': the spectral references are of Williamson's"):
        resolve_case({"name": "tc5_mountain", "reference": "T341"}, Planet(a=A / 10), Path("s.toml"))


def test_resolve_case_finds_a_state_file_beside_the_scene(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "state.nc").write_bytes(b"")
    with pytest.raises(SceneError, match=r"^case.path = '(.*)/scenes/state.nc': ") as beside:
        resolve_case({"name": "file", "path": "state.nc", "time": 0.0}, EARTH, tmp_path / "scenes" / "s.toml")
    assert beside.value.args[0].startswith(f"case.path = '{tmp_path}/scenes/state.nc'")  # not the current folder's


def test_resolve_terms_keeps_the_order_and_names_the_term():
    tc1 = make_case("tc1_cosine_bell")
    assert resolve_terms(["continuity"], tc1, "tc1_cosine_bell") == ("continuity",)
    with pytest.raises(SceneError, match=r"^term 'continuity' is listed twice in terms$"):
        resolve_terms(["continuity", "continuity"], tc1, "tc1_cosine_bell")
    with pytest.raises(SceneError, match=r"^case tc5_mountain needs the term\(s\) topography \(terms = "):
        resolve_terms(list(HV_TERMS), make_case("tc5_mountain"), "tc5_mountain")


def test_resolve_initialization_builds_the_digital_filter_or_refuses_an_exact_case():
    tc5 = make_case("tc5_mountain")
    assert resolve_initialization("none", {"span_hours": 12.0}, tc5, "tc5_mountain") is None
    dfi = resolve_initialization("dfi", {"span_hours": 12.0, "cutoff_hours": 6.0}, tc5, "tc5_mountain")
    assert dfi == {"method": "dfi", "span_hours": 12.0, "cutoff_hours": 6.0}
    with pytest.raises(SceneError, match=r"^dfi.span_hours must be > 0 \(got -1.0\)$"):
        resolve_initialization("dfi", {"span_hours": -1.0}, tc5, "tc5_mountain")
    with pytest.raises(SceneError, match=r"^case.initialization = \"dfi\" would spoil case tc2_steady's exact"):
        resolve_initialization("dfi", {}, make_case("tc2_steady"), "tc2_steady")


def test_resolve_grid_gives_the_files_grid_and_the_runs():
    path = Path("s.toml")
    default = SceneGrid(16, 4, None)
    assert resolve_grid(None, path) == (default, default, ("the scene has no [grid]: ne = 16, np = 4 (the defaults)",))
    assert resolve_grid({"ne": 8, "np": 3}, path, ne=4) == (SceneGrid(8, 3), SceneGrid(4, 3), ())
    map2 = CubeMesh(8, "element_local")
    assert resolve_grid({"ne": 8, "map": "element_local"}, path, np_=5) == (
        SceneGrid(8, 4, map2),
        SceneGrid(8, 5, map2),
        (),
    )
    with pytest.raises(SceneError, match=r"^np must be an integer in 2\.\.8 \(got 9\)$"):
        resolve_grid({"ne": 8}, path, np_=9)
    with pytest.raises(SceneError, match=r"^grid.stretch_factor must be >= 1 \(got 0.5\)$"):
        resolve_grid({"ne": 8, "stretch_factor": 0.5}, path)


@pytest.mark.skipif(not TEMPEST_NE2.is_file(), reason="needs the shared meshes")
def test_resolve_grid_takes_a_mesh_file_for_the_run():
    scene, run, notes = resolve_grid({"ne": 16}, Path("s.toml"), mesh=TEMPEST_NE2)
    assert scene == SceneGrid(16, 4) and (run.ne, run.np, run.mesh.nelem, notes) == (0, 4, 24, ())
    assert resolve_grid({"ne": 16, "map": "equiangular"}, Path("s.toml"), mesh=TEMPEST_NE2)[1].mesh.map == "equiangular"
    with pytest.raises(SceneError, match=r"^ne = 4 and mesh .*TEMPEST_NE2.g: a mesh file's elements are its own"):
        resolve_grid({}, Path("s.toml"), ne=4, mesh=TEMPEST_NE2)


def test_resolve_spacing_of_the_grid_and_the_planet():
    gap3, gap4 = 1.0, 1 - 1 / math.sqrt(5)  # first GLL intervals of np = 3 and 4 on [-1, 1]
    assert resolve_spacing(SceneGrid(16, 4), SceneGrid(16, 4), A, A) == SAME
    assert resolve_spacing(SceneGrid(16, 4), SceneGrid(8, 4), A, A) == Spacing(2.0, 2.0, 1.0, (A, A))
    coarse = resolve_spacing(SceneGrid(4, 4), SceneGrid(4, 3), A, A)
    # the GLL nodes (each within a few ε), their gaps and three divisions: 16 roundings at most
    assert coarse.mean == 1.5 and abs(coarse.smallest - gap3 / gap4) <= bound(16, gap3 / gap4)
    small = resolve_spacing(SceneGrid(16, 4), SceneGrid(16, 4), A / 10, A)
    assert small == Spacing(1.0, 0.1, 0.1, (A / 10, A))
    assert resolve_spacing(SceneGrid(16, 4), SceneGrid(16, 4), A / 10, None) == Spacing(1.0, 1.0, 1.0, (A / 10, None))
    stretched = resolve_spacing(SceneGrid(4, 4), SceneGrid(4, 4, STRETCHED), A, A)
    assert stretched.mean == 1.0 and 0 < stretched.smallest < 1  # the stretch shrinks the smallest spacing


def test_resolve_output_interval_defaults_and_refusals():
    assert resolve_output_interval({}) == (1.0, 0)
    assert resolve_output_interval({"every_days": 0.25, "log_every_steps": 10}) == (0.25, 10)
    with pytest.raises(SceneError, match=r"^output.every_days must be > 0 \(got 0.0\)$"):
        resolve_output_interval({"every_days": 0.0})
    with pytest.raises(SceneError, match=r"^output.log_every_steps must be >= 0 \(got -1; 0: no log lines\)$"):
        resolve_output_interval({"log_every_steps": -1})


def test_resolve_stepper_days_prefers_the_keywords():
    assert resolve_stepper_days({}) == ("ssprk3", 1.0)
    assert resolve_stepper_days({"stepper": "rk4", "days": 3.0}) == ("rk4", 3.0)
    assert resolve_stepper_days({"stepper": "rk4", "days": 3.0}, "leapfrog", 2.0) == ("leapfrog", 2.0)
    with pytest.raises(SceneError, match=r"^unknown stepper 'euler' \(known: leapfrog, "):
        resolve_stepper_days({"stepper": "euler"})
    with pytest.raises(SceneError, match=r"^days must be > 0 \(got '5', a str\)$"):
        resolve_stepper_days({}, days="5")


def test_the_step_rule_scales_and_cuts_the_scenes_dt():
    grid = SceneGrid(4, 4)
    assert scene_dt(None, 60.0, "s", grid, SAME, Times(1.0, 1.0)) == (60.0, "the dt given", ())
    assert scene_dt(300.0, None, "s", grid, SAME, Times(5.0, 1.0)) == (300.0, "time.dt of scene s", ())
    coarse = Spacing(4.0, 4.0, 1.0, (A, A))  # ne 16 -> 4: a 4x larger spacing, a dt 4x longer
    assert scene_dt(300.0, None, "s", grid, coarse, Times(5.0, 1.0)) == (
        1200.0,
        "time.dt of scene s scaled to ne=4 np=4",
        ("dt scaled with the smallest node spacing to 1200 s",),
    )
    # a run of 0.005 days (432 s) is one step of 432 s, not 1200 s
    dt, _, notes = scene_dt(300.0, None, "s", grid, coarse, Times(0.005, 1.0))
    assert dt == 432.0 and notes == (
        "warning: dt cut 2.78x (from 1200 s, scaled with the smallest node spacing) to 432 s to divide the run "
        "length of 0.005 days",
    )
    small = Spacing(1.0, 0.1, 0.1, (A / 10, A))
    assert scene_dt(300.0, None, "s", SceneGrid(16, 4), small, Times(5.0, 1.0)) == (
        30.0,
        "time.dt of scene s scaled to ne=16 np=4 radius=637122 m",
        ("dt scaled with the planet's radius (637122 m against the scene's 6.37122e+06 m) to 30 s",),
    )
    with pytest.raises(SceneError, match=r"^time.dt is missing$"):
        scene_dt(None, None, "s", grid, SAME, Times(1.0, 1.0))
    with pytest.raises(SceneError, match=r"^the run length of 1 days is not a whole number of steps of dt = 7 s"):
        scene_dt(None, 7.0, "s", grid, SAME, Times(1.0, 1.0))


def test_time_dt_np_lengthens_a_scaled_dt_at_the_np_it_names():
    """galewsky's ``dt_np = {6 = 1.2}``: at np 6 its scaled dt is 1.2x the spacing's (then cut to
    divide a day), the note saying so; at its own np 8 and at np 4 the spacing's alone; a file
    whose own np is named is scaled by the ratio of the two factors; bad keys are refused."""
    dense = {"hyperviscosity.every": 1}  # the scaled dt alone, not shortened for a sparser ∇⁴ (``sparse_dt``)
    plain = load_scene("galewsky", ne=25, np_=6, overrides={"time.dt_np": {}, **dense})
    longer = load_scene("galewsky", ne=25, np_=6, overrides=dense)
    assert plain.dt == DAY / 624 and longer.dt == DAY / 520  # 624 / 1.2 = 520 steps a day
    assert longer.notes[0] == "dt scaled with the smallest node spacing and time.dt_np (1.2x at np 6) to 166.154 s"
    for ne, np_ in ((12, 8), (30, 4)):
        assert (
            load_scene("galewsky", ne=ne, np_=np_).dt
            == load_scene("galewsky", ne=ne, np_=np_, overrides={"time.dt_np": {}}).dt
        )
    assert resolve_dt_np({"dt_np": {"6": 1.2}}, 8, 6) == 1.2
    assert resolve_dt_np({"dt_np": {"6": 1.5, "4": 3.0}}, 6, 4) == 2.0
    assert resolve_dt_np({}, 6, 4) == 1.0
    with pytest.raises(SceneError, match=r"^time.dt_np keys must be np values 2-\d+ \(got 'six'\)$"):
        resolve_dt_np({"dt_np": {"six": 1.2}}, 8, 6)
    with pytest.raises(SceneError, match=r"^time.dt_np.6 must be a number > 0 \(got -1\)$"):
        load_scene("galewsky", ne=4, np_=6, overrides={"time.dt_np": {"6": -1}})


def test_resolve_output_files_orders_the_fields_and_checks_the_streams():
    output = {"fields": ["v", "h"], "streams": [{"name": "6h", "every_days": 0.25}]}
    assert resolve_output_files(output, 300.0, 1.0, "x") == (
        ("h", "v"),
        ({"name": "6h", "every_days": 0.25, "fields": OUTPUT_FIELDS},),
    )
    assert resolve_output_files({}, 300.0, 1.0, "x") == ((), ())
    with pytest.raises(SceneError, match=r"^output.streams\[0\].name must be a distinct file-name suffix"):
        resolve_output_files({"streams": [{"name": "restart", "every_days": 1.0}]}, 300.0, 1.0, "x")


def test_resolve_stepper_options_checks_them_and_warns_of_another_steppers():
    assert resolve_stepper_options("leapfrog", {"robert_asselin": 0.1}, {}) == ({"robert_asselin": 0.1}, ())
    options, notes = resolve_stepper_options("rk4", {}, {"leapfrog.robert_asselin": 0.1, "time.dt": 60.0})
    assert options == {} and notes == (
        "warning: -s leapfrog.robert_asselin: not an option of rk4, the stepper that runs; not used",
    )
    with pytest.raises(SceneError, match=r"^leapfrog.robert_asselin must be in \[0, 0.5\) \(got -1.0\)$"):
        resolve_stepper_options("leapfrog", {"robert_asselin": -1.0}, {})


def test_resolve_hyperviscosity_scales_the_coefficients_given_and_the_efold_rule():
    grid = SceneGrid(16, 4)
    assert resolve_hyperviscosity({"nu": 1e15}, HV_TERMS, grid, SAME) == (SceneHyperviscosity(1e15, 1e15, 1e15, 1), ())
    coarse = Spacing(2.0, 2.0, 1.0, (A, A))  # ne 16 -> 8
    hv, notes = resolve_hyperviscosity({"nu": 1e15, "subcycle": 2}, HV_TERMS, SceneGrid(8, 4), coarse)
    nu = 1e15 * 2.0**HYPERVIS_EXPONENT
    assert hv == SceneHyperviscosity(nu, nu, nu, 2)
    assert notes == ("nu scaled as dx^3.2 and radius^4: nu, nu_div, nu_s = 9.19e+15, 9.19e+15, 9.19e+15 m^4/s",)
    rule = efold_nu(3.0, 16, 4, A)
    efold = resolve_hyperviscosity({"efold_hours": 3.0, "nu_div": 5e14}, HV_TERMS, grid, SAME)
    assert efold == (SceneHyperviscosity(rule, 5e14, rule, 1), ())
    unused = resolve_hyperviscosity({"nu": 1e15}, HV_TERMS[:-1], grid, SAME)
    assert unused == (
        SceneHyperviscosity(0.0, 0.0, 0.0, 1),
        ("hyperviscosity coefficients given, but the scene's terms have no hyperviscosity: not used",),
    )
    with pytest.raises(SceneError, match=r"^hyperviscosity.nu_s must be >= 0 \(got -1.0\)$"):
        resolve_hyperviscosity({"nu_s": -1.0}, HV_TERMS, grid, SAME)
    with pytest.raises(SceneError, match=r"^the hyperviscosity term needs hyperviscosity.nu, nu_div, nu_s or efold"):
        resolve_hyperviscosity({}, HV_TERMS, grid, SAME)


def test_scene_title_says_when_the_case_is_switched():
    assert scene_title("tc2_steady", "tc2_steady", "tc2_steady", "TC2") == ("tc2_steady", "TC2")
    assert scene_title("tc5_mountain", "tc2_steady", "tc2_steady", "TC2") == (
        "tc5_mountain_in_tc2_steady",
        "case tc5_mountain with scene tc2_steady's grid, terms and stepping",
    )


def test_the_nested_view_groups_the_flat_fields_by_table():
    scene = load_scene("tc6_rossby_haurwitz", ne=4, days=1.0, overrides={"output.fields": ["h"]})
    assert scene.grid == SceneGrid(4, 4, None)
    # ne30's 300 s: 2250 s at ne4, 39 a day; 48 take the ∇⁴ every 2 steps for less (``sparse_dt``)
    assert scene.time == SceneTime("kgu35", {}, 86400 / 48, 1.0)
    hv = SceneHyperviscosity(scene.nu, scene.nu_div, scene.nu_s, 1, every=2)
    assert scene.hyperviscosity == hv and scene.nu > 0
    assert scene.output == SceneOutput(1.0, 0, ("h",), ())
    with pytest.raises(AttributeError):
        scene.grid = SceneGrid(8, 4)
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.time.dt = 60.0


def test_load_scene_takes_an_ensemble_and_members_as_run_does():
    # issue 117 item 8: Python's TypeError before; a table as ``run``'s keyword, members its count
    plain = load_scene("tc2_steady", ne=2)
    assert plain.ensemble is None
    table = load_scene("tc2_steady", ne=2, ensemble={"members": 2, "perturbation": 0.5})
    assert table.ensemble == {"members": 2, "perturbation": 0.5, "seed": 0}
    counted = load_scene("tc2_steady", ne=2, members=3)
    assert counted.ensemble == {"members": 3, "perturbation": 0.0, "seed": 0}
    both = load_scene("tc2_steady", ne=2, members=3, ensemble={"seed": 7})
    assert both.ensemble == {"members": 3, "perturbation": 0.0, "seed": 7}
    # the other tables and values as run takes them, merged into the file's tables
    out = load_scene("tc2_steady", ne=2, output={"every_days": 0.5}, overrides={"output.fields": ["h"]})
    assert out.output == SceneOutput(0.5, 0, ("h",), ()) and plain.output.every_days == 1.0
    with pytest.raises(SceneError, match=r"^members = 2 and ensemble.members = 3: give one of them"):
        load_scene("tc2_steady", members=2, ensemble={"members": 3})
    with pytest.raises(SceneError, match=r"ensemble.members must be an integer >= 1 \(got 0\)"):
        load_scene("tc2_steady", members=0)


@pytest.mark.parametrize(
    ("override", "line"),
    [
        ({"case.alpha": math.nan}, "case.alpha must be finite (got nan)"),
        ({"case.alpha": math.inf}, "case.alpha must be finite (got inf)"),
        ({"hyperviscosity.nu": -math.inf}, "hyperviscosity.nu must be finite (got -inf)"),
        ({"output.streams": [{"name": "6h", "every_days": math.nan}]}, "output.streams[0].every_days must be finite"),
    ],
)
def test_every_float_a_scene_takes_is_finite(override, line):
    """No float a scene takes may be a NaN or an infinity: one line naming the key (issue 65)."""
    with pytest.raises(SceneError) as err:
        load_scene("tc2_steady", overrides=override)
    assert str(err.value).startswith(line) and "\n" not in str(err.value)


def test_the_command_line_refuses_a_nan_case_parameter_with_exit_2(capsys, tmp_path, monkeypatch):
    from helpers import cli_one_line

    monkeypatch.chdir(tmp_path)
    for text in ("nan", "inf"):
        cli_one_line(
            capsys, ["run", "tc2_steady", "-s", f"case.alpha={text}"], 2, f"case.alpha must be finite (got {text})"
        )
    assert list(tmp_path.iterdir()) == []  # nothing written
