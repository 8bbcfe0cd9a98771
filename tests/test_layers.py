"""The layers (pyproject.toml's [tool.importlinter], docs/design.md) hold: each folder of
swe_sphere imports only from the folders below it, the kernels (``swe_sphere/kernels``, a
link to ``kernels/``) from none, and no import circle, function-level imports included.
CI runs ``lint-imports`` too; this test makes ``python -m pytest`` alone catch a new circle."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LINT = "import sys; from importlinter.cli import lint_imports; sys.exit(lint_imports(no_cache=True, no_logo=True))"


def test_every_import_points_down_and_none_closes_a_circle():
    done = subprocess.run([sys.executable, "-c", LINT], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "Contracts: 2 kept, 0 broken." in done.stdout
