"""A run from a reanalysis file alone (``swe-sphere run FILE.nc``, ``swe_sphere.run(path or
Dataset)``) and a scene's start from one (``--initial FILE.nc``): the case ``reanalysis``
(``io.reanalysis``) with case 7's settings, the scene named after the file."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from .resolved import Scene
from .scene import load_scene

TEMPLATE = "tc7_era_july"  # the settings a file alone runs with: case 7's (TC6's rules: grid, dt, ∇⁴)
NETCDF = (".nc", ".nc4", ".netcdf", ".cdf")


def is_state_file(scene) -> bool:
    """Whether ``scene`` (a scene's name or path, as ``run`` takes it) names a netCDF state, not a scene."""
    return isinstance(scene, (str, os.PathLike)) and str(scene).lower().endswith(NETCDF)


def start_overrides(initial=None, level=None, time=None, truncation=None) -> dict:
    """The ``case.*`` overrides of a start from the reanalysis file ``initial`` (None: the scene's
    own) at ``level`` (hPa), ``time`` and ``truncation`` (each None: not given)."""
    out = {} if initial is None else {"case.name": "reanalysis", "case.initial_file": str(initial)}
    given = (("level", level), ("time", time), ("truncation", truncation))
    return out | {f"case.{key}": value for key, value in given if value is not None}


def state_scene(path, overrides: dict, **load_keywords) -> Scene:
    """The scene of a run from the reanalysis file ``path`` alone: ``TEMPLATE``'s settings with
    ``overrides`` (``load_scene``'s, ``case.level`` ... among them) and its start from ``path``,
    named after the file (its run file's default name ``<stem>_ne30np4_kgu35.nc``). Raises
    ``SceneError`` (the file's refusals, one line each)."""
    scene = load_scene(TEMPLATE, **load_keywords, overrides={**overrides, **start_overrides(path)})
    description = f"Williamson et al. (1992) case 7 from {Path(path).name} (settings of {TEMPLATE})"
    return dataclasses.replace(scene, name=Path(path).stem, description=description)
