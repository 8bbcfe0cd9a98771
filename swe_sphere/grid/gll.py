"""Gauss–Lobatto–Legendre (GLL) points, weights and derivative matrix on [-1, 1].

Source: Canuto, Hussaini, Quarteroni & Zang (2006), Spectral Methods, §2.3
(eqs. 2.3.12–2.3.13 for nodes and weights, eq. 2.4.34 for the collocation
derivative); HOMME's ``quadrature_mod::gausslobatto`` and ``derivative_mod::dvv``.
"""

from __future__ import annotations

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
    pn = legendre.Legendre.basis(n)
    interior = np.sort(pn.deriv().roots().real) if n > 1 else np.empty(0)
    x = np.concatenate(([-1.0], interior, [1.0]))
    pnx = pn(x)
    w = 2.0 / (n * (n + 1) * pnx**2)
    d = np.zeros((np_, np_))
    for i in range(np_):
        for j in range(np_):
            if i != j:
                d[i, j] = pnx[i] / (pnx[j] * (x[i] - x[j]))
    d[0, 0] = -n * (n + 1) / 4.0
    d[n, n] = n * (n + 1) / 4.0
    return GLL(np_, x, w, d)


def truncation(np_: int) -> np.ndarray:
    """(np_, np_) matrix T: for f the values at the ``np_`` GLL points, T f the values there
    of f's interpolant with its Legendre term of degree np_ − 1 dropped, i.e. its L²
    projection onto the polynomials of degree ≤ np_ − 2; f − T f is the highest mode's part,
    the tail whose size estimates a spectral element's truncation error (Mavriplis 1994,
    J. Sci. Comput. 9:1; the "np − 1 projection"). Raises as ``gll``."""
    x = gll(np_).points
    V = legendre.legvander(x, np_ - 1)  # V[i, n] = P_n(x_i): nodal values of the Legendre modes
    keep = np.ones(np_)
    keep[-1] = 0.0
    return V @ np.diag(keep) @ np.linalg.inv(V)
