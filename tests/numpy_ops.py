"""Independent, vectorised numpy reference of the spectral-element operators.

Written from the formulas of HOMME's ``derivative_mod`` (Taylor & Fournier
2010; Dennis et al. 2012), not from the Warp kernels. Fields are handled as
``(nelem, np, np)`` arrays indexed ``[e, j, i]`` (i along ξ, j along η), which
is exactly the element-local flat storage ``p = e*np*np + j*np + i`` reshaped.
``dvv[i, m] = l_m'(ξ_i)`` so that ``(dvv @ f)[i] = f'(ξ_i)``.

Conventions
-----------
* D maps reference contravariant components to (east, north) components;
  ``Dinv`` maps (east, north) to contravariant; ``Dᵀ`` maps (east, north) to
  covariant. Flat storage ``D[(2r + c), p] = D_{r+1, c+1}``.
* strong gradient    ∇f = Dinv^T (∂ξ f, ∂η f)
* strong divergence  ∇·v = (∂ξ(J c¹) + ∂η(J c²)) / J,   c = Dinv v, J = metdet
* strong vorticity   ζ = (∂ξ v₂ − ∂η v₁) / J,            v_cov = Dᵀ v
* weak Laplacian     (L f)_mn = −Σ_quad spheremp ∇φ_mn·∇f  (element-local;
  the unweighted DSS turns it into the assembled Laplacian)
"""

from __future__ import annotations

import numpy as np


class NumpyOps:
    """Reference operators bound to one ``CubedSphere``."""

    def __init__(self, grid):
        self.grid = grid
        self.np = n = grid.np
        self.nelem = grid.nelem
        self.shape = (grid.nelem, n, n)
        self.dvv = np.asarray(grid.rule.dvv, dtype=float)
        r = self.el
        # 2×2 metric blocks, each (nelem, np, np)
        self.D = [[r(grid.D[0]), r(grid.D[1])], [r(grid.D[2]), r(grid.D[3])]]
        self.Dinv = [[r(grid.Dinv[0]), r(grid.Dinv[1])], [r(grid.Dinv[2]), r(grid.Dinv[3])]]
        self.J = r(grid.metdet)
        self.spheremp = r(grid.spheremp)
        self.gid = np.asarray(grid.gid)
        # assembled mass, computed here rather than taken from grid.rspheremp
        self.mass = np.bincount(self.gid, weights=grid.spheremp)[self.gid]

    # -- layout ---------------------------------------------------------------
    def el(self, f):
        """flat (..., N) → (..., nelem, np, np) [e, j, i]."""
        f = np.asarray(f, dtype=float)
        return f.reshape(*f.shape[:-1], *self.shape)

    @staticmethod
    def flat(f):
        """(..., nelem, np, np) → (..., N)."""
        return f.reshape(*f.shape[:-3], -1)

    # -- reference derivatives -------------------------------------------------
    def d_xi(self, f):
        """∂f/∂ξ of an element field [.., e, j, i]."""
        return np.einsum("im,...ejm->...eji", self.dvv, f)

    def d_eta(self, f):
        """∂f/∂η of an element field [.., e, j, i]."""
        return np.einsum("jm,...emi->...eji", self.dvv, f)

    # -- strong-form operators (flat in, flat out) ------------------------------
    def gradient(self, f):
        """(N,) → (2, N): (east, north) components of ∇f."""
        f = self.el(f)
        a, b = self.d_xi(f), self.d_eta(f)
        Di = self.Dinv
        return self.flat(np.stack([Di[0][0] * a + Di[1][0] * b, Di[0][1] * a + Di[1][1] * b]))

    def divergence(self, u, v):
        """(N,), (N,) → (N,): ∇·(u east + v north)."""
        u, v = self.el(u), self.el(v)
        Di, J = self.Dinv, self.J
        c1 = Di[0][0] * u + Di[0][1] * v
        c2 = Di[1][0] * u + Di[1][1] * v
        return self.flat((self.d_xi(J * c1) + self.d_eta(J * c2)) / J)

    def vorticity(self, u, v):
        """(N,), (N,) → (N,): k·∇×(u east + v north)."""
        u, v = self.el(u), self.el(v)
        D = self.D
        v1 = D[0][0] * u + D[1][0] * v
        v2 = D[0][1] * u + D[1][1] * v
        return self.flat((self.d_xi(v2) - self.d_eta(v1)) / self.J)

    def laplace_wk(self, f):
        """(..., N) → (..., N): element-local weak Laplacian −∫ ∇φ·∇f (not DSS'd)."""
        f = self.el(f)
        a, b = self.d_xi(f), self.d_eta(f)
        Di = self.Dinv
        ge = Di[0][0] * a + Di[1][0] * b
        gn = Di[0][1] * a + Di[1][1] * b
        F1 = self.spheremp * (Di[0][0] * ge + Di[0][1] * gn)  # quadrature-weighted contravariant
        F2 = self.spheremp * (Di[1][0] * ge + Di[1][1] * gn)
        # ∂ξ φ_{m n}(i, j) = dvv[i, m] δ_{jn};  ∂η φ_{m n}(i, j) = dvv[j, n] δ_{im}
        out = np.einsum("im,...eni->...enm", self.dvv, F1) + np.einsum("jn,...ejm->...enm", self.dvv, F2)
        return self.flat(-out)

    def laplacian(self, f):
        """Assembled Laplacian: unweighted DSS of the weak Laplacian."""
        return self.dss(self.laplace_wk(f), weighted=False)

    # -- direct stiffness summation ---------------------------------------------
    def dss(self, x, weighted=True):
        """(..., N) → (..., N). Weighted: mass-weighted average of the copies;
        unweighted: sum of the copies divided by the assembled mass."""
        x = np.asarray(x, dtype=float)
        w = self.grid.spheremp if weighted else 1.0
        rows = x.reshape(-1, x.shape[-1]) * w
        summed = np.stack([np.bincount(self.gid, weights=r) for r in rows])[:, self.gid]
        return (summed / self.mass).reshape(x.shape)

    # -- shallow-water right-hand side -------------------------------------------
    def sw_tendency(self, state, terms, fcor, hs, g):
        """Element-local (not DSS'd) tendency (3, N) of the named terms."""
        u, v, h = (np.asarray(r, dtype=float) for r in state)
        out = np.zeros((3, u.size))
        if "continuity" in terms:
            out[2] -= self.divergence(h * u, h * v)
        if "momentum_advection" in terms:
            zeta = self.vorticity(u, v)
            ke = self.gradient(0.5 * (u * u + v * v))
            out[0] += zeta * v - ke[0]  # −ζ k×v, k×v = (−v, u)
            out[1] += -zeta * u - ke[1]
        if "coriolis" in terms:
            out[0] += fcor * v
            out[1] -= fcor * u
        if "pressure_gradient" in terms:
            out[:2] -= g * self.gradient(h)
        if "topography" in terms:
            out[:2] -= g * self.gradient(hs)
        return out

    def sw_rhs(self, state, terms, fcor, hs, g):
        """DSS'd shallow-water tendency (3, N)."""
        return self.dss(self.sw_tendency(state, terms, fcor, hs, g), weighted=True)

    def gravity_wave(self, z, g, H):
        """(3, N) L z = (−g G z_h, −H D z_v), the linear gravity-wave operator about the
        depth H with the DSS'd gradient G and divergence D."""
        G = self.dss(self.gradient(z[2]))
        return np.concatenate([-g * G, -H * self.dss(self.divergence(z[0], z[1])[None])])

    # -- hyperviscosity --------------------------------------------------------------
    def biharmonic(self, state, hs, nus=(1.0, 1.0, 1.0)):
        """(4, N) B state, the hyperviscosity operator with (ν, ν_div, ν_s) of
        (Cartesian wind, free surface h + hs) as in ``kernels.hyperviscosity``:
        Y₁ = ν (P ΔX + 2v/a²) + (ν_div − ν) G∇·v, ν_s Δ(h + hs); Y₂ = ΔY₁ + 2Y₁/a²
        (wind), with Δ the assembled Laplacian and G, ∇· the DSS'd strong operators."""
        nu, nu_div, nu_s = nus
        u, v, h = (np.asarray(r, dtype=float) for r in state)
        g = self.grid
        shift = 2.0 / g.radius**2
        wind = u * g.east + v * g.north
        L = self.laplacian(np.concatenate([wind, (h + hs)[None]]))
        rhat = g.xyz
        L[:3] -= np.sum(L[:3] * rhat, axis=0) * rhat
        grad_div = self.dss(self.gradient(self.dss(self.divergence(u, v))))
        Y = np.concatenate(
            [nu * (L[:3] + shift * wind) + (nu_div - nu) * (grad_div[0] * g.east + grad_div[1] * g.north), nu_s * L[3:]]
        )
        out = self.laplacian(Y)
        out[:3] += shift * Y[:3]
        return out

    def hyperviscosity_step(self, state, hs, coef, nus=(1.0, 1.0, 1.0)):
        """state + coef·B state, the wind taken back to (east, north)."""
        Y = self.biharmonic(state, hs, nus)
        g = self.grid
        out = np.array(state, dtype=float)
        out[0] += coef * np.sum(Y[:3] * g.east, axis=0)
        out[1] += coef * np.sum(Y[:3] * g.north, axis=0)
        out[2] += coef * Y[3]
        return out
