"""The solvers layer: linear and exponential solvers that know an operator, not a stepper.

``helmholtz_matrix`` (the Helmholtz matrix, for the tests; the solve itself is the model's inverse,
``model.helmholtz``, ``model.helmholtz_cg`` and ``model.guess_history``), ``krylov`` (the Krylov basis
and FGMRES), ``jacobian`` (finite-difference Jacobian-vector products), ``kiops`` (φ-functions
by KIOPS, Gaudreault, Rainwater & Tokman 2018).

May import: ``core``, ``grid``, ``model``, ``kernels``; never ``steppers``.
"""

__all__ = ["helmholtz_matrix", "jacobian", "kiops", "krylov"]
