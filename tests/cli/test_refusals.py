"""Bad input (exit 2, one line naming the field or value, no file) and blow-ups (exit 3,
the step, model time and place; the file keeps the good output times)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cli_helpers import (
    BLOWUP,
    BLOWUP_RE,
    cuda_available,
    edited_scene,
    in_tmp,  # noqa: F401  (the fixture: every test in a folder of its own)
    nc_files,
    run_cli,
    stderr_lines,
)
from helpers import TINY, cli_main, one_line

# ---------------------------------------------------------------------------
# Bad input: exit 2, one line naming the field or value, no file
# ---------------------------------------------------------------------------


def assert_bad_input(code, out, err, tmp_path, *needles):
    line = one_line(code, err, 2)
    for needle in needles:
        assert needle.lower() in line.lower(), (needle, line)
    assert nc_files(tmp_path) == [], nc_files(tmp_path)


BAD_ARGS = [
    (("--dt", "0"), ("dt", "0")),
    (("--dt", "-300"), ("dt", "-300")),
    (("--dt", "nan"), ("dt", "nan")),
    (("--dt", "inf"), ("dt", "inf")),
    (("--dt", "7000"), ("dt", "7000")),  # does not divide the run length of 1 day
    (("--dt", "6750", "--days", "5"), ("dt", "6750", "output interval")),  # divides 5 days, not 1 day
    (("--days", "0"), ("days", "0")),
    (("--days", "-1"), ("days", "-1")),
    (("--days", "nan"), ("days", "nan")),
    (("--ne", "0"), ("ne", "0")),
    (("--ne", "-3"), ("ne", "-3")),
    (("--ne", "abc"), ("ne", "abc")),
    (("--np", "1"), ("np", "1")),
    (("--np", "9"), ("np", "9")),
    (("--stepper", "euler"), ("stepper", "euler")),
    (("--device", "tpu"), ("device", "tpu")),
]


@pytest.mark.parametrize("args,needles", BAD_ARGS, ids=[" ".join(a) for a, _ in BAD_ARGS])
def test_bad_command_line_values(args, needles, capsys, tmp_path):
    out = tmp_path / "out.nc"
    base = ["--ne", "2", "--np", "4", "--days", "1", "--device", "cpu", "--no-progress"]
    code, stdout, err = run_cli(capsys, "tc2_steady", *base, *args, "--output", out)
    assert_bad_input(code, stdout, err, tmp_path, *needles)


def test_unknown_scene_file(capsys, tmp_path):
    code, out, err = run_cli(capsys, tmp_path / "nope.toml", *TINY, "--output", tmp_path / "o.nc")
    assert_bad_input(code, out, err, tmp_path, "nope.toml")


@pytest.mark.parametrize(
    "edit,needles",
    [
        pytest.param(lambda t: t.replace("[grid]", "[grid"), ("TOML",), id="malformed-toml"),
        pytest.param(lambda t: t + "\nfoo = [1, \n", ("TOML",), id="unterminated-array"),
        pytest.param(
            lambda t: t.replace('name = "tc2_steady"', 'name = "tc99_nothing"'),
            ("case", "tc99_nothing"),
            id="unknown-case",
        ),
        pytest.param(
            lambda t: t.replace('"coriolis"', '"coriolis", "friction"'), ("term", "friction"), id="unknown-term"
        ),
        pytest.param(
            lambda t: t.replace('stepper = "ssprk3"', 'stepper = "euler"'), ("stepper", "euler"), id="unknown-stepper"
        ),
        pytest.param(lambda t: "colour = 3\n" + t, ("colour",), id="unknown-top-level-key"),
        pytest.param(lambda t: t.replace("[grid]\n", "[grid]\nnx = 3\n"), ("grid.nx",), id="unknown-grid-key"),
        pytest.param(lambda t: t.replace("[time]\n", "[time]\nsteps = 3\n"), ("time.steps",), id="unknown-time-key"),
        pytest.param(lambda t: t + "\n[physics]\ng = 9.8\n", ("physics",), id="unknown-table"),
        pytest.param(
            lambda t: t.replace("alpha = 0.0", "alpha = 0.0\nbeta = 1.0"), ("case.beta",), id="unknown-case-parameter"
        ),
        pytest.param(lambda t: t.replace("dt = 300.0", "dt = 0.0"), ("dt",), id="scene-dt-zero"),
        pytest.param(lambda t: t.replace("dt = 300.0", "dt = -300.0"), ("dt",), id="scene-dt-negative"),
        pytest.param(lambda t: t.replace("days = 5.0", "days = 0.0"), ("days",), id="scene-days-zero"),
        pytest.param(lambda t: t.replace("ne = 16", "ne = 0"), ("ne",), id="scene-ne-zero"),
        pytest.param(lambda t: t.replace("np = 4", "np = 9"), ("np",), id="scene-np-9"),
        pytest.param(lambda t: t.replace("ne = 16", 'ne = "two"'), ("grid.ne", "two"), id="scene-ne-string"),
        pytest.param(
            lambda t: t.replace("every_days = 1.0", "every_days = 0.0"), ("every_days",), id="scene-output-every-zero"
        ),
    ],
)
def test_bad_scene_files(edit, needles, capsys, tmp_path):
    scene = edited_scene(tmp_path, edit)
    # no overrides: they would mask the edited values (every case fails while loading the scene)
    args = ["--device", "cpu", "--no-progress", "--output", tmp_path / "out.nc"]
    code, out, err = run_cli(capsys, scene, *args)
    assert_bad_input(code, out, err, tmp_path, *needles)


def test_output_into_a_missing_folder(capsys, tmp_path):
    target = tmp_path / "no_such_folder" / "out.nc"
    code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", target)
    assert_bad_input(code, out, err, tmp_path, "no_such_folder")
    assert not target.parent.exists()


def test_output_under_a_regular_file(capsys, tmp_path):
    (tmp_path / "plain_file").write_text("not a folder")
    code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", tmp_path / "plain_file" / "o.nc")
    assert_bad_input(code, out, err, tmp_path, "plain_file")


def test_output_is_a_folder(capsys, tmp_path):
    (tmp_path / "folder.nc").mkdir()
    code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", tmp_path / "folder.nc")
    assert code == 2 and len(stderr_lines(err)) == 1 and "folder.nc" in err, err
    assert list((tmp_path / "folder.nc").iterdir()) == []


def test_output_into_a_read_only_folder(capsys, tmp_path):
    folder = tmp_path / "read_only"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", folder / "o.nc")
        if os.access(folder, os.W_OK):  # root may write into it, and does (the refusal: the test below)
            assert code == 0 and (folder / "o.nc").is_file(), err
        else:
            assert_bad_input(code, out, err, tmp_path, "read_only")
    finally:
        folder.chmod(0o755)


def test_output_into_a_folder_reported_read_only(monkeypatch, capsys, tmp_path):
    """The read-only check where permissions cannot bite (root): os.access says no."""
    folder = tmp_path / "locked"
    folder.mkdir()
    real_access = os.access

    def access(path, mode, *args, **kwargs):
        if Path(path).resolve() == folder.resolve() and mode & os.W_OK:
            return False
        return real_access(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", access)
    code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", folder / "o.nc")
    assert_bad_input(code, out, err, tmp_path, "locked")


def _not_a_reference(folder: Path) -> Path:
    """A netCDF file of a reference's coefficients without its vorticity."""
    from swe_sphere.cases.reference import find_reference

    path = folder / "no_vorticity.nc"
    with xr.open_dataset(find_reference("galewsky", perturbed=False), decode_times=False) as ds:
        ds.drop_vars(["vort_spec_re", "vort_spec_im"]).to_netcdf(path)
    return path


@pytest.mark.parametrize(
    "command, scene, value, why",
    [
        ("sweep", "tc5_mountain", "missing.nc", "reference file not found: missing.nc"),
        ("run", "tc5_mountain", "junk.nc", "junk.nc: not a readable netCDF file"),
        (
            "run",
            "tc5_mountain",
            "NOT_A_REFERENCE",
            "not a reference file: missing variable(s) 'vort_spec_re', 'vort_spec_im'",
        ),
        (
            "run",
            "tc2_steady",
            "tc5_mountain_T213.nc",
            "case tc2_steady is scored against its exact solution, not a reference file",
        ),
        (
            "sweep",
            "tc5_mountain",
            "tc6_rossby_haurwitz_T213.nc",
            "the file is a tc6_rossby_haurwitz reference (its title), not one of tc5_mountain",
        ),
        (
            "run",
            "galewsky",
            "galewsky_balanced_T213.nc",
            "the file is a galewsky_balanced reference (its title), not one of galewsky",
        ),
    ],
    ids=["missing-sweep", "not-netcdf", "not-a-reference", "exact-solution", "other-case", "other-galewsky"],
)
def test_a_bad_case_reference_is_refused(capsys, tmp_path, command, scene, value, why):
    """-s case.reference=...: exit 2, one line naming the key, the value and why; nothing written."""
    (tmp_path / "junk.nc").write_text("not netCDF")
    if value == "NOT_A_REFERENCE":
        value = str(_not_a_reference(tmp_path))
    code, _, err = cli_main(
        capsys, command, scene, "--ne", "2", "--device", "cpu", "-s", f"case.reference={value}",
        "--output", tmp_path / "out",
    )  # fmt: skip
    lines = stderr_lines(err)
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"swe-sphere: error: case.reference = {value!r}: ") and why in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(cuda_available(), reason="CUDA is available here")
def test_device_cuda_without_cuda(capsys, tmp_path):
    out = tmp_path / "out.nc"
    code, stdout, err = run_cli(
        capsys,
        "tc2_steady",
        "--ne",
        "2",
        "--np",
        "4",
        "--days",
        "1",
        "--device",
        "cuda",
        "--no-progress",
        "--output",
        out,
    )
    assert_bad_input(code, stdout, err, tmp_path, "cuda")


@pytest.mark.gpu
@pytest.mark.skipif(not cuda_available(), reason="needs a CUDA device")
def test_tiny_run_on_cuda_matches_cpu(capsys, tmp_path):
    results = {}
    for device in ("cuda", "cpu"):
        out = tmp_path / f"{device}.nc"
        code, _, err = run_cli(
            capsys,
            "tc2_steady",
            "--ne",
            "2",
            "--np",
            "4",
            "--days",
            "1",
            "--device",
            device,
            "--no-progress",
            "--output",
            out,
        )
        assert code == 0, err
        with xr.open_dataset(out, decode_times=False) as ds:
            assert ds.attrs["device"] == device
            results[device] = ds.load()
    cuda, cpu = results["cuda"], results["cpu"]
    assert cuda.l2_h.values[-1] < 3e-3
    np.testing.assert_allclose(cuda.h.values, cpu.h.values, rtol=1e-10)
    np.testing.assert_allclose(cuda.u.values, cpu.u.values, rtol=1e-8, atol=1e-8)


# ---------------------------------------------------------------------------
# Blow-up: exit 3, message with step, model time and place, file keeps the good times
# ---------------------------------------------------------------------------


def test_blowup_exits_3_and_keeps_the_good_output(capsys, tmp_path):
    out = tmp_path / "blow.nc"
    code, stdout, err = run_cli(capsys, *BLOWUP, "--output", out)
    assert code == 3, err
    lines = stderr_lines(err)
    # the stability warning at start (Courant 1.54 > ssprk3's 1.11) foretold it
    assert len(lines) == 2 and "above ssprk3's stability limit" in lines[0], err
    lines = lines[1:]
    m = BLOWUP_RE.search(lines[0])
    assert m, lines[0]
    assert str(out) in lines[0] or out.name in lines[0]
    step, days = int(m["step"]), float(m["days"])
    lat, lon = float(m["lat"]), float(m["lon"])
    dt = 7200.0
    assert step >= 2
    assert days == pytest.approx(step * dt / 86400, abs=1e-4)
    assert days > 1  # so that at least one daily output precedes it
    assert -90 <= lat <= 90 and 0 <= lon < 360

    assert nc_files(tmp_path) == [out]
    with xr.open_dataset(out, decode_times=False) as ds:
        t = ds.time.values
        good_days = [d for d in range(0, 6) if d < days]
        last_good = (step - 1) * dt / 86400
        expected = good_days + ([last_good] if last_good not in good_days else [])
        np.testing.assert_allclose(t, expected, atol=1e-9)
        np.testing.assert_array_equal(ds.steps.values[-1], step - 1)
        assert np.all(np.diff(t) > 0)  # no repeated time
        for name in ("h", "u", "v", "mass", "total_energy", "l2_h", "rhs_evals", "wall_time"):
            assert np.isfinite(ds[name].values).all(), name
        assert (ds.h.values > 0).all()
        assert "blowup" in ds.attrs
        assert f"step {step}" in ds.attrs["blowup"]
        # the reported place is a node of the grid
        dist = np.hypot(ds.lat.values - lat, (ds.lon.values - lon + 180) % 360 - 180)
        assert dist.min() < 0.01
        assert json.loads(ds.attrs["scene"])["dt"] == dt
