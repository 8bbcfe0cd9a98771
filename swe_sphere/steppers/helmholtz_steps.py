"""What the steppers that solve with the linear gravity-wave operator share: the operator,
its Helmholtz solver (the model's ``implicit_terms`` and ``implicit_inverse``), and the solver
options they no longer take."""

from __future__ import annotations

from functools import partial

from .base import entry

# the solver options the semi-implicit, IMEX and JFNK steppers no longer have, and why (``Stepper.removed_options``)
REMOVED_SOLVER_OPTIONS = {
    "helmholtz_solver": "the compiled CG is the only Helmholtz solver (the host solvers cg, amg, chebyshev, vcycle were slower at the default threads)",
}


class HelmholtzSteps:
    """What the semi-implicit and IMEX steppers share, put before their ``Stepper`` base:
    ``linear``, the model's ``GravityWaveOperator`` about their options' ``mean_depth``
    (``implicit_terms``), and ``helmholtz``, its ``HelmholtzSolver`` with their
    ``HelmholtzOptions`` (``warm``; the model's ``implicit_inverse``); the
    mean depth and the CG's warm guess in ``state``/``restore``; the CG's device counters as
    ``counts`` (read with the step when not ``deferred``, ``base.device_counts``); and a
    graph key once the step reads nothing: H fixed (the first step's host read,
    ``GravityWaveOperator.set_depth``), the counters ``deferred``, and the CG's loops able to
    be graph nodes (``HelmholtzSolver.graphable``: one rank; on CUDA conditional nodes).
    Raises ValueError for a model without the continuity and pressure-gradient terms."""

    capturable = differentiable = True
    solvers = ("helmholtz",)

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.linear = model.implicit_terms(self.options.mean_depth)
        self.helmholtz = model.implicit_inverse(self.options, self.linear, warm=True)

    def counts(self):
        return {"helmholtz": self.helmholtz.iterations()}

    def device_arrays(self):
        return [self.helmholtz.stats]

    def graph_key(self):
        solver = self.helmholtz
        # under a checkpoint (a controlled try) a solve copies a guess history on the host's decision
        ready = solver.H and solver.graphable and self.deferred and not solver.checkpointed
        return super().graph_key() if ready else None

    def state(self):
        return {**super().state(), **self.helmholtz.state()}

    def restore(self, state):
        super().restore(state)
        self.helmholtz.restore(state, partial(entry, self))

    def checkpoint(self):
        # the solver's guess histories as device copies (``HelmholtzSolver.checkpoint``), not
        # gathered to the host as ``state`` does (4.3 ms a step at ne16, 28 % of an ark324 step)
        return super().state(), self.helmholtz.checkpoint()

    def rollback(self, saved):
        base, solver = saved
        super().restore(base)
        self.helmholtz.rollback(solver)
