"""The arguments of a ``ShallowWater`` model checked before anything is built: its terms and
its tracers' options (each refusal one line naming the argument)."""

from ..core.arguments import got, integer_argument
from ..core.errors import ArgumentError
from ..kernels import tendencies
from .limiter import LIMITERS
from .precision import tracers_refusal

TERMS = (
    "continuity",
    "momentum_advection",
    "coriolis",
    "pressure_gradient",
    "topography",
    "hyperviscosity",
    "forcing",
)


def checked_terms(terms, forcing) -> tuple:
    """``terms`` as a tuple; ValueError for an unknown term, or a forcing term without its
    forcing or without a tendency term to add to."""
    terms = tuple(terms)
    for t in terms:
        if t not in TERMS:
            raise ValueError(f"unknown term {t!r} (known: {', '.join(TERMS)})")
    if "forcing" in terms and forcing is None:
        raise ValueError("the forcing term needs a forcing (kernel, params); the case supplies it")
    if "forcing" in terms and not set(terms) & set(tendencies.TENDENCY_TERMS):
        raise ValueError("the forcing term adds to the tendency: name at least one tendency term")
    return terms


def checked_tracers(tracers, terms: tuple, limiter, precision, tracer_hyperviscosity, stage_hyperviscosity) -> None:
    """``ShallowWater``'s tracer arguments checked. Raises ``ArgumentError`` for ``tracers`` not
    an integer ≥ 0, tracers without the continuity term (they ride it) or under a precision that
    does not carry them (``precision.tracers_refusal``), ``stage_hyperviscosity`` without tracers,
    the "hyperviscosity" term or ``tracer_hyperviscosity``, and a ``limiter`` not in ``LIMITERS``."""
    integer_argument("tracers", tracers, low=0)
    if tracers and "continuity" not in terms:
        raise ArgumentError("tracers ride the continuity: a model with tracers needs the continuity term")
    if stage_hyperviscosity and not (tracers and "hyperviscosity" in terms and tracer_hyperviscosity):
        raise ArgumentError("stage_hyperviscosity needs tracers, the hyperviscosity term and tracer_hyperviscosity")
    if limiter not in LIMITERS:
        raise ArgumentError(f"limiter must be one of {', '.join(LIMITERS)} (got {got(limiter)})")
    if tracers and (why := tracers_refusal(precision)) is not None:
        raise ArgumentError(f"tracers={tracers} with {why}")
