"""How many ∇⁴ evaluations a step of Δt takes: forward-Euler substeps or the stages of an RKL1
super-step (Meyer, Balsara & Aslam 2014), chosen from the stiffness ν Δt λ (HOMME's
``hypervis_subcycle`` substeps, with RKL1 where it needs fewer). Read by ``Hyperviscosity``'s
plan and by a scene's step rule before any model is built (``config.step_rule``)."""

import math


def forward_euler_substeps(stiffness: float, subcycle: int) -> int:
    """Forward-Euler substeps of the ∇⁴ over dt, ``stiffness`` = ν dt λ (max(ν, ν_div, ν_s)
    and λ the ∇⁴'s spectral radius): at least ``subcycle``, and enough that ν (dt/n) λ ≤ 1.5."""
    return max(subcycle, math.ceil(stiffness / 1.5))


def rkl1_stages(stiffness: float) -> int:
    """RKL1 stages s over dt at ``stiffness`` = ν dt λ: the fewest (≥ 2) whose stability
    interval, (s² + s)/2 forward-Euler limits (Meyer, Balsara & Aslam 2014, §3), covers
    ν dt λ / 1.5 (the same 1.5/2 margin as the substeps)."""
    return max(2, math.ceil((math.sqrt(1.0 + 8.0 * stiffness / 1.5) - 1.0) / 2.0 - 1e-12))


def evaluations(stiffness: float, subcycle: int) -> tuple[int, bool]:
    """(∇⁴ evaluations, RKL1?) of one ``Hyperviscosity.apply`` over dt at ``stiffness`` = ν dt
    λ: the forward-Euler substeps, or the RKL1 stages where those are fewer and the substeps
    are set by stability, not by ``subcycle``."""
    n, s = forward_euler_substeps(stiffness, subcycle), rkl1_stages(stiffness)
    return (s, True) if s < n and n > subcycle else (n, False)
