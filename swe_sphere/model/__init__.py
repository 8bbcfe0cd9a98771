"""The model layer: the shallow-water right-hand side and what acts on a state of it.

``shallow_water.ShallowWater`` (the RHS by labelled terms), its implicit split: ``gravity_wave.
GravityWaveOperator`` (the linear gravity-wave operator L and its mean-depth rule) and its inverse
``helmholtz.HelmholtzSolver`` (the Helmholtz solve; its CG in ``helmholtz_cg``, its start in
``guess_history``), the model's ``implicit_terms`` and ``implicit_inverse``; ``hyperviscosity.Hyperviscosity``
(HOMME's ``biharmonic_wk`` ∇⁴, its substeps), ``lanes.TendencyLanes`` (the tendency's vector
lanes on the CPU at np 4), ``bad_nodes.BadNodes`` (the non-finite or dry-node
check), ``launches`` (the launch recorder they all launch through, and ``Update``, a linear
combination written by an operator's DSS), ``transposes`` (the operators' transposes the
gradients of a run reverse steps with), ``diagnostics`` (invariants, Courant numbers,
signal rates).

May import: ``core``, ``grid``, ``kernels``.
"""

__all__ = [
    "bad_nodes",
    "diagnostics",
    "gravity_wave",
    "guess_history",
    "helmholtz",
    "helmholtz_cg",
    "hyperviscosity",
    "lanes",
    "launches",
    "shallow_water",
    "transposes",
]
