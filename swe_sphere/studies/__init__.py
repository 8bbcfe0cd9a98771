"""The studies layer: many runs, and what is read off run files.

``sweep`` (error × Δt × cost: which stepper reaches an accuracy cheapest; ``sweep.plan`` is
what `swe-sphere sweep` runs), ``stability`` (the largest stable Δt), ``analysis`` (spectra,
zonal means), ``plotting``.

May import: every layer below (``core`` to ``simulation``).
"""

__all__ = ["analysis", "plotting", "stability", "sweep"]
