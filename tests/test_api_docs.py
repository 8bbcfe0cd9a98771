"""The public API's docstrings state its contract in numpydoc sections: ``swe_sphere.run``,
``Simulation`` and its public methods, ``load_scene``, ``remap_dataset``, the sweep's and the
frontier's ``plan`` name every parameter under Parameters and have Returns (or Yields) and Raises;
``Scene`` names every field under Attributes; each error says what it is."""

from __future__ import annotations

import dataclasses
import inspect
import re

import pytest

from swe_sphere import api
from swe_sphere.config.scene import Scene, load_scene
from swe_sphere.core import errors
from swe_sphere.ensemble import Ensemble
from swe_sphere.io.remap import remap_dataset
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.studies import frontier
from swe_sphere.studies.sweep import Plan, plan

HEADER = re.compile(r"^ *(\w[\w ]*)\n *-{3,}\n", re.M)


def sections(obj) -> dict[str, str]:
    """A docstring's numpydoc sections: title → body."""
    doc = inspect.getdoc(obj) or ""
    heads = list(HEADER.finditer(doc))
    return {h.group(1): doc[h.end() : nxt.start() if nxt else len(doc)] for h, nxt in zip(heads, [*heads[1:], None])}


def named(body: str) -> set[str]:
    """The names an entry list documents: ``a : type``, ``a, b : type``, ``a, b`` or ``**kw`` lines."""
    names = set()
    for line in body.splitlines():
        if line and not line.startswith(" "):
            names |= {n.strip().lstrip("*") for n in line.split(" : ")[0].split(",")}
    return names


FUNCTIONS = [
    api.run,  # swe_sphere.run's (the package's own defers the import)
    Simulation,
    Ensemble,
    Simulation.from_checkpoint,
    Simulation.run,
    Simulation.advance,
    Simulation.steps,
    Simulation.state,
    load_scene,
    remap_dataset,
    plan,
    Plan.run,
    frontier.plan,
    frontier.Frontier.run,
]


@pytest.mark.parametrize("func", FUNCTIONS, ids=lambda f: f.__qualname__)
def test_every_parameter_is_documented(func):
    found = sections(func)
    params = inspect.signature(func.__init__ if inspect.isclass(func) else func).parameters
    wanted = {name for name in params if name not in ("self", "cls")}
    assert "Parameters" in found, func
    assert named(found["Parameters"]) >= wanted, wanted - named(found["Parameters"])
    if not inspect.isclass(func):
        assert {"Returns", "Yields"} & set(found), func
    assert "Raises" in found, func


def test_the_scene_names_every_field():
    assert named(sections(Scene)["Attributes"]) == {f.name for f in dataclasses.fields(Scene)}


@pytest.mark.parametrize("name", errors.__all__)
def test_every_error_says_what_it_is(name):
    cls = getattr(errors, name)
    assert issubclass(cls, errors.SweSphereError) and len(inspect.getdoc(cls)) > 40
    if name in ("BlowUp", "Interrupted"):
        assert {"result"} <= named(sections(cls)["Attributes"])


def test_the_reference_names_every_grid_key():
    """The `[grid]` paragraph (now docs/how-to/meshes.md) left out `cube` (issue 86, item 5): it names
    every key of the scene's [grid] table."""
    from pathlib import Path

    from swe_sphere.config.schema import SCHEMA

    page = (Path(__file__).parents[1] / "docs" / "how-to" / "meshes.md").read_text()
    start = page.index("The mesh, in a scene's `[grid]`")
    paragraph = page[start:].split("\n\n")[0]
    assert [k for k in SCHEMA["grid"] if not re.search(rf"`{k}(`| =)", paragraph)] == []
