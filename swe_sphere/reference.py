"""Spectral reference solutions (netCDF files), their interpolation to model nodes, and their own error.

The bundled files in ``testcases/reference/`` come from an independent
pseudo-spectral (SHTns) shallow-water model at T213, RK4, ∇⁴ hyperdiffusion;
see the README there for how they were made and their limits. A scene may
name another file of the same format (``case.reference``, e.g. the T341 TC5
run): :func:`locate` finds it. :func:`floor` says how far a reference is from
a finer one, where that was measured.
"""

from __future__ import annotations

import importlib.resources
import math
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.interpolate import RectBivariateSpline

_VARIABLES = ("lat", "lon", "time", "h_surface", "hs", "u", "v", "vorticity", "divergence")
_PAD = 6  # grid rows/columns added across each pole and each longitude edge
_DAY_TOL = 1e-6


def stored_index(days: np.ndarray, day: float) -> int | None:
    """The index in ``days`` (a reference's stored days) of ``day`` (within 1e-6
    day), or None when the reference does not store it."""
    hits = np.flatnonzero(np.abs(np.asarray(days) - day) <= _DAY_TOL)
    return int(hits[0]) if hits.size else None


def _open(path) -> xr.Dataset:
    """The open dataset of a reference file (lazy: values are read on use), its
    variables, time units and grid layout checked. Raises ``FileNotFoundError``
    if ``path`` does not exist, ``ValueError`` if it is not readable netCDF, lacks
    a variable or has an unexpected layout."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"reference file not found: {path}")
    try:
        ds = xr.open_dataset(path, decode_times=False)
    except Exception as exc:  # netCDF4 / xarray raise several types, some with many-line messages
        raise ValueError(f"{path}: not a readable netCDF file ({type(exc).__name__})") from None
    try:
        missing = [name for name in _VARIABLES if name not in ds.variables]
        if missing:
            raise ValueError(f"{path}: not a reference file: missing variable(s) {', '.join(map(repr, missing))}")
        units = ds["time"].attrs.get("units", "days")
        if not units.startswith("days"):
            raise ValueError(f"{path}: time must be in days (units {units!r})")
        lat, lon = ds["lat"].values, ds["lon"].values
        if not (np.all(np.diff(lat) > 0) and np.allclose(lon, 360.0 / lon.size * np.arange(lon.size)) and lon.size % 2 == 0):
            raise ValueError(f"{path}: lat must ascend and lon be 0, 360/n, ... with n even")
    except BaseException:
        ds.close()
        raise
    return ds


def stored_days(path) -> np.ndarray:
    """The days (ntime,) float64 a reference file stores, without reading its
    fields; the file is checked as ``Reference`` checks it (same errors)."""
    with _open(path) as ds:
        return np.asarray(ds["time"].values, dtype=np.float64)


def stored_case(path) -> str | None:
    """The case a reference file says it solves: the tail of its ``title`` attribute
    after the last ": " (the bundled files' "T213 spectral-transform reference
    solution: tc5_mountain" → "tc5_mountain"), or None when it has no title. Same
    errors as ``stored_days``."""
    with _open(path) as ds:
        title = ds.attrs.get("title")
    return title.rsplit(": ", 1)[-1].strip() if isinstance(title, str) and ": " in title else None


class Reference:
    """Spectral reference solution read from one netCDF file.

    The file holds, on a Gaussian grid of ``nlat`` × ``nlon`` points (``lat``
    degrees north, ascending; ``lon`` degrees east, equally spaced from 0) and
    ``time`` (days): ``h_surface``, ``h``, ``u``, ``v``, ``vorticity``,
    ``divergence`` (time, lat, lon) and ``hs`` (lat, lon); heights in m, winds
    in m s⁻¹ (eastward, northward), vorticity and divergence in s⁻¹.
    The bundled files (320 × 640, T213) are described in
    ``testcases/reference/README.md``; :func:`find_reference` locates them.

    Attributes:
      days (ntime,) float64   stored output days
      lat, lon (nlat,), (nlon,) float64   grid, radians
      path                    the file read

    :meth:`at` interpolates with bicubic splines (float64) on the grid padded
    periodically in longitude and across each pole (the field continued along
    the meridian, i.e. taken at lon + 180°, wind components with changed sign).

    Raises ``FileNotFoundError`` if ``path`` does not exist and ``ValueError``
    if it is not readable netCDF or lacks a variable or has an unexpected layout.
    """

    def __init__(self, path):
        self.path = Path(path)
        with _open(self.path) as ds:
            lat = np.asarray(ds["lat"].values, dtype=np.float64)
            lon = np.asarray(ds["lon"].values, dtype=np.float64)
            self.days = np.asarray(ds["time"].values, dtype=np.float64)
            fields = {k: ds[k].transpose("time", "lat", "lon").values for k in ("h_surface", "u", "v", "vorticity")}
            fields["hs"] = ds["hs"].transpose("lat", "lon").values[None]
        self.lat, self.lon = np.radians(lat), np.radians(lon)
        self._fields = fields
        self._splines: dict[tuple[int, str], RectBivariateSpline] = {}
        # padded coordinates: mirror rows across the poles, wrap columns around the globe
        p = _PAD
        self._plat = np.concatenate([-math.pi - self.lat[p - 1 :: -1], self.lat, math.pi - self.lat[: -p - 1 : -1]])
        self._plon = np.radians(360.0 / lon.size) * np.arange(-p, lon.size + p)

    def _spline(self, itime: int, name: str) -> RectBivariateSpline:
        key = (itime, name)
        if key not in self._splines:
            f = np.asarray(self._fields[name][0 if name == "hs" else itime], dtype=np.float64)
            p, n = _PAD, f.shape[1]
            sign = -1.0 if name in ("u", "v") else 1.0
            over = sign * np.roll(f, n // 2, axis=1)  # value at lon + 180°
            f = np.concatenate([over[p - 1 :: -1], f, over[: -p - 1 : -1]], axis=0)
            f = np.concatenate([f[:, -p:], f, f[:, :p]], axis=1)
            self._splines[key] = RectBivariateSpline(self._plat, self._plon, f, kx=3, ky=3, s=0)
        return self._splines[key]

    def at(self, day: float, lat, lon) -> dict[str, np.ndarray]:
        """Fields interpolated to points (``lat``, ``lon``) at a stored day.

        ``lat``, ``lon``: radians, arrays of any equal (or broadcastable) shape;
        ``lon`` in any range. Returns float64 arrays of that shape:
        ``'h_surface'``, ``'h'``, ``'hs'`` (m) and ``'u'``, ``'v'`` (m s⁻¹),
        with ``h = h_surface − hs``, and ``'vorticity'`` (s⁻¹). Compare ``h_surface``: ``hs`` (hence ``h``)
        has a kink at the TC5 cone's edge and interpolates less accurately there.

        Raises ``ValueError`` if ``day`` is not stored (within 1e-6 day) or a
        latitude lies outside [−π/2, π/2].
        """
        itime = stored_index(self.days, day)
        if itime is None:
            raise ValueError(f"day {day:g} not stored in {self.path.name} (stored: {', '.join(f'{d:g}' for d in self.days)})")
        lat, lon = np.broadcast_arrays(np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64))
        if np.any(np.abs(lat) > math.pi / 2 + 1e-12):
            raise ValueError("latitude outside [-pi/2, pi/2] radians")
        x, y = lat.ravel(), np.mod(lon.ravel(), 2 * math.pi)
        out = {name: self._spline(itime, name).ev(x, y).reshape(lat.shape) for name in ("h_surface", "hs", "u", "v", "vorticity")}
        out["h"] = out["h_surface"] - out["hs"]
        return out


def _bundled(name: str) -> Path:
    """The path a bundled reference file of this name has (it may not exist)."""
    return Path(str(importlib.resources.files("swe_sphere.testcases") / "reference" / name))


def locate(spec: str) -> Path:
    """The absolute path of a reference file given as a path (absolute, or relative
    to the current directory) or as the file name of a bundled one (e.g.
    "tc5_mountain_T213.nc"). Raises ``FileNotFoundError`` if neither exists."""
    path = Path(spec)
    if path.is_file():
        return path.absolute()
    bundled = _bundled(path.name)
    if path.parent == Path(".") and bundled.is_file():
        return bundled
    raise FileNotFoundError(f"reference file not found: {spec}")


def reference_path(case) -> Path | None:
    """The installed reference file of a case object (``Case.reference_file``), or None."""
    if case.reference_file is None:
        return None
    path = _bundled(case.reference_file)
    return path if path.is_file() else None


def find_reference(case_name: str, perturbed: bool = True) -> Path | None:
    """Bundled reference file of a case (``Case.reference_file``), or None.

    'tc5_mountain' → ``testcases/reference/tc5_mountain_T213.nc``,
    'tc6_rossby_haurwitz' → ``tc6_rossby_haurwitz_T213.nc``, 'galewsky' →
    ``galewsky_T213.nc``, or ``galewsky_balanced_T213.nc`` when ``perturbed`` is
    False. None for other cases, and if the file is not installed. The folder is
    ``importlib.resources.files('swe_sphere.testcases') / 'reference'``.
    """
    from .cases import make_case

    return reference_path(make_case(case_name, {"perturbed": bool(perturbed)} if case_name == "galewsky" else {}))


# A reference's own error: the normalized l2 distance of each file to a finer run
# of the same model, (h + hs, vorticity, divergence) by stored day, vorticity and
# divergence over one normaliser sqrt(∫ ζ² + δ²) of the finer run's wind, as
# ``scoring.rotational_divergent_errors`` scores a run. A run's spatial error
# near it cannot be told from the reference's own. Source:
# /work/shared/reference/README.md, "How close T213 is to the truth" (TC5 T213 −
# T341, compared spectrally). Unmeasured elsewhere (T341 itself, TC6, Galewsky).
FLOORS = {
    "tc5_mountain_T213.nc": ("T213 vs T341", {
        1.0: (3.4e-6, 1.7e-3, 6.3e-3),
        2.0: (4.3e-6, 2.0e-3, 5.5e-3),
        5.0: (5.9e-6, 5.7e-3, 4.2e-3),
        10.0: (7.8e-6, 6.0e-3, 3.6e-3),
        15.0: (1.0e-5, 7.8e-3, 3.1e-3),
    }),
}


def floor(name, day: float) -> tuple[float, float, float] | None:
    """The reference file ``name``'s (a file name or path; only its name counts)
    own normalized l2 error (h + hs, vorticity, divergence) at ``day`` (within
    1e-6 day), from ``FLOORS`` (whose first item names the comparison, e.g.
    "T213 vs T341"); None where it is unknown."""
    _, by_day = FLOORS.get(Path(name).name, ("", {}))
    i = stored_index(list(by_day), day)
    return None if i is None else list(by_day.values())[i]
