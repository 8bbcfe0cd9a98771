"""The adjoint of one step of any stepper whose step is the model's verbs alone, by one mechanism:
the step taken again from x(n) on a tape (``tape``), then the tape reversed.

Adjoints are carried as the continuous fields μ = R Q λ (λ the element-local adjoint: ∂J/∂x
over every copy; Q the sum over a node's copies, R the inverse assembled mass rspheremp): the
gradient in the mass inner product, δJ = Σ spheremp · μ · δx over the element-local nodes for a
continuous δx (every array a step writes is continuous). F = M⁻¹ Q W T(x) (T the element-local
tendency, W the element mass spheremp, M⁻¹ = R). In that form the DSS's transpose is λ_T = W μ_K
(R and Q commute, R being continuous); the ∇⁴ is its own transpose, R Q Bᵀ = B R Q (the tensor
∇⁴'s with its Laplacians swapped, the ∇δ term's added apart); T's transpose is the model's
(``model.transposes``), whose λ is gathered back by the unweighted DSS, μ = R Q λ.

The reverse walks the tape backwards with one adjoint array per array the step touched:
- out = Σ c·x: μ_x += c μ_out for each x that is not out, then μ_out ← c_out μ_out (c_out the
  coefficient of out itself, 0 where it is not a term);
- an F: its updates last first as combinations, F's share summed into k̄, then μ_x += R Q Tᵀ(x)
  W k̄ (``TendencyTranspose``, its DSS unweighted); L likewise with Lᵀ (``GravityTranspose``: Tᵀ
  of the pressure gradient and continuity at (0, 0, H)); G and D each other's transposes;
- the ∇⁴: μ ← H_dtᵀ μ in place (``HyperviscosityTranspose``);
- a solve: t = A_a⁻ᵀ (μ_z + μ_Lz/a) (``GravityTranspose.solve``, the same CG between two scalings
  of the h row), μ_z, μ_Lz ← 0, μ_r += s·t − (s/a) μ_Lz.
x(n) and the arrays the stepper carries (``carried_arrays``) have the driver's rows of μ; the
twin's other arrays adjoints of their own, zero at the start of each reverse. A new stepper or
Butcher table written with these verbs has its gradient with no adjoint code. The reverse's
launches are recorded once per tape (its arrays and coefficients) and replayed.

The parameters (``parameters=True``): ∂J/∂ν, ∂J/∂ν_s and the ∇⁴'s share of ∂J/∂hs summed by the
∇⁴'s transpose, plus the forcing −g∇hs's share of ∂J/∂hs, the pressure gradient's transpose of
Σ λ over the F evaluations (``fbar``). F is linear in g (−g∇(h + hs)) and in Ω (f (v, −u),
f ∝ Ω), so with k̄ the adjoint of an F(Y), g ∂J/∂g = Σ ⟨k̄, F_g(Y)⟩ and Ω ∂J/∂Ω = Σ ⟨k̄, f (v,
−u)⟩ over the evaluations (``d_planet``), F_g the RHS of those two terms alone; x(0), hs and a
case's forcing held fixed. Checked by dot-product tests of each piece and Taylor tests of the
whole (``tests/adjoint``).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.errors import ArgumentError
from ..model.launches import Update
from ..model.shallow_water import ShallowWater
from ..model.transposes import Combinations, PlanetSums
from .tape import (
    Combine,
    Divergence,
    Evaluate,
    Gradient,
    Linear,
    Smooth,
    Solve,
    Tape,
    TapedModel,
    array_key,
    arrays_of,
    op_key,
    written_by,
)

f64 = wp.float64

# the tapes whose reverses an adjoint keeps recorded (``reverse.TapeAdjoint``): a controlled run
# takes its Δt from a grid of 16 an octave (``integrator.control.DT_GRID``), so few recur at once
HELD_DTS = 8


def refusal(model: ShallowWater) -> str | None:
    """Why the adjoint cannot serve ``model`` (None: it can)."""
    if model.hv is not None:
        if model.hv.nu_div != model.hv.nu and model.hv.nu == 0:
            return "nu_div != nu with nu = 0 has no adjoint yet (its ∇δ term's transpose reads the ν-scaled pass)"
    return None


class TapeAdjoint:
    """The adjoint of one step of ``stepper`` on ``model`` at Δt = ``dt`` (s), its steps from model
    time ``t0`` (s), taken from a tape of the step (module doc): ``reverse(s, mu, k)`` maps the
    adjoint μ (3 + 3c, N) of s(k+1) = (x, the c carried arrays) to that of s(k) in place, s = s(k)
    (3 + 3c, N) read only. ``parameters``: ∂J/∂ν, ν_s, hs, g and Ω summed (module doc: ``d_nu``,
    ``d_planet``, ``hs_gradient``). ``set_dt`` as the stepper's (ValueError where it keeps one Δt).
    ``ArgumentError`` (``refusal``) for a model it cannot serve, with ``parameters`` for a
    stepper that solves with L (which holds g and H), or, from ``reverse``, for a step with a verb
    it cannot transpose; ``StepFailure`` where a solve, taken again or transposed, misses the
    stepper's ``tol`` within ``maxiter``.

    Work arrays (3, N): the twin stepper's own; a copy of each state that an F (with ``parameters``
    the ∇⁴, L or G too) reads and the step overwrites after; k̄ for each F where its updates cannot
    stand for it; an adjoint for each array of the twin's that the step writes; with a solve, a
    ``HelmholtzSolver`` of its own."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        if parameters and getattr(stepper, "linear", None) is not None:
            raise ArgumentError(
                f"parameters must be False with {stepper.name} (got True): its gradient is the initial "
                "state's alone (its gravity-wave operator L holds g and H)"
            )
        why = refusal(model)
        if why is not None:
            raise ArgumentError(why)
        self.model, self.dt, self.parameters, self.t0 = model, float(dt), bool(parameters), float(t0)
        self.tendency = model.operators.tendency_transpose(model.terms, model.g)  # Fᵀ: ``transpose``'s launches
        # the terms F holds, the x̄ its transposes write, f̄ = Σ λ's wind rows (the forcing −g∇hs's adjoint)
        self.terms, self.xbar, self.fbar = self.tendency.terms, self.tendency.xbar, self.tendency.fbar
        self.d_nu = np.zeros(2)  # ∂J/∂ν (wind rows), ∂J/∂ν_s (h row), m⁻⁴ s · J
        self.planet = PlanetSums(model)
        self.d_planet, self.g_terms = self.planet.sums, self.planet.g_terms  # g ∂J/∂g, Ω ∂J/∂Ω (J), summed in place
        self.d_hs = self._zeros(1)  # the ∇⁴'s share of ∂J/∂hs, continuous (mass form)
        self.tape = Tape(model, self.parameters)
        self.stepper, self._synced = stepper, False
        self.twin = type(stepper)(TapedModel(model, self.tape), float(dt), stepper.options)
        self.work = self._zeros(3)
        self.combinations = Combinations(model.launches)
        self._mu: dict[tuple, object] = {}  # the twin's arrays' adjoints, by address
        self._kbar: list = []  # k̄ of each F or L of a tape, in order
        self._smoothing: dict[float, object] = {}  # the ∇⁴'s transposes, by span
        self._gravity: dict[int, object] = {}  # L's transposes, by its operator
        self._plans: dict[tuple, list] = {}  # a tape's reverse, by its key
        self._solving = None  # a solve's reverse's work arrays (t, w), made at the first
        self._transposed = None  # G's and D's transposes' work array, made at the first

    def set_dt(self, dt: float) -> None:
        dt = float(dt)
        if dt != self.twin.dt:
            self.twin.set_dt(dt)
        self.dt = dt

    def _take(self, x, k: int) -> None:
        """The twin's step k from s = ``x`` on a fresh tape (``Tape.expected`` deciding what runs); at
        the first, the twin restored from the stepper's ``state()``: what its first step or
        ``prepare`` fixed (a mean depth H, local time stepping's levels)."""
        if not self._synced:
            self.twin.restore(self.stepper.state())
            self._synced = True
        wp.copy(self.work, x[0:3])
        self._carried = self.twin.carried_arrays()  # in the order the state holds them (MRAB3's rotate)
        for i, a in enumerate(self._carried):
            wp.copy(a, x[3 * i + 3 : 3 * i + 6])
        self.twin.t0 = self.t0  # the run's clock (``core.clock.StepTimes`` sets this object's)
        self.twin.set_phase(k)
        with self.tape.record():
            self.twin.step(self.work)

    def reverse(self, x, mu, k: int = 0) -> None:
        """μ of s(k+1) → μ of s(k), in place; x = s(k) (read only), k the step's index."""
        tape = self.tape
        self._take(x, k)
        key = self._key(mu)
        plan = self._plans.get(key)  # the same operations taken under the same decisions: no more to check
        if plan is None:
            if tape.expected is not None and tape.expected[0] != tape.structure():
                tape.expected = None  # taken with another step's decisions: again, in full
                self._take(x, k)
                key = self._key(mu)
            if tape.expected is None:
                tape.analyse()  # for the next steps
            plan = self._plans.get(key)
            if plan is None:
                if len(self._plans) >= HELD_DTS:
                    del self._plans[next(iter(self._plans))]
                plan = self._plans[key] = self._plan(mu)
        for action in plan:
            action()

    def _key(self, mu) -> tuple:
        """A tape's reverse's key: μ, the decisions the step was taken under (``Tape.expected``'s
        runs and copies; None: all) and its operations with their coefficients (``op_key``)."""
        expected = self.tape.expected
        return (mu.ptr, expected and expected[1:], *map(op_key, self.tape.ops))

    # -- the reverse's plan -------------------------------------------------------------
    def _plan(self, mu) -> list:
        """The actions (callables) of the tape's reverse, last operation first (module doc)."""
        carried = self.twin.carried_arrays()
        self._bases = [(self.work, mu[0:3]), *((a, mu[3 * i + 3 : 3 * i + 6]) for i, a in enumerate(carried))]
        for a in (a for op in self.tape.ops for a in arrays_of(op) if a.shape[0] == 3):
            self._adjoint(a)
        self._check_parts()
        actions, n = [], 0
        for op in reversed(self.tape.ops):
            if isinstance(op, Combine):
                actions += self._combination(op)
            elif isinstance(op, Smooth):
                actions.append(self._smoothing_action(op))
            elif isinstance(op, Solve):
                actions += self._solve(op)
            else:
                if len(self._kbar) == n:
                    self._kbar.append(self._zeros(3))
                actions += self._evaluation(self._kbar[n], op)
                n += 1
        zeros = [m.zero_ for _, m in self._bases[1 + len(carried) :]]  # the twin's own from zero
        return zeros + actions + self._reorder(mu, carried)

    def _reorder(self, mu, carried) -> list:
        """μ's rows of the carried arrays from their order after the step (the plan's) to their
        order before it, where the step rotates them (MRAB3's histories)."""
        before = [next(i for i, b in enumerate(carried) if b.ptr == a.ptr) for a in self._carried]
        if before == list(range(len(carried))):
            return []
        held = wp.zeros((3 * len(carried), mu.shape[1]), dtype=f64, device=self.model.topology.device)
        rows = [(mu[3 * j + 3 : 3 * j + 6], held[3 * i : 3 * i + 3]) for i, j in enumerate(before)]
        return [
            lambda: [wp.copy(h, m) for m, h in rows],
            lambda: [wp.copy(mu[3 * i + 3 : 3 * i + 6], h) for i, (_, h) in enumerate(rows)],
        ]

    def _check_parts(self) -> None:
        """An F over a part (``rhs_part``) writes its part's nodes alone, so it is reversed as a whole
        overwrite only where nothing but F over that part writes its array (its other nodes zero
        from the start: ``steppers.local.LevelSplit``, MRAB3's histories); ``ArgumentError`` else."""
        for op in self.tape.ops:
            if isinstance(op, Evaluate) and op.part is not None:
                out = op.updates[0].out
                if any(
                    not (isinstance(other, Evaluate) and other.part is op.part)
                    and any(self._overlaps(out, w) for w in written_by(other))
                    for other in self.tape.ops
                ) or self._overlaps(out, self.work):
                    raise ArgumentError("the tape met rhs_part into an array that other operations write")

    def _adjoint(self, a):
        """The adjoint (rows, N) of the twin's array or row view ``a``: a view of a whole (3, N)
        array's, or one of its own shape (made for an array met first, a constant's never read)."""
        rowbytes = a.strides[0]
        for base, m in self._bases:
            offset = a.ptr - base.ptr
            if base.strides == a.strides and 0 <= offset < base.shape[0] * rowbytes and offset % rowbytes == 0:
                r0 = offset // rowbytes
                if r0 + a.shape[0] > base.shape[0]:
                    break
                return m[r0 : r0 + a.shape[0]]
        m = self._mu.get(array_key(a))
        if m is None:
            m = self._mu[array_key(a)] = wp.zeros(a.shape, dtype=f64, device=self.model.topology.device)
        self._bases.append((a, m))
        return m

    def _launches(self, out, terms) -> list:
        return [launch.launch for launch in self.combinations.combination(out, terms)]

    def _scale(self, m, c: float) -> list:
        """m ← c·m: nothing for c = 1, a fill for c = 0."""
        return [] if c == 1.0 else [m.zero_] if c == 0.0 else self._launches(m, [(c, m)])

    @staticmethod
    def _overlaps(a, b) -> bool:
        return a.ptr < b.ptr + b.shape[0] * b.strides[0] and b.ptr < a.ptr + a.shape[0] * a.strides[0]

    def _combination(self, op) -> list:
        """out = Σ c·x reversed (at its listed nodes alone where it has ``nodes``, ``lincomb_at``'s four
        terms padded with zeros): μ_x += c μ_out for the x that are not out, μ_out ← c_out μ_out."""
        m_out, actions, own = self._adjoint(op.out), [], 0.0

        def write(m, terms) -> list:
            if op.nodes is None:
                return self._launches(m, terms)
            terms = [*terms, *((0.0, m_out),) * (4 - len(terms))]
            return [self.model.launches.lincomb_at(m, terms, op.nodes).launch]

        for c, a in op.terms:
            if array_key(a) == array_key(op.out):
                own += c
            elif self._overlaps(a, op.out):
                raise ArgumentError("the tape met a combination whose output overlaps a term in part")
            elif c != 0.0:
                m_a = self._adjoint(a)
                actions += write(m_a, [(1.0, m_a), (c, m_out)])
        if op.nodes is None:
            return actions + self._scale(m_out, own)
        return actions + (write(m_out, [(own, m_out)]) if own != 1.0 else [])

    def _evaluation(self, kbar, op) -> list:
        """An F's, L's, G's or D's reverse (module doc): its updates' combinations reversed, last
        first, its share summed into k̄ (rows 0–2 for F and L, 0–1 for G, 2 for D), then μ_x +=
        (its transpose) k̄. Where every update of F or L writes all rows of a whole array of its
        own that no later update reads, k̄ is the updates' adjoints as they stand before their
        reverses: the transpose reads them so, and only its DSS waits for the combinations."""
        single = self._single(op)
        if single is not None:
            return single
        updates, outs = op.updates, [u.out for u in op.updates]
        krows = slice(0, 2) if isinstance(op, Gradient) else slice(2, 3) if isinstance(op, Divergence) else slice(0, 3)
        direct = (
            isinstance(op, (Evaluate, Linear))
            and all(u.rows is None and u.out.shape[0] == 3 for u in updates)
            and not any(
                self._overlaps(o, p) or any(s is not None and self._overlaps(o, s) for _, s in later.terms)
                for j, o in enumerate(outs)
                for p, later in zip(outs[j + 1 :], updates[j + 1 :])
            )
        )
        kterms = [(a, self._adjoint(u.out)) for u in updates for a, src in u.terms if src is None] if direct else []
        actions = self._transpose(op, kterms)
        started = False
        for u in reversed(updates):
            out, kb = (u.out, kbar[krows]) if u.rows is None else (u.out[u.rows], kbar[u.rows])
            m_out, own = self._adjoint(out), 0.0
            for a, src in u.terms:
                if src is None:
                    if direct:
                        continue
                    if not started and kb.shape == kbar[krows].shape:
                        actions += self._launches(kb, [(a, m_out)])
                    else:
                        if not started:
                            actions.append(kbar.zero_)
                        actions += self._launches(kb, [(1.0, kb), (a, m_out)])
                    started = True
                elif array_key(src) == array_key(u.out):
                    own += a
                elif a != 0.0:
                    m_src = self._adjoint(src if u.rows is None else src[u.rows])
                    actions += self._launches(m_src, [(1.0, m_src), (a, m_out)])
            actions += self._scale(m_out, own)
        if started:
            actions += self._transpose(op, [(1.0, kbar)])
        if started or kterms:
            actions += self._gather(op)
        return actions

    def _single(self, op) -> list | None:
        """An F's or L's lone update, out = c_out·out + c·s + a·F (an explicit stage's; either
        array term may be absent), reversed inside the DSS its transpose needs anyway (two updates
        of one pass, ``Topology.dss_update``): μ_s += c μ_out beside μ_x += R Q x̄, then μ_out ←
        c_out μ_out, or, where out is x itself, μ_s += c μ_x before μ_x ← c_out μ_x + R Q x̄. None
        for another op (``_evaluation``'s general path)."""
        if not isinstance(op, (Evaluate, Linear)) or len(op.updates) != 1:
            return None
        (u,) = op.updates
        forced = [a for a, src in u.terms if src is None]
        arrays = [(c, src) for c, src in u.terms if src is not None]
        others = [(c, src) for c, src in arrays if array_key(src) != array_key(u.out)]
        if u.rows is not None or u.out.shape[0] != 3 or len(forced) != 1 or len(others) > 1 or len(arrays) > 2:
            return None
        if any(self._overlaps(src, u.out) for c, src in others):
            raise ArgumentError("the tape met a combination whose output overlaps a term in part")
        m_out, m_x = self._adjoint(u.out), self._adjoint(op.x)
        own = sum(c for c, src in arrays if array_key(src) == array_key(u.out))
        others = [(c, self._adjoint(src)) for c, src in others]
        tail = []
        if array_key(op.x) == array_key(u.out):  # μ_s += c μ_x, then μ_x ← c_out μ_x + R Q x̄
            last = (m_x, ((own, m_x), (1.0, None)) if own else ((1.0, None),))  # c_out 0: R Q x̄ alone, no read
            updates = [*((m_s, ((1.0, m_s), (c, m_x))) for c, m_s in others), last]
        elif others and others[0][1].ptr == m_x.ptr and others[0][1].shape == m_x.shape:  # s is x
            updates = [(m_x, ((1.0, m_x), (others[0][0], m_out), (1.0, None)))]
            if own not in (0.0, 1.0):
                updates.append((m_out, ((own, m_out),)))
            else:
                tail = self._scale(m_out, own)
        else:
            updates = [(m_x, ((1.0, m_x), (1.0, None))), *((m_s, ((1.0, m_s), (c, m_out))) for c, m_s in others)]
            tail = self._scale(m_out, own)
        dss = self.model.topology.dss_update(self.xbar, updates, weighted=False)
        return self._transpose(op, [(forced[0], m_out)]) + [launch.launch for launch in dss] + tail

    def _transpose(self, op, kbar) -> list:
        """The transpose's first part on k̄ = Σ c·a over ``kbar``, with ``parameters`` g's and Ω's
        sums first: x̄ = (F's or L's transpose) W k̄ into ``xbar``, or for G (D) −D k̄ (−G k̄) into a
        work array (in the mass form D and −G are each other's transposes: ``GravityTranspose``)."""
        if not kbar:
            return []
        actions, m = [], self.model
        if self.parameters and not isinstance(op, Divergence):
            actions.append(self._planet(op, kbar))
        if isinstance(op, Linear):
            launches = self._gravity_of(op.operator).transpose(self.tendency, kbar)
        elif isinstance(op, Evaluate):
            launches = self.tendency.transpose(op.state, kbar, op.terms, None if op.part is None else op.part.exact)
        else:
            (c, k), t = kbar[0], self._work()
            if len(kbar) > 1 or c != 1.0:
                raise ArgumentError("the tape met G or D read as a combination")  # (``_evaluation`` sums k̄ first)
            if isinstance(op, Gradient):
                return actions + [lambda: m.operators.divergence_update(k, [Update(t[2:3], ((-1.0, None),))])]
            return actions + [lambda: m.operators.gradient_update(k, 2, [Update(t[0:2], ((-1.0, None),))])]
        return actions + [launch.launch for launch in launches]

    def _gather(self, op) -> list:
        """The transpose's last part, after the updates' combinations: μ_x += R Q x̄ by the unweighted
        DSS, or for G (D) μ_x[row] (μ_x's wind) += the work array's."""
        if isinstance(op, (Evaluate, Linear)):
            m_x = self._adjoint(op.x)
            dss = self.model.topology.dss_update(self.xbar, [(m_x, ((1.0, m_x), (1.0, None)))], weighted=False)
            return [launch.launch for launch in dss]
        t = self._work()
        rows, src = (slice(op.row, op.row + 1), t[2:3]) if isinstance(op, Gradient) else (slice(0, 2), t[0:2])
        m_x = self._adjoint(op.x[rows])
        return self._launches(m_x, [(1.0, m_x), (1.0, src)])

    def _work(self):
        if self._transposed is None:
            self._transposed = self._zeros(3)
        return self._transposed

    def _planet(self, op, kbar):
        """With ``parameters``, g's and Ω's sums of an F, L or G whose adjoint is Σ c·a over ``kbar``
        (``PlanetSums.add``: L's g term its wind rows' −g G h, G's a g-proportional coefficient)."""
        if isinstance(op, Evaluate):
            state, part, g_terms, rotation = (
                op.state,
                op.part,
                tuple(t for t in self.g_terms if t in op.terms),
                "coriolis" in op.terms,
            )
        else:
            state, part, g_terms, rotation = op.state, None, ("pressure_gradient",), False
            if isinstance(op, Gradient):
                if op.row != 2:
                    raise ArgumentError("the tape's gravity sums read G of a depth row")
                kbar = [(-c / self.model.g, a) for c, a in kbar]
        return lambda: self.planet.add(state, kbar, g_terms, rotation, part)

    def _gravity_of(self, operator, solves: bool = False):
        """L's transposes (``GravityWaveOperator.transpose``); for a solve's (``solves``) with a
        Helmholtz solver of their own (the model's ``implicit_inverse`` with the twin's options: its
        ``tol`` and ``maxiter``)."""
        key = (id(operator), solves)
        gravity = self._gravity.get(key)
        if gravity is None:
            solver = self.model.implicit_inverse(self.twin.options, operator, warm=True) if solves else None
            gravity = self._gravity[key] = operator.transpose(solver)
        return gravity

    def _solve(self, op) -> list:
        """z = A_a⁻¹ (s·r), L z = (z − s·r)/a reversed (module doc), through work arrays t and w."""
        if self._solving is None:
            self._solving = (self._zeros(3), self._zeros(3))
        t, w = self._solving
        gravity = self._gravity_of(op.solver.operator, solves=True)
        m_z, m_r, a, s = self._adjoint(op.z), self._adjoint(op.r), op.a, op.scale
        m_w = None if op.implicit is None else self._adjoint(op.implicit)
        actions = self._launches(t, [(1.0, m_z), *([] if m_w is None else [(1.0 / a, m_w)])])
        if m_w is not None:
            actions += self._launches(w, [(1.0, m_w)]) + [m_w.zero_]
        actions += [m_z.zero_, lambda: gravity.solve(t, a)]
        return actions + self._launches(m_r, [(1.0, m_r), (s, t), *([] if m_w is None else [(-s / a, w)])])

    def _smoothing_action(self, op):
        """The ∇⁴ over its span reversed in place on μ_x (with ``parameters`` its sums from the state before it)."""
        transpose = self._smoothing.get(op.dt)
        if transpose is None:
            shared = next(iter(self._smoothing.values()), None)
            transpose = self._smoothing[op.dt] = self.model.hv.transpose(self.tendency, op.dt, shared)
        m_x, before = self._adjoint(op.x), op.state
        if not self.parameters:
            return lambda: transpose.transpose(m_x)
        return lambda: transpose.transpose(m_x, lambda out: wp.copy(out, before), self.d_nu, self.d_hs)

    def _zeros(self, rows: int):
        return wp.zeros((rows, self.model.topology.N), dtype=f64, device=self.model.topology.device)

    def hs_gradient(self) -> np.ndarray:
        """∂J/∂hs (N,) on this rank's nodes, continuous (mass form, as μ), summed over the steps reversed so far:
        the ∇⁴'s share and the forcing's (``TendencyTranspose.forcing_transpose`` of f̄)."""
        out = self.d_hs.numpy()[0]
        if not self.terms or "topography" not in self.model.terms:
            return out
        return out + self.tendency.forcing_transpose()
