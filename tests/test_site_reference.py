"""The site's API page (docs/reference/api.md) has an entry for every name of
``swe_sphere.__all__``, and what it renders, those names' docstrings and their public members',
cites no issue number and no commit: a reference page says what is, history stays in git."""

import importlib
import inspect
import re
from pathlib import Path

import pytest

import swe_sphere

API_PAGE = Path(__file__).resolve().parents[1] / "docs" / "reference" / "api.md"
HISTORY = re.compile(r"\bissues? #?\d+|\bgit show\b|\bcommit [0-9a-f]{7,}\b|\b[0-9a-f]{7}:[\w/]+\.md\b")


def _entries() -> set[str]:
    text = API_PAGE.read_text()
    listed = set(re.findall(r"^   ([A-Za-z_][\w.]*)$", text, re.M))  # autosummary's lines
    return listed | set(re.findall(r"^\.\. py:data:: (\S+)$", text, re.M))


def test_every_name_of_all_has_an_entry_on_the_api_page():
    assert sorted(set(swe_sphere.__all__) - _entries()) == []


def _resolve(entry: str):
    """The object of an entry (``Simulation``, ``simulation.summary.RunResult``) under swe_sphere."""
    module, _, name = f"swe_sphere.{entry}".rpartition(".")
    return getattr(importlib.import_module(module), name)


@pytest.mark.parametrize("name", sorted(_entries()))
def test_an_api_entry_cites_no_issue_and_no_commit(name):
    obj = _resolve(name)
    if not (inspect.isclass(obj) or inspect.isfunction(obj)):
        return  # __version__, STEPPERS: their entries are written on the page
    docs = {name: inspect.getdoc(obj) or ""}
    if inspect.isclass(obj):  # autodoc's :members: renders the public members defined on it
        docs |= {f"{name}.{k}": inspect.getdoc(v) or "" for k, v in vars(obj).items() if not k.startswith("_")}
    cited = {where: HISTORY.findall(doc) for where, doc in docs.items() if HISTORY.search(doc)}
    assert cited == {}


def test_the_steppers_page_cites_no_issue_and_no_commit():
    from swe_sphere.steppers import STEPPERS  # the page renders each registered class's docstring

    cited = {name: HISTORY.findall(inspect.getdoc(cls) or "") for name, cls in STEPPERS.items()}
    assert {name: found for name, found in cited.items() if found} == {}


@pytest.mark.parametrize("name", sorted(_entries()))
def test_numpydoc_reads_an_api_entrys_sections_as_written(name):
    """Prose after a section without its own header is read as more of that section (a
    paragraph after Parameters as parameters named by its words): numpydoc renders it mangled."""
    docscrape = pytest.importorskip("numpydoc.docscrape")  # the docs extra's
    obj = _resolve(name)
    objs = {name: obj}
    if inspect.isclass(obj):
        objs |= {f"{name}.{k}": v for k, v in vars(obj).items() if not k.startswith("_")}
    misread = []
    for where, o in objs.items():
        doc = inspect.getdoc(o) or ""
        if not re.search(r"^(Parameters|Returns|Raises|Yields|Attributes)\n-+$", doc, re.M):
            continue
        parsed = docscrape.NumpyDocString(doc)
        sections = ("Parameters", "Returns", "Raises", "Yields", "Attributes", "Other Parameters")
        names = [p.name for section in sections for p in parsed[section]]
        # a name, names, or none (a Returns or Raises entry of its type alone)
        misread += [(where, n) for n in names if not re.fullmatch(r"(\*{0,2}\w+(, \*{0,2}\w+)*)?", n.strip())]
    assert misread == []


def test_every_test_file_the_pages_cite_exists():
    """A page that backs a figure with a test names its file (``tests/integrator/test_step_control.py``):
    each cited path exists, so a test moved to its subject's folder takes its citations along."""
    root = API_PAGE.parents[2]
    pages = [*root.glob("docs/**/*.md"), root / "README.md"]
    cited = {path for page in pages for path in re.findall(r"\btests/[\w/]+\.py\b", page.read_text())}
    assert "tests/integrator/test_step_control.py" in cited
    assert sorted(path for path in cited if not (root / path).is_file()) == []
