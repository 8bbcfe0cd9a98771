"""The built-in Runge–Kutta tables, as data: the explicit steppers ``ssprk3``,
``rk4``, ``kgu35``, the embedded pairs ``bs32``, ``dp54``, ``ssprk43``,
``rdpk3sp35``, the IMEX pairs of ``imex`` (``scheme``) and the embedded IMEX pairs
``ark324`` and ``ark436`` (``IMEX_PAIRS``, steppers of their own), each a
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

# Embedded pairs: b_hat the weights of a solution of embedded_order from the same stages, the
# step's error estimate Δt Σ (b − b_hat)_j K_j. A first-same-as-last (FSAL) pair is written with
# its last stage, F(x(n+1)), as a stage of the step (A's last row b, b's last entry 0): correct,
# one RHS a step dearer than reusing it as the next step's first.
_RDPK_B = (
    "0.114793597102354117173360132449",
    "0.0893344285311331559270838452313",
    "0.43558710250086169924837226938",
    "0.247357618820145114672972586681",
    "0.112927253045505912978211166259",
)
EXPLICIT |= {
    "bs32": dict(
        name="bs32",
        order=3,
        embedded_order=2,
        description="""Bogacki–Shampine 3(2) embedded pair, FSAL: third order with a second-order error
        estimate (Bogacki & Shampine 1989, Appl. Math. Lett. 2, 321). 4 RHS evaluations per step
        (the FSAL stage evaluated).""",
        A=((0, 0, 0, 0), ("1/2", 0, 0, 0), (0, "3/4", 0, 0), ("2/9", "1/3", "4/9", 0)),
        b=("2/9", "1/3", "4/9", 0),
        b_hat=("7/24", "1/4", "1/3", "1/8"),
        c=(0, "1/2", "3/4", 1),
    ),
    "rk43": dict(
        name="rk43",
        order=4,
        embedded_order=3,
        description="""Classical RK4 with a third-order FSAL error estimate: ``rk4``'s steps (its bits
        at a fixed Δt). F(x(n+1)) is a fifth stage with b_hat = (1/6, 1/3, 1/3, 0, 1/6), so
        e = Δt/6 (F(Y_4) − F(x(n+1))): the third-order conditions with RK4's last weight moved to
        the FSAL stage (checked by the order conditions). 4 RHS evaluations per step under error
        control (the FSAL stage is the next step's first), 5 at a fixed Δt.""",
        A=((0,) * 5, ("1/2", 0, 0, 0, 0), (0, "1/2", 0, 0, 0), (0, 0, 1, 0, 0), ("1/6", "1/3", "1/3", "1/6", 0)),
        b=("1/6", "1/3", "1/3", "1/6", 0),
        b_hat=("1/6", "1/3", "1/3", 0, "1/6"),
        c=(0, "1/2", "1/2", 1, 1),
    ),
    "kgu352": dict(
        name="kgu352",
        order=3,
        embedded_order=2,
        description="""HOMME's KGU35 with a second-order FSAL error estimate: ``kgu35``'s steps (its
        bits at a fixed Δt). F(x(n+1)) is a sixth stage and the embedded solution the trapezoidal
        rule x(n) + Δt/2 (F(x(n)) + F(x(n+1))), b_hat = (1/2, 0, 0, 0, 0, 1/2), so
        e = Δt (−F(x(n))/4 + 3F(Y_5)/4 − F(x(n+1))/2). 5 RHS evaluations per step under error
        control (the FSAL stage is the next step's first), 6 at a fixed Δt.""",
        A=(
            (0,) * 6,
            ("1/5", 0, 0, 0, 0, 0),
            (0, "1/5", 0, 0, 0, 0),
            (0, 0, "1/3", 0, 0, 0),
            (0, 0, 0, "2/3", 0, 0),
            ("1/4", 0, 0, 0, "3/4", 0),
        ),
        b=("1/4", 0, 0, 0, "3/4", 0),
        b_hat=("1/2", 0, 0, 0, 0, "1/2"),
        c=(0, "1/5", "1/5", "1/3", "2/3", 1),
    ),
    "dp54": dict(
        name="dp54",
        order=5,
        embedded_order=4,
        description="""Dormand–Prince 5(4) embedded pair, FSAL: fifth order with a fourth-order error
        estimate (Dormand & Prince 1980, J. Comput. Appl. Math. 6, 19: RK5(4)7M, MATLAB's ode45).
        7 RHS evaluations per step (the FSAL stage evaluated).""",
        A=(
            (0,) * 7,
            ("1/5", 0, 0, 0, 0, 0, 0),
            ("3/40", "9/40", 0, 0, 0, 0, 0),
            ("44/45", "-56/15", "32/9", 0, 0, 0, 0),
            ("19372/6561", "-25360/2187", "64448/6561", "-212/729", 0, 0, 0),
            ("9017/3168", "-355/33", "46732/5247", "49/176", "-5103/18656", 0, 0),
            ("35/384", 0, "500/1113", "125/192", "-2187/6784", "11/84", 0),
        ),
        b=("35/384", 0, "500/1113", "125/192", "-2187/6784", "11/84", 0),
        b_hat=("5179/57600", 0, "7571/16695", "393/640", "-92097/339200", "187/2100", "1/40"),
        c=(0, "1/5", "3/10", "4/5", "8/9", 1, 1),
    ),
    "ssprk43": dict(
        name="ssprk43",
        order=3,
        embedded_order=2,
        description="""SSPRK(4,3) with a second-order embedded error estimate: four-stage third-order
        SSP Runge–Kutta (Kraaijevanger 1991, SSP coefficient 2: three Euler steps of Δt/2, an
        average, one more) with Conde, Fekete & Shadid's 2018 (arXiv 1806.08693) embedding, the
        SSPRK(3,2) of its first three stages. 4 RHS evaluations per step.""",
        A=((0, 0, 0, 0), ("1/2", 0, 0, 0), ("1/2", "1/2", 0, 0), ("1/6", "1/6", "1/6", 0)),
        b=("1/6", "1/6", "1/6", "1/2"),
        b_hat=("1/3", "1/3", "1/3", 0),
        c=(0, "1/2", 1, "1/2"),
    ),
    # Ranocha, Dalcin, Parsani & Ketcheson 2022 (Commun. Appl. Math. Comput. 4, 1191), RDPK3SpFSAL35:
    # their 3S*+ low-storage coefficients (36 digits, as OrdinaryDiffEq.jl's
    # RDPK3SpFSAL35ConstantCache) turned into the Butcher table in exact arithmetic, here to 30 digits
    "rdpk3sp35": dict(
        name="rdpk3sp35",
        order=3,
        embedded_order=2,
        description="""RDPK3SpFSAL35 of Ranocha, Dalcin, Parsani & Ketcheson 2022: five stages, third
        order, a second-order FSAL embedding, optimised for error-controlled spectral-element and
        DG runs. 6 RHS evaluations per step (the FSAL stage evaluated).""",
        A=(
            (0,) * 6,
            ("0.230029862451807622389941828631", 0, 0, 0, 0, 0),
            ("0.102861190514670210323409604056", "0.302143416694828880903440211956", 0, 0, 0, 0),
            (
                "0.0627887262584205148075854540791",
                "0.0294329445692917459561847267896",
                "0.802560618541631093758300908587",
                0,
                0,
                0,
            ),
            (
                "0.0477155788514121837269000574229",
                "0.0363703046324337341309728634311",
                "0.203211915038468890103895714999",
                "0.436215894360344093065514824515",
                0,
                0,
            ),
            (*_RDPK_B, 0),
        ),
        b=(*_RDPK_B, 0),
        b_hat=(
            "9.484166705035703392326247283838082847e-02",
            "1.726371339430353766966762629176676070e-01",
            "3.998243189084371024483169698618455770e-01",
            "1.718016807580178450618829007973835152e-01",
            "5.881914422155740300718268359027168467e-02",
            "1.020760551185952388626787099944507877e-01",
        ),
        c=(
            0,
            "0.230029862451807622389941828631",
            "0.405004607209499091226849816012",
            "0.894782289369343354522071089456",
            "0.723513692882658901027283460368",
            1,
        ),
    ),
}

# the IMEX pairs' advective Courant limits (|v| Δt/Δx at t = 0; their gravity waves implicit),
# below the smallest stable one of the stability suite's bisections at ne 8 (Galewsky np 8, TC6
# and TC5 np 4; benchmarks/results/cli_runs/stability_imex_pairs_ne8.csv): ark324 2.71 / 2.35 / 0.88,
# ark436 1.34 / 0.84 / 1.18, as ``imex``'s 1.0 lies below ARS(3,4,3)'s 2.71 / 2.35 / 1.01 there
IMEX_ADVECTIVE_LIMITS = {"ark324": 0.85, "ark436": 0.8}

# the largest stable (|v| + sqrt(g h)) Δt / Δx (``Stepper.courant_limit``); a table missing here
# takes its stability polynomial's estimate (``runge_kutta.COURANT_PER_AXIS_LIMIT``)
COURANT_LIMITS = {
    "ssprk3": 1.11,
    "rk4": 1.73,
    "kgu35": 2.32,  # bisection on TC2 (5 days) at ne 8 np 4 only: 1.34 × rk4's there
    # the embedded pairs at a fixed Δt, the smallest of the stability suite's bisections on TC2
    # (5 days) at ne 8 np 4, ne 4 np 4 and ne 3 np 6 (docs/explanation/efficiency/error_control.md):
    # bs32 1.108 / 1.195 / 1.218, dp54 1.279 / 1.482 / 1.508, ssprk43 1.374 / 1.482 / 1.508,
    # rdpk3sp35 1.726 / 1.853 / 1.919; their stability polynomials' estimates (rk4's measured
    # limit per imaginary-axis unit) are 1.06, 0.61, 1.32 and 1.68: dp54's |R(iy)| passes 1 at
    # y = 1.0 but stays below 1.003 to y = 1.5 and 1.032 to y = 2, a growth the ∇⁴ damps
    "bs32": 1.11,
    "rk43": 1.73,  # rk4's stability polynomial (b's last weight 0): rk4's limit
    "kgu352": 2.32,  # kgu35's, likewise
    "dp54": 1.28,
    "ssprk43": 1.37,
    "rdpk3sp35": 1.73,
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

# Kennedy & Carpenter 2003 (Appl. Numer. Math. 44, 139) ARK3(2)4L[2]SA and ARK4(3)6L[2]SA: the
# ERK and ESDIRK tables (first stage explicit, then γ on the diagonal; L-stable, stiffly accurate)
# with one b and one embedded b̂ for both parts, as SUNDIALS ARKODE's ARK324L2SA_ERK_4_2_3 /
# _DIRK_4_2_3 and ARK436L2SA_ERK_6_3_4 / _DIRK_6_3_4 print them
_G324 = "1767732205903/4055673282236"
_B324 = ("1471266399579/7840856788654", "-4482444167858/7529755066697", "11266239266428/11593286722821", _G324)
_BH324 = (
    "2756255671327/12835298489170",
    "-10771552573575/22201958757719",
    "9247589265047/10645013368117",
    "2193209047091/5459859503100",
)
_B436 = ("82889/524892", 0, "15625/83664", "69875/102672", "-2260/8211", "1/4")
_BH436 = (
    "4586570599/29645900160",
    0,
    "178811875/945068544",
    "814220225/1159782912",
    "-3700637/11593932",
    "61727/225920",
)
IMEX_PAIRS = {
    "ark324": dict(
        name="ARK3(2)4L[2]SA",
        order=3,
        embedded_order=2,
        description="""IMEX ARK3(2)4L[2]SA of Kennedy & Carpenter 2003: third order, a second-order
        embedded error estimate, the gravity waves implicit; 4 stages, 3 Helmholtz solves and 4 RHS
        evaluations per step.""",
        A_E=(
            (0, 0, 0, 0),
            ("1767732205903/2027836641118", 0, 0, 0),
            ("5535828885825/10492691773637", "788022342437/10882634858940", 0, 0),
            ("6485989280629/16251701735622", "-4246266847089/9704473918619", "10755448449292/10357097424841", 0),
        ),
        A_I=(
            (0, 0, 0, 0),
            (_G324, _G324, 0, 0),
            ("2746238789719/10658868560708", "-640167445237/6845629431997", _G324, 0),
            _B324,
        ),
        b_E=_B324,
        b_I=_B324,
        b_hat_E=_BH324,
        b_hat_I=_BH324,
        c=(0, "1767732205903/2027836641118", "3/5", 1),
    ),
    "ark436": dict(
        name="ARK4(3)6L[2]SA",
        order=4,
        embedded_order=3,
        description="""IMEX ARK4(3)6L[2]SA of Kennedy & Carpenter 2003: fourth order, a third-order
        embedded error estimate, the gravity waves implicit; 6 stages, 5 Helmholtz solves and 6 RHS
        evaluations per step.""",
        A_E=(
            (0,) * 6,
            ("1/2", 0, 0, 0, 0, 0),
            ("13861/62500", "6889/62500", 0, 0, 0, 0),
            (
                "-116923316275/2393684061468",
                "-2731218467317/15368042101831",
                "9408046702089/11113171139209",
                0,
                0,
                0,
            ),
            (
                "-451086348788/2902428689909",
                "-2682348792572/7519795681897",
                "12662868775082/11960479115383",
                "3355817975965/11060851509271",
                0,
                0,
            ),
            (
                "647845179188/3216320057751",
                "73281519250/8382639484533",
                "552539513391/3454668386233",
                "3354512671639/8306763924573",
                "4040/17871",
                0,
            ),
        ),
        A_I=(
            (0,) * 6,
            ("1/4", "1/4", 0, 0, 0, 0),
            ("8611/62500", "-1743/31250", "1/4", 0, 0, 0),
            ("5012029/34652500", "-654441/2922500", "174375/388108", "1/4", 0, 0),
            ("15267082809/155376265600", "-71443401/120774400", "730878875/902184768", "2285395/8070912", "1/4", 0),
            _B436,
        ),
        b_E=_B436,
        b_I=_B436,
        b_hat_E=_BH436,
        b_hat_I=_BH436,
        c=(0, "1/2", "83/250", "31/50", "17/20", 1),
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
