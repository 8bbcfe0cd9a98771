"""The adjoint of one step of any stepper whose step is the model's verbs alone, by one mechanism:
the step taken again from x(n) on a tape, then the tape reversed (issue 82's "step as a plan").

The stepper's own code is the plan. A twin of the stepper (its class, Δt and options) is built on
a ``TapedModel``, which forwards every verb to the model and writes on the tape what it did:
- ``rhs_update(x, updates)`` (and ``rhs``, one update of F alone): F(x) at a copy of x taken before
  the call, then each update out[rows] = Σ a·src (src None: F), in order;
- a recorded combination's launch (``lincomb``): out = Σ c·x;
- ``hyperviscosity(x, dt)``: x ← H_dt(x) in place (with ``parameters`` a copy of x before it).
Any other verb that writes state (``pointwise``, ``rhs_part``) has no transpose here: an
``ArgumentError`` names it.

The reverse walks the tape backwards with one adjoint array per array the step touched, in the
mass form of ``adjoint.explicit`` (μ = R Q λ: every array the step writes is continuous):
- out = Σ c·x: μ_x += c μ_out for each x that is not out, then μ_out ← c_out μ_out (c_out the
  coefficient of out itself, 0 where it is not a term);
- an F evaluation: its updates last first as combinations, F's share summed into k̄, then
  μ_x += R Q Tᵀ(x) W k̄ (``model.transposes.TendencyTranspose``, its DSS unweighted), and with
  ``parameters`` the planet's and topography's sums of (x, k̄) (``StepAdjoint.planet_terms``);
- the ∇⁴: μ ← H_dtᵀ μ in place (``model.transposes.HyperviscosityTranspose``, with ``parameters``
  ∂J/∂ν, ∂J/∂ν_s and ∂J/∂hs summed from the copy before it).
x(n) and the arrays the stepper carries (``carried_arrays``) have the driver's rows of μ; the
twin's other arrays adjoints of their own, zero at the start of each reverse. A new explicit
stepper or Butcher table written with these verbs has its gradient with no adjoint code.
The reverse's launches are recorded once per tape (its arrays and coefficients) and replayed.
"""

from __future__ import annotations

import warp as wp

from ..core.errors import ArgumentError
from ..model.launches import Update
from ..model.shallow_water import ShallowWater
from ..model.transposes import Combinations
from .explicit import HELD_DTS, Transposes

f64 = wp.float64

MOMENTUM_ROWS = ("momentum_advection", "coriolis", "pressure_gradient", "topography", "forcing")


def written_rows(terms) -> slice | None:
    """The rows of F that the tendency of ``terms`` writes (None: all three): the depth row by
    continuity and a forcing, the wind rows by the momentum terms and a forcing."""
    depth = "continuity" in terms or "forcing" in terms
    wind = any(t in MOMENTUM_ROWS for t in terms)
    return None if depth and wind else slice(2, 3) if depth else slice(0, 2)


class _TapedLaunch:
    """A recorded combination's launch (``ShallowWater.lincomb``) that writes itself on the tape."""

    def __init__(self, tape: Tape, launch, out, terms):
        self.tape, self.real, self.out, self.terms = tape, launch, out, tuple(terms)

    def launch(self) -> None:
        if self.tape.combine(self.out, self.terms):
            self.real.launch()


class TapedModel:
    """A ``ShallowWater`` whose state-writing verbs are written on ``tape`` as they run
    (module doc); every other member is the model's."""

    def __init__(self, model: ShallowWater, tape: Tape):
        self._model, self._tape = model, tape

    def __getattr__(self, name):
        return getattr(self._model, name)

    def rhs(self, x, out, terms=None) -> None:
        rows = written_rows(self._model.terms if terms is None else terms)
        if self._tape.evaluate(x, (Update(out, ((1.0, None),), rows),), terms):
            self._model.rhs(x, out, terms)

    def rhs_update(self, x, updates, terms=None) -> None:
        if self._tape.evaluate(x, tuple(updates), terms):
            self._model.rhs_update(x, updates, terms)

    def lincomb(self, out, terms):
        terms = list(terms)
        return _TapedLaunch(self._tape, self._model.lincomb(out, terms), out, terms)

    def hyperviscosity(self, x, dt: float) -> None:
        if self._tape.smooth(x, dt):
            self._model.hyperviscosity(x, dt)

    def pointwise(self, kernel, *inputs, unique=False) -> None:
        raise ArgumentError(f"no gradient through the pointwise kernel {kernel.key!r} (the tape's verbs: tape.py)")

    def rhs_part(self, x, out, part, terms=None) -> None:
        raise ArgumentError("no gradient through rhs_part on the tape (local time stepping's own adjoint serves it)")


class Tape:
    """One step's operations as ``TapedModel`` wrote them (``ops``: kind, the array written or read,
    then the kind's own), with the copies of the states the reverse reads that the step overwrites
    (``copies``, (3, N) device arrays reused step after step in the same order).

    ``expected``: what the last step's tape showed of a step like it (``analyse``): which
    operations a reverse needs run (those whose results reach a state an F reads: an F at the
    last stage, or the ∇⁴ at the end, need not run) and which states need a copy (those an
    operation that runs writes after an F, or with ``keep_smoothed`` the ∇⁴, read them). A step
    whose operations turn out otherwise (``structure``) is taken again in full (``TapeAdjoint``)."""

    def __init__(self, model: ShallowWater, keep_smoothed: bool):
        self.model, self.keep_smoothed = model, keep_smoothed
        self.ops: list[tuple] = []
        self.copies: list = []
        self.expected = None  # (structure, runs, copies) of the last analysed tape; None: run and copy all
        self._used = 0

    def clear(self) -> None:
        self.ops, self._used = [], 0

    def _decide(self, x) -> tuple[bool, object]:
        """Whether the next operation runs, and the state it reads as the reverse will (a copy or x)."""
        i, expected = len(self.ops), self.expected
        run, copy = (True, True) if expected is None or i >= len(expected[1]) else (expected[1][i], expected[2][i])
        if not copy:
            return run, x
        if self._used == len(self.copies):
            self.copies.append(wp.zeros((3, self.model.topology.N), dtype=f64, device=self.model.topology.device))
        out = self.copies[self._used]
        self._used += 1
        wp.copy(out, x)
        return run, out

    def evaluate(self, x, updates, terms) -> bool:
        """An F at x written into ``updates``; whether it runs."""
        run, state = self._decide(x)
        self.ops.append(("evaluate", x, state, updates, self.model.terms if terms is None else tuple(terms)))
        return run

    def _runs(self) -> bool:
        i, expected = len(self.ops), self.expected
        return expected is None or i >= len(expected[1]) or expected[1][i]

    def combine(self, out, terms) -> bool:
        """out = Σ c·x; whether it runs."""
        run = self._runs()
        self.ops.append(("combine", out, terms))
        return run

    def smooth(self, x, dt: float) -> bool:
        """The ∇⁴ over dt in place on x (nothing without it); whether it runs."""
        hv = self.model.hv
        if hv is None or hv.nu_max == 0:
            return False
        run, state = self._decide(x) if self.keep_smoothed else (self._runs(), None)
        self.ops.append(("smooth", x, float(dt), state))
        return run

    def structure(self) -> tuple:
        """The operations' kinds, arrays, rows and terms, not their coefficients."""
        out = []
        for kind, a, *rest in self.ops:
            if kind == "evaluate":
                out.append((kind, _key(a), rest[2], *((_key(u.out), _rows(u), *_sources(u)) for u in rest[1])))
            else:
                out.append((kind, _key(a), *((_key(b) for _, b in rest[0]) if kind == "combine" else ())))
        return tuple(out)

    def analyse(self) -> None:
        """``expected`` from this tape (the class doc), rows as the unit: each array's rows are
        found in the whole (3, N) arrays the operations name."""
        wholes = [a for op in self.ops for a in _arrays(op) if a.shape[0] == 3]

        def cells(a, rows=None) -> set:
            a = a if rows is None else a[rows]
            base = next((w for w in wholes if 0 <= a.ptr - w.ptr < 3 * w.strides[0]), a)
            r0 = (a.ptr - base.ptr) // a.strides[0]
            return {(base.ptr, r) for r in range(r0, r0 + a.shape[0])}

        def writes(op) -> set:
            if op[0] == "evaluate":
                return set().union(*(cells(u.out, u.rows) for u in op[3]))
            return cells(op[1])

        def reads(op) -> set:
            if op[0] == "evaluate":
                return set().union(*(cells(s, u.rows) for u in op[3] for _, s in u.terms if s is not None))
            return set().union(*(cells(b) for _, b in op[2])) if op[0] == "combine" else cells(op[1])

        needed, runs = set(), []  # the rows a later operation or the reverse reads, last operation first
        for op in reversed(self.ops):
            written = writes(op)
            runs.append(bool(written & needed))
            if runs[-1]:
                needed = (needed - written) | reads(op) if op[0] != "smooth" else needed
            if op[0] == "evaluate" or op[0] == "smooth" and self.keep_smoothed:
                needed |= cells(op[1])  # the state the reverse linearises about (or Φ)
        runs.reverse()
        copies = [
            any(run and writes(later) & cells(op[1]) for later, run in zip(self.ops[i:], runs[i:]))
            for i, op in enumerate(self.ops)
        ]
        self.expected = (self.structure(), runs, copies)


def _rows(update) -> tuple | None:
    return None if update.rows is None else (update.rows.start, update.rows.stop)


def _sources(update) -> tuple:
    return tuple(None if s is None else _key(s) for _, s in update.terms)


def _arrays(op) -> list:
    if op[0] == "combine":
        return [op[1], *(a for _, a in op[2])]
    if op[0] == "smooth":
        return [op[1]]
    return [op[1], *(a for u in op[3] for a in (u.out, *(s for _, s in u.terms if s is not None)))]


def _key(a) -> tuple:
    return (a.ptr, a.shape, a.strides)


class TapeAdjoint(Transposes):
    """The adjoint of one step of ``stepper`` on ``model`` at Δt = ``dt`` (s), its steps from model
    time ``t0`` (s), taken from a tape of the step (module doc): ``reverse(s, mu, k)`` maps the
    adjoint μ (3 + 3c, N) of s(k+1) = (x, the c carried arrays) to that of s(k) in place, s = s(k)
    (3 + 3c, N) read only, after ``prepare`` from x(0). ``parameters`` as ``StepAdjoint``'s (∂J/∂ν, ν_s, hs, g and Ω).
    ``set_dt`` as the stepper's (ValueError where it keeps one Δt). ``ArgumentError``
    (``explicit.refusal``) for a model it cannot serve, or, from ``reverse``, for a step with a
    verb it cannot transpose.

    Work arrays (3, N): the twin stepper's own, a copy of each state an F or the ∇⁴ read, k̄ a
    F evaluation, an adjoint for each array of the twin's the step writes."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        self._setup(model, dt, parameters, t0)
        self.tape = Tape(model, self.parameters)
        self.twin = type(stepper)(TapedModel(model, self.tape), float(dt), stepper.options)
        self.twin.t0 = float(t0)
        self.work = self._zeros(3)
        self.combinations = Combinations(model.launches)
        self._mu: dict[tuple, object] = {}  # the twin's arrays' adjoints, by address
        self._kbar: list = []  # k̄ of each F evaluation of a tape, in order
        self._smoothing: dict[float, object] = {}  # the ∇⁴'s transposes, by span
        self._plans: dict[tuple, list] = {}  # a tape's reverse, by its key

    @property
    def t0(self) -> float:
        return self.twin.t0 if hasattr(self, "twin") else self._t0

    @t0.setter
    def t0(self, value: float) -> None:
        if hasattr(self, "twin"):
            self.twin.t0 = float(value)
        self._t0 = float(value)

    def set_dt(self, dt: float) -> None:
        dt = float(dt)
        if dt != self.twin.dt:
            self.twin.set_dt(dt)
        self.dt = dt

    def prepare(self, x0) -> None:
        """The twin prepared from x(0) as the run's stepper (local time stepping fixes its levels)."""
        self.twin.prepare(x0)

    def before_hyperviscosity(self, out) -> None:
        """out = the state the last reversed step's ∇⁴ started from (kept with ``parameters``; without
        the ∇⁴ the step's end)."""
        wp.copy(out, next((op[3] for op in reversed(self.tape.ops) if op[0] == "smooth"), self.work))

    def _take(self, x, k: int) -> None:
        """The twin's step k from s = ``x`` on a fresh tape (``Tape.expected`` deciding what runs)."""
        wp.copy(self.work, x[0:3])
        for i, a in enumerate(self.twin.carried_arrays()):
            wp.copy(a, x[3 * i + 3 : 3 * i + 6])
        self.tape.clear()
        self.twin.set_phase(k)
        self.twin.step(self.work)

    def reverse(self, x, mu, k: int = 0) -> None:
        """μ of s(k+1) → μ of s(k), in place; x = s(k) (read only), k the step's index."""
        tape = self.tape
        self._take(x, k)
        if tape.expected is None or tape.expected[0] != tape.structure():
            if tape.expected is not None:  # taken with another step's decisions: again, in full
                tape.expected = None
                self._take(x, k)
            tape.analyse()  # for the next steps
        key = (mu.ptr, *map(_op_key, tape.ops))
        plan = self._plans.get(key)
        if plan is None:
            if len(self._plans) >= HELD_DTS:
                del self._plans[next(iter(self._plans))]
            plan = self._plans[key] = self._plan(mu)
        for action in plan:
            action()

    # -- the reverse's plan -------------------------------------------------------------
    def _plan(self, mu) -> list:
        """The actions (callables) of the tape's reverse, last operation first (module doc)."""
        carried = self.twin.carried_arrays()
        self._bases = [(self.work, mu[0:3]), *((a, mu[3 * i + 3 : 3 * i + 6]) for i, a in enumerate(carried))]
        for a in (a for op in self.tape.ops for a in _arrays(op) if a.shape[0] == 3):
            self._adjoint(a)
        actions = [m.zero_ for _, m in self._bases[1 + len(carried) :]]
        evaluations = sum(op[0] == "evaluate" for op in self.tape.ops)
        while len(self._kbar) < evaluations:
            self._kbar.append(self._zeros(3))
        n = evaluations
        for op in reversed(self.tape.ops):
            if op[0] == "combine":
                actions += self._combination(op[1], op[2])
            elif op[0] == "smooth":
                actions.append(self._smoothing_action(*op[1:]))
            else:
                n -= 1
                actions += self._evaluation(self._kbar[n], *op[1:])
        return actions

    def _adjoint(self, a):
        """The adjoint (rows, N) of the twin's array or row view ``a`` (made for a whole (3, N) array
        met first)."""
        rowbytes = a.strides[0]
        for base, m in self._bases:
            offset = a.ptr - base.ptr
            if base.strides == a.strides and 0 <= offset < base.shape[0] * rowbytes and offset % rowbytes == 0:
                r0 = offset // rowbytes
                if r0 + a.shape[0] > base.shape[0]:
                    break
                return m[r0 : r0 + a.shape[0]]
        if a.shape[0] != 3:
            raise ArgumentError(f"the tape met rows {a.shape} of an array the step never names whole")
        m = self._mu.get(_key(a))
        if m is None:
            m = self._mu[_key(a)] = self._zeros(3)
        self._bases.append((a, m))
        return m

    def _launches(self, out, terms) -> list:
        return [launch.launch for launch in self.combinations.combination(out, terms)]

    def _scale(self, m, c: float) -> list:
        """m ← c·m: nothing for c = 1, a fill for c = 0."""
        return [] if c == 1.0 else [m.zero_] if c == 0.0 else self._launches(m, [(c, m)])

    def _overlaps(self, a, b) -> bool:
        return a.ptr < b.ptr + b.shape[0] * b.strides[0] and b.ptr < a.ptr + a.shape[0] * a.strides[0]

    def _combination(self, out, terms) -> list:
        """out = Σ c·x reversed: μ_x += c μ_out for the x that are not out, μ_out ← c_out μ_out."""
        m_out, actions, own = self._adjoint(out), [], 0.0
        for c, a in terms:
            if _key(a) == _key(out):
                own += c
            elif self._overlaps(a, out):
                raise ArgumentError("the tape met a combination whose output overlaps a term in part")
            elif c != 0.0:
                m_a = self._adjoint(a)
                actions += self._launches(m_a, [(1.0, m_a), (c, m_out)])
        return actions + self._scale(m_out, own)

    def _evaluation(self, kbar, x, state, updates, terms) -> list:
        """An F evaluation's reverse (module doc): its updates' combinations reversed, last first, F's
        share summed into k̄, then μ_x += R Q Tᵀ(x) W k̄. Where every update writes all rows of an
        array of its own that no later update reads, k̄ is the updates' adjoints as they stand
        before their reverses: Tᵀ reads them so, and only its DSS waits for the combinations."""
        outs = [u.out for u in updates]
        direct = all(u.rows is None for u in updates) and not any(
            self._overlaps(o, p) or any(s is not None and self._overlaps(o, s) for _, s in later.terms)
            for j, o in enumerate(outs)
            for p, later in zip(outs[j + 1 :], updates[j + 1 :])
        )
        kterms = [(a, self._adjoint(u.out)) for u in updates for a, src in u.terms if src is None] if direct else []
        actions, started = self._parameters(state, kterms, terms), False
        actions += [launch.launch for launch in self.tendency.transpose(state, kterms, terms)] if kterms else []
        for u in reversed(updates):
            rows = slice(0, 3) if u.rows is None else u.rows
            m_out, own = self._adjoint(u.out[rows]), 0.0
            for a, src in u.terms:
                if src is None:
                    if direct:
                        continue
                    if not started and u.rows is None:
                        actions += self._launches(kbar, [(a, m_out)])
                    else:
                        if not started:
                            actions.append(kbar.zero_)
                        actions += self._launches(kbar[rows], [(1.0, kbar[rows]), (a, m_out)])
                    started = True
                elif _key(src) == _key(u.out):
                    own += a
                elif a != 0.0:
                    m_src = self._adjoint(src[rows])
                    actions += self._launches(m_src, [(1.0, m_src), (a, m_out)])
            actions += self._scale(m_out, own)
        if started:
            actions += self._parameters(state, [(1.0, kbar)], terms)
            actions += [launch.launch for launch in self.tendency.transpose(state, [(1.0, kbar)], terms)]
        if started or kterms:
            m_x = self._adjoint(x)
            dss = self.model.topology.dss_update(self.xbar, [(m_x, ((1.0, m_x), (1.0, None)))], weighted=False)
            actions += [launch.launch for launch in dss]
        return actions

    def _parameters(self, state, kbar, terms) -> list:
        """With ``parameters``, the planet's sums of an F at ``state`` whose adjoint is Σ c·a over ``kbar``."""
        if not (self.parameters and kbar):
            return []
        g_terms = tuple(t for t in self.g_terms if t in terms)
        return [lambda: self.planet_terms(state, kbar, g_terms, "coriolis" in terms)]

    def _smoothing_action(self, x, dt: float, before):
        """The ∇⁴ over ``dt`` reversed in place on μ_x (with ``parameters`` its sums, Φ = ``before``)."""
        transpose = self._smoothing.get(dt)
        if transpose is None:
            shared = next(iter(self._smoothing.values()), None)
            transpose = self._smoothing[dt] = self.model.hv.transpose(self.tendency, dt, shared)
        m_x = self._adjoint(x)
        if not self.parameters:
            return lambda: transpose.transpose(m_x)
        return lambda: transpose.transpose(m_x, lambda out: wp.copy(out, before), self.d_nu, self.d_hs)


def _op_key(op) -> tuple:
    """An operation's arrays, rows, terms and coefficients: a tape's reverse is recorded once per such key."""
    kind, x, *rest = op
    if kind == "combine":
        return (kind, _key(x), *((c, _key(a)) for c, a in rest[0]))
    if kind == "smooth":
        return (kind, _key(x), rest[0], rest[1] is not None and _key(rest[1]))
    state, updates, terms = rest
    keyed = ((_key(u.out), _rows(u), *((a, None if s is None else _key(s)) for a, s in u.terms)) for u in updates)
    return (kind, _key(x), _key(state), terms, *keyed)
