"""A tape of one step of a stepper: what a gradient's reverse (``reverse.TapeAdjoint``) reads of a
step taken again from x(n) (issue 82's "step as a plan": the stepper's own code is the plan).

A twin of the stepper (its class, Δt and options) is built on a ``TapedModel``, which forwards
every verb to the model and, while the tape records, writes on it what it did:
- ``Evaluate``: F(x) (``rhs_update``, or ``rhs`` as one update of F alone; ``rhs_part`` over a
  part's elements) at x as it stood, then each update out[rows] = Σ a·src (src None: F), in order;
- ``Combine``: out = Σ c·x (a recorded combination's launch, ``lincomb``, or ``pointwise``'s
  ``blas.axpby`` and ``axpbypcz``), and ``CombineAt`` the same at listed nodes (``launches.
  lincomb_at``: MRAB3's sums);
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


class CombineAt(NamedTuple):
    out: object
    terms: tuple
    nodes: object  # the element-local nodes it writes (int32 device array); out's others kept


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


def _rows(update) -> tuple | None:
    return None if update.rows is None else (update.rows.start, update.rows.stop)


def _updates_key(updates, coefficients: bool) -> tuple:
    return tuple(
        (
            array_key(u.out),
            _rows(u),
            *((a if coefficients else None, None if s is None else array_key(s)) for a, s in u.terms),
        )
        for u in updates
    )


def op_key(op, coefficients: bool = True) -> tuple:
    """An operation's kind, arrays, rows and terms, and its coefficients (``coefficients``)."""
    c = (lambda v: v) if coefficients else (lambda v: None)
    if isinstance(op, Evaluate):
        part = None if op.part is None else id(op.part)
        return ("F", array_key(op.x), c(array_key(op.state)), op.terms, part, _updates_key(op.updates, coefficients))
    if isinstance(op, Gradient):
        state = op.state is not None and c(array_key(op.state))  # read by g's sums (``parameters``)
        return ("G", array_key(op.x), state, op.row, _updates_key(op.updates, coefficients))
    if isinstance(op, Divergence):
        return ("D", array_key(op.x), _updates_key(op.updates, coefficients))
    if isinstance(op, (Combine, CombineAt)):
        at = () if isinstance(op, Combine) else (op.nodes.ptr,)
        return ("C", array_key(op.out), *at, *((c(a), array_key(x)) for a, x in op.terms))
    if isinstance(op, Smooth):
        return ("H", array_key(op.x), c(op.dt), op.state is not None and c(array_key(op.state)))
    if isinstance(op, Linear):
        state = op.state is not None and c(array_key(op.state))
        return ("L", array_key(op.x), state, id(op.operator), _updates_key(op.updates, coefficients))
    return (
        "S",
        array_key(op.r),
        array_key(op.z),
        op.implicit is not None and array_key(op.implicit),
        c(op.a),
        c(op.scale),
    )


def written_by(op) -> list:
    """The arrays (row views) an operation writes."""
    if isinstance(op, (Evaluate, Linear, Gradient, Divergence)):
        return [u.out if u.rows is None else u.out[u.rows] for u in op.updates]
    if isinstance(op, Solve):
        return [op.z, *([op.implicit] if op.implicit is not None else [])]
    return [op.out if isinstance(op, (Combine, CombineAt)) else op.x]


def arrays_of(op) -> list:
    """Every array an operation names."""
    if isinstance(op, (Evaluate, Linear, Gradient, Divergence)):
        return [op.x, *(a for u in op.updates for a in (u.out, *(s for _, s in u.terms if s is not None)))]
    if isinstance(op, (Combine, CombineAt)):
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
    that writes itself (``op``, a ``Combine`` or ``CombineAt``) on the tape."""

    def __init__(self, tape: Tape, launch, op):
        self.tape, self.real, self.op = tape, launch, op

    def launch(self) -> None:
        if not self.tape.recording or self.tape.write(self.op):
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
        return _TapedLaunch(self._tape, self._launches.lincomb_at(out, terms, nodes), CombineAt(out, terms, nodes))


class TapedModel:
    """A ``ShallowWater`` whose state-writing verbs are written on ``tape`` while it records
    (module doc); every other member is the model's. The gravity-wave operator and the Helmholtz
    solver built on it find ``tape`` and write themselves there."""

    def __init__(self, model: ShallowWater, tape: Tape):
        self._model, self.tape = model, tape
        self.operators = _TapedOperators(model.operators, tape)
        self.launches = _TapedLaunches(model.launches, tape)

    def __getattr__(self, name):
        return getattr(self._model, name)

    def rhs(self, x, out, terms=None) -> None:
        rows = written_rows(self._model.terms if terms is None else terms)
        if self.tape.evaluate(x, (Update(out, ((1.0, None),), rows),), terms):
            self._model.rhs(x, out, terms)

    def rhs_update(self, x, updates, terms=None) -> None:
        if self.tape.evaluate(x, tuple(updates), terms):
            self._model.rhs_update(x, updates, terms)

    def lincomb(self, out, terms):
        terms = tuple(terms)
        return _TapedLaunch(self.tape, self._model.lincomb(out, terms), Combine(out, terms))

    def hyperviscosity(self, x, dt: float) -> None:
        if self.tape.smooth(x, dt):
            self._model.hyperviscosity(x, dt)

    def pointwise(self, kernel, *inputs, unique=False) -> None:
        if not self.tape.recording or self.tape.write(Combine(*combination(kernel, inputs))):
            self._model.pointwise(kernel, *inputs, unique=unique)

    def rhs_part(self, x, out, part, terms=None) -> None:
        rows = written_rows(self._model.terms if terms is None else terms)
        if self.tape.evaluate(x, (Update(out, ((1.0, None),), rows),), terms, part):
            self._model.rhs_part(x, out, part, terms)


class _TapedOperators:
    """The model's ``ElementOperators`` whose gradient and divergence updates (the split-explicit
    and multirate substeps') are written on the tape while it records; every other member theirs."""

    def __init__(self, operators, tape: Tape):
        self._operators, self._tape = operators, tape

    def __getattr__(self, name):
        return getattr(self._operators, name)

    def gradient_update(self, x, row: int, updates) -> None:
        if self._tape.gradient(x, row, updates):
            self._operators.gradient_update(x, row, updates)

    def divergence_update(self, x, updates) -> None:
        if not self._tape.recording or self._tape.write(Divergence(x, tuple(updates))):
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

    @contextmanager
    def solving(self, solver, r, a: float, z, scale: float, implicit):
        """A Helmholtz solve (``HelmholtzSolver.solve``): written on the tape while it records, its
        own launches not; yields whether it runs."""
        if not self.recording:
            yield True
            return
        run = self.write(Solve(r, z, implicit, float(a), float(scale), solver))
        self.recording = False
        try:
            yield run
        finally:
            self.recording = True

    def linear(self, operator, x, updates) -> bool:
        """L x written into ``updates`` (``GravityWaveOperator.update``); whether it runs."""
        if not self.recording:
            return True
        return self.write(Linear(x, tuple(updates), operator, self._state(x) if self.parameters else None))

    def gradient(self, x, row: int, updates) -> bool:
        """−g·τ G x[row] written into ``updates`` (``ElementOperators.gradient_update``); whether it runs."""
        if not self.recording:
            return True
        return self.write(Gradient(x, int(row), tuple(updates), self._state(x) if self.parameters else None))

    def _runs(self) -> bool:
        i, expected = len(self.ops), self.expected
        return expected is None or i >= len(expected[1]) or expected[1][i]

    def write(self, op) -> bool:
        """``op`` on the tape; whether it runs."""
        run = self._runs()
        self.ops.append(op)
        return run

    def _state(self, x):
        """x as the reverse will read it: x itself, or a copy (``expected``)."""
        i, expected = len(self.ops), self.expected
        if expected is not None and i < len(expected[2]) and not expected[2][i]:
            return x
        if self._used == len(self.copies):
            self.copies.append(wp.zeros((3, self.model.topology.N), dtype=f64, device=self.model.topology.device))
        out = self.copies[self._used]
        self._used += 1
        wp.copy(out, x)
        return out

    def evaluate(self, x, updates, terms, part=None) -> bool:
        """An F at x (over ``part``'s elements alone, an ``ElementPart``) written into ``updates``;
        whether it runs."""
        if not self.recording:
            return True
        terms = self.model.terms if terms is None else tuple(terms)
        return self.write(Evaluate(x, self._state(x), updates, terms, part))

    def smooth(self, x, dt: float) -> bool:
        """The ∇⁴ over dt in place on x (nothing without it); whether it runs."""
        hv = self.model.hv
        if not self.recording or hv is None or hv.nu_max == 0:
            return True
        return self.write(Smooth(x, float(dt), self._state(x) if self.parameters else None))

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
            if isinstance(op, (Combine, CombineAt)):  # at listed nodes: out's others read as kept
                return set().union(*(cells(b) for _, b in op.terms), cells(op.out) if isinstance(op, CombineAt) else ())
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
        copies = [
            bool(linearised(op))
            and any(run and writes(later) & cells(op.x) for later, run in zip(self.ops[i:], runs[i:]))
            for i, op in enumerate(self.ops)
        ]
        self.expected = (self.structure(), runs, copies)
