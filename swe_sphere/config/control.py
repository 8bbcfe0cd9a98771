"""[time]'s step control (``control = "fixed" | "cfl" | "error" | "balanced"`` and its keys):
``resolve_control`` checks them into a ``SceneControl`` for ``load_scene``, with the defaults
every mode's consumer shares (the Courant cap's fraction, the balanced mode's fraction).

Every problem raises ``SceneError`` (a ValueError) with a one-line message naming the key.
"""

from __future__ import annotations

from ..core.arguments import got
from ..core.errors import SceneError
from ..steppers import STEPPERS
from ..steppers.control import CONTROLLERS
from .schema import SceneControl, is_number

# [time] control's modes and the keys each reads
CONTROL_KEYS = {
    "fixed": (),
    "cfl": ("cfl", "dt_min", "dt_max"),
    "error": ("rtol", "atol", "per_unit_step", "controller", "cfl", "dt_min", "dt_max"),
    "balanced": ("balance", "controller", "cfl", "dt_min", "dt_max"),
}
ESTIMATED = ("error", "balanced")
# a sweep's controlled run, "STEPPER@KEY=VALUE" (``studies.sweep.plan``): the [time] key the value
# sets and the others the run takes (``tolerance_table``); rtol_per_day: rtol per unit step
TOLERANCES = {
    "rtol": ("rtol", {"control": "error"}),
    "rtol_per_day": ("rtol", {"control": "error", "per_unit_step": True}),
    "balance": ("balance", {"control": "balanced"}),
    "cfl": ("cfl", {"control": "cfl"}),
}
BALANCE = 0.1  # time.balance's default: the sweep's criterion, temporal error ≤ 10 % of the spatial (docs/explanation/methods.md)
DT_MIN_FRACTION = 1e-3  # dt_min's default: this fraction of the first step
# time.cfl's default: this fraction of the stepper's measured Courant limit (``Stepper.courant_limit``,
# a bisection on TC2 at t = 0): the target under "cfl", the cap under "error" (at ne8 the pairs' limits
# on TC5, TC6 and Galewsky are 0.99-1.42 x TC2's in the same Courant number: docs/explanation/efficiency/error_control.md)
CFL_FRACTION = 0.9
# time.cfl past this multiple of the stepper's measured limit is refused (no measured case reached
# 1.42 x TC2's limit), past the limit itself warned (``cfl_notes``)
CFL_REFUSED = 2.0


def is_controlled(table: dict) -> bool:
    """Whether [time] ``table`` asks for steps chosen step to step (a ``control`` other than
    "fixed"; the mode itself checked by ``resolve_control``)."""
    return table.get("control", "fixed") != "fixed"


def resolve_control(table: dict, stepper: str, options: dict, dt: float) -> SceneControl | None:
    """[time]'s step control for ``stepper`` with ``options`` and the first step ``dt`` (s):
    None for ``control = "fixed"`` (the default). Defaults: rtol 1e-4; atol rtol in each
    field's units (m s⁻¹, m); per_unit_step false; balance ``BALANCE``; the controller Ranocha et al.'s PID for the
    pair where tuned (``pid_bs32``...), else ARKODE's PI; cfl ``CFL_FRACTION`` × the
    stepper's measured Courant limit, under "cfl" the target, under "error" and "balanced" a
    cap (``false``: none; none for a stepper without a measured limit); dt_min
    ``DT_MIN_FRACTION`` × dt. Raises ``SceneError``, one line naming the key: an unknown mode,
    a key the mode does not read, a stepper that cannot change its dt, a pair-less stepper
    under "error" or "balanced", rtol ≤ 0, a bad atol, balance ≤ 0, an unknown controller,
    cfl ≤ 0, dt_min ≤ 0 or above dt_max or above dt (the first step)."""
    mode = table.get("control", "fixed")
    if mode not in CONTROL_KEYS:
        raise SceneError(f"time.control must be one of {', '.join(CONTROL_KEYS)} (got {mode!r})")
    for key in dict.fromkeys(k for keys in CONTROL_KEYS.values() for k in keys):
        if key in table and key not in CONTROL_KEYS[mode]:
            raise SceneError(f"time.{key} is not read under control = {mode!r} (set time.control)")
    if mode == "fixed":
        return None
    cls = STEPPERS[stepper]
    if not cls.changes_dt(options):
        raise SceneError(
            f"time.control = {mode!r} needs a stepper that can change its dt between steps; {stepper} cannot "
            "(its history is its dt's)"
        )
    rtol, atol, controller, balance, per_unit_step = None, (None, None), None, None, False
    if mode in ESTIMATED:
        if not cls.has_estimate(options):
            pairs = ", ".join(k for k, c in STEPPERS.items() if isinstance(c.embedded_order, int) and c.embedded_order)
            raise SceneError(
                f"time.control = {mode!r} needs an embedded pair; {stepper} has no error estimate "
                f"(pairs: {pairs}, a tableau with b_hat; or control = 'cfl')"
            )
    if mode == "error":
        rtol = table.get("rtol", 1e-4)
        if not rtol > 0:
            raise SceneError(f"time.rtol must be > 0 (got {rtol!r})")
        atol = _atol(table.get("atol", rtol))
        per_unit_step = table.get("per_unit_step", False)  # a boolean: the schema's types
    if mode == "balanced":
        balance = table.get("balance", BALANCE)
        if isinstance(balance, bool) or not is_number(balance) or not balance > 0:
            raise SceneError(f"time.balance must be a number > 0 (got {got(balance)})")
        balance = float(balance)
    if mode in ESTIMATED:
        controller = table.get("controller", f"pid_{stepper}" if f"pid_{stepper}" in CONTROLLERS else "pi")
        if controller not in CONTROLLERS:
            raise SceneError(f"time.controller must be one of {', '.join(CONTROLLERS)} (got {controller!r})")
    cfl, cfl_default = _cfl(table, mode, cls, stepper)
    dt_min, dt_max = table.get("dt_min", DT_MIN_FRACTION * dt), table.get("dt_max")
    if not dt_min > 0 or (dt_max is not None and not dt_max > 0):
        raise SceneError(f"time.dt_min and time.dt_max must be > 0 (got {dt_min!r}, {dt_max!r})")
    if dt_max is not None and dt_min > dt_max:
        raise SceneError(f"time.dt_min = {dt_min:g} s is above time.dt_max = {dt_max:g} s")
    if dt_min > dt:  # the first step, at dt (or dt_max below it), would stop the run at once
        raise SceneError(f"time.dt_min = {dt_min:g} s is above the first step's dt = {dt:g} s (time.dt)")
    dt_max = None if dt_max is None else float(dt_max)
    return SceneControl(mode, rtol, *atol, controller, cfl, float(dt_min), dt_max, cfl_default, balance, per_unit_step)


def _atol(value) -> tuple[float, float]:
    """(wind (m s⁻¹), h (m)) of time.atol: a number ≥ 0 for both, or an array of two."""
    pair = list(value) if isinstance(value, list) else [value, value]
    if len(pair) != 2 or not all(is_number(a) and a >= 0 for a in pair):
        raise SceneError(f"time.atol must be a number >= 0 or [wind (m/s), h (m)] of them (got {got(value)})")
    return float(pair[0]), float(pair[1])


def _cfl(table: dict, mode: str, cls, stepper: str) -> tuple[float | None, bool]:
    """(time.cfl, whether it is error control's default cap): the value given (> 0; under
    "error" and "balanced" ``false``: no cap), else ``CFL_FRACTION`` × the stepper's measured
    Courant limit (under "cfl" the target, refused for a stepper without one; under "error"
    and "balanced" the cap, none for a stepper without one: the IMEX pairs)."""
    limit, cfl = measured_courant_limit(cls), table.get("cfl")
    if "cfl" not in table and limit is None and mode == "cfl":
        raise SceneError(f"time.cfl is missing: {stepper} has no measured Courant limit to aim below")
    if "cfl" not in table or (cfl is False and mode in ESTIMATED):
        return (None, False) if limit is None or cfl is False else (CFL_FRACTION * limit, mode in ESTIMATED)
    off = " or false (no cap)" if mode in ESTIMATED else ""
    if isinstance(cfl, bool) or not is_number(cfl) or not cfl > 0:
        raise SceneError(f"time.cfl must be > 0{off} (got {got(cfl)})")
    if limit is not None and cfl > CFL_REFUSED * limit:
        raise SceneError(
            f"time.cfl = {cfl:g} is past {CFL_REFUSED:g} x {stepper}'s measured Courant limit {limit:g} (TC2 at "
            f"t = 0; no measured case reached 1.42 x it): give at most {CFL_REFUSED * limit:.3g}{off}"
        )
    return float(cfl), False


def cfl_notes(control: SceneControl | None, stepper: str) -> tuple[str, ...]:
    """A warning for a time.cfl given above ``stepper``'s measured Courant limit (and within
    ``CFL_REFUSED`` x it, ``_cfl``): the steps it asks for may blow up. () otherwise."""
    limit = measured_courant_limit(STEPPERS[stepper])
    if control is None or control.cfl is None or limit is None or control.cfl <= limit:
        return ()
    what = "target" if control.mode == "cfl" else "cap"
    return (
        f"warning: time.cfl = {control.cfl:g} (the Courant {what}) is above {stepper}'s measured Courant limit "
        f"{limit:g} (TC2 at t = 0): its steps may blow up",
    )


def tolerance_table(key: str, value: float) -> dict:
    """The [time] keys of a sweep's run "STEPPER@KEY=VALUE" (``key`` one of ``TOLERANCES``)."""
    name, table = TOLERANCES[key]
    return {**table, name: value}


def tolerance(control: SceneControl) -> tuple[str, float]:
    """The key of ``TOLERANCES`` that ``control`` is asked by and its value (rtol under
    "error", per unit step rtol_per_day, balance under "balanced", cfl under "cfl"): what
    names a sweep's controlled run."""
    for key, (name, table) in TOLERANCES.items():
        if control.mode == table["control"] and control.per_unit_step == table.get("per_unit_step", False):
            return key, getattr(control, name)
    raise ValueError(f"no sweep run is named by control {control.mode!r}")


def measured_courant_limit(cls) -> float | None:
    """A stepper class's measured Courant limit: the signal's (``Stepper.courant_limit``), else
    the advective one's (``advective_courant_limit``); None for one without (a user's table:
    its limit is its instance's)."""
    limit = cls.courant_limit if isinstance(cls.courant_limit, float) else cls.advective_courant_limit
    return limit if isinstance(limit, float) else None
