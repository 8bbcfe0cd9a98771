"""What a stepper, a solver or the adjoint may ask of a model: ``SteppingModel``, the 26 members
of ``ShallowWater`` that ``steppers/``, ``solvers/`` and ``adjoint/`` use (``tests/test_layers.py``
holds them to this list, as the privacy rule holds modules to public names).

A new stepper's author reads this first. The verbs, as Dinosaur's ``explicit_terms`` /
``implicit_terms`` / ``implicit_inverse`` and ClimaCore's ``rhs!``:

- **the tendency**: ``rhs`` (F(x), or the part of F named by ``terms``), ``rhs_update`` (F(x)
  written straight into linear combinations as its DSS makes it: a stage's updates without a
  pass of their own), ``rhs_part`` (over an ``ElementPart``: local time stepping's levels),
  ``set_time`` (the model time a time-dependent forcing reads);
- **the ∇⁴**: ``hyperviscosity`` (its step over Δt, split from the dynamics) and, for the adjoint
  and the step plans, ``hv`` (the ``Hyperviscosity``: its plan, coefficients and operator; None
  without the term);
- **states**: ``new_state``, ``lincomb`` (out = Σ c·x, recorded), ``pointwise`` (a pointwise
  kernel, recorded), ``bad_nodes`` (the check of a state for non-finite or dry nodes), and the
  state a step's stages carry: ``state_dtype`` (float64, or float32 under "float32_state"),
  ``to_step_state`` and ``from_step_state`` (the float64 state to it at a step's start and back
  at its end, or nothing where the run keeps it: ``held``), ``restore_mass`` (the mass to keep
  put back after the end's ∇⁴: the float32 state's mass fixer);
- **the implicit split**: ``implicit_terms`` (L, the linear gravity-wave terms about a mean depth,
  a ``GravityWaveOperator``) and ``implicit_inverse`` ((I − aL)⁻¹, a ``HelmholtzSolver`` about it),
  which the steppers that treat L apart ask for and do not build;
- **the operators beside the tendency**: ``operators`` (``ElementOperators``: the DSS'd G and D
  of the gravity-wave operator and the Helmholtz solves, scatter and assembly, the geometry
  arrays the element kernels read);
- **where and what**: ``topology`` (device, N, grid, the DSS, reductions), ``launches`` (the
  ``LaunchRecorder`` every launch goes through, its threads and graph guard), ``terms`` (the
  scene's terms: what F holds), ``rows`` (a state's: 3 and a tracer mass each), ``limiter`` (the
  tracers' shape-preserving limiter, or None), ``g`` (m s⁻²);
- **the recorder**: ``recorder``, None, or the tape a gradient injects (``adjoint.tape.TapedModel``)
  on which the operators built on the model (the gravity-wave operator, the Helmholtz solver)
  write their launches, so that they ask the model and not the adjoint.
"""

from __future__ import annotations

from typing import Protocol

import warp as wp


class SteppingModel(Protocol):
    """The members of a model (``ShallowWater``) that steppers, solvers and the adjoint use
    (shapes: states (rows, N) float64 device arrays, N the element-local nodes)."""

    topology: object  # ``grid.topology.Topology``
    launches: object  # ``model.launches.LaunchRecorder``
    operators: object  # ``model.element_operators.ElementOperators``
    hv: object  # ``model.hyperviscosity.Hyperviscosity`` or None
    filter: object  # ``model.filter.ElementFilter`` or None
    bad_nodes: object  # ``model.bad_nodes.BadNodes``
    terms: tuple
    rows: int  # a state's rows: u, v, h and a tracer mass hq each (3 + the model's tracers)
    limiter: object  # ``model.limiter.TracerLimiter`` of the tracers, or None
    g: float
    state_dtype: object  # the Warp float type a step's stages hold (``precision.state_dtype``)
    held: object  # ``model.held.HeldState``: the state a run holds between steps (its ``dtype``)
    recorder: object  # None, or a gradient's tape (``adjoint.tape.Tape``) the operators built on it write on

    def rhs(self, x: wp.array2d, out: wp.array2d, terms: tuple | None = None) -> None: ...
    def rhs_update(self, x: wp.array2d, updates, terms: tuple | None = None) -> None: ...
    def rhs_part(self, x: wp.array2d, out: wp.array2d, part, terms: tuple | None = None) -> None: ...
    def set_time(self, t: float) -> None: ...
    def hyperviscosity(self, x: wp.array2d, dt: float) -> None: ...
    def implicit_terms(self, mean_depth: float = 0.0): ...
    def implicit_inverse(self, options, linear=None, warm: bool = False): ...
    def new_state(self, u=None, v=None, h=None) -> wp.array2d: ...
    def lincomb(self, out, terms): ...
    def pointwise(self, kernel, *inputs, unique: bool = False) -> None: ...
    def to_step_state(self, x: wp.array2d, y: wp.array2d) -> None: ...
    def from_step_state(self, y: wp.array2d, x: wp.array2d) -> None: ...
    def restore_mass(self, x: wp.array2d) -> None: ...


def members() -> set[str]:
    """The protocol's member names."""
    return set(SteppingModel.__annotations__) | {
        name for name in vars(SteppingModel) if not name.startswith("_") and callable(vars(SteppingModel)[name])
    }
