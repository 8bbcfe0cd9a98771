"""What ``swe-sphere run`` prints: the header before the loop (scene, grid, mesh
figures, stepper, Courant numbers, notes, outputs) and the summary after it."""

from __future__ import annotations

import math
import sys

MAX_DISTORTION = 4.0  # HOMME's print_cfl warns of elements more distorted than this (dx_long / dx_short)


def _mesh_lines(sim) -> list[str]:
    """HOMME's ``print_cfl`` figures of a run's mesh (rank 0; [] on the others; call on every
    rank): the Dinv-based node spacing (``grid.quality``), the largest distortion (a warning
    line above ``MAX_DISTORTION``), the area ratio and the worst element's Courant numbers."""
    from ..grid.quality import element_sizes
    from ..model.diagnostics import worst_element_courant

    u, v, h = sim.fields()
    Dinv = sim.topology.gather(sim.topology.grid.Dinv)  # rank 0's whole grid is gathered, without a metric
    if not sim.root:
        return []
    sizes = element_sizes(sim.grid, Dinv)
    s, scene = sizes.summary(), sim.scene
    c = worst_element_courant(sim.grid, sizes, u, v, h, scene.dt, sim.g, "pressure_gradient" in scene.terms)
    grav = "" if math.isnan(c["courant_gravity"]) else f"gravity-wave {c['courant_gravity']:.3f}, "
    lines = [
        f"mesh        node spacing (Dinv-based, the one dt scales with on a mesh) {s['dx_short_min'] / 1e3:.1f} to {s['dx_long_max'] / 1e3:.1f} km "
        f"(dx_short mean {s['dx_short_mean'] / 1e3:.1f} km), largest distortion {s['distortion_max']:.2f}, "
        f"area ratio {s['area_ratio']:.2f}",
        f"mesh        worst element {s['worst'] + 1} (dx_short {sizes.dx_short[s['worst']] / 1e3:.1f} km): Courant "
        f"{grav}advective {c['courant_advective']:.3f} (dt / dx_short)",
    ]
    if s["distortion_max"] > MAX_DISTORTION:
        e = int(sizes.distortion.argmax())
        lines.append(
            f"swe-sphere: warning: element {e + 1} is distorted {s['distortion_max']:.2f}x (dx_long / dx_short, above "
            f"HOMME's {MAX_DISTORTION:g}): its spacing is uneven and it sets a short explicit step"
        )
    return lines


def control_line(c, dt: float) -> str:
    """The header's line of a scene's step control (a ``SceneControl``; ``dt`` the scene's, s)."""
    from ..config.control import CFL_FRACTION

    what = "cfl"
    if c.mode == "error":
        what = (
            f"error: rtol {c.rtol:g}, atol {c.atol_wind:g} m/s (u, v) and {c.atol_h:g} m (h), controller {c.controller}"
        )
        what += ", the error per unit step (a day)" if c.per_unit_step else ""
    elif c.mode == "balanced":
        what = f"balanced: a step's error held to {c.balance:g} of the spatial error's estimated rate over it"
        what += f", controller {c.controller}"
    if c.mode == "cfl":
        cfl = "" if c.cfl is None else f", Courant target {c.cfl:g}"
    elif c.cfl is None:
        cfl = ", no Courant cap"
    else:
        cfl = f", Courant cap {c.cfl:.3g}"
        if c.cfl_default:
            cfl += f" (the default: {CFL_FRACTION:g} x the stepper's measured limit; -s time.cfl=false: none)"
    most = "" if c.dt_max is None else f", dt_max {c.dt_max:g} s"
    first = "dt above" if c.dt_max is None or c.dt_max >= dt else f"dt_max {c.dt_max:g} s"  # ``StepControl``'s clamp
    return f"{what}{cfl}; {first} is the first step, dt_min {c.dt_min:g} s{most}; steps land on the output times"


def header(args, sim, output, device, comm) -> None:
    """The lines before the loop (rank 0 prints; call on every rank: the mesh figures
    and the smallest spacing gather over ranks)."""
    from ..core.constants import EARTH

    scene = sim.scene
    c = sim.courant()
    dx = -sim.topology.max(-float(sim.topology.grid.dx.min()))
    mesh_lines = _mesh_lines(sim) if scene.mesh is not None else []  # every rank: it gathers the state
    print(f"scene       {scene.name}: {scene.description}")
    print(
        f"grid        {scene.grid_text}: {scene.nelem} elements, {sim.topology.grid.nunique} unique nodes"
        + ("" if mesh_lines else f", min node spacing {dx / 1e3:.1f} km")  # a mesh's: its Dinv-based line
    )
    if scene.planet != EARTH.as_table():
        p = scene.planet
        print(
            f"planet      radius {p['radius']:g} m, omega {p['omega']:g} 1/s, gravity {p['gravity']:g} m/s^2 "
            f"(the Earth's: {EARTH.a:g} m, {EARTH.omega:g} 1/s, {EARTH.g:g} m/s^2)"
        )
    for line in mesh_lines:
        print(line, file=sys.stderr if line.startswith("swe-sphere: warning") else sys.stdout)
    print(terms_line(scene))
    print(
        f"stepper     {sim.stepper.label(scene.stepper_options)}, dt = {scene.dt:g} s, {scene.nsteps} steps to day {scene.days:g}, device {device}"
    )
    for line in sim.stepper.describe():
        print(f"{scene.stepper:11s} {line}")
    print(precision_line(scene))
    if scene.control is not None:
        print(f"control     {control_line(scene.control, scene.dt)}")
    if comm is not None:
        sizes = [len(p) for p in sim.topology.parts]
        print(
            f"ranks       {comm.size} MPI ranks: {min(sizes)}-{max(sizes)} elements each along a space-filling curve, "
            f"{sim.model.threads} CPU threads each"
        )
    if sim.step:
        print(f"continue    from {args.continue_from} at step {sim.step} (day {sim.time:g})")
    elif args.continue_from is not None and scene.branch is not None:
        b = scene.branch
        print(
            f"branch      from {args.continue_from} at its step {b['step']} (day {b['day']:g}; {b['stepper']}, dt = {b['dt']:g} s): "
            f"{scene.stepper} starts there afresh"
        )
    _courant_notes_outputs(args, sim, output, c)


def precision_line(scene) -> str:
    """The header's ``precision`` line: the scene's (``Scene.precision``), float32 the tendency's and the ∇⁴'s."""
    between = "float64 between steps" if scene.compensated else "float32 between steps, h - H0"
    state = {
        "float32": " (tendency and hyperviscosity; state float64)",
        "float32_state": f" (tendency, hyperviscosity and a step's state and stages; state {between})",
    }.get(scene.precision, "")
    return f"precision   {scene.precision}{state}"


def terms_line(scene) -> str:
    """The header's ``terms`` line: the scene's terms, its ∇⁴ coefficient and its element filter."""
    every = f", every {scene.hypervis_every} steps" if scene.hypervis_every > 1 else ""
    nu = f" (nu = {scene.nu:.3g} m^4/s, subcycle {scene.hypervis_subcycle}{every})" if scene.nu else ""
    f = scene.element_filter
    filt = "" if f is None else f"; element filter mu = {f[0]:g}, p_bv = {f[1]:g}, s_bv = {f[2]:.3g}{every}"
    return f"terms       {', '.join(scene.terms)}{nu}{filt}"


def courant_line(c: dict, day: float, over: str = "nodes") -> str:
    """The header's ``Courant`` line of ``courant_numbers``' dict ``c`` at model day ``day``,
    its maxima ``over`` the nodes (an ensemble's: and its members)."""
    grav = "" if math.isnan(c["courant_gravity"]) else f", gravity-wave {c['courant_gravity']:.3f}"
    return f"Courant     advective {c['courant_advective']:.3f}{grav} (max over {over} at t = {day:g} d)"


def scene_notes(scene, continued) -> tuple:
    """The notes of ``scene``; of a continuation's (``continued``: the restart file), the notes
    on its dt said as the first run's, whose dt goes on (that run's restart interval, not this one's)."""
    if continued is None:
        return scene.notes
    return tuple(
        f"{n} (the run continued, {continued.name}: its dt goes on)" if n.startswith("dt ") else n for n in scene.notes
    )


def print_notes(notes, root: bool) -> None:
    """The header's notes: a ``warning: `` one on stderr (rank 0's alone: seen with stdout
    redirected), the others as ``note`` lines."""
    for note in notes:
        if note.startswith("warning: "):
            if root:
                print(f"swe-sphere: {note}", file=sys.stderr)
        else:
            print(f"note        {note}")


def print_output(scene, output, only: str = "") -> None:
    """A header's line of the run file ``output`` (a run's and an ensemble's): its interval, or
    where the run is shorter than that, the two times it holds (the run's start and its end)."""
    every = scene.output_every_days
    when = "every day" if every == 1 else f"every {every:g} days"
    if every > scene.run_days:  # ``--days 0.5`` of a scene writing every day: no time but the start and the end
        when = f"at the start and at day {scene.days:g}: the run is shorter than its {every:g}-day interval"
    print(f"output      {output} ({when}{only})")


def print_streams(scene, output) -> None:
    """A header's line for each ``[[output.streams]]`` of ``scene`` beside the run file ``output``
    (a run's and an ensemble's)."""
    from ..simulation.writers import stream_path

    for st in scene.output_streams:
        print(
            f"stream      {stream_path(output, st['name'])} (every {st['every_days']:g} days: {', '.join(st['fields'])})"
        )


def _courant_notes_outputs(args, sim, output, c) -> None:
    """The header's lines from the Courant numbers ``c`` (``Simulation.courant``) on:
    notes and warnings, the output files, the log, the digital-filter start, setup time."""
    from ..simulation.writers import restart_path

    scene = sim.scene
    print(courant_line(c, sim.time))
    extra = [n for n in (sim.stability_warning(), sim.backend.threads_note()) if n]
    print_notes((*scene_notes(scene, args.continue_from), *extra), sim.root)
    only = f": {', '.join(scene.output_fields)}" if scene.output_fields else ""
    print_output(scene, output, only)
    print_streams(scene, output)
    if scene.log_every_steps:
        print(
            f"log         every {scene.log_every_steps} steps: relative change of mass, energy, enstrophy since t = 0; max Courant numbers"
        )
    if args.restart_every is not None:
        print(f"restart     {restart_path(output)} (every {args.restart_every:g} days and at the end)")
    if sim.dfi is not None:
        print(f"initial     {sim.dfi.describe(scene.digital_filter)}")
    print(f"setup       {sim.setup_time:.2f} s")


def summary(r, sim) -> None:
    d = r.diagnostics
    steps, loop = r.steps - r.first_step, r.loop_time
    print("summary")
    print(
        f"  wall time   {loop:.2f} s for {steps} steps, setup {r.setup_time:.2f} s"
        + (f" (cumulative since t = 0: {r.wall_time:.2f} s)" if r.first_step else "")
    )
    if steps:
        rest = (
            f", then {1e3 * (loop - r.first_step_time) / (steps - 1):.2f} ms/step over {steps - 1} steps"
            if steps > 1
            else ""
        )
        print(
            f"  time        compile {r.compile_time:.2f} s (setup and loop), first step {r.first_step_time:.3f} s{rest}"
        )
    print(f"  RHS evals   {r.rhs_evals}")
    if sim.control is not None:  # counted since t = 0, as a restart file carries them
        print(f"  steps       {sim.control.summary()}")
    if sim.dfi is not None:
        print(
            f"  initial     digital-filter start: {sim.dfi.rhs_evals} RHS evals, {sim.dfi.wall_time:.2f} s (in setup); rms dh/dt "
            f"{sim.dfi.dhdt_rms[0]:.3e} -> {sim.dfi.dhdt_rms[1]:.3e} m/s"
        )
    elif sim.scene.initialization is not None:
        print("  initial     digital-filter start of the run continued (not redone)")
    for k, total in r.iterations.items():
        print(f"  {k:11s} {total} iterations, {total / max(r.steps, 1):.1f} per step")
    for k in ("mass", "total_energy", "potential_enstrophy"):
        if k in d:
            print(f"  {k:20s} {d[k]:.10e}  relative change {d[k + '_change']:+.3e}")
    cmax = {k: max(h[k] for h in r.history) for k in ("courant_advective", "courant_gravity")}
    grav = "" if math.isnan(cmax["courant_gravity"]) else f", gravity-wave {cmax['courant_gravity']:.3f}"
    print(f"  Courant     max over output times: advective {cmax['courant_advective']:.3f}{grav}")
    if "l2_h" in d:
        print(f"  error h     l1 {d['l1_h']:.3e}  l2 {d['l2_h']:.3e}  linf {d['linf_h']:.3e}")
        print(f"  error wind  l1 {d['l1_wind']:.3e}  l2 {d['l2_wind']:.3e}  linf {d['linf_wind']:.3e}")
        print(
            f"  error wind  l2 vorticity {d['l2_vorticity']:.3e}  l2 divergence {d['l2_divergence']:.3e} "
            "(curl and divergence of v - v_exact by the model's operators, over those of v_exact)"
        )
    if "l2_h" not in d and sim.scene.reference_file is None:
        print("  error       none: nothing to score against (no exact solution, no reference solution for this run)")
    if "ref_l2_h_surface" in d:
        # the reference stores a few days only: quote the last output time past the start it has
        name = sim.scene.reference_file.stem.rsplit("_", 1)[-1]  # the truncation, for the spectral files ("T213")
        vs = f"vs {name}"
        scored = [h for h in r.history if h["steps"] > 0 and math.isfinite(h["ref_l2_h_surface"])]
        if not scored:
            from ..cases.reference import stored_days

            days = ", ".join(f"{day:g}" for day in stored_days(sim.scene.reference_file))
            print(f"  {vs:11s} none: no output time after t = 0 is one {name} stores (days {days})")
        else:
            d = scored[-1]
            at = "" if d is r.history[-1] else f" (day {d['day']:g}, its last output time {name} stores)"
            print(
                f"  {vs} h+hs l1 {d['ref_l1_h_surface']:.3e}  l2 {d['ref_l2_h_surface']:.3e}  linf {d['ref_linf_h_surface']:.3e}{at}"
            )
            print(f"  {vs} wind l1 {d['ref_l1_wind']:.3e}  l2 {d['ref_l2_wind']:.3e}  linf {d['ref_linf_wind']:.3e}")
            print(
                f"  {vs} wind l2 vorticity {d['ref_l2_vorticity']:.3e}  l2 divergence {d['ref_l2_divergence']:.3e} "
                f"(curl and divergence of v - v_{name} by the model's operators, over those of v_{name})"
            )
            print(
                f"  {vs} vorticity l2 {d['ref_l2_vorticity_eq83']:.3e} (Williamson eq. 83: the model's vorticity "
                f"against {name}'s own at the nodes, as other models publish it)"
            )
        finer = _finer_reference(sim.scene, name)
        if finer:
            print(f"  {'reference':11s} {name}, the scene's default; {finer}")
    print(f"  output      {r.output}")
    if r.checkpoint is not None:
        print(f"  restart     {r.checkpoint}")


def _finer_reference(scene, name: str) -> str:
    """Where a run is scored against its case's default reference, truncation ``name``, and a
    finer one is bundled (Galewsky's, TC5's and TC6's T341): the words that say which and how to
    score against it ("the bundled T341 stores day 6: -s case.reference=T341"); else ""."""
    if scene.reference is not None:  # chosen: nothing to say
        return ""
    from ..cases.reference import reference_path, stored_days, truncations

    case = scene.make_case()
    finer = [t for t in truncations(case) if int(t[1:]) > int(name[1:])]
    if not finer:
        return ""
    days = ", ".join(f"{day:g}" for day in stored_days(reference_path(case, finer[-1])))
    return f"the bundled {finer[-1]} stores day{'s' if ',' in days else ''} {days}: -s case.reference={finer[-1]}"
