"""``swe-sphere list``: every scene, stepper and term named."""

from __future__ import annotations

import re

from swe_sphere.cli import main
from swe_sphere.steppers import STEPPERS

from cli_helpers import (
    STEPPER_NAMES,
    TERM_NAMES,
    TESTCASES,
    in_tmp,  # noqa: F401  (the fixture: every test in a folder of its own)
)

# ---------------------------------------------------------------------------
# swe-sphere list
# ---------------------------------------------------------------------------


def test_list_names_every_scene_stepper_and_term(capsys):
    assert main(["list"]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    words = set(re.findall(r"[\w.+-]+", out))
    scenes = sorted(p.stem for p in TESTCASES.rglob("*.toml"))  # tableaus/ too
    assert len(scenes) >= 10
    for name in scenes:
        assert name in words, f"scene {name} not listed"
    for name in STEPPER_NAMES:
        assert name in words, f"stepper {name} not listed"
    for name in TERM_NAMES:
        assert name in words, f"term {name} not listed"
    steppers = out.split("steppers:\n")[1].split("terms:\n")[0].splitlines()
    assert "``" not in out  # docstrings' reST literals printed plain
    assert all(len(line) < 400 and line.endswith(".") for line in steppers), steppers  # a whole first sentence each
    # not cut inside a citation ("(Bogacki & Shampine 1989, Appl." was bs32's)
    assert all(line.count("(") == line.count(")") for line in steppers), steppers


def test_list_says_which_steppers_have_a_gradient_and_error_control(capsys):
    """Each stepper's second line: explicit, a gradient or none (``Stepper.differentiable``, what
    ``swe_sphere.gradient`` refuses on), error control by an embedded pair's order."""
    assert main(["list"]) == 0
    block = capsys.readouterr().out.split("steppers:\n")[1].split("terms:\n")[0].splitlines()
    traits = {line.split()[0]: block[i + 1].strip() for i, line in enumerate(block) if not line.startswith(" " * 4)}
    assert traits["rk4"] == "explicit; a gradient."
    assert traits["leapfrog"] == "explicit; a gradient; one Δt a run."
    assert traits["rk43"] == "explicit; a gradient; error control (an embedded order-3 estimate)."
    assert traits["imex"] == "a gradient."
    assert traits["epi2"] == "no gradient; one Δt a run."
    assert traits["implicit"] == "no gradient; error control (an embedded order-2 estimate)."
    assert sorted(traits) == sorted(STEPPERS)  # every registered stepper, a line each
