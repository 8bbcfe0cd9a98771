"""The stepper interface.

A stepper is built with the model, the step ``dt`` (s) and its options; it
allocates its buffers and records its launches once, then ``step(x)``
advances the state ``x`` (3, N) in place by dt and returns a ``StepStats``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import warp as wp

from ..kernels import blas
from ..model import ShallowWater

f64 = wp.float64


@dataclass
class StepStats:
    """What one step cost: RHS evaluations and solver iterations (by solver name)."""

    rhs_evals: int
    iterations: dict = field(default_factory=dict)


class StepFailure(RuntimeError):
    """A step could not be completed (a solver did not converge); the message says why."""


class Stepper:
    """Base class. Subclasses set ``name`` and implement ``step``."""

    name = ""
    options: dict[str, type] = {}  # scene table [<name>]: option → type
    solvers: tuple[str, ...] = ()  # names of the iteration counts in StepStats

    @classmethod
    def check_options(cls, **options) -> None:
        """Raise ValueError '<option> must ...' for an invalid option value."""

    def __init__(self, model: ShallowWater, dt: float):
        if not dt > 0:
            raise ValueError(f"dt must be > 0 (got {dt})")
        self.model, self.dt = model, float(dt)
        self.N = model.N
        self._pointwise_launches: dict[tuple, object] = {}

    def _buffer(self):
        return wp.zeros((3, self.N), dtype=f64, device=self.model.device)

    def _lincomb(self, out, *terms):
        """Record out = Σ c·x for two or three (c, x) pairs; returns the launch
        (split over the model's CPU threads like the model's own launches)."""
        args = [a for c, x in terms for a in (f64(c), x)]
        kernel = blas.axpby if len(terms) == 2 else blas.axpbypcz
        return self.model._launch_pointwise(kernel, 3, [*args, out])

    def _pointwise(self, kernel, *inputs, unique=False) -> None:
        """Run a pointwise kernel on ``inputs``, over (3, N) with ``block`` (or over
        (3, nunique) if ``unique``): recorded on the first call with these arrays,
        later calls only set its scalar arguments."""
        key = (kernel.key, *(a.ptr if isinstance(a, wp.array) else None for a in inputs))
        launch = self._pointwise_launches.get(key)
        if launch is None:
            m = self.model
            build = m._launch(kernel, (3, m.grid.nunique), list(inputs)) if unique else m._launch_pointwise(kernel, 3, list(inputs))
            launch = self._pointwise_launches[key] = build
        else:
            for arg, value in zip(kernel.adj.args, inputs):
                if not isinstance(value, wp.array):
                    launch.set_param_by_name(arg.label, value)
        launch.launch()

    def step(self, x: wp.array2d) -> StepStats:
        raise NotImplementedError
