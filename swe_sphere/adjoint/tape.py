"""A tape of one step of a stepper: what a gradient's reverse (``reverse.TapeAdjoint``) reads of a
step taken again from x(n) (issue 82's "step as a plan": the stepper's own code is the plan).

A twin of the stepper (its class, Δt and options) is built on a ``TapedModel``, which forwards
every verb to the model and, while the tape records, writes on it what it did:
- ``Evaluate``: F(x) (``rhs_update``, or ``rhs`` as one update of F alone; ``rhs_part`` over a
  part's elements) at x as it stood, then each update out[rows] = Σ a·src (src None: F), in order;
- ``Combine``: out = Σ c·x (a recorded combination's launch, ``lincomb``, or ``pointwise``'s
  ``blas.axpby`` and ``axpbypcz``), at listed nodes alone with ``nodes`` (``launches.lincomb_at``:
  MRAB3's sums);
- ``Smooth``: x ← H_dt(x) in place, the ∇⁴ (``hyperviscosity``);
- ``Gradient`` and ``Divergence``: the operators' G x[row] and D of x's wind written into updates
  (``ElementOperators.gradient_update``, ``divergence_update``: the split-explicit and multirate
  substeps');
- ``Linear``: the gravity-wave operator L written into updates as F is (``GravityWaveOperator.
  update``, ``apply``), and ``Solve``: z = (I − aL)⁻¹ (s·r), with ``implicit`` L z = (z − s·r)/a
  (``HelmholtzSolver.solve``): both write themselves on the tape of the model they were built on.
Another ``pointwise`` kernel has no transpose here: an ``ArgumentError`` names it. ``Tape.analyse``
tells a step taken again for its reverse which operations need run and which states need a copy.
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import NamedTuple

import warp as wp

from ..core.errors import ArgumentError
from ..kernels import blas
from ..model.launches import Update
from ..model.shallow_water import ShallowWater

f64 = wp.float64

MOMENTUM_ROWS = ("momentum_advection", "coriolis", "pressure_gradient", "topography", "forcing")


def written_rows(terms) -> slice | None:
    """The rows of F that the tendency of ``terms`` writes (None: all three): the depth row by
    continuity and a forcing, the wind rows by the momentum terms and a forcing."""
    depth = "continuity" in terms or "forcing" in terms
    wind = any(t in MOMENTUM_ROWS for t in terms)
    return None if depth and wind else slice(2, 3) if depth else slice(0, 2)


class Evaluate(NamedTuple):
    x: object
    state: object  # x as the reverse reads it: x itself, or a copy where the step overwrites x after
    updates: tuple
    terms: tuple
    part: object = None  # an ``ElementPart``: F over its elements alone (``rhs_part``)


class Combine(NamedTuple):
    out: object
    terms: tuple
    nodes: object = None  # the element-local nodes it writes alone (int32 device array), out's others kept


class Smooth(NamedTuple):
    x: object
    dt: float
    state: object  # with ``parameters``, x before the ∇⁴ as the reverse reads it; else None


class Linear(NamedTuple):
    x: object
    updates: tuple
    operator: object  # the ``GravityWaveOperator``
    state: object = None  # with ``parameters``, x as the reverse reads it (g's sum)


class Gradient(NamedTuple):
    x: object
    row: int
    updates: tuple  # of (2, N) row views: G x[row] written as L's updates are, its coefficients ∝ g
    state: object = None  # with ``parameters``, x as the reverse reads it (g's sum)


class Divergence(NamedTuple):
    x: object
    updates: tuple  # of (1, N) row views: D of x's wind rows written as L's updates are


class Solve(NamedTuple):
    r: object
    z: object
    implicit: object  # L z's array, or None
    a: float
    scale: float
    solver: object  # the ``HelmholtzSolver``


def array_key(a) -> tuple:
    """An array's (or view's) address, shape and strides."""
    return (a.ptr, a.shape, a.strides)


def op_key(op, coefficients: bool = True) -> tuple:
    """An operation's kind and the arrays, rows, terms and operators it names, with its
    coefficients (floats) and the states its reverse reads (``state``) where ``coefficients``:
    without them, what a step like it repeats (``Tape.structure``). Called twice a step reversed:
    the fields' kinds are unrolled, not walked."""

    def c(a):
        return a if coefficients else None

    def update(u):
        return (
            array_key(u.out),
            u.rows and (u.rows.start, u.rows.stop),
            *((c(a), s and array_key(s)) for a, s in u.terms),
        )

    key = [type(op).__name__]
    for f, v in zip(type(op).__annotations__, op):
        if f == "updates":
            key.append(tuple(map(update, v)))
        elif f == "terms":  # a combination's (c, x) pairs, or an F's term names
            key.append(tuple((c(t[0]), array_key(t[1])) if isinstance(t, tuple) else t for t in v))
        elif isinstance(v, wp.array):
            key.append(array_key(v) if coefficients or f != "state" else None)
        elif isinstance(v, float):
            key.append(c(v))
        else:  # a row, None, or an operator, solver or element part by identity
            key.append(v if v is None or isinstance(v, int) else id(v))
    return tuple(key)


def written_by(op) -> list:
    """The arrays (row views) an operation writes."""
    if isinstance(op, (Evaluate, Linear, Gradient, Divergence)):
        return [u.out if u.rows is None else u.out[u.rows] for u in op.updates]
    if isinstance(op, Solve):
        return [op.z, *([op.implicit] if op.implicit is not None else [])]
    return [op.out if isinstance(op, Combine) else op.x]


def arrays_of(op) -> list:
    """Every array an operation names."""
    if isinstance(op, (Evaluate, Linear, Gradient, Divergence)):
        return [op.x, *(a for u in op.updates for a in (u.out, *(s for _, s in u.terms if s is not None)))]
    if isinstance(op, Combine):
        return [op.out, *(a for _, a in op.terms)]
    if isinstance(op, Smooth):
        return [op.x]
    return [op.r, op.z, *([op.implicit] if op.implicit is not None else [])]


def combination(kernel, inputs) -> tuple:
    """(out, terms) of a pointwise ``blas.axpby`` or ``axpbypcz`` launch's inputs; ``ArgumentError``
    for another kernel (the tape has no transpose for it)."""
    if kernel is blas.axpby or kernel is blas.axpbypcz:
        *pairs, out = inputs
        return out, tuple((float(pairs[i]), pairs[i + 1]) for i in range(0, len(pairs), 2))
    raise ArgumentError(f"no gradient through the pointwise kernel {kernel.key!r} (the tape's verbs: adjoint/tape.py)")


class _TapedLaunch:
    """A recorded combination's launch (``ShallowWater.lincomb``, ``LaunchRecorder.lincomb_at``)
    that writes itself (``op``, a ``Combine``) on the tape."""

    def __init__(self, tape: Tape, launch, op):
        self.tape, self.real, self.op = tape, launch, op

    def launch(self) -> None:
        if self.tape.runs(lambda: self.op):
            self.real.launch()


class _TapedLaunches:
    """The model's ``LaunchRecorder`` whose combinations at listed nodes (``lincomb_at``: MRAB3's
    sums) write themselves on the tape; every other member its own."""

    def __init__(self, launches, tape: Tape):
        self._launches, self._tape = launches, tape

    def __getattr__(self, name):
        return getattr(self._launches, name)

    def lincomb_at(self, out, terms, nodes):
        terms = tuple(terms)
        return _TapedLaunch(self._tape, self._launches.lincomb_at(out, terms, nodes), Combine(out, terms, nodes))


class TapedModel:
    """A ``ShallowWater`` whose state-writing verbs are written on ``tape`` while it records
    (module doc); every other member is the model's. The gravity-wave operator and the Helmholtz
    solver built on it find ``tape`` as the model's ``recorder`` (``SteppingModel``) and write
    themselves there."""

    def __init__(self, model: ShallowWater, tape: Tape):
        if model.filter is not None:  # its transpose is not built: a gradient would miss it
            raise ArgumentError("a gradient of a run with an element filter ([filter]) is not built: drop the filter")
        if model.rows > 3:  # its tapes and costs are of u, v, h: the tracers' rows would go undifferentiated
            raise ArgumentError("a gradient of a run with tracers ([tracers]) is not built: drop the tracers")
        self._model, self.tape = model, tape
        self.recorder = tape  # the operators built on this model write on it
        self.operators = _TapedOperators(model.operators, tape)
        self.launches = _TapedLaunches(model.launches, tape)

    def __getattr__(self, name):
        return getattr(self._model, name)

    # the implicit split built on this model, not on the one it wraps: L and its solves find the tape
    implicit_terms = ShallowWater.implicit_terms
    implicit_inverse = ShallowWater.implicit_inverse

    def _evaluates(self, x, updates, terms, part=None) -> bool:
        terms = self._model.terms if terms is None else tuple(terms)
        return self.tape.runs(lambda: Evaluate(x, self.tape.state(x), tuple(updates), terms, part))

    def _whole(self, out, terms) -> tuple:  # F alone into out, on the rows its terms write
        return (Update(out, ((1.0, None),), written_rows(self._model.terms if terms is None else terms)),)

    def rhs(self, x, out, terms=None) -> None:
        if self._evaluates(x, self._whole(out, terms), terms):
            self._model.rhs(x, out, terms)

    def rhs_update(self, x, updates, terms=None) -> None:
        if self._evaluates(x, updates, terms):
            self._model.rhs_update(x, updates, terms)

    def rhs_part(self, x, out, part, terms=None) -> None:
        if self._evaluates(x, self._whole(out, terms), terms, part):
            self._model.rhs_part(x, out, part, terms)

    def lincomb(self, out, terms):
        terms = tuple(terms)
        return _TapedLaunch(self.tape, self._model.lincomb(out, terms), Combine(out, terms))

    def hyperviscosity(self, x, dt: float) -> None:
        hv = self._model.hv  # nothing to write without it
        if hv is None or hv.nu_max == 0 or self.tape.runs(lambda: Smooth(x, float(dt), self.tape.held(x))):
            self._model.hyperviscosity(x, dt)

    def pointwise(self, kernel, *inputs, unique=False) -> None:
        if self.tape.runs(lambda: Combine(*combination(kernel, inputs))):
            self._model.pointwise(kernel, *inputs, unique=unique)


class _TapedOperators:
    """The model's ``ElementOperators`` whose gradient and divergence updates (the split-explicit
    and multirate substeps') are written on the tape while it records; every other member theirs."""

    def __init__(self, operators, tape: Tape):
        self._operators, self._tape = operators, tape

    def __getattr__(self, name):
        return getattr(self._operators, name)

    def gradient_update(self, x, row: int, updates) -> None:
        if self._tape.runs(lambda: Gradient(x, int(row), tuple(updates), self._tape.held(x))):
            self._operators.gradient_update(x, row, updates)

    def divergence_update(self, x, updates) -> None:
        if self._tape.runs(lambda: Divergence(x, tuple(updates))):
            self._operators.divergence_update(x, updates)


class Tape:
    """One step's operations as ``TapedModel`` wrote them (``ops``), while ``recording``, with the
    copies of the states the reverse reads that the step overwrites (``copies``, (3, N) device
    arrays reused step after step in the same order).

    ``expected``: what the last step's tape showed of a step like it (``analyse``): which
    operations a reverse needs run (those whose results reach a state an F reads: an F at the
    last stage, or the ∇⁴ at the end, need not run) and which states need a copy (those an
    operation that runs writes after an F, or with ``parameters`` the ∇⁴, L or G, read them). A step
    whose operations turn out otherwise (``structure``) is taken again in full (``TapeAdjoint``)."""

    def __init__(self, model: ShallowWater, parameters: bool):
        self.model, self.parameters = model, parameters
        self.ops: list = []
        self.copies: list = []
        self.expected = None  # (structure, runs, copies) of the last analysed tape; None: run and copy all
        self.recording = False
        self._used = 0

    @contextmanager
    def record(self):
        """Write the operations of what runs inside on a fresh tape."""
        self.ops, self._used, self.recording = [], 0, True
        try:
            yield
        finally:
            self.recording = False

    def runs(self, make) -> bool:
        """Whether the operation ``make()`` builds runs (``expected``), written on the tape while it
        records; ``make`` is not called otherwise (nothing copied)."""
        if not self.recording:
            return True
        i, expected = len(self.ops), self.expected
        self.ops.append(make())
        return expected is None or i >= len(expected[1]) or expected[1][i]

    @contextmanager
    def solving(self, solver, r, a: float, z, scale: float, implicit):
        """A Helmholtz solve (``HelmholtzSolver.solve``): written on the tape while it records, its
        own launches not; yields whether it runs."""
        run = self.runs(lambda: Solve(r, z, implicit, float(a), float(scale), solver))
        recording, self.recording = self.recording, False
        try:
            yield run
        finally:
            self.recording = recording

    def linear(self, operator, x, updates) -> bool:
        """L x written into ``updates`` (``GravityWaveOperator.update``); whether it runs."""
        return self.runs(lambda: Linear(x, tuple(updates), operator, self.held(x)))

    def state(self, x):
        """x as the reverse will read it, for the operation about to be written: x itself, or a
        copy (``expected``)."""
        i, expected = len(self.ops), self.expected
        if expected is not None and i < len(expected[2]) and not expected[2][i]:
            return x
        if self._used == len(self.copies):
            self.copies.append(wp.zeros((3, self.model.topology.N), dtype=f64, device=self.model.topology.device))
        out = self.copies[self._used]
        self._used += 1
        wp.copy(out, x)
        return out

    def held(self, x):
        """``state(x)`` where the parameters' sums read it (``parameters``), else None."""
        return self.state(x) if self.parameters else None

    def structure(self) -> tuple:
        """The operations' kinds, arrays, rows and terms, not their coefficients."""
        return tuple(op_key(op, coefficients=False) for op in self.ops)

    def analyse(self) -> None:
        """``expected`` from this tape (the class doc), rows as the unit: each array's rows are
        found in the whole (3, N) arrays the operations name."""
        wholes = [a for op in self.ops for a in arrays_of(op) if a.shape[0] == 3]

        def cells(a, rows=None) -> set:
            a = a if rows is None else a[rows]
            base = next((w for w in wholes if 0 <= a.ptr - w.ptr < 3 * w.strides[0]), a)
            r0 = (a.ptr - base.ptr) // a.strides[0]
            return {(base.ptr, r) for r in range(r0, r0 + a.shape[0])}

        def writes(op) -> set:
            return set().union(*map(cells, written_by(op)))

        def reads(op) -> set:
            if isinstance(op, (Evaluate, Linear, Gradient, Divergence)):
                sources = set().union(*(cells(s, u.rows) for u in op.updates for _, s in u.terms if s is not None))
                return sources if isinstance(op, Evaluate) else sources | cells(op.x)
            if isinstance(op, Combine):  # at listed nodes: out's others read as kept
                return set().union(*(cells(b) for _, b in op.terms), cells(op.out) if op.nodes is not None else ())
            return cells(op.r) if isinstance(op, Solve) else cells(op.x)

        def linearised(op) -> set:  # the state the reverse reads
            if isinstance(op, Evaluate) or isinstance(op, (Smooth, Linear, Gradient)) and self.parameters:
                return cells(op.x)
            return set()

        needed, runs = set(), []  # the rows a later operation or the reverse reads, last operation first
        for op in reversed(self.ops):
            written = writes(op)
            runs.append(bool(written & needed))
            if runs[-1]:
                needed = (needed - written) | reads(op)
            needed |= linearised(op)
        runs.reverse()
        copies = tuple(
            bool(linearised(op))
            and any(run and writes(later) & cells(op.x) for later, run in zip(self.ops[i:], runs[i:]))
            for i, op in enumerate(self.ops)
        )
        self.expected = (self.structure(), tuple(runs), copies)
