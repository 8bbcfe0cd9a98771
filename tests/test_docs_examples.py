"""Every example of README.md and docs/**/*.md runs as written, in page order, in one fresh
folder per page (as a user on a fresh clone: ``testcases/`` beside it): each bash/sh and
Python code block, and each command written inline (`` `swe-sphere run galewsky --days
12` ``, a span of one or two lines), one after the other, so that a page whose commands
collide (a default file name taken twice, a study folder written twice) fails here.

The runs are shortened: ``swe-sphere`` is tests/docs_shortening.py in front of the real
tool (tiny grids that keep the page's grids apart, one run a sweep (two members for a perturbed one); plain commands and
Python blocks in a row run in one process, ``docs_shortening.run_each``); a Python
block's ``ne=N`` becomes ``ne=small_ne(N)`` likewise, and a ``dt=`` beside it keeps its
Courant number, and a ``frontier.plan``'s lists keep what ``swe-sphere frontier`` keeps
(``python_line``). Left out, with the reason: ``pip
install`` and ``python -m pytest`` (this test runs inside them), ``python -m sphinx`` (the
site's build, run by CI: a page's folder here holds no docs/), ``mpiexec`` lines (MPI
tests: tests/test_mpi.py), ``--device cuda`` lines (tests/test_cuda.py),
``python benchmarks/`` (timings: the benchmarks are measured, not examples), a bare
subcommand written inline (`` `swe-sphere remap` ``: a name, not a command), and a
command with a placeholder (``NU``, ``S``, ``DT``, ``DIR``, ``...``: a value the reader
fills in)."""

from __future__ import annotations

import builtins
import importlib
import importlib.util
import json
import os
import re
import shlex
import shutil
import subprocess
import symtable
import sys
from pathlib import Path

import pytest

from swe_sphere.config.schema import SCHEMA
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import write_exodus

from docs_shortening import EACH, KEPT, coarser_dt, run_each, shorten, small_ne

ROOT = Path(__file__).resolve().parents[1]
STUDY = Path("docs", "explanation", "efficiency")  # the efficiency study's folder: its scripts, tables, figures
SHIM = Path(__file__).resolve().with_name("docs_shortening.py")
# A fenced block (language, text), or an inline code span of one or two lines.
EXAMPLE = re.compile(r"^```(\w*)\n(.*?)^```|`([^`\n]+(?:\n[^`\n]+)?)`", re.M | re.S)
INLINE_COMMAND = re.compile(r"(\w+=\S* )*(swe-sphere \w+ \S|python \S)")
LEFT_OUT = ("pip install", "python -m pytest", "python -m sphinx", "mpiexec", "--device cuda", "python benchmarks/")
SHELL_SYNTAX = re.compile(r"[$|&;<>()`*?~{}\[\]!#\\]")  # what makes a line more than a command's words
PLACEHOLDER = re.compile(r"(?<![\w$.{'/-])(\.\.\.|[A-Z]{1,3}|DIR)(?![\w.=/'-])")


def examples(path: Path, inline: bool = True) -> list[tuple[str, str]]:
    """(language, text) of each example of ``path`` in page order: its bash/sh/python
    code blocks and (``inline``) its inline commands, as ``bash``."""
    out = []
    for lang, block, span in EXAMPLE.findall(path.read_text()):
        if span:
            if inline and INLINE_COMMAND.match(command := " ".join(span.split())):
                out.append(("bash", command))
        elif lang in ("bash", "sh", "python"):
            out.append((lang, block))
    return out


def shell_line(line: str) -> str | None:
    """One shell line without what is left out (None: nothing left)."""
    parts = []
    for command in line.split("&&"):
        command = re.sub(r"(^|\s+)#.*$", "", command).strip()  # a comment, or a line of one
        if not command or any(word in command for word in LEFT_OUT):
            continue
        if "swe-sphere" in command or command.startswith("python "):
            if PLACEHOLDER.search(command):
                continue
        parts.append(command)
    return " && ".join(parts) or None


def python_line(line: str) -> str:
    """A Python line shortened as a command line is: ``ne=N`` → ``ne=small_ne(N)`` and, with it,
    ``dt=X`` → ``dt=coarser_dt(X, N)`` (the same Courant number: a Δt written for np 4 that a
    scene's np 8 breaks still breaks here; README's galewsky loop at ne=8 dt=600 ran at ne 2 with
    a quarter of its Courant number, stable, where as written it blew up at step 7). A
    ``frontier.plan(...)`` keeps what ``swe-sphere frontier`` keeps (``KEPT``): the first of its
    ``ne=[...]`` (shortened), two of its ``np_=[...]`` and the first of its ``steppers=[...]``."""
    if "frontier.plan(" in line:
        line = re.sub(r"\b(ne|np_|steppers)=\[([^\]]*)\]", _frontier_list, line)
    ne = re.search(r"\bne=(\d+)", line)
    if ne is None:
        return line
    line = re.sub(r"\bdt=(\d+(?:\.\d*)?(?:e\d+)?)", lambda m: f"dt={coarser_dt(float(m[1]), int(ne[1]))}", line)
    return re.sub(r"\bne=(\d+)", lambda m: f"ne={small_ne(int(m[1]))}", line)


def _frontier_list(match: re.Match) -> str:
    """A ``frontier.plan`` list argument (``ne=[2, 4]``) shortened as its option on the command line."""
    name, items = match[1], [item.strip() for item in match[2].split(",")]
    items = items[: KEPT["frontier"]["--" + name.rstrip("_")]]
    return f"{name}=[{', '.join(str(small_ne(int(i))) if name == 'ne' else i for i in items)}]"


def programs(path: Path, inline: bool = True) -> list[list[str]]:
    """The page's examples as commands to run in order: a shell block (or inline command)
    as one ``bash`` script, a Python block as one program as written (pasted alone it runs: its
    own imports; the page's earlier blocks' files are there, their runs not made twice). Plain
    ``swe-sphere`` commands (``plain_words``) and Python blocks one after another (in a block, or
    blocks and inline commands in a row) run in one process (``docs_shortening.run_each``: each
    block in a namespace of its own; ``a && b`` two commands, b after a, each ending the row where
    it fails); a shell block that is more than plain commands runs between."""
    out, row = [], []  # row: (the program of an item alone, the item for run_each)

    def flush():  # the items in a row: one process for two or more
        if len(row) > 1:
            out.append([sys.executable, str(SHIM), EACH, json.dumps([item for _, item in row])])
        elif row:
            out.append(row[0][0])
        row.clear()

    for lang, text in examples(path, inline):
        if lang == "python":
            text = "\n".join(python_line(line) for line in text.splitlines())
            row.append(([sys.executable, "-c", text], text))
            continue
        lines = [
            command for line in text.replace("\\\n", " ").splitlines() if (command := shell_line(line)) is not None
        ]
        commands = [command.strip() for line in lines for command in line.split("&&")]  # a && b: a, then b
        words = [plain_words(command) for command in commands]
        if commands and None not in words:
            row.extend((["bash", "-c", f"set -e\n{command}"], w) for command, w in zip(commands, words))
        elif lines:
            flush()
            out.append(["bash", "-c", "\n".join(["set -e", *lines])])
    flush()
    return out


def plain_words(line: str) -> list[str] | None:
    """The arguments of ``line`` when it is a plain ``swe-sphere`` command (words and quotes,
    nothing else the shell reads: no variable, glob, pipe, redirection or list), which
    ``docs_shortening.run_each`` runs in one process with those beside it, one after the other
    as ``set -e`` runs them; None otherwise (its block runs in bash as written)."""
    if SHELL_SYNTAX.search(line):
        return None
    words = shlex.split(line)
    return words[1:] if words and words[0] == "swe-sphere" else None


def run_examples(path: Path, folder: Path, inline: bool = True) -> None:
    (folder / "testcases").symlink_to(ROOT / "testcases")
    (folder / STUDY).mkdir(parents=True)  # the pages' scripts, beside the figures they write
    (folder / STUDY / "tables.py").symlink_to(ROOT / STUDY / "tables.py")
    # the frontier figures' script merges into the tables beside itself and draws there (copies:
    # what it writes stays in the test's folder) and reads the peers' results
    for f in [ROOT / STUDY / "frontier_figures.py", *(ROOT / STUDY).glob("*.csv")]:
        shutil.copy(f, folder / STUDY)
    (folder / "benchmarks").mkdir()
    (folder / "benchmarks" / "results").symlink_to(ROOT / "benchmarks" / "results")
    bin_ = folder / ".bin"
    bin_.mkdir()
    (bin_ / "swe-sphere").write_text(f'#!/bin/sh\nexec "{sys.executable}" "{SHIM}" "$@"\n')
    (bin_ / "swe-sphere").chmod(0o755)
    env = {
        **os.environ,
        "PATH": os.pathsep.join([str(bin_), str(Path(sys.executable).parent), os.environ["PATH"]]),
        "MPLBACKEND": "Agg",
        "SWE_SPHERE_THREADS": "1",
    }
    for argv in programs(path, inline):
        proc = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True, timeout=1800)
        assert proc.returncode == 0, f"{path.name}: example failed:\n{argv[-1]}\n{proc.stderr[-3000:]}"


def test_a_page_grids_stay_apart():
    assert [small_ne(ne) for ne in (2, 4, 8, 16, 30, 60, 120)] == [2, 2, 2, 3, 4, 5, 6]
    # at np above 4 the GLL points of np 4's grid, 2 elements at least: np tells the files apart
    assert [small_ne(ne, 8) for ne in (8, 12, 30, 60, 120)] == [2, 2, 2, 2, 3]
    assert [small_ne(ne, 6) for ne in (8, 16, 30, 60)] == [2, 2, 2, 3] and small_ne(30, 3) == 4
    assert shorten(["run", "galewsky"]) == ["run", "galewsky", "--ne", "2"]  # the scene's ne12 np8
    assert shorten(["run", "tc5_mountain_homme", "--ne", "30", "--np", "8"])[2:] == ["--ne", "2", "--np", "8"]
    assert shorten(["run", "tc5_mountain_homme", "--ne", "60"]) == ["run", "tc5_mountain_homme", "--ne", "5"]
    assert shorten(["run", "tc5_mountain_homme"]) == ["run", "tc5_mountain_homme", "--ne", "4"]  # the scene's 30
    assert shorten(["run", "tc2_steady", "-s", "a.b=1"]) == ["run", "tc2_steady", "-s", "a.b=1", "--ne", "3"]
    assert shorten(["stability", "galewsky"]) == ["stability", "galewsky", "--ne", "2"]
    assert shorten(["stability", "tc5_mountain", "galewsky", "--steppers", "rk4,kgu35"]) == [
        *(
            "stability",
            "tc5_mountain",
            "--steppers",
            "rk4",
            "--ne",
            "2",
            "--output",
            "stability_tc5_mountain_galewsky_ne2",
        )
    ]
    ark = ["stability", "galewsky", "tc6_rossby_haurwitz", "tc5_mountain", "--steppers", "ark324,imex"]
    assert shorten(ark) == [  # Galewsky's np 8 left for TC6's np 4
        *("stability", "tc6_rossby_haurwitz", "--steppers", "ark324", "--ne", "2"),
        *("--output", "stability_galewsky_tc6_rossby_haurwitz_tc5_mountain_ne2"),
    ]
    assert shorten([*ark, "--np", "3"])[1] == "galewsky"  # every case at one np: the first
    file_grids = (["run", "--continue", "r.restart.nc", "--days", "20"], ["run", "tc2_steady", "--mesh", "x.g"])
    for argv in (*file_grids, ["run", "tc2_steady", "-s", "grid.ne=0", "-s", 'grid.mesh_file="/m/x.g"']):
        assert shorten(argv) == argv
    refine = ["mesh", "--ne", "10", "--refine-box", "10", "50", "246.7", "293.3", "--levels", "2", "--output", "x4.g"]
    assert shorten(refine) == [*refine[:-3], "1", *refine[-2:]]  # one level: the box's transitions need ne10
    assert shorten(["plot", "tc2_steady_ne8np4_ssprk3_2d.nc"]) == ["plot", "tc2_steady_ne2np4_ssprk3_2d.nc"]
    assert shorten(["plot", "galewsky_ne12np8_kgu35.nc"]) == ["plot", "galewsky_ne2np8_kgu35.nc"]
    assert shorten(["run", "tc2_steady", "--ne", "8", "-s", "case.path=tc5_mountain_ne16np4_rk4.nc"])[-1] == (
        "case.path=tc5_mountain_ne3np4_rk4.nc"
    )


def test_a_scene_on_a_mesh_file_keeps_the_file_s_grid(tmp_path):
    write_exodus(tmp_path / "ne2.g", cube_mesh(2))
    scene = tmp_path / "on_mesh.toml"
    terms = '["continuity", "momentum_advection", "coriolis", "pressure_gradient"]'
    scene.write_text(
        f'terms = {terms}\n[case]\nname = "tc2_steady"\n[grid]\nne = 0\nmesh_file = "ne2.g"\n[time]\ndt = 900.0\n'
    )
    assert shorten(["run", str(scene), "--dt", "90"]) == ["run", str(scene), "--dt", "90"]
    assert shorten(["run", "tc2_steady", "--dt", "90"])[-4:] == ["--dt", str(coarser_dt(90.0, 16)), "--ne", "3"]


def test_a_sweep_makes_one_run_in_one_process():
    assert shorten(["sweep", "tc5_mountain", "--ne", "16", "--runs", "rk4@1,kgu35@2", "--workers", "2"]) == [
        *["sweep", "tc5_mountain", "--ne", "3", "--runs", "rk4@1"]
    ]
    steppers = [
        "sweep",
        "tc5_mountain",
        "--ne",
        "8",
        "--steppers",
        "rk4,kgu35",
        "--courant",
        "0.5,1",
        "--dt",
        "600,900",
    ]
    assert shorten(steppers)[4:] == ["--steppers", "rk4", "--courant", "0.5", "--dt", "2400.0"]
    members = ["sweep", "tc2_steady", "--ne", "4", "--members", "4", "--perturbation", "1", "--output", "m"]
    assert shorten(members)[4:6] == ["--members", "2"]
    varied = ["sweep", "tc2_steady", "--members", "3", "--vary", "case.h0=1,2,3"]  # a value a member: all three
    assert shorten(varied)[:6] == varied
    frontier = ["frontier", "tc2_steady", "--ne", "2,4", "--np", "3,4,6", "--steppers", "rk4,kgu35", "--days", "1"]
    assert shorten(frontier) == [*frontier[:3], "2", "--np", "3,4", "--steppers", "rk4", "--days", "1"]
    assert shorten(["frontier", "galewsky", "--ne", "16", "--np", "7,8"]) == [
        *["frontier", "galewsky", "--ne", "3", "--np", "7,8"]
    ]  # its grid shortened as a run's
    assert shorten(["stability", "tc5_mountain", "--steppers", "rk4,kgu35,ssprk3", "--ne", "16"]) == [
        *["stability", "tc5_mountain", "--steppers", "rk4", "--ne", "3"]
    ]


def test_a_given_dt_keeps_its_courant_number_and_divides_the_day():
    assert coarser_dt(90.0, 30) == 86400 / 128  # 960 steps a day on ne30 → 128 on ne4 (7.5x coarser)
    assert coarser_dt(257.14285714285717, 30) == 86400 / 45  # 336 a day → 44.8 → 45
    assert coarser_dt(3600.0, 4) == 7200.0  # ne4 → ne2: twice as coarse
    galewsky = shorten(["run", "galewsky", "--stepper", "fbrk32", "--dt", "216"])  # 400 a day on its ne12 np8
    assert galewsky[-4:] == ["--dt", str(86400 / 67), "--ne", "2"]  # 400 · 2/12 = 66.7 → 67 a day on ne2 np8
    homme = shorten(["run", "tc5_mountain_homme", "--ne", "30", "--np", "8", "--dt", "41.73913043478261"])
    assert homme[-2:] == ["--dt", str(86400 / 138)] and coarser_dt(41.73913043478261, 30, 8) == 86400 / 138
    given = shorten(["run", "galewsky", "--ne", "30", "--np", "4", "--dt", "216"])  # ne30: 53.3 a day on ne4
    assert given[2:] == ["--ne", "4", "--np", "4", "--dt", str(86400 / 53)]
    assert shorten(["run", "--continue", "r.restart.nc", "--dt", "360"])[-1] == "360"  # the file's grid: unknown


def test_a_python_block_keeps_its_courant_number(tmp_path):
    """README's `Simulation("galewsky", ne=8, days=6, dt=600)` blew up as written (the scene
    runs np 8) but ran shortened to ne 2 at the same dt, a quarter of its Courant number."""
    page = tmp_path / "page.md"
    page.write_text('```python\nsim = Simulation("galewsky", ne=8, days=6, dt=600)\nx = f(ne=2, dt=1800.0)\n```\n')
    assert programs(page)[0][-1] == 'sim = Simulation("galewsky", ne=2, days=6, dt=2400.0)\nx = f(ne=2, dt=1800.0)'
    frontier = 'f = frontier.plan("tc2_steady", ne=[16, 4], np_=[3, 4, 6], steppers=["rk4", "kgu35@0.5"], days=1)'
    assert python_line(frontier) == 'f = frontier.plan("tc2_steady", ne=[3], np_=[3, 4], steppers=["rk4"], days=1)'
    assert python_line("f(ne=[16, 4])") == "f(ne=[16, 4])"  # another call's list: as written


def test_inline_commands_are_examples_and_placeholders_are_not(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "Run `swe-sphere run galewsky --stepper fbrk32 --dt 257.1\n--days 12` and `--ne 8`;\n"
        "`swe-sphere remap` is a name, `swe-sphere: error` a message.\n"
        "```bash\nI=rk4@1\nswe-sphere sweep tc5_mountain --runs $I,${I/rk4/kgu35} --output s  # two\n"
        "swe-sphere sweep galewsky --runs ... --output g\nmpiexec -n 2 swe-sphere run tc5_mountain\n```\n"
        "Then `swe-sphere run tc5_mountain --stepper S --dt DT`, "
        "`swe-sphere run tc6_rossby_haurwitz_homme -s hyperviscosity.nu=NU`, "
        "`python docs/explanation/efficiency/tables.py s --figures DIR` and `python -m pytest -m slow`.\n"
    )
    assert [argv[-1] for argv in programs(page)] == [
        "set -e\nswe-sphere run galewsky --stepper fbrk32 --dt 257.1 --days 12",
        "set -e\nI=rk4@1\nswe-sphere sweep tc5_mountain --runs $I,${I/rk4/kgu35} --output s",
    ]


def test_plain_commands_and_python_blocks_in_a_row_run_in_one_process(tmp_path):
    """Plain ``swe-sphere`` lines and Python blocks in a row (in a block, blocks and the inline
    command after them, a comment line between): one process (``docs_shortening.run_each``),
    a command's words as the shell splits them, a Python block as written; a block
    with anything else the shell reads runs in bash between, and so does a plain command alone."""
    page = tmp_path / "page.md"
    page.write_text(
        "```bash\nswe-sphere run tc5_mountain --output 'a b.nc' && swe-sphere plot \"a b.nc\" --day 5  # a map\n"
        "# the same for galewsky\n```\nthen `swe-sphere plot o.nc --day 1`.\n"
        "```python\nimport swe_sphere\nx = 1\n```\n"
        "```bash\nswe-sphere run tc2_steady --output o.nc\nswe-sphere plot o.nc > o.txt\n```\n"
        "```python\nprint(2)\n```\nand `swe-sphere plot o.nc --day 2`.\n"
        "```bash\nls > o.txt\n```\nThen `swe-sphere plot o.nc --day 3`.\n"
    )
    each, bash, each_after, ls, alone = programs(page)
    assert each[1:3] == each_after[1:3] == [str(SHIM), EACH]
    assert json.loads(each[3]) == [
        ["run", "tc5_mountain", "--output", "a b.nc"],
        ["plot", "a b.nc", "--day", "5"],
        ["plot", "o.nc", "--day", "1"],
        "import swe_sphere\nx = 1",
    ]
    assert bash == ["bash", "-c", "set -e\nswe-sphere run tc2_steady --output o.nc\nswe-sphere plot o.nc > o.txt"]
    assert json.loads(each_after[3]) == ["print(2)", ["plot", "o.nc", "--day", "2"]]
    assert ls == ["bash", "-c", "set -e\nls > o.txt"]
    assert alone == ["bash", "-c", "set -e\nswe-sphere plot o.nc --day 3"]


def test_each_python_block_runs_as_a_program_of_its_own(tmp_path, monkeypatch, capsys):
    """In one process (``run_each``) a block sees no name an earlier block made, and the first
    block that raises or exits with a status ends the row with that status (1 for a raise, its
    traceback on stderr), as ``python -c`` would."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", list(sys.argv))
    assert run_each(["x = 1", "assert 'x' not in globals() and __name__ == '__main__'"]) == 0
    assert run_each(["import sys\nsys.exit(3)", "open('after', 'w')"]) == 3
    assert run_each(["raise ValueError('the block failed')", "open('after', 'w')"]) == 1
    assert "ValueError: the block failed" in capsys.readouterr().err
    assert not (tmp_path / "after").exists()


# every Markdown page of the manual, by kind; the gallery's examples (docs/examples/) run in the
# site's build, and what the build writes (docs/gallery/, the html) is no page
KINDS = ("getting-started", "how-to", "explanation", "reference")
DOCS_PAGES = tuple(
    sorted([*(ROOT / "docs").glob("*.md"), *(p for k in KINDS for p in (ROOT / "docs" / k).rglob("*.md"))])
)
PAGES = (ROOT / "README.md", *DOCS_PAGES)
SCENE_KEY = re.compile(r"(?:^|\s)([a-z_]+)\.([a-z_][a-z_0-9]*)(?=[=\s]|$)")  # `grid.cube`, `-s grid.cube=...`


def _is_python_name(section: str, key: str) -> bool:
    """Whether ``section.key`` names a module or attribute (``grid.quality``, ``time.process_time``)."""
    for module in (f"swe_sphere.{section}", section):
        try:
            if importlib.util.find_spec(f"{module}.{key}") is not None:
                return True
        except ModuleNotFoundError:
            pass
        try:
            if hasattr(importlib.import_module(module), key):
                return True
        except ImportError:
            pass
    return False


def _unbound_names(source: str) -> list[str]:
    """The names a Python block reads at its top level or as globals of its functions and
    comprehensions that it neither imports nor assigns, nor are builtins (``symtable``)."""
    top = symtable.symtable(source, "<block>", "exec")
    bound = {s.get_name() for s in top.get_symbols() if s.is_assigned() or s.is_imported()}
    read, tables = set(), [top]
    while tables:
        table = tables.pop()
        read |= {s.get_name() for s in table.get_symbols() if s.is_referenced() and (table is top or s.is_global())}
        tables += table.get_children()
    return sorted(read - bound - set(dir(builtins)))


def test_each_python_block_runs_pasted_alone():
    """docs/how-to/gradients.md's fifth block (and two of the README's) used `swe_sphere` that an
    earlier block imported: pasted alone, a NameError (issue 117, item 14). Each block binds
    every name it reads."""
    unbound = [
        f"{page.relative_to(ROOT)} block {k}: {names}"
        for page in PAGES
        for k, (lang, text) in enumerate(examples(page, inline=False))
        if lang == "python" and (names := _unbound_names(text))
    ]
    assert unbound == []


def test_the_pages_name_only_scene_keys_that_exist():
    """docs/explanation/efficiency.md named `grid.equidistant` ("unknown key grid.equidistant in scene"; the
    key is `grid.cube`): every `SECTION.KEY` written in a page's code span, SECTION a scene
    table of fixed keys, is a key of it."""
    unknown = []
    for page in PAGES:
        for span in re.findall(r"`([^`\n]+)`", page.read_text()):
            for section, key in SCENE_KEY.findall(span):
                keys = SCHEMA.get(section)
                if isinstance(keys, dict) and key not in keys and not _is_python_name(section, key):
                    unknown.append(f"{page.relative_to(ROOT)}: {section}.{key} in `{span}`")
    assert unknown == []


def test_the_readme_says_what_a_frontier_rerun_takes():
    """The README said a frontier "rerun reuses the runs"; the same command again is refused
    ("output file exists: .../frontier.csv") unless --overwrite, as every command that would
    replace results is (tests/studies/test_frontier.py: the rerun with overwrite reuses them)."""
    text = " ".join((ROOT / "README.md").read_text().split())
    frontier = text[text.index("### frontier") : text.index("### stability")]
    assert "a rerun reuses the runs" not in frontier
    assert "with `--overwrite` replaces these files and makes only the runs it lacks" in frontier


# each page a group of its own, so that the pages (minutes together) spread over the workers
@pytest.mark.xdist_group("docs-readme")
def test_readme_examples_run_as_written(tmp_path):
    run_examples(ROOT / "README.md", tmp_path, inline=False)  # its inline commands restate its blocks


# the efficiency study's page is ten sweeps and their tables: about a minute of CPU even
# shortened; each study's own page (docs/explanation/efficiency/*.md) runs every command that made it
SLOW_PAGES = (ROOT / STUDY.with_suffix(".md"), *(ROOT / STUDY).glob("*.md"))


@pytest.mark.parametrize(
    "page",
    [
        pytest.param(
            str(p.relative_to(ROOT / "docs")),
            marks=[
                pytest.mark.xdist_group(f"docs-{p.relative_to(ROOT / 'docs').with_suffix('')}"),
                *([pytest.mark.slow] if p in SLOW_PAGES else []),
            ],
        )
        for p in DOCS_PAGES
        if programs(p)
    ],
)
def test_docs_examples_run_as_written(tmp_path, page):
    run_examples(ROOT / "docs" / page, tmp_path)
