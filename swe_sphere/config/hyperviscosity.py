"""The resolvers of a scene's [hyperviscosity] table (``load_scene``'s, as ``resolve``'s for the
other tables): the coefficients on the run's grid and planet (``resolve_hyperviscosity``, the
e-folding rule ``efold_nu``) and the steps between applications (``resolve_every``). Every
problem raises ``SceneError`` with a one-line message naming the key.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ..core.arguments import got
from ..core.errors import SceneError
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
    that ratio to the power 4 − s, so s = 4 states the rule element by element. inf past a
    float's range."""
    L = 2 * ne * (np_ - 1)
    return _fourth_power(radius) / (hours * 3600.0 * (L * (L + 1)) ** 2)


def _fourth_power(x: float) -> float:
    """x⁴, inf past a float's range (a float's ** raises there)."""
    try:
        return x**4
    except OverflowError:
        return math.inf


def _coefficients(table: dict, given: list, grid: SceneGrid, spacing: Spacing, exponent: float):
    """(nu, nu_div, nu_s (m⁴ s⁻¹), notes) of ``resolve_hyperviscosity``: the ``given`` ones
    scaled as dx^``exponent`` and radius⁴, the others the e-folding rule's, or nu's. Raises
    ``SceneError`` where one is past a float's range (an e-folding time of 1e-300 h)."""
    ratio, planet_factor = spacing.mean, _fourth_power(spacing.scale)
    nus = {key: table[key] * ratio**exponent * planet_factor for key in given}
    notes = []
    if "efold_hours" in table:
        mean_ne = grid.record.mean_ne
        rule = efold_nu(table["efold_hours"], mean_ne, grid.np, spacing.radii[0])
        nus = {key: nus.get(key, rule) for key in ("nu", "nu_div", "nu_s")}
        if ratio != 1.0 and math.isfinite(rule):
            degree = round(2 * mean_ne * (grid.np - 1))
            notes.append(f"nu = {rule:.3g} m^4/s: {table['efold_hours']:g} h e-folding at degree {degree}")
    else:
        nus = {key: nus.get(key, nus.get("nu", 0.0)) for key in ("nu", "nu_div", "nu_s")}
    past = [key for key, nu in nus.items() if not math.isfinite(nu)]
    if past:
        keys = [k for k in (*given, "efold_hours") if k in table]
        raise SceneError(
            f"hyperviscosity.{past[0]} on {grid.record.description(grid.np)} and a planet of radius "
            f"{spacing.radii[0]:g} m is past a float's range (from hyperviscosity.{keys[0]} = {table[keys[0]]:g})"
        )
    return nus, notes


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
    ratio = spacing.mean
    given = [k for k in ("nu", "nu_div", "nu_s") if k in table]
    nus, notes = _coefficients(table, given, grid, spacing, exponent)
    if "hyperviscosity" in terms and max(nus.values()) == 0:
        raise SceneError("the hyperviscosity term needs hyperviscosity.nu, nu_div, nu_s or efold_hours > 0")
    if "hyperviscosity" not in terms:
        if given or scaling is not None:
            notes.append("hyperviscosity coefficients given, but the scene's terms have no hyperviscosity: not used")
        nus = dict.fromkeys(nus, 0.0)
    elif (ratio != 1.0 or spacing.scale != 1.0) and given and max(nus.values()) > 0:
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
# Nyquist degree (``efold_nu``). Measured (docs/explanation/efficiency.md, "A step's cost"; eq. 83 against T341):
# galewsky ne12 np8 kgu35 (τ 3 h) day-6 vorticity +0.26 % at τ/11, +0.8 % at τ/5.7, +2.9 % at τ/2.9;
# TC5 ne30 np4 rk4 (τ 3 h) day-15 h + hs +0.0 % at τ/12.8, +0.1 % at τ/6.4
EVERY_SPAN = 1 / 6


# ν λ τ on the uniform cube by np (λ the ∇⁴'s spectral radius, ``Hyperviscosity.biharmonic_radius``;
# τ the e-folding time of the Nyquist degree, ``efold_nu``): measured at ne4, 8 and 12, within
# 1.7 % of one another, growing with ne: the ne12 figures and 2 % more, so that the ∇⁴'s plan over
# kΔt (``model.hyperviscosity_plan.evaluations``) counted before the model is built is not below the
# model's own
CUBE_STIFFNESS = {np_: 1.02 * v for np_, v in {3: 3.17, 4: 7.42, 5: 16.43, 6: 32.64, 7: 59.11, 8: 99.46}.items()}
# ``auto_every``'s search for a k that divides a count of steps stops past this many candidates
# (a count of more than 10¹² steps: an output interval far past any run's ``MAX_STEPS``)
DIVISOR_SEARCH = 10**6


class Span(NamedTuple):
    """``every_span``'s answer, the ∇⁴'s span as numbers for the step rule (``step_rule.scene_dt``)
    and the schedule (``resolve_every``): ``span`` (s) the longest kΔt, ``tau`` (s) the grid
    scale's e-folding time, ``stiffness`` ν λ (s⁻¹) where known before the model is built (the
    uniform cube and the constant ∇⁴, ``CUBE_STIFFNESS``; else None) and the ∇⁴'s ``subcycle``."""

    span: float
    tau: float
    stiffness: float | None
    subcycle: int


def every_span(table: dict, hv: SceneHyperviscosity, grid: SceneGrid, radius: float, stepper: str, controlled: bool):
    """The ``Span`` of ``every = "auto"`` on ``grid`` and a planet of ``radius`` (m): the longest
    span kΔt, ``EVERY_SPAN`` of τ, the e-folding time (``efold_nu``'s rule solved for τ) of the
    grid's Nyquist degree under the largest of ν, ν_div, ν_s; None where k is 1 whatever Δt (an
    integer ``every``, a controlled Δt, a three-level scheme, no ∇⁴, a τ of 0 s or past a
    float's range)."""
    nu = max(hv.nu, hv.nu_div, hv.nu_s)
    if table.get("every", 1) != "auto" or controlled or STEPPERS[stepper].dense_hyperviscosity or nu == 0:
        return None
    tau = efold_nu(1.0, grid.record.mean_ne, grid.np, radius) / nu * 3600.0
    if not 0 < tau < math.inf:  # no span a float holds (a planet of 1e308 m): k 1
        return None
    known = grid.mesh is None and hv.scaling is None and grid.np in CUBE_STIFFNESS
    return Span(EVERY_SPAN * tau, tau, CUBE_STIFFNESS[grid.np] / tau if known else None, hv.subcycle)


def auto_every(span: float, dt: float, steps: tuple) -> int:
    """The k of ``every = "auto"`` at ``dt`` (s): the largest k whose kΔt is at most ``span``
    (s) and that is at most the run's steps, preferring the largest k ≥ half that which divides
    one of ``steps`` (the steps of an output interval and of the whole run, the run's last: the
    ∇⁴ then done at those times). A run of fewer steps than ``span`` holds takes its ∇⁴ once, at
    its end, over the whole run."""
    run = steps[-1]
    # no k past the run: one took no ∇⁴ at all (TC5 ne4 at dt 100 s: k 18, a 5-step run undamped)
    ratio = span / dt * (1 + 1e-9)
    most = max(1, math.floor(ratio)) if ratio < run else run
    # the largest that divides either: the output interval's alone took k = 3 where 6 of the
    # run's fit (galewsky ne16 np6, 333 steps a day), the ∇⁴ twice as often for nothing
    found = [_largest_divisor(n, (most + 1) // 2, most) for n in steps]
    return max((k for k in found if k is not None), default=most)


def _largest_divisor(n: int, low: int, high: int) -> int | None:
    """The largest divisor of ``n`` in ``low``..``high`` (None: none, or none found within
    ``DIVISOR_SEARCH`` candidates): the candidates down from ``high``, or the cofactors up from
    n / ``high``, whichever are fewer."""
    if n == 0:  # every k divides it
        return high
    if n < low:
        return None
    if n <= high:
        return n
    first, last = -(-n // high), n // low  # the cofactors n / k of k in low..high
    if min(high - low, last - first) > DIVISOR_SEARCH:
        return None
    if high - low <= last - first:
        return next((k for k in range(high, low - 1, -1) if n % k == 0), None)
    return next((n // q for q in range(first, last + 1) if n % q == 0), None)


def resolve_every(
    table: dict, span: Span | None, dt: float, steps: tuple, stepper: str, controlled: bool
) -> tuple[int, tuple]:
    """(k, notes): the steps between ∇⁴ applications of [hyperviscosity] ``every`` on the run's
    grid and Δt (s). An integer is k as given; "auto" ``auto_every``'s k within ``every_span``'s
    ``span`` (``steps``: an output interval's and the whole run's), and 1 where k > 1 does not
    fit (``span`` None: a controlled Δt, a three-level scheme, no ∇⁴); a note names k > 1 (and
    says where it is the run's steps: the ∇⁴ once, at its end). Raises ``SceneError`` naming the
    key: an integer k > 1 under a controlled Δt or with a stepper whose ∇⁴ runs after every
    step, with its reason (``Stepper.dense_hyperviscosity``)."""
    every = table.get("every", 1)
    if every == "auto":
        k = 1 if span is None else auto_every(span.span, dt, steps)
        if k == 1:
            return 1, ()
        once = ": once, at the run's end" if k == steps[-1] else ""
        return k, (
            f"hyperviscosity every {k} steps{once} ({k * dt / 60:.3g} min; the grid scale's e-folding "
            f"{span.tau / 3600:.3g} h)",
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
