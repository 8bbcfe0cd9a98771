"""Scores of a run: its fields against the truth, against a same-grid run, and its stability.

The truth of a case is its exact solution (TC1, TC2, TC4, Läuter) or else a
spectral reference (``reference``: the case's bundled T213 file, or the file
the scene chose, ``Scene.reference_file``; at the days the file stores). A
``Scorer`` owns the truth of one run and turns fields into normalized errors
(Williamson et al. 1992, eqs. 82–87), with the wind error split into its
vorticity (balanced flow) and divergence (gravity waves) by the model's own
operators. ``Simulation`` scores every output time with it; ``sweep`` scores
the states it keeps (total, temporal and time-filtered errors) and, with
``stability``, judges stability by ``instability``.

All fields are element-local (N,) and continuous, so an area integral is
``Σ spheremp·f`` (``CubedSphere.integrate``, HOMME ``global_integral``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..core.constants import DAY
from ..grid.cubed_sphere import CubedSphere
from ..grid.quality import REGIONS, element_regions, element_sizes
from .reference import Reference, stored_days, stored_index

ENERGY_GROWTH_LIMIT = 0.01  # a run whose total energy grows by more than this fraction is unstable


def williamson_norms(grid: CubedSphere, f, f_true) -> dict[str, float]:
    """Normalized l1, l2, l∞ errors of a scalar (Williamson et al. 1992, eqs. 82–84):
    l1 = I|f−fT| / I|fT|, l2 = sqrt(I(f−fT)²)/sqrt(I fT²), l∞ = max|f−fT| / max|fT|."""
    e = f - f_true
    I = grid.integrate
    return {
        "l1": I(np.abs(e)) / I(np.abs(f_true)),
        "l2": float(np.sqrt(I(e * e) / I(f_true * f_true))),
        "linf": float(np.max(np.abs(e)) / np.max(np.abs(f_true))),
    }


def regional_ratio(grid: CubedSphere, squared_error, squared_scale, node_regions) -> dict[str, float]:
    """sqrt(I_R e²) / sqrt(I_R n²) over each region's elements (``quality.REGIONS``,
    ``quality.element_regions``), I_R the area integral over region R's elements, of the
    squared error e² ``squared_error`` and squared scale n² ``squared_scale`` ((N,)
    element-local each); ``node_regions`` (N,) each node's region, its element's (None: a mesh
    of one resolution, every region NaN); NaN for a region without elements."""
    out = dict.fromkeys(REGIONS, math.nan)
    if node_regions is None:
        return out
    for k, name in enumerate(REGIONS):
        inside = node_regions == k
        if inside.any():
            out[name] = float(np.sqrt(grid.integrate(inside * squared_error) / grid.integrate(inside * squared_scale)))
    return out


def regional_l2(grid: CubedSphere, f, f_true, node_regions) -> dict[str, float]:
    """The normalized l2 error of a scalar over each region's elements (``regional_ratio``):
    sqrt(I_R(f−fT)²) / sqrt(I_R fT²) (Williamson et al. 1992, eq. 83, on a part of the sphere).
    ``f``, ``f_true`` (N,) element-local; ``node_regions`` as ``regional_ratio``'s."""
    return regional_ratio(grid, (f - f_true) ** 2, f_true * f_true, node_regions)


def williamson_vector_norms(grid: CubedSphere, u, v, u_true, v_true) -> dict[str, float]:
    """Normalized l1, l2, l∞ errors of the wind (Williamson et al. 1992, eqs. 85–87),
    with |·| the length of the vector difference."""
    I = grid.integrate
    de = np.hypot(u - u_true, v - v_true)
    dt = np.hypot(u_true, v_true)
    return {
        "l1": I(de) / I(dt),
        "l2": float(np.sqrt(I(de * de) / I(dt * dt))),
        "linf": float(np.max(de) / np.max(dt)),
    }


def rotational_divergent_errors(grid: CubedSphere, zeta_err, delta_err, zeta_true, delta_true) -> dict[str, float]:
    """Normalized l2 errors of relative vorticity (the balanced flow) and of
    divergence (gravity waves): sqrt(I ζe²) / n and sqrt(I δe²) / n with
    n = sqrt(I(ζT² + δT²)), the true wind's velocity-gradient scale. One
    normaliser for both (the true divergence may vanish, as on TC2), so that
    their squares add up to the error of the wind's gradient in the same units.
    ``zeta_err``, ``delta_err`` (s⁻¹, (N,)): vorticity and divergence of the
    wind error; ``zeta_true``, ``delta_true``: those of the true wind."""
    I = grid.integrate
    n = np.sqrt(I(zeta_true**2 + delta_true**2))
    return {"l2_vorticity": float(np.sqrt(I(zeta_err**2)) / n), "l2_divergence": float(np.sqrt(I(delta_err**2)) / n)}


def instability(result) -> str:
    """Why a run (``simulation.RunResult``, a blow-up's partial one included) counts
    as unstable: its blow-up message, or its total energy grown by more than
    ``ENERGY_GROWTH_LIMIT`` at an output time; "" for a stable run."""
    if result.blowup is not None:
        return result.blowup
    growth = max(h.get("total_energy_change", 0.0) for h in result.history)
    return f"total energy grew by {growth:.2%}" if growth > ENERGY_GROWTH_LIMIT else ""


def truth(case, reference) -> str:
    """What a run of ``case`` is scored against, for output attributes: "exact
    solution", the file name of ``reference`` (a path: ``Scene.reference_file``),
    or "none"."""
    if case.exact_solution:
        return "exact solution"
    return "none" if reference is None else Path(reference).name


def unscored(case, day: float, reference) -> str | None:
    """Why the truth cannot score a state of ``case`` (a ``cases.Case``) at ``day``,
    in one line: the reference file ``reference`` (a path: ``Scene.reference_file``)
    does not store that day (the bundled T213 files store a few whole days: TC5 0,
    1, 2, 5, 10, 15), or the case has neither an exact solution nor a reference
    (``reference`` None). None when it can."""
    if case.exact_solution:
        return None
    if reference is None:
        return "the case has no exact solution and no reference file (case.reference names one)"
    path = Path(reference)
    days = stored_days(path)
    if stored_index(days, day) is not None:
        return None
    return f"{path.name} stores days {', '.join(f'{d:g}' for d in days)}, not day {day:g}"


class Scorer:
    """The truth of one run and its scores. Build and call on every rank (the
    wind-error split and the reference's hand-out are collective); the figures
    come back on every rank.

    ``case``: the run's ``cases.Case``; ``model``: its ``ShallowWater``, whose
    vorticity and divergence operators split wind errors; ``topology``: its
    ``Topology``; ``grid``: the whole grid on rank 0 (None elsewhere,
    ``Topology.whole_grid``); ``hs``: the whole-grid surface height (m, (nnodes,),
    rank 0); ``reference``: the path of the reference file to score against
    (``Scene.reference_file``), read on rank 0, or None (a case scored against
    its exact solution, or one without a truth). Raises ``FileNotFoundError`` or
    ``ValueError`` for a file that is not a reference (``reference.Reference``).

    Attributes: ``reference`` (``reference.Reference`` on rank 0, else None),
    ``reference_days`` (its stored days on every rank, None without one),
    ``node_regions`` (each whole-grid node's region (nnodes,), its element's
    ``quality.element_regions``, on rank 0 of a mesh of several resolutions; else None).
    """

    def __init__(self, case, model, topology, grid, hs, reference):
        self.case, self.model, self.topology, self.grid, self.hs = case, model, topology, grid, hs
        self.root = topology.comm.rank == 0
        self.reference = Reference(reference) if reference is not None and self.root else None
        self.reference_days = topology.bcast(self.reference.days if self.reference is not None else None)
        self._last = None  # (day, the reference there on the whole grid): the start is scored twice
        self.node_regions = None
        if topology.grid.mesh is not None:  # the equiangular cube is one resolution
            Dinv = topology.gather(topology.grid.Dinv)  # rank 0's whole grid is gathered, without a metric
            regions = element_regions(element_sizes(grid, Dinv)) if self.root else None
            if regions is not None:
                self.node_regions = np.repeat(regions, grid.np**2)  # element-local nodes, element by element

    # -- vorticity and divergence ---------------------------------------------------
    def rotation_divergence(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """Relative vorticity and divergence (s⁻¹, (nnodes,) each, whole grid, on rank 0;
        None elsewhere) of a continuous wind given on this rank's nodes (m s⁻¹,
        (N,) each; the whole grid on one rank), by the model's operators + DSS."""
        a = self.topology.gather(self._rotation_divergence(u, v))
        return (None, None) if a is None else (a[0], a[1])

    def _rotation_divergence(self, u, v) -> np.ndarray:
        """(2, N): ``rotation_divergence`` on this rank's nodes, before the gather."""
        return self.model.operators.rotation_divergence(u, v)

    def wind_error_decomposition(self, u, v, u_true, v_true, regions: bool = False) -> dict:
        """``l2_vorticity``, ``l2_divergence``: the wind error split into its
        rotational (balanced-flow) and divergent (gravity-wave) parts, as the
        vorticity and divergence of v − vT by the model's operators (one operator
        on both sides, so the derivative's own discretisation error cancels),
        normalized as in ``rotational_divergent_errors``. ``regions``: also the
        divergent part by region (``regional_ratio``: each region's sqrt(I_R δe²)
        over its own sqrt(I_R(ζT² + δT²))) as ``l2_divergence_refined``,
        ``l2_divergence_transition``, ``l2_divergence_coarse`` (NaN without regions).
        Winds on this rank's nodes (N,)."""
        a = self.topology.gather(
            np.concatenate(
                [self._rotation_divergence(u - u_true, v - v_true), self._rotation_divergence(u_true, v_true)]
            )
        )  # (error, true) × (ζ, δ)
        d = None
        if self.root:
            d = rotational_divergent_errors(self.grid, *a)
            if regions:
                by_region = regional_ratio(self.grid, a[1] ** 2, a[2] ** 2 + a[3] ** 2, self.node_regions)
                d.update({f"l2_divergence_{k}": val for k, val in by_region.items()})
        return self.topology.bcast(d)

    # -- against the truth ----------------------------------------------------------
    def errors(self, t: float, x: np.ndarray, u, v, h, regions: bool = False) -> dict:
        """Errors of a state at time ``t`` (s) against the truth: with an exact
        solution ``l1_h``, ``l2_h``, ``linf_h``, ``l1_wind``, ``l2_wind``,
        ``linf_wind``, ``l2_vorticity``, ``l2_divergence``; with a reference the
        same of h + hs and the wind as ``ref_l1_h_surface`` … ``ref_linf_wind``,
        ``ref_l2_vorticity``, ``ref_l2_divergence`` and ``ref_l2_vorticity_eq83`` (Williamson et al.
        1992 eq. 83 of the vorticity: the state's by the model's operators against the reference's
        own at the nodes, ``williamson_norms``; the measure other models publish), NaN at a day it does not
        store (``unscored`` says why; every output time has every series); {}
        for a case with neither. ``regions``: also the l2 of h (h + hs) by region
        (``regional_l2``) as ``l2_h_refined``, ``l2_h_transition``, ``l2_h_coarse``
        (``ref_l2_h_surface_refined`` …; NaN without regions), and the divergence's
        (``wind_error_decomposition``) as ``l2_divergence_refined`` … (``ref_l2_divergence_refined`` …). ``x``: the state on this
        rank's nodes (3, N) (u, v in m s⁻¹, h in m); ``u``, ``v``, ``h``: the same on the
        whole grid (nnodes,) on rank 0 (None elsewhere)."""
        local = self.topology.grid
        split = ref_split = None
        if self.case.exact_solution:
            ue, ve, _ = self.case.exact(local.lat, local.lon, t)
            split = self.wind_error_decomposition(x[0], x[1], ue, ve, regions)
        r = None  # the reference interpolated to the whole grid, on rank 0, at a day it stores
        if self.reference_days is not None and stored_index(self.reference_days, t / DAY) is not None:
            r = self._reference_at(t / DAY) if self.root else None
            ur, vr = self.topology.distribute(np.stack([r["u"], r["v"]]) if self.root else None, 2, "reference wind")
            ref_split = self.wind_error_decomposition(x[0], x[1], ur, vr, regions)
            zeta = self.rotation_divergence(x[0], x[1])[0]  # the run's own vorticity, as its file writes it
        d = None
        if self.root:
            d = {}
            if self.case.exact_solution:
                ue, ve, he = self.case.exact(self.grid.lat, self.grid.lon, t)
                d.update({f"{k}_h": val for k, val in williamson_norms(self.grid, h, he).items()})
                if regions:
                    d.update({f"l2_h_{k}": val for k, val in regional_l2(self.grid, h, he, self.node_regions).items()})
                d.update({f"{k}_wind": val for k, val in williamson_vector_norms(self.grid, u, v, ue, ve).items()})
                d.update(split)
            if self.reference is not None:
                d.update(self._reference_errors(u, v, h, r, ref_split))
                if r is not None:  # Williamson eq. 83 of the vorticity, as the peers score it
                    d["ref_l2_vorticity_eq83"] = williamson_norms(self.grid, zeta, r["vorticity"])["l2"]
                if regions:
                    truth = None if r is None else r["h_surface"]
                    d.update({f"ref_l2_h_surface_{k}": val for k, val in self._regional(h + self.hs, truth).items()})
        return self.topology.bcast(d)

    def _reference_at(self, day: float) -> dict:
        """The reference's fields on the whole grid at a stored ``day`` (``Reference.at``; rank
        0), the last day's kept: a run scores its start at set-up and again as its file's first
        time, and the synthesis is a third of a start's scoring."""
        if self._last is None or self._last[0] != day:
            self._last = (day, self.reference.at(day, self.grid.lat, self.grid.lon))
        return self._last[1]

    def _regional(self, f, f_true) -> dict:
        """``regional_l2`` of ``f`` against ``f_true`` on the whole grid (all NaN for ``f_true`` None:
        a day the reference does not store)."""
        if f_true is None:
            return dict.fromkeys(REGIONS, math.nan)
        return regional_l2(self.grid, f, f_true, self.node_regions)

    def _reference_errors(self, u, v, h, r, split) -> dict:
        """Normalized errors of the free surface h + hs and of the wind against the
        reference ``r`` on the whole grid, with the wind error's parts ``split``
        (NaN at days the reference does not store: ``r`` None)."""
        names = [f"ref_{k}_{f}" for f in ("h_surface", "wind") for k in ("l1", "l2", "linf")]
        names += ["ref_l2_vorticity", "ref_l2_divergence"]
        if r is None:
            return dict.fromkeys([*names, "ref_l2_vorticity_eq83"], float("nan"))
        out = {f"ref_{k}_h_surface": val for k, val in williamson_norms(self.grid, h + self.hs, r["h_surface"]).items()}
        out.update(
            {f"ref_{k}_wind": val for k, val in williamson_vector_norms(self.grid, u, v, r["u"], r["v"]).items()}
        )
        out.update({f"ref_{k}": val for k, val in split.items()})
        return out

    def total_errors(self, t: float, x: np.ndarray) -> dict:
        """A sweep's total errors of state ``x`` (this rank's (3, N)) at time ``t`` (s):
        l2 of h (exact solution) or of h + hs (reference) as ``total_error``, the same by
        region (``regional_l2``: ``total_error_refined``, ``total_error_transition``,
        ``total_error_coarse``; NaN on a mesh of one resolution), and of the wind's vorticity
        and divergence (``total_error_vorticity``, ``total_error_divergence``), the divergence's
        by region too (``total_error_divergence_refined`` …); NaN where ``unscored``. Against a
        reference the vorticity's is Williamson's eq. 83 (``ref_l2_vorticity_eq83``), the measure
        the peers publish and ``benchmarks/peers/peer_dinosaur.py`` scores every model by, so that a
        frontier and the peers are read on one scale (the curl of the wind error,
        ``ref_l2_vorticity``, is 6–8 % below it at np 8: issue 81)."""
        whole = self.topology.gather(x)
        d = self.errors(t, x, *((None,) * 3 if whole is None else whole[:3]), regions=True)
        pre, h = ("", "l2_h") if "l2_h" in d else ("ref_", "ref_l2_h_surface")
        return {
            "total_error": d.get(h, math.nan),
            **{f"total_error_{k}": d.get(f"{h}_{k}", math.nan) for k in REGIONS},
            "total_error_vorticity": d.get("ref_l2_vorticity_eq83" if pre else "l2_vorticity", math.nan),
            "total_error_divergence": d.get(f"{pre}l2_divergence", math.nan),
            **{f"total_error_divergence_{k}": d.get(f"{pre}l2_divergence_{k}", math.nan) for k in REGIONS},
        }

    # -- against a same-grid run ------------------------------------------------------
    def _against(self, x: np.ndarray, x_ref: np.ndarray) -> tuple[float, float, dict, dict]:
        """(l2 of h + hs, l2 of the wind, the wind error's split with its divergence by region,
        l2 of h + hs by region (``regional_l2``)) of state ``x`` against ``x_ref`` (this rank's
        (3, N) each), on every rank."""
        a, b = self.topology.gather(x), self.topology.gather(x_ref)
        split = self.wind_error_decomposition(x[0], x[1], x_ref[0], x_ref[1], regions=True)
        norms = None
        if self.root:
            surface, surface_ref = a[2] + self.hs, b[2] + self.hs
            norms = (
                williamson_norms(self.grid, surface, surface_ref)["l2"],
                williamson_vector_norms(self.grid, a[0], a[1], b[0], b[1])["l2"],
                regional_l2(self.grid, surface, surface_ref, self.node_regions),
            )
        h, wind, by_region = self.topology.bcast(norms)
        return h, wind, split, by_region

    def temporal_errors(self, x: np.ndarray, x_ref: np.ndarray) -> dict:
        """Temporal errors of a run's state ``x`` against the same-grid small-Δt
        run's ``x_ref`` at the same time (this rank's (3, N) each): l2 of h + hs
        (``temporal_error``), the same by region (``regional_l2``, each region's l2 normalized
        by the small-Δt run's ∫(h + hs)² over its elements: ``temporal_error_refined``,
        ``temporal_error_transition``, ``temporal_error_coarse``; NaN on a mesh of one
        resolution), of the wind (``temporal_error_wind``) and of its vorticity and
        divergence (``temporal_error_vorticity``, ``temporal_error_divergence``), the
        divergence's by region too (``temporal_error_divergence_refined`` …)."""
        h, wind, split, by_region = self._against(x, x_ref)
        return {
            "temporal_error": h,
            **{f"temporal_error_{k}": val for k, val in by_region.items()},
            "temporal_error_wind": wind,
            "temporal_error_vorticity": split["l2_vorticity"],
            "temporal_error_divergence": split["l2_divergence"],
            **{f"temporal_error_divergence_{k}": split[f"l2_divergence_{k}"] for k in REGIONS},
        }

    def filtered_errors(self, xf: np.ndarray | None, xf_ref: np.ndarray | None) -> dict:
        """l2 of the difference of two time-filtered states (``timefilter.TimeFilter``:
        a run's and the small-Δt run's, this rank's (3, N) each) in h + hs
        (``temporal_error_filtered``) and in its wind's vorticity
        (``temporal_error_filtered_vorticity``); NaN without both."""
        if xf is None or xf_ref is None:
            return {"temporal_error_filtered": math.nan, "temporal_error_filtered_vorticity": math.nan}
        h, _, split, _ = self._against(xf, xf_ref)
        return {"temporal_error_filtered": h, "temporal_error_filtered_vorticity": split["l2_vorticity"]}
