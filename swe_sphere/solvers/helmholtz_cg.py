"""The Helmholtz solve's CG, now the model's: ``model.helmholtz_cg`` (issue 100; these names kept here)."""

from ..model.helmholtz_cg import SINGLE_FLOOR, SINGLE_TOL, HelmholtzCG

__all__ = ["SINGLE_FLOOR", "SINGLE_TOL", "HelmholtzCG"]
