"""The model's DSS'd spectral-element operators and the device geometry they read.

``ElementOperators`` is what a stepper, a solver or the adjoint applies to a state besides the
tendency (``ShallowWater.rhs``): the gradient G = DSS∘grad and the divergence D = DSS∘div of the
gravity-wave operator and the Helmholtz solves (``model.gravity_wave``, ``model.helmholtz``),
written into updates as their DSS makes them; the unique-node assembly and scatter; the
vorticity and divergence the diagnostics report; and the arrays the element kernels take: the
metric terms D, D⁻¹ and metdet (HOMME's ``D``, ``Dinv``, ``metdet``), ``fcor`` and ``hs``, the derivative matrix
``dvv`` (and as the per-element kernels' rows, ``dvv_rows``), the unit vectors ``east``,
``north`` and positions ``xyz`` at the nodes, and work arrays. Every launch is recorded once a
pair of arrays in the model's ``LaunchRecorder`` and replayed (HOMME's ``derivative_mod``
operators, ``gradient_sphere``, ``divergence_sphere``, ``vorticity_sphere``, with its
``bndry_exchange`` DSS).

Where the model's steps read none of the float64 geometry (``on_demand``: a float32 state's steps
read their float32 copies, ``model.precision``), the device holds it only where something reads
it: the float64 values stay on the host (``values``: the grid's and the case's), a float type's
copies are rounded from them (``rounded``), an array a step reads is uploaded on its first read
and held, and the diagnostics' vorticity and divergence run on copies for one use (on a CPU the
host values themselves) and work arrays that are let go after: the same kernels and the same
bits as on held arrays (issue 128: the arrays a float32 run holds).
"""

from __future__ import annotations

import contextlib
from types import SimpleNamespace

import numpy as np
import warp as wp

from ..core.parallel import array_key
from ..kernels import operators
from .launches import check_updates
from .transposes import TendencyTranspose

f64 = wp.float64

# the float64 geometry the element kernels read, by name (``ElementOperators.values``): the grid's
# metric terms and frame, the case's Coriolis parameter and surface height, the topography's −g∇hs
GEOMETRY = ("D", "Dinv", "metdet", "xyz", "east", "north", "fcor", "hs", "forcing")
# the work arrays (rows of N) of the operators' element passes; "wind" the diagnostics' input
# (``rotation_divergence``), made on its first use alone
WORK = {"scalar": 1, "scalar_dss": 1, "vec_work": 2, "wind": 2}


class ElementOperators:
    """The DSS'd operators of ``grid`` (a ``CubedSphere``) assembled by ``topology`` on
    ``device``, their launches recorded in ``launches`` (the model's ``LaunchRecorder``);
    ``per_element``: the kernels' layout (an element a thread, else a node a thread); ``static_np``
    the np the per-node tendency and ∇⁴ kernels are compiled for (the grid's; 0, the per-element
    layout's, whose kernels take it otherwise). Compiled for np, their loops along an element's rows
    unroll and a node's indices divide by a constant: a step's graph 8 % faster for galewsky, 4 % for
    TC5 ne30 and as fast at ne120 on an H100, the same bits (issue 83 item 5; benchmarks/gpu/GPU.md).

    Arrays (device, element-local, N the grid's nodes): ``D``, ``Dinv`` (N, 2, 2; m and m⁻¹ per
    reference unit), ``metdet`` (N,), ``dvv`` (np, np), ``dvv_rows`` (the per-element kernels'
    ``dvv`` argument), ``xyz``, ``east``, ``north`` (N, 3; unit sphere), the case's Coriolis
    parameter ``fcor`` (N,; s⁻¹) and surface height ``hs`` (N,; m), with ``g`` (m s⁻²; None: no
    topography) the "topography" term's ``forcing`` −g∇hs (2, N; m s⁻²), and the work arrays
    ``scalar`` (1, N), ``scalar_dss`` (1, N) and ``vec_work`` (2, N): uploaded at the build, or
    with ``on_demand`` each on its first read (the module's note); ``geometry`` the names of those
    it holds (``GEOMETRY``'s; "forcing" with ``g``), their float64 values on the host ``values``."""

    def __init__(
        self, grid, topology, launches, per_element: bool, device: str, fcor, hs, g=None, on_demand: bool = False
    ):
        self.grid, self.topology, self.launches, self.per_element = grid, topology, launches, bool(per_element)
        self.device, self.on_demand = device, bool(on_demand)
        self.static_np = 0 if self.per_element else grid.np
        self.N = grid.nnodes
        self.dvv = wp.array(np.ascontiguousarray(grid.rule.dvv), dtype=f64, device=device)
        self.dvv_rows = operators.dvv_matrix(grid.rule.dvv)
        geometry = (grid.D, grid.Dinv, grid.metdet, grid.xyz, grid.east, grid.north)
        # the float64 values not yet uploaded (the grid's own arrays, and copies of the case's fields)
        self._host = {k: np.ascontiguousarray(a, dtype=float) for k, a in zip(GEOMETRY, geometry)}
        self._host.update(fcor=np.array(fcor, dtype=float), hs=np.array(hs, dtype=float))
        if g is not None:  # the "topography" term's −g∇hs, the gradient of hs by the element's operator
            hs2, forcing = self.one_use("hs").reshape((1, self.N)), wp.zeros((2, self.N), dtype=f64, device=device)
            inputs = [hs2, 0, self.one_use("Dinv"), self.dvv, grid.np, forcing, 0]
            wp.launch(operators.gradient_sphere, self.N, inputs, device=device)
            self._host["forcing"] = -float(g) * forcing.numpy()
        self.geometry = tuple(self._host)  # the names held, on the device or the host
        if not self.on_demand:  # the steps read them: uploaded now
            for name in (*self.geometry, "scalar", "scalar_dss", "vec_work"):
                getattr(self, name)

    def __getattr__(self, name: str):
        """A float64 device array of ``geometry`` (from its host values, let go then) or a work
        array of ``WORK``, made on its first read and held from then on (an attribute like the
        others)."""
        host = self.__dict__.get("_host", {})
        if name in host:
            value = wp.array(host.pop(name), dtype=f64, device=self.device)
        elif name in WORK:
            value = wp.zeros((WORK[name], self.N), dtype=f64, device=self.device)
        else:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        setattr(self, name, value)
        return value

    def values(self, name: str) -> np.ndarray:
        """The float64 values of the geometry ``name`` (``GEOMETRY``; ``geometry`` holds it) on the
        host: the device array's where uploaded (on a CPU a view), else the host's."""
        return self.__dict__[name].numpy() if name in self.__dict__ else self._host[name]

    def one_use(self, name: str) -> wp.array:
        """The float64 geometry ``name`` on the device for one use: the held array where there is
        one, else a copy not kept (on a CPU the host values themselves, no copy)."""
        if name in self.__dict__:
            return self.__dict__[name]
        return wp.array(self._host[name], dtype=f64, device=self.device, copy=False)

    def rounded(self, name: str, dtype) -> wp.array:
        """The geometry ``name`` as ``dtype``'s kernels read it: under float64 the device array
        (uploaded on first read), else a copy rounded once from the float64 values (``values``)."""
        if dtype is f64:
            return getattr(self, name)
        return wp.array(self.values(name), dtype=dtype, device=self.device)

    def set_fcor(self, fcor: np.ndarray) -> None:
        """The Coriolis parameter (N,; s⁻¹) set in place, on the device where uploaded (the
        launches read it there), else on the host: a shared ensemble's members' own, after the build."""
        if "fcor" in self.__dict__:
            self.fcor.assign(np.asarray(fcor, dtype=float))
        else:
            self._host["fcor"][:] = fcor

    @contextlib.contextmanager
    def hs_as(self, hs: wp.array):
        """``hs`` (N,; m) standing for the surface height inside the block (zeros: the ∇⁴ operator
        without its hs offset, as ``Hyperviscosity.biharmonic_radius`` and the adjoint's substeps
        record it), the case's put back after, however the block ends."""
        saved, self.hs = self.hs, hs
        try:
            yield
        finally:
            self.hs = saved

    def tendency_transpose(self, terms: tuple, g: float) -> TendencyTranspose:
        """A transpose of the tendency of ``terms`` at gravity ``g`` (m s⁻²) on these operators'
        arrays, with work arrays of its own (``model.transposes``): an adjoint's."""
        return TendencyTranspose(self, terms, g)

    def as_rows(self, a: wp.array) -> wp.array:
        """``a`` as the GLL rows the per-element kernels read and write (``kernels.operators.row_vectors``)."""
        return operators.row_vectors(a, self.grid.np)

    def _element_grad(self, x, row):
        """The launch of the element-local ∇ x[row] into ``vec_work``."""
        if self.per_element:
            return self.launches.elements(
                operators.gradient_element(self.grid.np),
                [self.as_rows(x), row, self.as_rows(self.Dinv), self.dvv_rows, self.as_rows(self.vec_work)],
            )
        return self.launches.nodes(
            operators.gradient_sphere, self.N, [x, row, self.Dinv, self.dvv, self.grid.np, self.vec_work]
        )

    def _element_div(self, x, frame=None, vorticity: bool = False):
        """The launch of the element-local ∇·v (``vorticity``: ζ = k·∇×v) of x's rows 0, 1 into
        ``scalar``: ``frame``'s (the arrays ``_diagnosed`` passes; None: these operators' own)."""
        f = self if frame is None else frame
        metric = f.D if vorticity else f.Dinv
        if self.per_element:
            kernel = (operators.vorticity_element if vorticity else operators.divergence_element)(self.grid.np)
            inputs = [*map(self.as_rows, (x, metric, f.metdet)), self.dvv_rows, self.as_rows(f.scalar.flatten())]
            return self.launches.elements(kernel, inputs)
        kernel = operators.vorticity_sphere if vorticity else operators.divergence_sphere
        return self.launches.nodes(kernel, self.N, [x, metric, f.metdet, self.dvv, self.grid.np, f.scalar.flatten()])

    def _build_grad(self, x, row, out):
        return [self._element_grad(x, row), *self.topology.dss(self.vec_work, 1, out)]

    def divergence_launches(self, x: wp.array2d, out: wp.array2d) -> list:
        """The launches (unrecorded by the model) of ``divergence(x, out)``: the element pass into
        ``scalar`` and its DSS (the ∇⁴'s δ when ν_div ≠ ν)."""
        return [self._element_div(x), *self.topology.dss(self.scalar, 1, out)]

    def gradient(self, x: wp.array2d, row: int, out: wp.array2d) -> None:
        """out (2, N) = G f = DSS(∇ x[row]) (units of x per m)."""
        self.launches.replay(
            ("grad", array_key(x), row, array_key(out)), (x, out), lambda: self._build_grad(x, row, out)
        )

    def divergence(self, x: wp.array2d, out: wp.array2d) -> None:
        """out (1, N) = D v = DSS(∇·v) of the wind in rows 0, 1 of x (s⁻¹ × units)."""
        self.launches.replay(("div", array_key(x), array_key(out)), (x, out), lambda: self.divergence_launches(x, out))

    def dss_update(self, x: wp.array2d, updates) -> list:
        """The launches (unrecorded) of the weighted DSS of the element-local x (rows, N)
        written into one or two ``Update``s of all rows (``Topology.dss_update``; src None
        standing for the DSS'd x): what an operator's ``*_update`` ends with."""
        return self.topology.dss_update(x, [(u.out, u.terms) for u in updates])

    def gradient_update(self, x: wp.array2d, row: int, updates) -> None:
        """G x[row] = DSS(∇ x[row]) as ``gradient`` computes it, not stored but written,
        as its DSS makes it, into one or two ``Update(out, terms)`` of (2, N) arrays
        (row views such as ``z[0:2]``): out = Σ a·src over terms (a, src), src None
        standing for G x[row] (``Topology.dss_update``: one to three terms, at most two
        arrays). Outputs may alias x and the terms. Recorded once per arrays, the coefficients
        launch arguments (``LaunchRecorder.replay_updates``)."""
        self.launches.replay_updates(
            ("grad_update", array_key(x), row),
            (x,),
            check_updates(updates),
            lambda u: [self._element_grad(x, row), *self.dss_update(self.vec_work, u)],
        )

    def divergence_update(self, x: wp.array2d, updates) -> None:
        """D v = DSS(∇·v) of x's rows 0, 1 as ``divergence`` computes it, written into
        one or two ``Update(out, terms)`` of (1, N) arrays as ``gradient_update``'s."""
        self.launches.replay_updates(
            ("div_update", array_key(x)),
            (x,),
            check_updates(updates),
            lambda u: [self._element_div(x), *self.dss_update(self.scalar, u)],
        )

    def assemble(self, x: wp.array2d, row: int, out: wp.array) -> None:
        """Unique-node out (nunique,) = M x[row]: assembled mass times a continuous field."""
        self.launches.replay(
            ("assemble", array_key(x), row, array_key(out)), (x, out), lambda: self.topology.assemble(x, row, out)
        )

    def scatter(self, y: wp.array, out: wp.array2d, row: int, rows: int = 1) -> None:
        """Element-local out[row : row + rows] from a unique-node vector y of ``rows`` rows."""
        self.launches.replay(
            ("scatter", array_key(y), array_key(out), row, rows),
            (y, out),
            lambda: self.topology.scatter(y, out, row, rows),
        )

    def _diagnosed(self, key, x, element, names) -> np.ndarray:
        """The DSS of ``element(x, frame)`` (the launch of an element pass into frame's ``scalar``),
        (N,) numpy: on the held arrays, recorded under ``key``; ``on_demand``, on a frame for one
        use (the geometry ``names`` by ``one_use``, its own work arrays), launched once and let go."""
        if not self.on_demand:
            build = lambda: [element(x), *self.topology.dss(self.scalar, 1, self.scalar_dss)]  # noqa: E731
            self.launches.replay(key, (x,), build)
            return self.scalar_dss.numpy()[0].copy()
        frame = SimpleNamespace(**{k: self.one_use(k) for k in names})
        frame.scalar, out = (wp.zeros((1, self.N), dtype=f64, device=self.device) for _ in range(2))
        for launch in [element(x, frame), *self.topology.dss(frame.scalar, 1, out)]:
            launch.launch()
        return out.numpy()[0].copy()

    def vorticity(self, x: wp.array2d) -> np.ndarray:
        """Relative vorticity ζ (s⁻¹), (N,) numpy, with the model's operator and a DSS."""
        element = lambda x, frame=None: self._element_div(x, frame, vorticity=True)  # noqa: E731
        return self._diagnosed(("vort", array_key(x)), x, element, ("D", "metdet"))

    def wind_divergence(self, x: wp.array2d) -> np.ndarray:
        """Divergence δ = ∇·v (s⁻¹) of the wind in rows 0, 1 of x, (N,) numpy: the
        operator the model steps with (``divergence``), DSS'd."""
        return self._diagnosed(("wind_div", array_key(x)), x, self._element_div, ("Dinv", "metdet"))

    def rotation_divergence(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(2, N) ζ and δ (s⁻¹) of the continuous wind u, v ((N,) each, m s⁻¹, on the host) by
        ``vorticity`` and ``wind_divergence``: the wind in the work array ``wind``, or
        ``on_demand`` in a copy for one use."""
        if self.on_demand:
            x = wp.array(np.stack([u, v]), dtype=f64, device=self.device, copy=False)
        else:
            x = self.wind
            x.assign(np.stack([u, v]))
        return np.stack([self.vorticity(x), self.wind_divergence(x)])
