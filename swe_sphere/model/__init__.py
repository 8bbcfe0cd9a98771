"""The model layer: the shallow-water right-hand side and what acts on a state of it.

``shallow_water.ShallowWater`` (the RHS by labelled terms), ``hyperviscosity.Hyperviscosity``
(HOMME's ``biharmonic_wk`` ∇⁴, its substeps), ``bad_nodes.BadNodes`` (the non-finite or dry-node
check), ``diagnostics`` (invariants, Courant numbers, signal rates).

May import: ``core``, ``grid``, ``kernels``.
"""

__all__ = ["bad_nodes", "diagnostics", "hyperviscosity", "shallow_water"]
