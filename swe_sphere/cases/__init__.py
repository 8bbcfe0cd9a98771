"""The cases layer: the test cases and what a run is scored against.

``library`` (Williamson et al. 1992 cases 1–6, Läuter et al. 2005, Galewsky et al. 2004:
initial states, ``fcor``, ``hs``, exact solutions; ``make_case``), ``reference`` (the spectral
T213/T341 references and their floors), ``scoring`` (Williamson 1992 normalized l1/l2/l∞, eqs. 82–84).

May import: ``core``, ``grid``, ``model``, ``kernels``.
"""

__all__ = ["library", "reference", "scoring"]
