"""Initial states, Coriolis parameter, surface height and exact solutions.

Williamson, Drake, Hack, Jakob & Swarztrauber (1992), J. Comput. Phys. 102,
211–224 (cases 1–6; equation numbers below are theirs) and Galewsky,
Scott & Polvani (2004), Tellus 56A, 429–440 (barotropic jet) and Läuter,
Handorf & Dethloff (2005), J. Comput. Phys. 210, 535–553 (unsteady exact
solution).

Every function takes latitude and longitude in radians (any shape) and returns
numpy arrays of that shape: winds ``u`` (eastward), ``v`` (northward) in m s⁻¹,
fluid depth ``h`` and surface height ``hs`` in m, ``fcor`` in s⁻¹.

On a planet of one's own (``Case.planet``, a ``constants.Planet``) the cases
follow the DCMIP small-planet convention (Wedi & Smolarkiewicz 2009, Q. J. R.
Meteorol. Soc. 135, 469–484; the DCMIP 2012 test cases): their shapes are in angles and
their winds (m s⁻¹) and depths (m) are the Earth case's, so the papers'
lengths and rates tied to the Earth's radius keep the Earth's value (TC1–3's
u0 = 2π a/12 days with Williamson's a, TC4's σ = (2a/10⁶)², TC6's winds
a ω and a K); the balance (gh from a Ω u0, ...) and Coriolis use the planet's
radius, rotation and gravity. So radius a/X with Ω·X runs the Earth's flow
X times faster: day d of the Earth is day d/X there.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ..core.constants import DAY, EARTH, Planet


def _xyz(lat, lon):
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])


def _rotate(xyz, axis, angle):
    """Rodrigues rotation of unit vectors xyz (3, ...) about unit ``axis`` by ``angle`` (rad)."""
    axis = np.asarray(axis, dtype=float).reshape(3, *([1] * (xyz.ndim - 1)))
    c, s = math.cos(angle), math.sin(angle)
    cross = np.cross(axis, xyz, axis=0)
    dot = np.sum(axis * xyz, axis=0)
    return xyz * c + cross * s + axis * dot * (1 - c)


def _great_circle(lat, lon, lat_c, lon_c):
    """Great-circle angle (rad) between (lat, lon) and (lat_c, lon_c)."""
    cosr = np.sin(lat_c) * np.sin(lat) + np.cos(lat_c) * np.cos(lat) * np.cos(lon - lon_c)
    return np.arccos(np.clip(cosr, -1.0, 1.0))


def zonal_balance(jet, planet, samples: int = 20001):
    """g·h(φ) − g·h(−π/2) (m² s⁻²) of a zonal flow u = jet(φ) (m s⁻¹, vectorized)
    in gradient-wind balance, d(gh)/dφ = −a u (2Ω sin φ + u tan φ / a)
    (Williamson et al. 1992 eq. 92 for case 3; Galewsky et al. 2004 eq. 3), by
    cumulative Simpson quadrature on ``samples`` latitudes and a cubic spline
    (error < 1e-12 of gh for the C∞ jets used here). Returns a ``scipy.interpolate.CubicSpline``
    of φ (rad)."""
    # imported here: scipy.integrate costs a third of a second, and only the jets' cases need it
    from scipy.integrate import cumulative_simpson
    from scipy.interpolate import CubicSpline

    phi = np.linspace(-math.pi / 2, math.pi / 2, samples)
    u = jet(phi)
    with np.errstate(invalid="ignore"):  # tan φ at the poles, where u = 0
        dgh = np.where(u == 0.0, 0.0, -planet.a * u * (2 * planet.omega * np.sin(phi) + np.tan(phi) * u / planet.a))
    return CubicSpline(phi, cumulative_simpson(dgh, x=phi, initial=0.0))


@functools.lru_cache(maxsize=32)
def _jet_balance(case):
    """``zonal_balance`` of ``case.jet`` on ``case.planet``, computed once per case: a case is a
    frozen dataclass whose fields (its type and planet among them) fix its jet, so an equal case
    gets the same spline, the same bits; TC3's ``initial`` and TC4's ``exact`` ask at every
    output time and score (0.01-0.15 s a call)."""
    return zonal_balance(case.jet, case.planet)


@dataclass(frozen=True)
class Case:
    """Base class: a case supplies fcor, hs, the initial state and, if known, the exact solution."""

    planet: Planet = field(default=EARTH, kw_only=True)  # the planet it is set on (module docstring)
    exact_solution = False
    # the terms a scene of this case must simulate (it may add hyperviscosity, ...):
    # the full shallow-water dynamics unless the case says less is valid
    required_terms = frozenset({"continuity", "momentum_advection", "coriolis", "pressure_gradient"})
    h_is_depth = True  # False: h is a tracer carried by a prescribed wind (TC1)
    reference_file = None  # name of the reference it is scored against by default (testcases/reference/), if any

    def forcing(self):
        """(kernel, params) of the case's analytic forcing for ``ShallowWater``'s
        "forcing" term, or None: the case is unforced."""
        return None

    def fcor(self, lat, lon):
        return 2 * self.planet.omega * np.sin(lat)

    def hs(self, lat, lon):
        return np.zeros_like(lat)

    def initial(self, lat, lon):
        """Return (u, v, h) at t = 0."""
        raise NotImplementedError

    def notes(self) -> tuple:
        """Lines for the run's header and its scene: what the case read to make its start (none here)."""
        return ()

    def exact(self, lat, lon, t):
        """Return (u, v, h) at time t (s); only for cases with ``exact_solution``."""
        raise NotImplementedError(f"{type(self).__name__} has no exact solution")


@dataclass(frozen=True)
class SolidBody(Case):
    """Solid-body rotation about an axis tilted by ``alpha`` from the pole (eqs. 75–76)."""

    alpha: float = 0.0

    @property
    def u0(self):
        return 2 * math.pi * EARTH.a / (12 * DAY)  # Williamson's 38.6 m/s on any planet (module docstring)

    @property
    def axis(self):
        return np.array([-math.sin(self.alpha), 0.0, math.cos(self.alpha)])

    def wind(self, lat, lon):
        a = self.alpha
        u = self.u0 * (np.cos(lat) * math.cos(a) + np.sin(lat) * np.cos(lon) * math.sin(a))
        v = -self.u0 * np.sin(lon) * math.sin(a)
        return u, v

    def _rotated_back(self, lat, lon, t):
        """Lat/lon of the departure points of a solid-body rotation over time t."""
        xyz = _rotate(_xyz(lat, lon), self.axis, -self.u0 / self.planet.a * t)
        return np.arcsin(np.clip(xyz[2], -1, 1)), np.arctan2(xyz[1], xyz[0])


@dataclass(frozen=True)
class CosineBell(SolidBody):
    """Case 1: cosine bell advected once around the sphere in 12 days (eqs. 73–76)."""

    exact_solution = True
    required_terms = frozenset({"continuity"})  # the prescribed wind carries h alone
    h_is_depth = False
    h0: float = 1000.0
    lat_c: float = 0.0
    lon_c: float = 1.5 * math.pi

    def _bell(self, lat, lon):
        R = self.planet.a / 3
        r = self.planet.a * _great_circle(lat, lon, self.lat_c, self.lon_c)
        return np.where(r < R, 0.5 * self.h0 * (1 + np.cos(math.pi * r / R)), 0.0)

    def initial(self, lat, lon):
        return (*self.wind(lat, lon), self._bell(lat, lon))

    def exact(self, lat, lon, t):
        return (*self.wind(lat, lon), self._bell(*self._rotated_back(lat, lon, t)))


@dataclass(frozen=True)
class SteadyZonal(SolidBody):
    """Case 2: global steady-state nonlinear geostrophic flow (eqs. 90–95)."""

    exact_solution = True
    gh0: float = 2.94e4  # m² s⁻²

    def _rot_sin(self, lat, lon):
        a = self.alpha
        return -np.cos(lon) * np.cos(lat) * math.sin(a) + np.sin(lat) * math.cos(a)

    def fcor(self, lat, lon):
        return 2 * self.planet.omega * self._rot_sin(lat, lon)

    def initial(self, lat, lon):
        p = self.planet
        gh = self.gh0 - (p.a * p.omega * self.u0 + 0.5 * self.u0**2) * self._rot_sin(lat, lon) ** 2
        return (*self.wind(lat, lon), gh / p.g)

    def exact(self, lat, lon, t):
        return self.initial(lat, lon)


@dataclass(frozen=True)
class CompactZonal(SteadyZonal):
    """Case 3: steady nonlinear zonal geostrophic flow with compact support
    (eqs. 96–105), about an axis tilted by ``alpha``. In the rotated frame
    (latitude θ', sin θ' = r̂·axis) the flow is zonal,
    u' = u0 b(x) b(xe − x) e^{4/xe}, x = xe (θ' − θb)/(θe − θb),
    b(x) = e^{−1/x} for x > 0 else 0, and gh follows from the balance
    (``zonal_balance``) with gh = gh0 at θ' = −π/2; fcor is rotated as in
    case 2. The exact solution is steady and C∞ but not analytic."""

    theta_b: float = -math.pi / 6
    theta_e: float = math.pi / 2
    x_e: float = 0.3

    def jet(self, theta):
        x = self.x_e * (theta - self.theta_b) / (self.theta_e - self.theta_b)

        def b(y):
            return np.where(y > 0, np.exp(-1.0 / np.where(y > 0, y, 1.0)), 0.0)

        return self.u0 * b(x) * b(self.x_e - x) * math.exp(4.0 / self.x_e)

    def _height(self):
        gh = _jet_balance(self)
        return lambda theta: (self.gh0 + gh(theta)) / self.planet.g

    def initial(self, lat, lon):
        r = _xyz(lat, lon)
        axis = self.axis.reshape(3, *([1] * lat.ndim))
        sin_t = np.clip(np.sum(axis * r, axis=0), -1.0, 1.0)
        theta = np.arcsin(sin_t)
        cos_t = np.sqrt(np.maximum(1.0 - sin_t**2, 0.0))
        speed = self.jet(theta)  # 0 near the rotated poles (θe = π/2, θb > −π/2)
        wind = np.cross(axis, r, axis=0) * np.where(speed == 0.0, 0.0, speed / np.where(cos_t > 0, cos_t, 1.0))
        east = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)])
        north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
        return np.sum(wind * east, axis=0), np.sum(wind * north, axis=0), self._height()(theta)


@dataclass(frozen=True)
class UnsteadySolidBody(SteadyZonal):
    """Läuter, Handorf & Dethloff (2005), example 3: an unsteady exact solution
    of the unforced equations. Case 2's tilted solid-body rotation held fixed
    in the inertial frame, so that on the Earth it turns westward once a day:
    with λ* = λ + Ωt, u = u0 (cos φ cos α + sin φ cos λ* sin α),
    v = −u0 sin λ* sin α, and g(h + hs) = k1 − ½(u0 b + Ωa sin φ)² + ½(Ωa sin φ)²
    with b = sin φ cos α − cos φ cos λ* sin α, over the surface height
    hs = (Ωa sin φ)²/(2g) (which stands in for the centrifugal term the
    equations leave out). Periodic with period 2π/Ω."""

    required_terms = Case.required_terms | {"topography"}

    alpha: float = math.pi / 4
    k1: float = 133681.0  # m² s⁻²

    def fcor(self, lat, lon):
        return Case.fcor(self, lat, lon)

    def hs(self, lat, lon):
        p = self.planet
        return (p.omega * p.a * np.sin(lat)) ** 2 / (2 * p.g)

    def initial(self, lat, lon):
        return self.exact(lat, lon, 0.0)

    def exact(self, lat, lon, t):
        p = self.planet
        lon_t = lon + p.omega * t
        u, v = self.wind(lat, lon_t)
        b = self._rot_sin(lat, lon_t)
        w = p.omega * p.a * np.sin(lat)
        return u, v, (self.k1 - 0.5 * (self.u0 * b + w) ** 2) / p.g


@dataclass(frozen=True)
class ForcedLow(Case):
    """Case 4: forced nonlinear system with a translating low (§3.4, eqs.
    106–129; after Browning et al. 1989). The exact solution is
    u = ū − (1/a) ∂ψ/∂φ, v = (1/(a cos φ)) ∂ψ/∂λ, g h = Φ̄(φ) + f ψ
    with the jet ū = u0 sin¹⁴(2φ) in balance with
    Φ̄ = Φ0 − ∫_{−π/2}^{φ} (a f + ū tan φ') ū dφ' (``zonal_balance``)
    and the low ψ = ψ0 exp(−σ (1 − C)/(1 + C)),
    C = sin φ0 sin φ + cos φ0 cos φ cos(λ − u0 t/a − λ0), which moves east at
    u0 cos φ0 along φ0. Parameters (theirs): u0 = 20 m s⁻¹, Φ0 = 1e5 m² s⁻²,
    ψ0 = −0.03 Φ0/f0 with f0 = 2Ω sin(π/4), σ = (2a/10⁶)², (λ0, φ0) = (0, π/4).
    The solution holds under the forcing that the equations leave over on it
    (``kernels.forcing.translating_low``, in closed form)."""

    required_terms = Case.required_terms | {"forcing"}
    exact_solution = True

    u0: float = 20.0
    phi0: float = 1.0e5  # m² s⁻²
    lat0: float = math.pi / 4
    lon0: float = 0.0

    @property
    def psi0(self) -> float:
        return -0.03 * self.phi0 / (2 * self.planet.omega * math.sin(math.pi / 4))

    @property
    def sigma(self) -> float:
        return (2 * EARTH.a / 1e6) ** 2  # the low's width in angle, the Earth's on any planet

    def jet(self, lat):
        return self.u0 * np.sin(2 * lat) ** 14

    def forcing(self):
        # imported here: Warp's import (about 0.4 s) is a run's, not a plot's or a reference's
        from ..kernels import forcing as forcing_kernels

        p = self.planet
        params = (self.psi0, self.sigma, self.lat0, self.lon0, self.u0, p.omega, p.a, p.g)
        return forcing_kernels.translating_low, forcing_kernels.TranslatingLowParams(*params)

    def initial(self, lat, lon):
        return self.exact(lat, lon, 0.0)

    def exact(self, lat, lon, t):
        """(u, v, h) at time t (s), the wind v = ū ê + k×∇ψ taken
        in Cartesian vectors, ψ's gradient (ψ_C/a)(p − C r̂) (finite at the poles)."""
        p = self.planet
        r = _xyz(lat, lon)
        lonc = self.lon0 + self.u0 / p.a * t
        centre = np.array(
            [math.cos(self.lat0) * math.cos(lonc), math.cos(self.lat0) * math.sin(lonc), math.sin(self.lat0)]
        )
        C = np.tensordot(centre, r, axes=1)
        arg = self.sigma * (1 - C) / np.maximum(1 + C, 1e-2)
        psi = np.where((C > -0.99) & (arg < 700.0), self.psi0 * np.exp(-np.minimum(arg, 700.0)), 0.0)  # as the kernel
        psi_c = 2 * self.sigma * psi / np.maximum(1 + C, 1e-2) ** 2
        wind = (psi_c / p.a) * np.cross(r, centre.reshape(3, *([1] * lat.ndim)), axis=0)  # k×∇ψ
        east = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)])
        north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
        u = self.jet(lat) + np.sum(wind * east, axis=0)
        v = np.sum(wind * north, axis=0)
        gh = self.phi0 + _jet_balance(self)(lat) + 2 * p.omega * np.sin(lat) * psi
        return u, v, gh / p.g


@dataclass(frozen=True)
class Mountain(Case):
    """Case 5: zonal flow over an isolated conical mountain (eqs. 130–135, α = 0)."""

    required_terms = Case.required_terms | {"topography"}
    reference_file = "tc5_mountain_T213.nc"

    u0: float = 20.0
    h0: float = 5960.0
    hs0: float = 2000.0
    radius: float = math.pi / 9
    lat_c: float = math.pi / 6
    lon_c: float = 1.5 * math.pi

    def hs(self, lat, lon):
        r2 = np.minimum(self.radius**2, (lon - self.lon_c) ** 2 + (lat - self.lat_c) ** 2)
        return self.hs0 * (1 - np.sqrt(r2) / self.radius)

    def initial(self, lat, lon):
        p = self.planet
        surface = self.h0 - (p.a * p.omega * self.u0 + 0.5 * self.u0**2) * np.sin(lat) ** 2 / p.g
        return self.u0 * np.cos(lat), np.zeros_like(lat), surface - self.hs(lat, lon)


@dataclass(frozen=True)
class RossbyHaurwitz(Case):
    """Case 6: Rossby–Haurwitz wave of wavenumber R = 4 (eqs. 143–146)."""

    reference_file = "tc6_rossby_haurwitz_T213.nc"

    omega_w: float = 7.848e-6
    K: float = 7.848e-6
    R: int = 4
    h0: float = 8000.0

    def initial(self, lat, lon):
        # ω and K scaled so that the winds a ω, a K are the Earth's on any planet (module docstring)
        p, R = self.planet, self.R
        a, Om = p.a, p.omega
        w, K = self.omega_w * (EARTH.a / a), self.K * (EARTH.a / a)
        c, s = np.cos(lat), np.sin(lat)
        u = a * w * c + a * K * c ** (R - 1) * (R * s**2 - c**2) * np.cos(R * lon)
        v = -a * K * R * c ** (R - 1) * s * np.sin(R * lon)
        A = 0.5 * w * (2 * Om + w) * c**2 + 0.25 * K**2 * (
            c ** (2 * R) * ((R + 1) * c**2 + (2 * R**2 - R - 2)) - 2 * R**2 * c ** (2 * R - 2)
        )
        B = 2 * (Om + w) * K / ((R + 1) * (R + 2)) * c**R * ((R**2 + 2 * R + 2) - (R + 1) ** 2 * c**2)
        C = 0.25 * K**2 * c ** (2 * R) * ((R + 1) * c**2 - (R + 2))
        gh = p.g * self.h0 + a**2 * (A + B * np.cos(R * lon) + C * np.cos(2 * R * lon))
        return u, v, gh / p.g


@dataclass(frozen=True)
class Galewsky(Case):
    """Galewsky et al. (2004): balanced mid-latitude jet (eqs. 2–3), mean depth 10 km,
    plus the localized height perturbation of their eq. 4 unless ``perturbed`` is False."""

    perturbed: bool = True
    umax: float = 80.0

    lat0: float = math.pi / 7
    lat1: float = math.pi / 2 - math.pi / 7
    mean_depth: float = 10000.0
    hhat: float = 120.0
    alpha_p: float = 1.0 / 3.0
    beta_p: float = 1.0 / 15.0
    lat2: float = math.pi / 4
    lon2: float = 0.0  # the bump's longitude (rad; theirs 0)

    @property
    def reference_file(self):
        """The bundled T213 run of Galewsky's own values (jet, bump height and place); None for others."""
        if (self.umax, self.hhat, self.lat2, self.lon2) != (80.0, 120.0, math.pi / 4, 0.0):
            return None
        return "galewsky_T213.nc" if self.perturbed else "galewsky_balanced_T213.nc"

    def jet(self, lat):
        en = math.exp(-4.0 / (self.lat1 - self.lat0) ** 2)
        inside = (lat > self.lat0) & (lat < self.lat1)
        arg = np.where(inside, (lat - self.lat0) * (lat - self.lat1), -1.0)
        return np.where(inside, self.umax / en * np.exp(1.0 / arg), 0.0)

    def _balanced_height(self):
        """h(lat) from gradient-wind balance (their eq. 3), shifted so that the
        global mean depth is mean_depth: mean = ½∫ h cosφ dφ."""
        gh = _jet_balance(self)
        phi = np.linspace(-math.pi / 2, math.pi / 2, 20001)
        mean = 0.5 * np.trapezoid(gh(phi) / self.planet.g * np.cos(phi), phi)
        return lambda lat: gh(lat) / self.planet.g + self.mean_depth - mean

    def initial(self, lat, lon):
        h = self._balanced_height()(lat)
        if self.perturbed:
            lam = np.mod(lon - self.lon2 + math.pi, 2 * math.pi) - math.pi  # (-π, π] about the bump (lon - 0: lon)
            h = h + self.hhat * np.cos(lat) * np.exp(-((lam / self.alpha_p) ** 2)) * np.exp(
                -(((self.lat2 - lat) / self.beta_p) ** 2)
            )
        return self.jet(lat), np.zeros_like(lat), h


@dataclass(frozen=True)
class DeformationalFlow(Case):
    """The transport tests' prescribed wind (Lauritzen, Skamarock, Prather & Taylor 2012, Geosci.
    Model Dev. 5, 887, §2.1): Nair & Lauritzen (2010)'s nondivergent deformational flow (their
    case 4), with λ' = λ − 2πt/T,

        u = k0 sin²λ' sin 2θ cos(πt/T) + (2πa/T) cos θ,   v = k0 sin 2λ' cos θ cos(πt/T),

    k0 = κ a / T, κ = ``kappa`` (10: HOMME's ``get_nondiv2d_uv``, whose swirl-test figures the
    docs compare against; 0: solid-body rotation, Williamson's case 1 with α = 0 on a depth), T =
    ``period_days``. Its depth h0 stays constant (the flow is nondivergent) and what it carries
    is back where it started at t = T: the scene's [tracers] are scored there. The wind changes in
    time by the "forcing" term (``kernels.forcing.deformational_flow``: ∂v/∂t, no forcing of h),
    the continuity alone moving h and the tracers."""

    required_terms = frozenset({"continuity", "forcing"})
    exact_solution = True
    divergent = 0.0  # the forcing kernel's choice of flow (1: ``DivergentFlow``)
    kappa: float = 10.0
    period_days: float = 12.0
    h0: float = 1000.0

    @property
    def period(self) -> float:
        return self.period_days * DAY

    def forcing(self):
        from ..kernels import forcing as forcing_kernels  # as ForcedLow's: Warp's import is a run's

        a, T = self.planet.a, self.period
        params = forcing_kernels.DeformationalParams(self.kappa * a / T, 2 * math.pi / T, math.pi / T, self.divergent)
        return forcing_kernels.deformational_flow, params

    def fcor(self, lat, lon):
        return np.zeros_like(lat)  # no Coriolis term: the wind is prescribed

    def initial(self, lat, lon):
        return self.exact(lat, lon, 0.0)

    def exact(self, lat, lon, t):
        """(u, v, h0) at time t (s): the prescribed wind and the constant depth."""
        a, T = self.planet.a, self.period
        k0, shifted, ct = self.kappa * a / T, lon - 2 * math.pi * t / T, math.cos(math.pi * t / T)
        u = k0 * np.sin(shifted) ** 2 * np.sin(2 * lat) * ct + 2 * math.pi * a / T * np.cos(lat)
        v = k0 * np.sin(2 * shifted) * np.cos(lat) * ct
        return u, v, np.full(np.shape(lat), self.h0)


@dataclass(frozen=True)
class DivergentFlow(DeformationalFlow):
    """The transport tests' divergent prescribed wind (Lauritzen et al. 2012, Geosci. Model Dev.
    5, 887, §2.1: Nair & Lauritzen (2010)'s case 3 with the background rotation), with
    λ' = λ − 2πt/T,

        u = −k0 sin²(λ'/2) sin 2θ cos²θ cos(πt/T) + (2πa/T) cos θ,
        v = (k0/2) sin λ' cos³θ cos(πt/T),

    k0 = κ a / T, κ = ``kappa`` (5: their k = 1 at T = 5 on the unit sphere). The divergence
    moves the depth h, which the continuity carries as a density (the tracers' mixing ratios
    q = hq / h are advected); at t = T the flow has undone itself and h, q are back where they
    started: that is the only time the solution is known, so the case has no exact solution to
    score its outputs against (``wind`` gives the prescribed wind at any t). The wind changes in
    time by the "forcing" term (``kernels.forcing.deformational_flow``)."""

    exact_solution = False
    divergent = 1.0
    kappa: float = 5.0

    def initial(self, lat, lon):
        u, v = self.wind(lat, lon, 0.0)
        return u, v, np.full(np.shape(lat), self.h0)

    def wind(self, lat, lon, t):
        """(u, v) (m s⁻¹) of the prescribed wind at time t (s)."""
        a, T = self.planet.a, self.period
        k0, shifted, ct = self.kappa * a / T, lon - 2 * math.pi * t / T, math.cos(math.pi * t / T)
        cos_lat = np.cos(lat)
        u = -k0 * np.sin(shifted / 2) ** 2 * np.sin(2 * lat) * cos_lat**2 * ct + 2 * math.pi * a / T * cos_lat
        v = 0.5 * k0 * np.sin(shifted) * cos_lat**3 * ct
        return u, v

    exact = Case.exact  # h is known at t = 0 and T only


# name → (class, allowed parameters with their types)
CASES: dict[str, tuple[type[Case], dict[str, type]]] = {
    "tc1_cosine_bell": (CosineBell, {"alpha": float}),
    "tc2_steady": (SteadyZonal, {"alpha": float}),
    "tc3_compact_zonal": (CompactZonal, {"alpha": float}),
    "tc4_forced_low": (ForcedLow, {"u0": float}),
    "lauter_unsteady": (UnsteadySolidBody, {"alpha": float}),
    "tc5_mountain": (Mountain, {}),
    "tc6_rossby_haurwitz": (RossbyHaurwitz, {}),
    # the jet's peak wind (m/s), the bump's height (m), latitude and longitude (rad)
    "galewsky": (Galewsky, {"perturbed": bool, "umax": float, "hhat": float, "lat2": float, "lon2": float}),
    # κ of k0 = κ a / T (0: solid-body rotation), T (days), the constant depth (m)
    "deformational_flow": (DeformationalFlow, {"kappa": float, "period_days": float, "h0": float}),
    # the same with the divergent wind (κ 5 by default)
    "divergent_flow": (DivergentFlow, {"kappa": float, "period_days": float, "h0": float}),
}


def make_case(name: str, params: dict | None = None, planet: Planet = EARTH, cases: dict = CASES) -> Case:
    """Build a case by name from ``cases`` (name → (class, allowed parameters); the
    analytic ``CASES``, or ``initial_state.SCENE_CASES``, which adds a file's state)
    with keyword parameters on ``planet``; ValueError names an unknown case or parameter."""
    if name not in cases:
        raise ValueError(f"unknown case {name!r} (known: {', '.join(cases)})")
    cls, allowed = cases[name]
    params = dict(params or {})
    for key, value in params.items():
        if key not in allowed:
            raise ValueError(f"unknown parameter case.{key} for {name} (allowed: {', '.join(allowed) or 'none'})")
        if allowed[key] is float and (isinstance(value, bool) or not isinstance(value, (int, float))):
            raise ValueError(f"case.{key} must be a number (got {value!r})")
        if allowed[key] is bool and not isinstance(value, bool):
            raise ValueError(f"case.{key} must be true or false (got {value!r})")
        if allowed[key] is str and not isinstance(value, str):
            raise ValueError(f"case.{key} must be a string (got {value!r})")
    return cls(**params, planet=planet)
