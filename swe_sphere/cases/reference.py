"""Reference solutions (netCDF files) evaluated at model nodes, and their own error.

The bundled files in ``testcases/reference/`` hold the spherical-harmonic
coefficients of an independent pseudo-spectral (SHTns) shallow-water model's
runs at T213 and T341 (RK4, ∇⁴ hyperdiffusion; see the README there for how
they were made, which days they keep and their limits), evaluated exactly at any
point by ``ducc0.sht.synthesis_general``. A reference is named by a path, a
bundled file name, or a truncation ("T213", "T341": the case's bundled file at
it): :func:`locate` finds it. Gridded files of the same fields (lat-lon,
interpolated by splines) are read too. :func:`floor` says how far a reference
is from a finer one, where that was measured.
"""

from __future__ import annotations

import importlib.resources
import math
import re
from pathlib import Path

import ducc0
import netCDF4
import numpy as np

from ..core.constants import EARTH
from ..core.errors import ArgumentError
from .library import CASES, make_case

_GRIDDED = ("lat", "lon", "time", "h_surface", "hs", "u", "v", "vorticity", "divergence")
_SPECTRAL = ("time", "sh_l", "sh_m", *(f"{f}_spec_{p}" for f in ("hfree", "vort", "div") for p in ("re", "im")))
_TRUNCATION = re.compile(r"T\d+")  # a bundled reference's short name: its truncation
_PAD = 6  # grid rows/columns added across each pole and each longitude edge
_DAY_TOL = 1e-6
_EPSILON = 1e-12  # ducc0's synthesis accuracy (relative): far below the float32 coefficients' 6e-8
# ducc0's oversampling of the points' NUFFT, held at one value: left free (1.1-2.6) it picks the
# cheapest kernel for the number of points, so a node's value changed (by 1e-9 m of h at T24) with
# how many nodes a rank asked for; held, each node's value is its own (the same bits on any rank
# count), as accurate (4e-13 of the largest value from the free choice at T24-T341) and as fast
_SIGMA = (2.0, 2.001)


def stored_index(days: np.ndarray, day: float) -> int | None:
    """The index in ``days`` (a reference's stored days) of ``day`` (within 1e-6
    day), or None when the reference does not store it."""
    hits = np.flatnonzero(np.abs(np.asarray(days) - day) <= _DAY_TOL)
    return int(hits[0]) if hits.size else None


def _is_spectral(ds: netCDF4.Dataset) -> bool:
    return "sh_l" in ds.variables


def _values(ds: netCDF4.Dataset, name: str, dims: tuple[str, ...] | None = None) -> np.ndarray:
    """Variable ``name`` read whole, unpacked (``scale_factor``, ``add_offset``), fill values
    NaN as xarray decodes them, axes in the order ``dims`` (default: the file's). Raises
    ``ValueError`` when ``dims`` are not the variable's dimensions."""
    var = ds.variables[name]
    values = var[...]
    if np.ma.isMaskedArray(values):
        values = np.ma.filled(values, np.nan) if values.dtype.kind == "f" else values.data
    if dims is None:
        return np.asarray(values)
    if sorted(var.dimensions) != sorted(dims):
        raise ValueError(f"{ds.filepath()}: {name} must have dimensions {dims} (has {var.dimensions})")
    return np.transpose(values, [var.dimensions.index(d) for d in dims])


def _open(path) -> netCDF4.Dataset:
    """The open dataset of a reference file (lazy: values are read on use), its
    variables, time units and layout checked: spherical-harmonic coefficients
    (``_SPECTRAL``, if it has ``sh_l``) or a lat-lon grid (``_GRIDDED``). Raises
    ``FileNotFoundError`` if ``path`` does not exist, ``ValueError`` if it is not
    readable netCDF, lacks a variable or has an unexpected layout. Read with netCDF4
    itself: xarray (and pandas) would add a third of a second to every scored run's start."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"reference file not found: {path}")
    try:
        ds = netCDF4.Dataset(path)
    except Exception:  # netCDF4 raises several types, some with many-line messages
        raise ValueError(f"{path}: not a readable netCDF file") from None
    try:
        missing = [name for name in (_SPECTRAL if _is_spectral(ds) else _GRIDDED) if name not in ds.variables]
        if missing:
            raise ValueError(f"{path}: not a reference file: missing variable(s) {', '.join(map(repr, missing))}")
        units = getattr(ds.variables["time"], "units", "days")
        if not units.startswith("days"):
            raise ValueError(f"{path}: time must be in days (units {units!r})")
        if _is_spectral(ds):
            l, m = _values(ds, "sh_l").astype(np.int64), _values(ds, "sh_m").astype(np.int64)
            lmax = int(l.max(initial=0))
            if l.size != (lmax + 1) * (lmax + 2) // 2 or np.any(m * (2 * lmax + 1 - m) // 2 + l != np.arange(l.size)):
                raise ValueError(f"{path}: sh_l, sh_m must be the triangular m-major order (m = 0..L, l = m..L)")
        else:
            lat, lon = _values(ds, "lat"), _values(ds, "lon")
            if not (
                np.all(np.diff(lat) > 0)
                and np.allclose(lon, 360.0 / lon.size * np.arange(lon.size))
                and lon.size % 2 == 0
            ):
                raise ValueError(f"{path}: lat must ascend and lon be 0, 360/n, ... with n even")
    except BaseException:
        ds.close()
        raise
    return ds


def stored_days(path) -> np.ndarray:
    """The days (ntime,) float64 a reference file stores, without reading its
    fields; the file is checked as ``Reference`` checks it (same errors)."""
    with _open(path) as ds:
        return np.asarray(_values(ds, "time"), dtype=np.float64)


def _title_case(ds: netCDF4.Dataset) -> str | None:
    title = getattr(ds, "title", None)
    return title.rsplit(": ", 1)[-1].strip() if isinstance(title, str) and ": " in title else None


def stored_case(path) -> str | None:
    """The case a reference file says it solves: the tail of its ``title`` attribute
    after the last ": " (the bundled files' "T213 spectral-transform reference
    solution: tc5_mountain" → "tc5_mountain"), or None when it has no title. Same
    errors as ``stored_days``."""
    with _open(path) as ds:
        return _title_case(ds)


def cases_of(path, case) -> tuple[str | None, str | None]:
    """(the case the reference file ``path`` says it solves, the one the bundled
    reference of the case object ``case`` says): ``stored_case`` of each, None
    for a file without a title or a case without a bundled reference. A file
    whose case differs from the case's own is another case's reference. Same
    errors as ``stored_days``."""
    own = reference_path(case)
    return stored_case(path), None if own is None else stored_case(own)


class Reference:
    """A reference solution read from one netCDF file, evaluated at any points.

    ``Reference(path)`` is a :class:`SpectralReference` for a file of
    spherical-harmonic coefficients (the bundled ones) and a
    :class:`GriddedReference` for fields on a lat-lon grid.

    Attributes:
      days (ntime,) float64   stored output days
      path                    the file read

    Raises ``FileNotFoundError`` if ``path`` does not exist and ``ValueError``
    if it is not readable netCDF or lacks a variable or has an unexpected layout.
    """

    def __new__(cls, path):
        if cls is Reference:
            with _open(path) as ds:
                cls = SpectralReference if _is_spectral(ds) else GriddedReference
        return super().__new__(cls)

    def at(self, day: float, lat, lon) -> dict[str, np.ndarray]:
        """Fields at points (``lat``, ``lon``) at a stored day.

        ``lat``, ``lon``: radians, arrays of any equal (or broadcastable) shape;
        ``lon`` in any range. Returns float64 arrays of that shape:
        ``'h_surface'``, ``'h'``, ``'hs'`` (m) and ``'u'``, ``'v'`` (m s⁻¹),
        with ``h = h_surface − hs``, and ``'vorticity'`` (s⁻¹). Compare
        ``h_surface``: for TC5 ``hs`` is the exact cone, not the truncated
        mountain the spectral model ran with.

        Raises ``ArgumentError`` (a ValueError) if ``day`` is not stored (within 1e-6 day),
        ``ValueError`` if a latitude lies outside [−π/2, π/2].
        """
        itime = stored_index(self.days, day)
        if itime is None:
            raise ArgumentError(
                f"day {day:g} not stored in {self.path.name} (stored: {', '.join(f'{d:g}' for d in self.days)})"
            )
        lat, lon = np.broadcast_arrays(np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64))
        if np.any(np.abs(lat) > math.pi / 2 + 1e-12):
            raise ValueError("latitude outside [-pi/2, pi/2] radians")
        # _fields: the subclass's evaluation at 1-D points, longitudes in [0, 2π)
        out = {
            k: f.reshape(lat.shape)
            for k, f in self._fields(itime, lat.ravel(), np.mod(lon.ravel(), 2 * math.pi)).items()
        }
        out["h"] = out["h_surface"] - out["hs"]
        return out


def synthesis(alm: np.ndarray, lmax: int, lat, lon, gradient: bool = False) -> np.ndarray:
    """Σ alm Y_lm (nalm,) complex, healpy's m-major order up to ``lmax``, orthonormal harmonics,
    a real field Σ_l [a_l0 Y_l0 + 2 Re Σ_{m≥1} a_lm Y_lm]) at the points ``lat``, ``lon`` (1-D,
    radians, lon in [0, 2π)), (n,); or with ``gradient`` its (∂/∂θ, ∂/∂λ / sin θ) (2, n) on the
    unit sphere. By ``ducc0.sht.synthesis_general`` to a relative accuracy of 1e-12, each point's
    value the same whatever other points are asked for (``_SIGMA``)."""
    loc = np.stack([np.clip(math.pi / 2 - lat, 0.0, math.pi), lon], axis=1)
    out = ducc0.sht.synthesis_general(
        alm=alm[None],
        lmax=lmax,
        loc=loc,
        epsilon=_EPSILON,
        sigma_min=_SIGMA[0],
        sigma_max=_SIGMA[1],
        spin=1 if gradient else 0,
        mode="DERIV1" if gradient else "STANDARD",
    )
    return out if gradient else out[0]


def spectral_fields(h, zeta, delta, lmax: int, a: float, lat, lon) -> dict[str, np.ndarray]:
    """A band-limited state at points: h + hs, relative vorticity and divergence given as
    coefficients (nalm,) complex (``synthesis``' convention and order up to ``lmax``; m, s⁻¹, s⁻¹)
    on a sphere of radius ``a`` (m), evaluated at ``lat``, ``lon`` (1-D, radians, lon in [0, 2π)):
    ``'h_surface'`` (m), ``'u'``, ``'v'`` (m s⁻¹), ``'vorticity'`` (s⁻¹), each (n,) float64.
    The wind u = (∂ψ/∂θ + ∂χ/∂λ / sin θ)/a, v = (∂ψ/∂λ / sin θ − ∂χ/∂θ)/a (θ colatitude) from
    ψ_lm = −a² ζ_lm / (l(l+1)), χ_lm = −a² δ_lm / (l(l+1)), as spin-1 gradients. The one
    evaluation of the references and of a state analysed from a file (``io.reanalysis``)."""
    l = np.concatenate([np.arange(m, lmax + 1) for m in range(lmax + 1)])
    ll = l * (l + 1)
    inverse_laplacian = -(a**2) / np.where(ll > 0, ll, 1) * (ll > 0)  # ∇⁻² on the sphere of radius a
    dpsi = synthesis(inverse_laplacian * zeta, lmax, lat, lon, gradient=True)
    dchi = synthesis(inverse_laplacian * delta, lmax, lat, lon, gradient=True)
    return {
        "h_surface": synthesis(h, lmax, lat, lon),
        "u": (dpsi[0] + dchi[1]) / a,
        "v": (dpsi[1] - dchi[0]) / a,
        "vorticity": synthesis(zeta, lmax, lat, lon),
    }


class SpectralReference(Reference):
    """A reference stored as spherical-harmonic coefficients, evaluated exactly.

    The file (the layout of ``testcases/reference/README.md``, SHTns' own) holds
    ``sh_l``, ``sh_m`` (nlm,): degree and order, m-major; ``hfree_spec``,
    ``vort_spec``, ``div_spec`` ``_re``/``_im`` (time, nlm): h + hs (m),
    relative vorticity and divergence (s⁻¹), orthonormal harmonics without the
    Condon–Shortley phase, a real field being Σ_l [c_l0 Y_l0 + 2 Re Σ_{m≥1} c_lm Y_lm];
    ``time`` (days); attributes ``earth_radius_m`` (default Williamson's a) and
    ``title`` (the case, ``stored_case``).

    :meth:`at` synthesises with ``ducc0.sht.synthesis_general`` (accuracy 1e-12)
    h + hs and the vorticity as scalars, and the wind u = (∂ψ/∂θ + ∂χ/∂λ / sin θ)/a,
    v = (∂ψ/∂λ / sin θ − ∂χ/∂θ)/a (θ colatitude) from ψ_lm = −a² ζ_lm / (l(l+1)),
    χ_lm = −a² δ_lm / (l(l+1)) as spin-1 gradients (ducc0's "DERIV1" mode).
    ``hs``: the case's own surface (``cases``, the exact TC5 cone) when the title
    names a known case; else the file's ``hs_spec`` if stored, else zero.

    Attributes: ``days``, ``path``, ``lmax`` (the truncation).
    """

    def __init__(self, path):
        self.path = Path(path)
        with _open(self.path) as ds:
            self.days = np.asarray(_values(ds, "time"), dtype=np.float64)
            l, m = _values(ds, "sh_l").astype(np.int64), _values(ds, "sh_m").astype(np.int64)
            self.lmax = int(l.max())
            self._a = float(getattr(ds, "earth_radius_m", EARTH.a))
            # ducc0's (HEALPix's) harmonics carry the Condon–Shortley phase (−1)^m; these do not
            phase = np.where(m % 2 == 1, -1.0, 1.0)

            def coefficients(name):
                return (
                    _values(ds, f"{name}_re").astype(np.float64) + 1j * _values(ds, f"{name}_im").astype(np.float64)
                ) * phase

            self._h, self._zeta, self._delta = (coefficients(f"{f}_spec") for f in ("hfree", "vort", "div"))
            case = _title_case(ds)
            if case in CASES:
                self._hs = make_case(case).hs
            elif "hs_spec_re" in ds.variables:
                hs = coefficients("hs_spec")
                self._hs = lambda lat, lon: synthesis(hs, self.lmax, lat, lon)
            else:
                self._hs = lambda lat, lon: np.zeros_like(lat)

    def _fields(self, itime, lat, lon):
        fields = spectral_fields(self._h[itime], self._zeta[itime], self._delta[itime], self.lmax, self._a, lat, lon)
        return {**fields, "hs": self._hs(lat, lon)}


class GriddedReference(Reference):
    """A reference stored on a Gaussian (or any ascending-latitude) lat-lon grid.

    The file holds, on ``nlat`` × ``nlon`` points (``lat`` degrees north,
    ascending; ``lon`` degrees east, equally spaced from 0) and ``time`` (days):
    ``h_surface``, ``h``, ``u``, ``v``, ``vorticity``, ``divergence`` (time,
    lat, lon) and ``hs`` (lat, lon); heights in m, winds in m s⁻¹ (eastward,
    northward), vorticity and divergence in s⁻¹ (the layout of the gridded
    T213 and T341 files the spectral model also wrote).

    :meth:`at` interpolates with bicubic splines (float64) on the grid padded
    periodically in longitude and across each pole (the field continued along
    the meridian, i.e. taken at lon + 180°, wind components with changed sign).

    Attributes: ``days``, ``path``, ``lat``, ``lon`` ((nlat,), (nlon,) radians).
    """

    def __init__(self, path):
        self.path = Path(path)
        with _open(self.path) as ds:
            lat = np.asarray(_values(ds, "lat"), dtype=np.float64)
            lon = np.asarray(_values(ds, "lon"), dtype=np.float64)
            self.days = np.asarray(_values(ds, "time"), dtype=np.float64)
            fields = {k: _values(ds, k, ("time", "lat", "lon")) for k in ("h_surface", "u", "v", "vorticity")}
            fields["hs"] = _values(ds, "hs", ("lat", "lon"))[None]
        self.lat, self.lon = np.radians(lat), np.radians(lon)
        self._grid_fields = fields
        self._splines = {}
        # padded coordinates: mirror rows across the poles, wrap columns around the globe
        p = _PAD
        self._plat = np.concatenate([-math.pi - self.lat[p - 1 :: -1], self.lat, math.pi - self.lat[: -p - 1 : -1]])
        self._plon = np.radians(360.0 / lon.size) * np.arange(-p, lon.size + p)

    def _spline(self, itime: int, name: str):
        from scipy.interpolate import RectBivariateSpline  # slow to import; the bundled files need no spline

        key = (itime, name)
        if key not in self._splines:
            f = np.asarray(self._grid_fields[name][0 if name == "hs" else itime], dtype=np.float64)
            p, n = _PAD, f.shape[1]
            sign = -1.0 if name in ("u", "v") else 1.0
            over = sign * np.roll(f, n // 2, axis=1)  # value at lon + 180°
            f = np.concatenate([over[p - 1 :: -1], f, over[: -p - 1 : -1]], axis=0)
            f = np.concatenate([f[:, -p:], f, f[:, :p]], axis=1)
            self._splines[key] = RectBivariateSpline(self._plat, self._plon, f, kx=3, ky=3, s=0)
        return self._splines[key]

    def _fields(self, itime, lat, lon):
        return {name: self._spline(itime, name).ev(lat, lon) for name in ("h_surface", "hs", "u", "v", "vorticity")}


def _bundled(name: str) -> Path:
    """The path a bundled reference file of this name has (it may not exist)."""
    return Path(str(importlib.resources.files("swe_sphere.testcases") / "reference" / name))


def reference_path(case, truncation: str | None = None) -> Path | None:
    """The installed reference file of a case object at a truncation: its own
    (``Case.reference_file``: T213, case 7's T341) or the bundled file of the same case at another
    truncation ("T341": ``tc5_mountain_T213.nc`` → ``tc5_mountain_T341.nc``).
    None if the case has no reference or the file is not installed."""
    if case.reference_file is None:
        return None
    path = _bundled(f"{_stem(case)}_{truncation}.nc" if truncation is not None else case.reference_file)
    return path if path.is_file() else None


def _stem(case) -> str:
    """What a case's bundled files are named by: its reference file's name without
    the truncation ("tc5_mountain_T213.nc" → "tc5_mountain")."""
    return Path(case.reference_file).stem.rsplit("_", 1)[0]


def truncations(case) -> list[str]:
    """The truncations ("T213", "T341") of a case object's bundled references, lowest first."""
    if case.reference_file is None:
        return []
    found = (p.stem.rsplit("_", 1)[-1] for p in _bundled("").glob(f"{_stem(case)}_T*.nc"))
    return sorted((t for t in found if _TRUNCATION.fullmatch(t)), key=lambda t: int(t[1:]))


def locate(spec: str, case=None) -> Path:
    """The absolute path of a reference file given as a path (absolute, or relative
    to the current directory), as the file name of a bundled one (e.g.
    "tc5_mountain_T341.nc") or, given the run's case object, as a truncation
    ("T213", "T341": ``reference_path``). Raises ``FileNotFoundError`` if none
    exists (for a truncation: naming the ones bundled for the case, or saying the
    case has an exact solution instead)."""
    path = Path(spec)
    if path.is_file():
        return path.absolute()
    if case is not None and _TRUNCATION.fullmatch(spec) and case.reference_file is None:
        why = "it is scored against its exact solution" if case.exact_solution else "none is bundled"
        raise FileNotFoundError(
            f"no {spec} reference for this case: {why} (a run file or a reference file's path can be compared)"
        )
    if case is not None and _TRUNCATION.fullmatch(spec):
        bundled = reference_path(case, spec)
        if bundled is None:
            have = truncations(case)
            raise FileNotFoundError(f"no bundled {spec} reference for this case (bundled: {', '.join(have) or 'none'})")
        return bundled
    bundled = _bundled(path.name)
    if path.parent == Path(".") and bundled.is_file():
        return bundled
    raise FileNotFoundError(f"reference file not found: {spec}")


def find_reference(case_name: str, perturbed: bool = True, truncation: str = "T213") -> Path | None:
    """Bundled reference file of a case by name at a truncation, or None.

    'tc5_mountain' → ``testcases/reference/tc5_mountain_T213.nc``,
    'tc6_rossby_haurwitz' → ``tc6_rossby_haurwitz_T213.nc``, 'galewsky' →
    ``galewsky_T213.nc``, or ``galewsky_balanced_T213.nc`` when ``perturbed`` is
    False; ``truncation="T341"``: ``tc5_mountain_T341.nc`` etc. None for other
    cases, and if the file is not installed. The folder is
    ``importlib.resources.files('swe_sphere.testcases') / 'reference'``.
    """
    return reference_path(
        make_case(case_name, {"perturbed": bool(perturbed)} if case_name == "galewsky" else {}), truncation
    )


# A reference's own error: the normalized l2 distance of each file to a finer run
# of the same model, (h + hs, vorticity, divergence) by stored day, vorticity and
# divergence over one normaliser sqrt(∫ ζ² + δ²) of the finer run's wind, as
# ``scoring.rotational_divergent_errors`` scores a run. A run's spatial error
# near it cannot be told from the reference's own. Source:
# testcases/reference/README.md, "How close T213 is to the truth" (TC5 T213 −
# T341, compared spectrally). T341's own error is unmeasured; the README's TC6 and
# Galewsky tables are not entered here (sweeps of those cases quote no floor).
FLOORS = {
    "tc5_mountain_T213.nc": (
        "T213 vs T341",
        {
            1.0: (3.4e-6, 1.7e-3, 6.3e-3),
            2.0: (4.3e-6, 2.0e-3, 5.5e-3),
            5.0: (5.9e-6, 5.7e-3, 4.2e-3),
            10.0: (7.8e-6, 6.0e-3, 3.6e-3),
            15.0: (1.0e-5, 7.8e-3, 3.1e-3),
        },
    ),
}


def floor(name, day: float) -> tuple[float, float, float] | None:
    """The reference file ``name``'s (a file name or path; only its name counts)
    own normalized l2 error (h + hs, vorticity, divergence) at ``day`` (within
    1e-6 day), from ``FLOORS`` (whose first item names the comparison, e.g.
    "T213 vs T341"); None where it is unknown."""
    _, by_day = FLOORS.get(Path(name).name, ("", {}))
    i = stored_index(list(by_day), day)
    return None if i is None else list(by_day.values())[i]
