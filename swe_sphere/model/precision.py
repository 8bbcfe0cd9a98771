"""The model's precision: the float type its tendency and its ∇⁴ are computed in.

``precision = "float32"`` computes the shallow-water tendency (``kernels.tendencies``) in
float32 from the float64 state, and its DSS sums the float32 element tendencies in float64
into the float64 stage and step updates (``kernels.dss``); the ∇⁴ hyperviscosity
(``model.hyperviscosity``, ``kernels.hyperviscosity``) the same way: its weak Laplacians and
work arrays float32, the state read and rounded, its DSSs summed in float64 and its last one
adding coef·Y₂ to the float64 state in float64. What stays float64, as the ports that work
keep it (IFS, FESOM2, Klöwer et al. 2022, J. Adv. Model. Earth Syst. 14, e2021MS002684): the
grid's geometry, computed in float64 and rounded once to float32 for the tendency and the ∇⁴;
the state and the accumulation of every increment, small against it (a step changes h of
10 km by centimetres: float32's 6e-8 relative spacing would swallow them); the clock; the
solvers; global sums, invariants and error norms. A float32 tendency reads half the
geometry's and the tendency's bytes, and on a GPU without fast float64 runs at float32's rate.

``precision = "float32_state"`` holds a step's state and stages in float32 as well: u, v and the
depth's departure h − H₀ (``kernels.departure``), which the tendency reads as it is stored and
the DSS's combinations write (each summed in float32: ``kernels.dss.combination``). By default
the run keeps that float32 state from step to step (``model.held``: the diagnostics and the files
read it converted, the ∇⁴ acts on it in place); with ``ShallowWater``'s ``compensated`` an
explicit Runge–Kutta step takes it from a float64 state at its start and adds its increment back
in float64 at its end (Klöwer et al. 2022's compensated time integration), the float64 state
then being what the clock's loop, the ∇⁴ (as under "float32"), the diagnostics and the files read.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import warp as wp

from ..core.arguments import got
from ..core.errors import ArgumentError
from ..kernels import operators

# the tendency's float type of each precision; "float32_state" holds the state too in float32
PRECISIONS = {"float64": wp.float64, "float32": wp.float32, "float32_state": wp.float32}


def precision_dtype(precision: str):
    """The Warp float type of ``precision``'s tendency ("float64", or "float32" for "float32" and
    "float32_state"); ``ArgumentError`` naming ``precision`` otherwise."""
    if not isinstance(precision, str) or precision not in PRECISIONS:
        raise ArgumentError(f"precision must be one of {', '.join(PRECISIONS)} (got {got(precision)})")
    return PRECISIONS[precision]


def tracers_refusal(precision: str) -> str | None:
    """Why ``precision`` cannot carry tracers, in one line (None: it can, "float64"): the
    tracers' tendency rows, their ∇⁴ and their limiter are written in float64 alone. Both the
    model (``ShallowWater``'s ``tracers``) and a scene's [tracers] (``config.tracers``) refuse
    with it."""
    if precision == "float64":
        return None
    return f'precision "{precision}" does not carry tracers (their tendency and ∇⁴ are float64 alone): use "float64"'


def state_dtype(precision: str):
    """The Warp float type a step's state and stages are held in: float32 under
    "float32_state" (u, v and h − H₀: ``kernels.departure``), else float64."""
    return wp.float32 if precision == "float32_state" else wp.float64


def rounded(a: wp.array | None, dtype) -> wp.array | None:
    """The float64 array ``a`` in ``dtype``: ``a`` itself under float64, else a copy rounded once
    (on a's device); None for None."""
    if a is None or dtype is wp.float64:
        return a
    return wp.array(a.numpy(), dtype=dtype, device=a.device)


class TendencyArrays(NamedTuple):
    """What the tendency kernels read and write besides the state, in the model's float type
    ``dtype``: the metric terms ``Dinv`` (4, N; D is not read: ``operators.covariant_inverse``),
    ``metdet``, ``fcor``, the element mass
    ``mass`` (spheremp, N) and the topographic forcing −g∇hs ``forcing`` (2, N; None without
    topography), the derivative matrix ``dvv`` (np, np) and ``dvv_rows`` (the per-element
    kernels'), the element-local tendency ``tend`` (rows, N: 3 and the tracers') they write, and ``depth`` H₀ (m) the
    reference depth the pressure gradient's g h is taken from (``kernels.tendencies.tendency``:
    ∇(g(h − H₀)) with h − H₀ formed in float64, so that float32 carries h's variation, not its
    mean: SpeedyWeather's scaling of its variables). Under float64 these are the model's own
    arrays (nothing is copied) and H₀ is unread; under float32 copies rounded once from the
    float64 arrays (metdet, fcor and forcing None where the tendency's lanes hold their own:
    ``model.lanes``)."""

    dtype: object
    Dinv: wp.array2d
    metdet: wp.array
    fcor: wp.array
    mass: wp.array
    forcing: wp.array2d | None
    dvv: wp.array2d
    dvv_rows: object
    tend: wp.array2d
    depth: float

    @classmethod
    def of(
        cls,
        dtype,
        ops,
        mass: wp.array,
        topography: bool,
        depth: float,
        rows: int = 3,
        rows_geometry: bool = True,
    ) -> TendencyArrays:
        """The arrays of ``ops`` (the model's ``ElementOperators``: its ``forcing`` with
        ``topography``) and ``mass`` (float64) as the tendency reads them in ``dtype``, a new
        ``tend`` of the state's ``rows`` (3 and a row for each tracer), and the reference ``depth``
        (m). ``rows_geometry`` False (the tendency's lanes hold their own geometry:
        ``model.lanes``): under float32 no copies of metdet, fcor and forcing (None), which only
        the tendency's rows read."""
        tend = wp.zeros((rows, ops.N), dtype=dtype, device=ops.device)
        if dtype is wp.float64:
            forcing = ops.forcing if topography else None
            return cls(dtype, ops.Dinv, ops.metdet, ops.fcor, mass, forcing, ops.dvv, ops.dvv_rows, tend, 0.0)
        dvv = np.asarray(ops.grid.rule.dvv)
        kept = (lambda name: ops.rounded(name, dtype)) if rows_geometry else (lambda name: None)
        return cls(
            dtype,
            ops.rounded("Dinv", dtype),
            kept("metdet"),
            kept("fcor"),
            rounded(mass, dtype),
            kept("forcing") if topography else None,
            rounded(ops.dvv, dtype),
            operators.dvv_matrix(dvv, dtype),
            tend,
            float(depth),
        )


def reference_depth(h: np.ndarray, topology=None) -> float:
    """H₀ (m) for a float32 tendency: the midpoint of the global extremes of ``h`` (this rank's
    element-local depths; ``topology`` reduces over the ranks, None: ``h`` is the whole grid's).
    Max and min are exact in any order, so every rank count gets the same H₀, and the same bits."""
    h = np.asarray(h, dtype=float)
    if topology is None:
        return 0.5 * (float(h.max()) + float(h.min()))
    return 0.5 * (topology.max(float(h.max())) - topology.max(float(-h.min())))
