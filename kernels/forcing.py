"""Analytic forcing: Williamson et al. (1992) case 4, the forced translating low; the transport
tests' prescribed winds (Nair & Lauritzen 2010's deformational flows) as ∂v/∂t.

The case's exact solution (their §3.4, eqs. 106–129, and parameters; NCAR
STSWM's ``FORCE``/``BUBFNC`` for the same case) is a nondivergent flow v = k×∇Ψ with
streamfunction Ψ = ψ̄(φ) + ψ(C) and geopotential Φ = Φ̄(φ) + f ψ:

* the zonal jet ū = u0 sin¹⁴(2φ) (dψ̄/dφ = −a ū) balanced by
  dΦ̄/dφ = −(a f + ū tan φ) ū,
* the low ψ = ψ0 exp(−σ (1 − C)/(1 + C)), C = r̂·p(t) the cosine of
  the distance to its centre p(t) = (cos φ0 cos λc, cos φ0 sin λc, sin φ0),
  λc = λ0 + (u0/a) t, which turns eastward about the axis ẑ.

The forcing is what the unforced equations leave over on that solution: F_v = ∂v/∂t + (ζ + f) k×v + ∇(½|v|² + Φ) and
F_h = ∂h/∂t + ∇·(h v) = (∂Φ/∂t + v·∇Φ)/g (∇·v = 0). Here it is written in
3-D Cartesian vectors on the unit sphere (r̂ the node's position), which
keeps it exact and finite at the poles: with ψ_C, ψ_CC the C-derivatives of
ψ and U(z) = ū/cos φ = 2¹⁴ u0 z¹⁴ (1 − z²)^{13/2} (z = sin φ),

    v = (ψ_C/a) r̂×p − U r̂×ẑ,     ∂v/∂t = (1/a)(ψ_CC Ċ r̂×p + ψ_C r̂×ṗ),
    ζ = ((1 − C²) ψ_CC − 2C ψ_C)/a² + (2zU − (1 − z²) U_z)/a,
    a∇Φ = (Φ̄_z + 2Ωψ)(ẑ − z r̂) + f ψ_C (p − C r̂),   Φ̄_z = −z U (2Ωa + U),
    a∇(½|v|²) = P[(ψ_CC/a)(v·r̂×p) p + (ψ_C/a) p×v − U_z (v·r̂×ẑ) ẑ − U ẑ×v]

(P = I − r̂r̂ᵀ, ṗ = (u0/a) ẑ×p, Ċ = r̂·ṗ): the last is the tangential part of
Jᵀv, J the Jacobian of the wind's extension off the sphere.
"""

from typing import Any

import warp as wp

from .operators import CPU_FAST

f64 = wp.float64
wp.set_module_options({"enable_backward": False, **CPU_FAST})

# psi0 (m² s⁻¹), sigma, lat0, lon0 (rad), u0 (m s⁻¹), Omega (s⁻¹), a (m), g (m s⁻²)
TranslatingLowParams = wp.types.vector(length=8, dtype=f64)


@wp.kernel
def translating_low(
    xyz: wp.array2d(dtype=f64),
    east: wp.array2d(dtype=f64),
    north: wp.array2d(dtype=f64),
    c: TranslatingLowParams,
    t: f64,
    tend: wp.array2d(dtype=Any),
    block: int,
    offset: int,
):
    """tend[:, p] += (F_u, F_v, F_h) of case 4 at time t (s) (module docstring),
    F_u, F_v in m s⁻², F_h in m s⁻¹, at ``block`` consecutive nodes a thread
    (as ``blas.axpby``), computed in float64 and added in tend's type (float64, or a float32
    tendency: ``ShallowWater``'s precision). Dim N/block."""
    psi0, sigma, lat0, lon0 = c[0], c[1], c[2], c[3]
    u0, omega, a, g = c[4], c[5], c[6], c[7]
    rate = u0 / a
    lonc = lon0 + rate * t
    pc = wp.vec3d(wp.cos(lat0) * wp.cos(lonc), wp.cos(lat0) * wp.sin(lonc), wp.sin(lat0))
    pdot = rate * wp.vec3d(-pc[1], pc[0], f64(0.0))
    zhat = wp.vec3d(f64(0.0), f64(0.0), f64(1.0))
    start = (wp.tid() + offset) * block
    for p in range(start, start + block):
        r = wp.vec3d(xyz[0, p], xyz[1, p], xyz[2, p])
        C = wp.dot(r, pc)
        psi = f64(0.0)
        psi_c = f64(0.0)
        psi_cc = f64(0.0)
        if C > f64(-0.99):  # nearer the antipode 1/(1 + C) is not safe (and ψ/ψ0 < exp(−3e4))
            q = f64(1.0) / (f64(1.0) + C)
            arg = sigma * (f64(1.0) - C) * q
            if arg < f64(700.0):  # beyond, ψ/ψ0 < 1e-304: zero here, not subnormal (10× slower)
                psi = psi0 * wp.exp(-arg)
                psi_c = f64(2.0) * sigma * psi * q * q
                psi_cc = psi_c * f64(2.0) * (sigma * q * q - q)
        z = r[2]
        cz2 = wp.max(f64(1.0) - z * z, f64(0.0))  # cos² φ
        cz = wp.sqrt(cz2)
        z2 = z * z
        z4 = z2 * z2
        z12 = z4 * z4 * z4
        c8 = cz2 * cz2 * cz2 * cz2
        U = u0 * f64(16384.0) * z12 * z2 * c8 * cz2 * cz2 * cz  # 2¹⁴ u0 z¹⁴ cos¹³ φ
        Uz = u0 * f64(16384.0) * z12 * z * c8 * cz2 * cz * (f64(14.0) - f64(27.0) * z2)  # dU/dz
        rp = wp.cross(r, pc)
        rz = wp.cross(r, zhat)
        v = (psi_c / a) * rp - U * rz
        Cdot = wp.dot(r, pdot)
        vt = (psi_cc * Cdot * rp + psi_c * wp.cross(r, pdot)) / a
        zeta = ((f64(1.0) - C * C) * psi_cc - f64(2.0) * C * psi_c) / (a * a) + (f64(2.0) * z * U - cz2 * Uz) / a
        f = f64(2.0) * omega * z
        phibar_z = -z * U * (f64(2.0) * omega * a + U)
        grad_phi = ((phibar_z + f64(2.0) * omega * psi) * (zhat - z * r) + f * psi_c * (pc - C * r)) / a
        jtv = (
            (psi_cc / a) * wp.dot(v, rp) * pc
            + (psi_c / a) * wp.cross(pc, v)
            - Uz * wp.dot(v, rz) * zhat
            - U * wp.cross(zhat, v)
        )
        grad_k = (jtv - wp.dot(r, jtv) * r) / a
        fv = vt + (zeta + f) * wp.cross(r, v) + grad_k + grad_phi
        e = wp.vec3d(east[0, p], east[1, p], east[2, p])
        n = wp.vec3d(north[0, p], north[1, p], north[2, p])
        tend[0, p] = tend[0, p] + type(tend[0, p])(wp.dot(fv, e))
        tend[1, p] = tend[1, p] + type(tend[1, p])(wp.dot(fv, n))
        tend[2, p] = tend[2, p] + type(tend[2, p])((f * psi_c * Cdot + wp.dot(v, grad_phi)) / g)


for _t in (f64, wp.float32):  # the tendency's float types
    wp.overload(translating_low, {"tend": wp.array2d(dtype=_t)})


# k0 = κ a / T (m s⁻¹), 2π / T and π / T (s⁻¹), and 0 or 1: the nondivergent or the divergent
# deformational flow (``deformational_flow``)
DeformationalParams = wp.types.vector(length=4, dtype=f64)


@wp.kernel
def deformational_flow(
    xyz: wp.array2d(dtype=f64),
    east: wp.array2d(dtype=f64),
    north: wp.array2d(dtype=f64),
    c: DeformationalParams,
    t: f64,
    tend: wp.array2d(dtype=Any),
    block: int,
    offset: int,
):
    """tend[0:2, p] += ∂u/∂t, ∂v/∂t (m s⁻²) at time t (s) of Nair & Lauritzen (2010)'s
    deformational flows (Lauritzen et al. 2012 §2.1), with λ' = λ − 2πt/T: c[3] = 0 the
    nondivergent one (their case 4; HOMME's ``get_nondiv2d_uv``),
    u = k0 sin²λ' sin 2θ cos(πt/T) + u0 cos θ,  v = k0 sin 2λ' cos θ cos(πt/T);
    c[3] = 1 the divergent one (their case 3 with the background rotation),
    u = −k0 sin²(λ'/2) sin 2θ cos²θ cos(πt/T) + u0 cos θ,  v = (k0/2) sin λ' cos³θ cos(πt/T);
    so that a stepper's stages carry the prescribed wind in time (the case's continuity alone
    moves h and the tracers); k0 = 0: solid-body rotation, whose wind does not change. Rows 2..
    (h, the tracers) get nothing. ``block`` nodes a thread as ``translating_low``. Dim N/block."""
    k0 = c[0]
    omega = c[1]  # the background's rotation rate
    rate = c[2]  # the deformation's reversal
    ct = wp.cos(rate * t)
    st = wp.sin(rate * t)
    start = (wp.tid() + offset) * block
    for p in range(start, start + block):
        x, y, z = xyz[0, p], xyz[1, p], xyz[2, p]
        cos_lat = wp.sqrt(x * x + y * y)
        lam = wp.atan2(y, x) - omega * t
        s1 = wp.sin(lam)
        sin_2lat = f64(2.0) * z * cos_lat
        du = f64(0.0)
        dv = f64(0.0)
        if c[3] == f64(0.0):
            s2 = wp.sin(f64(2.0) * lam)
            du = -k0 * sin_2lat * (omega * s2 * ct + rate * s1 * s1 * st)
            dv = -k0 * cos_lat * (f64(2.0) * omega * wp.cos(f64(2.0) * lam) * ct + rate * s2 * st)
        else:  # d/dt sin²(λ'/2) = −(ω/2) sin λ', d/dt sin λ' = −ω cos λ'
            cos2 = cos_lat * cos_lat
            half = wp.sin(f64(0.5) * lam)
            du = k0 * sin_2lat * cos2 * (f64(0.5) * omega * s1 * ct + rate * half * half * st)
            dv = -f64(0.5) * k0 * cos2 * cos_lat * (omega * wp.cos(lam) * ct + rate * s1 * st)
        tend[0, p] = tend[0, p] + type(tend[0, p])(du)
        tend[1, p] = tend[1, p] + type(tend[1, p])(dv)


for _t in (f64, wp.float32):  # the tendency's float types
    wp.overload(deformational_flow, {"tend": wp.array2d(dtype=_t)})
