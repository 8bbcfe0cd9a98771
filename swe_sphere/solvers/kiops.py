"""KIOPS: φ-functions of a matrix applied to vectors by adaptive Krylov projection
(Gaudreault, Rainwater & Tokman 2018, J. Comput. Phys. 372, 236), on Warp arrays, for the
exponential steppers (``exponential``): ``Kiops`` (the method, its sources and its choices in
its docstring), ``KiopsStats`` (what one product did) and the substep controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from ..core.errors import StepFailure
from .krylov import KrylovBasis

f64 = wp.float64
MAX_SUBSTEPS = 1000  # accepted and rejected; beyond it the product fails (StepFailure)


@dataclass
class KiopsStats:
    """What one ``Kiops.apply`` did: Krylov vectors built (products with A, those of a
    zero vector included), accepted and rejected substeps, the Krylov size to start the
    next call with, and the sum of the accepted substeps' error estimates."""

    krylov: int
    substeps: int
    rejected: int
    m: int
    error: float


class Kiops:
    """φ-function products w = Σ_k τ^k φ_k(τA) u_k, k = 0 … p, for vectors of length n
    (this process's part of a unique-node vector) on ``topology``'s device, with
    Krylov spaces of at most ``m_max`` vectors orthogonalised against the last ``iop``.

    It evaluates

        w = Σ_{k=0}^{p} τ^k φ_k(τA) u_k,    φ_0(z) = e^z,  φ_k(z) = Σ_{j≥0} z^j / (j + k)!,

    the solution at t = τ of w' = A w + Σ_{k≥1} t^(k−1)/(k−1)! u_k, w(0) = u_0. The
    vectors u_1 … u_p enter through one exponential of an augmented matrix
    (Al-Mohy & Higham 2011, SIAM J. Sci. Comput. 33, 488, Thm 2.1; used so by KIOPS):
    w is the first n entries of exp(τÃ) [u_0; e_p] with

        Ã = [[A, W], [0, J]],   W = [u_p, …, u_1] (n × p),   J the p × p shift (ones above the diagonal),

    and exp(τÃ) is approximated on the Krylov space of Ã: V_m, H_m from m Arnoldi
    steps, w ≈ β V_m exp(τH_m) e_1. Each Arnoldi step is one product with A (the
    caller's ``matvec``, a Jacobian–vector product) plus the p augmented entries,
    which stay on the host (every process holds the same copy). As KIOPS:

    * incomplete orthogonalisation: each new vector against the last ``iop`` (2)
      only, so the work and the storage read per step do not grow with m; the
      Arnoldi relation ÃV_m = V_m H_m + h_{m+1,m} v_{m+1} e_mᵀ holds without full
      orthogonality. Classical Gram–Schmidt, its inner products summed over
      processes by ``Topology.sums`` (``krylov.KrylovBasis``), with a
      second pass only when the first removes more than 1 − 1/√2 of the vector's
      norm (Daniel, Gragg, Kaufman & Stewart 1976, Math. Comp. 30, 772; how often it runs and
      what it costs: docs/explanation/defaults.md);
    * the error estimate β h_{m+1,m} |[exp(τH̃)]_{m,m+1}| (H̃: H_m with a unit
      (1, m+1) entry, so that its exponential holds φ_1(τH_m) e_1 too; Saad 1992,
      SIAM J. Numer. Anal. 29, 209),
      compared with τ_end · tol / τ;
    * substeps: exp((τ_now + τ)Ã) = exp(τÃ) exp(τ_nowÃ), so a substep restarts from
      [w(τ_now); exp(τ_now J) e_p], exp(τJ) e_p = (τ^(p−1)/(p−1)!, …, τ, 1);
    * adaptive τ and m (Niesen & Wright 2012, ACM TOMS 38, 22: the order of the
      error in τ and its decay rate in m estimated from the last rejection;
      safety factors γ = 0.9 for τ_end ≤ 1, else 0.2; a substep is accepted when
      its error is within δ = 1.4 of the target); the last m is returned for the
      next call (Gaudreault & Pudykiewicz 2016, J. Comput. Phys. 322, 827: carried
      from step to step);
    * the vectors u_1 … u_p scaled by a power of two near their largest norm, the
      augmented entries by its inverse (exact in binary), so that Ã's blocks are
      of one size.

    The small exponential is ``scipy.linalg.expm`` on the host ((m+1) × (m+1), m ≤ 128).

    ``apply(matvec, u0, us, out, tau, tol, m, m_min)`` → ``KiopsStats``: ``matvec(v, out)``
    writes A v (Warp arrays of length n); ``u0`` a vector or None (zero); ``us`` the
    vectors u_1 … u_q, q ≤ p (the others zero); ``out`` receives w (may not alias
    an input); ``tol`` bounds the estimated error of w (Euclidean norm over all
    processes, the units of u); ``m`` the first substep's Krylov size, kept within
    [min(m_min, m_max), m_max]. Raises ``StepFailure`` on a non-finite error estimate, after
    ``MAX_SUBSTEPS`` substeps or when a substep shrinks below 1e-12 τ.
    """

    def __init__(self, n: int, p: int, m_max: int, topology, iop: int = 2):
        self.n, self.p, self.m_max, self.iop = int(n), max(int(p), 1), int(m_max), int(iop)
        self.topology = topology
        self.basis = KrylovBasis(self.n, self.m_max + 1, topology)
        # rows lo … of V, one view each made once (a Warp view costs ~25 µs; the same view keys the same recorded launch)
        self.tails_V = [self.basis.V[lo:] for lo in range(self.m_max + 1)]
        self.U = wp.zeros((self.p, self.n), dtype=f64, device=topology.device)  # row q: ν u_(p−q)
        self.rows_U = [self.U[q] for q in range(self.p)]
        self.aug = np.zeros((self.m_max + 1, self.p))  # the basis vectors' augmented entries
        self.H = np.zeros((self.m_max + 1, self.m_max + 1))
        self._none = np.zeros(0)

    def _start(self, out, tau_now: float, mu: float) -> float:
        """The substep's first basis vector from [w(τ_now); μ exp(τ_now J) e_p]; returns its norm β."""
        p, b = self.p, self.basis
        a0 = np.array([mu * tau_now ** (p - 1 - q) / math.factorial(p - 1 - q) for q in range(p)])
        beta = math.sqrt(b.project_dots(b.V, out, 0, None, 0)[0] + a0 @ a0)
        b.lincomb(b.V, self._none, 1.0 / beta, out, b.rows_V[0])
        self.aug[0] = a0 / beta
        return beta

    def _arnoldi(self, matvec, j: int, tol: float) -> float:
        """V_j = Ã V_(j−1) orthogonalised against the last ``iop`` vectors and normalised;
        H's column j − 1. Returns h_(j,j−1), or 0.0 for a happy breakdown (‖V_j‖ < tol:
        the space is invariant; V_j then unused)."""
        b, aug, V = self.basis, self.aug, self.basis.rows_V
        matvec(V[j - 1], V[j])
        b.lincomb(self.U, aug[j - 1], 1.0, V[j], V[j])  # + W · (augmented entries)
        a = np.append(aug[j - 1, 1:], 0.0)  # J · (augmented entries)
        lo = max(0, j - self.iop)
        k, B, A = j - lo, self.tails_V[lo], aug[lo:j]
        *h, ww = b.project_dots(B, V[j], 0, None, k)
        h = np.array(h) + A @ a
        ww += a @ a
        if ww - h @ h >= 0.5 * ww:  # one pass: w kept more than 1/√2 of its norm
            h2, h = h, np.zeros(k)
        else:  # the second pass of classical Gram–Schmidt
            d = b.project_dots(B, V[j], k, h, k)
            a -= h @ A
            h2 = d[:k] + A @ a
            ww = d[k] + a @ a
        self.H[lo:j, j - 1] = h + h2
        nrm = math.sqrt(max(ww - h2 @ h2, 0.0))  # Pythagoras: B's rows are orthonormal
        if nrm < tol:
            return 0.0
        b.lincomb(B, -h2 / nrm, 1.0 / nrm, V[j], V[j])
        aug[j] = (a - h2 @ A) / nrm
        self.H[j, j - 1] = nrm
        return nrm

    def apply(
        self, matvec, u0, us, out, tau: float = 1.0, tol: float = 1e-7, m: int = 10, m_min: int = 10
    ) -> KiopsStats:
        from scipy.linalg import expm  # here: scipy.linalg costs every command's start 0.1 s of CPU

        b, H = self.basis, self.H
        mu = self._load(u0, us, out)
        tau_end = float(tau)
        control = SubstepControl(tau_end, min(int(m_min), self.m_max), self.m_max)
        m = max(control.m_min, min(int(m), self.m_max))
        tau_now, tau = 0.0, tau_end
        j, krylov, substeps, rejected, ireject, error = 0, 0, 0, 0, 0, 0.0
        oldm, oldtau, omega = -1, math.nan, math.nan
        while tau_now < tau_end:
            if substeps + rejected >= MAX_SUBSTEPS or tau < 1e-12 * tau_end:
                raise StepFailure(
                    f"KIOPS did not reach tol {tol:.1e} in {substeps + rejected} substeps (at τ {tau_now:.3e} of {tau_end:.3e}, "
                    f"substep {tau:.1e}, Krylov size {m})"
                )
            if j == 0:
                H[:] = 0.0
                beta = self._start(out, tau_now, mu)
            nrm = -1.0
            while j < m:
                j += 1
                krylov += 1
                nrm = self._arnoldi(matvec, j, tol)
                if nrm == 0.0:
                    break
            happy = nrm == 0.0
            nrm = H[j, j - 1]
            H[0, j] = 1.0  # exp(τH̃)[:j, j] = τφ_1(τH_j) e_1: its last entry is the error estimate's
            H[j, j - 1] = 0.0
            E = expm(tau * H[: j + 1, : j + 1])
            H[j, j - 1] = nrm
            if happy:
                err, omega = 0.0, 0.0
                tau_new, m_new = min(tau_end - (tau_now + tau), tau), m
            else:
                err = abs(beta * nrm * E[j - 1, j])
                if not math.isfinite(err):
                    raise StepFailure(f"KIOPS error estimate is not finite (Krylov size {j}, τ {tau:.3e})")
                oldomega, omega = omega, tau_end * err / (tau * tol)
                tau_new, m_new = control.next(j, tau_now, (tau, oldtau), (m, oldm), (omega, oldomega), ireject)
            if omega <= DELTA:  # accepted: w(τ_now + τ) = β V_j exp(τH_j) e_1
                b.lincomb(b.V, beta * E[:j, 0], 0.0, out, out)
                tau_now += tau
                if tau_end - tau_now <= 1e-12 * tau_end:  # what rounding of the substeps leaves over
                    tau_now = tau_end
                substeps += 1
                error += err
                j = ireject = 0
            else:
                ireject += 1
                rejected += 1
                H[0, j] = 0.0
            oldtau, tau = tau, tau_new
            oldm, m = m, m_new
        return KiopsStats(krylov, substeps, rejected, m, error)

    def _load(self, u0, us, out) -> float:
        """u_1 … u_p into U scaled by ν = 2^−e (2^e near their largest norm), u_0 (or zero)
        into ``out``; returns μ = 2^e, the augmented entries' scale. Raises ValueError for
        more than p vectors."""
        b, p = self.basis, self.p
        if len(us) > p:
            raise ValueError(f"at most {p} vectors u_1 … u_p (got {len(us)})")
        norms = [self.topology.norm(u) for u in us]
        scale = max(norms, default=0.0)
        ex = math.ceil(math.log2(scale)) if scale > 0 else 0
        nu, mu = 2.0**-ex, 2.0**ex
        for q in range(p):
            k = p - q  # row q holds u_k
            if k <= len(us):
                b.lincomb(self.U, self._none, nu, us[k - 1], self.rows_U[q])
            else:
                self.rows_U[q].zero_()
        if u0 is None:
            out.zero_()
        else:
            wp.copy(out, u0)
        return mu


DELTA = 1.4  # a substep is accepted when its error is within δ of the target


@dataclass
class SubstepControl:
    """The next substep τ and Krylov size m after a try (Niesen & Wright 2012, ACM TOMS 38, 22,
    as KIOPS): the error's order in τ and its decay rate in m measured from the last rejected
    try when it changed only τ or only m, else the a priori j/4 and 2 (or once more the last
    measured value); safety factor γ = 0.9 for τ_end ≤ 1, else 0.2 (0.6 and 0.1 when the space
    is at ``m_max``); m changes by at most a third a try and stays in [m_min, m_max]."""

    tau_end: float
    m_min: int
    m_max: int
    order: float = 1.0
    kest: float = 2.0
    order_measured: bool = False
    kest_measured: bool = False

    def next(self, j: int, tau_now: float, taus, ms, omegas, ireject: int) -> tuple[float, int]:
        """(τ, m) for the next try after one with Krylov size ``j`` from ``tau_now``;
        ``taus``, ``ms``, ``omegas``: (this try's, the last try's) substep, Krylov size and
        error over its target; ``ireject`` the rejections since the last accepted substep."""
        (tau, oldtau), (m, oldm), (omega, oldomega) = taus, ms, omegas
        tau_end, m_min, m_max = self.tau_end, self.m_min, self.m_max
        gamma, gamma_mmax = (0.2, 0.1) if tau_end > 1 else (0.9, 0.6)
        if ireject >= 1 and m == oldm and tau != oldtau and omega > 0 and oldomega > 0:
            self.order, self.order_measured = max(1.0, math.log(omega / oldomega) / math.log(tau / oldtau)), True
        elif not self.order_measured or ireject == 0:
            self.order = j / 4
        else:
            self.order_measured = False
        if ireject >= 1 and m != oldm and tau == oldtau and omega > 0 and oldomega > 0:
            self.kest, self.kest_measured = max(1.1, (omega / oldomega) ** (1.0 / (oldm - m))), True
        elif not self.kest_measured or ireject == 0:
            self.kest = 2.0
        else:
            self.kest_measured = False
        order = self.order
        remaining = tau_end - tau_now if omega > DELTA else tau_end - (tau_now + tau)
        if omega > 0:
            tau_opt = min(remaining, max(tau / 5, min(5 * tau, tau * (gamma / omega) ** (1 / order))))
            m_opt = math.ceil(j + math.log(omega / gamma) / math.log(self.kest))
        else:
            tau_opt, m_opt = min(remaining, 5 * tau), m
        m_opt = max(m_min, min(m_max, max(math.floor(3 / 4 * m), min(m_opt, math.ceil(4 / 3 * m)))))
        if j < m_max:
            return min(remaining, tau), m_opt
        if omega > DELTA:  # the space can grow no more: shorten the substep instead
            return min(tau_end - tau_now, max(tau / 5, tau * (gamma_mmax / omega) ** (1 / order))), j
        return tau_opt, m
