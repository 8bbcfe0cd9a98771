"""A state of the real atmosphere from a reanalysis file, by the references' own machinery.

A CF netCDF file (or an ``xarray.Dataset``) on a global regular or Gaussian lat-lon grid
(latitude either way, longitude 0–360 or −180–180) holding the geopotential (m² s⁻², divided
by the planet's g to the model's h, so that g h is the file's geopotential) or the geopotential
height (m: times g₀ = 9.80665, WMO's standard gravity, to the geopotential), told apart by
``standard_name`` or ``units``, and the wind u, v (m s⁻¹) is read at one level
(``level``, hPa) and one time (``time``: an ISO date such as "2021-01-15T00" on a date
coordinate, "NAME=VALUE" on another dimension, e.g. "month=1", or a value of the one
dimension left). Variables are found by their CF ``standard_name``, else by the usual names
(``reanalysis_file.NAMES``); a file is read with netCDF4 itself (xarray's open costs a run 2-3 s of imports).
The fields are analysed into spherical harmonics with ``ducc0.sht.analysis_2d`` in the grid's
own exact quadrature (Gauss–Legendre for a Gaussian grid, Clenshaw–Curtis for a regular grid
with poles, Fejér's rules without them), the wind as its vorticity and divergence (ducc0's spin-1 transform: (−v, u) on the colatitude–longitude
basis has E = −a δ_lm / √(l(l+1)), B = −a ζ_lm / √(l(l+1))), truncated, and synthesised at any
points exactly as the spectral references are (``reference.spectral_fields``).

The truncation: ``truncation`` as given (a sharp cut, as the references' T106 start), else the
highest degree both the data's quadrature and the model's grid resolve (``grid_degree``, the
Nyquist degree 2 ne (np − 1)), tapered by cos² over its top third (no Gibbs ringing at the
cut). A surface height ``surface_file`` (orography in m, or surface geopotential) is analysed
at the same truncation and taper: hs, and h = (h + hs) − hs; else hs = 0.

Every problem raises ``SceneError`` (one line naming the file and variable): not netCDF, one
of our own run files, no height or wind, units neither m nor m² s⁻², not global, NaN or fill
values, a level or time not in the file, a 3-D field and no level, several times and no time.

Sources: Williamson et al. (1992) J. Comput. Phys. 102, 211–224, case 7 (the analysed 500 mb
height and wind as an initial state); ducc0 (Reinecke), ``ducc0.sht``.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..cases.library import Case
from ..cases.reference import SpectralReference, reference_path, spectral_fields, synthesis
from ..core.constants import EARTH
from ..core.errors import SceneError
from . import restart_file
from .formats import file_stamp
from .reanalysis_file import RINGS, open_source, read_field


def taper(lmax: int, truncation: int, sharp: bool) -> np.ndarray:
    """Weights (nalm,) in ducc0's order up to ``lmax``: 1 up to ``truncation`` and 0 above, with
    (unless ``sharp``) cos² rolling off from 2/3 of ``truncation`` to 0 just past it."""
    l = np.concatenate([np.arange(m, lmax + 1) for m in range(lmax + 1)])
    if sharp:
        return (l <= truncation).astype(np.float64)
    start = 2.0 * truncation / 3.0
    x = np.clip((l - start) / (truncation + 1 - start), 0.0, 1.0)
    return np.cos(0.5 * math.pi * x) ** 2


@dataclass(frozen=True)
class Analysed:
    """A band-limited state: h + hs, vorticity, divergence and hs as coefficients (nalm,)
    complex in ducc0's order up to ``lmax`` (m, s⁻¹, s⁻¹, m), on a sphere of radius ``a``."""

    h_surface: np.ndarray
    vorticity: np.ndarray
    divergence: np.ndarray
    hs: np.ndarray | None
    lmax: int
    a: float
    read: str = ""  # what was read and how (``analyse``): the variables, level, time, grid and truncation

    def at(self, lat, lon) -> dict[str, np.ndarray]:
        """``reference.spectral_fields`` at ``lat``, ``lon`` (radians, any equal shape), with
        ``'hs'`` (m) and ``'h'`` = h_surface − hs; arrays of that shape."""
        shape = np.shape(lat)
        lat, lon = np.ravel(lat).astype(np.float64), np.mod(np.ravel(lon), 2 * math.pi)
        out = spectral_fields(self.h_surface, self.vorticity, self.divergence, self.lmax, self.a, lat, lon)
        out["hs"] = np.zeros_like(lat) if self.hs is None else synthesis(self.hs, self.lmax, lat, lon)
        out["h"] = out["h_surface"] - out["hs"]
        return {k: v.reshape(shape) for k, v in out.items()}


def analyse(source, level=None, time=None, truncation=None, grid_degree=None, surface=None, planet=EARTH, where=None):
    """The ``Analysed`` state of ``source`` (a path or an ``xarray.Dataset``; module docstring)
    at ``level`` (hPa) and ``time``, truncated at ``truncation`` (sharp) or at the degree both
    the data and ``grid_degree`` resolve (tapered); ``surface``: a file of the surface height;
    heights h = geopotential / g and the wind on ``planet`` (a ``constants.Planet``: g, a).
    ``where`` names the source in messages. Raises ``SceneError``."""
    import ducc0

    where = where or (f"initial file {source}" if isinstance(source, (str, Path)) else "the initial dataset")
    ds = open_source(source, where)
    try:
        height, u, v = (read_field(ds, role, level, time, where) for role in ("height", "u", "v"))
    finally:
        ds.close()
    if v[1:4] != u[1:4] or height[1:4] != u[1:4]:
        raise SceneError(f"{where}: the height and the wind are on different grids")
    _, phi0, rings, degree, said = height
    nlat, nlon = height[0].shape
    if truncation is not None and not (isinstance(truncation, (int, float)) and 1 <= truncation == int(truncation)):
        raise SceneError(f"case.truncation must be a whole degree >= 1 (got {truncation!r})")
    cut = degree if grid_degree is None else min(degree, int(grid_degree))
    lmax = cut if truncation is None else int(truncation)
    if lmax > degree:
        raise SceneError(f"{where}: truncation T{lmax} is above the T{degree} its grid resolves exactly")
    weights = taper(lmax, lmax, sharp=truncation is not None)

    def scalar(values, phi):
        return weights * ducc0.sht.analysis_2d(map=values[None], spin=0, lmax=lmax, geometry=rings, phi0=phi)[0]

    wind = np.stack([-v[0], u[0]])  # (v_θ, v_λ): ducc0's spin-1 components
    e, b = ducc0.sht.analysis_2d(map=wind, spin=1, lmax=lmax, geometry=rings, phi0=phi0)
    l = np.concatenate([np.arange(m, lmax + 1) for m in range(lmax + 1)])
    root = np.sqrt(l * (l + 1.0)) / planet.a
    hs = None if surface is None else _surface(surface, lmax, weights, where) / planet.g
    h_surface = scalar(height[0], phi0) / planet.g
    read = (
        f"{said}; wind {u[4].partition(' (')[0]}, {v[4].partition(' (')[0]}; a {RINGS[rings]} grid of {nlat} x "
        f"{nlon}, analysed to T{lmax} "
        + ("(sharp)" if truncation is not None else "(tapered: cos² from 2/3 of it)")
        + ("" if surface is None else f", over the surface of {Path(surface).name}")
    )
    return Analysed(h_surface, -weights * root * b, -weights * root * e, hs, lmax, planet.a, read)


def _surface(surface, lmax: int, weights, where: str) -> np.ndarray:
    """The surface geopotential's coefficients (m² s⁻²) from the file ``surface`` at the state's truncation."""
    import ducc0

    where = f"surface file {surface} ({where})"
    ds = open_source(surface, where)
    try:
        values, phi0, rings, degree, _ = read_field(ds, "surface", None, None, where)
    finally:
        ds.close()
    if lmax > degree:
        raise SceneError(f"{where}: its grid resolves T{degree}, below the state's T{lmax}")
    return weights * ducc0.sht.analysis_2d(map=values[None], spin=0, lmax=lmax, geometry=rings, phi0=phi0)[0]


GIVEN = "xarray.Dataset"  # the start of a case's initial_file that names a Dataset given in Python (``given``)
_given: dict[str, tuple[int, object]] = {}  # such a name → (a token of this Dataset, the Dataset), while given
_tokens = itertools.count()


def is_given(name) -> bool:
    """Whether a reanalysis case's ``initial_file`` ``name`` names a Dataset given in Python (``given``)."""
    return isinstance(name, str) and name.startswith(GIVEN)


@contextlib.contextmanager
def given(dataset):
    """The name under which a reanalysis case reads ``dataset`` (an ``xarray.Dataset``) as its
    ``initial_file`` while inside, which its run files record: ``GIVEN``, with the file it was
    opened from and its title where it has them (no temporary file; a restart file keeps its analysed
    state, ``restart_file.ANALYSED``, so a continuation needs neither)."""
    about = (("opened from", dataset.encoding.get("source")), ("title", dataset.attrs.get("title")))
    about = "; ".join(f"{what} {' '.join(str(value).split())}" for what, value in about if value)
    name = GIVEN + (f" ({about})" if about else "")
    _given[name] = (next(_tokens), dataset)
    try:
        yield name
    finally:
        del _given[name]


@functools.lru_cache(maxsize=4)
def _cached(path, stamp, level, time, truncation, grid_degree, surface, planet):
    if path in _given:  # a Dataset given in Python, ``stamp`` its token
        return analyse(_given[path][1], level, time, truncation, grid_degree, surface, planet, "the Dataset given")
    return analyse(path, level, time, truncation, grid_degree, surface, planet)


@functools.lru_cache(maxsize=4)
def _kept(path, stamp) -> Analysed:
    return Analysed(**restart_file.read_analysed(path))


@dataclass(frozen=True)
class Reanalysis(Case):
    """A state of one's own from a reanalysis file (module docstring): ``initial_file`` at
    ``level`` (hPa) and ``time``, truncated at ``truncation`` (default: tapered at what the
    data and ``grid_degree``, the model grid's Nyquist degree that ``Scene.make_case`` gives,
    resolve), over the surface of ``surface_file`` (else hs = 0). Unforced, scored against nothing.

    ``analysed_file``: a restart file keeping that state (``restart_file.ANALYSED``), read instead of
    ``initial_file`` and ``surface_file`` (which then only record what was read), so a continuation
    (``checkpoint.read`` sets it) needs neither; ``CheckpointError`` where it cannot be read."""

    initial_file: str | None = None
    level: float | None = None
    time: str | None = None
    truncation: float | None = None
    surface_file: str | None = None
    grid_degree: float | None = None
    analysed_file: str | None = None

    def __post_init__(self):  # read and checked once (``SceneError``), when the scene is loaded
        if self.initial_file is None:
            raise SceneError("case.initial_file is missing: the reanalysis file (netCDF) of the initial state")
        if self.analysed_file is not None:
            state = _kept(self.analysed_file, file_stamp(self.analysed_file))
        else:
            key = (self.level, self.time, self.truncation, self.grid_degree, self.surface_file, self.planet)
            given = _given.get(self.initial_file)
            state = _cached(self.initial_file, file_stamp(self.initial_file) if given is None else given[0], *key)
        object.__setattr__(self, "_state", state)

    @property
    def analysed(self) -> Analysed:
        """The analysed state the case synthesises at the nodes (a restart file keeps it)."""
        return self._state

    @property
    def required_terms(self):
        return Case.required_terms | ({"topography"} if self.surface_file is not None else set())

    def hs(self, lat, lon):
        return self._state.at(lat, lon)["hs"]

    def notes(self) -> tuple:
        name = self.initial_file if is_given(self.initial_file) else Path(self.initial_file).name
        return (f"read from {name}: {self._state.read}",)

    def initial(self, lat, lon):
        return _initial(self._state.at(lat, lon), self.initial_file, self.surface_file)


def _initial(fields: dict, where, surface_file=None) -> tuple:
    """(u, v, h) of evaluated ``fields``; ``SceneError`` where h <= 0: the surface of
    ``surface_file`` above the level's height, or (none given) the level's height itself."""
    low = np.count_nonzero(fields["h"] <= 0)
    if low and surface_file is not None:
        raise SceneError(
            f"{where}: h = (h + hs) - hs <= 0 at {low} nodes: the surface of {surface_file} rises above the "
            "level's height there (choose a higher level or no surface_file)"
        )
    if low:
        raise SceneError(
            f"{where}: the level's height is zero or below at {low} nodes (lowest {fields['h'].min():.0f} m; "
            "a level below the ground there): choose a higher level"
        )
    return fields["u"], fields["v"], fields["h"]


@functools.lru_cache(maxsize=1)
def _january() -> SpectralReference:
    return SpectralReference(reference_path(EraJanuary()))


@dataclass(frozen=True)
class EraJanuary(Case):
    """Williamson et al. (1992) case 7 on ERA-Interim's January-mean 500 hPa state: h + hs
    (hs = 0), vorticity and divergence truncated at T106, the bundled T341 reference's day 0
    (``testcases/reference/README.md``), synthesised exactly at the nodes; scored against
    that reference's days 1–5 (T213's, ``case.reference = "T213"``, differ from them by more than
    a fine grid's vorticity error: 8.4e-2 at day 5)."""

    reference_file = "tc7_era_january_T341.nc"

    def initial(self, lat, lon):
        return _initial(_january().at(0.0, lat, lon), self.reference_file)


# the cases of this module a scene may name (``initial_state.SCENE_CASES``)
REANALYSIS_CASES = {
    "tc7_era_january": (EraJanuary, {}),
    "reanalysis": (
        Reanalysis,
        {
            "initial_file": str,
            "level": float,
            "time": str,
            "truncation": float,
            "surface_file": str,
            "analysed_file": str,
        },
    ),
}
