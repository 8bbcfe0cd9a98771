"""The solvers layer: linear and exponential solvers that know an operator, not a stepper.

``helmholtz`` (the gravity-wave Helmholtz CG and its guess history), ``krylov`` (the Krylov basis
and FGMRES), ``jacobian`` (finite-difference Jacobian-vector products), ``kiops`` (φ-functions
by KIOPS, Gaudreault, Rainwater & Tokman 2018).

May import: ``core``, ``grid``, ``model``, ``kernels``; never ``steppers``.
"""

__all__ = ["helmholtz", "jacobian", "kiops", "krylov"]
