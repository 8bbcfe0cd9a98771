"""The layers (pyproject.toml's [tool.importlinter], docs/explanation/design.md) hold: each folder of
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
    "arg._cls": "Warp's struct instance's class, whose fields name the arrays a launch moves (core.tally)",
}

# the tests' reaches into other libraries' underscored names, each with why (none into the package's)
TEST_LIBRARY_NAMES = {
    "wp._src": "Warp >= 1.10 moved its runtime context there; no public query of its CUDA compiler",
    "conn._FillValue": "netCDF's reserved attribute name (the CF conventions'), read from a written file",
    # argparse has no public walk of a parser's subcommands and options; sphinx-argparse, whose page
    # tests/cli/test_cli_page.py checks against the parser, reads the same names
    "argparse._SubParsersAction": "argparse's subcommands, found as sphinx-argparse finds them",
    "argparse._HelpAction": "argparse's -h, left off the CLI page",
    "p._actions": "a parser's options, as sphinx-argparse reads them",
    "sub._actions": "a subcommand's options, as sphinx-argparse reads them",
}
# the package's private names a test names in a string (a frame's function, an attribute by a
# variable's name), each with why
TEST_PRIVATE_STRINGS = {
    "_checked": "fault injection inside a whole step's capture tells it from a solve's capture by "
    "GraphedSteps._checked's frame (test_graph_fallback): no public signal tells the two apart",
}
ATTRIBUTE_CALLS = ("getattr", "setattr", "hasattr", "delattr")  # and monkeypatch.setattr/delattr


def private_reaches(source: str) -> list[tuple[int, str]]:
    """(line, text) of each reach into a private name in ``source``: ``obj._name`` where obj
    is not ``self``, ``cls`` or ``super()``, the same by name (``getattr(obj, "_name")``,
    ``setattr``, ``hasattr``, ``delattr``, pytest's ``monkeypatch.setattr(obj, "_name", v)``
    and ``monkeypatch.setattr("module.obj._name", v)``; text ``obj._name``), and ``from x
    import _name``. Dunder (``__len__``) and sunder (ctypes' ``_length_``) names are public
    protocol."""

    def private(name: str) -> bool:
        return name.startswith("_") and not name.endswith("_")

    def own(obj) -> bool:
        return (isinstance(obj, ast.Name) and obj.id in ("self", "cls")) or (
            isinstance(obj, ast.Call) and isinstance(obj.func, ast.Name) and obj.func.id == "super"
        )

    def by_name(call: ast.Call) -> str | None:  # the private name a getattr-like call reaches, as obj._name
        func = call.func
        name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else None
        if name not in ATTRIBUTE_CALLS or not call.args or (isinstance(func, ast.Name) and len(call.args) < 2):
            return None
        first, second = call.args[0], call.args[1] if len(call.args) > 1 else None
        if isinstance(first, ast.Constant) and isinstance(first.value, str) and "." in first.value:
            return first.value if private(first.value.rsplit(".", 1)[1]) else None  # monkeypatch's dotted target
        if isinstance(second, ast.Constant) and isinstance(second.value, str) and private(second.value):
            return None if own(first) else f"{ast.unparse(first)}.{second.value}"
        return None

    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and private(node.attr):
            if not own(node.value):
                found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, ast.Call) and by_name(node):
            found.append((node.lineno, by_name(node)))
        elif isinstance(node, ast.ImportFrom):
            found.extend((node.lineno, f"from {node.module} import {a.name}") for a in node.names if private(a.name))
    return sorted(found)


def test_private_reaches_are_found():
    source = "self._a; cls._b; super()._c; x.__len__; t._length_\nm._d\nself.model._e\nfrom y import _f, g\n"
    assert private_reaches(source) == [(2, "m._d"), (3, "self.model._e"), (4, "from y import _f")]
    by_name = (
        'getattr(self, "_a"); hasattr(x, "b"); getattr(x, "__len__")\nhasattr(wp, "_src")\n'
        'monkeypatch.setattr(st, "_cycle_key", f); monkeypatch.setattr(st, "x", f)\n'
        'monkeypatch.setattr("m.Stepper._at", f); monkeypatch.setattr("m.Stepper.at", f)\n'
    )
    assert private_reaches(by_name) == [(2, "wp._src"), (3, "st._cycle_key"), (4, "m.Stepper._at")]
    held = 'owner, name = (st, "_x_substep")\nsetattr(owner, name, f); f"{k}_x_h"; "_x_other"\n'
    assert named_in_strings(held, {"_x_substep", "_x_h"}) == [(1, "_x_substep")]


def private_names(files) -> set[str]:
    """The private names ``files`` define: functions, classes, assigned names and attributes."""
    names = set()
    for path in files:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.add(node.name)
            elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                names.add(node.attr)
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                names.add(node.id)
    return {name for name in names if name.startswith("_") and not name.endswith("_")}


def named_in_strings(source: str, names: set[str]) -> list[tuple[int, str]]:
    """(line, name) of each string constant of ``source`` (not an f-string's part) that is one
    of ``names``: a reach by a name held in a variable (``setattr(owner, name, f)``)."""
    tree = ast.parse(source)
    parts = {id(v) for node in ast.walk(tree) if isinstance(node, ast.JoinedStr) for v in node.values}
    return sorted(
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and node.value in names and id(node) not in parts
    )


def package_files() -> list[Path]:
    """The package's modules: swe_sphere/ and kernels/ (swe_sphere/kernels is a link to it)."""
    return [
        path
        for path in sorted(REPO.glob("swe_sphere/**/*.py")) + sorted(REPO.glob("kernels/*.py"))
        if not path.is_relative_to(REPO / "swe_sphere" / "kernels")
    ]


def unlisted_reaches(files, allowed: dict) -> list[str]:
    """ "path:line: text" of each private reach in ``files`` (``private_reaches``) not in ``allowed``."""
    return [
        f"{path.relative_to(REPO)}:{line}: {text}"
        for path in files
        for line, text in private_reaches(path.read_text())
        if text not in allowed
    ]


def test_no_module_reads_another_module_or_class_private_names():
    """Every module of swe_sphere/ and kernels/ (swe_sphere/kernels is a link to it) reaches
    into no other module's or class's private names, but the listed library ones."""
    files = package_files()
    assert len(files) >= 80  # the tree, not an empty glob
    reaches = unlisted_reaches(files, LIBRARY_NAMES)
    assert not reaches, "\n".join(reaches)


def test_no_test_reads_the_package_private_names():
    """The tests go through the package's public surface (steppers', solvers', the model's
    documented members): no reach into a private name, but the listed library ones."""
    files = sorted(REPO.glob("tests/**/*.py"))
    assert len(files) >= 100  # the suite, not an empty glob
    reaches = unlisted_reaches(files, TEST_LIBRARY_NAMES)
    names = private_names(package_files())
    reaches += [
        f"{path.relative_to(REPO)}:{line}: the string {name!r}"
        for path in files
        for line, name in named_in_strings(path.read_text(), names)
        if name not in TEST_PRIVATE_STRINGS
    ]
    assert not reaches, "\n".join(reaches)


def model_reads(source: str) -> list[tuple[int, str]]:
    """(line, member) of each attribute read on a model in ``source``: on the names ``model``
    and ``m`` and on names bound to ``<something>.model``, and on ``<something>.model`` itself
    (``self.model.rhs``)."""
    tree = ast.parse(source)
    names = {"model", "m"}
    for node in ast.walk(tree):  # m = self.model, and m, topo = self.model, self.topology
        if isinstance(node, ast.Assign):
            for target in node.targets:
                pairs = [(target, node.value)]
                if isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple):
                    pairs = list(zip(target.elts, node.value.elts))
                names.update(
                    t.id
                    for t, v in pairs
                    if isinstance(t, ast.Name) and isinstance(v, ast.Attribute) and v.attr == "model"
                )
    return sorted(
        (node.lineno, node.attr)
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute)
        and (
            (isinstance(node.value, ast.Name) and node.value.id in names)
            or (isinstance(node.value, ast.Attribute) and node.value.attr == "model")
        )
    )


def test_model_reads_are_found():
    source = "m = self.model\nm.rhs(x)\nmodel.topology.N\nstepper.model.lincomb\nmine, t = sim.model, 1\nmine.g\n"
    assert model_reads(source) == [(2, "rhs"), (3, "topology"), (4, "lincomb"), (6, "g")]


def test_steppers_solvers_and_the_adjoint_ask_the_model_for_its_protocol_alone():
    """Issue 82: steppers/, solvers/ and adjoint/ read only the members of ``model.protocol.
    SteppingModel`` (20: issue 100 added ``recorder``, the tape injected where it was probed for,
    and the implicit split ``implicit_terms`` and ``implicit_inverse``;
    issue 99 ``filter``, which a gradient refuses; issue 125 ``rows``, a state's with its tracers, and ``limiter``, theirs;
    issue 128 ``state_dtype``, ``to_step_state``, ``from_step_state`` and ``restore_mass``, the float32 state's,
    and ``held``, the state a run keeps between steps)
    of a model, and every one of them is a ``ShallowWater``'s."""
    from swe_sphere.config.scene import load_scene
    from swe_sphere.model.protocol import members

    from helpers import make_sim

    public = set(members())
    assert len(public) == 26
    files = [p for d in ("steppers", "solvers", "adjoint") for p in sorted((REPO / "swe_sphere" / d).glob("*.py"))]
    assert len(files) >= 30
    model = make_sim(load_scene("galewsky", ne=2, np_=4)).model  # every term but the forcing
    instance = {name for name in dir(model) if not name.startswith("_")}
    assert public <= instance
    outside = [
        f"{path.relative_to(REPO)}:{line}: model.{name}"
        for path in files
        for line, name in model_reads(path.read_text())
        if name in instance and name not in public
    ]
    assert not outside, "\n".join(outside)


def stepper_reads(source: str) -> list[tuple[int, str]]:
    """(line, member) of each attribute read or written on a stepper in ``source``: on the names
    ``stepper`` and ``st`` and on names bound to ``stepper`` or ``<something>.stepper``, on
    ``<something>.stepper`` itself (``self.stepper.multirate``), and ``getattr(stepper, "name")``."""
    tree = ast.parse(source)
    names = {"stepper", "st"}

    def is_stepper(node) -> bool:
        return (isinstance(node, ast.Name) and node.id in names) or (
            isinstance(node, ast.Attribute) and node.attr == "stepper"
        )

    for node in ast.walk(tree):  # st = self.stepper, and st, m = stepper, self.model
        if isinstance(node, ast.Assign):
            for target in node.targets:
                pairs = [(target, node.value)]
                if isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple):
                    pairs = list(zip(target.elts, node.value.elts))
                names.update(t.id for t, v in pairs if isinstance(t, ast.Name) and is_stepper(v))
    reads = [
        (node.lineno, node.attr)
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute) and is_stepper(node.value)
    ]
    reads += [
        (node.lineno, node.args[1].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id in ("getattr", "hasattr")
        and len(node.args) >= 2
        and is_stepper(node.args[0])
        and isinstance(node.args[1], ast.Constant)
    ]
    return sorted(reads)


def test_stepper_reads_are_found():
    source = (
        "st = self.stepper\nst.split.H\nstepper.mrab.levels\nself.stepper.n_fast = 1\n"
        "mine, t = stepper, 1\nmine.old\ngetattr(stepper, 'table', None)\nmodel.stepper_like\n"
    )
    assert stepper_reads(source) == [(2, "split"), (3, "mrab"), (4, "n_fast"), (6, "old"), (7, "table")]


def test_the_adjoint_asks_a_stepper_for_its_protocol_alone():
    """Issue 82: adjoint/ reads (and writes) only the members of ``steppers.protocol``'s protocols
    of a stepper (every stepper's ``DifferentiableStepper``, and ``linear`` of one that solves
    with L), each one a stepper's; and imports nothing of steppers/ but the protocol module and the
    public table type it names (``butcher.Table``)."""
    from swe_sphere.config.scene import load_scene
    from swe_sphere.steppers.protocol import DifferentiableStepper, members

    from helpers import make_sim

    public = members()
    assert len(public) == 13, sorted(public)
    files = sorted((REPO / "swe_sphere" / "adjoint").glob("*.py"))
    outside = [
        f"{path.relative_to(REPO)}:{line}: stepper.{name}"
        for path in files
        for line, name in stepper_reads(path.read_text())
        if name not in public
    ]
    assert not outside, "\n".join(outside)
    # every stepper's members on a built stepper
    stepper = make_sim(load_scene("galewsky", ne=2, np_=4)).stepper
    assert all(hasattr(stepper, name) for name in members(DifferentiableStepper))
    imports = [
        f"{path.relative_to(REPO)}:{node.lineno}: {node.module} {[a.name for a in node.names]}"
        for path in files
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ImportFrom)
        and "steppers" in (node.module or "").split(".")
        and not (node.module.endswith("steppers.protocol"))
        and not (node.module.endswith("steppers.butcher") and {a.name for a in node.names} <= {"Table"})
    ]
    imports += [
        f"{path.relative_to(REPO)}:{node.lineno}: import {a.name}"
        for path in files
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.Import)
        for a in node.names
        if "steppers" in a.name.split(".")
    ]
    assert not imports, "\n".join(imports)
