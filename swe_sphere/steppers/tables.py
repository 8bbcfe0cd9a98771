"""The built-in Runge–Kutta tables, as data: the explicit steppers ``ssprk3``,
``rk4``, ``kgu35`` and the IMEX pairs of ``imex`` (``scheme``), each a
``[tableau]`` table (``butcher.TableauOptions``' parts, entries numbers or
fractions as strings), checked by ``butcher.parse`` as a user's table is and
stepped by the same engine (``runge_kutta``).

The explicit tables' ``description`` is the stepper's summary (``swe-sphere list``);
``COURANT_LIMITS`` are their measured limits (``Stepper.courant_limit``).

ARS pairs (Ascher, Ruuth & Spiteri 1997, Appl. Numer. Math. 25, 151): the entries
are the float64 values of the closed forms below (printed with 17 digits, so
they read back as the same floats), c the explicit part's row sums; the
first stage is x(n) (A_I's first row and column zero), b_E = b_I = A_I's last row.
"""

from __future__ import annotations

EXPLICIT = {
    "ssprk3": dict(
        name="ssprk3", order=3,
        description="""Three-stage, third-order strong-stability-preserving Runge–Kutta in
        Shu–Osher form (Shu & Osher 1988, eq. 2.18). 3 RHS evaluations per step.""",
        A=((0, 0, 0), (1, 0, 0), ("1/4", "1/4", 0)), b=("1/6", "1/6", "2/3"), c=(0, 1, "1/2"),
    ),
    "rk4": dict(
        name="rk4", order=4,
        description="Classical fourth-order Runge–Kutta (Kutta 1901). 4 RHS evaluations per step.",
        A=((0, 0, 0, 0), ("1/2", 0, 0, 0), (0, "1/2", 0, 0), (0, 0, 1, 0)), b=("1/6", "1/3", "1/3", "1/6"), c=(0, "1/2", "1/2", 1),
    ),
    "kgu35": dict(
        name="kgu35", order=3,
        description="""HOMME's ``tstep_type = 5`` (E3SM ``prim_advance_mod``; Kinnmark & Gray 1984
        in Ullrich's five-stage third-order form): u1 = u0 + Δt/5 f(u0),
        u2 = u0 + Δt/5 f(u1), u3 = u0 + Δt/3 f(u2), u4 = u0 + 2Δt/3 f(u3),
        u5 = (5u1 − u0)/4 + 3Δt/4 f(u4) = u0 + Δt/4 f(u0) + 3Δt/4 f(u4). Third order
        (measured 3 on TC6), imaginary-axis limit √15 ≈ 3.87 against RK4's 2.83.
        5 RHS evaluations per step.""",
        A=((0,) * 5, ("1/5", 0, 0, 0, 0), (0, "1/5", 0, 0, 0), (0, 0, "1/3", 0, 0), (0, 0, 0, "2/3", 0)),
        b=("1/4", 0, 0, 0, "3/4"), c=(0, "1/5", "1/5", "1/3", "2/3"),
    ),
}

# the largest stable (|v| + sqrt(g h)) Δt / Δx (``Stepper.courant_limit``)
COURANT_LIMITS = {
    "ssprk3": 1.11,
    "rk4": 1.73,
    "kgu35": 2.32,  # bisection on TC2 (5 days) at ne 8 np 4 only: 1.34 × rk4's there
}

# ARS(2,3,2), §2.5: γ = 1 − 1/√2, δ = −2√2/3; second order
_G2, _D2, _1G2 = 0.29289321881345254, -0.9428090415820635, 0.7071067811865475  # γ, δ, 1 − γ
# ARS(3,4,3), §2.7: γ the root 0.4358665215… of 6γ³ − 18γ² + 9γ − 1 = 0 (L-stable SDIRK3),
# b = (0, β₁, β₂, γ), β₁ = −3γ²/2 + 4γ − 1/4, β₂ = 3γ²/2 − 5γ + 5/4, A_I₃₂ = (1 − γ)/2;
# Â₄₂ = Â₄₃ = 0.5529291480359398, Â₄₁ = 1 − 2Â₄₂, Â₃₁ and Â₃₂ from the third-order conditions
# (the paper prints them to 10 digits; ClimaTimeSteppers' closed forms); third order
_G3, _B1, _B2, _A42 = 0.435866521508459, 1.20849664917601, -0.6443631706844692, 0.5529291480359398
IMEX = {
    "ars232": dict(
        name="ARS(2,3,2)", order=2,
        A_E=((0, 0, 0), (_G2, 0, 0), (_D2, 1.9428090415820636, 0)),
        A_I=((0, 0, 0), (0, _G2, 0), (0, _1G2, _G2)),
        b_E=(0, _1G2, _G2), b_I=(0, _1G2, _G2), c=(0, _G2, 1.0),
    ),
    "ars343": dict(
        name="ARS(3,4,3)", order=3,
        A_E=((0, 0, 0, 0), (_G3, 0, 0, 0), (0.3212788860286271, 0.39665437472560217, 0, 0), (-0.10585829607187969, _A42, _A42, 0)),
        A_I=((0, 0, 0, 0), (0, _G3, 0, 0), (0, 0.2820667392457705, _G3, 0), (0, _B1, _B2, _G3)),
        b_E=(0, _B1, _B2, _G3), b_I=(0, _B1, _B2, _G3), c=(0, _G3, 0.7179332607542293, 1.0),
    ),
}
