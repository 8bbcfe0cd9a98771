"""The adjoint of one step of the forward–backward FB-RK(3,2) (``steppers.explicit.FBRK32``):
its three stages, each the continuity half then the momentum half, then the split ∇⁴.

The step's map, x(n) = (u_n, h_n) = Z_0, stage i = 0, 1, 2 with c_i, β_i the stepper's:
    h_(i+1) = h_n + c_i Δt F_h(Z_i),
    h̃_i = h_n + β_i c_i Δt F_h(Z_i) (i < 2),  h̃_2 = 2β_2 h_n + β_2 Δt F_h(Z_2) + (1 − 2β_2) h_2,
    S_i = (u_i, h̃_i),  u_(i+1) = u_n + c_i Δt F_u(S_i),  Z_(i+1) = (u_(i+1), h_(i+1)),
and x(n+1) = H(Z_3). F_h is the continuity half (the depth row), F_u the momentum half (the wind
rows). Reversed with the adjoints μ = R Q λ of ``explicit`` (the mass form): each half's
transpose is the tendency's of its own terms (``TendencyTranspose.transpose``), read with a k̄ whose
other rows are zero.
"""

from __future__ import annotations

from ..core.errors import ArgumentError
from ..model.launches import Update
from ..model.shallow_water import ShallowWater
from .explicit import StepAdjoint


class ForwardBackwardAdjoint(StepAdjoint):
    """The adjoint of one FB-RK(3,2) step of ``model`` at Δt = ``dt`` (s), the stepper's
    c, β and halves (``stepper``: an ``FBRK32``, its ``fbrk()``); otherwise as ``StepAdjoint`` (``reverse``,
    ``parameters``: ∂J/∂ν, ν_s, hs, g and Ω; a forcing's stages at their times). ``ArgumentError`` for a model without
    momentum terms (its wind a combination alone), and as ``StepAdjoint``.

    Work arrays (3, N) held: Z_0…Z_3, S_0…S_2, the continuity half's k̄, the momentum half's
    DSS'd x̄, two for the Z̄, one for x̄(n)'s direct terms and a forcing's wind: fourteen, with (2, N) f̄."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        self._setup(model, dt, parameters, t0)
        steps = stepper.fbrk()
        if not steps.momentum:
            raise ArgumentError("fbrk32's adjoint needs the momentum terms")
        self.continuity, self.momentum = steps.continuity, steps.momentum
        self.C, self.BETA = tuple(steps.c), tuple(steps.beta)
        zeros = self._zeros
        self.Z = [zeros(3) for _ in range(4)]
        self.x = self.Z[0]
        self.S = [zeros(3) for _ in range(3)]
        self.kh, self.su = zeros(3), zeros(3)  # the continuity half's k̄, R Q x̄ of the momentum half's
        self.zbar = [zeros(3), zeros(3)]
        self.acc = zeros(3)  # x̄(n)'s terms from u_n and h_n in the stages' combinations
        self.forcing_wind = zeros(3)  # a forcing's wind rows (the continuity half's): x's, not the adjoint's
        self._for_dt()

    def _stage_plan(self, zeros) -> None:
        """None: ``stages`` forms the stages with the Δt of the step."""

    def stages(self, k: int = 0) -> None:
        """Z_1…Z_3 and S_0…S_2 of step k from x = Z_0, as the stepper forms them (``FBRK32``:
        each half's combinations written by its DSS, the same sums in the same order; a
        forcing's wind rows, which the continuity half holds, in ``kh`` and added to the wind;
        each stage at the stepper's time, t0 + (k + c_(i−1))·Δt)."""
        m, dt, x, Z, S = self.model, self.dt, self.x, self.Z, self.S
        U, H = slice(0, 2), slice(2, 3)
        forced = "forcing" in self.continuity
        self.combine(S[0][U], [(1.0, x[U])])
        for i, (c, beta) in enumerate(zip(self.C, self.BETA)):
            last = i == len(self.C) - 1
            m.set_time(self.t0 + (k + (self.C[i - 1] if i else 0.0)) * dt)
            tilde = (
                ((2 * beta, x), (beta * c * dt, None), (1 - 2 * beta, Z[i]))
                if last
                else ((1.0, x), (beta * c * dt, None))
            )
            depth = (Update(self.forcing_wind, ((1.0, None),), U),) if forced else ()
            depth += (Update(S[i], tilde, H), Update(Z[i + 1], ((1.0, x), (c * dt, None)), H))
            m.rhs_update(Z[i], depth, self.continuity)
            wind = ((1.0, x), *(((c * dt, self.forcing_wind),) if forced else ()), (c * dt, None))
            m.rhs_update(
                S[i], (Update(Z[i + 1], wind, U), *(() if last else (Update(S[i + 1], wind, U),))), self.momentum
            )

    def before_hyperviscosity(self, out) -> None:
        self.combine(out, [(1.0, self.Z[3])])

    def _record(self, mu) -> list:
        """The stages' transposes, last first, as (Y, k̄'s terms or None, launches) segments
        (``reverse``: the parameters' sums read the momentum halves' (S_i, k̄_u)); Z̄ = μ of
        Z_3 first, μ ← x̄(n) last (module doc). Each half's transpose reads only its own rows
        of k̄ (its terms' outputs), so k̄_u is read as cΔt Z̄_(i+1) itself and k̄_h is written
        whole by the momentum half's DSS, its wind rows unread; the DSS's also write the
        running sums: acc, x̄(n)'s direct terms (the u_n and h_n of each combination), and Z̄_i."""
        m, dt, topo = self.model, self.dt, self.model.topology
        H = slice(2, 3)
        cur, segments = mu, [(None, None, [m.lincomb(self.acc, [(1.0, mu)])])]
        for i in reversed(range(len(self.C))):
            c, beta, last, nxt = self.C[i], self.BETA[i], i == len(self.C) - 1, self.zbar[i % 2]
            ku = [(c * dt, cur)]  # k̄_u = cΔt ū_(i+1)
            launches = self.tendency.transpose(self.S[i], ku, self.momentum)
            # S̄_i = R Q x̄: its wind Z_i's; its depth h̃_i's, into k̄_h = cΔt h̄_(i+1) + βcΔt h̃̄_i, h̄_n, h̄_2
            kh = (self.kh, ((c * dt, cur), (beta * c * dt, None)))
            launches += topo.dss_update(self.xbar, [kh, (self.su, ((1.0, None),))], weighted=False)
            launches.append(m.lincomb(self.acc[H], [(1.0, self.acc[H]), (2 * beta if last else 1.0, self.su[H])]))
            launches.append(m.lincomb(self.su[H], [((1 - 2 * beta) if last else 0.0, self.su[H])]))
            segments.append((self.S[i], ku, launches))
            launches = self.tendency.transpose(self.Z[i], [(1.0, self.kh)], self.continuity)
            total = (1.0, self.acc), (1.0, self.su), (1.0, None)  # acc += Z̄_i: ū_i, h̄_i (stage i − 1's own)
            if i:  # Z̄_i = S̄_i's (the wind, and h̄_2's share of h̃_2) + F_hᵀ's
                launches += topo.dss_update(self.xbar, [(nxt, ((1.0, self.su), (1.0, None))), (self.acc, total)], False)
            else:  # x̄(n) = acc + Z̄_0
                launches += topo.dss_update(self.xbar, [(mu, total)], weighted=False)
            segments.append((None, None, launches))
            cur = nxt
        return segments
