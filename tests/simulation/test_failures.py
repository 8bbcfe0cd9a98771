"""Every failure is one line with the right exit status (2 bad input, 3 blow-up /
solver failure / too little memory), across run, stability, sweep, plot, remap
and the environment; the memory guard; semantic checks on scenes; ``-s``
overrides; the Python API; ``--version``; the Δt-cut warning."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

from swe_sphere import __version__
from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import ResourceError, SceneError
from swe_sphere.core.runtime import check_memory, run_bytes

from helpers import TC2_SCENE, TINY, cli_one_line, write_tc2_scene


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def scene_with(tmp_path, name="s.toml", **replace):
    text = TC2_SCENE.format(ne=2, stepper="ssprk3", dt=1800.0, days=1.0, tables="")
    for old, new in replace.items():
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


# -- failures that were tracebacks once, now one line ----------------------------


@pytest.mark.parametrize("value", ["0", "-2", "abc"])
def test_bad_thread_count_is_one_line(capsys, monkeypatch, value):
    monkeypatch.setenv("SWE_SPHERE_THREADS", value)
    cli_one_line(capsys, ["run", "tc2_steady", *TINY, "--days", "0.25"], 2, "SWE_SPHERE_THREADS", repr(value))


def test_tiny_output_interval_with_a_grid_override(tmp_path, capsys):
    """every_days = 1e-12 with --ne: was ZeroDivisionError, then a dt cut to the interval and
    its step count refused; now the interval itself is refused first, in O(1), naming the
    count of times it asks for (``Clock.check_times``)."""
    path = scene_with(tmp_path, **{"days = 1.0": "days = 1.0\n[output]\nevery_days = 1e-12"})
    cli_one_line(capsys, ["run", str(path), "--ne", "3", "--device", "cpu"], 2, "output.every_days", "1e+12 times")


def test_dt_cut_more_than_twice_warns(tmp_path):
    path = scene_with(tmp_path, **{"days = 1.0": "days = 0.01\n[output]\nevery_days = 1e-4"})
    scene = load_scene(path, ne=3)
    warn = [n for n in scene.notes if n.startswith("warning: dt cut")]
    assert len(warn) == 1 and "0.0001 days" in warn[0] and "to 8.64 s" in warn[0], scene.notes
    assert not any(n.startswith("dt scaled") for n in scene.notes), scene.notes  # the warning says it
    assert scene.dt == pytest.approx(8.64)
    assert not any("warning" in n for n in load_scene("tc2_steady", ne=3).notes)  # scaled, cut < 2x: no warning


def test_stability_ne_zero_and_unknown_names(capsys):
    cli_one_line(capsys, ["stability", "--ne", "0", "tc5_mountain"], 2, "--ne", "0")
    cli_one_line(capsys, ["stability", "nope"], 2, "unknown stability case 'nope'")
    cli_one_line(capsys, ["stability", "--steppers", "leapfrog,nope"], 2, "unknown stepper 'nope'")


def test_sweep_bad_input(capsys):
    cli_one_line(capsys, ["sweep", "tc2_steady", "--steppers", "bogus"], 2, "unknown stepper 'bogus'")
    cli_one_line(capsys, ["sweep", "tc2_steady", "--dt", "1,x"], 2, "--dt")
    cli_one_line(capsys, ["sweep", "tc2_steady", "--ne", "0"], 2, "ne must be")


def test_memory_guard_refuses_before_allocating(capsys):
    """--ne 100000 (960 G nodes, about a petabyte, more than any host has): refused by
    the estimate (exit 3, one line), not by a MemoryError after allocating."""
    line = cli_one_line(
        capsys, ["run", "tc2_steady", "--ne", "100000", "--device", "cpu"], 3, "ne=100000 np=4", "GiB of memory"
    )
    assert "available" in line
    assert run_bytes(100000, 4, "ssprk3") > 1e15
    with pytest.raises(ResourceError, match="needs about"):
        check_memory(1 << 62, "this")
    check_memory(1 << 20, "this")  # a MiB is always there


def test_remap_resolution_guard(tmp_path, capsys):
    assert main(["run", "tc2_steady", *TINY, "--days", "0.25", "--output", "r.nc"]) == 0
    capsys.readouterr()
    cli_one_line(capsys, ["remap", "r.nc", "--resolution", "0.01"], 3, "remapping to 0.01 degrees", "18001 x 36000")
    assert not list(tmp_path.glob("*latlon*"))


# -- semantic checks on scenes -------------------------------------------------------


def test_duplicate_and_missing_terms(tmp_path, capsys):
    dup = scene_with(tmp_path, "dup.toml", **{'"coriolis"': '"coriolis", "coriolis"'})
    cli_one_line(capsys, ["run", str(dup), "--device", "cpu"], 2, "term 'coriolis' is listed twice")
    cor = scene_with(
        tmp_path, "cor.toml", **{'"continuity", "momentum_advection", "coriolis", "pressure_gradient"': '"coriolis"'}
    )
    cli_one_line(
        capsys,
        ["run", str(cor), "--device", "cpu"],
        2,
        "case tc2_steady needs the term(s) continuity, momentum_advection, pressure_gradient",
    )
    # TC1 declares continuity alone valid; TC5 needs its topography
    assert load_scene("tc1_cosine_bell").terms == ("continuity",)
    with pytest.raises(SceneError, match="needs the term\\(s\\) topography"):
        load_scene(
            "tc5_mountain", overrides={"terms": ["continuity", "momentum_advection", "coriolis", "pressure_gradient"]}
        )


def test_plot_diff_refuses_another_case_unless_forced(tmp_path, capsys):
    assert main(["run", "tc2_steady", *TINY, "--days", "1", "--output", "tc2.nc"]) == 0
    assert main(["run", "tc6_rossby_haurwitz", *TINY, "--days", "1", "--output", "tc6.nc"]) == 0
    assert (
        main(
            [
                "run",
                "tc2_steady",
                "--ne",
                "3",
                "--device",
                "cpu",
                "--no-progress",
                "--days",
                "1",
                "--output",
                "tc2ne3.nc",
            ]
        )
        == 0
    )
    capsys.readouterr()
    cli_one_line(
        capsys, ["plot", "tc2.nc", "--diff", "tc6.nc", "--output", "png"], 2, "case tc6_rossby_haurwitz", "--force"
    )
    cli_one_line(capsys, ["plot", "tc2.nc", "--diff", "tc2ne3.nc", "--output", "png"], 2, "ne=3 np=4", "--force")
    from swe_sphere.cases.reference import find_reference

    cli_one_line(
        capsys,
        ["plot", "tc2.nc", "--diff", str(find_reference("tc5_mountain")), "--output", "png"],
        2,
        "tc5_mountain_T213.nc is not a reference of case tc2_steady",
    )
    assert not (tmp_path / "png").exists()
    assert main(["plot", "tc2.nc", "--diff", "tc6.nc", "--output", "png", "--force"]) == 0
    assert len(list((tmp_path / "png").glob("*.png"))) == 2


# -- overrides, version, API ----------------------------------------------------------


def test_set_overrides_are_validated_like_the_file(tmp_path, capsys):
    scene = load_scene("tc5_mountain", overrides={"hyperviscosity.nu": 5e14, "output.every_days": 0.25})
    assert scene.output_every_days == 0.25 and scene.nu == 5e14
    cli_one_line(
        capsys,
        ["run", "tc5_mountain", "-s", "hyperviscosity.nu=-1", "--device", "cpu"],
        2,
        "hyperviscosity.nu must be >= 0",
    )
    cli_one_line(
        capsys,
        ["run", "tc5_mountain", "-s", "implicit.preconditioner=amg", "--stepper", "implicit", "--device", "cpu"],
        2,
        "implicit.preconditioner must be",
    )
    cli_one_line(capsys, ["run", "tc5_mountain", "-s", "bogus.key=1", "--device", "cpu"], 2, "unknown key 'bogus'")
    cli_one_line(capsys, ["run", "tc5_mountain", "-s", "time.dt=abc", "--device", "cpu"], 2, "time.dt must be float")
    cli_one_line(capsys, ["run", "tc5_mountain", "-s", "nonsense", "--device", "cpu"], 2, "SECTION.KEY=VALUE")
    assert (
        main(["run", "tc2_steady", *TINY, "--days", "0.25", "-s", "output.every_days=0.125", "--output", "o.nc"]) == 0
    )
    with xr.open_dataset(tmp_path / "o.nc", decode_times=False) as ds:
        np.testing.assert_allclose(ds.time.values, [0, 0.125, 0.25])


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"swe-sphere {__version__}"


def test_python_api_is_quiet_and_returns_a_dataset(tmp_path):
    """In a fresh interpreter (Warp not yet initialised): nothing on stderr, a
    Dataset with numeric time, overrides by table."""
    code = (
        "import swe_sphere\n"
        "ds = swe_sphere.run('tc2_steady', ne=2, days=0.5, device='cpu', output={'every_days': 0.25}, output_file='api.nc')\n"
        "print(list(ds.time.values), ds.h.sel(time=0.5).shape, ds.attrs['stepper'])\n"
        "print(swe_sphere.Simulation.__name__, swe_sphere.load_scene('tc2_steady').case)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert proc.stdout.splitlines() == [
        "[np.float64(0.0), np.float64(0.25), np.float64(0.5)] (218,) ssprk3",
        "Simulation tc2_steady",
    ]
    assert (tmp_path / "api.nc").is_file()


def test_api_overrides_and_errors():
    import swe_sphere

    with pytest.raises(SceneError, match="unknown key 'nope'"):
        swe_sphere.run("tc2_steady", ne=2, days=0.25, device="cpu", nope={"x": 1})
    scene = load_scene("tc2_steady", ne=2, days=0.25)
    with pytest.raises(SceneError, match="dataclasses.replace"):
        swe_sphere.run(scene, ne=3)
    ds = swe_sphere.run(dataclasses.replace(scene, stepper="rk4"), device="cpu")
    assert ds.attrs["stepper"] == "rk4" and ds.sizes["time"] == 2


def test_compress_stores_float32(tmp_path):
    assert main(["run", "tc2_steady", *TINY, "--days", "0.25", "--output", "c.nc", "--compress"]) == 0
    assert main(["run", "tc2_steady", *TINY, "--days", "0.25", "--output", "f.nc"]) == 0
    with (
        xr.open_dataset(tmp_path / "c.nc", decode_times=False) as c,
        xr.open_dataset(tmp_path / "f.nc", decode_times=False) as f,
    ):
        assert c.h.encoding["dtype"] == np.float32 and c.h.encoding["zlib"]
        assert f.h.encoding["dtype"] == np.float64
        np.testing.assert_allclose(c.h.values, f.h.values, rtol=1e-7)


def test_explicit_dt_above_the_stability_limit_warns(tmp_path):
    """leapfrog on TC2 ne = 2: dt = 3600 s (Courant sum 0.77 > 0.58) warns and does blow
    up; dt = 1800 s (0.38) neither warns nor blows up."""
    from helpers import make_sim, run

    fast = make_sim(load_scene(write_tc2_scene(tmp_path / "a.toml", stepper="leapfrog", dt=3600.0, days=2.0)))
    warning = fast.stability_warning()
    assert warning is not None and "leapfrog's stability limit of about 0.58" in warning
    slow = load_scene(write_tc2_scene(tmp_path / "b.toml", stepper="leapfrog", dt=1800.0, days=2.0))
    assert make_sim(slow).stability_warning() is None
    assert run(fast.scene)[0].blowup is not None
    assert run(slow)[0].blowup is None
    assert make_sim(dataclasses.replace(slow, stepper="implicit", dt=7200.0)).stability_warning() is None


def test_imex_dt_above_its_advective_limit_warns(tmp_path):
    """IMEX treats advection explicitly: on TC2 ne = 2, dt = 12 h gives |v| dt/dx = 1.69
    (> 1.0, Imex.advective_courant_limit) and warns with the dt that keeps below; 6 h
    (0.85) does not, though its gravity-wave Courant number is 3.8."""
    from helpers import make_sim

    big = load_scene(write_tc2_scene(tmp_path / "a.toml", stepper="imex", dt=43200.0, days=2.0))
    warning = make_sim(big).stability_warning()
    assert warning is not None and "advective Courant number |v| dt/dx of 1.69" in warning
    assert "imex's stability limit of about 1 " in warning and "dt <= 2.55e+04 s" in warning
    assert make_sim(big).largest_dt_within_limit() == pytest.approx(43200.0 / 1.69, rel=3e-3)  # the dt it offers
    assert make_sim(dataclasses.replace(big, dt=21600.0)).stability_warning() is None


def test_api_errors_are_importable_and_name_the_api():
    import swe_sphere
    from swe_sphere.config import scene as config
    from swe_sphere.io import output_files as output

    assert swe_sphere.SceneError is config.SceneError and swe_sphere.OutputError is output.OutputError
    for name in ("CheckpointError", "BlowUp", "Interrupted", "StepFailure", "ResourceError"):
        assert issubclass(getattr(swe_sphere, name), Exception)
    with pytest.raises(swe_sphere.SceneError, match=r"ne must be an integer >= 1 \(got '8', a str\)"):
        swe_sphere.run("tc2_steady", ne="8", days=1, device="cpu")
    with pytest.raises(swe_sphere.SceneError, match=r"dt must be > 0 \(got '60', a str\)"):
        swe_sphere.run("tc2_steady", ne=2, dt="60", days=1, device="cpu")
