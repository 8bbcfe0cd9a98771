"""The layers (pyproject.toml's [tool.importlinter], docs/design.md) hold: no module
imports from a layer above it, kernels import nothing of swe_sphere, and no import
circle, function-level imports included. CI runs ``lint-imports`` too; this test
makes ``python -m pytest`` alone catch a new circle."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LINT = "import sys; from importlinter.cli import lint_imports; sys.exit(lint_imports(no_cache=True, no_logo=True))"


def test_every_import_points_down_and_none_closes_a_circle():
    # from the repository root: kernels/ is linted as the top-level package "kernels" (pyproject.toml)
    done = subprocess.run([sys.executable, "-c", LINT], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "Contracts: 3 kept, 0 broken." in done.stdout


def test_kernels_import_only_kernels():
    """What lint-imports cannot see: linted as the top-level "kernels", a relative
    import out of it (``from ..grid import``, swe_sphere.grid once installed) is dropped."""
    out = [f"{path.name}:{node.lineno}" for path in sorted((REPO / "kernels").glob("*.py"))
           for node in ast.walk(ast.parse(path.read_text())) if isinstance(node, ast.ImportFrom) and node.level > 1]
    assert not out, f"kernels import from outside kernels/ at {', '.join(out)}"
