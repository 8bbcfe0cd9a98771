"""The newest options' edges (the first hour's fifth pass, issue 117): intervals of 1e308 and
5e-324 days, ensemble degrees, ``plot --animate`` to a file, the ∇⁴'s every, interrupts in plot. Each refusal is
one line, exit 2, made before anything is written."""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers import TINY, cli_main, one_line

RUN = ("run", "tc2_steady", *TINY, "--days", "0.1")


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize(
    "scene, options",
    [
        ("tc2_steady", ["-s", "output.every_days=1e308"]),
        ("tc2_steady", ["--restart-every", "1.7976931348623157e308"]),
        ("tc5_mountain", ["-s", "output.every_days=1e308", "--restart-every", "1e308"]),  # "auto" ∇⁴ schedule
    ],
)
def test_an_interval_of_1e308_days_runs(capsys, scene, options):
    """`run tc2_steady --ne 4 --days 0.1 -s output.every_days=1e308` (and `--restart-every 1e308`)
    ended in "internal error: OverflowError": the ∇⁴'s schedule and the whole-step rule counted
    1e308 days in seconds. An interval past the run is its end."""
    code, out, err = cli_main(capsys, "run", scene, *RUN[2:], *options, "--output", "c.nc")
    assert code == 0 and err == "", err
    # the output's "shorter than its 1e+308-day interval", the restart's "every 1.797...e+308 days"
    assert ("e+308-day interval" in out or "e+308 days" in out) and Path("c.nc").exists()


@pytest.mark.parametrize("option", [["-s", "output.every_days=5e-324"], ["--restart-every", "5e-324"]])
def test_an_interval_of_5e_324_days_is_refused(capsys, option):
    code, out, err = cli_main(capsys, *RUN, *option, "--output", "c.nc")
    one_line(code, err, 2, "interval", "4.94066e-324 days gives more than 1e+308 times")
    assert out == "" and list(Path().iterdir()) == []


def test_bad_ensemble_degrees_are_named_before_a_missing_members(capsys):
    """`--members 2 --perturbation 1 -s ensemble.degrees=[20,1]` was refused as "ensemble.members is
    missing"; the degrees are the problem."""
    code, out, err = cli_main(capsys, *RUN, "--members", "2", "--perturbation", "1", "-s", "ensemble.degrees=[20,1]")
    one_line(code, err, 2, "ensemble.degrees must be [l_min, l_max]", "(got [20, 1])")
    assert out == "" and list(Path().iterdir()) == []


def test_plot_animate_to_a_file_name_writes_that_file(capsys):
    """`plot good.nc --animate --output p.gif` made a folder p.gif/ holding good_h_surface.gif."""
    assert cli_main(capsys, *RUN, "-s", "output.every_days=0.05", "--output", "r.nc")[0] == 0
    code, out, err = cli_main(capsys, "plot", "r.nc", "--animate", "--width", "400", "--output", "p.gif")
    assert code == 0 and out.splitlines() == ["p.gif"], err
    assert Path("p.gif").is_file()
    code, _, err = cli_main(capsys, "plot", "r.nc", "--animate", "--output", "p.gif")
    one_line(code, err, 2, "exists")


def test_hyperviscosity_every_s_edges_name_the_scene_s_key_and_their_own_reason(capsys):
    """Item 11: `-s hyperviscosity.every=1.5` (or `true`) was refused naming the model's
    `hypervis_every`; `lts` was refused with leapfrog's three-level reason; `every=4` on a scene
    without a ∇⁴ passed without a word."""
    for value in ("1.5", "true"):
        code, out, err = cli_main(capsys, *RUN, "-s", f"hyperviscosity.every={value}", "--output", "e.nc")
        line = one_line(code, err, 2, "hyperviscosity.every must be an integer >= 1 or 'auto'")
        assert "hypervis_every" not in line and not Path("e.nc").exists()
    lts = ("run", "tc5_mountain", *TINY, "--days", "0.1", "--stepper", "lts", "-s", "hyperviscosity.every=4")
    code, out, err = cli_main(capsys, *lts, "--output", "l.nc")
    line = one_line(code, err, 2, "hyperviscosity.every = 4: lts applies its ∇⁴ once a coarse step")
    assert "three-level" not in line
    code, out, err = cli_main(capsys, *RUN, "-s", "hyperviscosity.every=4", "--output", "n.nc")
    assert code == 0 and "hyperviscosity.every = 4 is unread: the scene has no ∇⁴ (ν = 0) and no [filter]" in out


def test_an_interrupt_during_plot_says_so(capsys, monkeypatch):
    """Item 13: Ctrl-C during `plot --animate` said "outside the time loop", a run's words."""
    from swe_sphere.studies import animation

    assert cli_main(capsys, *RUN, "--output", "r.nc")[0] == 0

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(animation, "animate_run", interrupted)
    code, out, err = cli_main(capsys, "plot", "r.nc", "--animate", "--output", "r.gif")
    line = one_line(code, err, 130, "interrupted by SIGINT in swe-sphere plot; no output was written")
    assert "time loop" not in line and not Path("r.gif").exists()


def test_the_layout_refusal_names_the_drop_policy_not_the_stepper():
    """Item 13: "shared" asked of members that need a model each because of `--blow-up drop` blamed
    "stepper ssprk3"."""
    from swe_sphere import load_scene
    from swe_sphere.members.units import layout

    scene = load_scene("tc2_steady", ne=2, np_=4, stepper="ssprk3")
    with pytest.raises(ValueError, match=r"^layout: these members need a model each \(blow_up 'drop'\): 'in_turn'$"):
        layout(scene, None, "shared", "cpu", own=True)
