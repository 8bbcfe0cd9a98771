"""The frontier: error against cost over a ladder of grids, each stepper near its stable limit.

A frontier is a study over grids as the sweep (``studies.sweep``) is one over steps: for each
(ne, np) of the ladder it runs a sweep of the steppers, each at a fraction of its own
measured stability limit (``Stepper.courant_limit``, a signal-rate Courant number), in a
sweep folder of its own (``DIR/ne<ne>np<np>/``, the sweep's files and run cache: a rerun
reuses every run made there with the same settings), and scores each run by one of the
sweep's error columns at the last day (``ERRORS``: h + hs, vorticity or divergence, against
the exact solution or the case's reference, e.g. T341) and its cost per simulated day on
the sweep's clock (``--cost``: the CPU time of the time loop; one thread with
``SWE_SPHERE_THREADS=1``). A run is on the Pareto front (``pareto_front``) when no other is
at least as cheap and as accurate and better in one; ``cheapest_for`` is the configuration
a user asking for an error should run. ``Frontier.run`` writes ``OUTPUTS``: the table
(frontier.csv, frontier.nc) and the figure (frontier.png, log-log error against cost, the
front drawn, each point labelled ne/np/stepper)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.backend import pick_device
from ..core.errors import ArgumentError
from ..io.output_files import atomic_path, check_results, folder_lock
from ..io.run_file import history_line
from ..io.table_file import table_dataset, write_table_file
from ..steppers import STEPPERS
from . import sweep
from .figures import label_log_axis, new_figure, save_png
from .sweep.report import RECORD

# error name: (the sweep's row column, its info's spatial-error key, what it measures)
ERRORS = {
    "h": ("total_error", "spatial_error", "h + hs"),
    "vorticity": ("total_error_vorticity", "spatial_error_vorticity", "relative vorticity"),
    "divergence": ("total_error_divergence", "spatial_error_divergence", "divergence"),
}
# Galewsky's jet is judged by its vorticity (Galewsky et al. 2004's figures; the peers'
# comparisons of issue 63); the Williamson cases by h + hs (Williamson et al. 1992)
DEFAULT_ERROR = {"galewsky": "vorticity"}
# a fraction of the stepper's limit measured on TC2 at ne8 np4: Galewsky and finer grids
# blow up a little below it (docs/explanation/efficiency/sweep.md: RK4 at 1.24 Δt_g on Galewsky ne30)
DEFAULT_FRACTION = 0.8
DEFAULT_STEPPERS = ("kgu35", "fbrk32")  # the efficiency study's winners (docs/explanation/efficiency.md)
OUTPUTS = ("frontier.csv", "frontier.nc", "frontier.png")

COLUMN_ATTRS = {  # frontier.csv's columns and frontier.nc's variables: (units, long_name); units None: text
    "label": (None, "configuration: ne/np/stepper"),
    "ne": ("1", "elements along a cube edge"),
    "np": ("1", "GLL points per element direction"),
    "nodes": ("1", "unique grid nodes, 6 ne^2 (np - 1)^2 + 2"),
    "stepper": (None, "time stepper"),
    "fraction_of_limit": ("1", "time step over the stepper's measured stability limit (its courant_limit)"),
    "dt": ("s", "time step"),
    "dt_over_gravity_limit": ("1", "time step over the gravity-wave limit (Courant number 1)"),
    "stable": ("1", "1 if the run reached its last day without blowing up, else 0"),
    "error": ("1", "normalized l2 error (Williamson et al. 1992) at the last day, of the frontier's quantity"),
    "spatial_error": ("1", "the same error of the grid's small-dt RK4 run (the sweep's spatial error)"),
    "cost_per_day": ("s", "the run's time loop on the frontier's clock per simulated day"),
    "cost_time": ("s", "the run's time loop on the frontier's clock to the last day"),
    "cpu_time": ("s", "process CPU time of the time loop to the last day, all threads summed"),
    "wall_time": ("s", "wall time of the time loop to the last day"),
    "threads": ("1", "compute threads"),
    "load_average": ("1", "mean 1-minute load average at the run's start and last day"),
    "on_front": ("1", "1 if no other run is at least as cheap and as accurate, and better in one"),
}
COLUMNS = tuple(COLUMN_ATTRS)


def pareto_front(costs, errors) -> np.ndarray:
    """Which points are on the Pareto front of error against cost: bool (n,), True where
    no other point has cost ≤ and error ≤ this one's, one of them strictly (two equal
    points are both on it). A point with a cost or error that is NaN, inf or ≤ 0 (an
    unstable run) is on no front and dominates nothing. Raises ValueError for
    ``costs`` and ``errors`` of different lengths."""
    c, e = np.asarray(costs, dtype=float), np.asarray(errors, dtype=float)
    if c.shape != e.shape or c.ndim != 1:
        raise ValueError(f"costs and errors must be two sequences of one length (got {c.shape} and {e.shape})")
    ok = np.isfinite(c) & np.isfinite(e) & (c > 0) & (e > 0)
    front = ok.copy()
    for i in np.flatnonzero(ok):
        no_worse = ok & (c <= c[i]) & (e <= e[i])
        front[i] = not np.any(no_worse & ((c < c[i]) | (e < e[i])))
    return front


def cheapest_for(rows, error: float) -> dict | None:
    """The row (``Frontier.run``'s) with the least ``cost_per_day`` among the stable runs
    whose ``error`` ≤ ``error``; None when none reaches it. It is on the front."""
    ok = [r for r in rows if r["stable"] and r["error"] <= error and math.isfinite(r["cost_per_day"])]
    return min(ok, key=lambda r: (r["cost_per_day"], r["error"]), default=None)


def stable_dt(stepper: str, limits: dict) -> float:
    """The Δt (s) at which ``stepper`` reaches its measured limit ``courant_limit`` on a grid
    whose ``explicit_limits`` are ``limits``: both limits are (|v| + sqrt(g h)) Δt / Δx,
    leapfrog's ``dt_leapfrog`` its own ``courant_limit`` over the fastest signal rate."""
    return STEPPERS[stepper].courant_limit / STEPPERS["leapfrog"].courant_limit * limits["dt_leapfrog"]


def parse_runs(items) -> tuple[tuple[str, float], ...]:
    """``["kgu35", "rk4@0.5"]`` (or (name, fraction) pairs) → ((stepper, fraction of its
    limit), ...), ``DEFAULT_FRACTION`` where none is given; duplicates once. Raises
    ValueError (naming ``--steppers``) for none, an unknown stepper, one without a
    measured limit (not explicit) or a fraction not a number > 0."""
    runs = []
    for item in items:
        name, sep, fraction = item.partition("@") if isinstance(item, str) else (item[0], "@", item[1])
        name = name.strip()
        if name not in STEPPERS:
            raise ValueError(f"--steppers: unknown stepper {name!r} (known: {', '.join(STEPPERS)})")
        if STEPPERS[name].courant_limit is None:
            known = ", ".join(s for s in STEPPERS if STEPPERS[s].courant_limit is not None)
            raise ValueError(f"--steppers: {name} has no measured stability limit to run near (those that do: {known})")
        try:
            value = float(fraction) if sep else DEFAULT_FRACTION
        except (TypeError, ValueError):
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"--steppers {name}@{fraction}: the fraction of its limit must be a number > 0")
        runs.append((name, value))
    if not runs:
        raise ValueError("--steppers names no stepper")
    return tuple(dict.fromkeys(runs))


def _grids(ne, np_) -> tuple[tuple[int, int], ...]:
    """The ladder: every ne × every np, ascending; ValueError (naming the option) for none."""
    for flag, values in (("--ne", ne), ("--np", np_)):
        if not values:
            raise ValueError(f"{flag} names no grid")
    return tuple(sorted({(int(n), int(p)) for n in ne for p in np_}))


@dataclass(frozen=True)
class Frontier:
    """A frontier as asked for (``plan``): the ladder's grids ((ne, np) pairs), the
    (stepper, fraction of its limit) runs on each, the error scored (a key of
    ``ERRORS``) and what ``sweep.plan`` makes each grid's sweep from: the scene, run
    length (days, None: the scene's) and ``{"section.key": value}`` overrides."""

    scene: str
    grids: tuple
    runs: tuple
    error: str
    days: float | None
    overrides: dict

    @property
    def default_output(self) -> Path:
        """The results' folder when none is given, in the working folder:
        ``frontier_<scene>_<days>d`` (a rerun finds its runs there)."""
        base = self.sweep_plan(*self.grids[0]).base
        return Path(f"frontier_{base.name}_{base.days:g}d")

    def sweep_plan(self, ne: int, np_: int, multiples=None) -> sweep.Plan:
        """The sweep of grid (ne, np): the runs at ``multiples`` of the gravity-wave limit
        (one per run, in order; None: 1, for checking the options alone), each capped at the run
        (not refused as a sweep's given multiples are: the frontier chose them)."""
        multiples = multiples or [1.0] * len(self.runs)
        runs = [(s, m) for (s, _), m in zip(self.runs, multiples)]
        plan = sweep.plan(self.scene, runs=runs, ne=ne, np_=np_, days=self.days, overrides=self.overrides)
        return dataclasses.replace(plan, given=False)

    def run(
        self,
        directory,
        device: str | None = None,
        *,
        pool=None,
        cost="cpu",
        targets=(),
        overwrite=False,
        peers=(),
        log=print,
    ):
        """Make or reuse every run, ``log`` each grid's sweep and then the frontier's table
        (``format_table``), write ``OUTPUTS`` under ``directory`` (each grid's sweep in
        ``directory/ne<ne>np<np>``, its files replaced, its runs reused).

        Parameters
        ----------
        directory : str or path
            The frontier's folder (created).
        device : {"cpu", "cuda"}, optional
            Warp device (default: ``SWE_SPHERE_DEVICE`` where set, else CUDA when present).
        pool : concurrent.futures.Executor, optional
            Runs each sweep's runs (``core.workers.executor``); None: here, one after another.
        cost : {"cpu", "wall"}
            The clock of the cost (the sweep's ``--cost``).
        targets : sequence of float
            Errors (normalized l2, > 0) for which the table names the cheapest run (``cheapest_for``).
        overwrite : bool
            Replace an earlier frontier's files in ``directory``.
        peers : sequence of dict
            Other models' points for the figure (``read_peers``; ``frontier_plot``), not the table.
        log : callable
            Called with each line to show.

        Returns
        -------
        rows : list[dict]
            One per run, ``COLUMNS`` each, in ladder and stepper order.
        paths : list[Path]
            The files written.

        Raises
        ------
        OutputError
            Another frontier holds ``directory``, or its results exist (without ``overwrite``).
        ValueError
            An unknown ``cost``; ``ArgumentError`` for a target not a number > 0 (before any run).
        BlowUp
            A grid's small-Δt reference run failed.
        Interrupted
            SIGINT or SIGTERM; the runs made are kept, and a rerun reuses them.
        """
        directory, device = Path(directory), pick_device(device)
        for target in targets:  # before any run
            if isinstance(target, bool) or not (
                isinstance(target, (int, float)) and math.isfinite(target) and target > 0
            ):
                raise ArgumentError(f"--target must be errors > 0 (normalized l2; got {target!r})")
        with folder_lock(directory, "frontier.lock"):
            check_results(directory, OUTPUTS, overwrite)
            rows, record = [], None
            for i, (ne, np_) in enumerate(self.grids):
                where = directory / f"ne{ne}np{np_}"
                log(f"frontier: grid {i + 1}/{len(self.grids)}, ne{ne} np{np_}, its sweep in {where}")
                grid_rows, record = self._grid(ne, np_, where, device, pool, cost, log)
                rows += grid_rows
            front = pareto_front([r["cost_per_day"] for r in rows], [r["error"] for r in rows])
            for r, on in zip(rows, front):
                r["on_front"] = int(on)
            attrs = {
                **{k: record[k] for k in RECORD if k not in ("ne", "np", "stepper_options")},  # the grids' own
                "error_column": ERRORS[self.error][0],  # the sweep's column the error is
                "error_of": ERRORS[self.error][2],
                "cost_clock": cost,
            }
            log(format_table(rows, attrs, targets))
            paths = write_outputs(rows, attrs, directory, overwrite=overwrite, peers=peers)
            for path in paths:
                log(f"wrote {path}")
        return rows, paths

    def _grid(self, ne, np_, where, device, pool, cost, log) -> tuple[list, dict]:
        """The rows of grid (ne, np) (``Frontier.run``'s) and its sweep's record: each
        stepper's fraction of its limit turned into a multiple of the gravity-wave
        limit on this grid's start state (the sweep's own, made once and reused)."""
        base = self.sweep_plan(ne, np_).base
        limits = sweep.explicit_limits(base, device, sweep.start_state(base, where, device, log))
        multiples = [f * stable_dt(s, limits) / limits["dt_gravity"] for s, f in self.runs]
        rows, info, _ = self.sweep_plan(ne, np_, multiples).run(
            where, device, pool=pool, cost=cost, overwrite=True, log=log
        )
        column, spatial, _ = ERRORS[self.error]
        out = []
        for r in rows:
            out.append(
                {
                    "label": f"ne{ne}/np{np_}/{r['stepper']}",
                    "ne": ne,
                    "np": np_,
                    "nodes": 6 * ne**2 * (np_ - 1) ** 2
                    + 2,  # each element's interior and its share of edges and corners
                    "stepper": r["stepper"],
                    "fraction_of_limit": r["dt"] / stable_dt(r["stepper"], limits),
                    "dt": r["dt"],
                    "dt_over_gravity_limit": r["dt_over_gravity_limit"],
                    "stable": int(r["stable"]),
                    "error": r[column] if r["stable"] else math.nan,
                    "spatial_error": info[spatial],
                    "cost_per_day": r["cost_time"] / base.run_days,
                    **{k: r[k] for k in ("cost_time", "cpu_time", "wall_time", "threads", "load_average")},
                }
            )
        return out, info


def plan(scene, *, ne, np_, steppers=None, error=None, reference=None, days=None, overrides=None) -> Frontier:
    """The frontier `swe-sphere frontier` would run with these options, validated (every
    grid's scene loaded); no run is made and no file written (``Frontier.run`` makes them).

    Parameters
    ----------
    scene : str or path
        Scene file or bundled scene name (``load_scene``).
    ne, np_ : sequence of int
        The ladder: every ne × every np (np 2..8).
    steppers : sequence of str or (str, float), optional
        "kgu35" or "kgu35@0.5": a stepper at a fraction of its measured stability limit
        (default ``DEFAULT_FRACTION``; explicit steppers only). Default ``DEFAULT_STEPPERS``.
    error : {"h", "vorticity", "divergence"}, optional
        The quantity scored (``ERRORS``; default ``DEFAULT_ERROR`` of the case, else "h").
    reference : str, optional
        What the runs are scored against where the case has no exact solution: a
        truncation ("T213", "T341") or a file (the ``case.reference`` override).
    days : float, optional
        The last model day (default: the scene's).
    overrides : dict, optional
        ``{"section.key": value}`` applied to every run (``-s``).

    Returns
    -------
    Frontier

    Raises
    ------
    ValueError
        No grid, an unknown or non-explicit stepper, a bad fraction or error name.
    SceneError
        A bad scene, grid or override (``load_scene``).

    Examples
    --------
    >>> f = plan("tc2_steady", ne=[2, 3], np_=[3, 4], steppers=["kgu35", "rk4"], days=0.1)  # doctest: +SKIP
    >>> rows, paths = f.run("frontier", "cpu")  # doctest: +SKIP
    """
    overrides = dict(overrides or {})
    if reference is not None:
        overrides["case.reference"] = reference
    if error is not None and error not in ERRORS:
        raise ValueError(f"--error must be one of {', '.join(ERRORS)} (got {error!r})")
    runs = parse_runs(DEFAULT_STEPPERS if steppers is None else steppers)
    frontier = Frontier(str(scene), _grids(ne, np_), runs, error or "h", days, overrides)
    bases = [frontier.sweep_plan(n, p).base for n, p in frontier.grids]  # every grid refused now, not after hours
    return frontier if error is not None else dataclasses.replace(frontier, error=DEFAULT_ERROR.get(bases[0].case, "h"))


def format_table(rows, attrs, targets=()) -> str:
    """The frontier as text: every run by cost per day, its error and whether it is on the
    front (``*``), the front from cheapest to most accurate, and for each of ``targets``
    (errors) the cheapest run that reaches it (``cheapest_for``)."""
    lines = [
        f"frontier: {attrs['scene']}, {attrs['days']:g} days, {attrs['error_of']} l2 against {attrs['reference']}, "
        f"{attrs['cost_clock']} s per simulated day",
        f"  {'configuration':24s} {'dt [s]':>9s} {'of limit':>8s} {'error':>10s} {'spatial':>10s} {'s/day':>9s} front",
    ]
    for r in sorted(rows, key=lambda r: (not r["stable"], r["cost_per_day"])):
        error = f"{r['error']:10.3e}" if r["stable"] else f"{'unstable':>10s}"
        lines.append(
            f"  {r['label']:24s} {r['dt']:9.2f} {r['fraction_of_limit']:8.2f} {error} {r['spatial_error']:10.3e} "
            f"{r['cost_per_day']:9.3g} {'*' if r['on_front'] else ''}"
        )
    front = sorted((r for r in rows if r["on_front"]), key=lambda r: r["cost_per_day"])
    lines.append("front (cheapest first): " + ", ".join(f"{r['label']} {r['error']:.3g}" for r in front))
    for target in targets:
        best = cheapest_for(rows, target)
        lines.append(
            f"cheapest for error <= {target:g}: "
            + (
                f"{best['label']} at {best['dt']:.4g} s, {best['cost_per_day']:.3g} s/day"
                if best
                else "no run reaches it"
            )
        )
    return "\n".join(lines)


def frontier_dataset(df, attrs: dict):
    """frontier.nc as an ``xarray.Dataset`` (``table_file.table_dataset``): one ``config``
    dimension (frontier.csv's rows), ``COLUMN_ATTRS`` its variables, ``attrs`` global."""
    return table_dataset(
        df,
        "config",
        COLUMN_ATTRS,
        row_long_name="configuration of the frontier (row of frontier.csv)",
        title=f"swe_sphere frontier: {attrs['case']}, {attrs['days']:g} days, {attrs['error_of']} against cost",
        history=history_line("swe_sphere frontier"),
        attrs=attrs,
    )


def write_outputs(rows, attrs: dict, directory, *, overwrite: bool = False, peers=()) -> list[Path]:
    """frontier.csv (``COLUMNS``, then ``attrs`` as constant columns), frontier.nc
    (``frontier_dataset``) and frontier.png (``frontier_plot``, with ``peers``' points):
    ``OUTPUTS`` under ``directory``; returns the paths. Raises ``OutputError`` before writing
    anything when one exists (unless ``overwrite``)."""
    import pandas as pd

    directory = Path(directory)
    check_results(directory, OUTPUTS, overwrite)
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    csv, nc, png = (directory / name for name in OUTPUTS)
    with atomic_path(csv, overwrite=overwrite) as tmp:
        df.assign(**attrs).to_csv(tmp, index=False)
    write_table_file(frontier_dataset(df, attrs), nc, overwrite=overwrite)
    return [csv, nc, frontier_figure(png, rows, attrs, peers)]


def frontier_figure(path, rows, attrs: dict, peers=()) -> Path:
    """frontier.png of ``rows`` with ``peers`` (``frontier_plot``), titled from ``attrs``
    (``write_outputs``'; frontier.csv's constant columns): its scene, days, error, reference
    and clock. Returns ``path``."""
    title = f"{attrs['scene']}, {attrs['days']:g} days: {attrs['error_of']} against {attrs['reference']}"
    xlabel = f"{attrs['cost_clock']} s per simulated day"
    return frontier_plot(path, rows, title=title, xlabel=xlabel, peers=peers)


def frontier_plot(
    path, rows, *, title: str = "", xlabel: str = "s per simulated day", figsize=(9.0, 6.0), peers=()
) -> Path:
    """Error against cost per day, log-log: each stable run of ``rows`` (``Frontier.run``'s)
    a point coloured by stepper, shaped by np and labelled ne/np/stepper (the front's in
    black, the others small and grey: points of one cost and error overlap); the front a line
    through its points from cheapest to most accurate; ``peers`` (``read_peers``' dicts: other
    models, scored and costed the same way elsewhere) large open markers, one shape a model,
    each labelled in its model's colour and joined by a dashed line. Returns ``path`` (PNG)."""
    fig = new_figure(figsize)
    ax = fig.add_subplot()
    stable = [r for r in rows if r["stable"] and r["cost_per_day"] > 0 and r["error"] > 0]
    markers = dict(zip(sorted({r["np"] for r in rows}), "os^Dvp<>"))
    for i, stepper in enumerate(dict.fromkeys(r["stepper"] for r in rows)):
        for p, marker in markers.items():
            pts = [r for r in stable if r["stepper"] == stepper and r["np"] == p]
            if pts:
                ax.scatter(
                    [r["cost_per_day"] for r in pts],
                    [r["error"] for r in pts],
                    color=f"C{i}",
                    marker=marker,
                    label=f"{stepper}, np{p}",
                    zorder=3,
                )
    for r in stable:  # the front's labels above its points, the others' small and grey below theirs
        on = bool(r["on_front"])
        ax.annotate(
            r["label"],
            (r["cost_per_day"], r["error"]),
            fontsize=8 if on else 6,
            color="black" if on else "0.45",
            xytext=(4, 4) if on else (4, -9),
            textcoords="offset points",
        )
    front = sorted((r for r in stable if r["on_front"]), key=lambda r: r["cost_per_day"])
    ax.plot([r["cost_per_day"] for r in front], [r["error"] for r in front], color="0.3", linewidth=1, label="front")
    _plot_peers(ax, peers)
    if stable or peers:
        ax.set_xscale("log")
        ax.set_yscale("log")
        label_log_axis(ax.xaxis)
        label_log_axis(ax.yaxis)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("normalized l2 error")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)
    return save_png(fig, path)


PEER_STYLES = (("*", "crimson"), ("X", "darkviolet"), ("P", "darkgreen"), ("h", "saddlebrown"))
PEER_COLUMNS = ("model", "label", "error", "cost_per_day")


def _plot_peers(ax, peers) -> None:
    """``frontier_plot``'s peers on ``ax``: per model (in order of appearance) one marker and
    colour of ``PEER_STYLES``, a dashed line through its points by cost, each point labelled."""
    models = list(dict.fromkeys(p["model"] for p in peers))
    for model, (marker, colour) in zip(models, PEER_STYLES * (len(models) // len(PEER_STYLES) + 1)):
        pts = sorted((p for p in peers if p["model"] == model), key=lambda p: p["cost_per_day"])
        x, y = [p["cost_per_day"] for p in pts], [p["error"] for p in pts]
        ax.plot(x, y, color=colour, linestyle="--", linewidth=0.8, zorder=2)
        ax.scatter(
            x, y, s=110, marker=marker, facecolors="none", edgecolors=colour, linewidths=1.4, label=model, zorder=4
        )
        for p in pts:
            ax.annotate(
                p["label"],
                (p["cost_per_day"], p["error"]),
                fontsize=8,
                color=colour,
                xytext=(6, -10),
                textcoords="offset points",
            )


def read_peers(path) -> list[dict]:
    """Other models' points for ``frontier_plot`` from a CSV (a header row) or a JSON list of
    objects, each with ``PEER_COLUMNS``: ``model`` (the legend's name), ``label`` (the point's,
    e.g. "T85"), ``error`` (the frontier's error, normalized l2) and ``cost_per_day`` (s per
    simulated day on the frontier's clock). Returns the points as dicts. Raises
    ``FileNotFoundError``; ``ValueError`` (naming the file) for a missing column, or an error or
    cost that is not a number > 0, a file that is not a table of peers (not UTF-8 text, not
    JSON where named .json, a CSV whose header lacks the columns, no peer)."""
    import csv
    import json

    path = Path(path)
    columns = ", ".join(PEER_COLUMNS)
    try:
        if path.suffix.lower() == ".json":
            items = json.loads(path.read_text())
        else:
            with path.open(newline="") as f:
                table = csv.DictReader(f)
                if not set(PEER_COLUMNS) & set(table.fieldnames or ()):  # one lacking: its peers say so
                    raise ValueError("no header row naming the columns")
                items = list(table)
    except (UnicodeDecodeError, json.JSONDecodeError, csv.Error, ValueError) as err:
        why = "not UTF-8 text" if isinstance(err, UnicodeDecodeError) else str(err).partition(":")[0]
        raise ValueError(
            f"{path}: not a table of peers ({why}): a CSV with a header row, or a JSON list, of {columns}"
        ) from None
    if not items:
        raise ValueError(f"{path}: holds no peer: a CSV with a header row, or a JSON list, of {columns}")
    peers = []
    for i, item in enumerate(items if isinstance(items, list) else [items]):
        missing = [k for k in PEER_COLUMNS if not isinstance(item, dict) or k not in item]
        if missing:
            raise ValueError(f"{path}: peer {i + 1} lacks {', '.join(missing)} (columns: {', '.join(PEER_COLUMNS)})")
        try:
            error, cost = float(item["error"]), float(item["cost_per_day"])
        except (TypeError, ValueError):
            error = cost = math.nan
        if not (error > 0 and cost > 0 and math.isfinite(error) and math.isfinite(cost)):
            raise ValueError(f"{path}: peer {i + 1} ({item['label']}): error and cost_per_day must be numbers > 0")
        peers.append({"model": str(item["model"]), "label": str(item["label"]), "error": error, "cost_per_day": cost})
    return peers
