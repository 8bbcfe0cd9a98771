"""A run from a reanalysis file alone (``swe-sphere run FILE.nc``, ``swe_sphere.run(path or
Dataset)``) and a scene's start from one (``--initial FILE.nc``): the case ``reanalysis``
(``io.reanalysis``) with case 7's settings, the scene named after the file."""

from __future__ import annotations

import os

from ..io.formats import is_netcdf, refuse_grib
from ..io.reanalysis import is_given

TEMPLATE = "tc7_era_july"  # the settings a file alone runs with: case 7's (TC6's rules: grid, dt, ∇⁴)
NETCDF = (".nc", ".nc4", ".netcdf", ".cdf")


def is_state_file(scene) -> bool:
    """Whether ``scene`` (a scene's name or path, as ``run`` takes it) names a netCDF state, not a
    scene: a Dataset given in Python (``reanalysis.given``), by its name's suffix, else by its first bytes (``io.formats``); ``SceneError`` for a
    GRIB file, which is no scene either."""
    if not isinstance(scene, (str, os.PathLike)):
        return False
    if is_given(scene):
        return True
    refuse_grib(scene, str(scene))
    return str(scene).lower().endswith(NETCDF) or is_netcdf(scene)


def start_overrides(initial=None, level=None, time=None, truncation=None) -> dict:
    """The ``case.*`` overrides of a start from the reanalysis file ``initial`` (None: the scene's
    own) at ``level`` (hPa), ``time`` and ``truncation`` (each None: not given)."""
    out = {} if initial is None else {"case.name": "reanalysis", "case.initial_file": str(initial)}
    given = (("level", level), ("time", time), ("truncation", truncation))
    return out | {f"case.{key}": value for key, value in given if value is not None}
