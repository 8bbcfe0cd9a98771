"""T213 spectral reference solutions (bundled netCDF files) and their interpolation to model nodes.

The files in ``testcases/reference/`` come from an independent pseudo-spectral
(SHTns) shallow-water model at T213, RK4, ∇⁴ hyperdiffusion; see the README
there for how they were made and their limits.
"""

from __future__ import annotations

import importlib.resources
import math
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.interpolate import RectBivariateSpline

_VARIABLES = ("lat", "lon", "time", "h_surface", "hs", "u", "v")
_PAD = 6  # grid rows/columns added across each pole and each longitude edge
_DAY_TOL = 1e-6


def stored_index(days: np.ndarray, day: float) -> int | None:
    """The index in ``days`` (a reference's stored days) of ``day`` (within 1e-6
    day), or None when the reference does not store it."""
    hits = np.flatnonzero(np.abs(np.asarray(days) - day) <= _DAY_TOL)
    return int(hits[0]) if hits.size else None


class Reference:
    """T213 reference solution read from one netCDF file.

    The file holds, on a Gaussian grid of ``nlat`` × ``nlon`` points (``lat``
    degrees north, ascending; ``lon`` degrees east, equally spaced from 0) and
    ``time`` (days): ``h_surface``, ``h``, ``u``, ``v`` (time, lat, lon) and
    ``hs`` (lat, lon); heights in m, winds in m s⁻¹ (eastward, northward).
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
        if not self.path.is_file():
            raise FileNotFoundError(f"reference file not found: {self.path}")
        try:
            ds = xr.open_dataset(self.path, decode_times=False)
        except Exception as exc:  # netCDF4 / xarray raise several types
            raise ValueError(f"{self.path}: not a readable netCDF file ({exc})") from None
        with ds:
            for name in _VARIABLES:
                if name not in ds.variables:
                    raise ValueError(f"{self.path}: missing variable {name!r}")
            units = ds["time"].attrs.get("units", "days")
            if not units.startswith("days"):
                raise ValueError(f"{self.path}: time must be in days (units {units!r})")
            lat = np.asarray(ds["lat"].values, dtype=np.float64)
            lon = np.asarray(ds["lon"].values, dtype=np.float64)
            self.days = np.asarray(ds["time"].values, dtype=np.float64)
            fields = {k: ds[k].transpose("time", "lat", "lon").values for k in ("h_surface", "u", "v")}
            fields["hs"] = ds["hs"].transpose("lat", "lon").values[None]
            if "vorticity" in ds.variables:  # optional: relative vorticity (s⁻¹)
                fields["vorticity"] = ds["vorticity"].transpose("time", "lat", "lon").values
        dlon = 360.0 / lon.size
        if not (np.all(np.diff(lat) > 0) and np.allclose(lon, dlon * np.arange(lon.size)) and lon.size % 2 == 0):
            raise ValueError(f"{self.path}: lat must ascend and lon be 0, 360/n, ... with n even")
        self.lat, self.lon = np.radians(lat), np.radians(lon)
        self._fields = fields
        self._splines: dict[tuple[int, str], RectBivariateSpline] = {}
        # padded coordinates: mirror rows across the poles, wrap columns around the globe
        p = _PAD
        self._plat = np.concatenate([-math.pi - self.lat[p - 1 :: -1], self.lat, math.pi - self.lat[: -p - 1 : -1]])
        self._plon = np.radians(dlon) * np.arange(-p, lon.size + p)

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
        with ``h = h_surface − hs``, and ``'vorticity'`` (s⁻¹) where the file
        has it (the bundled ones do). Compare ``h_surface``: ``hs`` (hence ``h``)
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
        out = {name: self._spline(itime, name).ev(x, y).reshape(lat.shape) for name in ("h_surface", "hs", "u", "v")}
        out["h"] = out["h_surface"] - out["hs"]
        if "vorticity" in self._fields:
            out["vorticity"] = self._spline(itime, "vorticity").ev(x, y).reshape(lat.shape)
        return out


def reference_path(case) -> Path | None:
    """The installed reference file of a case object (``Case.reference_file``), or None."""
    if case.reference_file is None:
        return None
    path = Path(str(importlib.resources.files("swe_sphere.testcases") / "reference" / case.reference_file))
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
