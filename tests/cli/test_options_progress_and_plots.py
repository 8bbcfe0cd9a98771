"""The command line's options and what it prints (the first hour's fourth pass, issue 102): values
replaced by an option still checked, ``load_scene`` taking what ``run`` takes, the header naming
the case as run, ensembles that say what they are, progress lines off a terminal, ``plot --animate``. Each refusal is one line, exit 2, made before anything is written."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import SceneError

from helpers import cli_main, one_line

RUN = ("run", "tc2_steady", "--ne", "2", "--days", "0.1", "--device", "cpu")  # no bar: stderr is captured


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize(
    "options, words",
    [
        (["--ne", "4", "-s", "grid.ne=-4"], ["grid.ne = -4", "integer >= 1", "ne = 4 replaces it"]),
        (["-s", "time.days=-2"], ["time.days = -2", "must be > 0", "days = 0.1 replaces it"]),
        (["--np", "4", "-s", "grid.np=9"], ["grid.np = 9", "2..8"]),
        (["--dt", "600", "-s", "time.dt=-1"], ["time.dt = -1", "must be > 0"]),
        (["--stepper", "rk4", "-s", "time.stepper='rk5'"], ["time.stepper = 'rk5'", "unknown stepper"]),
    ],
)
def test_a_set_value_an_option_replaces_is_still_checked(capsys, options, words):
    """`run tc2_steady --ne 4 -s grid.ne=-4` and `-s time.days=-2` with --days ran, exit 0:
    -s is documented as checked like the file, and a value the option replaces was dropped unread."""
    code, out, err = cli_main(capsys, *RUN, *options, "--output", "x.nc")
    one_line(code, err, 2, *words)
    assert out == "" and list(Path().iterdir()) == []


def test_a_value_an_option_replaces_is_fine_when_good():
    scene = load_scene("tc2_steady", ne=2, days=0.5, overrides={"grid.ne": 8, "time.days": 3})
    assert (scene.ne, scene.days) == (2, 0.5)


def test_load_scene_takes_np_as_run_does():
    """`load_scene("tc2_steady", ne=2, np=4)` raised a bare TypeError (it wanted np_=)."""
    assert load_scene("tc2_steady", ne=2, np=3).np == 3
    assert load_scene("tc2_steady", ne=2, np_=3).np == 3
    with pytest.raises(SceneError, match="np = 3 and np_ = 4: give one of them"):
        load_scene("tc2_steady", ne=2, np=3, np_=4)


def test_a_table_given_as_a_dict_is_merged_into_the_files():
    """`load_scene(..., overrides={"time": {"control": "error"}})` replaced the whole [time]
    table and then said "time.dt is missing"; `run(time={...})` merges."""
    scene = load_scene("tc2_steady", ne=2, stepper="bs32", overrides={"time": {"control": "error", "rtol": 1e-5}})
    plain = load_scene("tc2_steady", ne=2, stepper="bs32")
    assert scene.control.mode == "error" and scene.control.rtol == 1e-5
    assert scene.days == plain.days and scene.output_every_days == plain.output_every_days


def test_the_header_names_the_case_as_run(capsys):
    """`-s case.alpha=0.5` printed the file's "(alpha = 0)" alone."""
    code, out, _ = cli_main(capsys, *RUN, "-s", "case.alpha=0.5", "--output", "a.nc")
    assert code == 0
    first = out.splitlines()[0]
    assert first.startswith("scene       tc2_steady: ") and first.endswith("; run with case.alpha = 0.5"), first


@pytest.mark.parametrize(
    "value, words",
    [("1e308", ["case.alpha", "within ±2π", "1e+308"]), ("45", ["case.alpha", "radians", "45"])],
)
def test_an_angle_out_of_range_is_refused(capsys, value, words):
    """`-s case.alpha=1e308` ran (cos and sin of 1e308 are no tilt one means)."""
    code, out, err = cli_main(capsys, *RUN, "-s", f"case.alpha={value}", "--output", "a.nc")
    one_line(code, err, 2, *words)
    assert out == "" and list(Path().iterdir()) == []
    with pytest.raises(SceneError, match="case.lat2 must be an angle in radians within ±π/2"):
        load_scene("galewsky", ne=2, overrides={"case.lat2": 2.0})


def test_an_ensemble_too_large_for_memory_is_refused_before_it_is_built(capsys, monkeypatch):
    """`run tc2_steady --ne 4 --days 0.1 --members 100000` printed nothing for 90 s (no memory
    check), where `--ne 100000` is refused at once with its estimate."""
    import swe_sphere.core.runtime as runtime
    import swe_sphere.members.members as members
    from swe_sphere.simulation.simulation import Simulation

    monkeypatch.setattr(runtime, "available_memory", lambda: 2**30)
    monkeypatch.setattr(members, "CubedSphere", _not_built)
    code, out, err = cli_main(capsys, *RUN, "--ne", "4", "--members", "100000", "--output", "e.nc")
    line = one_line(code, err, 3, "an ensemble of 100000 members of ne=4 np=4 with ssprk3", "1 GiB is available")
    assert "157 GiB" in line  # 100000 members x 1536 nodes x 1100 bytes
    assert out == "" and list(Path().iterdir()) == []
    monkeypatch.setattr(runtime, "available_memory", lambda: 2**40)  # memory enough: the check passes
    with pytest.raises(AssertionError, match="built before the memory check"):
        Simulation("tc2_steady", "cpu", members=100, ne=4)


def _not_built(*args, **kwargs):
    raise AssertionError("built before the memory check")


def _ensemble_warnings(capsys, *options) -> list[str]:
    code, out, err = cli_main(capsys, *RUN, "--days", "0.05", "--members", "2", *options, "--output", "e.nc")
    assert code == 0 and "h spread" in out, err
    return [line for line in err.splitlines() if "start alike" in line]


def test_an_ensemble_of_members_alike_says_so(capsys):
    """`run galewsky --members 4` (no --perturbation, --vary or --initial) ran four identical
    members and reported a spread of 0 m without a word."""
    (line,) = _ensemble_warnings(capsys)
    assert line.startswith("swe-sphere: warning: the 2 members start alike") and "spread is 0 m" in line
    assert len(_ensemble_warnings(capsys, "--perturbation", "0", "--overwrite")) == 1
    assert _ensemble_warnings(capsys, "--perturbation", "1", "--overwrite") == []
    assert _ensemble_warnings(capsys, "--vary", "case.alpha=0,0.1", "--overwrite") == []


def test_members_help_says_any_stepper_and_in_turn(capsys):
    """`run --help` said --members runs "explicit steppers, fixed dt" in the same launches; an imex
    ensemble runs, and on a CPU the members run in turn."""
    code, out, _ = cli_main(capsys, "run", "--help")
    text = " ".join(out.split())
    assert code == 0 and "explicit steppers, fixed dt" not in text
    assert "(any stepper; under step control one dt for every member), in the same launches on CUDA for an" in text
    assert "own in turn (--layout)" in text
    code, out, _ = cli_main(
        capsys, *RUN, "--days", "0.05", "--stepper", "imex", "--members", "2", "--perturbation", "1"
    )
    assert code == 0 and "ensemble    2 members each on a model of its own, in turn" in out


@pytest.fixture
def slow_clock(monkeypatch):
    """The progress lines' clock, 100 s of wall time a reading: a line at every block of steps."""
    import itertools

    import swe_sphere.cli.progress as progress

    ticks = itertools.count(0.0, 100.0)
    monkeypatch.setattr(progress, "clock", lambda: next(ticks))


def _span(readings: int) -> str:
    minutes, seconds = divmod(100 * readings, 60)
    return f"{minutes} min {seconds:02d} s of wall time"


def _progress(out: str) -> list[str]:
    return [line for line in out.splitlines() if line.startswith("progress    ")]


QUARTER = ("--dt", "1800", "--days", "0.25", "-s", "output.every_days=0.125")  # 12 steps, outputs at 6 and 12


def test_a_run_off_a_terminal_prints_its_progress_every_n_seconds(capsys, slow_clock):
    """Off a terminal (a pipe, nohup, CI) a long run printed its header and then nothing until the
    summary (the README's TC5 run: 72-250 s); a line every --progress-every seconds of wall time."""
    code, out, _ = cli_main(capsys, *RUN, *QUARTER, "--progress-every", "30", "--output", "p.nc")
    assert code == 0
    lines = _progress(out)  # one at the end of each block of steps (the clock: 100 s a reading)
    assert len(lines) >= 2 and lines[-1].endswith("day 0.25 of 0.25 (100 %), step 12, " + _span(len(lines)))
    assert lines[0] == f"progress    day {1 / 48:.4g} of 0.25 (8 %), step 1, {_span(1)}"  # no pace yet
    for k, line in enumerate(lines[1:-1], 2):
        step = int(re.search(r"step (\d+),", line)[1])
        expected = f"progress    day {step / 48:.4g} of 0.25 ({100 * step / 12:.0f} %), step {step}, {_span(k)}, about "
        assert line.startswith(expected) and line.endswith(" left"), line
    assert out.index("output      p.nc") < out.index(lines[0]) < out.index("summary")
    for none in (["--progress-every", "30", "--no-progress"], ["--progress-every", "0"], []):
        code, out, _ = cli_main(capsys, *RUN, *QUARTER, *none, "--output", "p.nc", "--overwrite")
        assert code == 0 and _progress(out) == [], none  # in a caller's process: only when asked


def test_an_ensemble_off_a_terminal_prints_its_progress(capsys, slow_clock):
    args = (*RUN, *QUARTER, "--members", "2", "--perturbation", "1", "--progress-every", "30", "--output", "e.nc")
    code, out, _ = cli_main(capsys, *args)
    assert code == 0
    lines = _progress(out)  # one at the end of each block of steps, as a run's
    assert len(lines) >= 2 and lines[-1] == "progress    day 0.25 of 0.25 (100 %), step 12, " + _span(len(lines))


def test_a_progress_line_estimates_the_time_left(monkeypatch):
    import swe_sphere.cli.progress as progress

    now, lines = [100.0], []
    monkeypatch.setattr(progress, "clock", lambda: now[0])
    ticker = progress.ProgressLines(lines.append, 30)
    ticker.start(1.0, 11.0)  # a continued run, from day 1 to day 11
    for t, step, day in ((120.0, 5, 1.5), (140.0, 10, 3.0), (150.0, 12, 3.4), (4000.0, 99, 10.0)):
        now[0] = t
        ticker.tick(step, day)
    assert lines == [  # not at 120 s (20 s after the start), nor at 150 s (10 s after the last line)
        "day 3 of 11 (20 %), step 10, 40 s of wall time, about 1 min 47 s left",  # 20 s x 8 / 1.5 from 120 s
        "day 10 of 11 (90 %), step 99, 1 h 05 min of wall time, about 7 min 36 s left",  # 3880 s x 1 / 8.5
    ]


@pytest.mark.parametrize("value", ["-1", "nan", "inf"])
def test_a_bad_progress_interval_is_refused(capsys, value):
    code, out, err = cli_main(capsys, *RUN, "--progress-every", value, "--output", "p.nc")
    one_line(code, err, 2, "--progress-every must be a number of seconds >= 0", value)
    assert out == "" and list(Path().iterdir()) == []


@pytest.mark.parametrize(
    "options, words",
    [
        (
            ["--ne", "4", "--refine-box", "10", "50", "0", "40", "--levels", "20"],
            [
                "--levels 20 on --ne 4: 4194304 x 4194304 finest cells a face",
                "about 1.05e+06 GiB",
                "1 GiB is available",
            ],
        ),
        (["--ne", "100000"], ["--ne 100000: a cube of 6e+10 elements", "about 5.59e+05 GiB"]),
    ],
)
def test_a_mesh_too_large_to_make_is_refused_before_its_arrays(capsys, monkeypatch, options, words):
    """`mesh --ne 4 --refine-box 10 50 0 40 --levels 20` and `mesh --ne 100000` ended in numpy's
    out-of-memory text (exit 3), not a line naming the option."""
    import swe_sphere.core.runtime as runtime
    import swe_sphere.grid.refine as refine

    monkeypatch.setattr(runtime, "available_memory", lambda: 2**30)
    monkeypatch.setattr(refine, "make_mesh", _not_built)
    code, out, err = cli_main(capsys, "mesh", *options, "--output", "m.g")
    one_line(code, err, 2, *words)
    assert out == "" and list(Path().iterdir()) == []


ENSEMBLE = (*RUN, "--members", "2", "--perturbation", "1")


@pytest.mark.parametrize(
    "options, words",
    [
        (
            ["--perturbation-degrees", "20,1"],
            ["--perturbation-degrees 20,1", "1 <= L_MIN <= L_MAX"],
        ),  # was "(20, 1), a tuple"
        (  # was accepted at ne 4, its noise aliased onto the 24 degrees the grid holds
            ["--ne", "4", "--perturbation-degrees", "1,2000"],
            ["--perturbation-degrees 1,2000", "ne=4 np=4 grid resolves degrees up to about 24"],
        ),
    ],
)
def test_a_perturbation_band_is_checked_against_the_grid(capsys, options, words):
    code, out, err = cli_main(capsys, *ENSEMBLE, *options, "--output", "e.nc")
    one_line(code, err, 2, *words)
    assert out == "" and list(Path().iterdir()) == []


def test_a_continuation_whose_restart_file_would_be_its_input_names_output(capsys):
    """`--continue x.restart.nc --output x.nc` named the derived restart file as the clash."""
    assert cli_main(capsys, *RUN, "--days", "0.05", "--restart-every", "0.05", "--output", "x.nc")[0] == 0
    before = sorted(p.name for p in Path().iterdir())
    code, out, err = cli_main(capsys, "run", "--continue", "x.restart.nc", "--output", "x.nc", "--days", "0.1")
    one_line(code, err, 2, "--output x.nc: its restart file would be x.restart.nc, the file --continue reads")
    assert sorted(p.name for p in Path().iterdir()) == before


def test_a_name_too_long_is_bad_input(capsys):
    """A 300-character output name exited 3 (an OSError), not 2."""
    code, out, err = cli_main(capsys, *RUN, "--output", "a" * 300 + ".nc")
    one_line(code, err, 2, "File name too long")
    assert list(Path().iterdir()) == []


def test_debug_keeps_bad_inputs_exit_status(capsys):
    """`--debug` turned a bad input's exit 2 into 1 (the traceback raised out of main)."""
    code, _, err = cli_main(capsys, "--debug", *RUN, "--ne", "-1")
    assert code == 2 and "Traceback" in err and "SceneError: ne must be an integer >= 1 (got -1)" in err
    assert err.rstrip().endswith("swe-sphere: error: ne must be an integer >= 1 (got -1)")


def test_an_ensemble_says_its_restart_file_and_its_references_days(capsys):
    """An ensemble with --restart-every printed no restart line; its reference line said "(9 errors)"."""
    args = ("run", "tc5_mountain", "--ne", "2", "--days", "0.1", "--device", "cpu", "--members", "2")
    code, out, _ = cli_main(capsys, *args, "--perturbation", "1", "--restart-every", "0.05", "--output", "e.nc")
    assert code == 0 and "restart     e.restart.nc (every 0.05 days and at the end)" in out.splitlines()
    assert "  reference             none at day 0.1: T213 stores days 0, 1, 2, 5, 10, 15" in out.splitlines()
    assert "errors)" not in out


@pytest.mark.parametrize("flag", ["--dt", "--days"])
def test_an_infinite_step_or_length_is_named_as_not_finite(capsys, flag):
    """`--dt inf` said "dt must be > 0 (got inf)"."""
    code, out, err = cli_main(capsys, *RUN, flag, "inf", "--output", "x.nc")
    one_line(code, err, 2, f"argument {flag}: must be a finite number > 0 (got inf)")
    assert out == "" and list(Path().iterdir()) == []


@pytest.fixture
def three_times(capsys):
    """A run file of TC2 at ne 2 with output times 0, 0.125 and 0.25 days."""
    assert cli_main(capsys, *RUN, *QUARTER, "--output", "r.nc")[0] == 0
    return Path("r.nc")


def test_plot_animate_writes_a_gif_of_every_output_time(capsys, three_times):
    """`plot` made still maps only: a user who ran galewsky could not watch the jet roll up."""
    from PIL import Image

    code, out, err = cli_main(capsys, "plot", three_times, "--animate", "--field", "vorticity", "--output", "anim")
    assert code == 0, err
    assert out.splitlines() == ["anim/r_vorticity.gif"]
    with Image.open("anim/r_vorticity.gif") as gif:
        assert gif.size == (800, 400) and gif.n_frames == 3 and gif.info["duration"] == 250  # 4 frames a second
        frames = []
        for k in range(3):
            gif.seek(k)
            frames.append(np.asarray(gif.convert("RGB")))
    assert not np.array_equal(frames[0], frames[2])  # the title's day at least
    # again: refused without --overwrite, nothing replaced; two days of three at 400 px wide with it
    before = Path("anim/r_vorticity.gif").read_bytes()
    code, _, err = cli_main(capsys, "plot", three_times, "--animate", "--field", "vorticity", "--output", "anim")
    one_line(code, err, 2, "exists")
    assert Path("anim/r_vorticity.gif").read_bytes() == before
    args = ("plot", three_times, "--animate", "gif", "--field", "vorticity", "--day", "0", "0.25", "--width", "400")
    assert cli_main(capsys, *args, "--output", "anim", "--overwrite")[0] == 0
    with Image.open("anim/r_vorticity.gif") as gif:
        assert gif.size == (400, 200) and gif.n_frames == 2


@pytest.mark.parametrize(
    "options, words",
    [
        (["--animate", "--field", "h", "u"], ["--animate draws one --field (got h u)"]),
        (["--animate", "--diff", "T213"], ["--diff: not with --animate"]),
        (["--animate", "--spectrum"], ["--spectrum: not with --animate"]),
        (["--animate", "--day", "0.25"], ["an animation needs two output times or more (got 1)"]),
        (["--animate", "--day", "0", "0.3"], ["day 0.3 not in"]),
        (["--width", "10"], ["--width must be a whole number of pixels in 400..4000 (got 10)"]),
    ],
)
def test_plot_animate_refuses_in_one_line(capsys, three_times, options, words):
    code, out, err = cli_main(capsys, "plot", three_times, *options, "--output", "anim")
    one_line(code, err, 2, *words)
    assert not Path("anim").exists()


def test_an_mp4_needs_ffmpeg(capsys, three_times, monkeypatch):
    import shutil

    monkeypatch.setattr(shutil, "which", lambda name: None)
    code, out, err = cli_main(capsys, "plot", three_times, "--animate", "mp4", "--output", "anim")
    one_line(code, err, 2, "--animate mp4: ffmpeg is not on PATH")
    assert not Path("anim").exists()


def test_plot_width_sizes_a_map(capsys, three_times):
    from PIL import Image

    code, out, err = cli_main(capsys, "plot", three_times, "--field", "vorticity", "--width", "720", "--output", "f")
    assert code == 0, err
    with Image.open(out.splitlines()[0]) as png:
        assert png.size == (720, 360)


def test_the_readmes_picture_is_small_and_named_by_its_command():
    """The README opens with Galewsky's day-6 vorticity, made by the command it gives, under 200 kB."""
    repo = Path(__file__).resolve().parents[2]
    readme = (repo / "README.md").read_text()
    picture = repo / "docs" / "galewsky_vorticity_day6_lat0to90.png"
    assert readme.index("![") < readme.index("## What it is")
    assert f"]({picture.relative_to(repo)})" in readme and picture.stat().st_size < 200_000
    assert "swe-sphere plot galewsky.nc --field vorticity --day 6 --lat-range 0 90 --width 720 --output docs" in readme
