"""What a sweep shows and writes: the summary `swe-sphere sweep` prints (the table, the spatial
error beside the reference's floor, each stepper's cheapest sufficiently accurate run, the
verdicts) and its files (``OUTPUTS``): sweep.csv, sweep.nc (one ``run`` dimension, CF
attributes, what the sweep was made with), verdicts.csv and the error-against-cost PNGs."""

from __future__ import annotations

import math
from pathlib import Path

from ...grid.quality import REGIONS
from ...io.output_files import atomic_path, check_results
from ...io.run_file import command_line, history_line
from ...io.table_file import table_dataset, write_table_file
from ...steppers import STEPPERS
from ..figures import sweep_plot
from .verdicts import (
    COLUMN_ATTRS,
    COLUMNS,
    CRITERIA,
    SUFFICIENT,
    VERDICT_COLUMNS,
    cheapest_sufficient,
    floor_note,
    run_name,
    verdicts,
)


def format_verdicts(verdict_rows, info) -> str:
    """Per criterion a line with its spatial error and ``floor_note`` (``info``:
    ``Sweep.run``'s), then one line per stepper and the run it picks, its thresholds together
    where they pick the same run (or none): "<= 10%, 50%"."""
    picks: dict[tuple, tuple[list, dict]] = {}  # (criterion, stepper, the run picked) → (thresholds, a row)
    for v in verdict_rows:
        tolerance = v["tolerance"] if math.isfinite(v["tolerance"]) else None
        run = (v["dt"], tolerance) if math.isfinite(v["dt"]) else None  # a stepper's run: its dt (or tolerance)
        picks.setdefault((v["criterion"], v["stepper"], run), ([], v))[0].append(v["threshold"])
    lines, criterion = [], None
    for thresholds, v in picks.values():
        if v["criterion"] != criterion:
            criterion, note = v["criterion"], floor_note(info, CRITERIA[v["criterion"]][1])
            lines.append(f"  {criterion}: spatial error {v['spatial_error']:.3e}" + (f", {note}" if note else ""))
        within = ", ".join(f"{t:3.0%}" for t in thresholds)
        head = f"    {v['criterion']:30s} <= {within} {v['stepper']:22s}"
        if math.isfinite(v["tolerance"]):  # a controlled run: the tolerance that qualifies
            head += f" {v['stepper'].partition('@')[2]} = {v['tolerance']:g}, mean"
        if not math.isfinite(v["dt"]):
            lines.append(f"{head} no run qualifies")
            continue
        lines.append(
            f"{head} dt = {v['dt']:.4g} s = {v['dt_over_gravity_limit']:.2f} x gravity-wave, {v['dt_over_advective_limit']:.2f} x "
            f"advective, {v['dt_over_leapfrog_limit']:.2f} x leapfrog limit; CPU {v['cpu_time']:.3g} s, wall {v['wall_time']:.3g} s, "
            f"{v['rhs_equivalents']:.0f} RHS-eq ({v['rhs_evals']:.0f} RHS)"
        )
    return "\n".join(lines)


def format_summary(rows, info) -> str:
    """The table and, per stepper, the cheapest sufficiently accurate run and the
    verdicts (none where ``info`` says the run length is ``unscored``)."""
    head = (
        f"{'stepper':22s} {'dt [s]':>9s} {'dt/gw':>6s} {'dt/adv':>6s} {'stable':>6s} {'CPU [s]':>9s} {'wall [s]':>9s} {'load':>5s} {'RHS':>8s} {'RHS-eq':>8s} "
        f"{'Newton':>7s} {'GMRES':>7s} {'Helmh.':>7s} {'total err':>10s} {'time err':>10s} {'energy chg':>10s}"
    )
    lines = [head]
    for r in rows:
        lines.append(
            f"{run_name(r):22s} {r['dt']:9.2f} {r['dt_over_gravity_limit']:6.2f} {r['dt_over_advective_limit']:6.2f} "
            f"{'yes' if r['stable'] else 'NO':>6s} {r['cpu_time']:9.2f} {r['wall_time']:9.2f} {r['load_average']:5.1f} {r['rhs_evals']:8.0f} {r['rhs_equivalents']:8.0f} "
            f"{r['newton_iterations']:7.0f} "
            f"{r['gmres_iterations']:7.0f} {r['helmholtz_iterations']:7.0f} {r['total_error']:10.3e} {r['temporal_error']:10.3e} "
            f"{r['total_energy_change']:10.2e}"
        )
    if "unscored" in info:
        lines.append(
            f"spatial error: none, so no run is judged sufficient and there are no verdicts ({info['unscored']})"
        )
        return "\n".join(lines)
    spatial, note = info["spatial_error"], floor_note(info, "spatial_error")
    lines.append(
        f"spatial error (RK4 at dt = {info['reference_dt']:.4g} s, against {info['reference']}): {spatial:.3e}"
        + (f", {note}" if note else "")
        + f"; sufficient accuracy: temporal error <= {SUFFICIENT * spatial:.3e}"
    )
    for quantity, part in (("h + hs", ""), ("divergence", "divergence_")):
        spatial_by_region = {
            k: info[f"spatial_error_{part}{k}"] for k in REGIONS if math.isfinite(info[f"spatial_error_{part}{k}"])
        }
        if not spatial_by_region:
            continue
        by_region = ", ".join(f"{k} {e:.3e}" for k, e in spatial_by_region.items())
        lines.append(f"  {quantity} by region (quality.element_regions): {by_region}")
        lines.append(f"    temporal error of {quantity} by region (/ that region's spatial error):")
        for r in (r for r in rows if r["stable"]):
            by_region = ", ".join(
                f"{k} {r[f'temporal_error_{part}{k}']:.3e} ({r[f'temporal_error_{part}{k}'] / e:.3f})"
                for k, e in spatial_by_region.items()
            )
            lines.append(f"      {run_name(r):22s} dt = {r['dt']:.4g} s: {by_region}")
    best = cheapest_sufficient(rows, spatial)
    explicit = [best[s]["cost_time"] for s in best if STEPPERS[s.partition("@")[0]].explicit]
    ref_time = min(explicit) if explicit else math.nan
    for stepper in dict.fromkeys(r["stepper"] for r in rows):
        if stepper not in best:
            lines.append(f"  {stepper:22s} no run reached sufficient accuracy")
            continue
        b = best[stepper]
        lines.append(
            f"  {stepper:22s} cheapest sufficient: {run_name(b).partition('@')[2] + ', mean ' if '@' in stepper else ''}"
            f"dt = {b['dt']:.4g} s = {b['dt_over_gravity_limit']:.2f} x gravity-wave limit, "
            f"{b['dt_over_advective_limit']:.2f} x advective limit; CPU {b['cpu_time']:.2f} s, wall {b['wall_time']:.2f} s; "
            f"{b['cost_time'] / ref_time:.2f} x best explicit, "
            f"{b['rhs_equivalents']:.0f} RHS-eq"
        )
    lines.append(
        "verdicts: the cheapest run per criterion with temporal error <= 10 % / 50 % of that criterion's spatial error"
    )
    lines.append(format_verdicts(verdicts(rows, info), info))
    return "\n".join(lines)


RECORD = (
    "scene",
    "case",
    "ne",
    "np",
    "days",
    "overrides",
    "stepper_options",
    "reference",
    "time_filter",
    "device",
    "swe_sphere_version",
    "source_sha256",
)  # ``Sweep.record``'s keys: sweep.csv's last columns


def sweep_dataset(df, attrs: dict):
    """sweep.nc as an ``xarray.Dataset`` (``table_file.table_dataset``): one ``run``
    dimension (sweep.csv's rows), each of ``COLUMNS`` a variable on it with its units
    and long_name (``COLUMN_ATTRS``; ``stepper`` and ``reason`` text), ``attrs`` the
    global attributes, with CF's Conventions, title and history."""
    return table_dataset(
        df,
        "run",
        COLUMN_ATTRS,
        row_long_name="run of the sweep (row of sweep.csv)",
        title=f"swe_sphere sweep: {attrs['case']} ne{attrs['ne']} np{attrs['np']}, {attrs['days']:g} days",
        history=history_line(command_line("swe_sphere sweep")),
        attrs=attrs,
    )


PLOTS = (  # (x, y, file name, x label, spatial-error key): the frontier per criterion
    ("wall_time", "total_error", "error_vs_wall_time.png", "wall time [s]", "spatial_error"),
    ("dt", "total_error", "error_vs_dt.png", "dt [s]", "spatial_error"),
    ("dt", "temporal_error", "temporal_error_vs_dt.png", "dt [s]", "spatial_error"),
    (
        "wall_time",
        "total_error_vorticity",
        "error_vs_wall_time_vorticity.png",
        "wall time [s]",
        "spatial_error_vorticity",
    ),
    (
        "wall_time",
        "total_error_divergence",
        "error_vs_wall_time_divergence.png",
        "wall time [s]",
        "spatial_error_divergence",
    ),
)
OUTPUTS = ("sweep.csv", "sweep.nc", "verdicts.csv") + tuple(
    name for _, _, name, _, _ in PLOTS
)  # what write_outputs writes


def write_outputs(rows, info, limits, directory, *, overwrite: bool = False) -> list[Path]:
    """sweep.csv, sweep.nc (``sweep_dataset``: one ``run`` dimension), verdicts.csv and the PNGs (titled
    with the case, grid and days): ``OUTPUTS`` under ``directory``; returns the paths.
    What the sweep was made with (``info``'s ``RECORD`` keys: ``Sweep.record``) is in
    sweep.csv's last columns and, with the rest of ``info`` and ``limits``, in sweep.nc's
    attributes (integers as integers). Raises ``output.OutputError`` before writing
    anything if one of them exists (unless ``overwrite``)."""
    import pandas as pd

    directory = Path(directory)
    check_results(directory, OUTPUTS, overwrite)
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    df["stable"] = df["stable"].astype(int)
    csv, nc, vcsv = (directory / name for name in OUTPUTS[:3])
    with atomic_path(csv, overwrite=overwrite) as tmp:
        df.assign(**{k: info[k] for k in RECORD}).to_csv(tmp, index=False)
    with atomic_path(vcsv, overwrite=overwrite) as tmp:
        pd.DataFrame(verdicts(rows, info), columns=list(VERDICT_COLUMNS)).to_csv(tmp, index=False)
    write_table_file(sweep_dataset(df, {**info, **limits}), nc, overwrite=overwrite)
    paths = [csv, nc, vcsv]
    title = f"{info['case']} ne{info['ne']} np{info['np']}, {info['days']:g} days"
    for x, y, name, label, spatial in PLOTS:
        paths.append(sweep_plot(directory / name, rows, x, y=y, xlabel=label, floor=info[spatial], title=title))
    return paths


# -- the plan: from a scene and options to the runs `swe-sphere sweep` makes ------------------------
