"""What a simulation tells about its state: its fields gathered on rank 0, their
invariants, errors and Courant numbers, its run file's attributes, a log line and a stability
warning."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..cases.scoring import truth
from ..core.arguments import got
from ..core.errors import ArgumentError
from ..integrator.core import forwarded, trouble_line
from ..io.run_file import area_rms, member_statistics
from ..members import initial
from ..model.diagnostics import courant_numbers, invariants
from .checkpoint import branch_attrs
from .writers import scene_attrs


@dataclass
class WholeFields:
    """One state's fields gathered on rank 0 (``StateDiagnostics.gather_fields``): u, v
    (m s⁻¹), h (m), vorticity and, when asked for, divergence (s⁻¹, DSS'd), (nnodes,)
    each on rank 0 and None on the other ranks (divergence None when not asked for), and the
    tracers' masses hq (m; (K, nnodes), the scene's [tracers]; None without).
    Every rank holds one: whether a rank gathers is decided by whether it was
    given one, never by its contents, so all ranks take the same collectives."""

    u: np.ndarray | None
    v: np.ndarray | None
    h: np.ndarray | None
    vorticity: np.ndarray | None
    divergence: np.ndarray | None = None
    masses: np.ndarray | None = None


class MemberAxis:
    """What a run's state-and-diagnostics object answers of its N members alike (a single run's
    ``StateDiagnostics``, N = 1, and ``members.Members``), the member axis first: its Courant
    numbers, stability limit and warning, and the spread of h. A subclass gives ``run`` (its
    ``run_state.RunState``), ``grid`` (the whole grid on rank 0), ``root``, ``bcast``, ``states()``,
    ``fields()`` ((u, v, h) (N, n) each on rank 0) and ``member_g()`` (each member's g, m s⁻², on
    every rank; collective)."""

    def courant(self) -> list[dict]:
        """Each member's advective and gravity-wave Courant numbers at the run's Δt on its state now
        (``model.diagnostics.courant_numbers``), N dicts on every rank (collective)."""
        u, v, h = self.fields()
        g = self.member_g()
        return self.bcast([self._courant_numbers(*m, gk) for m, gk in zip(zip(u, v, h), g)] if self.root else None)

    def largest_dt_within_limit(self) -> list[float | None]:
        """Each member's Δt (s) at which its Courant number now reaches the stepper's measured
        stability limit (``stability_warning``'s); None for a stepper without one (collective)."""
        limits = [self._stability_limit(c) for c in self.courant()]
        return [None if limit is None else self._dt() * limit[0] / limit[2] for limit in limits]

    def stability_warning(self) -> list[str | None]:
        """Each member's one-line warning where Δt exceeds the stepper's measured stability limit
        on its state now (``largest_dt_within_limit``), else None (collective)."""
        return [self._warning(self._stability_limit(c)) for c in self.courant()]

    def h_spread_rms(self) -> float:
        """The members' spread of h now (m): the area-weighted RMS over the sphere of their
        standard deviation (``io.run_file.member_statistics``, ``area_rms``; 0 for one member), the
        run file's ``h_spread_rms`` (collective)."""
        h = self.states()[:, 2]
        return self.bcast(area_rms(self.grid, member_statistics(self.grid.to_unique(h))[1]) if self.root else None)

    def _states_argument(self, states, n: int, rows: int = 3) -> np.ndarray:
        """``set_states``' ``states`` as a float array (N, ``rows``, ``n``), else ``ArgumentError`` naming it."""
        try:
            states = np.asarray(states, dtype=float)
        except (TypeError, ValueError):
            raise ArgumentError(f"states must be numbers (m s⁻¹ and m) (got {got(states)})") from None
        if states.shape != (len(self), rows, n):
            raise ArgumentError(f"states must have shape {(len(self), rows, n)} (got {states.shape})")
        return states

    def _stability_limit(self, c: dict) -> tuple[float, str, float, str] | None:
        """(limit, what it limits, its value at the scene's dt for the Courant numbers ``c``, its
        source) of the stepper's stability limit, measured or a table's from its stability polynomial
        (``Stepper.courant_limit`` on (|v| + √(gh)) Δt/Δx for explicit steppers,
        ``advective_courant_limit`` on |v| Δt/Δx for IMEX and multirate), or None without one."""
        kind = self.run.stepper  # the instance: a table's limit is its own (``TableauRK``)
        if kind.courant_limit is not None:
            speed = c["courant_advective"] + (0.0 if math.isnan(c["courant_gravity"]) else c["courant_gravity"])
            return kind.courant_limit, "a Courant number (|v| + sqrt(g h)) dt/dx", speed, kind.courant_limit_source
        if kind.advective_courant_limit is not None:
            source = "its explicit advection's, measured on TC5, TC6 and Galewsky"
            return kind.advective_courant_limit, "an advective Courant number |v| dt/dx", c["courant_advective"], source
        return None

    def _warning(self, limit: tuple | None) -> str | None:
        """The stability warning of a member's ``_stability_limit``, None where it is kept."""
        if limit is None or limit[2] <= limit[0]:
            return None
        limit, what, speed, source = limit
        stepper = self.run.stepper.label(self.run.scene.stepper_options)  # a table by its name
        if limit == 0:
            return (
                f"warning: {stepper} is stable on no stretch of the imaginary axis (its stability polynomial "
                "has |R(iy)| > 1 for every y > 0): waves grow at every dt, held back only by hyperviscosity; it "
                "may blow up (three-stage third-order tables are stable to y = 1.73)"
            )
        dt = self._dt()
        return (
            f"warning: dt = {dt:g} s gives {what} of {speed:.3g}, above "
            f"{stepper}'s stability limit of about {limit:.3g} ({source}); it may blow up "
            f"(dt <= {dt * limit / speed:.4g} s keeps below)"
        )

    def _dt(self) -> float:
        """The run's dt (s): the scene's, or under step control the controller's current one (the
        step it goes on with, not one cut short to land on an output time)."""
        return self.run.scene.dt if self.run.control is None else self.run.control.dt

    def _courant_numbers(self, u, v, h, g: float) -> dict:
        """``diagnostics.courant_numbers`` at the run's dt (``_dt``) on whole-grid fields (rank 0)."""
        pressure = "pressure_gradient" in self.run.scene.terms  # gravity waves only with the pressure gradient term
        return courant_numbers(self.grid, u, v, h, self._dt(), g, pressure)


class StateDiagnostics(MemberAxis):
    """The diagnostics of a run's state, held by a ``Simulation`` as ``Simulation.diagnostics``:
    they read the run's state ``run`` (a ``run_state.RunState``: its x, scene, stepper, step,
    control and ``initial`` as they are at the call, a fitted Δt, a restored state) and its built
    parts: ``model``, ``topology``, ``grid``, ``case``, ``scorer`` (the errors against the case's
    truth), ``hs`` and ``fcor`` (nnodes,) on rank 0, ``root`` (this rank is 0). Fields are
    gathered on rank 0, which diagnoses the whole grid (the same arithmetic on any number of
    ranks) and broadcasts the figures. What the driver asks of a run, of one member or N
    (``members.Members`` answers alike): its states, restart parts, a bad step's line, its run
    file's attributes, its last good state, its members dropped and its ranks."""

    # the run file's per-time series a run's (``writers.RunFiles``); no member dropped nor counted (a restart file's)
    series = drop = members = None
    dropped: dict = {}  # {member: step} dropped: none in a single run
    drops: list = []  # their lines

    def __init__(self, run, model, topology, grid, case, scorer, hs, fcor, root: bool):
        self.run, self.model, self.topology, self.grid, self.case = run, model, topology, grid, case
        self.scorer, self.hs, self.fcor, self.root = scorer, hs, fcor, root
        self.bcast, self.ranks = topology.bcast, topology  # rank 0's values on every rank; what signals ask

    def __len__(self) -> int:
        """N: one member."""
        return 1

    def states(self) -> np.ndarray:
        """(N, 3, n) float64: every member's u, v (m s⁻¹) and h (m) on the whole grid's element-local
        nodes (a row more for each tracer's mass hq), on every rank (collective)."""
        # a copy: on one process the gather is the device state's own memory, stepped on after
        return self.topology.bcast(self.topology.gather(self.run.x.numpy()))[None].copy()

    def set_states(self, states) -> None:
        """The state now from ``states`` (1, 3, n; a row more for each tracer's mass hq), as ``members.Members.set_states`` (rank 0's handed
        out over the ranks; the stepper goes on from it as from its own). ``ArgumentError`` for another
        shape, a state not finite or an h <= 0 of a depth, nothing set."""
        states = self._states_argument(states, self.topology.nnodes_total, self.model.rows)
        if self.root:
            initial.checked_states(states, self.case, "states", [0])
        self.run.x.assign(self.topology.distribute(states[0] if self.root else None, 3, "states"))

    def member_g(self) -> list[float]:
        """The member's g (m s⁻²)."""
        return [self.model.g]

    def invariants(self) -> list[dict[str, float]]:
        """The member's mass (m³), total energy (m⁵ s⁻²) and potential enstrophy (m s⁻²) now
        (``model.diagnostics.invariants``, as ``members.Members.invariants``; collective)."""
        w = self.gather_fields()
        d = invariants(self.grid, w.u, w.v, w.h, self.hs, w.vorticity, self.fcor, self.model.g) if self.root else None
        return [self.bcast(d)]

    def errors(self) -> list[dict[str, float]]:
        """The member's errors now against the case's truth, as the run file has them
        (``cases.scoring.Scorer.errors``: Williamson et al. 1992's normalized l1, l2, l∞; {} for a
        case with neither an exact solution nor a reference; collective)."""
        w, x = self.gather_fields(), self.run.x.numpy()
        return [self.bcast(self.scorer.errors(self.run.seconds(self.run.step), x, w.u, w.v, w.h))]

    def restart_parts(self) -> tuple | None:
        """(x, stepper state, t = 0 diagnostics, grid) of a restart file, gathered and the stepper's
        state taken on every rank (collective), on rank 0 (None on the others)."""
        x, state = self.topology.gather(self.run.x.numpy()), self.run.stepper.state()
        return (x, state, self.run.initial, self.grid) if self.root else None

    def describe(self, bad: tuple) -> str:
        """The line of a checked step gone bad, ``bad`` = (step, trouble, detail) of an
        ``integrator.core.Stop`` (``trouble_line``)."""
        day = self.run.time if self.run.control is not None else self.run.scene.day(bad[0])
        return trouble_line(self.model, self.run.x, bad, day)

    last_good = forwarded("run.core.units.0.start", "The state (3, N) at the start of the step or block.", False)

    def opening(self, files, start: WholeFields, history: str | None, name: str, dfi, device: str) -> tuple:
        """(the Courant numbers of ``start``, the first diagnostics (None: the files take them), the
        global attributes of the run's files, and what else ``RunFiles.open`` takes (none)) of a
        run's files ``files`` (``name`` an ensemble's): what ran (``writers.scene_attrs``), where (on
        ``device`` over the topology's MPI ranks), from which start (the digital filter ``dfi`` or
        None) and command line (``history``), and its Courant numbers at the start."""
        courant = self.bcast(self._courant_numbers(start.u, start.v, start.h, self.model.g) if self.root else None)
        s = self.run.scene
        attrs = {
            **scene_attrs(s, "run", history, "swe_sphere.Simulation.run"),
            **self.run.stepper.attrs(),  # e.g. which Butcher table ran
            "device": device,
            "mpi_ranks": self.topology.comm.size,
            "initialization": "none" if s.initialization is None else s.initialization["method"],
            "reference": truth(self.case, s.reference_file),  # what the error series are against
            # planet_radius (m), planet_omega (1/s), planet_gravity (m/s^2)
            **{f"planet_{k}": v for k, v in s.planet.items()},
            **(dfi.attrs(s.digital_filter) if dfi is not None else {}),
            **({"continued_from_day": self.run.time} if self.run.step else {}),
            **branch_attrs(s),
            **{k: v for k, v in courant.items() if math.isfinite(v)},
        }
        return courant, None, attrs, {}

    def fields(self) -> tuple:
        """u, v (m s⁻¹), h (m) (N, nnodes) of the whole grid, gathered on rank 0 (call on every rank;
        (None, None, None) on the others)."""
        a = self.topology.gather(self.run.x.numpy())
        return (None, None, None) if a is None else tuple(a[:3, None].copy())  # a copy, as ``states``

    def divergence(self) -> np.ndarray | None:
        """Divergence of the wind (N, nnodes) of the whole grid, DSS'd (s⁻¹), on rank 0 (None elsewhere)."""
        d = self.topology.gather(self.model.operators.wind_divergence(self.run.x))
        return None if d is None else d[None].copy()

    def gather_fields(self, x=None, divergence: bool = False) -> WholeFields:
        """u, v, h, the vorticity and (``divergence``) the divergence of state x
        (default the current one), in one gather on rank 0 (call on every rank)."""
        x = self.run.x if x is None else x
        state = x.numpy()
        rows = [state[:3], self.model.operators.vorticity(x)[None]]
        if divergence:
            rows.append(self.model.operators.wind_divergence(x)[None])
        rows.append(state[3:])  # the tracers' masses
        a = self.topology.gather(np.concatenate(rows))  # rows u, v, h, vorticity (, divergence), masses
        if a is None:
            return WholeFields(*([None] * 4))
        n = 5 if divergence else 4
        return WholeFields(*a[:n], **({"masses": a[n:]} if self.model.tracers else {}))

    def diagnose(self, t: float, x=None, whole: WholeFields | None = None) -> dict:
        """Invariants (and their relative change), errors against the truth
        (``scoring.Scorer.errors``) and Courant numbers, on every rank (call on
        every rank). ``whole``: x's ``gather_fields`` when the caller has them (on
        every rank, or on none)."""
        whole = self.gather_fields(x) if whole is None else whole
        errors = self.scorer.errors(t, (self.run.x if x is None else x).numpy(), whole.u, whole.v, whole.h)
        return self.topology.bcast(self._figures(whole, errors) if self.root else None)

    def _figures(self, whole: WholeFields, errors=()) -> dict:
        """The invariants of ``whole`` and their change relative to ``initial``, ``errors`` and the
        Courant numbers (rank 0)."""
        d = invariants(self.grid, whole.u, whole.v, whole.h, self.hs, whole.vorticity, self.fcor, self.model.g)
        if not self.case.h_is_depth:  # h is a tracer (TC1): only its mass is an invariant
            d = {"mass": d["mass"]}
        for (name, _), hq in zip(self.run.scene.tracers, () if whole.masses is None else whole.masses, strict=True):
            d[f"{name}_mass"] = float(self.grid.integrate(hq))  # ∫hq dA (m³), conserved as h's
        start = self.run.initial or d  # diagnosing the initial state itself
        d |= {f"{k}_change": (d[k] - start[k]) / abs(start[k]) for k in d}
        d.update(errors, **self._courant_numbers(whole.u, whole.v, whole.h, self.model.g))
        return d

    def log_line(self, d: dict | None = None) -> str | None:
        """One line on the current step, as HOMME prints every ``statefreq`` steps:
        step, model day, relative changes of mass, total energy and potential
        enstrophy since t = 0 and the largest advective and gravity-wave Courant
        numbers over the nodes. ``d``: the step's ``diagnose`` when the caller has
        it; else the fields are gathered here (the one device synchronisation).
        Call on every rank; None on the ranks > 0."""
        whole = self.gather_fields() if d is None else None  # on every rank
        if not self.root:
            return None
        d = self._figures(whole) if d is None else d
        names = {"mass_change": "mass", "total_energy_change": "energy", "potential_enstrophy_change": "enstrophy"}
        changes = "".join(f"  {name} {d[k]:+.3e}" for k, name in names.items() if k in d)
        grav = "" if math.isnan(d["courant_gravity"]) else f" gravity-wave {d['courant_gravity']:.3f}"
        return (
            f"step {self.run.step} day {self.run.time:.4f}{changes}  Courant advective "
            f"{d['courant_advective']:.3f}{grav}"
        )
