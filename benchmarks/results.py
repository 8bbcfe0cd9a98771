"""What the benchmark scripts share: the results file and the path to one another.

A benchmark's latest figures are a file, ``benchmarks/results/<script>/<stem>.json`` (a folder per
script; ``stem`` the script's name unless it names a variant), written at the script's end through
:func:`recorded`, with what a figure needs to be read later beside it (the machine's CPU model and
cores, the commit and whether the tree differed from it, the UTC date, the load average at the
start and the end, the command line). The figures are what the script printed, line by line, and
whatever named figures it adds to the dict it is given; benchmarks/README.md's tables are generated
from them (``python benchmarks/tables.py``), and git keeps the earlier ones.

The scripts live in rooms by subject (peers/, studies/, gpu/, micro/, archive/, and folders below
them); each puts benchmarks/ first on its path and imports this module, which puts every room on
the path after it, so that a script imports another's helper by its name wherever either lives
(script names are unique across the rooms: tests/test_benchmark_inputs.py checks it)."""

from __future__ import annotations

import argparse
import contextlib
import datetime
import io
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
ROOMS = sorted({p.parent for p in HERE.glob("*/**/*.py")})
sys.path[1:1] = [str(room) for room in ROOMS if str(room) not in sys.path]


def one_line(kind, err, tb) -> None:
    """``sys.excepthook`` of every script that imports this module: the package's own errors (bad
    input, a blow-up: ``SweSphereError``) and a missing file end the script as the command line
    ends (one line naming the value, exit 2 or 3: ``swe_sphere.cli.main.classify``); anything else
    is a defect and keeps its traceback."""
    from swe_sphere import SweSphereError
    from swe_sphere.cli.main import classify

    if not isinstance(err, (SweSphereError, FileNotFoundError)):
        sys.__excepthook__(kind, err, tb)
        return
    code, message = classify(err)
    print(f"{Path(sys.argv[0]).name}: error: {message}", file=sys.stderr)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)  # a hook cannot raise SystemExit: the interpreter would report that instead


sys.excepthook = one_line

DAY = 86400.0  # s: the scripts' days and Δt (the package's own constant, not its public API: here, once)


def quiet_warp():
    """Warp initialised without its banner and load lines (the package's own start,
    ``swe_sphere.core.runtime.init_warp``), before a script's first table; returns ``warp``."""
    from swe_sphere.core.runtime import init_warp

    return init_warp()


def positive(kind, above=0):
    """An argparse ``type``: a ``kind`` (int or float) > ``above``, else argparse's one line (exit 2):
    a count or interval of 0 would end in a division by it or an empty median."""

    def parse(text: str):
        value = kind(text)
        if not value > above:
            raise argparse.ArgumentTypeError(f"must be > {above} (got {text})")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in "invalid int value"
    return parse


def section(doc: str, study: str) -> str:
    """The first paragraph of the section headed ````study```` of a script's docstring ``doc``: what
    that study (a subcommand) measures, its ``--help``."""
    text = doc.split(f"``{study}``\n")[1]
    return " ".join(text.split("\n\n")[0].strip("~\n").split())


def studies(doc: str, calls: dict) -> None:
    """A script of several studies: the first argument names one (``calls``: its name to the call
    taking the rest of the arguments, its own options); argparse's one line and exit 2 for another."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("study", choices=list(calls), help="the study (its options: STUDY --help)")
    parser.add_argument("options", nargs=argparse.REMAINDER, help="the study's options")
    args = parser.parse_args()
    calls[args.study](args.options)


def check_sources(parser, sources) -> None:
    """``parser.error`` (one line, exit 2) for a ``--source`` that holds no swe_sphere tree: on
    PYTHONPATH it would be skipped, and the installed tree timed under its name."""
    for source in sources:
        if source is not None and not (Path(source) / "swe_sphere").is_dir():
            parser.error(f"--source {source}: no swe_sphere tree there")


def interleaved(calls: dict, rounds: int) -> dict:
    """The median over ``rounds`` of each call's mean CPU ms: ``calls`` maps a name to (a call, how
    many times a round), the calls taken in turn each round, so that a change of the machine's load
    hits each alike; the CPU clock of this process (one thread: ``SWE_SPHERE_THREADS=1``)."""
    ms = {k: [] for k in calls}
    for _ in range(rounds):
        for k, (call, reps) in calls.items():
            start = time.process_time()
            for _ in range(reps):
                call()
            ms[k].append((time.process_time() - start) / reps * 1e3)
    return {k: statistics.median(v) for k, v in ms.items()}


def timed(f, calls: int, rounds: int) -> float:
    """The median over ``rounds`` of the mean CPU ms of ``calls`` calls of f (one call first)."""
    f()
    return interleaved({"f": (f, calls)}, rounds)["f"]


def interleave(a: list, b: list) -> list:
    """a[0], b[0], a[1], b[1], ... then the rest of the longer list: two models' runs taken in
    turn, so that a change of the machine's load hits both alike."""
    out = [x for pair in zip(a, b) for x in pair]
    return out + a[len(b) :] + b[len(a) :]


def cpu_model() -> str:
    """The CPU's model name (Linux's /proc/cpuinfo; elsewhere what ``platform`` says)."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def commit() -> dict:
    """The checkout's commit and whether its tracked files differ from it (None outside git)."""

    def git(*args: str) -> str | None:
        out = subprocess.run(["git", *args], cwd=HERE, capture_output=True, text=True)
        return out.stdout.strip() if out.returncode == 0 else None

    status = git("status", "--porcelain", "--untracked-files=no")
    return {"commit": git("rev-parse", "HEAD"), "dirty": None if status is None else bool(status)}


# an absolute path in a line of text: a slash that starts a word, then at least one folder, up to a
# blank, a quote, a colon, a comma or a bracket (a tree's label "TREE: 2.1 s", a profile's "x.py:12(f)")
_ABSOLUTE = re.compile(r"""(?<![\w.~/$-])/[\w.~+-]+/[\w.~+/-]*""")
_SYSTEM = ("usr", "bin", "lib", "proc", "etc", "dev", "sys")  # the same on every machine: kept


def portable(text: str, roots: tuple[str, ...] = (str(HERE.parent),)) -> str:
    """``text`` without the folders of the machine that ran it: a path into the repository (one of
    ``roots``: this checkout's) relative to its root, a package's file from its package on
    (``.../site-packages/numpy/x.py``: ``numpy/x.py``), the system's own folders (/usr, /proc, ...)
    as they are, and any other path ``DIR/<its last part>`` (a peer's build, a tree compared)."""

    def short(match: re.Match) -> str:
        path = match.group(0)
        for root in roots:
            if path == root or path.startswith(root + "/"):
                return path[len(root) + 1 :] or "."
        parts = path.strip("/").split("/")
        if parts[0] in _SYSTEM:
            return path
        for site in ("site-packages", "site"):
            if site in parts[:-1]:
                return "/".join(parts[parts.index(site) + 1 :])
        return f"DIR/{parts[-1] or parts[-2]}"

    return _ABSOLUTE.sub(short, text)


class _Tee(io.TextIOBase):
    """Writes to the terminal and keeps a copy, so that a script prints as it did."""

    def __init__(self, out) -> None:
        self.out, self.kept = out, io.StringIO()

    def write(self, text: str) -> int:
        self.kept.write(text)
        return self.out.write(text)

    def flush(self) -> None:
        self.out.flush()


@contextlib.contextmanager
def recorded(script: str, stem: str | None = None, study: str | None = None) -> Iterator[dict]:
    """Run the block with its printed lines kept; on a normal exit write them, and the named
    figures the block put in the yielded dict, to ``results/<script>/<stem>.json`` (default
    the script's stem), or with a ``study`` (a script of several) to
    ``results/<script>/<study>/<stem>.json`` (default the study's name); a ``stem`` that is an
    absolute path (``--results`` a path from the root) to ``<stem>.json`` itself. The folders are made if absent,
    the file replaced. ``script``: the script's path (``__file__``). Nothing is written when the
    block raises (a refused option, an interrupted run)."""
    figures: dict = {}
    load_start = os.getloadavg()
    started = datetime.datetime.now(datetime.UTC)
    tree = commit()  # at the start: the tree that ran (a checkout may move during a long run)
    tee = _Tee(sys.stdout)
    with contextlib.redirect_stdout(tee):
        yield figures
    record = {
        "script": Path(script).name,
        "command": " ".join(["python", str(Path(script).resolve().relative_to(HERE.parent)), *sys.argv[1:]]),
        "date": started.isoformat(timespec="seconds"),
        "machine": {"cpu": cpu_model(), "cores": os.cpu_count(), "system": platform.platform()},
        **tree,
        "load_average": {"start": [round(x, 2) for x in load_start], "end": [round(x, 2) for x in os.getloadavg()]},
        "figures": figures,
        "printed": tee.kept.getvalue().splitlines(),
    }
    folder = RESULTS / Path(script).stem / (study or "")
    path = folder / f"{stem or study or Path(script).stem}.json"  # an absolute stem: Path's / keeps it whole
    path.parent.mkdir(parents=True, exist_ok=True)
    # the file names no folder of this machine (the repository's own paths relative to it)
    path.write_text(portable(json.dumps(record, indent=1, ensure_ascii=False)) + "\n")
    # a stem given as a path (``--results`` an absolute path) is written there: said as it was written, not refused after the run
    shown = path.relative_to(HERE.parent) if path.is_relative_to(HERE.parent) else path
    print(f"figures written to {shown}", file=sys.stderr)
