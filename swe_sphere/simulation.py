"""The time loop: build everything from a scene, step, guard, write, summarise."""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import warp as wp
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from . import __version__
from .config import Scene
from .constants import DAY
from .diagnostics import courant_numbers, invariants, williamson_norms, williamson_vector_norms
from .grid import CubedSphere
from .model import ShallowWater
from .output import RunWriter
from .reference import Reference, find_reference
from .steppers import StepFailure, make_stepper


class BlowUp(RuntimeError):
    """The state became non-finite or the depth non-positive; the message gives step, time and place."""


@dataclass
class RunResult:
    """What a run produced: final diagnostics, counts and timings."""

    steps: int
    rhs_evals: int
    wall_time: float
    setup_time: float
    diagnostics: dict
    courant: dict
    output: Path | None
    blowup: str | None = None
    history: list = field(default_factory=list)
    iterations: dict = field(default_factory=dict)


class Simulation:
    """Build the grid, case, model and stepper of a scene; ``run`` integrates it.

    ``device``: "cpu" or "cuda" (Warp device names). ``progress``: show a tqdm bar.
    """

    def __init__(self, scene: Scene, device: str, *, progress: bool = True):
        t0 = time.perf_counter()
        self.scene, self.device, self.progress = scene, device, progress
        self.grid = grid = CubedSphere(scene.ne, scene.np)
        self.case = case = scene.make_case()
        self.fcor = case.fcor(grid.lat, grid.lon)
        self.hs = case.hs(grid.lat, grid.lon)
        self.g = case.planet.g
        self.model = ShallowWater(
            grid, scene.terms, self.fcor, self.hs, nu=scene.nu, hypervis_subcycle=scene.hypervis_subcycle, g=self.g, device=device
        )
        self.stepper = make_stepper(scene.stepper, self.model, scene.dt, **scene.stepper_options)
        ref_path = find_reference(scene.case, scene.case_params.get("perturbed", True))
        self.reference = Reference(ref_path) if ref_path is not None else None
        u, v, h = case.initial(grid.lat, grid.lon)
        self.x = self.model.new_state(u, v, h)
        self.last_good = wp.clone(self.x)
        self.initial = None
        self.initial = self.diagnose(0.0)
        self.setup_time = time.perf_counter() - t0

    # -- diagnostics --------------------------------------------------------
    def fields(self, x=None):
        a = (self.x if x is None else x).numpy()
        return a[0], a[1], a[2]

    def diagnose(self, t: float, x=None) -> dict:
        """Invariants (and their relative change), errors against the exact solution if any."""
        u, v, h = self.fields(x)
        zeta = self.model.vorticity(self.x if x is None else x)
        d = invariants(self.grid, u, v, h, self.hs, zeta, self.fcor, self.g)
        if "pressure_gradient" not in self.scene.terms:  # h is a tracer (TC1), not a depth
            d = {"mass": d["mass"]}
        start = self.initial or d  # diagnosing the initial state itself
        for k in list(d):
            d[f"{k}_change"] = (d[k] - start[k]) / abs(start[k])
        if self.case.exact_solution:
            ue, ve, he = self.case.exact(self.grid.lat, self.grid.lon, t)
            d.update({f"{k}_h": val for k, val in williamson_norms(self.grid, h, he).items()})
            d.update({f"{k}_wind": val for k, val in williamson_vector_norms(self.grid, u, v, ue, ve).items()})
        if self.reference is not None:
            d.update(self._reference_errors(t / DAY, u, v, h))
        d.update(courant_numbers(self.grid, u, v, h, self.scene.dt, self.g, "pressure_gradient" in self.scene.terms))
        return d

    def _reference_errors(self, day, u, v, h) -> dict:
        """Normalized errors of the free surface h + hs and of the wind against the
        T213 reference (NaN at days the reference does not store)."""
        names = [f"ref_{k}_{f}" for f in ("h_surface", "wind") for k in ("l1", "l2", "linf")]
        if np.min(np.abs(self.reference.days - day)) > 1e-6:
            return dict.fromkeys(names, float("nan"))
        r = self.reference.at(day, self.grid.lat, self.grid.lon)
        out = {f"ref_{k}_h_surface": val for k, val in williamson_norms(self.grid, h + self.hs, r["h_surface"]).items()}
        out.update({f"ref_{k}_wind": val for k, val in williamson_vector_norms(self.grid, u, v, r["u"], r["v"]).items()})
        return out

    def courant(self) -> dict:
        """Advective and gravity-wave Courant numbers of the scene's dt on the current state."""
        return courant_numbers(self.grid, *self.fields(), self.scene.dt, self.g, "pressure_gradient" in self.scene.terms)

    # -- the loop -----------------------------------------------------------
    def output_steps(self) -> set[int]:
        s = self.scene
        every = s.output_every_days * DAY / s.dt
        n_out = math.floor(s.days / s.output_every_days + 1e-9)
        return {min(s.nsteps, round(k * every)) for k in range(n_out + 1)} | {s.nsteps}

    def run(self, output: Path | None = None) -> RunResult:
        """Integrate the scene; write ``output`` (netCDF) if given.

        Raises ``BlowUp`` after closing the output with every good output time
        and the last good state (the step before the failure) appended.
        """
        s, model, stepper = self.scene, self.model, self.stepper
        courant = self.courant()
        solver_series = [f"{k}_iterations" for k in stepper.solvers]
        series = ["steps", "rhs_evals", *solver_series, "wall_time", *self.initial.keys()]
        writer = None
        if output is not None:
            attrs = {
                "title": f"swe_sphere run of scene {s.name}",
                "source": f"swe_sphere {__version__}",
                "swe_sphere_version": __version__,
                "scene": s.as_dict(),
                "case": s.case,
                "ne": s.ne,
                "np": s.np,
                "stepper": s.stepper,
                "dt": s.dt,
                "device": self.device,
                **{k: v for k, v in courant.items() if math.isfinite(v)},
            }
            writer = RunWriter(output, self.grid, self.hs, attrs, series)
        out_steps = self.output_steps()
        rhs_evals, wall, history, iterations = 0, 0.0, [], {k: 0 for k in stepper.solvers}

        def record(step, x=None):
            d = self.diagnose(step * s.dt, x)
            d.update(steps=step, rhs_evals=rhs_evals, wall_time=wall)
            d.update({f"{k}_iterations": iterations.get(k, 0) for k in stepper.solvers})
            history.append(d)
            if writer is not None:
                zeta = model.vorticity(self.x if x is None else x)  # DSS'd, element-local (s-1)
                writer.append(step * s.dt, *self.fields(x), {k: d[k] for k in series}, vorticity=zeta)

        # single-threaded BLAS: the Krylov solvers' vectors are too short for threads to
        # pay, and on a busy machine OpenBLAS's spinning threads made a norm cost 10 ms
        limits = threadpool_limits(limits=1, user_api="blas")
        try:
            record(0)
            bar = tqdm(total=s.nsteps, unit="step", disable=not self.progress, file=sys.stderr, dynamic_ncols=True)
            blowup = None
            with bar:
                for n in range(1, s.nsteps + 1):
                    t0 = time.perf_counter()
                    wp.copy(self.last_good, self.x)
                    try:
                        stats = stepper.step(self.x)
                        failure = None
                    except StepFailure as err:
                        stats, failure = None, str(err)
                    bad = model.first_bad_node(self.x) if failure is None else None
                    wp.synchronize_device(self.device)
                    wall += time.perf_counter() - t0
                    if stats is not None:
                        rhs_evals += stats.rhs_evals
                        for k, it in stats.iterations.items():
                            iterations[k] = iterations.get(k, 0) + it
                    if bad is not None or failure is not None:
                        blowup = self._blowup_message(n, bad) if failure is None else (
                            f"step {n} failed (model time {n * s.dt / DAY:.4f} days): {failure}"
                        )
                        if n - 1 not in out_steps:
                            record(n - 1, self.last_good)
                        if writer is not None:
                            writer.set_attrs(blowup=blowup)
                        break
                    if n in out_steps:
                        record(n)
                    bar.update(1)
                    if n % 50 == 0 or n == s.nsteps:
                        bar.set_postfix(day=f"{n * s.dt / DAY:.2f}", sim_days_per_s=f"{n * s.dt / DAY / max(wall, 1e-9):.3g}")
        except BaseException:
            if writer is not None:
                writer.abort()
            raise
        finally:
            limits.restore_original_limits()
        if writer is not None:
            writer.close()
        result = RunResult(
            steps=n if blowup is None else n - 1,
            rhs_evals=rhs_evals,
            wall_time=wall,
            setup_time=self.setup_time,
            diagnostics=history[-1],
            courant=courant,
            output=output,
            blowup=blowup,
            history=history,
            iterations=iterations,
        )
        if blowup is not None:
            err = BlowUp(blowup)
            err.result = result
            raise err
        return result

    def _blowup_message(self, step: int, p: int) -> str:
        u, v, h = self.fields()
        lat, lon = np.degrees(self.grid.lat[p]), np.degrees(self.grid.lon[p])
        what = "non-finite value" if not all(math.isfinite(f[p]) for f in (u, v, h)) else f"depth h = {h[p]:.4g} m <= 0"
        return (
            f"blow-up at step {step} (model time {step * self.scene.dt / DAY:.4f} days): {what} "
            f"at lat {lat:.2f}, lon {lon:.2f} degrees"
        )
