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
        name="ssprk3",
        order=3,
        description="""Three-stage, third-order strong-stability-preserving Runge–Kutta in
        Shu–Osher form (Shu & Osher 1988, eq. 2.18). 3 RHS evaluations per step.""",
        A=((0, 0, 0), (1, 0, 0), ("1/4", "1/4", 0)),
        b=("1/6", "1/6", "2/3"),
        c=(0, 1, "1/2"),
    ),
    "rk4": dict(
        name="rk4",
        order=4,
        description="Classical fourth-order Runge–Kutta (Kutta 1901). 4 RHS evaluations per step.",
        A=((0, 0, 0, 0), ("1/2", 0, 0, 0), (0, "1/2", 0, 0), (0, 0, 1, 0)),
        b=("1/6", "1/3", "1/3", "1/6"),
        c=(0, "1/2", "1/2", 1),
    ),
    "kgu35": dict(
        name="kgu35",
        order=3,
        description="""HOMME's ``tstep_type = 5`` (E3SM ``prim_advance_mod``; Kinnmark & Gray 1984
        in Ullrich's five-stage third-order form): u1 = u0 + Δt/5 f(u0),
        u2 = u0 + Δt/5 f(u1), u3 = u0 + Δt/3 f(u2), u4 = u0 + 2Δt/3 f(u3),
        u5 = (5u1 − u0)/4 + 3Δt/4 f(u4) = u0 + Δt/4 f(u0) + 3Δt/4 f(u4). Third order
        (measured 3 on TC6), imaginary-axis limit √15 ≈ 3.87 against RK4's 2.83.
        5 RHS evaluations per step.""",
        A=((0,) * 5, ("1/5", 0, 0, 0, 0), (0, "1/5", 0, 0, 0), (0, 0, "1/3", 0, 0), (0, 0, 0, "2/3", 0)),
        b=("1/4", 0, 0, 0, "3/4"),
        c=(0, "1/5", "1/5", "1/3", "2/3"),
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
        name="ARS(2,3,2)",
        order=2,
        A_E=((0, 0, 0), (_G2, 0, 0), (_D2, 1.9428090415820636, 0)),
        A_I=((0, 0, 0), (0, _G2, 0), (0, _1G2, _G2)),
        b_E=(0, _1G2, _G2),
        b_I=(0, _1G2, _G2),
        c=(0, _G2, 1.0),
    ),
    "ars343": dict(
        name="ARS(3,4,3)",
        order=3,
        A_E=(
            (0, 0, 0, 0),
            (_G3, 0, 0, 0),
            (0.3212788860286271, 0.39665437472560217, 0, 0),
            (-0.10585829607187969, _A42, _A42, 0),
        ),
        A_I=((0, 0, 0, 0), (0, _G3, 0, 0), (0, 0.2820667392457705, _G3, 0), (0, _B1, _B2, _G3)),
        b_E=(0, _B1, _B2, _G3),
        b_I=(0, _B1, _B2, _G3),
        c=(0, _G3, 0.7179332607542293, 1.0),
    ),
}

# Multirate tables (``multirate.Mri``), as a scene's ``[mri]`` table: s inner solves, the r-th
# (0-based) producing stage Y_{r+2} from Y_1 = x(n) … Y_{r+1}; alpha, beta, gamma (and beta1)
# s × s, lower triangular with the diagonal, column j standing for Y_{j+1}. MIS (Wensch, Knoth
# & Galant 2009, BIT 49, 449, eq. 2.3; Knoth & Wensch 2014, Comput. Math. Appl. 67, 1124):
# their α_ij, γ_ij (i = 2..s+1, j = 2..i−1) and β_ij (j = 1..i−1), the rows of their Y_1 dropped,
# α and γ's first column (Y_1 − x(n) = 0) zero. MIS2 and MIS3C as printed (12 digits); MIS4a
# with the authors' corrected β₅₁ (as ClimaTimeSteppers.jl). MRI-GARK (Sandu 2019, SIAM J.
# Numer. Anal. 57, 2300, Definition 2.2 and §8.1.1, "MRI-GARK-ERK33a", δ = −1/2): beta = Γ⁰,
# beta1 = Γ¹, each solve starting from the last stage (alpha the identity), gamma zero.
MULTIRATE = {
    "mis2": dict(
        name="MIS2",
        order=2,
        description="Wensch, Knoth & Galant 2009: 3 slow stages, second order",
        alpha=((0, 0, 0), (0, 0.536946566710, 0), (0, 0.480892968551, 0.500561163566)),
        beta=(
            (0.126848494553, 0, 0),
            (-0.784838278826, 1.37442675268, 0),
            (-0.0456727081749, -0.00875082271190, 0.524775788629),
        ),
        gamma=((0, 0, 0), (0, 0.652465126004, 0), (0, -0.0732769849457, 0.144902430420)),
    ),
    "mis3c": dict(
        name="MIS3C",
        order=2,
        description="Knoth & Wensch 2014: 3 slow stages, second order (its slow table third)",
        alpha=((0, 0, 0), (0, 0.589557277145, 0), (0, 0.544036601551, 0.565511042564)),
        beta=(
            (0.397525189225, 0, 0),
            (-0.227036463644, 0.624528794618, 0),
            (-0.00295238076840, -0.270971764284, 0.671323159437),
        ),
        gamma=((0, 0, 0), (0, 0.142798786398, 0), (0, -0.0428918957402, 0.0202720980282)),
    ),
    "mis4a": dict(
        name="MIS4a",
        order=3,
        description="Knoth & Wensch 2014: 4 slow stages, third order, a larger stability region",
        alpha=(
            (0, 0, 0, 0),
            (0, 0.52349249922385610, 0, 0),
            (0, 1.1683374366893629, -0.75762080241712637, 0),
            (0, -0.036477233846797109, 0.56936148730740477, 0.47746263002599681),
        ),
        beta=(
            (0.38758444641450318, 0, 0, 0),
            (-0.025318448354142823, 0.38668943087310403, 0, 0),
            (0.20899983523553325, -0.45856648476371231, 0.43423187573425748, 0),
            (-0.10048822195663100, -0.46186171956333327, 0.83045062122462809, 0.27014914900250392),
        ),
        gamma=(
            (0, 0, 0, 0),
            (0, 0.13145089796226542, 0, 0),
            (0, -0.36855857648747881, 0.33159232636600550, 0),
            (0, -0.065767130537473045, 0.040591093109036858, 0.064902111640806712),
        ),
    ),
    "mri_gark_erk33a": dict(
        name="MRI-GARK-ERK33a",
        order=3,
        description="Sandu 2019: 3 slow stages, third order, coupling linear in time",
        alpha=((1, 0, 0), (0, 1, 0), (0, 0, 1)),
        beta=(("1/3", 0, 0), ("-1/3", "2/3", 0), (0, "-2/3", 1)),
        beta1=((0, 0, 0), (0, 0, 0), ("1/2", 0, "-1/2")),
    ),
}
