"""The solvers layer: linear and exponential solvers that know an operator, not a stepper.

``helmholtz`` (the gravity-wave Helmholtz solve; its CG in ``helmholtz_cg``, its start in
``guess_history``, its matrix for the tests in ``helmholtz_matrix``), ``krylov`` (the Krylov basis
and FGMRES), ``jacobian`` (finite-difference Jacobian-vector products), ``kiops`` (φ-functions
by KIOPS, Gaudreault, Rainwater & Tokman 2018).

May import: ``core``, ``grid``, ``model``, ``kernels``; never ``steppers``.
"""

__all__ = ["guess_history", "helmholtz", "helmholtz_cg", "helmholtz_matrix", "jacobian", "kiops", "krylov"]
