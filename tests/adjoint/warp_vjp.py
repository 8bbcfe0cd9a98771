"""The tendency's vector–Jacobian product through Warp's automatic differentiation (issue 82,
item 1), beside the hand-written transpose (``kernels.tendency_adjoint.element``): shared by
tests/adjoint/test_tendency_vjp.py and benchmarks/micro/tendency_vjp.py.

The model's RHS is F = R Q W T(x) (``adjoint.reverse``); its VJP in the mass form takes μ to
R Q Tᵀ(x) W μ. Both sides here stop before the unweighted DSS R Q, which they share: each
returns x̄ = Tᵀ(x) W k̄ (element-local) and f̄ = the wind rows of W k̄ (the adjoint of the
topographic forcing −g∇hs, for ∂J/∂hs).

Warp's side is the CPU's forward kernel (``tendencies.tendency_element``: one thread per
element, on GLL rows) compiled again with ``enable_backward=True`` and launched with
``adjoint=True``: the backward kernel replays the forward and accumulates adj_x (+=) from
adj_tend = W k̄. It must be compiled with ``wp.config.enable_vector_component_overwrites``:
without it Warp 1.19 gives the wrong adjoint, silently, for a local row written twice
(``E[j] = E[j] + g h`` after ``E[j] = ½|v|²``, momentum advection with the pressure gradient:
the ½|v|² part's adjoint counted twice, 0.59 of the largest entry off at TC5's terms on ne 2
np 4). The per-node forward kernel (``tendencies.tendency``, its GLL loop bound read at run
time) differentiates wrongly with or without that flag (momentum advection: 0.77 off).
"""

from __future__ import annotations

import functools

import numpy as np
import warp as wp

from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.kernels import tendencies, tendency_adjoint
from swe_sphere.kernels.operators import CPU_FAST, row_type
from swe_sphere.model.shallow_water import ShallowWater

f64 = wp.float64
EPS = float(np.finfo(np.float64).eps)


def with_backward(forward, **options):
    """The kernel ``forward`` compiled again with its backward pass, module loaded on the CPU
    here with vector component overwrites on for its compilation alone; ``options``: more of
    ``wp.kernel``'s (``module_options``)."""
    kernel = wp.kernel(forward.func, enable_backward=True, module="unique", **options)
    held = wp.config.enable_vector_component_overwrites
    wp.config.enable_vector_component_overwrites = True
    try:
        wp.load_module(kernel.module, device="cpu")
    finally:
        wp.config.enable_vector_component_overwrites = held
    return kernel


@functools.cache
def autodiff_kernel(terms: tuple, np_: int):
    """``tendencies.tendency_element(terms, np_)`` with its backward pass (``with_backward``)."""
    return with_backward(tendencies.tendency_element(terms, np_), module_options=CPU_FAST)


@wp.kernel(enable_backward=False, module="unique")
def weighted(k: wp.array2d(dtype=f64), w: wp.array(dtype=f64), out: wp.array2d(dtype=f64)):
    """out = w·k row by row (the DSS's transpose W μ); dim (rows, N)."""
    r, p = wp.tid()
    out[r, p] = w[p] * k[r, p]


def model(ne: int, np_: int, terms, seed: int = 0) -> ShallowWater:
    """A one-thread CPU model of ``terms`` on (ne, np_) with random Coriolis and surface
    height (1e-4 s⁻¹, 100 m)."""
    grid = CubedSphere(ne, np_)
    rng = np.random.default_rng(seed)
    fcor, hs = 1e-4 * rng.standard_normal(grid.nnodes), 100.0 * rng.standard_normal(grid.nnodes)
    return ShallowWater(grid, terms, fcor, hs, threads=1, per_element=True)


def random_state(model: ShallowWater, rng) -> np.ndarray:
    """(3, N): winds of 20 m/s and a depth of 5000 ± 1000 m, independent at every copy."""
    return rng.standard_normal((3, model.N)) * [[20.0], [20.0], [1000.0]] + [[0.0], [0.0], [5000.0]]


def tendency_terms(model: ShallowWater) -> tuple:
    return tuple(t for t in tendencies.TENDENCY_TERMS if t in model.terms)


class TendencyVJP:
    """Both VJPs of ``model``'s tendency at state x (numpy (3, N)), as recorded launches:
    ``hand()`` the hand-written element kernel (k̄ one array), ``warp()`` Warp's backward
    kernel, ``warp_full()`` with what it needs besides (adj_x and f̄ zeroed, adj_tend = W k̄);
    ``forward()`` the tendency itself (for scale). Outputs: ``xbar``, ``fbar`` (hand) and
    ``xbar_ad``, ``fbar_ad`` (Warp), (3, N) and (2, N) wp arrays."""

    def __init__(self, model: ShallowWater, x: np.ndarray, kbar: np.ndarray):
        m, N, self.model = model, model.N, model
        terms, np_ = tendency_terms(m), m.grid.np
        R = m.operators.as_rows

        def zeros(rows):
            return wp.zeros((rows, N), dtype=f64)

        self.x, self.kbar = wp.array(x, dtype=f64), wp.array(kbar, dtype=f64)
        self.spheremp = wp.array(m.grid.spheremp, dtype=f64)
        self.xbar, self.fbar, self.xbar_ad, self.fbar_ad = zeros(3), zeros(2), zeros(3), zeros(2)
        self.tend, self.adj_tend = zeros(3), zeros(3)
        forcing = m.topo_forcing if m.topo_forcing is not None else zeros(2)
        nelem, metric = m.grid.nelem, (self.x, m.operators.D, m.operators.Dinv, m.operators.metdet, m.operators.fcor)
        K = R(self.kbar)
        hand = tendency_adjoint.element(terms, np_, 1)
        args = [*map(R, (*metric, self.spheremp)), m.g, m.operators.dvv_rows, wp.vec3d(1.0, 0.0, 0.0), K, K, K]
        self._hand = wp.launch(hand, nelem, [*args, R(self.xbar), R(self.fbar), 0], record_cmd=True)
        h0 = row_type(np_)(0.0)  # the float64 tendency's unread reference depth
        read = (self.x, *metric[2:])  # the forward reads no D (``operators.covariant_inverse``)
        inputs = [*map(R, (*read, forcing, self.spheremp)), m.g, h0, m.operators.dvv_rows, R(self.tend), 0]
        self._forward = wp.launch(tendencies.tendency_element(terms, np_), nelem, inputs, record_cmd=True)
        # adjoints of the metric terms not asked for: Warp skips a null adjoint array's adds
        adj = [
            R(self.xbar_ad),
            None,
            None,
            None,
            R(self.fbar_ad),
            None,
            0.0,
            h0,
            m.operators.dvv_rows,
            R(self.adj_tend),
            0,
        ]
        kernel = autodiff_kernel(terms, np_)
        self._warp = wp.launch(kernel, nelem, inputs, adj_inputs=adj, adjoint=True, record_cmd=True)
        self._weight = wp.launch(weighted, (3, N), [self.kbar, self.spheremp, self.adj_tend], record_cmd=True)

    def hand(self) -> None:
        self._hand.launch()

    def forward(self) -> None:
        self._forward.launch()

    def warp(self) -> None:
        self._warp.launch()

    def warp_full(self) -> None:
        self.xbar_ad.zero_()
        self.fbar_ad.zero_()
        self._weight.launch()
        self._warp.launch()

    def both(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(x̄ hand, x̄ Warp, f̄ hand, f̄ Warp) as numpy, each computed afresh."""
        self.fbar.zero_()
        self.hand()
        self.warp_full()
        return self.xbar.numpy(), self.xbar_ad.numpy(), self.fbar.numpy(), self.fbar_ad.numpy()


def tendency(model: ShallowWater, x: np.ndarray) -> np.ndarray:
    """T(x), the element-local tendency (3, N), by the model's CPU kernel."""
    m = model
    forcing = m.topo_forcing if m.topo_forcing is not None else wp.zeros((2, m.N), dtype=f64)
    tend, R = wp.zeros((3, m.N), dtype=f64), m.operators.as_rows
    args = [
        *map(
            R,
            (
                wp.array(x, dtype=f64),
                m.operators.Dinv,
                m.operators.metdet,
                m.operators.fcor,
                forcing,
                wp.array(m.grid.spheremp, dtype=f64),
            ),
        ),
        m.g,
        row_type(m.grid.np)(0.0),  # h0, unread in float64
        m.operators.dvv_rows,
        R(tend),
        0,
    ]
    wp.launch(tendencies.tendency_element(tendency_terms(m), m.grid.np), m.grid.nelem, args)
    return tend.numpy()


def sum_sizes(model: ShallowWater, x: np.ndarray, kbar: np.ndarray) -> np.ndarray:
    """(3, N): the size of each x̄ entry's sum, Σ_p |(W k̄)_p| |∂T_p/∂x_q| over the nodes p
    of q's element (T_p depends on its own element alone), the Jacobian's entries read from
    the hand-written transpose with one-hot cotangents at one local node of every element at
    once (3 np² launches)."""
    m = model
    np2, nelem = m.grid.np**2, m.grid.nelem
    lam = np.abs(kbar * m.grid.spheremp).reshape(3, nelem, np2)
    size, vjp = np.zeros((3, nelem, np2)), TendencyVJP(m, x, kbar)
    for r in range(3):
        for k in range(np2):
            one = np.zeros((3, nelem, np2))
            one[r, :, k] = 1.0 / m.grid.spheremp.reshape(nelem, np2)[:, k]  # W·one = 1 there
            vjp.kbar.assign(one.reshape(3, -1))
            vjp.hand()
            column = np.abs(vjp.xbar.numpy()).reshape(3, nelem, np2)  # |∂T_(r, e, k)/∂x| over element e
            size += lam[r, :, k][None, :, None] * column
    return size.reshape(3, -1)


def sum_depth(np_: int) -> int:
    """How many roundings deep an x̄ entry goes, bounding either side's error by depth·ε·size:
    a sum of 3(2np − 1) products (three rows at the 2np − 1 nodes sharing a GLL row or column)
    whose factors are up to np + 8 roundings deep (a reference derivative's np terms, the
    weight, the metric products, one division)."""
    return 3 * (2 * np_ - 1) + np_ + 8
