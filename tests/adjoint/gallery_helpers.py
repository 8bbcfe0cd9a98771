"""docs/examples/assimilation/_assimilation.py, the gallery's assimilation examples' shared
functions, as a module (docs/examples/ is no package: sphinx-gallery runs its files with the folder
on the path)."""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path

HELPERS = Path(__file__).resolve().parents[2] / "docs" / "examples" / "assimilation" / "_assimilation.py"


@functools.cache
def assimilation():
    """The module, loaded once."""
    spec = importlib.util.spec_from_file_location("_assimilation", HELPERS)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
