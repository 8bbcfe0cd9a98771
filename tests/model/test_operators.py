"""Tests of the spectral-element operators, the DSS and the shallow-water RHS.

The Warp kernels are checked three ways: against analytic values on smooth
fields (spectral convergence in np, algebraic convergence of order np − 1 in
ne), against the independent numpy reference in ``numpy_ops`` (to round-off),
and on structural properties (continuity and conservation of the DSS,
symmetry of the weak Laplacian, mass conservation of the RHS, launch lists).
"""

from __future__ import annotations

import functools
import math
from fractions import Fraction

import numpy as np
import pytest
import warp as wp

from swe_sphere.cases.library import make_case
from swe_sphere.grid.gll import gll
from swe_sphere.kernels import dss as dss_k
from swe_sphere.kernels import operators
from swe_sphere.model.arguments import TERMS
from swe_sphere.model.diagnostics import HARMONIC_KINDS, harmonic_state, hyperviscosity_rate, ideal_hyperviscosity_rate
from swe_sphere.model.launches import Update
from swe_sphere.model.shallow_water import ShallowWater

import roundoff
from helpers import cached_grid, requires_cuda
from numpy_ops import NumpyOps

DEV = "cpu"
UNFORCED = tuple(t for t in TERMS if t != "forcing")  # every term but a forced case's (tests/cases/test_forcing.py)
RHS_TERMS = tuple(t for t in UNFORCED if t != "hyperviscosity")


# -- Warp helpers ---------------------------------------------------------------
_models: dict = {}


def bare_model(ne, np_) -> ShallowWater:
    """A term-less model of the cached grid: uploaded metric arrays to launch kernels with."""
    key = (ne, np_)
    if key not in _models:
        g = cached_grid(ne, np_)
        z = np.zeros(g.nnodes)
        _models[key] = ShallowWater(g, [], z, z, device=DEV)
    return _models[key]


def w2(a) -> wp.array:
    return wp.array(np.ascontiguousarray(np.atleast_2d(a), dtype=float), dtype=wp.float64, device=DEV)


def wp_gradient(m, f):
    out = wp.zeros((2, m.N), dtype=wp.float64, device=DEV)
    wp.launch(
        operators.gradient_sphere, m.N, [w2(f), 0, m.operators.Dinv, m.operators.dvv, m.grid.np, out, 0], device=DEV
    )
    return out.numpy()


def wp_divergence(m, u, v):
    out = wp.zeros(m.N, dtype=wp.float64, device=DEV)
    wp.launch(
        operators.divergence_sphere,
        m.N,
        [w2([u, v]), m.operators.Dinv, m.operators.metdet, m.operators.dvv, m.grid.np, out, 0],
        device=DEV,
    )
    return out.numpy()


def wp_gradient_element(m, f):
    out = wp.zeros((2, m.N), dtype=wp.float64, device=DEV)
    rows = functools.partial(operators.row_vectors, np_=m.grid.np)  # the element kernels' GLL rows
    wp.launch(
        operators.gradient_element(m.grid.np),
        m.grid.nelem,
        [rows(w2(f)), 0, rows(m.operators.Dinv), m.operators.dvv_rows, rows(out), 0],
        device=DEV,
    )
    return out.numpy()


def wp_divergence_element(m, u, v):
    out = wp.zeros(m.N, dtype=wp.float64, device=DEV)
    rows = functools.partial(operators.row_vectors, np_=m.grid.np)
    wp.launch(
        operators.divergence_element(m.grid.np),
        m.grid.nelem,
        [*map(rows, (w2([u, v]), m.operators.Dinv, m.operators.metdet)), m.operators.dvv_rows, rows(out), 0],
        device=DEV,
    )
    return out.numpy()


def wp_vorticity_element(m, u, v):
    out = wp.zeros(m.N, dtype=wp.float64, device=DEV)
    rows = functools.partial(operators.row_vectors, np_=m.grid.np)
    wp.launch(
        operators.vorticity_element(m.grid.np),
        m.grid.nelem,
        [*map(rows, (w2([u, v]), m.operators.D, m.operators.metdet)), m.operators.dvv_rows, rows(out), 0],
        device=DEV,
    )
    return out.numpy()


def wp_vorticity(m, u, v):
    out = wp.zeros(m.N, dtype=wp.float64, device=DEV)
    wp.launch(
        operators.vorticity_sphere,
        m.N,
        [w2([u, v]), m.operators.D, m.operators.metdet, m.operators.dvv, m.grid.np, out, 0],
        device=DEV,
    )
    return out.numpy()


def wp_laplace_wk(m, F):
    F = w2(F)
    rows = F.shape[0]
    flux = wp.zeros((2 * rows, m.N), dtype=wp.float64, device=DEV)
    out = wp.zeros((rows, m.N), dtype=wp.float64, device=DEV)
    wp.launch(
        operators.laplace_wk_flux,
        m.N,
        [F, m.operators.Dinv, m.spheremp, m.operators.dvv, m.grid.np, flux, 0],
        device=DEV,
    )
    wp.launch(operators.laplace_wk_div, m.N, [flux, m.operators.dvv, m.grid.np, out, 0], device=DEV)
    return out.numpy()


def wp_dss(m, x, weighted=True):
    x = w2(x)
    out = wp.zeros(x.shape, dtype=wp.float64, device=DEV)
    for launch in m.topology.dss(x, weighted, out):
        launch.launch()
    return out.numpy()


def wp_laplacian(m, F):
    """Assembled Laplacian of each row of F (weak form, then unweighted DSS)."""
    return wp_dss(m, wp_laplace_wk(m, F), weighted=False)


# -- analytic fields -----------------------------------------------------------------
def tangent_components(g, V):
    """(east, north) components of Cartesian vectors V (3, N)."""
    return np.sum(V * g.east, 0), np.sum(V * g.north, 0)


def smooth_fields(g):
    """A smooth scalar f with its gradient, and a wind v = a∇f + k×a∇G with
    its divergence aΔf and vorticity aΔG. f and G are restrictions of harmonic
    polynomials to the sphere (spherical harmonics: Δ Y_l = −l(l+1) Y_l / a²)."""
    x, y, z = g.xyz
    a = g.radius
    f = x * y * z + (x * x - z * z)  # l = 3 plus l = 2
    grad_f = np.stack([y * z + 2 * x, x * z, x * y - 2 * z])  # Cartesian gradient of the polynomial
    lap_f = (-12 * x * y * z - 6 * (x * x - z * z)) / a**2
    G = x**4 - 6 * x * x * y * y + y**4  # l = 4
    grad_G = np.stack([4 * x**3 - 12 * x * y * y, -12 * x * x * y + 4 * y**3, np.zeros_like(z)])
    lap_G = -20 * G / a**2
    gf = np.stack(tangent_components(g, grad_f)) / a  # surface gradient (east, north)
    gG = np.stack(tangent_components(g, grad_G)) / a
    u = a * (gf[0] - gG[1])  # k × (e, n) = (−n, e)
    v = a * (gf[1] + gG[0])
    return dict(f=f, grad=gf, u=u, v=v, div=a * lap_f, vort=a * lap_G, lap=lap_f)


SOLID_BODY_OMEGA = 7.292e-5 * np.array([0.3, -0.5, 0.8])


def solid_body(g, omega=SOLID_BODY_OMEGA):
    """v = ω × (a r̂): divergence-free, vorticity 2 ω·r̂."""
    V = g.radius * np.cross(omega[:, None], g.xyz, axis=0)
    u, v = tangent_components(g, V)
    return u, v, 2 * (omega @ g.xyz)


def l2_err(g, num, exact):
    """Relative spheremp-weighted L2 error (vector rows summed)."""
    d = np.atleast_2d(num - exact)
    e = np.atleast_2d(exact)
    return math.sqrt(np.dot(g.spheremp, np.sum(d * d, 0)) / np.dot(g.spheremp, np.sum(e * e, 0)))


def max_err(num, exact):
    return np.abs(num - exact).max() / np.abs(exact).max()


def operator_errors(ne, np_, dss_first=False):
    """{'grad'|'div'|'vort': (L2, max)} relative errors of the Warp operators."""
    g, m = cached_grid(ne, np_), bare_model(ne, np_)
    s = smooth_fields(g)
    num = {
        "grad": wp_gradient(m, s["f"]),
        "div": wp_divergence(m, s["u"], s["v"]),
        "vort": wp_vorticity(m, s["u"], s["v"]),
    }
    if dss_first:
        num = {k: wp_dss(m, v).reshape(v.shape) for k, v in num.items()}
    return {k: (l2_err(g, num[k], s[k]), max_err(num[k], s[k])) for k in num}


def observed_rate(nes, errs):
    """Least-squares slope of −log(err) against log(ne)."""
    return -np.polyfit(np.log(nes), np.log(errs), 1)[0]


# -- GLL ---------------------------------------------------------------------------------
@pytest.mark.parametrize("np_", range(2, 9))
def test_gll_derivative_exact_for_polynomials(np_):
    rule = gll(np_)
    x = rule.points
    assert x[0] == -1 and x[-1] == 1 and np.all(np.diff(x) > 0)
    for k in range(np_):  # degree < np
        f, df = x**k, (k * x ** (k - 1) if k else np.zeros_like(x))
        assert np.abs(rule.dvv @ f - df).max() < 1e-12 * max(1, k * 1.0)
    # a random polynomial of degree np−1
    c = np.random.default_rng(np_).standard_normal(np_)
    p = np.polynomial.Polynomial(c)
    assert np.abs(rule.dvv @ p(x) - p.deriv()(x)).max() < 1e-12 * np.abs(c).sum() * np_
    # weights integrate degree ≤ 2np − 3 exactly
    assert abs(rule.weights.sum() - 2) < 1e-14
    for k in range(2 * np_ - 2):
        assert abs(rule.weights @ x**k - (1 - (-1) ** (k + 1)) / (k + 1)) < 1e-13


def _legendre_derivative(n: int, x: Fraction) -> Fraction:
    """P_n'(x) exactly (rationals): Σ over the terms of P_n's coefficients, from Bonnet's recurrence."""
    p0, p1 = [Fraction(1)], [Fraction(0), Fraction(1)]  # coefficients of P_0, P_1, lowest degree first
    for k in range(1, n):
        nxt = [Fraction(0)] + [Fraction(2 * k + 1, k + 1) * c for c in p1]
        for i, c in enumerate(p0):
            nxt[i] -= Fraction(k, k + 1) * c
        p0, p1 = p1, nxt
    return sum(i * c * x ** (i - 1) for i, c in enumerate(p1) if i)


@pytest.mark.parametrize("np_", range(3, 9))
def test_gll_points_are_correctly_rounded_and_dvv_differentiates_a_constant_to_its_rounding(np_):
    """Each interior GLL point is the root of P_N' rounded to the nearest float64 (P_N' changes
    sign within half a spacing of it, evaluated exactly), and each row of dvv sums, exactly,
    to within its entries' own roundings (Σ_j ε/2 |d_ij|: the derivative of a constant is 0).
    numpy's roots of P_N' were a few ulps off (1.5e-15 at np 8), which put dvv's rows 2.3e-13
    from 0 at np 8 (1.3e-15 at np 4, where the bound is 1.0e-15), and the continuity's element
    tendencies then integrated to a steady +0.015 ε of TC2's mass a step (ne4 and ne8 np4;
    ≤ 7e-4 ε with the correctly rounded rule: ``dt Σ tend / M``)."""
    rule = gll(np_)
    for x in rule.points[1:-1]:
        half = Fraction(float(np.spacing(abs(x)))) / 2
        below, above = (_legendre_derivative(np_ - 1, Fraction(float(x)) + s * half) for s in (-1, 1))
        assert below * above <= 0, x
    for row in rule.dvv:
        assert abs(sum(map(Fraction, row))) <= sum(Fraction(abs(d)) for d in row) * Fraction(roundoff.EPS) / 2


# -- convergence on smooth fields ----------------------------------------------------
def test_operators_converge_spectrally_in_np():
    """Fixed ne = 3: errors fall by more than 10³ from np = 4 to np = 8 and
    decrease monotonically with np."""
    errs = {np_: operator_errors(3, np_) for np_ in range(4, 9)}
    for op in ("grad", "div", "vort"):
        l2 = [errs[n][op][0] for n in range(4, 9)]
        mx = [errs[n][op][1] for n in range(4, 9)]
        assert l2[-1] < 1e-3 * l2[0], (op, l2)
        assert mx[-1] < 2e-3 * mx[0], (op, mx)
        assert all(b < a for a, b in zip(l2, l2[1:])), (op, l2)


@pytest.mark.parametrize("dss_first", [False, True], ids=["element-local", "dss"])
def test_operators_converge_at_order_np_minus_1_in_ne(dss_first):
    """np = 4, ne = 4, 8, 16: the L2 error falls like h³ (measured 2.95–3.0)
    and the max error at least like h^2.4 (measured 2.5–2.9, still pre-asymptotic)."""
    nes = [4, 8, 16]
    errs = [operator_errors(ne, 4, dss_first) for ne in nes]
    for op in ("grad", "div", "vort"):
        r_l2 = observed_rate(nes, [e[op][0] for e in errs])
        r_max = observed_rate(nes, [e[op][1] for e in errs])
        assert r_l2 >= 2.8, (op, r_l2)
        assert r_max >= 2.4, (op, r_max)


def test_solid_body_rotation():
    """v = ω×x: divergence → 0 and vorticity → 2ω·r̂, spectrally in np."""
    res = {}
    for np_ in (4, 8):
        g, m = cached_grid(3, np_), bare_model(3, np_)
        u, v, zeta = solid_body(g)
        scale = np.abs(zeta).max()
        res[np_] = (
            np.abs(wp_dss(m, wp_divergence(m, u, v))).max() / scale,
            np.abs(wp_dss(m, wp_vorticity(m, u, v))[0] - zeta).max() / scale,
        )
    assert res[8][0] < 1e-5 and res[8][1] < 1e-5, res
    assert res[8][0] < 1e-2 * res[4][0] and res[8][1] < 1e-2 * res[4][1], res


# -- DSS -----------------------------------------------------------------------------------------
@pytest.mark.roundoff
@pytest.mark.parametrize("ne,np_", [(2, 4), (3, 2), (2, 7)])
def test_dss_makes_continuous_and_keeps_integral(ne, np_, rng):
    g, m = cached_grid(ne, np_), bare_model(ne, np_)
    x = rng.standard_normal((3, g.nnodes)) + np.array([[0.0], [5.0], [-100.0]])
    out = wp_dss(m, x, weighted=True)
    rep = g.first[g.gid]
    np.testing.assert_array_equal(out, out[:, rep])  # every copy of a node gets the same bits
    # discontinuous input really was changed at shared nodes
    assert np.abs(x - x[:, rep]).max() > 0.1
    before, after = (x * g.spheremp).sum(axis=1), (out * g.spheremp).sum(axis=1)  # numpy's pairwise sums
    scale = (np.abs(x) * g.spheremp).sum(axis=1)
    roundoff.within(
        (np.abs(after - before) / scale).max(),
        roundoff.bound(roundoff.operator_roundings(np_) + 2 * math.ceil(math.log2(g.nnodes))),
        "|∫ DSS x − ∫ x| / ∫|x|",
    )
    # DSS of a continuous field is the identity (weighted), and the unweighted
    # DSS of spheremp·f gives back f
    out2 = wp_dss(m, out, weighted=True)
    assert close(out2, out, np_)
    out3 = wp_dss(m, out * g.spheremp, weighted=False)
    assert close(out3, out, np_)


# -- Warp kernels vs numpy reference ----------------------------------------------------------
def random_continuous(g, ops, rng, rows):
    return ops.dss(rng.standard_normal((rows, g.nnodes)))


def close(a, b, np_, passes=1, scale=None):
    """max |a − b| within ``roundoff.operator_roundings(np_, passes)`` ε of ``scale`` (default: max |b|); recorded."""
    scale = np.abs(b).max() if scale is None else scale
    roundoff.within(
        np.abs(a - b).max() / scale,
        roundoff.bound(roundoff.operator_roundings(np_, passes)),
        "max |kernel − numpy| / scale",
    )
    return True


@pytest.mark.roundoff
@pytest.mark.parametrize("np_", [4, 7])
def test_operator_kernels_match_numpy(np_, rng):
    g, m = cached_grid(2, np_), bare_model(2, np_)
    ops = NumpyOps(g)
    s = smooth_fields(g)
    # a smooth and a rough (element-local random) input for every operator
    for f, u, v in ((s["f"], s["u"], s["v"]), tuple(rng.standard_normal((3, g.nnodes)))):
        assert close(wp_gradient(m, f), ops.gradient(f), np_)
        assert close(wp_divergence(m, u, v), ops.divergence(u, v), np_)
        assert close(wp_gradient_element(m, f), ops.gradient(f), np_)  # the CPU layout
        assert close(wp_divergence_element(m, u, v), ops.divergence(u, v), np_)
        assert close(wp_vorticity(m, u, v), ops.vorticity(u, v), np_)
        assert close(wp_vorticity_element(m, u, v), ops.vorticity(u, v), np_)
        F = np.stack([f, u, v])
        assert close(wp_laplace_wk(m, F), ops.laplace_wk(F), np_, 2)
        for weighted in (True, False):
            assert close(wp_dss(m, F, weighted), ops.dss(F, weighted), np_)
        assert close(wp_laplacian(m, F), ops.laplacian(F), np_, 3)


@pytest.mark.roundoff
def test_model_vorticity_diagnostic(rng):
    """ShallowWater.vorticity = weighted DSS of the strong vorticity."""
    g, m = cached_grid(2, 5), bare_model(2, 5)
    ops = NumpyOps(g)
    s = smooth_fields(g)
    for u, v in ((s["u"], s["v"]), tuple(ops.dss(rng.standard_normal((2, g.nnodes))))):
        ref = ops.dss(ops.vorticity(u, v))
        assert close(m.operators.vorticity(m.new_state(u, v)), ref, 5, 2)


def tc5(g):
    c = make_case("tc5_mountain")
    return c.fcor(g.lat, g.lon), c.hs(g.lat, g.lon), np.array(c.initial(g.lat, g.lon))


def run_rhs(g, terms, fcor, hs, state, per_element=None):
    m = ShallowWater(g, terms, fcor, hs, device=DEV, per_element=per_element)
    x = m.new_state(*state)
    out = wp.zeros_like(x)
    m.rhs(x, out)
    return m, out.numpy()


def rhs_scales(ops, state, fcor, hs, g_):
    """Per row: the largest magnitude any single term contributes (the terms of
    a balanced state cancel, so the sum is not the scale of its round-off)."""
    per = np.array([np.abs(ops.sw_rhs(state, (t,), fcor, hs, g_)).max(axis=1) for t in RHS_TERMS])
    wind = per[:, :2].max()
    return np.array([wind, wind, per[:, 2].max()])


@pytest.mark.roundoff
@pytest.mark.parametrize("per_element", [True, False], ids=["per-element", "per-node"])
@pytest.mark.parametrize("np_", [4, 7])
def test_rhs_matches_numpy(np_, per_element, rng):
    """Both kernel layouts (per element: the CPU default; per node: CUDA's) on this device."""
    g = cached_grid(2, np_)
    ops = NumpyOps(g)
    fcor, hs, st = tc5(g)
    perturbed = st + ops.dss(rng.standard_normal((3, g.nnodes)) * np.array([[5.0], [5.0], [50.0]]))
    for state in (st, perturbed):
        scale = rhs_scales(ops, state, fcor, hs, 9.80616)
        for terms in [(t,) for t in RHS_TERMS] + [RHS_TERMS, ("continuity", "coriolis")]:
            m, got = run_rhs(g, terms, fcor, hs, state, per_element)
            ref = ops.sw_rhs(state, terms, fcor, hs, m.g)
            for r in range(3):
                close(got[r], ref[r], np_, 3, scale[r])  # the tendency's derivatives, their products, the DSS
            # rows a term does not touch stay exactly zero
            if "continuity" not in terms:
                assert not np.any(got[2])
            if set(terms) == {"continuity"}:
                assert not np.any(got[:2])


@pytest.mark.parametrize("terms", [RHS_TERMS, ("continuity",)], ids=["all", "continuity"])
def test_rhs_update_is_rhs_then_its_combinations(terms, rng):
    """``rhs_update`` (the combinations written by the DSS, F never stored) gives
    the bits of ``rhs`` followed by the ``blas`` combinations, for the steppers'
    patterns: in order (a later update reads an earlier one's output, an output
    the RHS's own input), rows of a subset, and rows F lacks (the continuity
    half's du, dv: F zero there)."""
    g = cached_grid(2, 4)
    fcor, hs, st = tc5(g)
    m = ShallowWater(g, terms, fcor, hs, device=DEV)
    H = slice(2, 3)
    cases = [
        lambda x, a, b: (Update(a, ((1.0, x), (0.5, None))), Update(b, ((1.0, x), (0.25, None)))),  # rk4
        lambda x, a, b: (Update(x, ((1 / 3, x), (2 / 3, a), (0.4, None))),),  # ssprk3: the input overwritten
        lambda x, a, b: (Update(b, ((1.0, x),)), Update(x, ((1.0, a), (0.3, None)))),  # leapfrog-trapezoidal
        lambda x, a, b: (Update(a, ((0.6, x), (0.2, None), (0.4, b)), H), Update(b, ((1.0, x), (0.7, None)), H)),
        lambda x, a, b: (Update(a, ((1.0, None),), H), Update(b, ((1.0, a), (-0.5, b), (0.1, None)))),  # F alone
    ]
    for case in cases:
        got, want = ([m.new_state(*st) for _ in range(3)] for _ in range(2))
        noise = rng.standard_normal((2, *st.shape))
        for arrays in (got, want):
            arrays[1].assign(st + noise[0])
            arrays[2].assign(st + noise[1])
        x, a, b = got
        m.rhs_update(x, case(x, a, b), terms)
        x, a, b = want
        k = wp.zeros_like(x)
        m.rhs(x, k, terms)
        for out, t, rows in case(x, a, b):
            rows = rows or slice(0, 3)
            m.lincomb(out[rows], ((c, (k if src is None else src)[rows]) for c, src in t)).launch()
        for g_, w_ in zip(got, want):
            assert np.array_equal(g_.numpy(), w_.numpy())


@pytest.mark.roundoff
def test_rhs_replay_uses_current_state(rng):
    """The second call only replays recorded launches; it must see new data in x."""
    g = cached_grid(2, 4)
    ops = NumpyOps(g)
    fcor, hs, st = tc5(g)
    m = ShallowWater(g, UNFORCED, fcor, hs, device=DEV)
    x = m.new_state(*st)
    out = wp.zeros_like(x)
    m.rhs(x, out)
    new = st + ops.dss(rng.standard_normal((3, g.nnodes)) * np.array([[5.0], [5.0], [50.0]]))
    x.assign(new)
    m.rhs(x, out)
    ref = ops.sw_rhs(new, RHS_TERMS, fcor, hs, m.g)
    scale = rhs_scales(ops, new, fcor, hs, m.g)
    got = out.numpy()
    for r in range(3):
        close(got[r], ref[r], g.np, 3, scale[r])


@pytest.mark.roundoff
@pytest.mark.parametrize("per_element", [True, False], ids=["per-element", "per-node"])
@pytest.mark.parametrize(
    "np_,subcycle,ratios", [(4, 1, (1.0, 1.0, 1.0)), (7, 2, (1.0, 3.0, 0.5)), (4, 1, (0.0, 1.0, 2.0))]
)
def test_hyperviscosity_matches_numpy(np_, subcycle, ratios, per_element, rng):
    """x ← x − (dt/n) B x, n times, on a state with grid-scale noise, for
    (ν, ν_div, ν_s) in the given ratios (the split, and ν = 0 with ν_div > 0);
    ν is chosen so the change is of the size of the state (no digits lost in
    the difference). Both kernel layouts."""
    g = cached_grid(2, np_)
    ops = NumpyOps(g)
    fcor, hs, st = tc5(g)
    state = st + ops.dss(rng.standard_normal((3, g.nnodes)) * np.array([[10.0], [10.0], [100.0]]))
    dt = 0.5
    m = ShallowWater(
        g, ["hyperviscosity"], fcor, hs, nu=1.0, hypervis_subcycle=subcycle, device=DEV, per_element=per_element
    )
    # ν at the forward-Euler limit the model allows per substep: the largest change it makes
    scale = 1.4 * subcycle / (dt * m.hv.biharmonic_radius() * max(ratios))
    nus = tuple(scale * r for r in ratios)
    m.nu, m.nu_div, m.nu_s = nus
    n = m.hv.substeps(dt)
    assert n == subcycle
    x = m.new_state(*state)
    m.hyperviscosity(x, dt)
    ref = state.copy()
    for _ in range(n):
        ref = ops.hyperviscosity_step(ref, hs, -dt / n, nus)
    got = x.numpy()
    change = np.abs(ref - state).max(axis=1)
    assert change[2] > 10.0 * ratios[2]  # of the 100 m noise: the test is not vacuous
    wind = change[:2].max()
    assert wind > 1.0
    passes = 5 * n  # a substep: two weak Laplacians, two DSS, the update
    close(got[:2], ref[:2], np_, passes, wind)
    close(got[2], ref[2], np_, passes, change[2])


# -- weak Laplacian ----------------------------------------------------------------------------
def harmonic(g, l):
    """A real spherical harmonic of degree l (harmonic homogeneous polynomial on the unit sphere)."""
    x, y, z = g.xyz
    return {
        1: z,
        2: x * y + 0.5 * (x * x - z * z),
        3: x * y * z + z * (2 * z * z - 3 * x * x - 3 * y * y),
        4: x**4 - 6 * x * x * y * y + y**4,
    }[l]


@pytest.mark.parametrize("l", [2, 3, 4])
def test_laplacian_of_spherical_harmonic(l):
    """DSS'd weak Laplacian of Y_l → −l(l+1)/a² Y_l; spectrally in np at ne = 3
    and at order ≥ 2.5 (L2; measured ≈ 2.7) in ne at np = 4."""
    errs = {}
    for ne, np_ in ((3, 4), (3, 8), (4, 4), (8, 4), (16, 4)):
        g, m = cached_grid(ne, np_), bare_model(ne, np_)
        Y = harmonic(g, l)
        exact = -l * (l + 1) / g.radius**2 * Y
        errs[ne, np_] = l2_err(g, wp_laplacian(m, Y)[0], exact)
    assert errs[3, 8] < 1e-3 * errs[3, 4], errs
    assert errs[3, 8] < 1e-4, errs
    assert observed_rate([4, 8, 16], [errs[n, 4] for n in (4, 8, 16)]) >= 2.5, errs


@pytest.mark.roundoff
@pytest.mark.parametrize("ne,np_", [(2, 4), (2, 8), (4, 3)])
def test_laplacian_of_constant_is_zero(ne, np_):
    g, m = cached_grid(ne, np_), bare_model(ne, np_)
    L = wp_laplacian(m, np.full(g.nnodes, 3.0))
    # the first derivative of a constant is its round-off, ``operator_roundings`` of 3/Δx; the
    # second multiplies that by Σ|dvv| ≤ np²/2 over Δx, the DSS adds a pass
    limit = roundoff.bound(roundoff.operator_roundings(np_, 3) * np_**2, 3.0 / g.dx.min() ** 2)
    roundoff.within(np.abs(L).max(), limit, "max |L 3|")


@pytest.mark.roundoff
@pytest.mark.parametrize("ne,np_", [(2, 4), (2, 6)])
def test_laplacian_symmetric_negative_semidefinite(ne, np_, rng):
    g, m = cached_grid(ne, np_), bare_model(ne, np_)
    ops = NumpyOps(g)
    F = random_continuous(g, ops, rng, 6)
    L = wp_laplacian(m, F)
    w = g.spheremp
    inner = lambda a, b: float(np.sum(w * a * b))  # noqa: E731  (numpy's pairwise sum)
    limit = roundoff.bound(roundoff.operator_roundings(np_, 3) + 2 * math.ceil(math.log2(g.nnodes)))
    for i in range(3):
        f, gg = F[2 * i], F[2 * i + 1]
        Lf, Lg = L[2 * i], L[2 * i + 1]
        scale = math.sqrt(inner(f, f) * inner(Lg, Lg)) + math.sqrt(inner(gg, gg) * inner(Lf, Lf))
        roundoff.within(abs(inner(f, Lg) - inner(Lf, gg)), limit * scale, "|(f, Lg) − (Lf, g)|")
        assert inner(f, Lf) < 0 and inner(gg, Lg) < 0
        # constants are in the kernel: ∫ L f = 0
        roundoff.within(abs(inner(np.ones_like(f), Lf)), limit * inner(np.abs(Lf), np.ones_like(f)), "|∫ L f|")


# -- what gets launched ------------------------------------------------------------------------
@pytest.fixture
def launch_log(monkeypatch):
    """Names of the kernels passed to warp.launch while the fixture is active."""
    log = []
    real = wp.launch

    def counting(kernel, *args, **kwargs):
        log.append(kernel.key)
        return real(kernel, *args, **kwargs)

    monkeypatch.setattr(wp, "launch", counting)
    return log


@pytest.mark.parametrize(
    "terms,expected",
    [
        (["continuity"], ["tendency__continuity__mass", "dss"]),
        (["pressure_gradient", "coriolis"], ["tendency__coriolis__pressure_gradient__mass", "dss"]),
        (["hyperviscosity"], ["dss"]),
        (
            list(UNFORCED),
            ["tendency__continuity__momentum_advection__coriolis__pressure_gradient__topography__mass", "dss"],
        ),
    ],
)
def test_only_named_terms_launch(terms, expected, launch_log):
    g = cached_grid(2, 4)
    fcor, hs, st = tc5(g)
    m = ShallowWater(g, terms, fcor, hs, nu=1e15, device=DEV)
    x = m.new_state(*st)
    out = wp.zeros_like(x)
    launch_log.clear()  # the topography forcing is computed at construction
    m.rhs(x, out)
    assert launch_log == expected
    assert m.rhs_kernels(x, out) == expected
    # later calls replay the recorded launches: nothing goes through wp.launch
    launch_log.clear()
    m.rhs(x, out)
    assert launch_log == []
    # a different output array is a new recording
    out2 = wp.zeros_like(x)
    assert m.rhs_kernels(x, out2) == expected
    assert launch_log == expected


@pytest.mark.parametrize("terms,nu", [(list(RHS_TERMS), 1e15), (["hyperviscosity"], 0.0)])
def test_hyperviscosity_launches_nothing_without_the_term(terms, nu, launch_log):
    g = cached_grid(2, 4)
    fcor, hs, st = tc5(g)
    m = ShallowWater(g, terms, fcor, hs, nu=nu, device=DEV)
    x = m.new_state(*st)
    launch_log.clear()
    m.hyperviscosity(x, 100.0)
    assert launch_log == []
    assert np.array_equal(x.numpy(), st)


@pytest.mark.parametrize("nu_div", [1e15, 3e15], ids=["nu_div=nu", "nu_div>nu"])
@pytest.mark.parametrize("per_element", [True, False], ids=["per-element", "per-node"])
def test_hyperviscosity_launch_list(per_element, nu_div, launch_log):
    """Three passes on the per-element layout, whose second weak Laplacian does the
    first DSS itself; six on the per-node layout, a flux pass before each weak Laplacian
    (the first forms the Cartesian wind as it reads it) and the first DSS, those four compiled
    for the grid's np; the divergence and its DSS, and the kernel that reads their gradient, only when ν_div ≠ ν."""
    g = cached_grid(2, 4)
    fcor, hs, st = tc5(g)
    m = ShallowWater(
        g,
        ["hyperviscosity"],
        fcor,
        hs,
        nu=1e15,
        nu_div=nu_div,
        hypervis_subcycle=2,
        device=DEV,
        per_element=per_element,
    )
    x = m.new_state(*st)
    m.hv.biharmonic_radius()  # its power iteration launches the same kernels
    launch_log.clear()
    m.hyperviscosity(x, 10.0)
    first = "first__divergent" if nu_div != 1e15 else "first"
    if per_element:
        expected = [f"laplacian_element__{first}", "laplacian_element__second", "dss_apply"]
    else:
        expected = [
            "laplacian_flux__cartesian__np4",
            f"laplacian_node__{first}__np4",
            "dss",
            "laplacian_flux__rows__np4",
            "laplacian_node__second__np4",
            "dss_apply",
        ]
    if nu_div != 1e15:
        expected = ["divergence_element" if per_element else "divergence_sphere", "dss", *expected]
    assert launch_log == expected


def test_unknown_term_and_negative_nu_raise():
    g = cached_grid(1, 2)
    z = np.zeros(g.nnodes)
    with pytest.raises(ValueError):
        ShallowWater(g, ["continuity", "diffusion"], z, z)
    with pytest.raises(ValueError):
        ShallowWater(g, ["hyperviscosity"], z, z, nu=-1.0)


# -- conservation ------------------------------------------------------------------------------
@pytest.mark.roundoff
@pytest.mark.parametrize("perturb", [False, True], ids=["tc5", "tc5+noise"])
def test_rhs_conserves_mass(perturb, rng):
    g = cached_grid(4, 4)
    fcor, hs, st = tc5(g)
    if perturb:
        st = st + NumpyOps(g).dss(rng.standard_normal((3, g.nnodes)) * np.array([[5.0], [5.0], [50.0]]))
    _, r = run_rhs(g, UNFORCED, fcor, hs, st)
    total = np.sum(g.spheremp * r[2])  # numpy's pairwise sum
    # a node's ∂h/∂t is a difference of fluxes h v over Δx rounded as in ``operator_roundings``
    # (a divergence and its DSS): a balanced flow's ∂h/∂t is far smaller than those terms
    flux = np.sum(g.spheremp * np.abs(st[2]) * np.hypot(st[0], st[1]) / g.dx)
    limit = roundoff.bound(roundoff.operator_roundings(4, 2) + math.ceil(math.log2(g.nnodes)), flux)
    roundoff.within(abs(total), limit, "|∫ ∂h/∂t|")


# -- CUDA ---------------------------------------------------------------------------------------
@requires_cuda
def test_cuda_matches_cpu():
    """The same kernels on CUDA give the CPU results (to round-off: FMA contraction may differ)."""
    g = cached_grid(2, 4)
    fcor, hs, st = tc5(g)
    res = {}
    for dev in ("cpu", "cuda"):
        m = ShallowWater(g, UNFORCED, fcor, hs, nu=1e15, device=dev)
        x = m.new_state(*st)
        out = wp.zeros_like(x)
        m.rhs(x, out)
        m.hyperviscosity(x, 100.0)
        res[dev] = out.numpy(), x.numpy()
    scale = rhs_scales(NumpyOps(g), st, fcor, hs, 9.80616)
    for r in range(3):
        assert np.abs(res["cuda"][0][r] - res["cpu"][0][r]).max() <= 1e-13 * scale[r]
        # against the row's largest value, not node by node: v after the ∇⁴ step crosses zero
        # (about 3e-13 of max |v| on a GPU; elementwise that is 26× near a zero of v)
        after = res["cpu"][1][r]
        assert np.abs(res["cuda"][1][r] - after).max() <= 1e-12 * np.abs(after).max()


@pytest.mark.roundoff
@pytest.mark.parametrize("rows", [1, 2, 3, 4])
@pytest.mark.parametrize("weighted", [True, False])
def test_dss_kernels_for_each_row_count_match_numpy(rows, weighted, rng):
    """The DSS compiled per row count (kernel key "dss") equals the numpy reference."""
    g, m = cached_grid(3, 4), bare_model(3, 4)
    x = rng.standard_normal((rows, g.nnodes))
    assert dss_k.dss_rows(rows, weighted, 4).key == "dss"
    ref = NumpyOps(g).dss(x, weighted=weighted)
    out = wp_dss(m, x, weighted)
    assert close(out, ref, 4)
    # every copy of a node gets the same bits: the result is exactly continuous
    first = out[:, g.first][:, g.gid]
    assert np.array_equal(out, first)


# -- hyperviscosity spectrum -------------------------------------------------------------------
@pytest.mark.parametrize("per_element", [True, False], ids=["per-element", "per-node"])
def test_hyperviscosity_damps_harmonics_at_homme_rates(per_element):
    """Spherical harmonics of degree l ≪ the grid scale (ne8 np4: l ≤ 12 of
    ≈ 48 nodes a quarter circle) decay at HOMME's continuous rates
    (``vlaplace_sphere_wk``: rigid rotation undamped, ν_div on the divergent
    wind, ν_s on h) to 1e-3 (measured ≤ 3e-4); the rotational l = 1 wind (rigid
    rotation) is not damped (measured 3e-8 of the l = 2 rate)."""
    g = cached_grid(8, 4)
    z = np.zeros(g.nnodes)
    nus = (1.5e15, 4.5e15, 0.75e15)
    m = ShallowWater(
        g, ["hyperviscosity"], z, z, nu=nus[0], nu_div=nus[1], nu_s=nus[2], device=DEV, per_element=per_element
    )
    for kind in HARMONIC_KINDS:
        for l in (2, 4, 8, 12):
            rate = hyperviscosity_rate(m, harmonic_state(g, l, kind))
            ideal = ideal_hyperviscosity_rate(l, kind, *nus, g.radius)
            assert abs(rate / ideal - 1) <= 1e-3, (kind, l, rate / ideal)
    rigid = hyperviscosity_rate(m, harmonic_state(g, 1, "rotational"))
    assert abs(rigid) <= 1e-6 * ideal_hyperviscosity_rate(2, "rotational", *nus, g.radius)


@pytest.mark.parametrize("np_", [5, 6, 7, 8])
def test_hyperviscosity_rates_at_high_np(np_):
    """The CPU layout's ∇⁴ at np 5–8 (rolled rows, ``operators.across_as_along``), with the
    scenes' ν_div = ν_s = ν (the first pass without ∇δ), damps the degree 2 and 4 harmonics at
    HOMME's continuous rates to 1e-4 on ne4 (measured ≤ 1.2e-6, at np 5). With the unrolled
    rows np 6 was off by 3.1e-3 here, and 2e5 × the per-node (CUDA) layout's ∇⁴ of TC5."""
    g = cached_grid(4, np_)
    z = np.zeros(g.nnodes)
    m = ShallowWater(g, ["hyperviscosity"], z, z, nu=1.5e15, device=DEV, per_element=True)
    for kind in HARMONIC_KINDS:
        for l in (2, 4):
            rate = hyperviscosity_rate(m, harmonic_state(g, l, kind))
            ideal = ideal_hyperviscosity_rate(l, kind, 1.5e15, 1.5e15, 1.5e15, g.radius)
            assert abs(rate / ideal - 1) <= 1e-4, (kind, l, rate / ideal)
