"""The Helmholtz solve, now the model's implicit inverse: ``model.helmholtz`` (issue 100; these
names kept here)."""

from ..model.helmholtz import (
    KEPT_COEFFICIENTS,
    MAX_GUESS_HISTORY,
    PRECISIONS,
    TIGHTEST,
    HelmholtzCG,
    HelmholtzOptions,
    HelmholtzSolver,
    check_precision,
)

__all__ = [
    "KEPT_COEFFICIENTS",
    "MAX_GUESS_HISTORY",
    "PRECISIONS",
    "TIGHTEST",
    "HelmholtzCG",
    "HelmholtzOptions",
    "HelmholtzSolver",
    "check_precision",
]
