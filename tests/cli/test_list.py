"""``swe-sphere list``: every scene, stepper and term named."""

from __future__ import annotations

import re

from swe_sphere.cli import main

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
