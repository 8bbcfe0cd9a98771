"""The resolvers of a scene's [hyperviscosity] table (``load_scene``'s, as ``resolve``'s for the
other tables): the coefficients on the run's grid and planet (``resolve_hyperviscosity``, the
e-folding rule ``efold_nu``) and the steps between applications (``resolve_every``). Every
problem raises ``SceneError`` with a one-line message naming the key.
"""

from __future__ import annotations

import math

from ..core.arguments import got
from ..core.clock import Clock, common_interval
from ..core.constants import DAY
from ..core.errors import SceneError
from ..model.hyperviscosity import evaluations
from ..steppers import STEPPERS
from .resolve import Spacing
from .schema import SceneGrid, SceneHyperviscosity

HYPERVIS_EXPONENT = 3.2  # ν ∝ Δx^3.2 (HOMME's resolution scaling; Dennis et al. 2012)


def efold_nu(hours: float, ne: float, np_: int, radius: float) -> float:
    """ν (m⁴ s⁻¹) that e-folds a degree-L harmonic in ``hours``, L = 2 ne (np − 1)
    the Nyquist degree of the 4 ne (np − 1) nodes around a great circle:
    ν = a⁴ / (τ (L(L+1))²). The T213 references use the same rule (3 h at
    l = 213: ν₄ = 7.34e13 m⁴ s⁻¹). On a mesh the rule is stated at the mean
    spacing: ne is that of the uniform cube with as many elements (``mesh.records``' ``mean_ne``:
    √(F/6) for a file of F elements; a stretched cube's own ne), so ν is the same for
    the same element count, and elements smaller than the mean are damped faster, as
    (mean spacing / their spacing)⁴; with the tensor ∇⁴ (``hyperviscosity.scaling = s``) as
    that ratio to the power 4 − s, so s = 4 states the rule element by element."""
    L = 2 * ne * (np_ - 1)
    return radius**4 / (hours * 3600.0 * (L * (L + 1)) ** 2)


def resolve_hyperviscosity(
    table: dict, terms: tuple, grid: SceneGrid, spacing: Spacing
) -> tuple[SceneHyperviscosity, tuple]:
    """(nu, nu_div, nu_s (m⁴ s⁻¹) and subcycle; notes) of the [hyperviscosity] table on the
    run's ``grid`` and planet. Coefficients given are for the scene file's grid and planet: they
    scale as ``spacing.mean`` to ``HYPERVIS_EXPONENT`` and, keeping their damping time at the
    grid scale, as ``spacing.scale``⁴ (the radii's ratio); ``efold_hours``
    sets the others on the run's grid (``efold_nu``); without it nu_div and nu_s default to nu.
    All are 0 without the hyperviscosity term. Raises ``SceneError`` naming the key: a negative
    coefficient, efold_hours, subcycle or every not > 0, the term without a coefficient > 0."""
    for key in ("efold_hours", "nu", "nu_div", "nu_s"):
        if table.get(key, 0.0) < 0 or (key == "efold_hours" and key in table and table[key] == 0):
            raise SceneError(
                f"hyperviscosity.{key} must be {'> 0' if key == 'efold_hours' else '>= 0'} (got {table[key]})"
            )
    scaling = table.get("scaling")
    if scaling is not None and not 0 <= scaling <= 4:
        raise SceneError(
            f"hyperviscosity.scaling must be in 0..4 (got {scaling}): the s of nu ~ dx^s per element "
            "(HOMME's hypervis_scaling, E3SM's 3.2)"
        )
    # under the tensor, given coefficients scale as dx^s
    exponent = HYPERVIS_EXPONENT if scaling is None else scaling
    ratio, planet_factor = spacing.mean, spacing.scale**4
    given = [k for k in ("nu", "nu_div", "nu_s") if k in table]
    nus = {key: table[key] * ratio**exponent * planet_factor for key in given}
    notes = []
    if "efold_hours" in table:
        mean_ne = grid.record.mean_ne
        rule = efold_nu(table["efold_hours"], mean_ne, grid.np, spacing.radii[0])
        nus = {key: nus.get(key, rule) for key in ("nu", "nu_div", "nu_s")}
        if ratio != 1.0:
            degree = round(2 * mean_ne * (grid.np - 1))
            notes.append(f"nu = {rule:.3g} m^4/s: {table['efold_hours']:g} h e-folding at degree {degree}")
    else:
        nus = {key: nus.get(key, nus.get("nu", 0.0)) for key in ("nu", "nu_div", "nu_s")}
    if "hyperviscosity" in terms and max(nus.values()) == 0:
        raise SceneError("the hyperviscosity term needs hyperviscosity.nu, nu_div, nu_s or efold_hours > 0")
    if "hyperviscosity" not in terms:
        if given or scaling is not None:
            notes.append("hyperviscosity coefficients given, but the scene's terms have no hyperviscosity: not used")
        nus = dict.fromkeys(nus, 0.0)
    elif (ratio != 1.0 or planet_factor != 1.0) and given and max(nus.values()) > 0:
        notes.append(
            f"nu scaled as dx^{exponent:g} and radius^4: nu, nu_div, nu_s = "
            f"{nus['nu']:.3g}, {nus['nu_div']:.3g}, {nus['nu_s']:.3g} m^4/s"
        )
    if scaling is not None and "hyperviscosity" in terms:
        a = spacing.radii[0]
        d_ref = math.pi * a / (4 * grid.record.mean_ne)  # ``grid.quality.reference_spacing``
        notes.append(
            f"tensor hyperviscosity: nu (dx / {2 * d_ref / (grid.np - 1) / 1e3:.4g} km)^{scaling:g} along each element "
            f"direction (HOMME's hypervis_scaling = {scaling:g}, nu = {nus['nu'] / (a**4 * (d_ref / a) ** scaling):.3g})"
        )
    subcycle = table.get("subcycle", 1)
    if subcycle < 1:
        raise SceneError(f"hyperviscosity.subcycle must be >= 1 (got {subcycle})")
    every = table.get("every", 1)
    whole = isinstance(every, int) or (isinstance(every, float) and every.is_integer())
    if every != "auto" and (isinstance(every, bool) or not whole or every < 1):
        raise SceneError(f"hyperviscosity.every must be an integer >= 1 or 'auto' (got {got(every)})")
    scaling = None if scaling is None or "hyperviscosity" not in terms else float(scaling)
    hv = SceneHyperviscosity(
        float(nus["nu"]),
        float(nus["nu_div"]),
        float(nus["nu_s"]),
        int(subcycle),
        scaling,
        1 if every == "auto" else every,
    )
    return hv, tuple(notes)


# ``every = "auto"``: the ∇⁴'s span kΔt at most this fraction of the e-folding time τ of the grid's
# Nyquist degree (``efold_nu``). Measured (docs/efficiency.md, "A step's cost"; eq. 83 against T341):
# galewsky ne12 np8 kgu35 (τ 3 h) day-6 vorticity +0.26 % at τ/11, +0.8 % at τ/5.7, +2.9 % at τ/2.9;
# TC5 ne30 np4 rk4 (τ 3 h) day-15 h + hs +0.0 % at τ/12.8, +0.1 % at τ/6.4
EVERY_SPAN = 1 / 6


# A ∇⁴ evaluation's cost against the rest of a step (one thread, CPU clock, medians of 9
# interleaved rounds, benchmarks/hyperviscosity_every.py, results sparse_every_*.json): 0.76 for TC5 ne8
# np4 rk4, 1.04 for galewsky ne12 np8 kgu35, 1.08 at ne22 np6
HV_SHARE = 0.9
# A dt shortened for a sparser ∇⁴ only where that saves more than the cost model's own error: 2 %
SPARSE_GAIN = 0.98
# ν λ τ on the uniform cube by np (λ the ∇⁴'s spectral radius, ``Hyperviscosity.biharmonic_radius``;
# τ the e-folding time of the Nyquist degree, ``efold_nu``): measured at ne4, 8 and 12, within
# 1.7 % of one another, growing with ne: the ne12 figures and 2 % more, so that the ∇⁴'s plan over
# kΔt (``model.hyperviscosity.evaluations``) counted before the model is built is not below the
# model's own
CUBE_STIFFNESS = {np_: 1.02 * v for np_, v in {3: 3.17, 4: 7.42, 5: 16.43, 6: 32.64, 7: 59.11, 8: 99.46}.items()}


def every_span(table: dict, hv: SceneHyperviscosity, grid: SceneGrid, spacing: Spacing, stepper: str, controlled: bool):
    """(span (s), τ (s)): the longest span kΔt that ``every = "auto"`` gives the ∇⁴,
    ``EVERY_SPAN`` of τ, the e-folding time (``efold_nu``'s rule solved for τ) of the grid's
    Nyquist degree under the largest of ν, ν_div, ν_s; None where k is 1 whatever Δt (an integer
    ``every``, a controlled Δt, a three-level scheme, no ∇⁴)."""
    nu = max(hv.nu, hv.nu_div, hv.nu_s)
    if table.get("every", 1) != "auto" or controlled or STEPPERS[stepper].dense_hyperviscosity or nu == 0:
        return None
    tau = efold_nu(1.0, grid.record.mean_ne, grid.np, spacing.radii[0]) / nu * 3600.0
    return EVERY_SPAN * tau, tau


def auto_every(span: float, dt: float, steps: tuple) -> int:
    """The k of ``every = "auto"`` at ``dt`` (s): the largest k whose kΔt is at most ``span``
    (s), preferring the largest k ≥ half that which divides one of ``steps`` (the steps of an
    output interval and of the whole run: the ∇⁴ then done at those times)."""
    most = max(1, math.floor(span / dt * (1 + 1e-9)))
    # the largest that divides either: the output interval's alone took k = 3 where 6 of the
    # run's fit (galewsky ne16 np6, 333 steps a day), the ∇⁴ twice as often for nothing
    return max((k for n in steps for k in range(most, (most + 1) // 2 - 1, -1) if n % k == 0), default=most)


def sparse_dt(dt: float, intervals: tuple, every: float, days: float, span: float, stiffness: float, subcycle: int):
    """The Δt (s) no longer than ``dt`` that costs least a day with the ∇⁴ every ``auto_every``
    steps: C/n' for n' ≥ n = C/Δt whole steps of C, the ``common_interval`` of ``intervals``
    (days: the run and the intervals that Δt divides), minimising n'(1 + ``HV_SHARE`` e(n')/k(n')),
    e the ∇⁴'s evaluations over kΔt (``evaluations`` at ν λ kΔt = ``stiffness`` kΔt, with
    ``subcycle``), the fewest steps where two cost the same; ``dt`` itself where it is not C/n or
    that saves less than ``SPARSE_GAIN``. A count of steps with few divisors takes a small k: TC5
    ne8 np4's odd 109 a day k = 1, its 110 k = 2 (a step 0.785x, a day 0.79x); galewsky ne24 np6's
    499, a prime, k = 6 in 2 RKL1 stages, its 508 k = 8 in 2 (0.333 to 0.25 evaluations a step,
    a day 0.865x; docs/efficiency.md, "A Δt for a sparser ∇⁴")."""
    common = common_interval(*intervals) * DAY
    n = round(common / dt)
    if n < 1 or abs(common / n - dt) > 1e-9 * dt:
        return dt

    def cost(m: int) -> float:
        step = common / m
        clock = Clock(step)
        k = auto_every(span, step, (clock.steps_in(every), clock.steps_in(days)))
        return m * (1 + HV_SHARE * evaluations(stiffness * k * step, subcycle)[0] / k)

    # k(m) ≤ span·m/C and a ∇⁴ takes one evaluation at least: no more steps than this can pay
    top = math.floor(cost(n) - HV_SHARE * common / (span * (1 + 1e-9)))
    best = min(range(n, max(n, top) + 1), key=cost)  # the first, the fewest steps, of equal costs
    return common / best if cost(best) <= SPARSE_GAIN * cost(n) else dt


def resolve_every(
    table: dict,
    hv: SceneHyperviscosity,
    grid: SceneGrid,
    spacing: Spacing,
    dt: float,
    steps: tuple,
    stepper: str,
    controlled: bool,
) -> tuple[int, tuple]:
    """(k, notes): the steps between ∇⁴ applications of [hyperviscosity] ``every`` on the run's
    grid and Δt (s). An integer is k as given; "auto" ``auto_every``'s k within ``every_span``'s
    span (``steps``: an output interval's and the whole run's), and 1 where k > 1 does not fit (a
    controlled Δt, a three-level scheme, no ∇⁴). Raises ``SceneError`` naming the key: an integer
    k > 1 under a controlled Δt or with a stepper whose ∇⁴ runs after every step, with its reason
    (``Stepper.dense_hyperviscosity``)."""
    every = table.get("every", 1)
    if every == "auto":
        limits = every_span(table, hv, grid, spacing, stepper, controlled)
        k = 1 if limits is None else auto_every(limits[0], dt, steps)
        if k == 1:
            return 1, ()
        return k, (
            f"hyperviscosity every {k} steps ({k * dt / 60:.3g} min; the grid scale's e-folding {limits[1] / 3600:.3g} h)",
        )
    if every > 1 and controlled:
        raise SceneError(
            f"hyperviscosity.every = {every} needs a fixed dt (time.control is not 'fixed'): the ∇⁴ "
            "covers every steps of one dt"
        )
    why = STEPPERS[stepper].dense_hyperviscosity
    if every > 1 and why:
        raise SceneError(f"hyperviscosity.every = {every}: {stepper} {why} (1 only; a one-step method takes every > 1)")
    return every, ()


def resolve_filter(table: dict, dt: float, every: int, controlled: bool) -> tuple[tuple | None, tuple]:
    """(``Scene.element_filter``, notes) of [filter]: (mu, p_bv, s_bv) of the Boyd–Vandeven element
    filter (``grid.gll.boyd_vandeven``; HOMME's ``filter_nl`` names), applied with the ∇⁴ (after
    every step, or every ``every``-th); None for no table or an empty one. ``mu`` in (0, 1], the
    weight of one application, or ``efold_hours`` τ > 0 instead: mu = 1 − exp(−every·dt/τ), so that
    the elements' highest Legendre mode e-folds in τ whatever the (fixed) step; ``p_bv`` > 0 (12) and
    ``s_bv`` in (0, 1) (2/3) have HOMME's shallow-water test defaults. Raises ``SceneError`` naming
    the key."""
    if not table:
        return None, ()
    mu, tau, p, s = table.get("mu"), table.get("efold_hours"), table.get("p_bv", 12.0), table.get("s_bv", 2.0 / 3.0)
    notes = ()
    if (mu is None) == (tau is None):
        raise SceneError(f"[filter] needs one of filter.mu and filter.efold_hours (got {got(mu)} and {got(tau)})")
    if tau is not None:
        if not tau > 0.0:
            raise SceneError(f"filter.efold_hours must be > 0 (got {got(tau)})")
        if controlled:
            raise SceneError("filter.efold_hours needs a fixed dt (time.control is not 'fixed'): give filter.mu")
        mu = -math.expm1(-every * dt / (3600.0 * tau))
        notes = (f"filter mu = {mu:.3g} an application: the elements' highest mode e-folds in {tau:g} h",)
    if not 0.0 < mu <= 1.0:
        raise SceneError(f"filter.mu must be in (0, 1], the weight of one application (got {got(mu)})")
    if not p > 0.0:
        raise SceneError(f"filter.p_bv must be > 0, the order of the filter's sigmoid (got {got(p)})")
    if not 0.0 < s < 1.0:
        raise SceneError(f"filter.s_bv must be in (0, 1), the fraction of the modes kept whole (got {got(s)})")
    return (float(mu), float(p), float(s)), notes
