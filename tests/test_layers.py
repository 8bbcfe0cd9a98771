"""The layers (pyproject.toml's [tool.importlinter], docs/design.md) hold: each folder of
swe_sphere imports only from the folders below it, the kernels (``swe_sphere/kernels``, a
link to ``kernels/``) from none, and no import circle, function-level imports included.
CI runs ``lint-imports`` too; this test makes ``python -m pytest`` alone catch a new circle."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LINT = "import sys; from importlinter.cli import lint_imports; sys.exit(lint_imports(no_cache=True, no_logo=True))"


def test_every_import_points_down_and_none_closes_a_circle():
    done = subprocess.run([sys.executable, "-c", LINT], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "Contracts: 2 kept, 0 broken." in done.stdout


# reaches into other libraries' underscored names that have no public equivalent, each with why
LIBRARY_NAMES = {
    "os._exit": "the standard library's documented exit without teardown (cli)",
    "atexit._run_exitfuncs": "the atexit callbacks run before os._exit skips the teardown (cli)",
    "Module._run_codegen": "Warp's code generation hooked to say once that kernels compile (core.runtime)",
    "view._ref": "Warp's keep-alive slot of an array view, set as wp.array.view sets it (kernels.operators)",
}


def private_reaches(source: str) -> list[tuple[int, str]]:
    """(line, text) of each reach into a private name in ``source``: ``obj._name`` where obj
    is not ``self``, ``cls`` or ``super()``, and ``from x import _name``. Dunder (``__len__``)
    and sunder (ctypes' ``_length_``) names are public protocol."""

    def private(name: str) -> bool:
        return name.startswith("_") and not name.endswith("_")

    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and private(node.attr):
            obj = node.value
            own = (isinstance(obj, ast.Name) and obj.id in ("self", "cls")) or (
                isinstance(obj, ast.Call) and isinstance(obj.func, ast.Name) and obj.func.id == "super"
            )
            if not own:
                found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, ast.ImportFrom):
            found.extend((node.lineno, f"from {node.module} import {a.name}") for a in node.names if private(a.name))
    return sorted(found)


def test_private_reaches_are_found():
    source = "self._a; cls._b; super()._c; x.__len__; t._length_\nm._d\nself.model._e\nfrom y import _f, g\n"
    assert private_reaches(source) == [(2, "m._d"), (3, "self.model._e"), (4, "from y import _f")]


def test_no_module_reads_another_module_or_class_private_names():
    """Every module of swe_sphere/ and kernels/ (swe_sphere/kernels is a link to it) reaches
    into no other module's or class's private names, but the listed library ones."""
    files = [
        path
        for path in sorted(REPO.glob("swe_sphere/**/*.py")) + sorted(REPO.glob("kernels/*.py"))
        if not path.is_relative_to(REPO / "swe_sphere" / "kernels")
    ]
    assert len(files) >= 80  # the tree, not an empty glob
    reaches = [
        f"{path.relative_to(REPO)}:{line}: {text}"
        for path in files
        for line, text in private_reaches(path.read_text())
        if text not in LIBRARY_NAMES
    ]
    assert not reaches, "\n".join(reaches)
