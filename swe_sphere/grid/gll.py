"""Gauss–Lobatto–Legendre (GLL) points, weights and derivative matrix on [-1, 1].

Source: Canuto, Hussaini, Quarteroni & Zang (2006), Spectral Methods, §2.3
(eqs. 2.3.12–2.3.13 for nodes and weights, eq. 2.4.34 for the collocation
derivative); HOMME's ``quadrature_mod::gausslobatto`` and ``derivative_mod::dvv``.
Each value is computed in 40-digit decimal arithmetic and rounded once to float64
(``_DIGITS``): numpy's roots of P_N' are a few ulps off (1.5e-15 at np 8), which put
dvv's entries up to 2.3e-13 off, so that a row's sum, the derivative of a constant,
was 2.3e-13 (np 8; 1.3e-15 at np 4) and the continuity's element tendencies integrated to a
steady 0.015 ε of the mass a step on TC2 ne8 np4 (0 with the rule correctly rounded).
"""

from __future__ import annotations

import decimal
import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre

NP_MIN, NP_MAX = 2, 8


@dataclass(frozen=True)
class GLL:
    """GLL rule with ``np`` points.

    Attributes
    ----------
    points : (np,) float64, ascending, points[0] = -1, points[-1] = 1.
    weights : (np,) float64, sum = 2; exact for polynomials of degree ≤ 2np − 3.
    dvv : (np, np) float64, ``dvv[i, m] = l_m'(points[i])`` with ``l_m`` the
        Lagrange basis polynomial of node m: ``(dvv @ f)[i] = f'(points[i])``
        exactly for polynomials f of degree < np.
    """

    np: int
    points: np.ndarray
    weights: np.ndarray
    dvv: np.ndarray


def gll(np_: int) -> GLL:
    """Build the ``np_``-point GLL rule (2 ≤ np_ ≤ 8).

    Raises ``ValueError`` for np_ outside 2..8.
    """
    if not NP_MIN <= np_ <= NP_MAX:
        raise ValueError(f"np must be in {NP_MIN}..{NP_MAX} (got {np_})")
    n = np_ - 1
    interior = np.sort(legendre.Legendre.basis(n).deriv().roots().real) if n > 1 else np.empty(0)
    with decimal.localcontext(prec=_DIGITS):
        roots = [_root(n, decimal.Decimal(float(r))) for r in interior]
        roots = [(r - s) / 2 for r, s in zip(roots, reversed(roots))]  # symmetric about 0: a middle point is 0
        x = [decimal.Decimal(-1), *roots, decimal.Decimal(1)]
        pnx = [_legendre(n, xi)[0] for xi in x]
        w = [2 / (n * (n + 1) * p * p) for p in pnx]
        d = [[pnx[i] / (pnx[j] * (x[i] - x[j])) if i != j else 0 for j in range(np_)] for i in range(np_)]
    d[0][0], d[n][n] = -n * (n + 1) / 4.0, n * (n + 1) / 4.0
    as_float = lambda values: np.array(values, dtype=float)  # noqa: E731 (each rounded once)
    return GLL(np_, as_float(x), as_float(w), as_float(d))


_DIGITS = 40  # the decimal digits GLL values are computed with before their one rounding to float64


def _legendre(n: int, x):
    """(P_n(x), P_n'(x), P_n''(x)) at a Decimal x, |x| < 1 for the derivatives (Bonnet's recurrence;
    (1 − x²) P_n' = n (P_{n−1} − x P_n), and P_n'' from Legendre's equation)."""
    p0, p1 = 1, x
    for k in range(1, n):
        p0, p1 = p1, ((2 * k + 1) * x * p1 - k * p0) / (k + 1)
    if abs(x) == 1:
        return p1, None, None
    dp = n * (p0 - x * p1) / (1 - x * x)
    return p1, dp, (2 * x * dp - n * (n + 1) * p1) / (1 - x * x)


def _root(n: int, x):
    """The root of P_n' near the Decimal x (numpy's, a few ulps of float64 off), by Newton's
    iteration to the context's precision."""
    for _ in range(50):
        _, dp, ddp = _legendre(n, x)
        step = dp / ddp
        x -= step
        if abs(step) < decimal.Decimal(10) ** (4 - _DIGITS):
            break
    return x


def truncation(np_: int) -> np.ndarray:
    """(np_, np_) matrix T: for f the values at the ``np_`` GLL points, T f the values there
    of f's interpolant with its Legendre term of degree np_ − 1 dropped, i.e. its L²
    projection onto the polynomials of degree ≤ np_ − 2; f − T f is the highest mode's part,
    the tail whose size estimates a spectral element's truncation error (Mavriplis 1994,
    J. Sci. Comput. 9:1; the "np − 1 projection"). Raises as ``gll``."""
    keep = np.ones(np_)
    keep[-1] = 0.0
    return modal(np_, keep)


def modal(np_: int, sigma) -> np.ndarray:
    """(np_, np_) matrix V diag(σ) V⁻¹, V[i, n] = P_n(x_i) the nodal values of the Legendre modes
    at the GLL points: for f the values there, the values of f's interpolant with its Legendre term
    of degree n multiplied by σ[n] (``sigma``, (np_,)). Raises as ``gll``."""
    V = legendre.legvander(gll(np_).points, np_ - 1)
    return V @ np.diag(np.asarray(sigma, dtype=float)) @ np.linalg.inv(V)


def boyd_vandeven(np_: int, mu: float, p: float = 12.0, s: float = 2.0 / 3.0) -> np.ndarray:
    """(np_, np_) matrix F = (1 − μ) I + μ V diag(σ) V⁻¹ (``modal``) of the Boyd–Vandeven (erfc-log)
    filter, HOMME's ``filter_matrix_create_inv`` with ``bv_transfer`` (``filter_mod``; Boyd 1996,
    Taylor, Tribbia & Iskandarani 1997, J. Comput. Phys. 130, 92, p. 98): the mode of degree k − 1
    (k = 1 … np_) kept where k/np_ < s, else σ = erfc(2√p·ω·√(−ln(1 − 4ω²)/(4ω²)))/2 with
    ω = (k/np_ − s)/(1 − s) − 1/2, 0 at the highest degree. ``mu`` in (0, 1] the weight of one
    application (HOMME's ``filter_mu``), ``p`` > 0 the sigmoid's order (``p_bv``), ``s`` in (0, 1)
    the lag (``s_bv``). F keeps constants: its rows sum to 1. Raises as ``gll``."""
    sigma = np.ones(np_)
    for k in range(1, np_ + 1):
        rat = k / np_
        if rat >= s:
            om = min((rat - s) / (1.0 - s), 1.0) - 0.5
            if om >= 0.5:
                sigma[k - 1] = 0.0
            elif om != -0.5:
                fac = math.sqrt(-math.log(1.0 - 4.0 * om * om) / (4.0 * om * om)) if om != 0.0 else 1.0
                sigma[k - 1] = 0.5 * math.erfc(2.0 * math.sqrt(p) * om * fac)
    return (1.0 - mu) * np.eye(np_) + mu * modal(np_, sigma)
