"""Every shell and Python example of README.md and docs/*.md runs as written, in
order, in one fresh folder (as a user on a fresh clone: ``testcases/`` beside it),
with one change: each ``swe-sphere run | sweep | stability`` and each Python
``ne=`` runs at a tiny grid (``--ne`` / ``ne=`` set to ``NE``, added where a scene's
own grid would be used but for a run on a ``--mesh`` file, and default file names
``*_ne<N>np*`` to match). Left out, with the reason: ``pip install`` and
``python -m pytest`` (this test runs inside them), ``mpiexec`` lines (MPI tests:
tests/test_mpi.py) and ``--device cuda`` lines (tests/test_cuda.py). README.md is
in the default run; docs/*.md are ``slow``, but for ``PAGES_LEFT_OUT``."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NE = 2
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)
LEFT_OUT = ("pip install", "python -m pytest", "mpiexec", "--device cuda")
GRID_COMMAND = re.compile(r"^swe-sphere (run|sweep|stability)\b")


def blocks(path: Path) -> list[tuple[str, str]]:
    """(language, text) of each bash/sh/python code block of ``path``, in order."""
    return [(lang, text) for lang, text in FENCE.findall(path.read_text()) if lang in ("bash", "sh", "python")]


def shell_line(line: str) -> str | None:
    """The command of one shell line at ``NE`` (None: left out)."""
    parts = []
    for command in line.split("&&"):
        command = re.sub(r"\s+#.*$", "", command).strip()
        if not command or any(word in command for word in LEFT_OUT):
            continue
        if GRID_COMMAND.match(command):
            if "--ne" in command.split():
                command = re.sub(r"--ne\s+\d+", f"--ne {NE}", command)
            elif not {"--continue", "--from", "--mesh"} & set(command.split()):
                command += f" --ne {NE}"
        parts.append(re.sub(r"_ne\d+np", f"_ne{NE}np", command))  # a default file name says the grid
    return " && ".join(parts) or None


def programs(path: Path) -> list[list[str]]:
    """The file's examples as commands to run in order: a shell block as one ``bash``
    script, a Python block as one program after the imports of the page's earlier
    Python blocks (the page reads as one session; its runs are not made twice)."""
    out, imports = [], []
    for lang, text in blocks(path):
        if lang == "python":
            text = re.sub(r"\bne=\d+", f"ne={NE}", text)
            out.append([sys.executable, "-c", "\n".join([*imports, text])])
            imports += [line for line in text.splitlines() if re.match(r"(import|from) \S", line)]
            continue
        lines = [
            command for line in text.replace("\\\n", " ").splitlines() if (command := shell_line(line)) is not None
        ]
        if lines:
            out.append(["bash", "-c", "\n".join(["set -e", *lines])])
    return out


def run_examples(path: Path, folder: Path) -> None:
    (folder / "testcases").symlink_to(ROOT / "testcases")
    env = {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
        "MPLBACKEND": "Agg",
        "SWE_SPHERE_THREADS": "1",
    }
    for argv in programs(path):
        proc = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True, timeout=1800)
        assert proc.returncode == 0, f"{path.name}: example failed:\n{argv[-1]}\n{proc.stderr[-3000:]}"


def test_shell_lines_are_shortened_only_in_their_grid():
    assert (
        shell_line("swe-sphere run tc5_mountain --ne 16 --days 5  # note")
        == f"swe-sphere run tc5_mountain --ne {NE} --days 5"
    )
    assert shell_line("swe-sphere run tc5_mountain -s a.b=1") == f"swe-sphere run tc5_mountain -s a.b=1 --ne {NE}"
    assert (
        shell_line("swe-sphere run --continue r.restart.nc --days 20")
        == "swe-sphere run --continue r.restart.nc --days 20"
    )
    assert shell_line("swe-sphere run tc2_steady --mesh x.g") == "swe-sphere run tc2_steady --mesh x.g"
    assert shell_line("swe-sphere plot tc5.nc --day 5") == "swe-sphere plot tc5.nc --day 5"
    assert (
        shell_line("swe-sphere plot tc2_steady_ne8np4_ssprk3.nc") == f"swe-sphere plot tc2_steady_ne{NE}np4_ssprk3.nc"
    )
    assert shell_line("pip install -e . && swe-sphere list") == "swe-sphere list"
    assert shell_line("mpiexec -n 4 swe-sphere run tc5_mountain") is None


def test_readme_examples_run_as_written(tmp_path):
    run_examples(ROOT / "README.md", tmp_path)


# efficiency.md records studies of hours (hundreds of 15-day runs) and names some run lists "..."
PAGES_LEFT_OUT = ("efficiency.md",)


@pytest.mark.slow
@pytest.mark.parametrize(
    "page", sorted(p.name for p in (ROOT / "docs").glob("*.md") if p.name not in PAGES_LEFT_OUT and blocks(p))
)
def test_docs_examples_run_as_written(tmp_path, page):
    run_examples(ROOT / "docs" / page, tmp_path)
