"""A benchmark script's bad input ends as the command line's does (benchmarks/results.py's
``one_line`` for the package's own errors, argparse's for the scripts' own checks): one line
naming the value, exit 2, no traceback, and no results file (written at a normal exit only)."""

from __future__ import annotations

import contextlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def written(folder: Path) -> dict:
    """Every file under ``folder`` (a folder of results per script) with its modification time."""
    return {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize(
    "script, args, says",
    [
        ("micro/step/step_cost.py", ["--ne", "-3"], "step_cost.py: error: ne must be an integer >= 1 (got -3)"),
        ("micro/gradient_cost.py", ["--ne", "2", "--steps", "-2"], "gradient_cost.py: error: --steps must be >= 1"),
        ("micro/ensemble_cost.py", ["--steps", "0"], "ensemble_cost.py: error: argument --steps: must be > 0 (got 0)"),
        (
            "micro/step/roofline.py",
            ["kernel_roofline", "--rounds", "0"],
            "roofline.py kernel_roofline: error: argument --rounds: must be > 0 (got 0)",
        ),
        (
            "archive/replaced_paths.py",
            ["across_elements", "--case", "9,2,4"],
            "replaced_paths.py across_elements: error: argument --case: --case 9,2,4: np 2-8",
        ),
        ("compare.py", ["nosuch"], "compare.py: error: no commit 'nosuch' in this repository"),
        ("compare.py", ["HEAD", "--factor", "0.9"], "compare.py: error: argument --factor: must be > 1.0 (got 0.9)"),
        (
            "micro/step/hyperviscosity_every.py",
            ["--scene", "tc2_steady", "--ne", "2"],
            "hyperviscosity_every.py: error: --scene tc2_steady: its terms have no hyperviscosity",
        ),
    ],
)
def test_a_bad_input_is_one_line_and_exit_2(tmp_path, script, args, says):
    results = written(BENCHMARKS / "results")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "SWE_SPHERE_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), *args], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith(says), done.stderr
    assert "Traceback" not in done.stderr
    assert written(BENCHMARKS / "results") == results


def test_the_card_s_items_run_on_the_cpu_at_tiny_size(tmp_path):
    """``benchmarks/gpu/gpu_session.sh card`` (issue 114 item 7: float32 against float64, first on a lent
    card) as a session checks it here: ``DEVICE=cpu NE_SMALL=1``, its ensemble item and an unknown
    one. The item's two precisions time the same steps (the float32 run's h within round-off of
    float32 of the float64 one's, not the same), the summary's table and figures under $OUT beside
    the bundle of the items' files, an unknown item one line and the status 1, nothing written
    under benchmarks/results."""
    import json
    import tarfile

    results = written(BENCHMARKS / "results")
    root = str(BENCHMARKS.parent)
    env = {
        **os.environ,
        "OMP_NUM_THREADS": "1",
        "SWE_SPHERE_THREADS": "1",
        "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])),
        "PYTHON": sys.executable,
        "OUT": str(tmp_path),
        "DEVICE": "cpu",
        "NE_SMALL": "1",
        "CARD": "members bogus",
    }
    done = subprocess.run(
        ["bash", str(BENCHMARKS / "gpu" / "gpu_session.sh"), "card"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert "== card: unknown item 'bogus'" in done.stdout
    figures = json.loads((tmp_path / "card.json").read_text())["figures"]
    rows = {r["precision"]: r for r in figures["precision"]}
    assert list(rows) == ["float64", "float32"] and {r["members"] for r in rows.values()} == {2}
    assert all(r["graphs_kept"] > 0 for r in rows.values())  # the card's path: each step a graph
    assert rows["float64"]["h_rel_diff"] == 0.0 and 0.0 < rows["float32"]["h_rel_diff"] < 1e-6
    assert figures["items"]["precision_members"]["exit"] == 0 and figures["mpi"] is None
    assert "| precision_members | galewsky | 2 8 | kgu35 | 2 | float32 |" in (tmp_path / "card.md").read_text()
    with tarfile.open(tmp_path / "card.tgz") as bundle:
        assert {"card/precision_members.json", "card/session.log"} <= set(bundle.getnames())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["card.json", "card.md", "card.tgz", "session.log"]
    assert written(BENCHMARKS / "results") == results


def _tables():
    """benchmarks/tables.py as a module (benchmarks/ is no package: its scripts run as files)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("benchmark_tables", BENCHMARKS / "tables.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_readme_is_generated_from_the_results_unchanged():
    """benchmarks/README.md is what ``python benchmarks/tables.py`` writes from the results: an
    edit by hand, or a results file added without regenerating, shows here."""
    assert _tables().page() == (BENCHMARKS / "README.md").read_text(), "python benchmarks/tables.py"


def test_the_rooms_keep_the_suite_s_rules():
    """Issue 126's targets: at most 12 files directly in any folder (of scripts or of results), a script's name once
    across the rooms (the scripts import one another by it), every results folder named after a script,
    no script over 600 lines nor a function over 80 code lines (comments, docstrings and blank
    lines left out), and no deprecated ``Ensemble``."""
    import ast

    folders = [BENCHMARKS, *(p for p in BENCHMARKS.rglob("*") if p.is_dir())]  # the results' folders too
    crowded = {str(f): n for f in folders if (n := sum(p.is_file() for p in f.iterdir())) > 12}
    assert not crowded, crowded
    scripts = [p for p in BENCHMARKS.rglob("*") if p.suffix in (".py", ".sh") and "results" not in p.parts]
    modules = [p.stem for p in scripts if p.suffix == ".py"]  # (gpu_session.sh drives gpu_session.py)
    assert len(modules) == len(set(modules)), sorted(s for s in modules if modules.count(s) > 1)
    stems = {p.stem for p in scripts}
    gallery = BENCHMARKS.parent / "docs" / "examples"  # the application scripts' place now, as plot_<name>.py
    elsewhere = {p.stem.removeprefix("plot_") for p in gallery.rglob("plot_*.py")}
    orphans = {p.name for p in (BENCHMARKS / "results").iterdir()} - stems - elsewhere
    assert not orphans, orphans
    long, ensembles = {}, []
    for path in (p for p in scripts if p.suffix == ".py"):
        text = path.read_text()
        lines, tree = text.splitlines(), ast.parse(text)
        if len(lines) > 600:
            long[path.name] = len(lines)
        docs = {
            n
            for node in ast.walk(tree)
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef) and ast.get_docstring(node)
            for n in range(node.body[0].lineno, node.body[0].end_lineno + 1)
        }
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef):
                code = [
                    n
                    for n in range(node.lineno, node.end_lineno + 1)
                    if n not in docs and lines[n - 1].strip() and not lines[n - 1].strip().startswith("#")
                ]
                if len(code) > 80:
                    long[f"{path.name}:{node.name}"] = len(code)
        ensembles += [path.name for node in ast.walk(tree) if isinstance(node, ast.Name) and node.id == "Ensemble"]
    assert not long, long
    assert not ensembles, ensembles


def below_the_public_api(path: Path) -> set[str]:
    """The ``swe_sphere`` names ``path`` imports (in its code or in the code of a child process it
    holds as a string) that are not public: neither a name of ``swe_sphere.__all__`` (imported from
    ``swe_sphere``), nor one docs/reference/api.md documents (``config.schema.SceneGrid``, ...), nor
    the console script's entry point (pyproject's ``swe_sphere.cli:main``, the command line)."""
    import ast
    import re
    import tomllib

    import swe_sphere

    root = BENCHMARKS.parent
    api = (root / "docs" / "reference" / "api.md").read_text()
    documented = re.findall(r"^\s+([a-z_]+(?:\.[a-z_]+)*\.[A-Za-z_]+)\s*$", api, re.M)
    entry = tomllib.loads((root / "pyproject.toml").read_text())["project"]["scripts"].values()
    public = {f"swe_sphere.{name}" for name in [*swe_sphere.__all__, *documented]}
    public |= {e.replace(":", ".") for e in entry}
    tree = ast.parse(path.read_text())
    trees = [tree]
    for node in ast.walk(tree):  # a child's code (``python -c CHILD``)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and "swe_sphere" in node.value:
            with contextlib.suppress(SyntaxError):
                trees.append(ast.parse(node.value))
    below = set()
    for node in (n for t in trees for n in ast.walk(t)):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "swe_sphere":
            below |= {f"{node.module}.{a.name}" for a in node.names} - public
        elif isinstance(node, ast.Import):
            below |= {a.name for a in node.names if a.name.startswith("swe_sphere.")} - public
    return below


def test_fewer_than_25_scripts_import_below_the_public_api():
    """Issue 126's target: a kernel's split should not reach into the benchmarks. A script that times
    one internal piece (a kernel, the DSS, a mesh reader) imports it, and that is fair; the rest reach
    the model through its public names. The shared module (results.py) is the suite's one adapter
    (Warp's quiet start, the command line's exit statuses) and is no script."""
    scripts = [p for p in BENCHMARKS.rglob("*.py") if "results" not in p.parts and p.name != "results.py"]
    below = {str(p.relative_to(BENCHMARKS)): sorted(n) for p in scripts if (n := below_the_public_api(p))}
    assert len(below) < 25, below
    assert below_the_public_api(BENCHMARKS / "regressions" / "whole_run.py") == set()  # the CLI's entry is public


# a folder of the machine that measured: its scratch, its home, its checkouts and virtual environments
# (the system's own, /usr/bin/mpirun or /proc/cpuinfo, are every machine's and stay)
MACHINE = re.compile(r"(?<![\w.~$/-])/(?:work|tmp|home|root|opt|mnt|scratch|Users)/[\w.~+/-]*")


def test_no_benchmark_file_names_a_folder_of_the_machine_that_ran_it():
    """Issue 127's noticed item: scripts, their notes and their results name the repository's paths
    relative to it and a peer's build or a tree compared as DIR/<its last part> (``results.portable``,
    applied to every record as it is written), never /work/..., /tmp/... or a home folder."""
    assert MACHINE.findall("--source /tmp/base-s: x; /work/main/swe_sphere/a.py:3; /usr/bin/mpirun; h / g; ~/site") == [
        "/tmp/base-s",
        "/work/main/swe_sphere/a.py",
    ]
    texts = [
        p for p in BENCHMARKS.rglob("*") if p.is_file() and p.suffix in (".py", ".sh", ".md", ".json", ".csv", ".txt")
    ]
    found = {str(p.relative_to(BENCHMARKS)): hits for p in texts if (hits := MACHINE.findall(p.read_text()))}
    assert found == {}


def cited_results() -> dict:
    """Every benchmarks/results path (a file or a glob) the documentation and the README cite, with
    the first file citing it (a script's docstring names where it writes, not a figure)."""
    root = BENCHMARKS.parent
    sources = [*root.glob("docs/**/*.md"), *root.glob("docs/examples/**/*.py"), root / "README.md"]
    cited = {}
    for source in sources:
        for path in re.findall(r"results/((?:[\w.-]+/)+[\w.*-]+\.(?:json|csv|txt|npz|nc))", source.read_text()):
            cited.setdefault(path, str(source.relative_to(root)))
    return cited


def test_every_cited_results_file_exists():
    """The documentation quotes a figure with its results file: each cited path (or glob) names at
    least one file under benchmarks/results (a pruned run is cited as ``git show COMMIT:PATH``)."""
    cited = cited_results()
    assert "error_control/adaptive_proportionality/adaptive_proportionality.json" in cited  # docs/explanation cites it
    missing = {path: source for path, source in cited.items() if not list((BENCHMARKS / "results").glob(path))}
    assert missing == {}


def test_a_record_names_the_repository_s_paths_relative_and_others_by_their_last_part():
    """``results.portable``, what every results file goes through as it is written: a path into the
    repository relative to its root, a package's file from its package on, the system's folders kept,
    any other path DIR/<its last part>; words with slashes that are no paths (units, ratios) untouched.
    (In a child process: results.py sets the interpreter's excepthook and path as a script's.)"""
    text = (
        "--mesh /w/repo/tests/data/m.g; /w/repo: 2.1 s; at /tmp/site/warp/_src/context.py:12(launch); "
        "/opt/v/lib/site-packages/numpy/x.py:3; /usr/bin/mpirun -np 1; --python /home/u/.venvs/d/bin/python; m/s, h / g"
    )
    code = f"import results; print(results.portable({text!r}, ('/w/repo',)))"
    done = subprocess.run([sys.executable, "-c", code], cwd=BENCHMARKS, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == (
        "--mesh tests/data/m.g; .: 2.1 s; at warp/_src/context.py:12(launch); "
        "numpy/x.py:3; /usr/bin/mpirun -np 1; --python DIR/python; m/s, h / g"
    )


def test_a_results_path_given_absolute_is_written_there(tmp_path):
    """``--results /some/where/x`` writes /some/where/x.json, with a script's study
    (``recorded``'s ``study``: results/<script>/<study>/<stem>.json) or without one; without
    ``--results`` a study's file is results/<script>/<study>/<study>.json as before. (In a child
    process, as above, its ``RESULTS`` moved to a folder of the test's.)"""
    code = (
        "import results, sys\n"
        "from pathlib import Path\n"
        "results.RESULTS = Path(sys.argv[3])\n"
        "for stem, study in ((sys.argv[1], 'across_elements'), (sys.argv[2], None), (None, 'across_elements')):\n"
        "    with results.recorded('replaced_paths.py', stem, study) as figures:\n"
        "        figures['n'] = 7; print('row')\n"
    )
    args = [str(tmp_path / "a" / "study"), str(tmp_path / "plain"), str(tmp_path / "results")]
    done = subprocess.run([sys.executable, "-c", code, *args], cwd=BENCHMARKS, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*.json")) == [
        "a/study.json",
        "plain.json",
        "results/replaced_paths/across_elements/across_elements.json",
    ]
    for path in tmp_path.rglob("*.json"):
        record = json.loads(path.read_text())
        assert record["figures"] == {"n": 7} and record["printed"] == ["row"]
    assert f"figures written to {tmp_path / 'a' / 'study.json'}" in done.stderr
