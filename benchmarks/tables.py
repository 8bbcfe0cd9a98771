"""benchmarks/README.md, written from the suite itself: each room's scripts (what each measures: its
docstring's first sentence, or a shell script's first comment) and each script's latest figure read
from its folder of results (the newest record by its date: the figure line it printed last, the
command with its arguments, the date, the machine, the load average at the start and the end, and
the commit). Nothing in it is typed by hand; a rerun on the same files writes the same page
(no clock or file time is read)::

    python benchmarks/tables.py            # rewrite benchmarks/README.md
    python benchmarks/tables.py --check    # exit 1, naming the page, when it differs from the files

Source: the practice of SpeedyWeather.jl, whose benchmark README is written by its runs."""

from __future__ import annotations

import argparse
import ast
import json
import shlex
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
README = HERE / "README.md"
GALLERY = HERE.parent / "docs" / "examples"  # the application scripts' place now, as <section>/plot_<name>.py
ROOMS = {
    "peers": "Peers: the same cases in other models (Dinosaur, HOMME, HOMME on RRM meshes, pySEs)",
    "studies": "Studies: long steps, implicit cost, the Helmholtz preconditioners, float32's accuracy, "
    "the face map, MPI scaling, local time stepping, step control (error and CFL control, its cost), and the "
    "package's own study commands",
    "studies/transport": "Studies: the tracers' transport tests (Lauritzen et al. 2012) beside HOMME's figures",
    "gpu": "GPU: the card script, its payload and the performance models ([GPU.md](gpu/GPU.md))",
    "micro": "Micro: memory, ensembles, gradients, meshes, precision, a run's cost outside its steps",
    "micro/step": "Micro: the RHS and the step (throughput, rooflines, parts, DSS, ∇⁴)",
    "archive": "Archive: what a replaced path justified (kept runnable, not kept current)",
    "regressions": "Regressions: the asv suite (run by asv on each commit: `compare.py`)",
    ".": "The suite's own modules and tools",
}
# a printed line that says how the run went, not what it measured
NOT_A_FIGURE = ("load average", "figures written", "figure written")

INTRO = """\
# Benchmarks

<!-- Written by `python benchmarks/tables.py` from benchmarks/results/: edit the scripts or
tables.py, never this page (tests/test_benchmark_inputs.py checks that it regenerates unchanged). -->

The suite in rooms by subject; each script writes its figures to `results/<script>/<stem>.json`
(`results.py`: the printed lines and named figures beside the machine, the commit, the UTC date,
the load average at the start and the end, and the command line), and this page is generated from
those files. A row holds the latest record of its script, no history: earlier figures are in git
(`git log -p -- benchmarks/results/<script>/`), and the hand-written page this replaced is
`git show d6c19d2:benchmarks/README.md`. What accuracy costs is the documentation's explanation
pages, which cite each figure's script and results file.

Commits are compared by airspeed velocity (asv) on the suite in `regressions/` (the default path's
whole process, the RHS, a step, an ensemble step, a gradient): see "Regressions between commits".

A script runs from the repository root (`python benchmarks/<room>/<script>.py --help`); bad input
ends it as it ends the command line: one line naming the value, exit 2. CPU figures that repeat on a
shared machine are one thread's on the CPU clock (`SWE_SPHERE_THREADS=1`, `--clock cpu` where a
script offers it); each row gives its load average.
"""

ASV = """\
## Regressions between commits

`benchmarks/regressions/` is an [asv](https://asv.readthedocs.io) suite over the public API,
configured by `benchmarks/asv.conf.json`; each commit is built into an environment of its own (the
machine's packages beside it). Two commits side by side, their rounds interleaved, a change beyond
the factor that asv's statistics call real flagged, and the table kept as a results file
(`results/compare/`, its row above):

    python benchmarks/compare.py d6c19d2 HEAD --factor 1.1
    SWE_SPHERE_ASV_QUICK=1 asv run --config benchmarks/asv.conf.json --python=same --quick   # CI's form

A setting against the scene's own at one commit (what `default_path.sh`'s `BASE_ARGS` did in one
tree) is the whole run's parameter `setting`: `swe-sphere run` flags in `SWE_SPHERE_ASV_SETTINGS`
(a JSON list), each timed beside the default, in turn (`regressions/whole_run.py`):

    SWE_SPHERE_ASV_SETTINGS='["--stepper rk4"]' asv run --config benchmarks/asv.conf.json --python=same --bench DefaultPath
    python benchmarks/compare.py BASE HEAD --bench DefaultPath --settings '--stepper rk4'   # both, at both commits
"""


def summary(path: Path) -> str:
    """What ``path`` measures: a Python script's docstring's first sentence, or the first comment
    block's first sentence of a shell script (its shebang skipped)."""
    text = path.read_text()
    if path.suffix == ".py":
        doc = ast.get_docstring(ast.parse(text)) or ""
    else:
        lines = [line for line in text.splitlines()[1:] if line.startswith("#")]
        doc = " ".join(line.lstrip("# ").strip() for line in lines[:4])
    title = [line for line in doc.split("\n\n")[0].splitlines() if not set(line.strip()) <= set("=-~^")]
    first = " ".join(" ".join(title).split())  # (a gallery example's title: its underline left out)
    end = first.find(". ")
    return cell(first if end < 0 else first[: end + 1])


def cell(text: str) -> str:
    """``text`` as one markdown table cell (pipes escaped)."""
    return text.replace("|", "\\|").strip()


def records(stem: str) -> list[dict]:
    """The JSON records of script ``stem``, oldest first (by their own UTC date, then name); a
    script of several studies keeps each study's in a folder of its own (``file`` then names it)."""
    out = []
    for path in sorted((RESULTS / stem).rglob("*.json")):
        record = json.loads(path.read_text())
        out.append({**record, "file": str(path.relative_to(RESULTS / stem))})
    return sorted(out, key=lambda r: (r.get("date", ""), r["file"]))


def figure(record: dict) -> str:
    """The record's figure: the last printed line that says what was measured."""
    lines = [line.strip() for line in record.get("printed", []) if line.strip()]
    kept = [line for line in lines if not line.lower().startswith(NOT_A_FIGURE)]
    return cell(kept[-1]) if kept else "(nothing printed)"


def conditions(record: dict, path: Path) -> str:
    """The command (the script at its place now, the recorded arguments), the date, the machine,
    the load average (1 min, start–end) and the commit of ``record``."""
    # an absolute path of the measuring machine (a peer's build, a tree compared) as DIR/its last part:
    # a reader's folders differ, and the page names no one's machine
    args = [f"DIR/{Path(a).name}" if a.startswith("/") else a for a in shlex.split(record.get("command", ""))[2:]]
    study = Path(record["file"]).parent.name if "file" in record else ""
    if study and record.get("script") != path.name:  # a study's run from before its script held several
        args = [study, *args]
    command = shlex.join(["python", str(path.relative_to(HERE.parent)), *args])
    if GALLERY in path.parents:  # an example now: its run as recorded, at its commit
        command = record.get("command", "?")
    machine = record.get("machine", {})
    load = record.get("load_average", {})
    start, end = (load.get(k, [None])[0] for k in ("start", "end"))
    commit = (record.get("commit") or "?")[:7] + (" + local changes" if record.get("dirty") else "")
    return cell(
        f"`{command}`; {record.get('date', '?')[:10]}, {machine.get('cpu', '?')} ×{machine.get('cores', '?')}, "
        f"load {start}–{end}, {commit}"
    )


def row(path: Path) -> str:
    """A script's row: name, what it measures, its results, its latest figure and conditions."""
    name = f"[`{path.name}`]({Path('..') / path.relative_to(HERE.parent) if GALLERY in path.parents else path.relative_to(HERE)})"
    stem = path.stem.removeprefix("plot_") if GALLERY in path.parents else path.stem
    folder = RESULTS / stem
    files = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file()) if folder.is_dir() else []
    recs = records(stem)
    if not files:
        own = "recorded(" in path.read_text() or path.suffix == ".sh"  # else a module the scripts import
        return f"| {name} | {summary(path)} | {'none yet' if own else 'a module of the suite'} | | |"
    where = f"[{len(files)} file{'s' * (len(files) > 1)}](results/{stem}/)"
    if not recs:
        return f"| {name} | {summary(path)} | {where} (text: {cell(', '.join(files))}) | | |"
    latest = recs[-1]
    return f"| {name} | {summary(path)} | {where}, latest `{latest['file']}` | {figure(latest)} | {conditions(latest, path)} |"


def scripts(room: str) -> list[Path]:
    """The scripts directly in ``room`` (Python and shell), by name."""
    folder = HERE / room
    return sorted(p for p in folder.iterdir() if p.suffix in (".py", ".sh") and p.is_file())


def moved() -> list[Path]:
    """The gallery's examples that were benchmark scripts: those with a results folder here."""
    return [
        p
        for p in sorted(GALLERY.rglob("plot_*.py"), key=lambda p: p.name)
        if (RESULTS / p.stem.removeprefix("plot_")).is_dir()
    ]


def page() -> str:
    parts = [INTRO]
    rooms = [(title, scripts(room)) for room, title in ROOMS.items()]
    rooms.append(("The application scripts, now the documentation gallery's examples (their earlier runs)", moved()))
    for title, paths in rooms:
        parts.append(f"## {title}\n")
        parts.append("| script | what it measures | results | latest figure | command, date, machine, load, commit |")
        parts.append("|---|---|---|---|---|")
        parts += [row(path) for path in paths]
        parts.append("")
    parts.append(ASV)
    parts += comparison()
    return "\n".join(parts)


def comparison() -> list[str]:
    """The latest ``compare.py`` record's table (asv's markdown rows), with its conditions."""
    recs = records("compare")
    if not recs:
        return []
    latest = recs[-1]
    rows = [line for line in latest.get("printed", []) if line.startswith("|")]
    head = f"The latest comparison (`results/compare/{latest['file']}`: {conditions(latest, HERE / 'compare.py')}):"
    return ["", head, "", *rows, "", figure(latest), ""]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 when the page differs from the results")
    args = parser.parse_args(argv)
    text = page()
    if args.check:
        if README.read_text() != text:
            print(f"{README.relative_to(HERE.parent)} differs from its results: python benchmarks/tables.py")
            return 1
        return 0
    README.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
